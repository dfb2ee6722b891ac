//! The guard on a command stream: the joint commands a stepped robot is sent one control
//! period at a time (cps's closed-loop executor on a simulator), judged one by one by the
//! one limit checker ([`cps_kinematics::StreamCheck`], the checks a plan's commands get):
//! backward differences from rest for velocity, acceleration and jerk, torque by inverse
//! dynamics where the robot has inertias ([`cps_kinematics::TorqueCheck`]), its rate from
//! the first command's; the position range with the plan's allowance (a joint that started
//! beyond a bound may move back, never further out). A command that breaks one is not sent.

use cps_kinematics::{JointBounds, StreamCheck, TorqueCheck};

use crate::RobotModel;
use crate::check::Breach;

/// The relative excess over a limit taken as rounding (a controller that clamps to a
/// limit exactly differs from it by rounding once differenced: that is not a breach).
const ROUNDING: f64 = 1e-9;

/// What the commands so far leave behind: the last command and its derivatives, and its
/// torques.
#[derive(Debug, Clone)]
pub(crate) struct CommandWatch {
    stream: StreamCheck<Vec<f64>, JointBounds<Vec<f64>>>,
    torques: TorqueCheck,
}

impl CommandWatch {
    /// A watch on commands every `dt` seconds to `model`'s robot, at rest at `q`; the
    /// first command is number 1 (0 is where it stands).
    pub(crate) fn new(model: &RobotModel, q: &[f64], dt: f64) -> Self {
        let bounds = JointBounds::of(&model.chain, &model.limits, &q.to_vec());
        CommandWatch {
            stream: StreamCheck::at_rest(bounds.with_rounding(ROUNDING), q.to_vec(), dt)
                .numbered_from(1),
            torques: TorqueCheck::default(),
        }
    }

    /// How many commands were accepted so far.
    pub(crate) fn commands(&self) -> usize {
        self.stream.taken()
    }

    /// The last command accepted (where the robot stood, before any).
    pub(crate) fn last(&self) -> &[f64] {
        self.stream.last().0
    }

    /// Judges the next command `q` against `model`'s limits: accepted (and remembered) or
    /// the first limit it breaks, at its time from the first command.
    pub(crate) fn judge(&mut self, model: &RobotModel, q: &[f64]) -> Result<(), Breach> {
        let robot = model.robot_limits();
        let dt = self.stream.period();
        let torques = &self.torques;
        let mut tau = None;
        self.stream
            .admit_also(q, |v, a| {
                let mut found = None;
                // Torques the model cannot compute here are not judged (as a plan's
                // check would have refused the model first).
                tau = torques
                    .judge(&robot, dt, (q, v, a), |j| {
                        found = (j.excess > 0.0).then_some(j);
                        found.is_none()
                    })
                    .ok()
                    .flatten();
                found
            })
            .map_err(Breach::from)?;
        self.torques.take(tau);
        Ok(())
    }
}
