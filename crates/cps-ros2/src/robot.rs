//! A robot driven by ros2_control's `joint_trajectory_controller` as a robot of cps's
//! execution contract ([`cps_robot::Robot`]), and the one place a plan becomes a
//! `trajectory_msgs/JointTrajectory` ([`trajectory_message`]).
//!
//! A plan is sent as one FollowJointTrajectory goal — its points at their times (or the
//! motion resampled at a chosen period), with the velocities and accelerations of the
//! motion the guard checked — while the robot's `sensor_msgs/JointState` is recorded. Entry
//! k of the run is the measured joints at point k's time after the controller accepted the
//! goal (the joint states' header stamps against the acceptance stamp; where the robot
//! sends no stamps, arrival times against the answer's). The tool pose is the model's
//! forward kinematics of those joints. A stop token cancels the goal: the controller then
//! stops the arm as it is configured to.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use cps_robot::{Ending, Plan, Robot, RobotError, RobotModel, Run, StopToken};

use crate::Ros2Error;
use crate::action::{FollowJointTrajectoryClient, FollowOutcome, FollowTimes};
use crate::names::NodeName;
use crate::node::{Node, Qos, Reader};
use crate::record::{JointRecording, RecordOptions, record_joint_states};
use crate::service::MappingChoice;
use cps_ros2_msg::msg::{
    FollowJointTrajectoryGoal, GoalId, JointState, JointTrajectory, JointTrajectoryPoint, Time,
    error_code_word,
};

/// The node name cps takes on the graph.
pub const NODE_NAME: &str = "cps";

/// A plan as the message a controller takes: the motion sampled every `period` seconds
/// (None: at the plan's own points) from time 0 — the start where the robot stands — to
/// the end, each point with the motion's velocities and accelerations there;
/// `time_from_start` exact to the nanosecond.
pub fn trajectory_message(names: &[String], plan: &Plan, period: Option<f64>) -> JointTrajectory {
    let times: Vec<f64> = match period {
        None => (0..plan.points().len()).map(|k| plan.time(k)).collect(),
        Some(p) => {
            let span = plan.duration();
            let steps = (span / p - 1e-9).ceil().max(1.0) as usize;
            (0..=steps).map(|k| (k as f64 * p).min(span)).collect()
        }
    };
    let points = times
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let s = plan.state_at(t);
            let at_point = period.is_none();
            JointTrajectoryPoint {
                // On a point, the point itself rather than the spline's rounding of it.
                positions: if at_point {
                    plan.points()[k].clone()
                } else {
                    s.q
                },
                velocities: s.d1,
                accelerations: s.d2,
                effort: vec![],
                time_from_start: Time::from_secs(t),
            }
        })
        .collect();
    JointTrajectory {
        joint_names: names.to_vec(),
        points,
        ..JointTrajectory::default()
    }
}

/// The recorded joints at each time of `at` (s from the goal's acceptance), linearly
/// between messages; None past the recording's end.
pub fn rows_at(rec: &JointRecording, outcome: &FollowOutcome, at: &[f64]) -> Option<Vec<Vec<f64>>> {
    let (_, source) = rec.times();
    let (times, zero): (&[u64], u64) = if source == "stamp" {
        let s = outcome.accepted_stamp;
        (
            &rec.stamps_ns,
            s.sec.max(0) as u64 * 1_000_000_000 + s.nanosec as u64,
        )
    } else {
        (&rec.received_ns, outcome.accepted_at_ns)
    };
    let t: Vec<f64> = times
        .iter()
        .map(|&x| (x as f64 - zero as f64) * 1e-9)
        .collect();
    at.iter()
        .map(|&want| {
            let i = t.partition_point(|&x| x < want);
            if i == t.len() {
                return None;
            }
            if i == 0 {
                return Some(rec.positions[0].clone());
            }
            let s = (want - t[i - 1]) / (t[i] - t[i - 1]);
            Some(
                rec.positions[i - 1]
                    .iter()
                    .zip(&rec.positions[i])
                    .map(|(a, b)| a + s * (b - a))
                    .collect(),
            )
        })
        .collect()
}

/// A goal id from the trajectory's own bytes, a counter and the time: unique per goal.
pub fn goal_id(message: &JointTrajectory, counter: u64) -> GoalId {
    use cps_ros2_msg::msg::Message;
    let bytes = message.to_cdr();
    let h = bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ *b as u64).wrapping_mul(0x0100_0000_01b3)
    });
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    GoalId::from_bits(((h as u128) << 64) ^ ((counter as u128) << 96) ^ now)
}

/// How to reach the controller.
#[derive(Debug, Clone, PartialEq)]
pub struct Ros2Settings {
    /// The controller (`/panda_arm_controller`).
    pub controller: String,
    /// The JointState topic (`/joint_states`).
    pub joint_states: String,
    /// The DDS domain (None: `ROS_DOMAIN_ID`, else 0).
    pub domain: Option<u16>,
    /// The action's request/reply mapping (default: the controller's middleware's).
    pub service_mapping: MappingChoice,
    /// The period plans are made at for it (s).
    pub dt: f64,
    /// The goal's point spacing (None: the plan's own points).
    pub goal_period: Option<f64>,
    /// How long to wait for the controller and the first joint state.
    pub wait: Duration,
    /// Joint names on the graph, in the model's order (None: the model's published names).
    pub joint_names: Option<Vec<String>>,
    /// Whether where the robot stands is read from its joint states before a plan is sent
    /// (so the guard checks the plan's start). False drives the controller blind: it is
    /// trusted to start from the plan's first point (a topic or an action whose joint states
    /// appear only once it moves).
    pub read_start: bool,
}

/// What the last goal came to: its message, its outcome and the joint states recorded
/// while it ran.
#[derive(Debug, Clone)]
pub struct LastGoal {
    /// The goal's trajectory as sent.
    pub message: JointTrajectory,
    /// What the controller answered.
    pub outcome: FollowOutcome,
    /// The robot's joint states while it ran (None: not recorded).
    pub recording: Option<JointRecording>,
}

/// A ROS 2 robot through its FollowJointTrajectory action and its joint states.
pub struct Ros2Robot {
    settings: Ros2Settings,
    node: Node,
    client: FollowJointTrajectoryClient,
    states: Option<Reader>,
    model: RobotModel,
    names: Vec<String>,
    latest: Option<Vec<f64>>,
    goals: u64,
    lost: u64,
    older: u64,
    last: Option<LastGoal>,
    /// The share of the running goal the controller reports done (`f64` bits).
    progress: Arc<AtomicU64>,
}

impl std::fmt::Debug for Ros2Robot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2Robot")
            .field("settings", &self.settings)
            .finish()
    }
}

fn graph_error(settings: &Ros2Settings, e: Ros2Error) -> RobotError {
    RobotError::Robot {
        robot: format!("ros2 {}", settings.controller),
        message: e.to_string(),
    }
}

impl Ros2Robot {
    /// Joins the graph as [`NODE_NAME`] and prepares the action client. With
    /// `settings.joint_states` non-empty, the robot's joint states are recorded while it
    /// moves, and with `settings.read_start` they are waited for (up to `settings.wait`) and
    /// checked to name every joint of `model`; with the topic empty, the robot is driven
    /// blind (nothing recorded; [`Robot::joint_positions`] fails).
    pub fn open(settings: &Ros2Settings, model: RobotModel) -> Result<Self, RobotError> {
        let e = |x: Ros2Error| graph_error(settings, x);
        let name = NodeName::from_env(NODE_NAME, settings.domain).map_err(e)?;
        let node = Node::new(name).map_err(e)?;
        let action = format!(
            "{}/follow_joint_trajectory",
            settings.controller.trim_end_matches('/')
        );
        let client =
            FollowJointTrajectoryClient::with_mapping(&node, &action, settings.service_mapping)
                .map_err(e)?;
        let states = if settings.joint_states.is_empty() {
            None
        } else {
            Some(
                node.subscription::<JointState>(
                    &settings.joint_states,
                    Qos::Reliable { depth: 100 },
                )
                .map_err(e)?,
            )
        };
        let names = settings
            .joint_names
            .clone()
            .unwrap_or_else(|| model.published_joint_names());
        let mut robot = Ros2Robot {
            settings: settings.clone(),
            node,
            client,
            states,
            names,
            model,
            latest: None,
            goals: 0,
            lost: 0,
            older: 0,
            last: None,
            progress: Arc::new(AtomicU64::new(0f64.to_bits())),
        };
        if robot.states.is_some() && settings.read_start {
            robot.measured()?;
        }
        Ok(robot)
    }

    /// The node (to publish on the same participant).
    pub fn node(&self) -> &Node {
        &self.node
    }

    /// The joint names on the graph, in the model's order.
    pub fn joint_names(&self) -> &[String] {
        &self.names
    }

    /// The share (0 to 1, `f64` bits) of the running goal the controller reports done, for a
    /// caller watching [`Robot::run`] from another thread.
    pub fn progress(&self) -> Arc<AtomicU64> {
        Arc::clone(&self.progress)
    }

    /// The last goal: its message, the controller's answer, the joint states recorded.
    pub fn last_goal(&self) -> Option<&LastGoal> {
        self.last.as_ref()
    }

    fn error(&self, message: String) -> RobotError {
        RobotError::Robot {
            robot: self.name(),
            message,
        }
    }

    /// The newest joint positions (waiting up to `wait` for a first message).
    fn measured(&mut self) -> Result<Vec<f64>, RobotError> {
        let Some(states) = self.states.as_mut() else {
            return Err(RobotError::Robot {
                robot: format!("ros2 {}", self.settings.controller),
                message: "no joint state topic to read where the robot stands".into(),
            });
        };
        let deadline = Instant::now() + self.settings.wait;
        loop {
            let mut seen: Option<Vec<String>> = None;
            while let Some(r) = states.take::<JointState>() {
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
            if Instant::now() >= deadline {
                let message = match seen {
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
                };
                return Err(self.error(message));
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Sends `message` as one goal and follows it to its end while recording the joint
    /// states (when the robot has a topic for them); `on_progress` sees the share of the
    /// trajectory the controller reports done. The goal's outcome, whatever it is (the
    /// caller words a refusal or an abort); errors only when the controller cannot be
    /// reached or answers nothing.
    pub fn follow(
        &mut self,
        message: JointTrajectory,
        stop: &StopToken,
        mut on_progress: impl FnMut(f64),
    ) -> Result<&LastGoal, RobotError> {
        let duration = message
            .points
            .last()
            .map_or(0.0, |p| p.time_from_start.secs());
        self.goals += 1;
        let id = goal_id(&message, self.goals);
        let stop_recording = AtomicBool::new(false);
        let options = RecordOptions {
            topic: self.settings.joint_states.clone(),
            joints: self.names.clone(),
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
            trajectory: message.clone(),
            goal_time_tolerance: Time::default(),
        };
        let record = self.states.is_some();
        let (node, client) = (&self.node, &mut self.client);
        let (recorded, outcome) = std::thread::scope(|s| {
            let recorder = record
                .then(|| s.spawn(|| record_joint_states(node, &options, &stop_recording, |_| {})));
            let _moving = stop.moving();
            let outcome = client.follow(&goal, id, times, stop.flag(), |f| {
                if duration > 0.0 {
                    on_progress((f.desired.time_from_start.secs() / duration).clamp(0.0, 1.0));
                }
            });
            if recorder.is_some() {
                // The last states are published as the result is: take them too.
                std::thread::sleep(Duration::from_millis(200));
            }
            stop_recording.store(true, Ordering::Relaxed);
            (recorder.map(|h| h.join()), outcome)
        });
        let outcome = outcome.map_err(|x| graph_error(&self.settings, x))?;
        let recording = match recorded {
            None => None,
            Some(r) => Some(
                r.map_err(|_| self.error("the recorder panicked".into()))?
                    .map_err(|x| graph_error(&self.settings, x))?,
            ),
        };
        if let Some(r) = &recording {
            self.lost += r.lost;
            self.older += r.older;
            if let Some(q) = r.positions.last() {
                self.latest = Some(q.clone());
            }
        }
        self.last = Some(LastGoal {
            message,
            outcome,
            recording,
        });
        Ok(self.last.as_ref().expect("just set"))
    }
}

/// A goal that did not succeed, in words.
pub fn goal_sentence(outcome: &FollowOutcome) -> String {
    if let Some(lost) = &outcome.lost {
        lost.clone()
    } else if !outcome.accepted {
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
    }
}

impl Robot for Ros2Robot {
    fn name(&self) -> String {
        format!("ros2 {}", self.settings.controller)
    }

    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn dt(&self) -> f64 {
        self.settings.dt
    }

    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        self.measured()
    }

    fn standing(&mut self) -> Result<Option<Vec<f64>>, RobotError> {
        if self.settings.read_start {
            self.measured().map(Some)
        } else {
            Ok(None)
        }
    }

    /// One goal for the whole plan; the run's entries are the recorded joint states at the
    /// points' times. A goal the controller refuses is an error (nothing moved); one it
    /// aborts or that is cancelled ends the run with what was recorded.
    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
        plan.check_dof(self.model.chain.dof())?;
        if stop.is_stopped() {
            // Stopped before moving: no goal is sent; where it stands, when it is read.
            let mut run = Run::new(Ending::Stopped);
            if self.settings.read_start {
                let q = self.measured()?;
                let tool = self.model.chain.fk(&q)?;
                run.push(0.0, q, tool);
            }
            return Ok(run);
        }
        let message = trajectory_message(&self.names, plan, self.settings.goal_period);
        let share = Arc::clone(&self.progress);
        share.store(0f64.to_bits(), Ordering::Relaxed);
        let last = self
            .follow(message, stop, |done| {
                share.store(done.to_bits(), Ordering::Relaxed)
            })?
            .clone();
        let outcome = &last.outcome;
        if !outcome.accepted {
            return Err(self.error(goal_sentence(outcome)));
        }
        let mut run = Run::new(if outcome.succeeded() {
            Ending::Finished
        } else if stop.is_stopped() && outcome.lost.is_none() {
            Ending::Stopped
        } else {
            Ending::Failed(goal_sentence(outcome))
        });
        let Some(rec) = &last.recording else {
            return Ok(run);
        };
        let at: Vec<f64> = (0..plan.points().len()).map(|k| plan.time(k)).collect();
        // Every point the recording reaches (a goal that ended early reaches fewer).
        let rows: Vec<Vec<f64>> = match rows_at(rec, outcome, &at) {
            Some(rows) => rows,
            None => {
                let mut rows = Vec::new();
                for &t in &at {
                    match rows_at(rec, outcome, &[t]) {
                        Some(mut r) => rows.push(r.remove(0)),
                        None => break,
                    }
                }
                if run.ending == Ending::Finished {
                    run.ending = Ending::Failed(format!(
                        "the joint states on {} stop before the movement's end ({} message(s) recorded)",
                        self.settings.joint_states,
                        rec.positions.len()
                    ));
                }
                rows
            }
        };
        for (k, q) in rows.into_iter().enumerate() {
            let tool = self.model.chain.fk(&q)?;
            run.push(plan.time(k), q, tool);
        }
        Ok(run)
    }

    fn report(&self) -> Option<String> {
        (self.goals > 0).then(|| {
            format!(
                "{} goal(s) to {}/follow_joint_trajectory, joint states from {} ({} lost){}",
                self.goals,
                self.settings.controller,
                self.settings.joint_states,
                self.lost,
                if self.older > 0 {
                    format!(
                        "; {} published before a recording began, dropped",
                        self.older
                    )
                } else {
                    String::new()
                }
            )
        })
    }
}
