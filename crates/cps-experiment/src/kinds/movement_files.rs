//! What every robot kind reports about the movement it hands to the robot: its limit usage
//! at the control rate and, with `[export]`, the retimed movement and the exported files.

use serde_json::{Map, Value, json};

use super::{CONTROL_RATE, limit_usage, usage_line};
use crate::ExperimentError;
use crate::plan::Experiment;
use crate::robots::RobotChoice;
use cps_movement::export::export_samples;
use cps_movement::limits::{JointTrajectory, LimitsReport};
use cps_movement::retiming::retime_samples;
use cps_outcome::outcome::{Document, Table};

/// A robot movement's report and files.
pub(crate) struct MovementFiles {
    /// Every limit at the control rate (on the movement as learned or executed).
    pub usage: LimitsReport,
    /// Summary fields: `retiming` (its JSON, or `{"error"}`) and `export` (one entry per
    /// file), when `[export]` asks for them.
    pub summary: Map<String, Value>,
    /// `<prefix>retimed.csv` when retimed.
    pub tables: Vec<Table>,
    /// The exported files.
    pub documents: Vec<Document>,
    /// Terminal lines (indented).
    pub lines: Vec<String>,
}

impl MovementFiles {
    /// Adds the summary fields, tables and documents to a kind's outcome parts.
    pub fn into_parts(
        self,
        summary: &mut Map<String, Value>,
        tables: &mut Vec<Table>,
        documents: &mut Vec<Document>,
        lines: &mut Vec<String>,
    ) {
        summary.extend(self.summary);
        tables.extend(self.tables);
        documents.extend(self.documents);
        lines.extend(self.lines);
    }

    /// A kind's outcome from its parts, with this movement's added.
    pub fn outcome(
        self,
        header: cps_outcome::outcome::RunHeader,
        report: cps_outcome::outcome::Report,
        mut summary: Map<String, Value>,
        mut tables: Vec<Table>,
        figures: Vec<cps_outcome::outcome::Figure>,
        mut lines: Vec<String>,
    ) -> cps_outcome::outcome::Outcome {
        let mut documents = Vec::new();
        self.into_parts(&mut summary, &mut tables, &mut documents, &mut lines);
        cps_outcome::outcome::Outcome {
            header,
            report,
            summary,
            tables,
            figures,
            documents,
            lines,
        }
    }
}

/// Checks, retimes and exports the joint movement `q` (one row per time of `times`) of
/// `robot`, naming its files with `prefix`. A retiming that cannot hold every limit is
/// reported, not fatal: the movement is then exported with its own timing.
pub(crate) fn movement_files(
    exp: &Experiment,
    robot: &RobotChoice,
    prefix: &str,
    times: &[f64],
    q: Vec<Vec<f64>>,
) -> Result<MovementFiles, ExperimentError> {
    let usage = limit_usage(robot, times, q.clone())?;
    let mut out = MovementFiles {
        lines: vec![format!("  {}", usage_line(&usage))],
        usage,
        summary: Map::new(),
        tables: Vec::new(),
        documents: Vec::new(),
    };
    let Some(plan) = &exp.export else {
        return Ok(out);
    };
    let model = &robot.model;
    let mut traj = JointTrajectory {
        names: model.joint_names.clone(),
        times: times.to_vec(),
        q,
    };
    if let Some(mode) = plan.retime {
        match retime_samples(model, &traj, CONTROL_RATE, mode) {
            Ok(mut r) => {
                out.lines.push(format!("  retimed: {}", r.lines()[0]));
                out.summary.insert("retiming".into(), r.json());
                traj = r.trajectory.clone();
                r.table.name = format!("{prefix}retimed");
                out.tables.push(r.table);
            }
            Err(e) => {
                out.lines
                    .push(format!("  retiming ({}) not possible: {e}", mode.name()));
                out.summary.insert(
                    "retiming".into(),
                    json!({"mode": mode.name(), "error": e.to_string()}),
                );
            }
        }
    }
    let mut exported = Vec::new();
    for format in &plan.formats {
        let e =
            export_samples(model, &traj, *format, &plan.options).map_err(ExperimentError::Input)?;
        let name = format!("{prefix}{}", format.file_name());
        out.lines.push(format!(
            "  exported {name}: {}",
            e.lines.first().map_or("", String::as_str)
        ));
        let mut json = e.json;
        json["file"] = json!(name);
        exported.push(json);
        out.documents.push(Document {
            name,
            bytes: e.bytes,
        });
    }
    if !exported.is_empty() {
        out.summary.insert("export".into(), Value::Array(exported));
    }
    Ok(out)
}
