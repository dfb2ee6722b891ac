//! A learned policy's recorded action chunks to a ros2_control joint_trajectory_controller
//! (`cps-cli ros2 follow`): one JointTrajectory message per chunk on
//! `<controller>/joint_trajectory`, each replacing the last at its chunk's arrival.
//!
//! Each message is the chunk executor's motion from the chunk's arrival on, as it would go
//! if no other chunk came (the chunk followed, then braked to rest after the stall
//! timeout; the last chunk followed to its end): points every `period` with the motion's
//! velocities and accelerations, stamped with the arrival. The executor is deterministic,
//! so the message that replaces it starts exactly where the one before has the arm at
//! that instant, moving as it moves: the controller's motion stays continuous across the
//! replacements, differing from the commands only by how late the controller takes a
//! message (a jerk-limited divergence: micro-radians for milliseconds). If the policy, the
//! file or cps stops, the controller's last message already brakes the arm to rest.
//!
//! The whole motion (every millisecond) is checked by the guard first, as every plan is;
//! nothing is published if it breaks a limit.

use std::path::Path;
use std::time::{Duration, Instant, SystemTime};

use cps_chunks::{Chunk, ChunkExecutor, ChunkVerdict, FollowSettings, replay_with};
use cps_robot::{Guarded, Plan, Policy, Robot, RobotError, RobotModel, StopToken};
use cps_ros2::names::NodeName;
use cps_ros2::node::{Node, Qos};
use cps_ros2::robot::NODE_NAME;
use cps_ros2_msg::msg::{Header, JointTrajectory, JointTrajectoryPoint, Message, Time};

use cps_outcome::{Ended, InputError};

use crate::error::DriveError;
use crate::said::ChunksPublished;

use crate::ros2::GraphSettings;

/// The commands' period (s).
const DT: f64 = 1e-3;

/// What `ros2 follow` does.
#[derive(Debug, Clone)]
pub struct FollowTopic {
    /// The controller (`/panda_arm_controller`).
    pub controller: String,
    /// Robot, joint names, domain.
    pub graph: GraphSettings,
    /// Seconds between the points of a message (the controller interpolates).
    pub period: f64,
    /// Seconds to wait for the controller.
    pub wait: f64,
}

/// A point of a message: time from its start (s), positions, velocities, accelerations.
pub type Point = (f64, Vec<f64>, Vec<f64>, Vec<f64>);

/// The executor's motion every millisecond, one replacement per chunk taken, and the
/// chunks refused with why.
pub type Replacements = (Plan, Vec<Replacement>, Vec<(usize, String)>);

/// One message: when its chunk arrived (s from the stream's start) and its points.
#[derive(Debug, Clone)]
pub struct Replacement {
    /// The chunk's index in the file.
    pub chunk: usize,
    /// Its arrival (s).
    pub at_s: f64,
    /// The motion from the arrival on, every `period` (time from the arrival, q, dq, ddq).
    pub points: Vec<Point>,
}

/// The executor's motion from rest at `start` for `chunks` (every millisecond), and one
/// replacement per chunk taken (see the module's text); the chunks refused with why.
pub fn replacements(
    model: &RobotModel,
    start: &[f64],
    chunks: &[Chunk],
    settings: &FollowSettings,
    period: f64,
) -> Result<Replacements, cps_chunks::FollowError> {
    let mut out = Vec::new();
    let (plan, log) = replay_with(model, start, DT, chunks, settings, &mut |taken| {
        out.push(Replacement {
            chunk: taken.chunk,
            at_s: taken.t,
            points: predicted(taken.executor, taken.last, taken.t, period),
        });
    })?;
    let refused = log
        .entries
        .iter()
        .enumerate()
        .filter_map(|(i, (_, v))| match v {
            Some(ChunkVerdict::Refused(why)) => Some((i, why.to_string())),
            _ => None,
        })
        .collect();
    Ok((plan, out, refused))
}

/// The motion of `ex` from `t` on if no other chunk came (the last chunk: followed to its
/// end), from its last command, sampled every `period` with its velocities and
/// accelerations: central differences of the millisecond commands, the one before the
/// last command rebuilt from its backward difference, so every point — the first
/// included — is differenced as the message before has it.
fn predicted(ex: &ChunkExecutor, last: bool, t: f64, period: f64) -> Vec<Point> {
    let mut c = ex.clone();
    if last {
        c.last_chunk();
    }
    let now = ex.position();
    let before: Vec<f64> = now
        .iter()
        .zip(ex.velocity())
        .map(|(q, v)| q - v * DT)
        .collect();
    let mut q = vec![before, now.to_vec()];
    for k in 1..=600_000 {
        q.push(c.tick(t + k as f64 * DT).to_vec());
        let done = if last {
            c.chunk_done(t + k as f64 * DT)
        } else {
            c.stalled_or_idle()
        };
        if done && c.at_rest() {
            break;
        }
    }
    let every = ((period / DT).round() as usize).max(1);
    let end = q.len() - 1;
    let at = |i: usize| {
        let (v, a) = if i < end {
            (0..now.len())
                .map(|j| {
                    (
                        (q[i + 1][j] - q[i - 1][j]) / (2.0 * DT),
                        (q[i + 1][j] - 2.0 * q[i][j] + q[i - 1][j]) / (DT * DT),
                    )
                })
                .unzip()
        } else {
            (vec![0.0; now.len()], vec![0.0; now.len()])
        };
        ((i - 1) as f64 * DT, q[i].clone(), v, a)
    };
    let mut points: Vec<Point> = (1..end).step_by(every).map(at).collect();
    points.push(at(end));
    points
}

fn time_of(t: SystemTime) -> Time {
    let d = t
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap_or(Duration::ZERO);
    Time {
        sec: d.as_secs() as i32,
        nanosec: d.subsec_nanos(),
    }
}

/// A controller's topic taking one replacement per chunk: a robot that publishes a plan
/// whose replacements it was given, each at its time. Only [`ros2_follow`] drives it,
/// behind the guard.
struct ChunkTopic {
    node_name: NodeName,
    topic: String,
    names: Vec<String>,
    model: RobotModel,
    wait: Duration,
    replacements: Vec<Replacement>,
    /// Messages published, and how late the last was against its arrival (s).
    published: usize,
    late_s: f64,
    subscribers: i32,
}

impl Robot for ChunkTopic {
    fn name(&self) -> String {
        format!("ros2 {}", self.topic)
    }
    fn model(&self) -> &RobotModel {
        &self.model
    }
    fn dt(&self) -> f64 {
        DT
    }
    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        Err(RobotError::Robot {
            robot: self.name(),
            message: "a topic reports no joint states".into(),
        })
    }
    fn standing(&mut self) -> Result<Option<Vec<f64>>, RobotError> {
        Ok(None)
    }
    /// Publishes each replacement at its chunk's arrival, stamped with it; a stop
    /// publishes no more (the controller's last message brakes the arm to rest).
    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<cps_robot::Run, RobotError> {
        let graph = |e: cps_ros2::Ros2Error| RobotError::Robot {
            robot: format!("ros2 {}", self.topic),
            message: e.to_string(),
        };
        let node = Node::new(self.node_name.clone()).map_err(graph)?;
        let mut writer = node
            .publisher::<JointTrajectory>(&self.topic, Qos::Reliable { depth: 10 })
            .map_err(graph)?;
        let begun = Instant::now();
        if !writer.wait_matched(begun + self.wait) {
            return Err(RobotError::Robot {
                robot: self.name(),
                message: format!(
                    "no subscriber to {} appeared within {:.1} s (is the controller active, on this ROS_DOMAIN_ID?)",
                    self.topic,
                    self.wait.as_secs_f64()
                ),
            });
        }
        std::thread::sleep(cps_ros2::node::settle(begun.elapsed().as_secs_f64()));
        self.subscribers = writer.matched();
        let (t0, wall0) = (Instant::now(), SystemTime::now());
        let mut ending = cps_robot::Ending::Finished;
        for r in &self.replacements {
            let due = t0 + Duration::from_secs_f64(r.at_s);
            while Instant::now() < due {
                if stop.is_stopped() {
                    break;
                }
                std::thread::sleep((due - Instant::now()).min(Duration::from_millis(5)));
            }
            if stop.is_stopped() {
                ending = cps_robot::Ending::Stopped;
                break;
            }
            let message = JointTrajectory {
                header: Header {
                    stamp: time_of(wall0 + Duration::from_secs_f64(r.at_s)),
                    frame_id: String::new(),
                },
                joint_names: self.names.clone(),
                points: r
                    .points
                    .iter()
                    .map(|(t, q, v, a)| JointTrajectoryPoint {
                        positions: q.clone(),
                        velocities: v.clone(),
                        accelerations: a.clone(),
                        effort: vec![],
                        time_from_start: Time::from_secs(*t),
                    })
                    .collect(),
            };
            writer.write_cdr(&message.to_cdr()).map_err(graph)?;
            self.late_s = self.late_s.max(due.elapsed().as_secs_f64());
            self.published += 1;
        }
        writer.wait_acknowledged(self.wait);
        let mut run = cps_robot::Run::new(ending);
        let start = plan.start().to_vec();
        let tool = self.model.chain.fk(&start)?;
        run.push(0.0, start, tool);
        Ok(run)
    }
}

/// `ros2 follow`: the chunks of `file` (targets at `rate_hz`) to the controller, one
/// replacement message per chunk (see the module's text), from where the first chunk has
/// the arm at its arrival (a topic reports no joint states). Returns the answer and how it
/// ended (completed: published; failed: refused or the controller missing; stopped).
pub fn ros2_follow(
    file: &Path,
    rate_hz: f64,
    s: &FollowTopic,
    settings: &FollowSettings,
    stop: &StopToken,
) -> Result<(ChunksPublished, Ended), DriveError> {
    settings.check().map_err(|e| InputError(e.to_string()))?;
    if !(s.period >= DT && s.period <= 1.0) {
        return Err(
            InputError(format!("--period {}: give seconds in [0.001, 1]", s.period)).into(),
        );
    }
    if !(s.wait.is_finite() && s.wait > 0.0 && s.wait <= 3600.0) {
        return Err(InputError(format!("--wait {}: give seconds in (0, 3600]", s.wait)).into());
    }
    let (model, names) = crate::ros2::robot_and_names(&s.graph)?;
    let me =
        NodeName::from_env(NODE_NAME, s.graph.domain).map_err(|e| InputError(e.to_string()))?;
    let controller = s.controller.trim_end_matches('/');
    if controller.is_empty() {
        return Err(InputError(format!(
            "--controller `{}`: give the controller's name, e.g. /panda_arm_controller",
            s.controller
        ))
        .into());
    }
    let topic = format!("{controller}/joint_trajectory");
    cps_ros2::names::resolve(&me, &topic)
        .map_err(|e| InputError(format!("--controller `{}`: {e}", s.controller)))?;
    let dof = model.chain.dof();
    let chunks = cps_movement::chunks::read_chunks(file, dof, rate_hz)?;
    let name = file.display().to_string();
    let first = &chunks[0];
    let start = first.targets[first.past_at(first.arrived_s).min(first.targets.len() - 1)].clone();
    let (plan, replacements, refused) = replacements(&model, &start, &chunks, settings, s.period)
        .map_err(|e| InputError(format!("{name}: {e}")))?;
    let count = replacements.len();
    let mut robot = Guarded::new(
        ChunkTopic {
            node_name: me,
            topic: topic.clone(),
            names: names.clone(),
            model: model.clone(),
            wait: Duration::from_secs_f64(s.wait),
            replacements,
            published: 0,
            late_s: 0.0,
            subscribers: 0,
        },
        Policy::STRICT,
    );
    let run = robot.run(&plan, stop).map_err(|e| match e {
        RobotError::Refused { robot, reason } => DriveError::Refused {
            sentence: format!(
                "{name}: refused before sending anything: the executor's motion for these chunks {}: {reason}",
                if matches!(reason, cps_robot::Refusal::Collision(_)) {
                    "comes too close"
                } else {
                    "breaks a limit"
                }
            ),
            source: Box::new(RobotError::Refused { robot, reason }),
        },
        RobotError::Robot { message, .. } => DriveError::Failed(message),
        other => DriveError::Robot(other),
    })?;
    let t = robot.into_inner();
    let published = ChunksPublished {
        file: name,
        controller: s.controller.clone(),
        topic,
        joint_names: names,
        robot: model.name.clone(),
        chunks: chunks.len(),
        replacements: count,
        published: t.published,
        refused,
        subscribers: t.subscribers,
        latest_s: t.late_s,
        duration_s: plan.duration(),
        complete: run.ending.complete(),
    };
    let code = match run.ending {
        cps_robot::Ending::Finished => Ended::Completed,
        cps_robot::Ending::Stopped => Ended::Stopped,
        _ => Ended::Failed,
    };
    Ok((published, code))
}
