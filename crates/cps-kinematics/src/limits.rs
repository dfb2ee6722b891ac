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
//! its worst sample.

use nalgebra::Vector3;

use crate::{KinematicsError, LinkInertia, SerialChain};

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

/// A quantity's samples (one row per command) and its symmetric limit per joint (`None`
/// for positions, bounded by the chain's range).
type Series = (Quantity, Vec<Vec<f64>>, Option<Vec<f64>>);

/// Backward differences of `x` (one row per sample) with step `dt`, starting from `first`.
fn differences(x: &[Vec<f64>], dt: f64, first: &[f64]) -> Vec<Vec<f64>> {
    let mut prev = first.to_vec();
    x.iter()
        .map(|row| {
            let d: Vec<f64> = row.iter().zip(&prev).map(|(a, b)| (a - b) / dt).collect();
            prev.clone_from(row);
            d
        })
        .collect()
}

/// Checks joint positions `q` (one row of `chain.dof()` values per command, the first at
/// time `t0`, then every `dt` seconds) against the chain's position and speed limits,
/// `limits`, and — with `inertia` — the torque limits through inverse dynamics with
/// `gravity`. See the module documentation for how the derivatives are taken.
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
    // At rest before the first command, the last one held for three periods after it.
    let mut held = q.to_vec();
    held.extend(std::iter::repeat_n(last.clone(), 3));
    let zero = vec![0.0; n];
    let v = differences(&held, dt, &held[0]);
    let a = differences(&v, dt, &zero);
    let j = differences(&a, dt, &zero);
    // Torques (and their rates) at every command, when the robot has inertias and a
    // torque limit to hold them to.
    let wants_torque = limits.torque.is_some() || limits.torque_rate.is_some();
    let (tau, rate) = match inertia.filter(|_| wants_torque) {
        Some(links) => {
            let tau = held
                .iter()
                .zip(&v)
                .zip(&a)
                .map(|((q, v), a)| chain.inverse_dynamics(links, gravity, q, v, a))
                .collect::<Result<Vec<_>, _>>()?;
            let rate = differences(&tau, dt, &tau[0]);
            (Some(tau), Some(rate))
        }
        None => (None, None),
    };
    let mut series: Vec<Series> = Vec::new();
    let mut not_checked = Vec::new();
    match chain.limits() {
        Some(_) => series.push((Quantity::Position, held, None)),
        None => not_checked.push((
            Quantity::Position,
            "the robot has no joint position limits".to_string(),
        )),
    }
    for (quantity, values, max) in [
        (
            Quantity::Velocity,
            Some(v),
            chain.velocity_limits().map(<[f64]>::to_vec),
        ),
        (Quantity::Acceleration, Some(a), limits.acceleration.clone()),
        (Quantity::Jerk, Some(j), limits.jerk.clone()),
        (Quantity::Torque, tau, limits.torque.clone()),
        (Quantity::TorqueRate, rate, limits.torque_rate.clone()),
    ] {
        match (values, max) {
            (Some(values), Some(m)) => series.push((quantity, values, Some(m))),
            (None, Some(_)) => not_checked.push((
                quantity,
                "the robot's link inertias are not known, so torques cannot be computed".into(),
            )),
            (_, None) => not_checked.push((
                quantity,
                format!("the robot has no {} limits", quantity.name()),
            )),
        }
    }
    let range = chain.limits();
    let mut peak_usage = Vec::new();
    let mut violations = Vec::new();
    for (quantity, values, max) in &series {
        let mut usage = vec![0.0_f64; n];
        for joint in 0..n {
            // The worst sample of the current run beyond the limit: (excess, k, value, limit).
            let mut run: Option<(f64, usize, f64, f64)> = None;
            for (k, row) in values.iter().enumerate() {
                let x = row[joint];
                let (use_pct, excess, bound) = match max {
                    Some(m) => {
                        let m = m[joint];
                        (100.0 * x.abs() / m, x.abs() - m, m.copysign(x))
                    }
                    None => {
                        let (lo, hi) = range.expect("positions are checked with a range");
                        let (lo, hi) = (lo[joint], hi[joint]);
                        let mid = 0.5 * (lo + hi);
                        let half = 0.5 * (hi - lo);
                        let bound = if x < mid { lo } else { hi };
                        (
                            100.0 * (x - mid).abs() / half,
                            (x - mid).abs() - half,
                            bound,
                        )
                    }
                };
                usage[joint] = usage[joint].max(use_pct);
                let ends = k + 1 == values.len();
                if excess > 0.0 && run.is_none_or(|r| excess > r.0) {
                    run = Some((excess, k, x, bound));
                }
                // A run ends at the first sample back within the limit, or with the samples.
                if (excess <= 0.0 || ends)
                    && let Some((_, k0, value, limit)) = run.take()
                {
                    violations.push(Violation {
                        joint: joint + 1,
                        quantity: *quantity,
                        time: t0 + k0 as f64 * dt,
                        value,
                        limit,
                    });
                }
            }
        }
        peak_usage.push((*quantity, usage));
    }
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
