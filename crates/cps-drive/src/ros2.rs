//! A ROS 2 robot from files and words (`cps-cli ros2 …`, Python's `cps.ros2`): a cps
//! joint CSV checked against the robot's limits and sent to a ros2_control
//! joint_trajectory_controller (its topic, or its FollowJointTrajectory action), and a
//! robot's `JointState` recorded as a cps joint CSV with a report. The graph itself is
//! `cps-ros2`'s.

use std::path::Path;
use std::time::Duration;

use cps_robot::{Guarded, Plan, Policy, Prepared, Refusal, Robot, RobotError, StopToken};
use cps_ros2::action::FollowOutcome;
use cps_ros2::names::NodeName;
use cps_ros2::node::{Node, Qos};
use cps_ros2::publish;
use cps_ros2::record::{JointRecording, RecordOptions, record_joint_states};
use cps_ros2::robot::{Ros2Robot, Ros2Settings, rows_at, trajectory_message};
use cps_ros2_msg::msg::JointTrajectory;
use serde_json::{Value, json};

use cps_movement::robot_file::{RobotModel, load_robot};
use cps_outcome::outcome::{Column, Format, Table};
use cps_outcome::{Ended, InputError};

use crate::error::DriveError;
use crate::said::{Sent, SentVia, StatesRecorded, Tracked};

pub use crate::ros2_graph::node;
pub use cps_ros2::robot::NODE_NAME;
pub use cps_ros2::service::{Mapping, MappingChoice};

/// How a trajectory reaches the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Via {
    /// `<controller>/joint_trajectory` (no answer: delivered is all cps knows).
    Topic,
    /// `<controller>/follow_joint_trajectory`: feedback, the result, cancel on Ctrl-C.
    Action,
}

/// The robot, its joints' names on the graph, and the domain.
#[derive(Debug, Clone)]
pub struct GraphSettings {
    /// The robot whose limits and joint names apply (`panda`, a file…).
    pub robot: String,
    /// Joint names instead of the robot's, in the robot's order.
    pub joint_names: Option<Vec<String>>,
    /// The DDS domain (None: `ROS_DOMAIN_ID`, else 0).
    pub domain: Option<u16>,
    /// A scene file whose obstacles every command is checked among, besides the robot
    /// itself ([`crate::scene::scene_shapes`]; its robot must be `robot`). None: the
    /// robot alone.
    pub scene: Option<std::path::PathBuf>,
}

impl GraphSettings {
    /// These settings with every command checked among the obstacles of `scene`, if given.
    pub fn in_scene(self, scene: Option<&Path>) -> Self {
        GraphSettings {
            scene: scene.map(Path::to_path_buf),
            ..self
        }
    }
}

/// Where and how to send.
#[derive(Debug, Clone)]
pub struct SendSettings {
    /// The controller's name (`/panda_arm_controller`).
    pub controller: String,
    /// Topic or action.
    pub via: Via,
    /// Robot, joint names, domain.
    pub graph: GraphSettings,
    /// Seconds between the points sent (the controller interpolates between them).
    pub period: f64,
    /// Seconds to wait for the controller to appear on the graph.
    pub wait: f64,
    /// Record the robot's joint states while the goal runs (action only).
    pub record: Option<SendRecord>,
    /// The action's request/reply mapping (default: the controller's middleware's).
    pub service_mapping: MappingChoice,
}

/// Where `ros2 send --record` writes what the robot did.
#[derive(Debug, Clone)]
pub struct SendRecord {
    /// The recording (CSV); its report goes beside it as `<stem>.report.json`.
    pub out: std::path::PathBuf,
    /// The JointState topic.
    pub topic: String,
    /// Replace existing files.
    pub force: bool,
}

/// The robot model of `graph` (among its scene's obstacles where it names one) and the
/// joint names for it (the robot's, or its names checked against the joint count).
pub(crate) fn robot_and_names(
    graph: &GraphSettings,
) -> Result<(RobotModel, Vec<String>), DriveError> {
    let (robot, names) = (&graph.robot, graph.joint_names.as_deref());
    let mut model = load_robot(robot, None, None)?;
    if let Some(scene) = &graph.scene {
        model.shapes = Some(crate::scene::scene_shapes(scene, &model.name)?);
    }
    let dof = model.chain.dof();
    let names = match names {
        None => cps_movement::export::joint_names(&model),
        Some(n) => {
            if n.len() != dof {
                return Err(InputError(format!(
                    "--joint-names: {} name(s) for the {}'s {dof} joints",
                    n.len(),
                    model.name
                ))
                .into());
            }
            if let Some(bad) = n
                .iter()
                .find(|s| s.trim().is_empty() || s.contains(char::is_whitespace))
            {
                return Err(
                    InputError(format!("--joint-names: `{bad}` is not a joint name")).into(),
                );
            }
            if let Some((i, _)) = n.iter().enumerate().find(|(i, s)| n[..*i].contains(s)) {
                return Err(InputError(format!("--joint-names: `{}` is named twice", n[i])).into());
            }
            n.to_vec()
        }
    };
    Ok((model, names))
}

/// A joint trajectory (called `name` in messages) as a plan: its own samples when they are
/// evenly spaced, else the cubic spline through them (at rest at both ends) sampled every
/// millisecond; times from its first sample.
pub fn plan_of(
    name: &str,
    traj: &cps_movement::limits::JointTrajectory,
    dof: usize,
) -> Result<Plan, DriveError> {
    let bad_row = traj
        .q
        .iter()
        .position(|r| r.len() != dof || r.iter().any(|x| !x.is_finite()));
    let increasing =
        traj.times.windows(2).all(|w| w[1] > w[0]) && traj.times.iter().all(|t| t.is_finite());
    if traj.times.len() < 2 || traj.q.len() != traj.times.len() || bad_row.is_some() || !increasing
    {
        return Err(InputError(format!(
            "{name}: a trajectory needs two or more samples at strictly increasing times, {dof} finite joint positions each{}",
            bad_row.map_or(String::new(), |k| format!(" (row {k} is not)"))
        ))
        .into());
    }
    let first = traj.times[1] - traj.times[0];
    let even = traj
        .times
        .windows(2)
        .all(|w| ((w[1] - w[0]) - first).abs() <= 1e-9 * first);
    let plan = if even {
        Plan::new(first, traj.q.clone())
    } else {
        let (_, dt, rows, _) = cps_movement::limits::at_rate(traj, 1.0 / cps_robot::CHECK_PERIOD)?;
        Plan::new(dt, rows)
    };
    plan.map_err(|e| InputError(format!("{name}: {e}")).into())
}

/// A refusal of the guard in `ros2 send`'s words.
fn refused(name: &str, model: &RobotModel, e: RobotError) -> DriveError {
    match e {
        RobotError::Refused { robot, reason } => DriveError::Refused {
            sentence: match &reason {
                // The path itself comes too close: to the robot, or to the scene's obstacles.
                Refusal::Collision(_) => format!("{name}: refused, nothing was sent: {reason}"),
                // (Never where the robot stands: `ros2 send` does not read it, and has no
                // approach to offer.)
                _ => format!(
                    "{name}: refused, nothing was sent: the trajectory breaks the {}'s limits: {reason}",
                    model.name,
                ),
            },
            source: Box::new(RobotError::Refused { robot, reason }),
        },
        other => DriveError::during(name, other),
    }
}

/// `ros2 send`: the file checked, then sent; returns the answer and how it ended
/// (failed: refused, aborted or cancelled for lateness; stopped: cancelled by `stop`). `progress` sees the share of
/// the trajectory the controller reports done (action only).
pub fn send(
    file: &Path,
    s: &SendSettings,
    stop: &StopToken,
    progress: impl FnMut(f64),
) -> Result<(Sent, Ended), DriveError> {
    let (model, _) = robot_and_names(&s.graph)?;
    let traj = cps_movement::limits::read_joint_trajectory(file, model.chain.dof())?;
    send_trajectory(&file.display().to_string(), &traj, s, stop, progress)
}

/// [`send`] for a trajectory in memory, called `name` in messages: a plan ([`plan_of`])
/// checked by the guard every robot runs behind (its limits; its start too where the
/// robot's joint states are read), made the controller's message by the one goal builder
/// ([`trajectory_message`]: points every `period`, with the motion's velocities and
/// accelerations), then published or followed as a goal.
pub fn send_trajectory(
    name: &str,
    traj: &cps_movement::limits::JointTrajectory,
    s: &SendSettings,
    stop: &StopToken,
    mut progress: impl FnMut(f64),
) -> Result<(Sent, Ended), DriveError> {
    if !(s.wait.is_finite() && s.wait > 0.0 && s.wait <= 3600.0) {
        return Err(InputError(format!("--wait {}: give seconds in (0, 3600]", s.wait)).into());
    }
    let (model, names) = robot_and_names(&s.graph)?;
    // A bad name or domain is the user's: named before anything joins the graph.
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
    cps_ros2::names::resolve(&me, &format!("{controller}/joint_trajectory"))
        .map_err(|e| InputError(format!("--controller `{}`: {e}", s.controller)))?;
    if let Some(r) = &s.record {
        if s.via == Via::Topic {
            return Err(InputError(
                "--record needs the action (a topic message has no start the recording could be compared from)".into(),
            )
            .into());
        }
        crate::recording::check_record_target(&r.out, r.force)?;
    }
    cps_movement::export::ExportOptions { period: s.period }.check()?;
    let plan = plan_of(name, traj, model.chain.dof())?;
    let wait = Duration::from_secs_f64(s.wait);
    // Judged once, before anything joins the graph: neither way reads where the robot
    // stands first (a topic is blind; the action's robot is opened without reading its
    // start), so the guard's verdict needs no node, and a refusal opens no DDS
    // participant. Both ways then run this verdict (`run_prepared`).
    let mut judge = Guarded::new(
        TopicRobot {
            node_name: me.clone(),
            topic: controller.to_string(),
            names: names.clone(),
            model: model.clone(),
            period: s.period,
            wait,
            sent: None,
        },
        Policy::STRICT,
    );
    let prepared = judge.prepare(&plan).map_err(|e| refused(name, &model, e))?;
    let to = Destination {
        name,
        model: &model,
        names: &names,
        controller,
        wait,
    };
    match s.via {
        Via::Topic => send_by_topic(&to, prepared, me, s, stop),
        Via::Action => send_by_action(&to, prepared, s, stop, &mut progress),
    }
}

/// Where [`send_trajectory`] sends a checked plan, and what it knows of the robot.
struct Destination<'a> {
    name: &'a str,
    model: &'a RobotModel,
    names: &'a [String],
    controller: &'a str,
    wait: Duration,
}

/// The plan published on the controller's topic, through the guard (one message, no
/// answer).
fn send_by_topic(
    to: &Destination<'_>,
    prepared: Prepared,
    me: NodeName,
    s: &SendSettings,
    stop: &StopToken,
) -> Result<(Sent, Ended), DriveError> {
    let Destination {
        name,
        model,
        names,
        controller,
        wait,
    } = *to;
    // Through the guard, with its verdict: published by the topic's robot (one message,
    // no answer).
    let topic = format!("{controller}/joint_trajectory");
    let mut robot = Guarded::new(
        TopicRobot {
            node_name: me,
            topic: topic.clone(),
            names: names.to_vec(),
            model: model.clone(),
            period: s.period,
            wait,
            sent: None,
        },
        Policy::STRICT,
    );
    let run = robot
        .run_prepared(prepared, stop)
        .map_err(|e| sent_or_refused(name, model, e))?;
    let Some((node, message, sent)) = robot.into_inner().sent else {
        return Err(DriveError::Failed("the topic's run sent nothing".into()));
    };
    let domain = node.name().domain;
    let via = SentVia::Topic {
        topic,
        published: sent,
    };
    let sent = sent_of(name, s, domain, names, &message, via);
    Ok((sent, Ended::of(run.ending.complete())))
}

/// The plan followed as a FollowJointTrajectory goal through the guard, its progress
/// reported, its outcome (and the recording, with `--record`) the answer.
fn send_by_action(
    to: &Destination<'_>,
    prepared: Prepared,
    s: &SendSettings,
    stop: &StopToken,
    progress: &mut impl FnMut(f64),
) -> Result<(Sent, Ended), DriveError> {
    let Destination {
        name,
        model,
        names,
        controller,
        wait,
    } = *to;
    let settings = Ros2Settings {
        controller: s.controller.clone(),
        joint_states: s.record.as_ref().map_or(String::new(), |r| r.topic.clone()),
        domain: s.graph.domain,
        service_mapping: s.service_mapping,
        dt: s.period,
        goal_period: Some(s.period),
        wait,
        joint_names: Some(names.to_vec()),
        read_start: false,
    };
    let robot = Ros2Robot::open(&settings, model.clone()).map_err(robot_message)?;
    let mut robot = Guarded::new(robot, Policy::STRICT);
    let message = trajectory_message(names, &prepared.plan, Some(s.period));
    let action = format!("{controller}/follow_joint_trajectory");
    let domain = robot.inner().node().name().domain;
    // The goal runs through the guard (`run_prepared`); its progress is read here
    // from the robot's share while it runs.
    let share = robot.inner().progress();
    let moves = message
        .points
        .last()
        .is_some_and(|p| p.time_from_start.secs() > 0.0);
    let ran = std::thread::scope(|scope| {
        let runner = scope.spawn(|| robot.run_prepared(prepared, stop));
        while !runner.is_finished() {
            if moves {
                progress(f64::from_bits(
                    share.load(std::sync::atomic::Ordering::Relaxed),
                ));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        runner.join()
    });
    let ran = ran.map_err(|_| DriveError::Failed("the goal's runner panicked".into()))?;
    // A goal the controller answered (done, aborted, refused) is worded from its
    // outcome; anything else could not reach the controller.
    let last = match (ran, robot.inner().last_goal()) {
        (_, Some(last)) => last.clone(),
        (Err(e), None) => {
            let text = robot_message(e).to_string();
            // No server: say what the graph offers instead.
            let hint = if text.contains("no action server answered") {
                crate::ros2_graph::action_hint(robot.inner().node(), &action)
            } else {
                String::new()
            };
            return Err(DriveError::Failed(format!("{text}{hint}")));
        }
        (Ok(_), None) => {
            return Err(DriveError::Failed(
                "the goal ran but left no outcome".into(),
            ));
        }
    };
    let o = &last.outcome;
    let recording = match (&s.record, &last.recording) {
        (Some(r), Some(rec)) => Some(Box::new(write_tracked(r, rec, o, &message, model)?)),
        _ => None,
    };
    let code = if stop.is_stopped() && !o.succeeded() {
        Ended::Stopped
    } else {
        Ended::of(o.succeeded())
    };
    let via = SentVia::Action {
        action,
        outcome: Box::new(o.clone()),
        recording,
    };
    Ok((sent_of(name, s, domain, names, &message, via), code))
}

/// A joint_trajectory_controller's topic as a robot: blind (it is trusted to start from a
/// plan's first point), a plan published as one JointTrajectory message, with no answer.
/// Only [`send_trajectory`] drives it, behind the guard.
struct TopicRobot {
    /// The node that joins the graph, once a plan has passed the guard.
    node_name: NodeName,
    topic: String,
    names: Vec<String>,
    model: RobotModel,
    period: f64,
    wait: Duration,
    /// The node that published, the message and how it went.
    sent: Option<(Node, JointTrajectory, publish::Published)>,
}

impl Robot for TopicRobot {
    fn name(&self) -> String {
        format!("ros2 {}", self.topic)
    }
    fn model(&self) -> &RobotModel {
        &self.model
    }
    fn dt(&self) -> f64 {
        self.period
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
    /// Publishes the plan: the run holds its start only (a topic says nothing of what the
    /// robot did), Finished when the subscriber acknowledged the message.
    fn run(&mut self, plan: &Plan, _stop: &StopToken) -> Result<cps_robot::Run, RobotError> {
        let message = trajectory_message(&self.names, plan, Some(self.period));
        let graph = |e: cps_ros2::Ros2Error| RobotError::Robot {
            robot: format!("ros2 {}", self.topic),
            message: e.to_string(),
        };
        let node = Node::new(self.node_name.clone()).map_err(graph)?;
        let sent = publish::publish(
            &node,
            &self.topic,
            &message,
            Qos::Reliable { depth: 1 },
            self.wait,
        )
        .map_err(graph)?;
        let mut run = cps_robot::Run::new(if sent.acknowledged {
            cps_robot::Ending::Finished
        } else {
            cps_robot::Ending::Failed("the message was not acknowledged in time".into())
        });
        let start = plan.start().to_vec();
        let tool = self.model.chain.fk(&start)?;
        run.push(0.0, start, tool);
        self.sent = Some((node, message, sent));
        Ok(run)
    }
}

/// A topic robot's error: a refusal worded as every refusal, anything else as it is.
fn sent_or_refused(name: &str, model: &RobotModel, e: RobotError) -> DriveError {
    match e {
        RobotError::Refused { .. } => refused(name, model, e),
        other => robot_message(other),
    }
}

/// A robot's failure in its own words (the robot's name is in the caller's sentence).
fn robot_message(e: RobotError) -> DriveError {
    match e {
        RobotError::Robot { message, .. } => DriveError::Failed(message),
        other => DriveError::Robot(other),
    }
}

/// What `ros2 send` says of the message sent `via` the topic or the action.
fn sent_of(
    name: &str,
    s: &SendSettings,
    domain: u16,
    names: &[String],
    message: &JointTrajectory,
    via: SentVia,
) -> Sent {
    Sent {
        file: name.to_string(),
        controller: s.controller.clone(),
        domain,
        joint_names: names.to_vec(),
        points: message.points.len(),
        duration_s: message
            .points
            .last()
            .map_or(0.0, |p| p.time_from_start.secs()),
        via,
    }
}

/// Writes `ros2 send --record`'s recording and its report: the recording's limit check and
/// how far the robot was from the points sent, at their times from the goal's acceptance.
fn write_tracked(
    r: &SendRecord,
    rec: &JointRecording,
    o: &FollowOutcome,
    message: &JointTrajectory,
    model: &RobotModel,
) -> Result<Tracked, DriveError> {
    let at: Vec<f64> = message
        .points
        .iter()
        .map(|p| p.time_from_start.secs())
        .collect();
    let tracking = match rows_at(rec, o, &at) {
        Some(rows) => {
            let dof = rows.first().map_or(0, Vec::len);
            let mut max = vec![0.0f64; dof];
            let mut sum = vec![0.0f64; dof];
            for (row, p) in rows.iter().zip(&message.points) {
                for j in 0..dof {
                    let e = (row[j] - p.positions[j]).abs();
                    max[j] = max[j].max(e);
                    sum[j] += e * e;
                }
            }
            let rms: Vec<f64> = sum.iter().map(|s| (s / rows.len() as f64).sqrt()).collect();
            let worst = max.iter().copied().fold(0.0, f64::max);
            Some((max, rms, worst))
        }
        None => None,
    };
    let tracking_json = tracking.as_ref().map_or(Value::Null, |(max, rms, worst)| {
        json!({ "max_error_rad": max, "rms_error_rad": rms, "worst_rad": worst })
    });
    let (times, _) = rec.times();
    let limits = cps_movement::limits::check_samples(
        model,
        &cps_movement::limits::JointTrajectory {
            names: rec.joints.clone(),
            times: times.clone(),
            q: rec.positions.clone(),
        },
        1000.0,
    )
    .ok()
    .filter(|_| times.len() >= 2 && times.windows(2).all(|w| w[1] > w[0]));
    let report = json!({
        "complete": o.succeeded(),
        "topic": r.topic,
        "goal_id": o.goal_id.to_string(),
        "status": o.status.word(),
        "messages": rec.messages,
        "kept": rec.positions.len(),
        "lost": rec.lost,
        "older": rec.older,
        "incomplete": rec.incomplete,
        "malformed": rec.dropped.malformed,
        "tracking": tracking_json,
        "limits": limits.as_ref().map_or(Value::Null, |l| l.json()),
    });
    cps_outcome::files::write_file(
        &r.out,
        &cps_outcome::files::table_csv(&recording_table(rec))?,
    )?;
    let text = format!("{report:#}");
    let report_file = crate::recording::report_path(&r.out);
    cps_outcome::files::write_file(&report_file, text.as_bytes())?;
    Ok(Tracked {
        topic: r.topic.clone(),
        tracking,
        limits,
        report,
        written: (r.out.clone(), report_file),
    })
}

/// What and where to record.
#[derive(Debug, Clone)]
pub struct RecordSettings {
    /// The JointState topic (`/joint_states`).
    pub topic: String,
    /// Seconds from the first message.
    pub duration: f64,
    /// Robot (whose joints, in its order, are kept), joint names, domain.
    pub graph: GraphSettings,
    /// Seconds to wait for the first message.
    pub wait: f64,
    /// Hear best-effort publishers too (may lose samples; reliable ones lose none).
    pub best_effort: bool,
}

/// The recording as a table: `t`, the joints' positions by name, then `<name>_vel`
/// where every message carried velocities.
pub fn recording_table(rec: &JointRecording) -> Table {
    let (t, _) = rec.times();
    let mut table = Table::new("recording").with(Column::numbers("t", t, Format::Plain));
    for (j, name) in rec.joints.iter().enumerate() {
        table.push(Column::numbers(
            name.clone(),
            rec.positions.iter().map(|r| r[j]).collect(),
            Format::Plain,
        ));
    }
    if !rec.velocities.is_empty() {
        for (j, name) in rec.joints.iter().enumerate() {
            table.push(Column::numbers(
                format!("{name}_vel"),
                rec.velocities.iter().map(|r| r[j]).collect(),
                Format::Plain,
            ));
        }
    }
    table
}

/// `ros2 record`: `settings.topic` for `settings.duration` s from its first message (or
/// until `stop`), written to `out` (a new file, or `force`) with its report beside it;
/// the recording checked against the robot's limits as any trajectory. Completed, or
/// stopped early (what came is kept).
pub fn record(
    s: &RecordSettings,
    out: &Path,
    force: bool,
    stop: &StopToken,
    progress: impl FnMut(f64),
) -> Result<(StatesRecorded, Ended), DriveError> {
    crate::recording::check_record_target(out, force)?;
    let (rec, mut recorded) = record_in_memory(s, stop, progress)?;
    let csv = cps_outcome::files::table_csv(&recording_table(&rec))?;
    cps_outcome::files::write_file(out, &csv)?;
    let text = format!("{:#}", json!(recorded));
    let report_file = crate::recording::report_path(out);
    cps_outcome::files::write_file(&report_file, text.as_bytes())?;
    recorded.written = Some((out.to_path_buf(), report_file));
    let ended = if rec.stopped {
        Ended::Stopped
    } else {
        Ended::Completed
    };
    Ok((recorded, ended))
}

/// [`record`] in memory: the recording and its report (JSON and lines).
pub fn record_in_memory(
    s: &RecordSettings,
    stop: &StopToken,
    progress: impl FnMut(f64),
) -> Result<(JointRecording, StatesRecorded), DriveError> {
    if !(s.duration.is_finite() && s.duration > 0.0 && s.duration <= 3600.0) {
        return Err(InputError(format!(
            "--duration {}: give seconds in (0, 3600]",
            s.duration
        ))
        .into());
    }
    if !(s.wait.is_finite() && s.wait > 0.0 && s.wait <= 3600.0) {
        return Err(InputError(format!("--wait {}: give seconds in (0, 3600]", s.wait)).into());
    }
    let (model, names) = robot_and_names(&s.graph)?;
    let node = node(s.graph.domain)?;
    let depth = 5000;
    let options = RecordOptions {
        topic: s.topic.clone(),
        joints: names.clone(),
        duration: Duration::from_secs_f64(s.duration),
        wait: Duration::from_secs_f64(s.wait),
        qos: if s.best_effort {
            Qos::BestEffort { depth }
        } else {
            Qos::Reliable { depth }
        },
    };
    let rec = record_joint_states(&node, &options, stop.flag(), progress)?;
    let (times, source) = rec.times();
    let span = times.last().copied().unwrap_or(0.0);
    let limits = cps_movement::limits::check_samples(
        &model,
        &cps_movement::limits::JointTrajectory {
            names: names.clone(),
            times: times.clone(),
            q: rec.positions.clone(),
        },
        1000.0,
    )
    .ok()
    .filter(|_| times.len() >= 2 && times.windows(2).all(|w| w[1] > w[0]));
    let recorded = StatesRecorded {
        topic: s.topic.clone(),
        domain: node.name().domain,
        joints: names,
        messages: rec.messages,
        kept: rec.positions.len(),
        lost: rec.lost,
        older: rec.older,
        incomplete: rec.incomplete,
        dropped: rec.dropped,
        time_source: source,
        first_message_s: rec.first_message_s,
        duration_s: span,
        complete: !rec.stopped,
        limits,
        written: None,
    };
    Ok((rec, recorded))
}
