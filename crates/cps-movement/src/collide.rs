//! A joint trajectory file against a robot's shapes and its scene's (`cps-cli collide`):
//! the check the guard makes before it sends a plan, run by a user on a file first.
//!
//! The file is read as `cps-cli limits check` reads it ([`crate::limits`]) and judged
//! twice: at the control rate, as the robot will receive it (the guard's check, the
//! verdict: a pair closer than the margin is a collision), and row by row, every pair
//! closer than [`REPORT_DISTANCE`] listed with its signed distance — links by their URDF
//! names, obstacles by their scene names, negative where two overlap (the depth).

use std::path::Path;
use std::sync::Arc;

use serde_json::{Value, json};

use crate::limits::{JointTrajectory, at_rate, check_rate, read_joint_trajectory};
use crate::robot_file::RobotModel;
use cps_outcome::InputError;

/// The distance (m) within which a row's pairs are listed.
pub const REPORT_DISTANCE: f64 = 0.10;

/// Two shapes and their signed distance at one configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct PairDistance {
    /// A link's name.
    pub first: String,
    /// Another link's name, or an obstacle's.
    pub second: String,
    /// Their signed distance (m; negative: overlapping, the depth).
    pub distance: f64,
}

/// Every pair of `robot`'s links (and a link and an obstacle) closer than `within` (m) at
/// `q`, closest first, each pair once at its closest shapes. Errors:
/// the robot has no shapes, `q` is not one of its configurations.
pub fn distances(
    robot: &RobotModel,
    q: &[f64],
    within: f64,
) -> Result<Vec<PairDistance>, InputError> {
    let shapes = shapes_of(robot)?;
    let mut frames = Vec::with_capacity(q.len() + 1);
    robot
        .chain
        .frames_into(q, &mut frames)
        .map_err(|e| InputError(e.to_string()))?;
    let model = shapes.model();
    // A link of several shapes (a finger's boxes) counts once per pair: its closest.
    let mut out: Vec<PairDistance> = Vec::new();
    for c in model.within(&frames, within) {
        let (a, b) = model.pair_names(c.pair);
        if !out.iter().any(|p| p.first == a && p.second == b) {
            out.push(PairDistance {
                first: a.to_string(),
                second: b.to_string(),
                distance: c.separation.distance,
            });
        }
    }
    Ok(out)
}

fn shapes_of(robot: &RobotModel) -> Result<&Arc<cps_robot::Shapes>, InputError> {
    robot.shapes.as_ref().ok_or_else(|| {
        InputError(format!(
            "the robot `{}` has no collision geometry: there is nothing to check (a URDF with <collision> elements, or a built-in Franka: fr3, panda)",
            robot.name
        ))
    })
}

/// A checked trajectory.
#[derive(Debug, Clone)]
pub struct CollideReport {
    /// The clearance kept (m).
    pub margin: f64,
    /// The robot's bodies, the scene's obstacles, and the pairs checked.
    pub counts: [usize; 3],
    /// The control rate (Hz) of the guard's check.
    pub rate: f64,
    /// The first collision at the control rate (None: every pair keeps the margin).
    pub collision: Option<cps_robot::Collision>,
    /// Per row of the file: its time and every pair within [`REPORT_DISTANCE`].
    pub rows: Vec<(f64, Vec<PairDistance>)>,
}

/// Checks a trajectory in memory against `robot`'s shapes at `rate` Hz, and lists each
/// row's near pairs.
pub fn check_samples(
    robot: &RobotModel,
    traj: &JointTrajectory,
    rate: f64,
) -> Result<CollideReport, InputError> {
    let shapes = shapes_of(robot)?;
    let collision = first_collision(robot, traj, rate)?;
    let rows = traj
        .times
        .iter()
        .zip(&traj.q)
        .map(|(&t, q)| Ok((t, distances(robot, q, REPORT_DISTANCE)?)))
        .collect::<Result<_, InputError>>()?;
    Ok(CollideReport {
        margin: shapes.margin(),
        counts: [
            shapes.bodies().len(),
            shapes.obstacles().len(),
            shapes.model().pair_count(),
        ],
        rate,
        collision,
        rows,
    })
}

/// The guard's verdict on a trajectory in memory: its first collision with `robot`'s
/// shapes at `rate` Hz (None: every pair keeps the margin; an error for a robot without
/// shapes).
pub fn first_collision(
    robot: &RobotModel,
    traj: &JointTrajectory,
    rate: f64,
) -> Result<Option<cps_robot::Collision>, InputError> {
    let shapes = shapes_of(robot)?;
    let (t0, dt, commands, _) = at_rate(traj, rate)?;
    let plan = cps_robot::Plan::new(dt, commands).map_err(|e| InputError(e.to_string()))?;
    Ok(cps_robot::check_shapes(shapes, &robot.chain, &plan, dt)
        .map_err(|e| InputError(e.to_string()))?
        .map(|mut c| {
            c.time += t0;
            c
        }))
}

/// Checks a joint trajectory file against `robot`'s shapes at `rate` Hz, keeping `margin`
/// (m) when given (`--margin`) instead of the robot's.
pub fn check_file(
    path: &Path,
    robot: &RobotModel,
    rate: f64,
    margin: Option<f64>,
) -> Result<CollideReport, InputError> {
    check_rate(rate)?;
    let kept;
    let robot = match margin {
        Some(m) => {
            kept = robot
                .with_margin(m)
                .map_err(|e| InputError(format!("--margin: {e}")))?;
            &kept
        }
        None => robot,
    };
    let traj = read_joint_trajectory(path, robot.chain.dof())?;
    check_samples(robot, &traj, rate).map_err(|e| InputError(format!("{}: {e}", path.display())))
}

impl CollideReport {
    /// Whether every pair keeps the margin at the control rate.
    pub fn ok(&self) -> bool {
        self.collision.is_none()
    }

    /// The row with the closest pair (its index, time and pair), if any pair came within
    /// [`REPORT_DISTANCE`].
    pub fn closest(&self) -> Option<(usize, f64, &PairDistance)> {
        self.rows
            .iter()
            .enumerate()
            .filter_map(|(i, (t, pairs))| pairs.first().map(|p| (i, *t, p)))
            .min_by(|a, b| a.2.distance.total_cmp(&b.2.distance))
    }

    /// `{"ok", "margin_m", "rate_hz", "bodies", "obstacles", "pairs_checked", "collision":
    /// {"first", "second", "time", "distance"} | null, "closest": {"row", "time", "first",
    /// "second", "distance"} | null, "rows": [{"row", "time", "pairs": [{"first", "second",
    /// "distance"}]}]}`: rows counted from 1 after the header, distances in metres.
    pub fn json(&self) -> Value {
        let pair = |p: &PairDistance| json!({"first": p.first, "second": p.second, "distance": p.distance});
        json!({
            "ok": self.ok(),
            "margin_m": self.margin,
            "rate_hz": self.rate,
            "bodies": self.counts[0],
            "obstacles": self.counts[1],
            "pairs_checked": self.counts[2],
            "collision": self.collision.as_ref().map(|c| json!({
                "first": c.first, "second": c.second, "time": c.time, "distance": c.distance,
                "sentence": c.to_string(),
            })),
            "closest": self.closest().map(|(i, t, p)| json!({
                "row": i + 1, "time": t, "first": p.first, "second": p.second, "distance": p.distance,
            })),
            "rows": self.rows.iter().enumerate().map(|(i, (t, pairs))| json!({
                "row": i + 1, "time": t, "pairs": pairs.iter().map(pair).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        })
    }

    /// The report in words, a line each: what was checked, the closest pair, the verdict.
    pub fn lines(&self) -> Vec<String> {
        let [bodies, obstacles, pairs] = self.counts;
        let mut lines = vec![format!(
            "{bodies} bodies, {obstacles} obstacles, {pairs} pairs checked at {} Hz, margin {:.1} mm",
            self.rate,
            1e3 * self.margin
        )];
        lines.push(match self.closest() {
            Some((i, t, p)) => format!(
                "closest: `{}` and `{}`, {:.1} mm {} at row {} (t = {t:.3} s)",
                p.first,
                p.second,
                1e3 * p.distance.abs(),
                if p.distance < 0.0 { "deep" } else { "apart" },
                i + 1,
            ),
            None => format!(
                "closest: no pair within {:.0} mm at any row",
                1e3 * REPORT_DISTANCE
            ),
        });
        lines.push(match &self.collision {
            Some(c) => format!("COLLISION: {c}"),
            None => format!("ok: every pair keeps {:.1} mm", 1e3 * self.margin),
        });
        lines
    }
}

says_itself_by_json_and_lines!(CollideReport);
