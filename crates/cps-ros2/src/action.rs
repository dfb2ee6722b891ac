//! A client of `control_msgs/action/FollowJointTrajectory`, the action ros2_control's
//! joint_trajectory_controller serves (and MoveIt calls): the goal sent, its feedback
//! followed, its result read, the goal cancelled on request.
//!
//! An action is three services and two topics under `<action>/_action/`; services carry
//! rmw_cyclonedds's request header (the client's id and a sequence number, echoed in the
//! reply), so a reply is matched to its request and others' replies are ignored.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::Ros2Error;
use crate::cdr::{CdrError, CdrReader};
use crate::msg::{
    CancelResponse, Feedback, FollowJointTrajectoryGoal, GetResultResponse, GoalId, GoalRequest,
    GoalStatus, RequestHeader, SendGoalRequest, SendGoalResponse, Time,
};
use crate::names::{dds_service, dds_topic};
use crate::node::{Counts, Node, Qos, Reader, Writer, settle, wait_until};

/// How long after an unanswered cancel it is asked again.
const CANCEL_AGAIN: Duration = Duration::from_secs(1);

/// One service's two ends.
struct Service {
    request: Writer,
    reply: Reader,
}

impl Service {
    fn new(
        node: &Node,
        name: &str,
        request_type: &str,
        reply_type: &str,
    ) -> Result<Self, Ros2Error> {
        let (rq, rr) = dds_service(node.name(), name)?;
        let qos = Qos::Reliable { depth: 100 };
        Ok(Service {
            request: node.writer(&rq, request_type, qos)?,
            reply: node.reader(&rr, reply_type, qos)?,
        })
    }

    fn ready(&mut self) -> bool {
        self.request.matched() > 0 && self.reply.matched() > 0
    }
}

/// What a goal came to.
#[derive(Debug, Clone, PartialEq)]
pub struct FollowOutcome {
    /// The goal's id.
    pub goal_id: GoalId,
    /// Seconds from the start until the server was found.
    pub discovery_s: f64,
    /// Whether the controller took the goal.
    pub accepted: bool,
    /// When the controller took it, by its clock (the trajectory's time 0 there).
    pub accepted_stamp: Time,
    /// When its answer arrived, by this machine's clock (ns since the Unix epoch).
    pub accepted_at_ns: u64,
    /// How it ended (for a refused goal: `Unknown`).
    pub status: GoalStatus,
    /// FollowJointTrajectory's `error_code` (0 successful).
    pub error_code: i32,
    /// The controller's words.
    pub error_string: String,
    /// Feedback messages received for this goal.
    pub feedback: u64,
    /// Whether a cancel was asked for (Ctrl-C, or no result in time).
    pub cancel_requested: bool,
    /// Samples dropped on the action's topics (malformed, oversized, undecodable).
    pub dropped: Counts,
}

impl FollowOutcome {
    /// Whether the goal was reached as asked.
    pub fn succeeded(&self) -> bool {
        self.accepted && self.status == GoalStatus::Succeeded && self.error_code == 0
    }
}

/// Time limits of one goal.
#[derive(Debug, Clone, Copy)]
pub struct FollowTimes {
    /// For the server to be found and to answer the goal.
    pub server: Duration,
    /// For the result after acceptance (the trajectory's duration and a margin).
    pub result: Duration,
    /// For the result after a cancel was sent.
    pub after_cancel: Duration,
}

/// A FollowJointTrajectory client of one action.
pub struct FollowJointTrajectoryClient {
    name: String,
    send_goal: Service,
    get_result: Service,
    cancel: Service,
    feedback: Reader,
    client: u64,
    sequence: i64,
}

impl FollowJointTrajectoryClient {
    /// A client of the action `name` (`/panda_arm_controller/follow_joint_trajectory`).
    pub fn new(node: &Node, name: &str) -> Result<Self, Ros2Error> {
        let a = format!("{name}/_action");
        let send_goal = Service::new(
            node,
            &format!("{a}/send_goal"),
            SendGoalRequest::TYPE,
            SendGoalResponse::TYPE,
        )?;
        let get_result = Service::new(
            node,
            &format!("{a}/get_result"),
            GoalRequest::GET_RESULT_TYPE,
            GetResultResponse::TYPE,
        )?;
        let cancel = Service::new(
            node,
            &format!("{a}/cancel_goal"),
            GoalRequest::CANCEL_TYPE,
            CancelResponse::TYPE,
        )?;
        let feedback = node.reader(
            &dds_topic(node.name(), &format!("{a}/feedback"))?,
            Feedback::TYPE,
            Qos::Reliable { depth: 100 },
        )?;
        // The client's id: its send_goal reply reader's, unique on the graph.
        let client = send_goal.reply.id();
        Ok(FollowJointTrajectoryClient {
            name: name.to_string(),
            send_goal,
            get_result,
            cancel,
            feedback,
            client,
            sequence: 0,
        })
    }

    /// The action's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Waits until the action server's three services are matched, or `deadline`.
    pub fn wait_for_server(&mut self, deadline: Instant) -> bool {
        wait_until(deadline, || {
            self.send_goal.ready() && self.get_result.ready() && self.cancel.ready()
        })
    }

    fn next_header(&mut self) -> RequestHeader {
        self.sequence += 1;
        RequestHeader {
            client: self.client,
            sequence: self.sequence,
        }
    }

    /// Sends `goal` with `goal_id`, follows it to its end and returns what it came to;
    /// `on_feedback` sees each feedback message of this goal; when `cancel` turns true
    /// the goal is cancelled and its end still awaited (within `times.after_cancel`).
    /// Errors: no server within `times.server`, no answer to the goal, no result.
    pub fn follow(
        &mut self,
        goal: &FollowJointTrajectoryGoal,
        goal_id: GoalId,
        times: FollowTimes,
        cancel: &AtomicBool,
        mut on_feedback: impl FnMut(&Feedback),
    ) -> Result<FollowOutcome, Ros2Error> {
        let start = Instant::now();
        if !self.wait_for_server(start + times.server) {
            let partial = self.partial();
            return Err(Ros2Error::NoPeer(format!(
                "no FollowJointTrajectory server answered at {} within {:.1} s (is the controller loaded and active, on this ROS_DOMAIN_ID?){}",
                self.name,
                times.server.as_secs_f64(),
                partial
            )));
        }
        let discovery_s = start.elapsed().as_secs_f64();
        std::thread::sleep(settle(discovery_s));
        let header = self.next_header();
        let request = SendGoalRequest {
            header,
            goal_id,
            goal: goal.clone(),
        };
        self.send_goal.request.write_cdr(&request.to_cdr())?;
        let mut outcome = FollowOutcome {
            goal_id,
            discovery_s,
            accepted: false,
            accepted_stamp: Time::default(),
            accepted_at_ns: 0,
            status: GoalStatus::Unknown,
            error_code: 0,
            error_string: String::new(),
            feedback: 0,
            cancel_requested: false,
            dropped: Counts::default(),
        };
        let answer = wait_reply(
            &mut self.send_goal.reply,
            header,
            Instant::now() + times.server,
            SendGoalResponse::decode,
            |r| r.header,
        );
        let Some(answer) = answer else {
            return Err(Ros2Error::NoPeer(format!(
                "{} did not answer the goal within {:.1} s",
                self.name,
                times.server.as_secs_f64()
            )));
        };
        outcome.accepted = answer.accepted;
        outcome.accepted_stamp = answer.stamp;
        outcome.accepted_at_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        if !answer.accepted {
            outcome.dropped = self.dropped();
            return Ok(outcome);
        }
        let result_header = self.next_header();
        self.get_result.request.write_cdr(
            &GoalRequest {
                header: result_header,
                goal_id,
            }
            .result_cdr(),
        )?;
        let mut deadline = Instant::now() + times.result;
        // A cancel is asked again each second until the server answers it (asking twice
        // is harmless; a request the server's reader had not matched yet is lost).
        let mut cancel_asked: Option<(RequestHeader, Instant)> = None;
        let mut cancel_answered = false;
        loop {
            if outcome.cancel_requested && !cancel_answered {
                if let Some((h, _)) = cancel_asked
                    && take_reply(&mut self.cancel.reply, h, CancelResponse::decode, |r| {
                        r.header
                    })
                    .is_some()
                {
                    cancel_answered = true;
                } else if cancel_asked.is_none_or(|(_, at)| at.elapsed() >= CANCEL_AGAIN) {
                    let h = self.next_header();
                    self.cancel
                        .request
                        .write_cdr(&GoalRequest { header: h, goal_id }.cancel_cdr())?;
                    cancel_asked = Some((h, Instant::now()));
                }
            }
            while let Some(f) = self.feedback.take_with(Feedback::decode) {
                if f.message.goal_id == goal_id {
                    outcome.feedback += 1;
                    on_feedback(&f.message);
                }
            }
            if let Some(r) = take_reply(
                &mut self.get_result.reply,
                result_header,
                GetResultResponse::decode,
                |r| r.header,
            ) {
                outcome.status = r.status;
                outcome.error_code = r.error_code;
                outcome.error_string = r.error_string;
                outcome.dropped = self.dropped();
                return Ok(outcome);
            }
            let late = Instant::now() >= deadline;
            if (cancel.load(Ordering::Relaxed) || late) && !outcome.cancel_requested {
                outcome.cancel_requested = true;
                deadline = Instant::now() + times.after_cancel;
            } else if late {
                return Err(Ros2Error::NoPeer(format!(
                    "{} sent no result for goal {goal_id} (cancelled after {:.1} s without one; the controller may still be moving)",
                    self.name,
                    times.result.as_secs_f64()
                )));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// What of a server was found, when only part of it was.
    fn partial(&mut self) -> String {
        let found: Vec<String> = [
            ("send_goal", &mut self.send_goal),
            ("get_result", &mut self.get_result),
            ("cancel_goal", &mut self.cancel),
        ]
        .into_iter()
        .flat_map(|(n, s)| {
            [
                (format!("{n} requests"), s.request.matched()),
                (format!("{n} replies"), s.reply.matched()),
            ]
        })
        .filter(|(_, m)| *m > 0)
        .map(|(n, _)| n)
        .collect();
        if found.is_empty() {
            String::new()
        } else {
            format!("; only found: {}", found.join(", "))
        }
    }

    fn dropped(&self) -> Counts {
        let mut c = Counts::default();
        for r in [
            self.send_goal.reply.counts(),
            self.get_result.reply.counts(),
            self.cancel.reply.counts(),
            self.feedback.counts(),
        ] {
            c.malformed += r.malformed;
            c.oversized += r.oversized;
            c.undecodable += r.undecodable;
            c.read += r.read;
        }
        c
    }
}

/// The reply to `header`, if it has come (others' replies are skipped).
fn take_reply<M>(
    reader: &mut Reader,
    header: RequestHeader,
    decode: fn(&mut CdrReader) -> Result<M, CdrError>,
    header_of: fn(&M) -> RequestHeader,
) -> Option<M> {
    while let Some(r) = reader.take_with(decode) {
        if header_of(&r.message) == header {
            return Some(r.message);
        }
    }
    None
}

fn wait_reply<M>(
    reader: &mut Reader,
    header: RequestHeader,
    deadline: Instant,
    decode: fn(&mut CdrReader) -> Result<M, CdrError>,
    header_of: fn(&M) -> RequestHeader,
) -> Option<M> {
    loop {
        if let Some(m) = take_reply(reader, header, decode, header_of) {
            return Some(m);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}
