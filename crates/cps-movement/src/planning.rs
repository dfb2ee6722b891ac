//! A collision-free path between two configurations (`cps-cli plan`): [`cps_plan::plan`]
//! on a robot's model (its own shapes, and its scene's when it comes from a scene), as a
//! report that says itself in words and as JSON, and the timed motion as a trajectory
//! table (`t`, then one column per joint, every control period).

use cps_outcome::outcome::{Column, Format, Table};
pub use cps_plan::{End, PlanError, Planned, Settings, reach};
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
        let mut out = Vec::new();
        match (self.margin, self.checked) {
            (Some(m), Some([bodies, obstacles, pairs])) => out.push(format!(
                "{}: {bodies} bodies, {obstacles} obstacle(s), {pairs} pairs kept {:.1} mm apart",
                self.robot,
                1e3 * m
            )),
            _ => out.push(format!(
                "{}: no collision shapes: the straight way, checked against the limits only",
                self.robot
            )),
        }
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
    let plan = &planned.plan;
    let times: Vec<f64> = (0..plan.points().len()).map(|k| plan.time(k)).collect();
    let mut table = Table::new("plan").with(Column::numbers("t", times, Format::Plain));
    for (j, name) in robot.joint_names.iter().enumerate() {
        table.push(Column::numbers(
            name.clone(),
            plan.points().iter().map(|q| q[j]).collect(),
            Format::Plain,
        ));
    }
    let shapes = robot.shapes.as_deref();
    Ok(PlanReport {
        robot: robot.name.clone(),
        margin: shapes.map(|s| s.margin()),
        checked: shapes.map(|s| {
            [
                s.bodies().len(),
                s.obstacles().len(),
                s.model().pair_count(),
            ]
        }),
        planned,
        table,
    })
}
