//! A collision-free path between two configurations (`cps-cli plan`): [`cps_plan::plan`]
//! on a robot's model (its own shapes, and its scene's when it comes from a scene), as a
//! report that says itself in words and as JSON, and the timed motion as a trajectory
//! table (`t`, then one column per joint, every control period). Movements joined by
//! planned transitions (`cps-cli plan --join`): [`cps_plan::join`] on trajectory files, as
//! a [`JoinReport`].

use std::path::{Path, PathBuf};

use cps_outcome::InputError;

use crate::limits::JointTrajectory;
use cps_outcome::outcome::{Column, Format, Table};
pub use cps_plan::{End, JoinError, Joined, Part, PlanError, Planned, Settings, reach};
use cps_robot::Plan;
use serde_json::{Value, json};

use crate::robot_file::RobotModel;

/// What `cps-cli plan` found.
#[derive(Debug, Clone)]
pub struct PlanReport {
    /// The robot's name.
    pub robot: String,
    /// The clearance margin every pair keeps (m; None: the robot has no shapes).
    pub margin: Option<f64>,
    /// The bodies and obstacles checked, and the pairs.
    pub checked: Option<[usize; 3]>,
    /// The planner's result.
    pub planned: Planned,
    /// The timed motion: `t` and one column per joint.
    pub table: Table,
}

says_itself_by_json_and_lines!(PlanReport);

impl PlanReport {
    /// The report as JSON: `{"robot", "margin_m", "waypoints", "length_rad",
    /// "duration_s", "clearance_m", "samples", "nodes", "measured", "planning_s",
    /// "verifying_s"}`.
    pub fn json(&self) -> Value {
        let p = &self.planned;
        json!({
            "robot": self.robot,
            "margin_m": self.margin,
            "waypoints": p.waypoints,
            "length_rad": p.length,
            "duration_s": p.plan.duration(),
            "clearance_m": p.clearance,
            "samples": p.tried.samples,
            "nodes": p.tried.nodes,
            "measured": p.measured,
            "planning_s": p.planning_seconds,
            "verifying_s": p.verifying_seconds,
        })
    }

    /// The report in words, a line each.
    pub fn lines(&self) -> Vec<String> {
        let p = &self.planned;
        let mut out = vec![checked_line(&self.robot, self.margin, self.checked)];
        let how = if p.tried.samples == 0 {
            "the straight way is free".to_string()
        } else {
            format!(
                "RRT-Connect: {} samples, trees of {} and {} nodes",
                p.tried.samples, p.tried.nodes[0], p.tried.nodes[1]
            )
        };
        out.push(format!(
            "path: {} waypoints, {:.3} rad long ({how}), found in {:.1} ms ({} configurations measured)",
            p.waypoints.len(),
            p.length,
            1e3 * p.planning_seconds,
            p.measured
        ));
        if let Some(c) = p.clearance {
            out.push(format!("clearance: {:.1} mm at the closest", 1e3 * c));
        }
        out.push(format!(
            "timed: {:.3} s at rest at each waypoint, every limit and every pair verified every {:.0} ms as the guard checks ({:.1} ms)",
            p.plan.duration(),
            1e3 * p.plan.dt(),
            1e3 * p.verifying_seconds
        ));
        out
    }
}

/// A path of `robot` from `from` to `to`, planned with `settings` (see [`cps_plan::plan`]).
pub fn plan_report(
    robot: &RobotModel,
    from: &[f64],
    to: &[f64],
    settings: &Settings,
) -> Result<PlanReport, PlanError> {
    let planned = cps_plan::plan(robot, from, to, settings)?;
    let table = motion_table(robot, &planned.plan);
    let shapes = robot.shapes.as_deref();
    Ok(PlanReport {
        robot: robot.name.clone(),
        margin: shapes.map(|s| s.margin()),
        checked: checked(robot),
        planned,
        table,
    })
}

/// The bodies, obstacles and pairs `robot`'s guard checks (None: it has no shapes).
fn checked(robot: &RobotModel) -> Option<[usize; 3]> {
    robot.shapes.as_deref().map(|s| {
        [
            s.bodies().len(),
            s.obstacles().len(),
            s.model().pair_count(),
        ]
    })
}

/// The first line of a report: what is checked, or that nothing is.
fn checked_line(robot: &str, margin: Option<f64>, checked: Option<[usize; 3]>) -> String {
    match (margin, checked) {
        (Some(m), Some([bodies, obstacles, pairs])) => format!(
            "{robot}: {bodies} bodies, {obstacles} obstacle(s), {pairs} pairs kept {:.1} mm apart",
            1e3 * m
        ),
        _ => format!(
            "{robot}: no collision shapes: the straight way, checked against the limits only"
        ),
    }
}

/// A timed motion as a trajectory table: `t`, then one column per joint.
fn motion_table(robot: &RobotModel, plan: &Plan) -> Table {
    let times: Vec<f64> = (0..plan.points().len()).map(|k| plan.time(k)).collect();
    let mut table = Table::new("plan").with(Column::numbers("t", times, Format::Plain));
    for (j, name) in robot.joint_names.iter().enumerate() {
        table.push(Column::numbers(
            name.clone(),
            plan.points().iter().map(|q| q[j]).collect(),
            Format::Plain,
        ));
    }
    table
}

/// A trajectory file (CSV: `t`, then a position per joint) as a movement every `dt`
/// seconds (see [`movement_of`]).
pub fn movement_file(path: &Path, robot: &RobotModel, dt: f64) -> Result<Plan, InputError> {
    let traj = crate::limits::read_joint_trajectory(path, robot.chain.dof())?;
    movement_of(&traj, dt).map_err(|e| InputError(format!("{}: {e}", path.display())))
}

/// A joint trajectory as a movement every `dt` seconds (resampled by a spline through its
/// rows when it is at another rate), from its first row.
pub fn movement_of(traj: &JointTrajectory, dt: f64) -> Result<Plan, InputError> {
    let (_, dt, commands, _) = crate::limits::at_rate(traj, 1.0 / dt)?;
    Plan::new(dt, commands).map_err(|e| InputError(e.to_string()))
}

/// What `cps-cli plan --join` made.
#[derive(Debug, Clone)]
pub struct JoinReport {
    /// The robot's name.
    pub robot: String,
    /// The clearance margin every pair keeps (m; None: the robot has no shapes).
    pub margin: Option<f64>,
    /// The bodies and obstacles checked, and the pairs.
    pub checked: Option<[usize; 3]>,
    /// Where the movements came from, in order: their files (or the arguments they were
    /// given in).
    pub sources: Vec<String>,
    /// The joined motion.
    pub joined: Joined,
    /// The joined motion: `t` and one column per joint.
    pub table: Table,
}

says_itself_by_json_and_lines!(JoinReport);

impl JoinReport {
    /// The report as JSON: `{"robot", "margin_m", "duration_s", "seconds", "stretches":
    /// [{"part": "movement" | "transition", "movement" (1-based, the one led into),
    /// "source" (its file), "start_s", "end_s", and a transition's "waypoints", "length_rad",
    /// "clearance_m", "planning_s"}]}`.
    pub fn json(&self) -> Value {
        let stretches: Vec<Value> = self
            .joined
            .stretches
            .iter()
            .map(|s| {
                let (part, k) = match s.part {
                    Part::Movement(k) => ("movement", k),
                    Part::Transition(k) => ("transition", k),
                };
                let mut v = json!({
                    "part": part,
                    "movement": k + 1,
                    "source": self.sources[k],
                    "start_s": s.start_s,
                    "end_s": s.end_s,
                });
                if let Some(p) = &s.planned {
                    v["waypoints"] = json!(p.waypoints);
                    v["length_rad"] = json!(p.length);
                    v["clearance_m"] = json!(p.clearance);
                    v["planning_s"] = json!(p.planning_seconds);
                }
                v
            })
            .collect();
        json!({
            "robot": self.robot,
            "margin_m": self.margin,
            "duration_s": self.joined.plan.duration(),
            "seconds": self.joined.seconds,
            "stretches": stretches,
        })
    }

    /// The report in words, a line each.
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![checked_line(&self.robot, self.margin, self.checked)];
        for s in &self.joined.stretches {
            let span = format!("{:8.3} – {:8.3} s", s.start_s, s.end_s);
            out.push(match (s.part, &s.planned) {
                (Part::Transition(k), Some(p)) => format!(
                    "{span}  a transition into movement {}: {} waypoints, {:.3} rad{}, found in {:.1} ms",
                    k + 1,
                    p.waypoints.len(),
                    p.length,
                    p.clearance
                        .map_or(String::new(), |c| format!(", {:.1} mm clear", 1e3 * c)),
                    1e3 * p.planning_seconds
                ),
                (Part::Movement(k) | Part::Transition(k), _) => format!(
                    "{span}  movement {} ({})",
                    k + 1,
                    self.sources[k]
                ),
            });
        }
        out.push(format!(
            "joined: {:.3} s, every limit and every pair verified every {:.0} ms as the guard checks ({:.1} ms with the planning)",
            self.joined.plan.duration(),
            1e3 * self.joined.plan.dt(),
            1e3 * self.joined.seconds
        ));
        out
    }
}

/// Why `cps-cli plan --join` made nothing.
#[derive(Debug, thiserror::Error)]
pub enum JoinFailure {
    /// A movement's file could not be read.
    #[error(transparent)]
    File(#[from] InputError),
    /// The movements could not be joined.
    #[error("{error}{}", .source_of.as_ref().map_or(String::new(), |s| format!(" (movement {} is {s})", .error.movement().map_or(0, |k| k + 1))))]
    Join {
        /// Why.
        error: Box<JoinError>,
        /// Where the movement it is at came from.
        source_of: Option<String>,
    },
}

impl JoinFailure {
    /// Whether the input is at fault (exit 2), not the search (exit 1).
    pub fn is_input(&self) -> bool {
        match self {
            JoinFailure::File(_) => true,
            JoinFailure::Join { error, .. } => error.is_input(),
        }
    }
}

/// `files`' movements joined by transitions planned with `settings`, from `from` (None:
/// the first movement's start; see [`join_movements`]). Errors: a file that cannot be
/// read (its sentence), or why the movements cannot be joined, the movement's file named.
pub fn join_report(
    robot: &RobotModel,
    from: Option<&[f64]>,
    files: &[PathBuf],
    settings: &Settings,
) -> Result<JoinReport, JoinFailure> {
    let movements = files
        .iter()
        .map(|f| {
            Ok((
                f.display().to_string(),
                movement_file(f, robot, settings.dt)?,
            ))
        })
        .collect::<Result<Vec<_>, InputError>>()?;
    join_movements(robot, from, movements, settings)
}

/// Movements, each with where it came from, joined by transitions planned with `settings`
/// from `from` (None: the first movement's start; see [`cps_plan::join`]): the report, or
/// why not with the movement's source named.
pub fn join_movements(
    robot: &RobotModel,
    from: Option<&[f64]>,
    movements: Vec<(String, Plan)>,
    settings: &Settings,
) -> Result<JoinReport, JoinFailure> {
    let (sources, plans): (Vec<String>, Vec<Plan>) = movements.into_iter().unzip();
    let joined =
        cps_plan::join(robot, from, &plans, settings).map_err(|error| JoinFailure::Join {
            source_of: error.movement().and_then(|k| sources.get(k)).cloned(),
            error: Box::new(error),
        })?;
    Ok(JoinReport {
        robot: robot.name.clone(),
        margin: robot.shapes.as_deref().map(|s| s.margin()),
        checked: checked(robot),
        sources,
        table: motion_table(robot, &joined.plan),
        joined,
    })
}
