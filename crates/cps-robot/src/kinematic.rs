//! The in-process stand-in: a robot simulated at the kinematic level, stepped, and able to
//! run plans like any other robot.

use cps_kinematics::{KinematicsError, SerialChain};
use nalgebra::IsometryMatrix3;

use crate::cycles::{CycleLoss, LinkBreak, LossyLink, RateCheck};
use crate::plan::{Plan, Run};
use crate::robot::{Generator, Robot, Stepped, Streaming, run_stepped};
use crate::{RobotError, RobotModel, StopToken};

#[derive(Debug, Clone, PartialEq)]
enum Command {
    Hold,
    Position(Vec<f64>),
    Velocity(Vec<f64>),
}

/// A robot simulated at the kinematic level: joints move exactly as commanded, within the
/// chain's position and speed limits (a drive saturates); no dynamics. Deterministic and
/// instantaneous to query, it is the default robot and the reference the simulators are
/// compared with.
///
/// A joint that starts outside a position limit (the thesis's initial configuration has
/// joint 4 just above its upper limit) is accepted, but is never moved further out.
#[derive(Debug, Clone)]
pub struct KinematicRobot {
    model: RobotModel,
    q: Vec<f64>,
    command: Command,
    dt: f64,
    time: f64,
    steps: u64,
    /// Periods it loses on purpose while streaming ([`KinematicRobot::lose_cycles`]).
    loss: Option<CycleLoss>,
    /// Periods lost so far, and streamed commands limited after one.
    lost: u64,
    limited: usize,
}

impl KinematicRobot {
    /// A robot of `chain` at configuration `q0`, stepped every `dt` seconds.
    pub fn new(chain: SerialChain, q0: &[f64], dt: f64) -> Result<Self, KinematicsError> {
        KinematicRobot::of_model(RobotModel::of_chain("in-process robot", chain), q0, dt)
    }

    /// A robot of `model` (its chain, and the limits plans are checked against) at `q0`,
    /// stepped every `dt` seconds.
    pub fn of_model(model: RobotModel, q0: &[f64], dt: f64) -> Result<Self, KinematicsError> {
        model.chain.check(q0)?;
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(KinematicsError::InvalidConfig(format!(
                "the robot's time step must be finite and > 0 (got {dt})"
            )));
        }
        Ok(Self {
            model,
            q: q0.to_vec(),
            command: Command::Hold,
            dt,
            time: 0.0,
            steps: 0,
            loss: None,
            lost: 0,
            limited: 0,
        })
    }

    /// Makes it lose `share` (0 to [`crate::MAX_LOSS`]) of its periods while streaming,
    /// chosen by `seed` — a test option: its commanded reference is then extrapolated at
    /// constant acceleration through each, as a Franka's is, and every command it gets is
    /// judged against that reference by its model's limits (a breach would be a Franka's
    /// discontinuity reflex: the run fails); the stream reaches it through cps's limiter
    /// ([`LossyLink`]), as the Franka's loop sends it. Arms of 1 to 8 joints.
    pub fn lose_cycles(&mut self, share: f64, seed: u64) -> Result<(), RobotError> {
        let bad = |message: String| RobotError::Robot {
            robot: "the in-process robot".into(),
            message,
        };
        if !(1..=8).contains(&self.q.len()) {
            return Err(bad(format!(
                "loses periods for arms of 1 to 8 joints; this one has {}",
                self.q.len()
            )));
        }
        let loss = CycleLoss::new(share, seed).map_err(|source| RobotError::Setting {
            robot: "the in-process robot".into(),
            source,
        })?;
        self.loss = (share > 0.0).then_some(loss);
        Ok(())
    }

    /// The streaming loop: `send(robot, command, last)` puts each command of `next` to the
    /// arm, or ends the run (a command it would not send); then a period passes.
    fn stream_with<S>(
        &mut self,
        next: &mut Generator<'_>,
        max_commands: usize,
        stop: &StopToken,
        mut send: S,
    ) -> Result<Run, RobotError>
    where
        S: FnMut(&mut Self, &[f64], bool) -> Result<Option<crate::Ending>, RobotError>,
    {
        let mut run = Run::new(crate::Ending::Finished);
        let t0 = self.time;
        run.push(0.0, self.q.clone(), self.model.chain.fk(&self.q)?);
        let mut command = self.q.clone();
        // It moves as told: its velocity is the last step's; it has no torques.
        let (mut previous, mut dq, tau) = (
            self.q.clone(),
            vec![0.0; self.q.len()],
            vec![0.0; self.q.len()],
        );
        let dt = self.dt;
        for k in 0.. {
            if let Some(ending) = over(stop, k, max_commands) {
                run.ending = ending;
                break;
            }
            for ((v, q), p) in dq.iter_mut().zip(&self.q).zip(&previous) {
                *v = (q - p) / dt;
            }
            previous.copy_from_slice(&self.q);
            let measured = crate::Measured {
                q: &self.q,
                dq: &dq,
                tau: &tau,
            };
            let last = next(&measured, self.time - t0, &mut command);
            if let Some(ending) = send(self, &command, last)? {
                run.ending = ending;
                break;
            }
            KinematicRobot::step(self)?;
            run.push(
                self.time - t0,
                self.q.clone(),
                self.model.chain.fk(&self.q)?,
            );
            if last {
                break;
            }
        }
        Ok(run)
    }

    /// [`Streaming::stream`] through a [`LossyLink`] of `N` joints.
    fn stream_lossy<const N: usize>(
        &mut self,
        next: &mut Generator<'_>,
        max_commands: usize,
        stop: &StopToken,
        loss: CycleLoss,
    ) -> Result<Run, RobotError> {
        let q0: [f64; N] = std::array::from_fn(|i| self.q[i]);
        let mut link = LossyLink::new(loss, RateCheck::of_model(&self.model, self.dt, q0));
        let run = self.stream_with(next, max_commands, stop, |robot, command, last| {
            let target: [f64; N] =
                command
                    .try_into()
                    .map_err(|_| KinematicsError::JointCount {
                        expected: N,
                        got: command.len(),
                    })?;
            Ok(match link.step(&target, last) {
                Ok(r) => {
                    KinematicRobot::command_joint_positions(robot, &r.q)?;
                    None
                }
                Err(LinkBreak::Refused(b)) => Some(crate::Ending::Failed(format!(
                    "a command beyond a limit was not sent ({b})"
                ))),
                Err(LinkBreak::Reflex(b)) => Some(crate::Ending::Failed(format!(
                    "reflex: a command broke a limit against the reference the robot held after a lost period ({b})"
                ))),
            })
        })?;
        self.lost += link.lost();
        self.limited += link.limited().commands;
        Ok(run)
    }

    /// The robot's model.
    pub fn chain(&self) -> &SerialChain {
        &self.model.chain
    }

    /// The current joint positions.
    pub fn q(&self) -> &[f64] {
        &self.q
    }

    /// Measured joint positions (rad).
    pub fn joint_positions(&mut self) -> Result<Vec<f64>, KinematicsError> {
        Ok(self.q.clone())
    }

    /// The robot's clock (s): steps × the time step.
    pub fn time(&mut self) -> Result<f64, KinematicsError> {
        Ok(self.time)
    }

    /// The tool's world pose.
    pub fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, KinematicsError> {
        self.model.chain.fk(&self.q)
    }

    /// Moves joint i by `dq_i`, held within the speed limit for one step and within the
    /// position limits (or towards them when outside).
    fn apply(&mut self, dq: &[f64]) {
        let vmax = self.model.chain.velocity_limits();
        let limits = self.model.chain.limits();
        for i in 0..self.q.len() {
            let mut d = dq[i];
            if let Some(v) = vmax {
                d = d.clamp(-v[i] * self.dt, v[i] * self.dt);
            }
            if let Some((lo, hi)) = limits {
                d = d.clamp((lo[i] - self.q[i]).min(0.0), (hi[i] - self.q[i]).max(0.0));
            }
            self.q[i] += d;
        }
    }

    fn checked(&self, v: &[f64], what: &str) -> Result<Vec<f64>, KinematicsError> {
        self.model.chain.check(v).map_err(|e| match e {
            KinematicsError::NotFinite { joint, value } => KinematicsError::InvalidConfig(format!(
                "commanded {what} of joint {joint} is not finite ({value})"
            )),
            other => other,
        })?;
        Ok(v.to_vec())
    }

    /// Commands joint positions, reached at the next step as far as the limits allow.
    pub fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        self.command = Command::Position(self.checked(q, "position")?);
        Ok(())
    }

    /// Commands joint velocities (rad/s), held until the next command.
    pub fn command_joint_velocities(&mut self, dq: &[f64]) -> Result<(), KinematicsError> {
        self.command = Command::Velocity(self.checked(dq, "velocity")?);
        Ok(())
    }

    /// Advances one time step.
    pub fn step(&mut self) -> Result<(), KinematicsError> {
        let dq: Vec<f64> = match &self.command {
            Command::Hold => vec![0.0; self.q.len()],
            Command::Position(target) => target.iter().zip(&self.q).map(|(t, q)| t - q).collect(),
            Command::Velocity(v) => v.iter().map(|v| v * self.dt).collect(),
        };
        self.apply(&dq);
        self.steps += 1;
        // Time as steps × dt: no drift from repeated additions.
        self.time = self.steps as f64 * self.dt;
        Ok(())
    }

    /// Puts the robot at `q` at rest with its clock at 0.
    pub fn reset(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        self.model.chain.check(q)?;
        self.q = q.to_vec();
        self.command = Command::Hold;
        self.steps = 0;
        self.time = 0.0;
        Ok(())
    }
}

impl Stepped for KinematicRobot {
    fn time(&mut self) -> Result<f64, RobotError> {
        Ok(self.time)
    }
    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), RobotError> {
        Ok(KinematicRobot::command_joint_positions(self, q)?)
    }
    fn step(&mut self) -> Result<(), RobotError> {
        Ok(KinematicRobot::step(self)?)
    }
}

impl Robot for KinematicRobot {
    fn name(&self) -> String {
        "the in-process robot".into()
    }
    fn model(&self) -> &RobotModel {
        &self.model
    }
    fn dt(&self) -> f64 {
        self.dt
    }
    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        Ok(self.q.clone())
    }
    /// Its step: it steps through a plan's motion sampled at it.
    fn command_period(&self) -> f64 {
        self.dt
    }
    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, RobotError> {
        Ok(self.model.chain.fk(&self.q)?)
    }
    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
        run_stepped(self, plan, stop)
    }
    fn teleport(&mut self, q: &[f64]) -> Result<bool, RobotError> {
        self.reset(q)?;
        Ok(true)
    }
    fn report(&self) -> Option<String> {
        self.loss.map(|_| {
            format!(
                "{} periods lost on purpose while streaming, {} commands limited after one",
                self.lost, self.limited
            )
        })
    }
    fn stepped(&mut self) -> Option<&mut dyn Stepped> {
        Some(self)
    }
    fn streaming(&mut self) -> Option<&mut dyn Streaming> {
        Some(self)
    }
}

/// Why a stream ends before its next command: stopped, or out of commands.
fn over(stop: &StopToken, k: usize, max_commands: usize) -> Option<crate::Ending> {
    if stop.is_stopped() {
        Some(crate::Ending::Stopped)
    } else if k == max_commands {
        Some(crate::Ending::Failed(format!(
            "{max_commands} commands were not enough to finish"
        )))
    } else {
        None
    }
}

impl Streaming for KinematicRobot {
    fn stream(
        &mut self,
        next: &mut Generator<'_>,
        max_commands: usize,
        stop: &StopToken,
    ) -> Result<Run, RobotError> {
        if let Some(loss) = self.loss {
            return match self.q.len() {
                1 => self.stream_lossy::<1>(next, max_commands, stop, loss),
                2 => self.stream_lossy::<2>(next, max_commands, stop, loss),
                3 => self.stream_lossy::<3>(next, max_commands, stop, loss),
                4 => self.stream_lossy::<4>(next, max_commands, stop, loss),
                5 => self.stream_lossy::<5>(next, max_commands, stop, loss),
                6 => self.stream_lossy::<6>(next, max_commands, stop, loss),
                7 => self.stream_lossy::<7>(next, max_commands, stop, loss),
                _ => self.stream_lossy::<8>(next, max_commands, stop, loss),
            };
        }
        self.stream_with(next, max_commands, stop, |robot, command, _| {
            KinematicRobot::command_joint_positions(robot, command)?;
            Ok(None)
        })
    }
}
