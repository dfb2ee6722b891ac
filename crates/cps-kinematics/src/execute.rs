//! Trajectory execution: follow a task-space trajectory with the inverse controller on any
//! [`RobotBackend`], recording what the robot really did (the thesis's "Jacobian inverse
//! control with recording", with an iteration cap instead of its endless loop).

use nalgebra::UnitQuaternion;

use crate::controllers::{ControllerConfig, control_step, task_error};
use crate::{IkTarget, KinematicsError, RobotBackend, SerialChain};

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

/// Follows `targets` (one per control period) on `backend`, whose kinematics `model`
/// describes: per sample, up to `max_iterations_per_sample` control steps
/// ([`control_step`], limits respected), each commanded as joint positions and followed by
/// one backend step, stopping early once the model says the sample is reached. Then the
/// backend's measured state is recorded. Never loops without bound. A backend that
/// [follows targets itself](RobotBackend::follows_targets) (CoppeliaSim's IK) is given
/// the sample as its target and stepped the same way, without cps's controller.
///
/// A backend that [runs sequences](RobotBackend::runs_sequences) (a simulator with cps's
/// scene script) gets the whole command sequence at once: the controller is run against
/// the model, which predicts that each command is reached at the next step, and the
/// backend executes the commands and records every step in a few exchanges instead of
/// several per step. Where the robot follows its commands (the kinematic robot, the
/// stand-in server) both ways give the same recording; where it lags (dynamics), the
/// recording shows the tracking error instead of the controller correcting it.
pub fn execute(
    backend: &mut (impl RobotBackend + ?Sized),
    model: &SerialChain,
    targets: &[IkTarget],
    config: &ExecutionConfig,
) -> Result<Recording, KinematicsError> {
    if backend.dof() != model.dof() {
        return Err(KinematicsError::JointCount {
            expected: model.dof(),
            got: backend.dof(),
        });
    }
    config.controller.validate(model)?;
    if !(config.tolerance > 0.0 && config.rotation_tolerance > 0.0) {
        return Err(KinematicsError::InvalidConfig(
            "execution tolerances must be > 0".into(),
        ));
    }
    if config.max_iterations_per_sample == 0 {
        return Err(KinematicsError::InvalidConfig(
            "max_iterations_per_sample must be at least 1".into(),
        ));
    }
    if backend.runs_sequences() && !backend.follows_targets() {
        return execute_planned(backend, model, targets, config);
    }
    let dt = backend.time_step();
    let mut rec = Recording::default();
    let t0 = backend.time()?;
    // The measured configuration is read once per control step and reused: a remote
    // backend pays a round trip per joint and call.
    let mut q = backend.joint_positions()?;
    for target in targets {
        let mut reached = false;
        let follows = backend.follows_targets();
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

/// [`execute`] for a backend that [runs sequences](RobotBackend::runs_sequences): the
/// controller's commands are planned on the model, sent at once, and the recording of
/// each sample's last step is kept.
fn execute_planned(
    backend: &mut (impl RobotBackend + ?Sized),
    model: &SerialChain,
    targets: &[IkTarget],
    config: &ExecutionConfig,
) -> Result<Recording, KinematicsError> {
    let dt = backend.time_step();
    let t0 = backend.time()?;
    let mut q = backend.joint_positions()?;
    let mut commands: Vec<Vec<f64>> = Vec::new();
    let mut last_step = Vec::with_capacity(targets.len());
    let mut unconverged = 0;
    for target in targets {
        let mut reached = false;
        for _ in 0..config.max_iterations_per_sample {
            let st = control_step(model, &q, target, dt, &config.controller)?;
            for (a, b) in q.iter_mut().zip(&st.dq) {
                *a += b;
            }
            commands.push(q.clone());
            let (ep, er) = task_error(&model.fk(&q)?, target);
            if ep.norm() <= config.tolerance && er.norm() <= config.rotation_tolerance {
                reached = true;
                break;
            }
        }
        unconverged += usize::from(!reached);
        last_step.push(commands.len() - 1);
    }
    let run = backend.run_joint_targets(&commands)?;
    let n = commands.len();
    if run.q.len() != n || run.tool.len() != n || run.time.len() != n {
        return Err(KinematicsError::Backend {
            backend: "the robot backend".into(),
            message: format!(
                "asked to run {n} steps, it recorded {} joint rows, {} poses and {} times",
                run.q.len(),
                run.tool.len(),
                run.time.len()
            ),
        });
    }
    let mut rec = Recording {
        steps: n,
        unconverged,
        ..Recording::default()
    };
    for (target, &k) in targets.iter().zip(&last_step) {
        let pose = &run.tool[k];
        let (ep, er) = task_error(pose, target);
        let p = pose.translation.vector;
        let o = UnitQuaternion::from_rotation_matrix(&pose.rotation);
        rec.time.push(run.time[k] - t0);
        rec.q.push(run.q[k].clone());
        rec.position.push([p.x, p.y, p.z]);
        rec.orientation.push([o.i, o.j, o.k, o.w]);
        rec.position_error.push(ep.norm());
        rec.rotation_error.push(er.norm());
    }
    Ok(rec)
}
