//! What the Franka and ROS 2 commands return: typed results, each saying itself as JSON
//! (`Serialize`, what `--json` prints and, for a recording, the report written beside it)
//! and as text (`Display`, a line each). The command line chooses which. (An execution's,
//! `franka::ExecutedTo`, is beside what it says, `franka::Executed`.)

use std::fmt;
use std::path::PathBuf;

use cps_franka::{GripperState, RobotState};
use serde::{Serialize, Serializer};
use serde_json::{Value, json};

/// Seven numbers as `franka` commands print them.
pub(crate) fn fmt7(x: &[f64]) -> String {
    x.iter()
        .map(|v| format!("{v:.4}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `franka state`: one state of the robot at `host`.
#[derive(Debug, Clone)]
pub struct StateAt {
    /// The robot's address.
    pub host: String,
    /// What it said.
    pub state: RobotState,
}

/// `{"host", "message_id", "q", "dq", "tau_J", "q_d", "O_T_EE", "tool_position",
/// "robot_mode", "errors", "control_command_success_rate"}`.
impl Serialize for StateAt {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let st = &self.state;
        json!({
            "host": self.host,
            "message_id": st.message_id,
            "q": st.q, "dq": st.dq, "tau_J": st.tau_j, "q_d": st.q_d,
            "O_T_EE": st.o_t_ee, "tool_position": st.tool_position(),
            "robot_mode": st.robot_mode.name(),
            "errors": st.errors.names(),
            "control_command_success_rate": st.control_command_success_rate,
        })
        .serialize(s)
    }
}

impl fmt::Display for StateAt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.state;
        let p = s.tool_position();
        let mode = s.robot_mode;
        writeln!(f, "{}: {} ({})", self.host, mode.name(), mode.sentence())?;
        writeln!(f, "  q      [{}] rad", fmt7(&s.q))?;
        writeln!(f, "  dq     [{}] rad/s", fmt7(&s.dq))?;
        writeln!(f, "  tau_J  [{}] N m", fmt7(&s.tau_j))?;
        let (x, y, z) = (p[0], p[1], p[2]);
        writeln!(f, "  tool   ({x:.4}, {y:.4}, {z:.4}) m in the base frame")?;
        write!(f, "  errors {}", s.errors.describe())
    }
}

/// `franka gripper`: the hand's state after the action, and whether a grasp held.
#[derive(Debug, Clone)]
pub struct HandAt {
    /// The robot's address.
    pub host: String,
    /// The hand's state after the action.
    pub state: GripperState,
    /// A grasp's outcome (None for any other action).
    pub grasped: Option<bool>,
}

/// `{"host", "width", "max_width", "is_grasped", "temperature", "grasped"?}`.
impl Serialize for HandAt {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let st = &self.state;
        let mut json = json!({ "host": self.host, "width": st.width, "max_width": st.max_width,
            "is_grasped": st.is_grasped, "temperature": st.temperature });
        if let Some(g) = self.grasped {
            json["grasped"] = json!(g);
        }
        json.serialize(s)
    }
}

impl fmt::Display for HandAt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.grasped {
            Some(true) => writeln!(f, "grasped")?,
            Some(false) => writeln!(f, "nothing grasped within the tolerances")?,
            None => {}
        }
        let s = &self.state;
        let holding = if s.is_grasped {
            "holding"
        } else {
            "not holding"
        };
        write!(
            f,
            "{} gripper: width {:.4} m of {:.4} m, {holding}, {} °C",
            self.host, s.width, s.max_width, s.temperature
        )
    }
}

/// `franka record` and `franka guide`: a recording written, and its report.
#[derive(Debug, Clone)]
pub struct Recorded {
    /// The robot's address.
    pub host: String,
    /// The recording written.
    pub out: PathBuf,
    /// Its samples.
    pub samples: usize,
    /// Its duration (s).
    pub duration_s: f64,
    /// Taught by guiding (`franka guide`), or recorded standing (`franka record`).
    pub guided: bool,
    /// The report written beside it (`<stem>.report.json`): `{"complete", "ending",
    /// "host", "samples", "duration_s", …}`.
    pub report: Value,
}

/// The report.
impl Serialize for Recorded {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.report.serialize(s)
    }
}

impl fmt::Display for Recorded {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ending = self.report["ending"].as_str().unwrap_or_default();
        let (n, d, out) = (self.samples, self.duration_s, self.out.display());
        if self.guided {
            writeln!(f, "{}: guided by hand; {ending}", self.host)?;
            write!(
                f,
                "  {n} samples over {d:.3} s in {out} (imitate it: cps-cli imitate {out} --columns q1,q2,q3,q4,q5,q6,q7 --out model.json)"
            )
        } else {
            writeln!(f, "{}: {ending}", self.host)?;
            write!(f, "  {n} samples over {d:.3} s in {out}")
        }
    }
}

/// `ros2 follow`: the chunks' replacement trajectories published on a controller's topic.
#[derive(Debug, Clone)]
pub struct ChunksPublished {
    /// The chunk file.
    pub file: String,
    /// The controller.
    pub controller: String,
    /// Its `joint_trajectory` topic.
    pub topic: String,
    /// The joints, in the messages' order.
    pub joint_names: Vec<String>,
    /// The robot whose limits the motion was checked against.
    pub robot: String,
    /// Chunks read.
    pub chunks: usize,
    /// Replacement trajectories made.
    pub replacements: usize,
    /// Those published.
    pub published: usize,
    /// The chunks refused, and why.
    pub refused: Vec<(usize, String)>,
    /// Subscribers of the topic.
    pub subscribers: i32,
    /// The latest a message went out after its chunk's arrival (s).
    pub latest_s: f64,
    /// The motion's length (s).
    pub duration_s: f64,
    /// Whether every replacement went out.
    pub complete: bool,
}

/// `{"file", "controller", "topic", "joint_names", "chunks", "replacements", "published",
/// "refused": [{"chunk", "why"}], "subscribers", "latest_s", "duration_s", "complete"}`.
impl Serialize for ChunksPublished {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let refused: Vec<Value> = self
            .refused
            .iter()
            .map(|(i, why)| json!({"chunk": i, "why": why}))
            .collect();
        json!({
            "file": self.file, "controller": self.controller, "topic": self.topic,
            "joint_names": self.joint_names, "chunks": self.chunks,
            "replacements": self.replacements, "published": self.published, "refused": refused,
            "subscribers": self.subscribers, "latest_s": self.latest_s,
            "duration_s": self.duration_s, "complete": self.complete,
        })
        .serialize(s)
    }
}

impl fmt::Display for ChunksPublished {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} of {} replacement trajectories published to {} ({} subscriber(s)), each at its chunk's arrival (at most {:.1} ms late): {:.3} s of motion",
            self.published,
            self.replacements,
            self.topic,
            self.subscribers,
            self.latest_s * 1e3,
            self.duration_s
        )?;
        write!(
            f,
            "\n  {} chunks, {} refused; the whole motion checked against the {}'s limits first",
            self.chunks,
            self.refused.len(),
            self.robot
        )?;
        for (i, why) in &self.refused {
            write!(f, "\n  chunk {i} refused: {why}")?;
        }
        Ok(())
    }
}

/// `ros2 record` (and `cps.ros2.record`): joint states recorded from a topic, with their
/// limit check; and where they were written, once they are.
#[derive(Debug, Clone)]
pub struct StatesRecorded {
    /// The JointState topic.
    pub topic: String,
    /// The DDS domain.
    pub domain: u16,
    /// The joints, in the robot's order.
    pub joints: Vec<String>,
    /// Messages heard.
    pub messages: u64,
    /// Messages kept.
    pub kept: usize,
    /// Messages lost on the way.
    pub lost: u64,
    /// Messages published before the recording began (dropped).
    pub older: u64,
    /// Messages without every joint.
    pub incomplete: u64,
    /// Samples the topic could not read.
    pub dropped: cps_ros2::node::Counts,
    /// Where each message's time comes from.
    pub time_source: &'static str,
    /// When the first message came (s after the start).
    pub first_message_s: f64,
    /// The span of the messages kept (s).
    pub duration_s: f64,
    /// Whether it ran its whole duration (not stopped).
    pub complete: bool,
    /// The limit check (None: fewer than two messages at increasing times).
    pub limits: Option<cps_movement::limits::LimitsReport>,
    /// The recording and its report, once written.
    pub written: Option<(PathBuf, PathBuf)>,
}

/// The report written beside the recording: `{"complete", "topic", "domain", "joints",
/// "messages", "kept", "lost", "older", "incomplete", "malformed", "oversized",
/// "undecodable", "time_source", "first_message_s", "duration_s", "limits"}`.
impl Serialize for StatesRecorded {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let d = &self.dropped;
        json!({
            "complete": self.complete,
            "topic": self.topic,
            "domain": self.domain,
            "joints": self.joints,
            "messages": self.messages,
            "kept": self.kept,
            "lost": self.lost,
            "older": self.older,
            "incomplete": self.incomplete,
            "malformed": d.malformed,
            "oversized": d.oversized,
            "undecodable": d.undecodable,
            "time_source": self.time_source,
            "first_message_s": self.first_message_s,
            "duration_s": self.duration_s,
            "limits": self.limits.as_ref().map_or(Value::Null, |l| l.json()),
        })
        .serialize(s)
    }
}

impl fmt::Display for StatesRecorded {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = &self.dropped;
        write!(
            f,
            "recorded {} JointState message(s) over {:.3} s from {} ({} lost, {} published before the recording began and dropped, {} without every joint, {} unreadable), times from each message's {}",
            self.kept,
            self.duration_s,
            self.topic,
            self.lost,
            self.older,
            self.incomplete,
            d.malformed + d.oversized + d.undecodable,
            self.time_source
        )?;
        match &self.limits {
            Some(l) => write!(f, "\n{l}")?,
            None => write!(
                f,
                "\nthe limit check needs two or more messages at increasing times"
            )?,
        }
        if let Some((out, report)) = &self.written {
            write!(f, "\nwrote {} and {}", out.display(), report.display())?;
        }
        Ok(())
    }
}

/// `ros2 send` (and `cps.ros2.send`): a trajectory sent to a controller, and what came of
/// it.
#[derive(Debug, Clone)]
pub struct Sent {
    /// The trajectory's name (its file).
    pub file: String,
    /// The controller.
    pub controller: String,
    /// The DDS domain.
    pub domain: u16,
    /// The joints, in the message's order.
    pub joint_names: Vec<String>,
    /// Points sent.
    pub points: usize,
    /// The trajectory's length (s).
    pub duration_s: f64,
    /// By the topic or by the action, and what each said.
    pub via: SentVia,
}

/// How [`Sent`] went.
#[derive(Debug, Clone)]
pub enum SentVia {
    /// Published on the controller's topic (no answer).
    Topic {
        /// The topic.
        topic: String,
        /// What the publication saw.
        published: cps_ros2::publish::Published,
    },
    /// A FollowJointTrajectory goal.
    Action {
        /// The action.
        action: String,
        /// Its outcome.
        outcome: Box<cps_ros2::action::FollowOutcome>,
        /// The joint states recorded while it ran (`--record`).
        recording: Option<Box<Tracked>>,
    },
}

/// `ros2 send --record`: the joint states recorded while the goal ran, how far the robot
/// was from the points sent, and the recording's limit check.
#[derive(Debug, Clone)]
pub struct Tracked {
    /// The JointState topic.
    pub topic: String,
    /// The largest distance to a point sent, per joint, its RMS, and the worst joint's
    /// (rad); None when the states stop before the goal's end.
    pub tracking: Option<(Vec<f64>, Vec<f64>, f64)>,
    /// The recording's limit check.
    pub limits: Option<cps_movement::limits::LimitsReport>,
    /// The report written beside the recording.
    pub report: Value,
    /// The recording and its report.
    pub written: (PathBuf, PathBuf),
}

impl Sent {
    fn json(&self) -> Value {
        let mut json = json!({
            "file": self.file,
            "controller": self.controller,
            "domain": self.domain,
            "joint_names": self.joint_names,
            "points": self.points,
            "duration_s": self.duration_s,
        });
        match &self.via {
            SentVia::Topic { topic, published } => {
                json["via"] = json!("topic");
                json["topic"] = json!(topic);
                json["discovery_s"] = json!(published.matched_after_s);
                json["acknowledged"] = json!(published.acknowledged);
                json["bytes"] = json!(published.bytes);
            }
            SentVia::Action {
                action,
                outcome: o,
                recording,
            } => {
                let dropped = o.dropped.malformed + o.dropped.oversized + o.dropped.undecodable;
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
                json["dropped"] = json!(dropped);
                json["succeeded"] = json!(o.succeeded());
                json["lost"] = json!(o.lost);
                if let Some(r) = recording {
                    json["recording"] = r.report.clone();
                }
            }
        }
        json
    }
}

/// `{"file", "controller", "domain", "joint_names", "points", "duration_s", "via", …}`:
/// the topic's `"topic", "discovery_s", "acknowledged", "bytes"`, or the goal's `"action",
/// "goal_id", "status", "error_code", …, "recording"?`.
impl Serialize for Sent {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.json().serialize(s)
    }
}

impl fmt::Display for Sent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.via {
            SentVia::Topic { topic, published } => {
                let ack = if published.acknowledged {
                    "acknowledged"
                } else {
                    "not acknowledged in time"
                };
                writeln!(
                    f,
                    "sent {} points ({:.3} s) to {topic} on domain {}: {} subscriber(s), {ack}",
                    self.points, self.duration_s, self.domain, published.subscribers
                )?;
                write!(
                    f,
                    "a topic has no answer: the controller's own log says whether it ran (use --action for its result)"
                )
            }
            SentVia::Action {
                action,
                outcome: o,
                recording,
            } => {
                if let Some(lost) = &o.lost {
                    write!(f, "{lost}")?;
                } else if !o.accepted {
                    write!(f, "{action} refused the goal {}", o.goal_id)?;
                } else {
                    let said = if o.error_string.is_empty() {
                        String::new()
                    } else {
                        format!(", \"{}\"", o.error_string)
                    };
                    write!(
                        f,
                        "goal {} {}: error code {} ({}){said}",
                        o.goal_id,
                        o.status.word(),
                        o.error_code,
                        cps_ros2_msg::msg::error_code_word(o.error_code),
                    )?;
                }
                write!(
                    f,
                    "\n{} feedback message(s); server found after {:.2} s",
                    o.feedback, o.discovery_s
                )?;
                if o.cancel_requested {
                    write!(f, "\nthe goal was cancelled (Ctrl-C or no result in time)")?;
                }
                if let Some(r) = recording {
                    write!(f, "\n{r}")?;
                }
                Ok(())
            }
        }
    }
}

impl fmt::Display for Tracked {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.tracking {
            Some((_, rms, worst)) => write!(
                f,
                "tracking: the robot within {worst:.2e} rad of the points sent (worst joint), RMS {:.2e} rad",
                rms.iter().copied().fold(0.0, f64::max)
            )?,
            None => write!(
                f,
                "tracking: not judged, the joint states on {} stop before the goal's end",
                self.topic
            )?,
        }
        if let Some(l) = &self.limits {
            write!(f, "\n{l}")?;
        }
        let (out, report) = &self.written;
        write!(f, "\nwrote {} and {}", out.display(), report.display())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hand(grasped: Option<bool>) -> HandAt {
        HandAt {
            host: "127.0.0.1".into(),
            state: GripperState {
                message_id: 7,
                width: 0.0312,
                max_width: 0.0801,
                is_grasped: grasped == Some(true),
                temperature: 31,
            },
            grasped,
        }
    }

    #[test]
    fn the_hand_says_its_state_and_a_grasps_outcome_in_json_and_in_words() {
        let held = hand(Some(true));
        let json = serde_json::to_value(&held).expect("a JSON value");
        assert_eq!(json["width"], 0.0312);
        assert_eq!(json["grasped"], true);
        assert_eq!(
            held.to_string(),
            "grasped\n127.0.0.1 gripper: width 0.0312 m of 0.0801 m, holding, 31 °C"
        );
        // Only a grasp says whether it held.
        let moved = hand(None);
        let json = serde_json::to_value(&moved).expect("a JSON value");
        assert!(json.get("grasped").is_none(), "{json}");
        assert_eq!(
            moved.to_string(),
            "127.0.0.1 gripper: width 0.0312 m of 0.0801 m, not holding, 31 °C"
        );
    }

    #[test]
    fn a_recording_says_its_report_and_where_it_is() {
        let report =
            json!({"complete": true, "ending": "recorded for the whole duration", "samples": 3});
        let recorded = |guided| Recorded {
            host: "h".into(),
            out: "rec.csv".into(),
            samples: 3,
            duration_s: 0.002,
            guided,
            report: report.clone(),
        };
        let standing = recorded(false);
        assert_eq!(serde_json::to_value(&standing).expect("JSON"), report);
        assert_eq!(
            standing.to_string(),
            "h: recorded for the whole duration\n  3 samples over 0.002 s in rec.csv"
        );
        let taught = recorded(true).to_string();
        assert!(taught.starts_with("h: guided by hand; recorded for the whole duration\n"));
        assert!(taught.ends_with(
            "(imitate it: cps-cli imitate rec.csv --columns q1,q2,q3,q4,q5,q6,q7 --out model.json)"
        ));
    }

    #[test]
    fn a_message_on_a_topic_says_it_has_no_answer_and_keeps_its_counts_in_json() {
        let sent = Sent {
            file: "traj.csv".into(),
            controller: "/arm".into(),
            domain: 7,
            joint_names: vec!["j1".into()],
            points: 101,
            duration_s: 1.0,
            via: SentVia::Topic {
                topic: "/arm/joint_trajectory".into(),
                published: cps_ros2::publish::Published {
                    matched_after_s: 0.25,
                    subscribers: 1,
                    acknowledged: true,
                    bytes: 4242,
                },
            },
        };
        let json = serde_json::to_value(&sent).expect("JSON");
        assert_eq!(json["via"], "topic");
        assert_eq!(json["bytes"], 4242);
        assert_eq!(json["domain"], 7);
        assert!(json.get("goal_id").is_none(), "{json}");
        let text = sent.to_string();
        assert!(
            text.starts_with("sent 101 points (1.000 s) to /arm/joint_trajectory on domain 7: 1 subscriber(s), acknowledged\n"),
            "{text}"
        );
        assert!(text.ends_with("(use --action for its result)"), "{text}");
    }

    #[test]
    fn joint_states_too_few_for_a_limit_check_say_so_and_where_they_were_written() {
        let mut recorded = StatesRecorded {
            topic: "/joint_states".into(),
            domain: 0,
            joints: vec!["j1".into()],
            messages: 1,
            kept: 1,
            lost: 0,
            older: 2,
            incomplete: 0,
            dropped: cps_ros2::node::Counts::default(),
            time_source: "header stamp",
            first_message_s: 0.1,
            duration_s: 0.0,
            complete: true,
            limits: None,
            written: None,
        };
        let json = serde_json::to_value(&recorded).expect("JSON");
        assert_eq!(json["limits"], Value::Null);
        assert_eq!(json["older"], 2);
        assert!(
            json.get("written").is_none(),
            "the report holds no path: {json}"
        );
        recorded.written = Some(("rec.csv".into(), "rec.report.json".into()));
        let text = recorded.to_string();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3, "{text}");
        assert_eq!(
            lines[1],
            "the limit check needs two or more messages at increasing times"
        );
        assert_eq!(lines[2], "wrote rec.csv and rec.report.json");
    }
}
