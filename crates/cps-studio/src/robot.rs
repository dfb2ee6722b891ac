//! The robot the studio shows: a scene's robot (the thesis's Panda by default), its pose
//! as points to draw (base, every joint's frame, the tool), and a learned movement
//! executed on it — the same reachability check and inverse controller the pipelines use.

use cps_dmp::Trajectory;
use cps_kinematics::SerialChain;
use cps_learn::{LearnError, RobotSetup, ViaPointTask, check_way_points, execute_trajectory};
use cps_robot::{KinematicRobot, Recording, StopToken};
use serde::Serialize;

/// Drawn poses per second of movement (the execution runs at the movement's dt).
const FRAMES_PER_SECOND: f64 = 25.0;

/// The robot of a studio.
#[derive(Debug, Clone)]
pub struct StudioRobot {
    /// Its name (`panda`).
    pub name: String,
    /// Model, initial configuration, execution settings.
    pub setup: RobotSetup,
    /// Its joint names, limits and inertias (for the limit check and the exports).
    pub model: cps_movement::robot_file::RobotModel,
}

/// The robot at rest, for the page to draw before anything is learned.
#[derive(Debug, Clone, Serialize)]
pub struct RobotView {
    /// The robot's name.
    pub name: String,
    /// Joints.
    pub dof: usize,
    /// The points to draw at the initial configuration: base, each joint's frame origin,
    /// tool (world frame, metres).
    pub points: Vec<[f64; 3]>,
}

/// A learned movement executed on the robot.
#[derive(Debug, Clone, Serialize)]
pub struct RobotAnswer {
    /// Why the robot cannot execute the task: the first way point out of reach, with its
    /// distance to the reachable set (nothing is executed then).
    pub unreachable: Option<String>,
    /// Times of the drawn poses, seconds.
    pub t: Vec<f64>,
    /// The drawn poses: per time, the points of [`RobotView::points`].
    pub frames: Vec<Vec<[f64; 3]>>,
    /// The executed tool path at the control period.
    pub tool: Vec<[f64; 3]>,
    /// The executed tool's largest distance from its target (m).
    pub max_tracking_error_m: f64,
    /// Samples the controller did not reach within its iteration cap.
    pub unconverged: usize,
    /// The executed joint movement against every limit at 1 kHz, as `cps-cli limits
    /// check` reports it (`ok`, peak usages, violations).
    pub limit_usage: serde_json::Value,
    /// The same in words, one line per finding.
    pub limit_lines: Vec<String>,
}

impl StudioRobot {
    /// The thesis's scene: the Panda placed as in its CoppeliaSim scene.
    pub fn thesis() -> Result<Self, String> {
        let scene = cps_movement::scene::Scene::thesis().map_err(|e| e.to_string())?;
        Ok(Self {
            name: scene.robot.name.clone(),
            setup: RobotSetup {
                chain: scene.robot.chain.clone(),
                initial_q: scene.initial_q,
                execution: cps_robot::ExecutionConfig::default(),
            },
            model: scene.robot,
        })
    }

    /// The robot at rest.
    pub fn view(&self) -> RobotView {
        RobotView {
            name: self.name.clone(),
            dof: self.setup.chain.dof(),
            points: points(&self.setup.chain, &self.setup.initial_q),
        }
    }

    /// Checks that the task's way points are reachable, then executes `traj` from the
    /// initial configuration on the in-process robot, stepped at the movement's `dt`,
    /// and, with `limits`, checks the executed movement against every limit at 1 kHz.
    pub fn execute(
        &self,
        task: &ViaPointTask,
        traj: &Trajectory,
        limits: bool,
    ) -> Result<RobotAnswer, String> {
        let mut answer = RobotAnswer {
            unreachable: None,
            t: Vec::new(),
            frames: Vec::new(),
            tool: Vec::new(),
            max_tracking_error_m: 0.0,
            unconverged: 0,
            limit_usage: serde_json::Value::Null,
            limit_lines: Vec::new(),
        };
        match check_way_points(task, &self.setup) {
            Ok(_) => {}
            Err(e @ LearnError::Unreachable { .. }) => {
                answer.unreachable = Some(e.to_string());
                return Ok(answer);
            }
            Err(e) => return Err(e.to_string()),
        }
        let dt = task.dmp.dt;
        let rec = self.run(traj, dt)?;
        if limits {
            let usage =
                cps_movement::limits::check_samples(&self.model, &self.joints(&rec), 1000.0)
                    .map_err(|e| e.to_string())?;
            answer.limit_usage = usage.json();
            answer.limit_lines = usage.lines();
        }
        let every = ((1.0 / FRAMES_PER_SECOND) / dt).round().max(1.0) as usize;
        for (k, q) in rec.q.iter().enumerate() {
            if k % every == 0 || k + 1 == rec.q.len() {
                answer.t.push(k as f64 * dt);
                answer.frames.push(points(&self.setup.chain, q));
            }
        }
        answer.tool = rec.position.clone();
        answer.max_tracking_error_m = rec.max_position_error();
        answer.unconverged = rec.unconverged;
        Ok(answer)
    }
}

impl StudioRobot {
    /// Executes `traj` from the initial configuration, stepped every `dt`.
    fn run(&self, traj: &Trajectory, dt: f64) -> Result<Recording, String> {
        let mut robot = KinematicRobot::new(self.setup.chain.clone(), &self.setup.initial_q, dt)
            .map_err(|e| e.to_string())?;
        execute_trajectory(&mut robot, &self.setup, traj, &StopToken::new())
            .map_err(|e| e.to_string())
    }

    /// The executed joints as a named joint trajectory.
    fn joints(&self, rec: &Recording) -> cps_movement::limits::JointTrajectory {
        cps_movement::limits::JointTrajectory {
            names: self.model.joint_names.clone(),
            times: rec.time.clone(),
            q: rec.q.clone(),
        }
    }

    /// `traj` executed and exported for ROS 2 and viewers (`ros2-yaml`, `mcap`,
    /// `csv-1khz`, as `cps-cli export`): the file's name suffix, content type and bytes.
    pub fn export(
        &self,
        traj: &Trajectory,
        dt: f64,
        format: &str,
    ) -> Result<(String, Vec<u8>), String> {
        use cps_movement::export::{ExportFormat, ExportOptions, export_samples};
        let format = ExportFormat::parse(format)?;
        let rec = self.run(traj, dt)?;
        let e = export_samples(
            &self.model,
            &self.joints(&rec),
            format,
            &ExportOptions::default(),
        )
        .map_err(|e| e.0)?;
        Ok((format.file_name().to_string(), e.bytes))
    }
}

/// Base, joint frame origins, tool: the robot's skeleton at `q`.
fn points(chain: &SerialChain, q: &[f64]) -> Vec<[f64; 3]> {
    let b = chain.base().translation.vector;
    let mut out = vec![[b.x, b.y, b.z]];
    if let Ok(pose) = chain.fk_frames(q) {
        for f in &pose.link_frames {
            let p = f.translation.vector;
            out.push([p.x, p.y, p.z]);
        }
        let p = pose.tool.translation.vector;
        out.push([p.x, p.y, p.z]);
    }
    out
}
