//! The guard on a command stream: the joint commands a stepped robot is sent one control
//! period at a time (cps's closed-loop executor on a simulator), judged one by one with
//! the checks a plan gets ([`crate::check`] through `cps_kinematics::check_joint_trajectory`):
//! backward differences from rest for velocity, acceleration and jerk, torque by inverse
//! dynamics where the robot has inertias, its rate from the first command's; the position
//! range with the plan's allowance (a joint that started beyond a bound may move back,
//! never further out). A command that breaks one is not sent.

use cps_kinematics::{POSITION_TOLERANCE, Quantity};

use crate::RobotModel;
use crate::check::{Breach, Limit, beyond_allowed};

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
    /// The next command's velocity, acceleration, and jerk or torque rate: reused, so a
    /// command allocates nothing beyond inverse dynamics' answer.
    next_v: Vec<f64>,
    next_a: Vec<f64>,
    scratch: Vec<f64>,
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
            next_v: vec![0.0; n],
            next_a: vec![0.0; n],
            scratch: vec![0.0; n],
        }
    }

    /// How many commands were accepted so far.
    pub(crate) fn commands(&self) -> usize {
        self.commands
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
        let (mut v, mut a, mut jerk) = (
            std::mem::take(&mut self.next_v),
            std::mem::take(&mut self.next_a),
            std::mem::take(&mut self.scratch),
        );
        for j in 0..n {
            v[j] = (q[j] - self.q[j]) / dt;
            a[j] = (v[j] - self.v[j]) / dt;
            jerk[j] = (a[j] - self.a[j]) / dt;
        }
        let verdict = self.judge_derivatives(model, q, &v[..n], &a[..n], &mut jerk[..n]);
        // The buffers go back: the accepted command's as its derivatives, the old ones as
        // the next command's scratch.
        if verdict.is_ok() {
            self.q[..n].copy_from_slice(&q[..n]);
            std::mem::swap(&mut self.v, &mut v);
            std::mem::swap(&mut self.a, &mut a);
            self.commands += 1;
        }
        (self.next_v, self.next_a, self.scratch) = (v, a, jerk);
        verdict
    }

    /// [`CommandWatch::judge`] on the command's derivatives (`jerk` is then reused for the
    /// torque rate); sets the torque on success.
    fn judge_derivatives(
        &mut self,
        model: &RobotModel,
        q: &[f64],
        v: &[f64],
        a: &[f64],
        jerk: &mut [f64],
    ) -> Result<(), Breach> {
        let dt = self.dt;
        let n = v.len();
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
        if let Some((lo, hi)) = model.chain.limits() {
            for j in 0..n {
                let bound = if q[j] < 0.5 * (lo[j] + hi[j]) {
                    lo[j]
                } else {
                    hi[j]
                };
                let beyond =
                    (q[j] < lo[j] - POSITION_TOLERANCE) || (q[j] > hi[j] + POSITION_TOLERANCE);
                if beyond && !beyond_allowed(self.start[j], q[j], bound) {
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
        let found = symmetric(Quantity::Velocity, v, model.chain.velocity_limits())
            .or_else(|| symmetric(Quantity::Acceleration, a, limits.acceleration.as_deref()))
            .or_else(|| symmetric(Quantity::Jerk, jerk, limits.jerk.as_deref()));
        if let Some(b) = found {
            return Err(b);
        }
        let wants_torque = limits.torque.is_some() || limits.torque_rate.is_some();
        let mut tau = None;
        if let (true, Some(links)) = (wants_torque, model.inertia.as_deref()) {
            let gravity = model.robot_limits().gravity;
            if let Ok(t) = model.chain.inverse_dynamics(links, gravity, &q[..n], v, a) {
                if let Some(b) = symmetric(Quantity::Torque, &t, limits.torque.as_deref()) {
                    return Err(b);
                }
                // The first command's rate is taken from itself, as a plan's is.
                let before = self.tau.as_deref().unwrap_or(&t);
                let rate = jerk;
                for j in 0..n {
                    rate[j] = (t[j] - before[j]) / dt;
                }
                if let Some(b) =
                    symmetric(Quantity::TorqueRate, rate, limits.torque_rate.as_deref())
                {
                    return Err(b);
                }
                tau = Some(t);
            }
        }
        self.tau = tau;
        Ok(())
    }
}
