//! The guard on a command stream: the joint commands a stepped robot is sent one control
//! period at a time (cps's closed-loop executor on a simulator), judged one by one with
//! the checks a plan gets ([`crate::check`] through `cps_kinematics::check_joint_trajectory`):
//! backward differences from rest for velocity, acceleration and jerk, torque by inverse
//! dynamics where the robot has inertias, its rate from the first command's; the position
//! range with the plan's allowance (a joint that started beyond a bound may move back,
//! never further out). A command that breaks one is not sent.

use cps_kinematics::{POSITION_TOLERANCE, Quantity};

use crate::RobotModel;
use crate::check::{Breach, Limit, OUTSIDE_SLACK};

/// The relative excess over a limit taken as rounding.
const ROUNDING: f64 = 1e-9;

/// What the commands so far leave behind: the last command and its derivatives.
#[derive(Debug, Clone)]
pub(crate) struct CommandWatch {
    dt: f64,
    /// Where the robot stood when the commands began (for the position allowance).
    start: Vec<f64>,
    q: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
    tau: Option<Vec<f64>>,
    /// Commands accepted so far.
    commands: usize,
}

impl CommandWatch {
    /// A watch on commands every `dt` seconds to a robot at rest at `q`.
    pub(crate) fn new(q: &[f64], dt: f64) -> Self {
        let n = q.len();
        CommandWatch {
            dt,
            start: q.to_vec(),
            q: q.to_vec(),
            v: vec![0.0; n],
            a: vec![0.0; n],
            tau: None,
            commands: 0,
        }
    }

    /// The last command accepted (where the robot stood, before any).
    pub(crate) fn last(&self) -> &[f64] {
        &self.q
    }

    /// Judges the next command `q` against `model`'s limits: accepted (and remembered) or
    /// the first limit it breaks, at its time from the first command.
    pub(crate) fn judge(&mut self, model: &RobotModel, q: &[f64]) -> Result<(), Breach> {
        let dt = self.dt;
        let n = q.len().min(self.q.len());
        let time = (self.commands + 1) as f64 * dt;
        let breach = |joint: usize, quantity: Quantity, value: f64, bound: f64| Breach {
            limit: Limit::Joint {
                joint: joint + 1,
                quantity,
            },
            time,
            command: self.commands + 1,
            value,
            bound,
        };
        let v: Vec<f64> = (0..n).map(|j| (q[j] - self.q[j]) / dt).collect();
        let a: Vec<f64> = (0..n).map(|j| (v[j] - self.v[j]) / dt).collect();
        let jerk: Vec<f64> = (0..n).map(|j| (a[j] - self.a[j]) / dt).collect();
        if let Some((lo, hi)) = model.chain.limits() {
            for j in 0..n {
                let bound = if q[j] < 0.5 * (lo[j] + hi[j]) {
                    lo[j]
                } else {
                    hi[j]
                };
                let outside = (q[j] - bound).abs();
                let beyond =
                    (q[j] < lo[j] - POSITION_TOLERANCE) || (q[j] > hi[j] + POSITION_TOLERANCE);
                // Moving back from beyond a bound it started beyond is allowed.
                let s = self.start[j];
                let started_beyond =
                    (q[j] > bound) == (s > bound) && (s - bound).abs() > POSITION_TOLERANCE;
                if beyond && !(started_beyond && outside <= (s - bound).abs() + OUTSIDE_SLACK) {
                    return Err(breach(j, Quantity::Position, q[j], bound));
                }
            }
        }
        // A command at a limit exactly (a controller that clamps to it) differs from it by
        // rounding once differenced: that is not a breach.
        let symmetric = |quantity: Quantity, values: &[f64], max: Option<&[f64]>| {
            let max = max?;
            (0..n)
                .find(|&j| values[j].abs() > max[j] * (1.0 + ROUNDING))
                .map(|j| breach(j, quantity, values[j], max[j].copysign(values[j])))
        };
        let limits = &model.limits;
        let found = symmetric(Quantity::Velocity, &v, model.chain.velocity_limits())
            .or_else(|| symmetric(Quantity::Acceleration, &a, limits.acceleration.as_deref()))
            .or_else(|| symmetric(Quantity::Jerk, &jerk, limits.jerk.as_deref()));
        if let Some(b) = found {
            return Err(b);
        }
        let wants_torque = limits.torque.is_some() || limits.torque_rate.is_some();
        let mut tau = None;
        if let (true, Some(links)) = (wants_torque, model.inertia.as_deref()) {
            let gravity = model.robot_limits().gravity;
            if let Ok(t) = model.chain.inverse_dynamics(links, gravity, q, &v, &a) {
                if let Some(b) = symmetric(Quantity::Torque, &t, limits.torque.as_deref()) {
                    return Err(b);
                }
                // The first command's rate is taken from itself, as a plan's is.
                let before = self.tau.as_deref().unwrap_or(&t);
                let rate: Vec<f64> = (0..n).map(|j| (t[j] - before[j]) / dt).collect();
                if let Some(b) =
                    symmetric(Quantity::TorqueRate, &rate, limits.torque_rate.as_deref())
                {
                    return Err(b);
                }
                tau = Some(t);
            }
        }
        self.q = q.to_vec();
        self.v = v;
        self.a = a;
        self.tau = tau;
        self.commands += 1;
        Ok(())
    }
}
