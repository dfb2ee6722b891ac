//! `[robot] backend = "ros2"`: a robot driven by ros2_control's
//! joint_trajectory_controller as a [`RobotBackend`], so the robot kinds (imitation, promp,
//! viapoint_joint, viapoint_executed) execute what they learned on any ROS 2 arm.
//!
//! A planned sequence (one row every `dt`) is checked whole against the scene robot's
//! limits, then sent as one FollowJointTrajectory goal (positions, and velocities by
//! central differences, rest at both ends); while the controller runs it, the robot's
//! `sensor_msgs/JointState` is recorded, and row k of the recording is the measured joints
//! at (k + 1)·dt after the controller accepted the goal (its header stamps against the
//! goal's acceptance stamp; where the robot sends no stamps, arrival times against the
//! answer's). The tool pose is the scene model's forward kinematics of those joints.
//!
//! [`STOP`] set by the host program (Ctrl-C) cancels the goal:
//! the controller then stops the arm as it is configured to.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use cps_kinematics::{KinematicsError, RobotBackend, SerialChain, StepRecording};
use cps_ros2::action::{FollowJointTrajectoryClient, FollowOutcome, FollowTimes};
use cps_ros2::msg::{
    FollowJointTrajectoryGoal, GoalId, JointState, JointTrajectory, JointTrajectoryPoint, Time,
    error_code_word,
};
use cps_ros2::names::NodeName;
use cps_ros2::node::{Node, Qos, Reader};
use cps_ros2::record::{JointRecording, RecordOptions, record_joint_states};
use nalgebra::IsometryMatrix3;

use crate::franka_backend::STOP;
use crate::robot_file::RobotModel;

/// The settings of [`Ros2Backend::open`].
#[derive(Debug, Clone, PartialEq)]
pub struct Ros2Settings {
    /// The controller (`/panda_arm_controller`).
    pub controller: String,
    /// The JointState topic (`/joint_states`).
    pub joint_states: String,
    /// The DDS domain (None: `ROS_DOMAIN_ID`, else 0).
    pub domain: Option<u16>,
    /// The control period the movement is planned at (s).
    pub dt: f64,
    /// How long to wait for the controller and the first joint state.
    pub wait: Duration,
}

/// The share of the velocity limits a move to a start configuration uses.
const APPROACH_SHARE: f64 = 0.2;

/// How far (rad) the robot may be from a start configuration without moving there.
const AT_START: f64 = 1e-3;

/// A ROS 2 robot as an experiment's backend.
pub struct Ros2Backend {
    settings: Ros2Settings,
    node: Node,
    client: FollowJointTrajectoryClient,
    states: Reader,
    model: RobotModel,
    /// The scene's chain (base and tool placed): tool poses in the world frame.
    chain: SerialChain,
    names: Vec<String>,
    latest: Option<Vec<f64>>,
    clock: f64,
    goals: u64,
    lost: u64,
    seq: u128,
}

impl std::fmt::Debug for Ros2Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2Backend")
            .field("settings", &self.settings)
            .finish()
    }
}

fn error(settings: &Ros2Settings, message: String) -> KinematicsError {
    KinematicsError::Backend {
        backend: format!("ros2 {}", settings.controller),
        message,
    }
}

impl Ros2Backend {
    /// Joins the graph, finds the robot's joint states (within `settings.wait`), and
    /// checks the robot reports every joint of `model` (its names; tool poses through
    /// `chain`, the scene's).
    pub fn open(
        settings: &Ros2Settings,
        model: &RobotModel,
        chain: &SerialChain,
    ) -> Result<Self, KinematicsError> {
        let e = |m: String| error(settings, m);
        let name = NodeName::from_env(crate::ros2::NODE_NAME, settings.domain)
            .map_err(|x| e(x.to_string()))?;
        let node = Node::new(name).map_err(|x| e(x.to_string()))?;
        let action = format!(
            "{}/follow_joint_trajectory",
            settings.controller.trim_end_matches('/')
        );
        let client =
            FollowJointTrajectoryClient::new(&node, &action).map_err(|x| e(x.to_string()))?;
        let states = node
            .subscription::<JointState>(&settings.joint_states, Qos::Reliable { depth: 100 })
            .map_err(|x| e(x.to_string()))?;
        let mut backend = Ros2Backend {
            settings: settings.clone(),
            node,
            client,
            states,
            names: crate::export::joint_names(model),
            model: model.clone(),
            chain: chain.clone(),
            latest: None,
            clock: 0.0,
            goals: 0,
            lost: 0,
            seq: 0,
        };
        backend.measured()?;
        Ok(backend)
    }

    /// The newest joint positions (waiting up to `wait` for a first message).
    fn measured(&mut self) -> Result<Vec<f64>, KinematicsError> {
        let deadline = std::time::Instant::now() + self.settings.wait;
        loop {
            let mut seen: Option<Vec<String>> = None;
            while let Some(r) = self.states.take::<JointState>() {
                let m = r.message;
                let cols: Option<Vec<usize>> = self
                    .names
                    .iter()
                    .map(|n| m.name.iter().position(|x| x == n))
                    .collect();
                match cols {
                    Some(c) if m.position.len() == m.name.len() => {
                        self.latest = Some(c.iter().map(|&i| m.position[i]).collect());
                    }
                    _ => seen = Some(m.name),
                }
            }
            if let Some(q) = &self.latest {
                return Ok(q.clone());
            }
            if std::time::Instant::now() >= deadline {
                return Err(error(
                    &self.settings,
                    match seen {
                        Some(names) => format!(
                            "the joint states on {} name {}, not every joint of the {} ({})",
                            self.settings.joint_states,
                            names.join(", "),
                            self.model.name,
                            self.names.join(", ")
                        ),
                        None => format!(
                            "no joint state arrived on {} within {:.1} s",
                            self.settings.joint_states,
                            self.settings.wait.as_secs_f64()
                        ),
                    },
                ));
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Runs `rows` (positions every `dt`, reached at (k + 1)·dt) as one goal while
    /// recording the robot; the recording and the goal's outcome.
    fn follow(
        &mut self,
        rows: &[Vec<f64>],
        dt: f64,
    ) -> Result<(JointRecording, FollowOutcome), KinematicsError> {
        let names = self.names.clone();
        let trajectory = goal_trajectory(&names, rows, dt);
        let duration = dt * rows.len() as f64;
        self.seq += 1;
        let id = GoalId::from_bits(
            (std::process::id() as u128) << 96
                ^ (self.seq << 64)
                ^ std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos()),
        );
        let stop_recording = AtomicBool::new(false);
        let options = RecordOptions {
            topic: self.settings.joint_states.clone(),
            joints: names,
            duration: Duration::from_secs_f64(duration * 1.5 + 60.0),
            wait: self.settings.wait,
            qos: Qos::Reliable { depth: 5000 },
        };
        let times = FollowTimes {
            server: self.settings.wait,
            result: Duration::from_secs_f64(duration * 1.5 + 10.0),
            after_cancel: Duration::from_secs(5),
        };
        let goal = FollowJointTrajectoryGoal {
            trajectory,
            goal_time_tolerance: Time::default(),
        };
        let (node, client) = (&self.node, &mut self.client);
        let (recorded, outcome) = std::thread::scope(|s| {
            let recorder = s.spawn(|| record_joint_states(node, &options, &stop_recording, |_| {}));
            let outcome = client.follow(&goal, id, times, &STOP, |_| {});
            // The last states are published as the result is: take them too.
            std::thread::sleep(Duration::from_millis(200));
            stop_recording.store(true, std::sync::atomic::Ordering::Relaxed);
            (recorder.join(), outcome)
        });
        let e = |m: String| error(&self.settings, m);
        let outcome = outcome.map_err(|x| e(x.to_string()))?;
        self.goals += 1;
        if !outcome.succeeded() {
            return Err(e(if !outcome.accepted {
                "the controller refused the goal".into()
            } else {
                format!(
                    "the goal {}: error code {} ({}){}",
                    outcome.status.word(),
                    outcome.error_code,
                    error_code_word(outcome.error_code),
                    if outcome.error_string.is_empty() {
                        String::new()
                    } else {
                        format!(", \"{}\"", outcome.error_string)
                    }
                )
            }));
        }
        let recorded = recorded
            .map_err(|_| e("the recorder panicked".into()))?
            .map_err(|x| e(x.to_string()))?;
        self.lost += recorded.lost;
        if let Some(q) = recorded.positions.last() {
            self.latest = Some(q.clone());
        }
        Ok((recorded, outcome))
    }

    /// Moves the robot to `q` at rest, at [`APPROACH_SHARE`] of its velocity limits.
    fn approach(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        let from = self.measured()?;
        let far = from
            .iter()
            .zip(q)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if far <= AT_START {
            return Ok(());
        }
        let vmax = self
            .model
            .chain
            .velocity_limits()
            .map_or_else(|| vec![1.0; q.len()], <[f64]>::to_vec);
        // A cosine blend peaks at π/2 · distance / T.
        let t = from
            .iter()
            .zip(q)
            .zip(&vmax)
            .map(|((a, b), v)| std::f64::consts::FRAC_PI_2 * (a - b).abs() / (APPROACH_SHARE * v))
            .fold(1.0, f64::max);
        let dt = self.settings.dt;
        let n = (t / dt).ceil() as usize;
        let rows: Vec<Vec<f64>> = (1..=n)
            .map(|k| {
                let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / n as f64).cos();
                from.iter().zip(q).map(|(a, b)| a + s * (b - a)).collect()
            })
            .collect();
        self.follow(&rows, dt).map(|_| ())
    }
}

/// The goal's points: row k at (k + 1)·dt, velocities by central differences, at rest at
/// the last point.
fn goal_trajectory(names: &[String], rows: &[Vec<f64>], dt: f64) -> JointTrajectory {
    let n = rows.len();
    let points = (0..n)
        .map(|k| {
            let velocities = if k + 1 == n {
                vec![0.0; rows[k].len()]
            } else {
                let before = if k == 0 { &rows[0] } else { &rows[k - 1] };
                let span = if k == 0 { dt } else { 2.0 * dt };
                rows[k + 1]
                    .iter()
                    .zip(before)
                    .map(|(a, b)| (a - b) / span)
                    .collect()
            };
            JointTrajectoryPoint {
                positions: rows[k].clone(),
                velocities,
                accelerations: vec![],
                effort: vec![],
                time_from_start: Time::from_secs((k + 1) as f64 * dt),
            }
        })
        .collect();
    JointTrajectory {
        joint_names: names.to_vec(),
        points,
        ..JointTrajectory::default()
    }
}

impl RobotBackend for Ros2Backend {
    fn dof(&self) -> usize {
        self.model.chain.dof()
    }

    fn time_step(&self) -> f64 {
        self.settings.dt
    }

    fn joint_positions(&mut self) -> Result<Vec<f64>, KinematicsError> {
        self.measured()
    }

    fn command_joint_positions(&mut self, _q: &[f64]) -> Result<(), KinematicsError> {
        Err(error(
            &self.settings,
            "runs whole sequences only (one goal each)".into(),
        ))
    }

    fn command_joint_velocities(&mut self, _dq: &[f64]) -> Result<(), KinematicsError> {
        Err(error(
            &self.settings,
            "runs whole sequences only (one goal each)".into(),
        ))
    }

    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, KinematicsError> {
        let q = self.measured()?;
        self.chain.fk(&q)
    }

    fn time(&mut self) -> Result<f64, KinematicsError> {
        Ok(self.clock)
    }

    fn step(&mut self) -> Result<(), KinematicsError> {
        Err(error(
            &self.settings,
            "runs whole sequences only (one goal each)".into(),
        ))
    }

    /// Moves the robot to `q` (a rest-to-rest goal at 20 % of its speed limits) and sets
    /// the clock to 0.
    fn reset(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        self.approach(q)?;
        self.clock = 0.0;
        Ok(())
    }

    fn runs_sequences(&self) -> bool {
        true
    }

    fn execution_report(&self) -> Option<String> {
        (self.goals > 0).then(|| {
            format!(
                "{} goal(s) to {}/follow_joint_trajectory, joint states from {} ({} lost)",
                self.goals, self.settings.controller, self.settings.joint_states, self.lost
            )
        })
    }

    fn run_joint_targets(
        &mut self,
        targets: &[Vec<f64>],
    ) -> Result<StepRecording, KinematicsError> {
        let dt = self.settings.dt;
        if targets.is_empty() {
            return Ok(StepRecording::default());
        }
        // Nothing is sent that breaks a limit: the whole sequence, from where the robot
        // stands, checked first.
        let mut times = vec![0.0];
        let mut q = vec![self.measured()?];
        for (k, r) in targets.iter().enumerate() {
            times.push((k + 1) as f64 * dt);
            q.push(r.clone());
        }
        let traj = crate::limits::JointTrajectory {
            names: self.names.clone(),
            times,
            q,
        };
        let report = crate::limits::check_samples(&self.model, &traj, 1.0 / dt)?;
        if !report.ok() {
            return Err(error(
                &self.settings,
                format!(
                    "refused, nothing was sent: the planned movement breaks the {}'s limits: {}",
                    self.model.name,
                    report.lines().join("; ")
                ),
            ));
        }
        let (rec, outcome) = self.follow(targets, dt)?;
        let at: Vec<f64> = (1..=targets.len()).map(|k| k as f64 * dt).collect();
        let rows = crate::ros2::rows_at(&rec, &outcome, &at).ok_or_else(|| {
            error(
                &self.settings,
                format!(
                    "the joint states on {} stop before the movement's end ({} message(s) recorded)",
                    self.settings.joint_states,
                    rec.positions.len()
                ),
            )
        })?;
        let mut out = StepRecording::default();
        for (k, q) in rows.into_iter().enumerate() {
            out.tool.push(self.chain.fk(&q)?);
            out.q.push(q);
            out.time.push(self.clock + (k + 1) as f64 * dt);
        }
        self.clock += targets.len() as f64 * dt;
        Ok(out)
    }
}
