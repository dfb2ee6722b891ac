//! The robot backend: what cps needs from a robot (simulated or real) to execute a
//! trajectory, and an in-process kinematic robot that implements it.
//!
//! Every backend is stepped: commands take effect at the next [`RobotBackend::step`], which
//! advances the backend's clock by [`RobotBackend::time_step`]. `cps-coppelia` implements
//! the same trait for CoppeliaSim (and its stand-in server), so code written against the
//! trait runs on any of them.

use nalgebra::IsometryMatrix3;

use crate::{KinematicsError, SerialChain};

/// A robot that can be read, commanded and stepped. Methods take `&mut self` because a
/// remote backend talks over a connection; every call can fail with
/// [`KinematicsError::Backend`].
pub trait RobotBackend {
    /// Number of joints.
    fn dof(&self) -> usize;
    /// The backend's control period in seconds.
    fn time_step(&self) -> f64;
    /// Measured joint positions (radians).
    fn joint_positions(&mut self) -> Result<Vec<f64>, KinematicsError>;
    /// Commands joint positions, reached at the next step as far as the backend's limits
    /// allow.
    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), KinematicsError>;
    /// Commands joint velocities (rad/s), held until the next command.
    fn command_joint_velocities(&mut self, dq: &[f64]) -> Result<(), KinematicsError>;
    /// The measured world pose of the tool point.
    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, KinematicsError>;
    /// The backend's clock in seconds.
    fn time(&mut self) -> Result<f64, KinematicsError>;
    /// Advances the backend by one time step.
    fn step(&mut self) -> Result<(), KinematicsError>;
    /// Puts the robot at `q` at rest with its clock at 0, ready to step: the start of a
    /// new run (a simulator stops, sets the joints and starts stepping again).
    fn reset(&mut self, q: &[f64]) -> Result<(), KinematicsError>;
    /// True if the backend moves its joints itself to follow a commanded tool target
    /// ([`RobotBackend::command_target`]), as CoppeliaSim's IK follows `/Panda_target`;
    /// [`crate::execute`] then commands targets instead of running cps's controller.
    /// Default: false.
    fn follows_targets(&self) -> bool {
        false
    }
    /// Commands the tool target, followed from the next step on. Only for backends that
    /// [follow targets](RobotBackend::follows_targets); the default refuses.
    fn command_target(&mut self, target: &crate::IkTarget) -> Result<(), KinematicsError> {
        let _ = target;
        Err(KinematicsError::Backend {
            backend: "this backend".into(),
            message: "it does not follow tool targets; command joint positions".into(),
        })
    }
    /// A sentence on how the executions so far went on this backend, for summaries (a real
    /// robot: the limit usage of what was sent, any slowing, the loop's timing); `None`
    /// where there is nothing beyond the recording to say. Default: `None`.
    fn execution_report(&self) -> Option<String> {
        None
    }
    /// True if [`RobotBackend::run_joint_targets`] runs a whole sequence inside the backend
    /// in a few exchanges (a simulator's scene script), rather than through the per-step
    /// calls of the default. [`crate::execute`] then plans the controller's commands on the
    /// model and sends them at once. Default: false.
    fn runs_sequences(&self) -> bool {
        false
    }
    /// Runs `targets` (one joint-position row per step): before step k the backend is
    /// commanded row k, then steps once; after each step the measured joints, the tool pose
    /// and the clock are recorded. The default does exactly that through
    /// [`RobotBackend::command_joint_positions`], [`RobotBackend::step`] and the readers,
    /// one call each; a backend that [runs sequences](RobotBackend::runs_sequences) does
    /// it inside itself and must give the same recording.
    fn run_joint_targets(
        &mut self,
        targets: &[Vec<f64>],
    ) -> Result<StepRecording, KinematicsError> {
        run_stepwise(self, targets)
    }
}

/// [`RobotBackend::run_joint_targets`] through the per-step calls: command a row, step,
/// read the joints, the tool pose and the clock; for backends that run sequences only
/// sometimes (a scene without cps's script).
pub fn run_stepwise(
    backend: &mut (impl RobotBackend + ?Sized),
    targets: &[Vec<f64>],
) -> Result<StepRecording, KinematicsError> {
    let mut rec = StepRecording::default();
    for row in targets {
        backend.command_joint_positions(row)?;
        backend.step()?;
        rec.q.push(backend.joint_positions()?);
        rec.tool.push(backend.tool_pose()?);
        rec.time.push(backend.time()?);
    }
    Ok(rec)
}

/// What [`RobotBackend::run_joint_targets`] recorded: one entry per step, after the step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepRecording {
    /// The backend's clock (seconds).
    pub time: Vec<f64>,
    /// Measured joint positions.
    pub q: Vec<Vec<f64>>,
    /// Measured tool pose in the world frame.
    pub tool: Vec<IsometryMatrix3<f64>>,
}

#[derive(Debug, Clone, PartialEq)]
enum Command {
    Hold,
    Position(Vec<f64>),
    Velocity(Vec<f64>),
}

/// A robot simulated at the kinematic level: joints move exactly as commanded, within the
/// chain's position and speed limits; no dynamics. Deterministic and instantaneous to
/// query, it is the default backend and the reference the simulator backends are compared
/// with.
///
/// A joint that starts outside a position limit (the thesis's initial configuration has
/// joint 4 just above its upper limit) is accepted, but is never moved further out.
#[derive(Debug, Clone)]
pub struct KinematicRobot {
    chain: SerialChain,
    q: Vec<f64>,
    command: Command,
    dt: f64,
    time: f64,
    steps: u64,
}

impl KinematicRobot {
    /// A robot of `chain` at configuration `q0`, stepped every `dt` seconds.
    pub fn new(chain: SerialChain, q0: &[f64], dt: f64) -> Result<Self, KinematicsError> {
        chain.check(q0)?;
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(KinematicsError::InvalidConfig(format!(
                "the robot's time step must be finite and > 0 (got {dt})"
            )));
        }
        Ok(Self {
            chain,
            q: q0.to_vec(),
            command: Command::Hold,
            dt,
            time: 0.0,
            steps: 0,
        })
    }

    /// The robot's model.
    pub fn chain(&self) -> &SerialChain {
        &self.chain
    }

    /// The current joint positions, without the `Result` of the trait.
    pub fn q(&self) -> &[f64] {
        &self.q
    }

    /// Moves joint i by `dq_i`, held within the speed limit for one step and within the
    /// position limits (or towards them when outside).
    fn apply(&mut self, dq: &[f64]) {
        let vmax = self.chain.velocity_limits();
        let limits = self.chain.limits();
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
        self.chain.check(v).map_err(|e| match e {
            KinematicsError::NotFinite { joint, value } => KinematicsError::InvalidConfig(format!(
                "commanded {what} of joint {joint} is not finite ({value})"
            )),
            other => other,
        })?;
        Ok(v.to_vec())
    }
}

impl RobotBackend for KinematicRobot {
    fn dof(&self) -> usize {
        self.chain.dof()
    }

    fn time_step(&self) -> f64 {
        self.dt
    }

    fn joint_positions(&mut self) -> Result<Vec<f64>, KinematicsError> {
        Ok(self.q.clone())
    }

    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        self.command = Command::Position(self.checked(q, "position")?);
        Ok(())
    }

    fn command_joint_velocities(&mut self, dq: &[f64]) -> Result<(), KinematicsError> {
        self.command = Command::Velocity(self.checked(dq, "velocity")?);
        Ok(())
    }

    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, KinematicsError> {
        self.chain.fk(&self.q)
    }

    fn time(&mut self) -> Result<f64, KinematicsError> {
        Ok(self.time)
    }

    fn step(&mut self) -> Result<(), KinematicsError> {
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

    fn reset(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        self.chain.check(q)?;
        self.q = q.to_vec();
        self.command = Command::Hold;
        self.steps = 0;
        self.time = 0.0;
        Ok(())
    }
}
