//! How close a learned robot movement comes to the robot's own shapes and its world's,
//! beside the movement it was learned from (blind to shapes): the summary's `clearance`
//! of every kind that learns a robot's movement.

use serde::Serialize;

/// The closest pair of a learned movement and of its start, and the clearance kept.
#[derive(Serialize)]
pub(crate) struct ClearanceSummary {
    /// The clearance learning kept (`[clearance] distance`, m), if any.
    kept_m: Option<f64>,
    /// The clearance between two of the robot's own shapes (`[clearance] self_distance`).
    kept_self_m: Option<f64>,
    /// The learned movement's closest pair (None: none within 10 cm).
    closest: Option<ClosestPair>,
    /// Its closest pair of a robot's shape and an obstacle (None: none within 10 cm).
    closest_to_world: Option<ClosestPair>,
    /// The warm start's (the movement before the clearance was kept).
    warm_start_closest: Option<ClosestPair>,
}

#[derive(Serialize)]
struct ClosestPair {
    first: String,
    second: String,
    time_s: f64,
    distance_m: f64,
}

impl From<cps_learn::Closest> for ClosestPair {
    fn from(c: cps_learn::Closest) -> Self {
        ClosestPair {
            first: c.first,
            second: c.second,
            time_s: c.time,
            distance_m: c.distance,
        }
    }
}

/// The stage that kept a task-space movement clear on the model
/// ([`cps_learn::keep_clear`]), in numbers.
#[derive(Serialize)]
pub(crate) struct KeptClearSummary {
    /// Levenberg–Marquardt's iterations and model executions (0 and 1: already clear).
    pub(crate) iterations: u64,
    evaluations: u64,
    pub(crate) termination: String,
    /// The clearance term on the model before and after.
    pub(crate) clearance_cost: [f64; 2],
    /// The anchor (the kind's own cost, or how far the movement strays) before and after.
    anchor_cost: [f64; 2],
    /// The model's execution's closest pair before and after (None: none within 10 cm).
    closest: [Option<ClosestPair>; 2],
}

impl KeptClearSummary {
    pub(crate) fn new(k: &cps_learn::KeptClear) -> Self {
        KeptClearSummary {
            iterations: k.search.generations,
            evaluations: k.search.evaluations,
            termination: k.search.termination.clone(),
            clearance_cost: k.clearance,
            anchor_cost: k.anchor,
            closest: k.closest.clone().map(|c| c.map(ClosestPair::from)),
        }
    }

    /// In words, for the run's printout: `what` was kept clear.
    pub(crate) fn line(&self, what: &str) -> String {
        let words = |c: &Option<ClosestPair>| match c {
            Some(c) => format!("{:.1} mm", 1e3 * c.distance_m),
            None => "> 100 mm".into(),
        };
        format!(
            "  {what} kept clear on the model: closest pair {} → {}, clearance cost {:.3e} → {:.3e} ({} iterations, {})",
            words(&self.closest[0]),
            words(&self.closest[1]),
            self.clearance_cost[0],
            self.clearance_cost[1],
            self.iterations,
            self.termination
        )
    }
}

/// A joint movement: its sample times and each joint's samples.
pub(crate) struct Joints<'a> {
    times: &'a [f64],
    joints: Vec<Vec<f64>>,
}

impl<'a> Joints<'a> {
    /// A joint-space trajectory's samples.
    pub(crate) fn of_trajectory(t: &'a cps_dmp::Trajectory) -> Self {
        Joints {
            times: t.times(),
            joints: (0..t.dims()).map(|j| t.position(j).to_vec()).collect(),
        }
    }

    /// A recording's joints.
    pub(crate) fn of_recording(r: &'a cps_robot::Recording) -> Self {
        let dof = r.q.first().map_or(0, Vec::len);
        Joints {
            times: &r.time,
            joints: (0..dof)
                .map(|j| r.q.iter().map(|q| q[j]).collect())
                .collect(),
        }
    }
}

impl ClearanceSummary {
    /// Looks at both movements against `shapes` (pairs within 10 cm).
    pub(crate) fn new(
        shapes: &cps_robot::Shapes,
        chain: &cps_kinematics::SerialChain,
        kept: Option<&cps_learn::Clearance>,
        learned: &Joints<'_>,
        warm: &Joints<'_>,
    ) -> Result<Self, cps_kinematics::KinematicsError> {
        let look = |m: &Joints<'_>| {
            cps_learn::closest(shapes, chain, m.times, |j| &m.joints[j], 0.1)
                .map(|c| c.map(ClosestPair::from))
        };
        let world =
            cps_learn::closest_to_world(shapes, chain, learned.times, |j| &learned.joints[j], 0.1)?;
        Ok(ClearanceSummary {
            kept_m: kept.map(|c| c.distance),
            kept_self_m: kept.map(|c| c.self_distance),
            closest: look(learned)?,
            closest_to_world: world.map(ClosestPair::from),
            warm_start_closest: look(warm)?,
        })
    }

    /// In words, for the run's printout.
    pub(crate) fn line(&self) -> String {
        let words = |c: &Option<ClosestPair>| match c {
            Some(c) => format!(
                "`{}` and `{}` {:.1} mm {} at {:.2} s",
                c.first,
                c.second,
                1e3 * c.distance_m.abs(),
                if c.distance_m < 0.0 { "deep" } else { "apart" },
                c.time_s
            ),
            None => "no pair within 100 mm".into(),
        };
        format!(
            "  shapes: closest {}{}; the warm start's {}",
            words(&self.closest),
            self.kept_m
                .map_or(String::new(), |k| format!(" (kept ≥ {:.1} mm)", 1e3 * k)),
            words(&self.warm_start_closest)
        )
    }
}
