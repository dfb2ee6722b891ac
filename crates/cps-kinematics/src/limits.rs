//! A robot's motion limits beyond its joint range and speed (which [`SerialChain`] keeps),
//! and checking a joint trajectory against all of them as a controller sees it.
//!
//! The check takes positions commanded at the control rate (every `dt` seconds) and
//! derives velocity, acceleration and jerk by backward differences of consecutive
//! commands, as a controller that receives positions does (libfranka's convention for
//! its limit checks), with the robot at rest before the first command and the last one
//! held afterwards (so starting and stopping are checked too). Torques come from inverse
//! dynamics at each command with those derivatives, torque rates from their backward
//! differences. A run of consecutive samples beyond a limit is one violation, reported at
//! its worst sample. A position counts as beyond its bound when it passes it by more than
//! [`POSITION_TOLERANCE`].

use nalgebra::Vector3;

use crate::{KinematicsError, LinkInertia, SerialChain};

mod stream;

pub use stream::{
    Excess, Held, JointBounds, Joints, Judged, OUTSIDE_SLACK, StreamBounds, StreamCheck,
    TorqueCheck, beyond_allowed,
};

/// How far (rad) a position may pass its bound before it counts as a violation: rounding
/// in the interpolation of a path that runs along a bound, far below any encoder's
/// resolution.
pub const POSITION_TOLERANCE: f64 = 1e-12;

/// A limited quantity of a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Quantity {
    /// Joint position (rad), within `[lower, upper]`.
    Position,
    /// Joint velocity (rad/s).
    Velocity,
    /// Joint acceleration (rad/s²).
    Acceleration,
    /// Joint jerk (rad/s³).
    Jerk,
    /// Joint torque (N m).
    Torque,
    /// Rate of change of the joint torque (N m/s).
    TorqueRate,
}

impl Quantity {
    /// Every quantity, in order.
    pub const ALL: [Quantity; 6] = [
        Quantity::Position,
        Quantity::Velocity,
        Quantity::Acceleration,
        Quantity::Jerk,
        Quantity::Torque,
        Quantity::TorqueRate,
    ];

    /// `position`, `velocity`, `acceleration`, `jerk`, `torque`, `torque_rate`.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Position => "position",
            Quantity::Velocity => "velocity",
            Quantity::Acceleration => "acceleration",
            Quantity::Jerk => "jerk",
            Quantity::Torque => "torque",
            Quantity::TorqueRate => "torque_rate",
        }
    }

    /// The SI unit.
    pub fn unit(self) -> &'static str {
        match self {
            Quantity::Position => "rad",
            Quantity::Velocity => "rad/s",
            Quantity::Acceleration => "rad/s²",
            Quantity::Jerk => "rad/s³",
            Quantity::Torque => "N m",
            Quantity::TorqueRate => "N m/s",
        }
    }
}

/// Symmetric per-joint bounds `|x| ≤ max` of the quantities beyond position and velocity;
/// `None` where the robot's data do not give them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointLimits {
    /// rad/s² per joint.
    pub acceleration: Option<Vec<f64>>,
    /// rad/s³ per joint.
    pub jerk: Option<Vec<f64>>,
    /// N m per joint.
    pub torque: Option<Vec<f64>>,
    /// N m/s per joint.
    pub torque_rate: Option<Vec<f64>>,
}

impl JointLimits {
    /// Checks that every given limit has one finite, positive value per joint.
    pub fn validate(&self, dof: usize) -> Result<(), KinematicsError> {
        for (q, v) in [
            (Quantity::Acceleration, &self.acceleration),
            (Quantity::Jerk, &self.jerk),
            (Quantity::Torque, &self.torque),
            (Quantity::TorqueRate, &self.torque_rate),
        ] {
            let Some(v) = v else { continue };
            if v.len() != dof {
                return Err(KinematicsError::InvalidModel(format!(
                    "{} limits have {} values for {dof} joints",
                    q.name(),
                    v.len()
                )));
            }
            if let Some(i) = v.iter().position(|x| !(x.is_finite() && *x > 0.0)) {
                return Err(KinematicsError::InvalidModel(format!(
                    "joint {}: the {} limit must be finite and > 0 (got {})",
                    i + 1,
                    q.name(),
                    v[i]
                )));
            }
        }
        Ok(())
    }
}

/// Limits of the tool's and the elbow's motion in Cartesian space: the largest norms of
/// velocity, acceleration and jerk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CartesianLimits {
    /// Translation of the tool point: m/s, m/s², m/s³.
    pub translation: [f64; 3],
    /// Rotation of the tool: rad/s, rad/s², rad/s³.
    pub rotation: [f64; 3],
    /// The elbow (Franka's redundancy parameter, joint 3's angle): rad/s, rad/s², rad/s³.
    pub elbow: [f64; 3],
}

/// A run of samples beyond one limit, at its worst sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Violation {
    /// 1-based joint number.
    pub joint: usize,
    /// What is beyond its limit.
    pub quantity: Quantity,
    /// Time of the worst sample (s).
    pub time: f64,
    /// Its value (signed; for positions the position itself).
    pub value: f64,
    /// The limit it exceeds (for positions the bound crossed).
    pub limit: f64,
}

/// The outcome of [`check_joint_trajectory`].
#[derive(Debug, Clone, PartialEq)]
pub struct LimitCheck {
    /// Per quantity checked, per joint: the peak usage in percent (100 = at the limit;
    /// for positions, how far from the middle of the range towards a bound).
    pub peak_usage: Vec<(Quantity, Vec<f64>)>,
    /// Every violation, in time order.
    pub violations: Vec<Violation>,
    /// Quantities that could not be checked, with the reason (a limit or the inertias
    /// missing from the robot's data).
    pub not_checked: Vec<(Quantity, String)>,
}

impl LimitCheck {
    /// Whether every checked limit holds.
    pub fn ok(&self) -> bool {
        self.violations.is_empty()
    }
}

/// The worst sample of a run beyond a limit: excess, command index, value, bound.
type Run = (f64, usize, f64, f64);

/// Per quantity and joint: the peak usage (fraction) and the run beyond the limit under
/// way, closed into violations as the commands go.
struct Runs {
    n: usize,
    t0: f64,
    dt: f64,
    usage: Vec<f64>,
    open: Vec<Option<Run>>,
    violations: Vec<Violation>,
}

impl Runs {
    fn new(n: usize, t0: f64, dt: f64) -> Self {
        Runs {
            n,
            t0,
            dt,
            usage: vec![0.0; Quantity::ALL.len() * n],
            open: vec![None; Quantity::ALL.len() * n],
            violations: Vec::new(),
        }
    }

    /// Notes command `k`'s value `judged`.
    fn note(&mut self, k: usize, judged: Judged) {
        let Held::Quantity(quantity) = judged.held else {
            return;
        };
        let joint = judged.joint - 1;
        let slot = quantity as usize * self.n + joint;
        self.usage[slot] = self.usage[slot].max(100.0 * judged.usage());
        let excess = judged.excess;
        if excess > 0.0 && self.open[slot].is_none_or(|r| excess > r.0) {
            self.open[slot] = Some((excess, k, judged.value, judged.bound));
        }
        // A run ends at the first sample back within the limit.
        if excess <= 0.0 {
            self.close(slot);
        }
    }

    fn close(&mut self, slot: usize) {
        if let Some((_, k0, value, limit)) = self.open[slot].take() {
            self.violations.push(Violation {
                joint: slot % self.n + 1,
                quantity: Quantity::ALL[slot / self.n],
                time: self.t0 + k0 as f64 * self.dt,
                value,
                limit,
            });
        }
    }
}

/// Checks joint positions `q` (one row of `chain.dof()` values per command, the first at
/// time `t0`, then every `dt` seconds) against the chain's position and speed limits,
/// `limits`, and — with `inertia` — the torque limits through inverse dynamics with
/// `gravity`. See the module documentation for how the derivatives are taken: the
/// commands go through [`StreamCheck::measure`] and [`TorqueCheck`], the checks every
/// command stream gets.
pub fn check_joint_trajectory(
    chain: &SerialChain,
    limits: &JointLimits,
    inertia: Option<&[LinkInertia]>,
    gravity: Vector3<f64>,
    t0: f64,
    dt: f64,
    q: &[Vec<f64>],
) -> Result<LimitCheck, KinematicsError> {
    let n = chain.dof();
    limits.validate(n)?;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(KinematicsError::InvalidModel(format!(
            "the control period must be finite and > 0 (got {dt})"
        )));
    }
    let Some(last) = q.last() else {
        return Err(KinematicsError::InvalidModel(
            "the trajectory has no samples".into(),
        ));
    };
    for row in q {
        chain.check(row)?;
    }
    let robot = RobotLimits {
        chain,
        limits,
        inertia,
        gravity,
        cartesian: None,
    };
    // At rest at the first command, the last one held for three periods after it.
    let bounds = JointBounds::of(chain, limits, &q[0]);
    let mut stream = StreamCheck::at_rest(bounds, q[0].clone(), dt);
    let mut torques = TorqueCheck::default();
    let mut runs = Runs::new(n, t0, dt);
    let held = q.iter().chain(std::iter::repeat_n(last, 3));
    for (k, row) in held.enumerate() {
        stream.measure(row, |j| runs.note(k, j));
        let (_, v, a) = stream.last();
        let tau = torques.judge(&robot, dt, (row, v, a), |j| {
            runs.note(k, j);
            true
        })?;
        torques.take(tau);
    }
    for slot in 0..runs.open.len() {
        runs.close(slot);
    }
    let mut peak_usage = Vec::new();
    let mut not_checked = Vec::new();
    let velocity = chain.velocity_limits().is_some();
    for quantity in Quantity::ALL {
        let given = match quantity {
            Quantity::Position => chain.limits().is_some(),
            Quantity::Velocity => velocity,
            Quantity::Acceleration => limits.acceleration.is_some(),
            Quantity::Jerk => limits.jerk.is_some(),
            Quantity::Torque => limits.torque.is_some(),
            Quantity::TorqueRate => limits.torque_rate.is_some(),
        };
        let torque = matches!(quantity, Quantity::Torque | Quantity::TorqueRate);
        if !given {
            let reason = match quantity {
                Quantity::Position => "the robot has no joint position limits".to_string(),
                _ => format!("the robot has no {} limits", quantity.name()),
            };
            not_checked.push((quantity, reason));
        } else if torque && inertia.is_none() {
            not_checked.push((
                quantity,
                "the robot's link inertias are not known, so torques cannot be computed".into(),
            ));
        } else {
            let slot = quantity as usize * n;
            peak_usage.push((quantity, runs.usage[slot..slot + n].to_vec()));
        }
    }
    let mut violations = runs.violations;
    violations.sort_by(|a, b| {
        a.time
            .total_cmp(&b.time)
            .then(a.joint.cmp(&b.joint))
            .then(a.quantity.cmp(&b.quantity))
    });
    Ok(LimitCheck {
        peak_usage,
        violations,
        not_checked,
    })
}

/// The Cartesian quantities [`check_cartesian`] looks at, in order: the tool point's
/// translation, the tool's rotation and the elbow (joint 3), each as velocity,
/// acceleration and jerk.
pub const CARTESIAN_QUANTITIES: [&str; 9] = [
    "translation_velocity",
    "translation_acceleration",
    "translation_jerk",
    "rotation_velocity",
    "rotation_acceleration",
    "rotation_jerk",
    "elbow_velocity",
    "elbow_acceleration",
    "elbow_jerk",
];

/// A run of commands beyond one Cartesian limit, at its worst command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CartesianViolation {
    /// One of [`CARTESIAN_QUANTITIES`].
    pub quantity: &'static str,
    /// Time of the worst command (s).
    pub time: f64,
    /// Its magnitude (m/s…, rad/s…).
    pub value: f64,
    /// The limit.
    pub limit: f64,
}

/// The outcome of [`check_cartesian`].
#[derive(Debug, Clone, PartialEq)]
pub struct CartesianCheck {
    /// Per quantity (in the order of [`CARTESIAN_QUANTITIES`]), its peak in percent of
    /// the limit.
    pub peak_usage: Vec<(&'static str, f64)>,
    /// Every violation, in time order.
    pub violations: Vec<CartesianViolation>,
}

/// Backward differences of vectors, from zero (at rest before the first).
fn vector_differences(x: &[Vector3<f64>], dt: f64) -> Vec<Vector3<f64>> {
    let mut prev = Vector3::zeros();
    x.iter()
        .map(|v| {
            let d = (v - prev) / dt;
            prev = *v;
            d
        })
        .collect()
}

/// Checks the tool's Cartesian motion under the joint commands `q` (as
/// [`check_joint_trajectory`] takes them: from `t0` every `dt`, at rest before, the last
/// held for three periods): the tool point's translation speed, acceleration and jerk
/// (norms of backward differences of its position), the same of its rotation (the
/// rotation between consecutive commands as a rotation vector over `dt`) and of the elbow
/// (joint 3's angle, Franka's redundancy parameter), against `limits`.
pub fn check_cartesian(
    chain: &SerialChain,
    limits: &CartesianLimits,
    t0: f64,
    dt: f64,
    q: &[Vec<f64>],
) -> Result<CartesianCheck, KinematicsError> {
    let Some(last) = q.last() else {
        return Err(KinematicsError::InvalidModel(
            "the trajectory has no samples".into(),
        ));
    };
    let mut held = q.to_vec();
    held.extend(std::iter::repeat_n(last.clone(), 3));
    let poses = held
        .iter()
        .map(|q| chain.fk(q))
        .collect::<Result<Vec<_>, _>>()?;
    let p0 = poses[0].translation.vector;
    let v: Vec<Vector3<f64>> = poses
        .iter()
        .scan(p0, |prev, pose| {
            let p = pose.translation.vector;
            let d = (p - *prev) / dt;
            *prev = p;
            Some(d)
        })
        .collect();
    let r0 = poses[0].rotation;
    let w: Vec<Vector3<f64>> = poses
        .iter()
        .scan(r0, |prev, pose| {
            let turn = pose.rotation * prev.inverse();
            *prev = pose.rotation;
            Some(turn.scaled_axis() / dt)
        })
        .collect();
    let elbow: Vec<Vector3<f64>> = if chain.dof() >= 3 {
        held.iter()
            .scan(held[0][2], |prev, q| {
                let d = (q[2] - *prev) / dt;
                *prev = q[2];
                Some(Vector3::new(d, 0.0, 0.0))
            })
            .collect()
    } else {
        Vec::new()
    };
    let mut series: Vec<(&'static str, Vec<f64>, f64)> = Vec::new();
    let groups = [
        (&v, limits.translation),
        (&w, limits.rotation),
        (&elbow, limits.elbow),
    ];
    for (g, (first, lim)) in groups.iter().enumerate() {
        if first.is_empty() {
            continue;
        }
        let second = vector_differences(first, dt);
        let third = vector_differences(&second, dt);
        for (k, values) in [*first, &second, &third].into_iter().enumerate() {
            series.push((
                CARTESIAN_QUANTITIES[3 * g + k],
                values.iter().map(|x| x.norm()).collect(),
                lim[k],
            ));
        }
    }
    let mut peak_usage = Vec::new();
    let mut violations = Vec::new();
    for (name, values, limit) in series {
        let mut peak = 0.0_f64;
        let mut run: Option<(usize, f64)> = None;
        for (k, &x) in values.iter().enumerate() {
            peak = peak.max(100.0 * x / limit);
            if x > limit && run.is_none_or(|r| x > r.1) {
                run = Some((k, x));
            }
            if (x <= limit || k + 1 == values.len())
                && let Some((k0, value)) = run.take()
            {
                violations.push(CartesianViolation {
                    quantity: name,
                    time: t0 + k0 as f64 * dt,
                    value,
                    limit,
                });
            }
        }
        peak_usage.push((name, peak));
    }
    violations.sort_by(|a, b| a.time.total_cmp(&b.time));
    Ok(CartesianCheck {
        peak_usage,
        violations,
    })
}

/// A robot's limits and, for torques, its dynamics: what a trajectory is checked and
/// retimed against.
#[derive(Debug, Clone, Copy)]
pub struct RobotLimits<'a> {
    /// Kinematics, position range and velocity limits.
    pub chain: &'a SerialChain,
    /// Acceleration, jerk, torque and torque-rate limits.
    pub limits: &'a JointLimits,
    /// Link inertias (torques are not limited without them).
    pub inertia: Option<&'a [LinkInertia]>,
    /// Gravity in the world frame.
    pub gravity: Vector3<f64>,
    /// Limits of the tool's Cartesian motion and the elbow's, if any.
    pub cartesian: Option<&'a CartesianLimits>,
}

/// Commands checked against every limit of a robot: the joints' and, when the robot has
/// them, the Cartesian ones.
#[derive(Debug, Clone, PartialEq)]
pub struct CommandCheck {
    /// Joint positions, velocities, accelerations, jerks, torques and torque rates.
    pub joints: LimitCheck,
    /// The tool's translation and rotation and the elbow.
    pub cartesian: Option<CartesianCheck>,
}

impl CommandCheck {
    /// Whether every checked limit holds.
    pub fn ok(&self) -> bool {
        self.violation_count() == 0
    }

    /// Joint and Cartesian violations together.
    pub fn violation_count(&self) -> usize {
        self.joints.violations.len() + self.cartesian.as_ref().map_or(0, |c| c.violations.len())
    }
}

/// Checks commands `q` (from `t0`, every `dt`) against every limit of `robot`
/// ([`check_joint_trajectory`] and, with Cartesian limits, [`check_cartesian`]).
pub fn check_commands(
    robot: &RobotLimits,
    t0: f64,
    dt: f64,
    q: &[Vec<f64>],
) -> Result<CommandCheck, KinematicsError> {
    let joints = check_joint_trajectory(
        robot.chain,
        robot.limits,
        robot.inertia,
        robot.gravity,
        t0,
        dt,
        q,
    )?;
    let cartesian = match robot.cartesian {
        Some(c) => Some(check_cartesian(robot.chain, c, t0, dt, q)?),
        None => None,
    };
    Ok(CommandCheck { joints, cartesian })
}
