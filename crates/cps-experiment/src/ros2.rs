//! A ROS 2 robot from files and words (`cps-cli ros2 …`, Python's `cps.ros2`): a cps
//! joint CSV checked against the robot's limits and sent to a ros2_control
//! joint_trajectory_controller (its topic, or its FollowJointTrajectory action), and a
//! robot's `JointState` recorded as a cps joint CSV with a report. The graph itself is
//! `cps-ros2`'s.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use cps_ros2::action::{FollowJointTrajectoryClient, FollowOutcome, FollowTimes};
use cps_ros2::msg::{
    FollowJointTrajectoryGoal, GoalId, JointTrajectory, JointTrajectoryPoint, Time, error_code_word,
};
use cps_ros2::names::NodeName;
use cps_ros2::node::{Node, Qos};
use cps_ros2::record::{JointRecording, RecordOptions, record_joint_states};
use cps_ros2::{Ros2Error, publish};
use serde_json::{Value, json};

use crate::outcome::{Column, Format, Table};
use crate::robot_file::{Answer, RobotModel, load_robot};
use crate::{ExperimentError, InputError};

/// The node name cps takes on the graph.
pub const NODE_NAME: &str = "cps";

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

/// The robot model and the joint names for it (the robot's, or `names` checked against
/// its joint count).
fn robot_and_names(
    robot: &str,
    names: Option<&[String]>,
) -> Result<(RobotModel, Vec<String>), ExperimentError> {
    let model = load_robot(robot, None, None)?;
    let dof = model.chain.dof();
    let names = match names {
        None => crate::export::joint_names(&model),
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

/// The node, on `domain` or `ROS_DOMAIN_ID`'s.
pub(crate) fn node(domain: Option<u16>) -> Result<Node, ExperimentError> {
    let name = NodeName::from_env(NODE_NAME, domain).map_err(|e| InputError(e.to_string()))?;
    Node::new(name).map_err(ros2_error)
}

/// A graph failure as cps reports it (bad names and domains are input).
pub fn ros2_error(e: Ros2Error) -> ExperimentError {
    match e {
        Ros2Error::Input(m) => InputError(m).into(),
        other => ExperimentError::Message(other.to_string()),
    }
}

/// A joint trajectory (called `name` in messages) as the message a controller takes:
/// checked against `model`'s limits at the points' rate (refused, with the report's lines,
/// when one is broken), then sampled every `period` s by the spline through it with
/// velocities and accelerations, from 0 at its first time; `time_from_start` exact to the
/// nanosecond.
pub fn trajectory_message_of(
    name: &str,
    traj: &crate::limits::JointTrajectory,
    model: &RobotModel,
    names: &[String],
    period: f64,
) -> Result<JointTrajectory, ExperimentError> {
    crate::export::ExportOptions { period }.check()?;
    let dof = model.chain.dof();
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
    let report = crate::limits::check_samples(model, traj, 1.0 / period)
        .map_err(|e| InputError(format!("{name}: {e}")))?;
    if !report.ok() {
        return Err(ExperimentError::Message(format!(
            "{name}: refused, nothing was sent: the trajectory breaks the {}'s limits at {} Hz\n{}",
            model.name,
            1.0 / period,
            report.lines().join("\n")
        )));
    }
    let s = crate::export::sample(traj, period);
    let points = (0..s.t.len())
        .map(|k| JointTrajectoryPoint {
            positions: s.q[k].clone(),
            velocities: s.qd[k].clone(),
            accelerations: s.qdd[k].clone(),
            effort: vec![],
            time_from_start: Time::from_secs(s.t[k]),
        })
        .collect();
    Ok(JointTrajectory {
        joint_names: names.to_vec(),
        points,
        ..JointTrajectory::default()
    })
}

/// A goal id from the trajectory's own bytes and the time: unique per send, the same
/// bytes never needed twice.
fn goal_id(message: &JointTrajectory) -> GoalId {
    use cps_ros2::msg::Message;
    let bytes = message.to_cdr();
    let h = bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ *b as u64).wrapping_mul(0x0100_0000_01b3)
    });
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    GoalId::from_bits(((h as u128) << 64) ^ now)
}

/// `ros2 send`: the file checked, then sent; returns the answer and the exit code (0
/// done; 1 refused, aborted or cancelled for lateness; 130 cancelled by `stop`). `progress` sees the share of
/// the trajectory the controller reports done (action only).
pub fn send(
    file: &Path,
    s: &SendSettings,
    stop: &AtomicBool,
    progress: impl FnMut(f64),
) -> Result<(Answer, u8), ExperimentError> {
    let (model, _) = robot_and_names(&s.graph.robot, s.graph.joint_names.as_deref())?;
    let traj = crate::limits::read_joint_trajectory(file, model.chain.dof())?;
    send_trajectory(&file.display().to_string(), &traj, s, stop, progress)
}

/// [`send`] for a trajectory in memory, called `name` in messages.
pub fn send_trajectory(
    name: &str,
    traj: &crate::limits::JointTrajectory,
    s: &SendSettings,
    stop: &AtomicBool,
    mut progress: impl FnMut(f64),
) -> Result<(Answer, u8), ExperimentError> {
    if !(s.wait.is_finite() && s.wait > 0.0 && s.wait <= 3600.0) {
        return Err(InputError(format!("--wait {}: give seconds in (0, 3600]", s.wait)).into());
    }
    let (model, names) = robot_and_names(&s.graph.robot, s.graph.joint_names.as_deref())?;
    if let Some(r) = &s.record {
        if s.via == Via::Topic {
            return Err(InputError(
                "--record needs the action (a topic message has no start the recording could be compared from)".into(),
            )
            .into());
        }
        crate::franka::check_record_target(&r.out, r.force)?;
    }
    let message = trajectory_message_of(name, traj, &model, &names, s.period)?;
    let duration = message
        .points
        .last()
        .map_or(0.0, |p| p.time_from_start.secs());
    let node = node(s.graph.domain)?;
    let wait = Duration::from_secs_f64(s.wait);
    let base = json!({
        "file": name,
        "controller": s.controller,
        "domain": node.name().domain,
        "joint_names": names,
        "points": message.points.len(),
        "duration_s": duration,
    });
    match s.via {
        Via::Topic => {
            let topic = format!("{}/joint_trajectory", s.controller.trim_end_matches('/'));
            let sent = publish::publish(&node, &topic, &message, Qos::Reliable { depth: 1 }, wait)
                .map_err(ros2_error)?;
            let mut json = base;
            json["via"] = json!("topic");
            json["topic"] = json!(topic);
            json["discovery_s"] = json!(sent.matched_after_s);
            json["acknowledged"] = json!(sent.acknowledged);
            json["bytes"] = json!(sent.bytes);
            let lines = vec![
                format!(
                    "sent {} points ({duration:.3} s) to {topic} on domain {}: {} subscriber(s), {}",
                    message.points.len(),
                    node.name().domain,
                    sent.subscribers,
                    if sent.acknowledged { "acknowledged" } else { "not acknowledged in time" }
                ),
                "a topic has no answer: the controller's own log says whether it ran (use --action for its result)".into(),
            ];
            Ok((
                Answer { json, lines },
                if sent.acknowledged { 0 } else { 1 },
            ))
        }
        Via::Action => {
            let action = format!(
                "{}/follow_joint_trajectory",
                s.controller.trim_end_matches('/')
            );
            let mut client =
                FollowJointTrajectoryClient::new(&node, &action).map_err(ros2_error)?;
            let goal = FollowJointTrajectoryGoal {
                trajectory: message.clone(),
                goal_time_tolerance: Time::default(),
            };
            let times = FollowTimes {
                server: wait,
                result: Duration::from_secs_f64(duration * 1.5 + 10.0),
                after_cancel: Duration::from_secs(5),
            };
            let stop_recording = AtomicBool::new(false);
            let recording = s.record.as_ref().map(|r| RecordOptions {
                topic: r.topic.clone(),
                joints: names.clone(),
                duration: Duration::from_secs_f64(duration * 1.5 + 60.0),
                wait,
                qos: Qos::Reliable { depth: 5000 },
            });
            let (o, rec) = std::thread::scope(|scope| {
                let recorder = recording.as_ref().map(|options| {
                    scope.spawn(|| record_joint_states(&node, options, &stop_recording, |_| {}))
                });
                let o = client.follow(&goal, goal_id(&message), times, stop, |f| {
                    if duration > 0.0 {
                        progress((f.desired.time_from_start.secs() / duration).clamp(0.0, 1.0));
                    }
                });
                if recorder.is_some() {
                    // The last states are published as the result is: take them too.
                    std::thread::sleep(Duration::from_millis(200));
                }
                stop_recording.store(true, std::sync::atomic::Ordering::Relaxed);
                (o, recorder.map(|h| h.join()))
            });
            let o = o.map_err(ros2_error)?;
            let (mut answer, code) = action_answer(base, &action, &o);
            if let (Some(r), Some(rec)) = (&s.record, rec) {
                let rec = rec
                    .map_err(|_| ExperimentError::Message("the recorder panicked".into()))?
                    .map_err(ros2_error)?;
                write_tracked(r, &rec, &o, &message, &model, &mut answer)?;
            }
            let stopped = stop.load(std::sync::atomic::Ordering::Relaxed);
            Ok((answer, if stopped && !o.succeeded() { 130 } else { code }))
        }
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
    answer: &mut Answer,
) -> Result<(), ExperimentError> {
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
            answer.lines.push(format!(
                "tracking: the robot within {worst:.2e} rad of the points sent (worst joint), RMS {:.2e} rad",
                rms.iter().copied().fold(0.0, f64::max)
            ));
            json!({ "max_error_rad": max, "rms_error_rad": rms, "worst_rad": worst })
        }
        None => {
            answer.lines.push(format!(
                "tracking: not judged, the joint states on {} stop before the goal's end",
                r.topic
            ));
            Value::Null
        }
    };
    let (times, _) = rec.times();
    let limits = crate::limits::check_samples(
        model,
        &crate::limits::JointTrajectory {
            names: rec.joints.clone(),
            times: times.clone(),
            q: rec.positions.clone(),
        },
        1000.0,
    )
    .ok()
    .filter(|_| times.len() >= 2 && times.windows(2).all(|w| w[1] > w[0]));
    if let Some(l) = &limits {
        answer.lines.extend(l.lines());
    }
    let report = json!({
        "complete": o.succeeded(),
        "topic": r.topic,
        "goal_id": o.goal_id.to_string(),
        "status": o.status.word(),
        "messages": rec.messages,
        "kept": rec.positions.len(),
        "lost": rec.lost,
        "incomplete": rec.incomplete,
        "malformed": rec.dropped.malformed,
        "tracking": tracking,
        "limits": limits.as_ref().map_or(Value::Null, |l| l.json()),
    });
    crate::files::write_file(&r.out, &crate::files::table_csv(&recording_table(rec))?)?;
    let text = serde_json::to_string_pretty(&report)
        .map_err(|e| ExperimentError::Message(e.to_string()))?;
    let report_file = crate::franka::report_path(&r.out);
    crate::files::write_file(&report_file, text.as_bytes())?;
    answer.json["recording"] = report;
    answer.lines.push(format!(
        "wrote {} and {}",
        r.out.display(),
        report_file.display()
    ));
    Ok(())
}

fn action_answer(mut json: Value, action: &str, o: &FollowOutcome) -> (Answer, u8) {
    json["via"] = json!("action");
    json["action"] = json!(action);
    json["goal_id"] = json!(o.goal_id.to_string());
    json["discovery_s"] = json!(o.discovery_s);
    json["accepted"] = json!(o.accepted);
    json["status"] = json!(o.status.word());
    json["error_code"] = json!(o.error_code);
    json["error_string"] = json!(o.error_string);
    json["feedback"] = json!(o.feedback);
    json["cancel_requested"] = json!(o.cancel_requested);
    json["dropped"] = json!(o.dropped.malformed + o.dropped.oversized + o.dropped.undecodable);
    json["succeeded"] = json!(o.succeeded());
    let mut lines = vec![if !o.accepted {
        format!("{action} refused the goal {}", o.goal_id)
    } else {
        format!(
            "goal {} {}: error code {} ({}){}",
            o.goal_id,
            o.status.word(),
            o.error_code,
            error_code_word(o.error_code),
            if o.error_string.is_empty() {
                String::new()
            } else {
                format!(", \"{}\"", o.error_string)
            }
        )
    }];
    lines.push(format!(
        "{} feedback message(s); server found after {:.2} s",
        o.feedback, o.discovery_s
    ));
    if o.cancel_requested {
        lines.push("the goal was cancelled (Ctrl-C or no result in time)".into());
    }
    (Answer { json, lines }, if o.succeeded() { 0 } else { 1 })
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
/// the recording checked against the robot's limits as any trajectory. Exit code 0, or
/// 130 stopped early (what came is kept).
pub fn record(
    s: &RecordSettings,
    out: &Path,
    force: bool,
    stop: &AtomicBool,
    progress: impl FnMut(f64),
) -> Result<(Answer, u8), ExperimentError> {
    crate::franka::check_record_target(out, force)?;
    let (rec, mut answer) = record_in_memory(s, stop, progress)?;
    let csv = crate::files::table_csv(&recording_table(&rec))?;
    crate::files::write_file(out, &csv)?;
    let text = serde_json::to_string_pretty(&answer.json)
        .map_err(|e| ExperimentError::Message(e.to_string()))?;
    let report_file = crate::franka::report_path(out);
    crate::files::write_file(&report_file, text.as_bytes())?;
    answer.lines.push(format!(
        "wrote {} and {}",
        out.display(),
        report_file.display()
    ));
    Ok((answer, if rec.stopped { 130 } else { 0 }))
}

/// [`record`] in memory: the recording and its report (JSON and lines).
pub fn record_in_memory(
    s: &RecordSettings,
    stop: &AtomicBool,
    progress: impl FnMut(f64),
) -> Result<(JointRecording, Answer), ExperimentError> {
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
    let (model, names) = robot_and_names(&s.graph.robot, s.graph.joint_names.as_deref())?;
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
    let rec = record_joint_states(&node, &options, stop, progress).map_err(ros2_error)?;
    let (times, source) = rec.times();
    let span = times.last().copied().unwrap_or(0.0);
    let mut lines = vec![format!(
        "recorded {} JointState message(s) over {span:.3} s from {} ({} lost, {} without every joint, {} unreadable), times from each message's {source}",
        rec.positions.len(),
        s.topic,
        rec.lost,
        rec.incomplete,
        rec.dropped.malformed + rec.dropped.oversized + rec.dropped.undecodable
    )];
    let limits = crate::limits::check_samples(
        &model,
        &crate::limits::JointTrajectory {
            names: names.clone(),
            times: times.clone(),
            q: rec.positions.clone(),
        },
        1000.0,
    );
    let limits_json = match &limits {
        Ok(r) if times.len() >= 2 && times.windows(2).all(|w| w[1] > w[0]) => {
            lines.extend(r.lines());
            r.json()
        }
        _ => {
            lines.push("the limit check needs two or more messages at increasing times".into());
            Value::Null
        }
    };
    let report = json!({
        "complete": !rec.stopped,
        "topic": s.topic,
        "domain": node.name().domain,
        "joints": names,
        "messages": rec.messages,
        "kept": rec.positions.len(),
        "lost": rec.lost,
        "incomplete": rec.incomplete,
        "malformed": rec.dropped.malformed,
        "oversized": rec.dropped.oversized,
        "undecodable": rec.dropped.undecodable,
        "time_source": source,
        "first_message_s": rec.first_message_s,
        "duration_s": span,
        "limits": limits_json,
    });
    Ok((
        rec,
        Answer {
            json: report,
            lines,
        },
    ))
}

/// The recorded joints at each time of `at` (s from the goal's acceptance), linearly
/// between messages; None past the recording's end.
pub(crate) fn rows_at(
    rec: &JointRecording,
    outcome: &FollowOutcome,
    at: &[f64],
) -> Option<Vec<Vec<f64>>> {
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
