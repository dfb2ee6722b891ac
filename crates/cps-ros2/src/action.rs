//! A client of a ROS 2 action — `control_msgs/action/FollowJointTrajectory`, the action
//! ros2_control's joint_trajectory_controller serves (and MoveIt calls), or any other whose
//! types implement [`Action`]: the goal sent, its feedback followed, its result read, the
//! goal cancelled on request.
//!
//! An action is three services and two topics under `<action>/_action/`; the services
//! speak their server's request/reply mapping, Cyclone's or Fast DDS's
//! ([`crate::service`]), so a reply is matched to its request and others' are ignored.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::Ros2Error;
use crate::names::dds_topic;
use crate::node::{Counts, Node, Qos, Reader, settle, wait_until};
use crate::service::{Mapping, MappingChoice, Pending, ServiceClient};
use cps_ros2_msg::cdr::CdrWriter;
use cps_ros2_msg::msg::{
    Action, CANCEL_REPLY_TYPE, CANCEL_REQUEST_TYPE, CancelAnswer, Feedback, FollowJointTrajectory,
    FollowJointTrajectoryGoal, GoalAnswer, GoalId, GoalResult, GoalStatus, Time, action_type,
};

/// How long after an unanswered cancel it is asked again.
const CANCEL_AGAIN: Duration = Duration::from_secs(1);

/// Writes a send_goal request's body: the goal's id, then the goal.
pub fn write_send_goal<A: Action>(w: &mut CdrWriter, goal_id: GoalId, goal: &A::Goal) {
    w.raw(&goal_id.0);
    A::encode_goal(goal, w);
}

/// What a goal of action `A` came to.
#[derive(Debug, Clone, PartialEq)]
pub struct ActionOutcome<R> {
    /// The goal's id.
    pub goal_id: GoalId,
    /// Seconds from the start until the server was found.
    pub discovery_s: f64,
    /// The request/reply mapping spoken with the server.
    pub mapping: Mapping,
    /// Whether the server took the goal.
    pub accepted: bool,
    /// When the server took it, by its clock.
    pub accepted_stamp: Time,
    /// When its answer arrived, by this machine's clock (ns since the Unix epoch).
    pub accepted_at_ns: u64,
    /// How it ended (for a refused goal: `Unknown`).
    pub status: GoalStatus,
    /// The server's result (none for a refused goal).
    pub result: Option<R>,
    /// Feedback messages received for this goal.
    pub feedback: u64,
    /// Whether a cancel was asked for (the caller's flag, or no result in time).
    pub cancel_requested: bool,
    /// Samples dropped on the action's topics (malformed, oversized, undecodable).
    pub dropped: Counts,
    /// Why the end of an accepted goal is not known, in a sentence: the server left while
    /// it ran, or sent no result even after a cancel ([`GoalStatus::Unknown`] then).
    pub lost: Option<String>,
}

/// How often a running goal's server is looked for on the graph.
const SERVER_CHECK: Duration = Duration::from_millis(50);

/// A client of one action of type `A`.
pub struct ActionClient<A: Action> {
    name: String,
    send_goal: ServiceClient,
    get_result: ServiceClient,
    cancel: ServiceClient,
    feedback: Reader,
    /// Whether the wait after matching was spent on the server matched now (a second
    /// goal to a server still matched need not wait again).
    settled: bool,
    _action: std::marker::PhantomData<A>,
}

impl<A: Action> ActionClient<A> {
    /// A client of the action `name` (`/panda_arm_controller/follow_joint_trajectory`),
    /// speaking `choice`'s request/reply mapping.
    pub fn new(node: &Node, name: &str, choice: MappingChoice) -> Result<Self, Ros2Error> {
        let a = format!("{name}/_action");
        let service = |s: &str, rq: String, rr: String| {
            ServiceClient::new(node, &format!("{a}/{s}"), &rq, &rr, choice)
        };
        let send_goal = service(
            "send_goal",
            action_type::<A>("SendGoal_Request"),
            action_type::<A>("SendGoal_Response"),
        )?;
        let get_result = service(
            "get_result",
            action_type::<A>("GetResult_Request"),
            action_type::<A>("GetResult_Response"),
        )?;
        let cancel = service(
            "cancel_goal",
            CANCEL_REQUEST_TYPE.to_string(),
            CANCEL_REPLY_TYPE.to_string(),
        )?;
        let feedback = node.reader(
            &dds_topic(node.name(), &format!("{a}/feedback"))?,
            &action_type::<A>("FeedbackMessage"),
            Qos::Reliable { depth: 100 },
        )?;
        Ok(ActionClient {
            name: name.to_string(),
            send_goal,
            get_result,
            cancel,
            feedback,
            settled: false,
            _action: std::marker::PhantomData,
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

    /// Sends `goal` with `goal_id`, follows it to its end and returns what it came to;
    /// `on_feedback` sees each feedback message of this goal; when `cancel` turns true
    /// the goal is cancelled and its end still awaited (within `times.after_cancel`).
    /// Errors: no server within `times.server`, no answer to the goal. Once the goal is
    /// accepted the answer is an outcome: a server that leaves while the goal runs (a
    /// crash is noticed when its participant's lease runs out) or sends no result even
    /// after a cancel ends it at once with [`ActionOutcome::lost`] saying so.
    pub fn follow(
        &mut self,
        goal: &A::Goal,
        goal_id: GoalId,
        times: FollowTimes,
        cancel: &AtomicBool,
        mut on_feedback: impl FnMut(&A::Feedback),
    ) -> Result<ActionOutcome<A::Result>, Ros2Error> {
        let start = Instant::now();
        let still_matched = self.settled
            && self.send_goal.ready()
            && self.get_result.ready()
            && self.cancel.ready();
        if !self.wait_for_server(start + times.server) {
            let partial = self.partial();
            return Err(Ros2Error::NoPeer(format!(
                "no action server answered at {} within {:.1} s (is the controller loaded and active, on this ROS_DOMAIN_ID?){}",
                self.name,
                times.server.as_secs_f64(),
                partial
            )));
        }
        let discovery_s = start.elapsed().as_secs_f64();
        if !still_matched {
            std::thread::sleep(settle(discovery_s));
            self.settled = true;
        }
        let mapping = self.send_goal.mapping();
        let sent = self
            .send_goal
            .send(|w| write_send_goal::<A>(w, goal_id, goal))?;
        let mut outcome = ActionOutcome {
            goal_id,
            discovery_s,
            mapping,
            accepted: false,
            accepted_stamp: Time::default(),
            accepted_at_ns: 0,
            status: GoalStatus::Unknown,
            result: None,
            feedback: 0,
            cancel_requested: false,
            dropped: Counts::default(),
            lost: None,
        };
        let answer =
            self.send_goal
                .wait_reply(sent, Instant::now() + times.server, GoalAnswer::decode);
        let Some(answer) = answer else {
            return Err(Ros2Error::NoPeer(format!(
                "{} did not answer the goal within {:.1} s (cps spoke {}'s request/reply mapping to it; a server on another middleware needs --service-mapping)",
                self.name,
                times.server.as_secs_f64(),
                mapping_name(mapping),
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
        let result_asked = self.get_result.send(|w| {
            w.raw(&goal_id.0);
        })?;
        let mut deadline = Instant::now() + times.result;
        let mut server_checked = Instant::now();
        // A cancel is asked again each second until the server answers it (asking twice
        // is harmless; a request the server's reader had not matched yet is lost).
        let mut cancel_asked: Option<(Pending, Instant)> = None;
        let mut cancel_answered = false;
        loop {
            if outcome.cancel_requested && !cancel_answered {
                if let Some((p, _)) = cancel_asked
                    && self.cancel.take_reply(p, CancelAnswer::decode).is_some()
                {
                    cancel_answered = true;
                } else if cancel_asked.is_none_or(|(_, at)| at.elapsed() >= CANCEL_AGAIN) {
                    // action_msgs/GoalInfo: the id, stamp zero.
                    let p = self.cancel.send(|w| {
                        w.raw(&goal_id.0);
                        w.i32(0).u32(0);
                    })?;
                    cancel_asked = Some((p, Instant::now()));
                }
            }
            while let Some(f) = self.feedback.take_with(|r| {
                let id = GoalId(r.array("goal_id")?);
                Ok((id, A::decode_feedback(r)?))
            }) {
                let (id, feedback) = f.message;
                if id == goal_id {
                    outcome.feedback += 1;
                    on_feedback(&feedback);
                }
            }
            if let Some(r) = self
                .get_result
                .take_reply(result_asked, |r| GoalResult::decode(r, A::decode_result))
            {
                outcome.status = r.status;
                outcome.result = Some(r.result);
                outcome.dropped = self.dropped();
                return Ok(outcome);
            }
            if server_checked.elapsed() >= SERVER_CHECK {
                server_checked = Instant::now();
                if !self.get_result.ready() {
                    outcome.lost = Some(format!(
                        "the action server {} left while goal {goal_id} ran ({} feedback message(s) had come); where the robot stopped is not known",
                        self.name, outcome.feedback
                    ));
                    outcome.dropped = self.dropped();
                    return Ok(outcome);
                }
            }
            let late = Instant::now() >= deadline;
            if (cancel.load(Ordering::Relaxed) || late) && !outcome.cancel_requested {
                outcome.cancel_requested = true;
                deadline = Instant::now() + times.after_cancel;
            } else if late {
                outcome.lost = Some(format!(
                    "{} sent no result for goal {goal_id} (cancelled after {:.1} s without one, and none came {:.1} s after that); the controller may still be moving",
                    self.name,
                    times.result.as_secs_f64(),
                    times.after_cancel.as_secs_f64()
                ));
                outcome.dropped = self.dropped();
                return Ok(outcome);
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
            s.found()
                .into_iter()
                .map(move |what| format!("{n} {what}"))
                .collect::<Vec<_>>()
        })
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
            self.send_goal.counts(),
            self.get_result.counts(),
            self.cancel.counts(),
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

fn mapping_name(m: Mapping) -> &'static str {
    match m {
        Mapping::Cyclone => "CycloneDDS",
        Mapping::FastDds => "Fast DDS",
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
    /// The request/reply mapping spoken with the controller.
    pub mapping: Mapping,
    /// Why the end of an accepted goal is not known ([`ActionOutcome::lost`]).
    pub lost: Option<String>,
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
    inner: ActionClient<FollowJointTrajectory>,
}

impl FollowJointTrajectoryClient {
    /// A client of the action `name` (`/panda_arm_controller/follow_joint_trajectory`)
    /// speaking its server's request/reply mapping.
    pub fn new(node: &Node, name: &str) -> Result<Self, Ros2Error> {
        Self::with_mapping(node, name, MappingChoice::Auto)
    }

    /// [`Self::new`], speaking `choice`'s mapping.
    pub fn with_mapping(node: &Node, name: &str, choice: MappingChoice) -> Result<Self, Ros2Error> {
        Ok(FollowJointTrajectoryClient {
            inner: ActionClient::new(node, name, choice)?,
        })
    }

    /// The action's name.
    pub fn name(&self) -> &str {
        self.inner.name()
    }

    /// Waits until the action server's three services are matched, or `deadline`.
    pub fn wait_for_server(&mut self, deadline: Instant) -> bool {
        self.inner.wait_for_server(deadline)
    }

    /// [`ActionClient::follow`] for a FollowJointTrajectory goal.
    pub fn follow(
        &mut self,
        goal: &FollowJointTrajectoryGoal,
        goal_id: GoalId,
        times: FollowTimes,
        cancel: &AtomicBool,
        on_feedback: impl FnMut(&Feedback),
    ) -> Result<FollowOutcome, Ros2Error> {
        let o = self
            .inner
            .follow(goal, goal_id, times, cancel, on_feedback)?;
        let result = o.result.unwrap_or_default();
        Ok(FollowOutcome {
            goal_id: o.goal_id,
            discovery_s: o.discovery_s,
            accepted: o.accepted,
            accepted_stamp: o.accepted_stamp,
            accepted_at_ns: o.accepted_at_ns,
            status: o.status,
            error_code: result.error_code,
            error_string: result.error_string,
            feedback: o.feedback,
            cancel_requested: o.cancel_requested,
            dropped: o.dropped,
            mapping: o.mapping,
            lost: o.lost,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::service::{RequestHeader, request_sample};

    #[test]
    fn a_send_goal_request_starts_with_the_service_header_and_the_id() {
        let header = RequestHeader {
            client: 0x0102030405060708,
            sequence: 3,
        };
        let goal = FollowJointTrajectoryGoal::default();
        let b = request_sample(header, |w| {
            write_send_goal::<FollowJointTrajectory>(w, GoalId([9; 16]), &goal)
        });
        assert_eq!(b[4..12], 0x0102030405060708u64.to_le_bytes());
        assert_eq!(b[12..20], 3u64.to_le_bytes());
        assert_eq!(b[20..36], [9; 16]);
        // trajectory: an empty header (stamp 8, frame_id 4 + 1, padded to 16), no names
        // (4), no points (4); multi_dof the same; four empty tolerance lists;
        // goal_time_tolerance.
        assert_eq!(b.len(), 4 + 32 + 24 + 24 + 16 + 8);
    }
}
