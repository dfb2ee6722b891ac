//! Trajectory execution: follow a task-space trajectory with the inverse controller on any
//! [`Robot`], recording what the robot really did (the thesis's "Jacobian inverse control
//! with recording", with an iteration cap instead of its endless loop).

use cps_kinematics::controllers::{ControllerConfig, control_step, task_error};
use cps_kinematics::{IkTarget, KinematicsError, SerialChain};
use nalgebra::UnitQuaternion;

use crate::plan::Plan;
use crate::robot::Robot;
use crate::{RobotError, StopToken};

/// Settings of [`execute`].
#[derive(Debug, Clone, PartialEq)]
pub struct ExecutionConfig {
    /// The inverse controller (default: damped least squares within limits).
    pub controller: ControllerConfig,
    /// Position error in metres at which a sample counts as reached. Default 1e-4.
    pub tolerance: f64,
    /// Rotation error in radians at which a pose sample counts as reached. Default 1e-3.
    pub rotation_tolerance: f64,
    /// Control iterations (backend steps) at most per trajectory sample; at least one is
    /// always taken, so the backend's clock advances with the trajectory. Default 10.
    pub max_iterations_per_sample: usize,
}

impl Default for ExecutionConfig {
    fn default() -> Self {
        Self {
            controller: ControllerConfig::default(),
            tolerance: 1e-4,
            rotation_tolerance: 1e-3,
            max_iterations_per_sample: 10,
        }
    }
}

/// What the robot did, one entry per trajectory sample (after its last iteration).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// Seconds since the execution started (the backend's clock minus its reading at the
    /// start), so recordings of different runs and backends share one time origin.
    pub time: Vec<f64>,
    /// Measured joint positions (radians).
    pub q: Vec<Vec<f64>>,
    /// Measured tool position in the world frame (metres).
    pub position: Vec<[f64; 3]>,
    /// Measured tool orientation as a unit quaternion `[x, y, z, w]`.
    pub orientation: Vec<[f64; 4]>,
    /// Distance from the sample's target position (metres).
    pub position_error: Vec<f64>,
    /// Rotation angle from the sample's target orientation (radians; 0 for positions).
    pub rotation_error: Vec<f64>,
    /// Backend steps taken in total.
    pub steps: usize,
    /// Samples still outside the tolerance when their iteration cap ran out.
    pub unconverged: usize,
}

impl Recording {
    /// The largest position error over the samples (metres).
    pub fn max_position_error(&self) -> f64 {
        self.position_error.iter().fold(0.0, |a, &e| a.max(e))
    }

    /// The root-mean-square position error (metres).
    pub fn rms_position_error(&self) -> f64 {
        let n = self.position_error.len().max(1) as f64;
        (self.position_error.iter().map(|e| e * e).sum::<f64>() / n).sqrt()
    }
}

/// Follows `targets` (one per control period) on `robot`, whose kinematics `model`
/// describes: per sample, up to `max_iterations_per_sample` control steps
/// ([`control_step`], limits respected), each commanded as joint positions and followed by
/// one step, stopping early once the model says the sample is reached. Then the robot's
/// measured state is recorded. Never loops without bound. A robot that [follows targets
/// itself](crate::Stepping::Targets) (CoppeliaSim's IK) is given the sample as its target
/// and stepped the same way, without cps's controller.
///
/// A robot that does not step, or [prefers plans](crate::Stepping::Plans) (a simulator with
/// cps's scene script), gets the whole command sequence as one [`Plan`] at its period: the
/// controller is run against the model, which predicts that each command is reached at the
/// next step, and the robot runs the commands and records every one (through the guard
/// when the robot is [guarded](crate::Guarded)). Where the robot follows its commands (the
/// kinematic robot, the stand-in server) both ways give the same recording; where it lags
/// (dynamics), the recording shows the tracking error instead of the controller
/// correcting it. `stop` ends a plan's run (the robot brakes; an error says how far it
/// got); a simulator's closed loop runs to its end (milliseconds).
pub fn execute(
    robot: &mut dyn Robot,
    model: &SerialChain,
    targets: &[IkTarget],
    config: &ExecutionConfig,
    stop: &StopToken,
) -> Result<Recording, RobotError> {
    if robot.model().chain.dof() != model.dof() {
        return Err(KinematicsError::JointCount {
            expected: model.dof(),
            got: robot.model().chain.dof(),
        }
        .into());
    }
    config.controller.validate(model)?;
    if !(config.tolerance > 0.0 && config.rotation_tolerance > 0.0) {
        return Err(
            KinematicsError::InvalidConfig("execution tolerances must be > 0".into()).into(),
        );
    }
    if config.max_iterations_per_sample == 0 {
        return Err(KinematicsError::InvalidConfig(
            "max_iterations_per_sample must be at least 1".into(),
        )
        .into());
    }
    let closed_loop = robot
        .stepped()
        .is_some_and(|s| s.stepping() != crate::Stepping::Plans);
    if !closed_loop {
        return execute_planned(robot, model, targets, config, stop);
    }
    let backend = robot.stepped().expect("a stepped robot");
    let dt = backend.dt();
    let mut rec = Recording::default();
    let t0 = backend.time()?;
    // The measured configuration is read once per control step and reused: a remote
    // robot pays a round trip per joint and call.
    let mut q = backend.joint_positions()?;
    for target in targets {
        let mut reached = false;
        let follows = matches!(backend.stepping(), crate::Stepping::Targets { .. });
        if follows {
            backend.command_target(target)?;
        }
        for _ in 0..config.max_iterations_per_sample {
            if !follows {
                let st = control_step(model, &q, target, dt, &config.controller)?;
                let next: Vec<f64> = q.iter().zip(&st.dq).map(|(a, b)| a + b).collect();
                backend.command_joint_positions(&next)?;
            }
            backend.step()?;
            rec.steps += 1;
            q = backend.joint_positions()?;
            let (ep, er) = task_error(&model.fk(&q)?, target);
            if ep.norm() <= config.tolerance && er.norm() <= config.rotation_tolerance {
                reached = true;
                break;
            }
        }
        rec.unconverged += usize::from(!reached);
        let pose = backend.tool_pose()?;
        let (ep, er) = task_error(&pose, target);
        let p = pose.translation.vector;
        let o = UnitQuaternion::from_rotation_matrix(&pose.rotation);
        rec.time.push(backend.time()? - t0);
        rec.q.push(q.clone());
        rec.position.push([p.x, p.y, p.z]);
        rec.orientation.push([o.i, o.j, o.k, o.w]);
        rec.position_error.push(ep.norm());
        rec.rotation_error.push(er.norm());
    }
    Ok(rec)
}

/// The commands [`execute`]'s controller sends for `targets` when the robot follows each
/// one (the model's prediction): every configuration from the start on, each sample's
/// last, and how many samples were not reached within their iterations.
#[derive(Debug, Clone, PartialEq)]
pub struct CommandPath {
    /// The start, then every command (one per control period).
    pub points: Vec<Vec<f64>>,
    /// Per target: the index into `points` of its last command.
    pub last_step: Vec<usize>,
    /// Targets not reached within `max_iterations_per_sample`.
    pub unconverged: usize,
}

/// The controller's commands for `targets` from `q0` on `model`, stepped every `dt`, as
/// [`execute`] sends them to a robot that reaches each command at the next step (see
/// [`CommandPath`]).
pub fn command_path(
    model: &SerialChain,
    q0: Vec<f64>,
    targets: &[IkTarget],
    config: &ExecutionConfig,
    dt: f64,
) -> Result<CommandPath, RobotError> {
    let mut q = q0.clone();
    let mut points: Vec<Vec<f64>> = vec![q0];
    let mut last_step = Vec::with_capacity(targets.len());
    let mut unconverged = 0;
    for target in targets {
        let mut reached = false;
        for _ in 0..config.max_iterations_per_sample {
            let st = control_step(model, &q, target, dt, &config.controller)?;
            for (a, b) in q.iter_mut().zip(&st.dq) {
                *a += b;
            }
            points.push(q.clone());
            let (ep, er) = task_error(&model.fk(&q)?, target);
            if ep.norm() <= config.tolerance && er.norm() <= config.rotation_tolerance {
                reached = true;
                break;
            }
        }
        unconverged += usize::from(!reached);
        last_step.push(points.len() - 1);
    }
    Ok(CommandPath {
        points,
        last_step,
        unconverged,
    })
}

/// [`execute`] as one plan: the controller's commands are planned on the model, run at
/// once, and the recording of each sample's last step is kept.
fn execute_planned(
    robot: &mut dyn Robot,
    model: &SerialChain,
    targets: &[IkTarget],
    config: &ExecutionConfig,
    stop: &StopToken,
) -> Result<Recording, RobotError> {
    let dt = robot.dt();
    let CommandPath {
        points,
        last_step,
        unconverged,
    } = command_path(model, robot.joint_positions()?, targets, config, dt)?;
    let n = points.len();
    let plan = Plan::new(dt, points)?;
    let run = robot.run(&plan, stop)?;
    if !run.ending.complete() {
        return Err(RobotError::Robot {
            robot: robot.name(),
            message: format!(
                "{} after {} of {} steps",
                run.ending.sentence(),
                run.len().saturating_sub(1),
                n - 1
            ),
        });
    }
    if run.len() != n {
        return Err(RobotError::Robot {
            robot: robot.name(),
            message: format!(
                "asked to run {} steps, it recorded {}",
                n - 1,
                run.len().saturating_sub(1)
            ),
        });
    }
    let mut rec = Recording {
        steps: n - 1,
        unconverged,
        ..Recording::default()
    };
    for (target, &k) in targets.iter().zip(&last_step) {
        let pose = &run.tool[k];
        let (ep, er) = task_error(pose, target);
        let p = pose.translation.vector;
        let o = UnitQuaternion::from_rotation_matrix(&pose.rotation);
        rec.time.push(run.time[k]);
        rec.q.push(run.q[k].clone());
        rec.position.push([p.x, p.y, p.z]);
        rec.orientation.push([o.i, o.j, o.k, o.w]);
        rec.position_error.push(ep.norm());
        rec.rotation_error.push(er.norm());
    }
    Ok(rec)
}
