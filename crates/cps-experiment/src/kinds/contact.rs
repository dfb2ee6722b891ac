//! `kind = "contact"`: a movement that touches, on a Franka in torque mode
//! ([`cps_drive::contact::run_contact`]): approach a surface until contact, press along the
//! force profile of `[contact]` while following its path on the surface, release, lift
//! off. Declares the summary (force error while pressing, peak force, path error, how it
//! ended, the loop's timing), the `contact` table (every tick), the force figure (desired
//! and estimated over time) and the path figure.

use serde::Serialize;

use super::Ctx;
use crate::{ExperimentError, InputError};
use cps_drive::contact::{ContactEnding, ContactOutcome, Stage, contact_on_robot};
use cps_outcome::outcome::{
    Column, Figure, Format, Outcome, Panels, Plot, Report, ReportTable, Series, Table,
};

#[derive(Serialize)]
struct Summary {
    ending: String,
    host: String,
    drive: &'static str,
    profile: String,
    profile_duration_s: f64,
    /// When and where contact was sensed (s from the start; m, base frame).
    contact_time_s: Option<f64>,
    contact_point_m: Option<[f64; 3]>,
    /// While pressing: RMS of the estimated force − the desired force along the direction.
    force_rms_error_n: f64,
    /// The largest estimated force along the direction.
    peak_force_n: f64,
    /// While pressing: RMS distance of the tool from its target across the direction.
    path_rms_error_mm: f64,
    duration_s: f64,
    samples: usize,
    loop_median_us: f64,
    loop_p99_us: f64,
    missed_ticks: u64,
    /// Cycles the robot went without a command from cps (missed, stale or dropped: it
    /// reused the torques before).
    extrapolated_cycles: u64,
    torque_commands_limited: usize,
}

/// Runs the contact task on the experiment's Franka.
pub(crate) fn run(
    ctx: &Ctx<'_>,
    spec: &crate::sections::contact::ContactSpec,
) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let Some(choice) = exp.robot.as_ref() else {
        return Err(
            InputError("kind = \"contact\" needs a [robot] that takes torques".into()).into(),
        );
    };
    let robot = choice.torque_robot(spec.drive)?;
    let host = &robot.host;
    let plan = &spec.plan;
    let out = contact_on_robot(&robot, plan, ctx.stop)?;
    let stopped = ctx.stop.is_stopped();
    let (force_rms, peak, path_rms) = out.measures(plan.direction);
    let t = &out.report.timing;
    let summary = Summary {
        ending: format!(
            "{}; {}",
            out.ending.sentence(),
            out.report.ending.sentence()
        ),
        host: host.clone(),
        drive: spec.drive.name(),
        profile: spec.profile.clone(),
        profile_duration_s: plan.primitive.duration(),
        contact_time_s: out.contact.map(|c| c.0),
        contact_point_m: out.contact.map(|c| c.1),
        force_rms_error_n: force_rms,
        peak_force_n: peak,
        path_rms_error_mm: path_rms * 1e3,
        duration_s: out.report.samples.last().map_or(0.0, |s| s.t),
        samples: out.report.samples.len(),
        loop_median_us: t.median_us,
        loop_p99_us: t.p99_us,
        missed_ticks: t.missed,
        extrapolated_cycles: out.report.reference.extrapolated,
        torque_commands_limited: out.report.limited.commands,
    };
    let mut header = ctx.header(out.report.ending.complete() && !stopped);
    if !matches!(out.ending, ContactEnding::Done) {
        header.failure = Some(out.ending.sentence());
    }
    let lines = lines(&summary);
    let report = Report {
        title: format!("{}: a contact task on {host}", exp.name),
        context: format!(
            "The tool approached the surface from {:?} along {:?} until cps's estimate of the contact force exceeded {} N, followed the force profile ({}) on it with the phase slowed by the force error, let go and lifted off. The force is cps's estimate from the measured joint torques (a momentum observer on the robot's own model).",
            plan.above, plan.direction, plan.detect, spec.profile
        ),
        tables: vec![ReportTable::pairs(
            "Contact",
            vec![
                ("ending", summary.ending.clone()),
                (
                    "contact",
                    summary.contact_point_m.map_or("none".into(), |p| {
                        format!(
                            "({:.4}, {:.4}, {:.4}) m at {:.3} s",
                            p[0],
                            p[1],
                            p[2],
                            summary.contact_time_s.unwrap_or(0.0)
                        )
                    }),
                ),
                (
                    "force error while pressing (RMS)",
                    format!("{:.2} N", summary.force_rms_error_n),
                ),
                ("peak force", format!("{:.1} N", summary.peak_force_n)),
                (
                    "path error while pressing (RMS)",
                    format!("{:.1} mm", summary.path_rms_error_mm),
                ),
                (
                    "loop",
                    format!(
                        "median {:.1} us, p99 {:.1} us, {} ticks missed; {}",
                        t.median_us,
                        t.p99_us,
                        t.missed,
                        out.report.cycles().sentence()
                    ),
                ),
            ],
        )],
    };
    let mut fields = serde_json::Map::new();
    fields.insert(
        "contact".into(),
        serde_json::to_value(&summary).map_err(|e| ExperimentError::Message(e.to_string()))?,
    );
    Ok(Outcome {
        header,
        summary: fields,
        tables: vec![table(&out)],
        figures: figures(&out),
        documents: Vec::new(),
        report,
        lines,
    })
}

fn lines(s: &Summary) -> Vec<String> {
    let mut l = vec![format!("  {}: {}", s.host, s.ending)];
    if let (Some(t), Some(p)) = (s.contact_time_s, s.contact_point_m) {
        l.push(format!(
            "  contact at ({:.4}, {:.4}, {:.4}) m, {t:.3} s in",
            p[0], p[1], p[2]
        ));
    }
    l.push(format!(
        "  while pressing: force error {:.2} N RMS, path error {:.1} mm RMS; peak force {:.1} N",
        s.force_rms_error_n, s.path_rms_error_mm, s.peak_force_n
    ));
    l.push(format!(
        "  {} samples over {:.3} s; loop median {:.1} us, p99 {:.1} us, {} ticks missed, {} cycles without a command, {} torque commands limited",
        s.samples,
        s.duration_s,
        s.loop_median_us,
        s.loop_p99_us,
        s.missed_ticks,
        s.extrapolated_cycles,
        s.torque_commands_limited
    ));
    l
}

/// Every tick: `t, id` (the robot state's message id), `stage, target_x..z, tool_x..z,
/// force_x..z` (cps's estimate), `robot_force_x..z` (the robot's), `pressing, desired, phase`.
fn table(out: &ContactOutcome) -> Table {
    let k = &out.ticks;
    let num = |name: &str, f: &dyn Fn(&cps_drive::contact::ContactTick) -> f64| {
        Column::numbers(name, k.iter().map(f).collect(), Format::Plain)
    };
    let mut t = Table::new("contact")
        .with(num("t", &|x| x.t))
        .with(Column::integers("id", k.iter().map(|x| x.id).collect()))
        .with(Column::texts(
            "stage",
            k.iter().map(|x| x.stage.name().to_string()).collect(),
        ));
    for (d, axis) in ["x", "y", "z"].iter().enumerate() {
        t.push(num(&format!("target_{axis}"), &|x| x.target[d]));
    }
    for (d, axis) in ["x", "y", "z"].iter().enumerate() {
        t.push(num(&format!("tool_{axis}"), &|x| x.tool[d]));
    }
    for (d, axis) in ["x", "y", "z"].iter().enumerate() {
        t.push(num(&format!("force_{axis}"), &|x| x.force[d]));
    }
    for (d, axis) in ["x", "y", "z"].iter().enumerate() {
        t.push(num(&format!("robot_force_{axis}"), &|x| x.robot_force[d]));
    }
    t.push(num("pressing", &|x| x.pressing));
    t.push(num("desired", &|x| x.desired));
    t.push(num("phase", &|x| x.phase));
    t
}

fn figures(out: &ContactOutcome) -> Vec<Figure> {
    // Every fifth tick: 200 points a second are plenty for a figure.
    let picked: Vec<_> = out.ticks.iter().step_by(5).collect();
    let times: Vec<f64> = picked.iter().map(|k| k.t).collect();
    let series = |label: &str, f: &dyn Fn(&cps_drive::contact::ContactTick) -> f64| {
        Series::new(
            label,
            times.clone(),
            vec![picked.iter().map(|k| f(k)).collect()],
        )
    };
    let force = Figure {
        name: "force".into(),
        caption: "The force along the pressing direction: desired (the profile, slowed by the force error) and estimated from the joint torques.".into(),
        plot: Plot::Panels(Panels::new(
            vec!["force [N]".into()],
            vec![series("desired", &|k| k.desired), series("estimated", &|k| k.pressing)],
        )),
    };
    let pressing: Vec<_> = out
        .ticks
        .iter()
        .filter(|k| k.stage == Stage::Press)
        .step_by(5)
        .collect();
    let ptimes: Vec<f64> = pressing.iter().map(|k| k.t).collect();
    let xyz = |f: &dyn Fn(&cps_drive::contact::ContactTick) -> [f64; 3]| -> Vec<Vec<f64>> {
        (0..3)
            .map(|d| pressing.iter().map(|k| f(k)[d]).collect())
            .collect()
    };
    let path = Figure {
        name: "path".into(),
        caption: "The tool's position while pressing: its target (the profile's path from the point of contact) and where the tool was.".into(),
        plot: Plot::Panels(Panels::new(
            vec!["x [m]".into(), "y [m]".into(), "z [m]".into()],
            vec![
                Series::new("target", ptimes.clone(), xyz(&|k| k.target)),
                Series::new("tool", ptimes.clone(), xyz(&|k| k.tool)),
            ],
        )),
    };
    vec![force, path]
}
