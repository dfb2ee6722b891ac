//! The reference the robot holds: what the FCI differentiates each command against.
//!
//! The robot judges a joint command by its backward differences from the reference it
//! holds — the last command it applied, with that command's velocity and acceleration
//! (sent back in every state as `q_d`, `dq_d`, `ddq_d`, so that a client can compute "in
//! advance, even in case of packet losses" what the robot will compute). A cycle whose
//! command is lost or late is not skipped: the robot "takes the previous waypoints and
//! performs a linear extrapolation (keep acceleration constant and integrate) for the
//! missed time step" (FCI documentation, minimum system and network requirements), and
//! judges the next command against that extrapolation. A client that judges its commands
//! against its own last one at a fixed 1 ms breaks the robot's rules on the first lost
//! cycle; one that times its motion by the robot's clock and judges against the robot's
//! reference, as libfranka does, goes on.
//!
//! [`ReferenceTracker`] keeps the robot's reference exactly, in doubles: every command cps
//! sent, and the extrapolation of every cycle cps did not answer. Whether a command cps
//! sent reached the robot in time is read back from the next state, whose `q_d`, `dq_d`,
//! `ddq_d` are that reference rounded to single precision: of the candidates — the
//! command applied; the command dropped and its cycle extrapolated; every command as sent
//! (a simulator that applies late commands too) — the robot's is the one the state rounds
//! to. A robot whose state carries no usable reference (franky-sim low-pass filters its
//! `dq_d`) leaves the commands as sent, counted as unconfirmed.
//!
//! Nothing here allocates: the tracker lives in the realtime loop.

use crate::limits::DT;
use crate::wire::{JOINTS, RobotState};

/// The joint reference a Franka holds: cps-robot's [`cps_robot::Reference`] of its seven
/// joints, its period the FCI's millisecond ([`DT`]).
pub type Reference = cps_robot::Reference<JOINTS>;

/// Whether `ours` is what the robot reported as `reported` (a single-precision float):
/// within two of its units in the last place, or `floor` where it is near zero.
#[inline]
fn rounds_to(ours: f64, reported: f64, floor: f64) -> bool {
    (ours - reported).abs() <= reported.abs() * 2.0 * f64::from(f32::EPSILON) + floor
}

/// How well a candidate reference agrees with what a state reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Agreement {
    /// Position, velocity and acceleration (a velocity motion: the last two).
    Whole,
    /// The position only.
    Position,
    /// Neither.
    None,
}

fn agreement(r: &Reference, s: &RobotState, velocity_motion: bool) -> Agreement {
    let position = (0..JOINTS).all(|i| rounds_to(r.q[i], s.q_d[i], 1e-9));
    let derivatives = (0..JOINTS)
        .all(|i| rounds_to(r.v[i], s.dq_d[i], 1e-6) && rounds_to(r.a[i], s.ddq_d[i], 1e-3));
    match (position || velocity_motion, derivatives) {
        (true, true) => Agreement::Whole,
        (true, false) if !velocity_motion => Agreement::Position,
        _ => Agreement::None,
    }
}

/// What the robot's states said of the commands cps sent, over a motion.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReferenceCounts {
    /// Cycles the robot extrapolated: those cps did not answer, and those whose command
    /// the robot dropped.
    pub extrapolated: u64,
    /// Commands cps sent that the robot dropped (its next state shows the extrapolation).
    pub dropped: u64,
    /// Commands cps sent that a simulator applied late (its next state showed them
    /// dropped; a later one, applied after all).
    pub applied_late: u64,
    /// States whose reported reference agreed with none of the candidates (a robot that
    /// reports no usable reference): the commands are taken as sent.
    pub unconfirmed: u64,
}

/// The robot's joint reference through a motion, kept exactly (see the module's text).
#[derive(Debug, Clone, Copy)]
pub struct ReferenceTracker {
    /// The reference the robot holds after cycle `base_id` (before the motion's first
    /// command: at rest where it starts).
    base: Reference,
    base_id: Option<u64>,
    /// The same, if every command cps sent was applied.
    as_sent: Reference,
    /// The last command sent, the robot cycle (state id) it answered, and whether cps was
    /// behind when it answered (it skipped stale states for it: the answer may come late).
    pending: Option<(u64, [f64; JOINTS], bool)>,
    /// Whether no command has been applied yet (the robot takes the first as a
    /// standstill).
    first: bool,
    /// Where a state showed a command dropped that a simulator may still apply late: the
    /// references with it applied after all (on time, or over the run of lost cycles it
    /// ended), as they stood right after it, and its cycle; until a state tells them apart.
    alternatives: [Option<(Reference, u64)>; 2],
    /// Whether those came from a state that showed the command dropped.
    after_drop: bool,
    /// The reference right after the last command the robot applied, and its cycle (None
    /// before the first).
    real: Option<(Reference, u64)>,
    /// A velocity motion: its `q_d` is the robot's integral, so only `dq_d` and `ddq_d`
    /// are compared.
    velocity_motion: bool,
    counts: ReferenceCounts,
}

impl ReferenceTracker {
    /// A motion starting at rest at `q0` (the robot's `q_d` before the Move).
    pub fn new(q0: [f64; JOINTS], velocity_motion: bool) -> Self {
        ReferenceTracker {
            base: Reference::at_rest(q0),
            base_id: None,
            as_sent: Reference::at_rest(q0),
            pending: None,
            first: true,
            alternatives: [None; 2],
            after_drop: false,
            real: None,
            velocity_motion,
            counts: ReferenceCounts::default(),
        }
    }

    /// Whether the robot's reference is not known for the next command: the last command
    /// may have come late — the state showed it dropped (what a real robot does with one
    /// that comes late), or it ended a run of cycles cps did not answer (it was answered
    /// late in the cycle) — and a simulator (franka-sim) applies a late command after all,
    /// after publishing that state, differenced over the run it ends. The references differ
    /// by what the command changed, which a command judged against the wrong one carries
    /// into the robot as a discontinuity; so none is sent for this cycle, and the next
    /// state, the robot's extrapolation of one or the other, tells them apart.
    pub fn unresolved(&self) -> bool {
        self.alternatives.iter().any(Option::is_some)
    }

    /// What the states said so far.
    pub fn counts(&self) -> ReferenceCounts {
        self.counts
    }

    /// Cycles after the base's and before `id` that went without a command.
    fn unanswered_before(&self, id: u64) -> u64 {
        self.base_id.map_or(0, |b| id.saturating_sub(b + 1))
    }

    /// The reference the robot holds when it judges the answer to `state`: the last
    /// command it applied (or the motion's start), extrapolated over every cycle since
    /// that went without one.
    pub fn reference(&mut self, state: &RobotState) -> Reference {
        let agrees = |r: &Reference| agreement(r, state, self.velocity_motion);
        let since = |id: u64| state.message_id.saturating_sub(id + 1);
        let Some((sent_id, q_c, behind)) = self.pending.take() else {
            let gap = self.unanswered_before(state.message_id);
            self.counts.extrapolated += gap;
            self.base = self.base.extrapolated_by(gap, DT);
            self.as_sent = self.as_sent.extrapolated_by(gap, DT);
            // Dropped (as the last state said), or applied late after all: this state says
            // which, where they differ.
            let late =
                self.alternatives.iter().flatten().find(|(alt, id)| {
                    agrees(&alt.extrapolated_by(since(*id), DT)) == Agreement::Whole
                });
            if let Some(&(alt, id)) = late
                && agrees(&self.base) != Agreement::Whole
            {
                self.base = alt.extrapolated_by(since(id), DT);
                self.real = Some((alt, id));
                if self.after_drop {
                    self.counts.dropped -= 1;
                    self.counts.extrapolated -= 1;
                }
                self.counts.applied_late += 1;
            }
            self.alternatives = [None; 2];
            if self.base_id.is_some() {
                self.base_id = Some(state.message_id - 1);
            }
            return self.base;
        };
        // Cycles before the one cps answered, and after it, that went unanswered.
        let before = self.unanswered_before(sent_id);
        let gap = since(sent_id);
        let after = |r: &Reference, cycles: u64| {
            if self.first {
                Reference::at_rest(q_c)
            } else {
                r.after_over(&q_c, cycles, DT)
            }
        };
        // The robot's: the command applied on time, or dropped; a simulator's that applies
        // late commands (franka-sim): the run of cycles it extrapolated since the last
        // command it applied taken back, and this one differenced over the whole run; or
        // every command applied as sent. Each as it stands right after the command.
        let applied = after(&self.base.extrapolated_by(before, DT), 1);
        let over_run = match self.real {
            Some((real, id)) => after(&real, sent_id.saturating_sub(id).max(1)),
            None => applied,
        };
        let as_sent = after(&self.as_sent.extrapolated_by(before, DT), 1);
        let dropped = self.base.extrapolated_by(before + 1, DT);
        let candidates = [
            (applied, Kind::Applied),
            (over_run, Kind::AppliedLate),
            (as_sent, Kind::AppliedLate),
            (dropped, Kind::Dropped),
        ];
        let now = |r: &Reference| r.extrapolated_by(gap, DT);
        let whole = candidates
            .iter()
            .find(|(r, _)| agrees(&now(r)) == Agreement::Whole);
        let (chosen, kind) = match whole {
            Some(&c) => c,
            None => {
                self.counts.unconfirmed += 1;
                // The position alone, where it tells one candidate from the others.
                let mut by_position = candidates
                    .iter()
                    .filter(|(r, _)| agrees(&now(r)) != Agreement::None);
                match (by_position.next(), by_position.next()) {
                    (Some(&c), None) => c,
                    _ => (applied, Kind::Applied),
                }
            }
        };
        self.counts.extrapolated += before + gap;
        match kind {
            Kind::Applied | Kind::AppliedLate => {
                self.real = Some((chosen, sent_id));
                if kind == Kind::AppliedLate {
                    self.counts.applied_late += 1;
                }
            }
            Kind::Dropped => {
                self.counts.dropped += 1;
                self.counts.extrapolated += 1;
            }
        }
        // A command that may still be applied late (shown dropped, or ending a run of
        // unanswered cycles): unresolved until the next state, where they differ at all.
        let maybe_late =
            kind == Kind::Dropped || (behind && kind == Kind::Applied && over_run != applied);
        self.alternatives = if maybe_late {
            [applied, over_run].map(|r| (r != chosen).then_some((r, sent_id)))
        } else {
            [None; 2]
        };
        self.after_drop = kind == Kind::Dropped;
        self.base = now(&chosen);
        self.base_id = Some(state.message_id - 1);
        self.as_sent = now(&as_sent);
        self.first = self.first && kind == Kind::Dropped;
        self.base
    }

    /// Notes the command sent in answer to the state `message_id` (after
    /// [`ReferenceTracker::reference`] for that state); `behind`: cps skipped stale states
    /// to answer it, so the answer may come late.
    pub fn sent(&mut self, message_id: u64, q_c: [f64; JOINTS], behind: bool) {
        self.pending = Some((message_id, q_c, behind));
        if self.base_id.is_none() {
            // The motion's first command: the robot held its start until then.
            self.base_id = Some(message_id.saturating_sub(1));
        }
    }

    /// Takes back the last command noted: it was not sent after all.
    pub fn withdraw(&mut self) {
        self.pending = None;
    }
}

/// The torques the robot applies through a torque-controlled motion: the state's
/// `tau_J_d`, which a dropped torque command leaves at the torques before it ("FCI will
/// reuse the torques of the last successful received packet"); the next command's rate is
/// judged from those.
#[derive(Debug, Clone, Copy, Default)]
pub struct TorqueTracker {
    /// The last state asked about.
    last: Option<u64>,
    /// The torques sent in answer to it, unless they were withdrawn.
    pending: Option<[f64; JOINTS]>,
    counts: ReferenceCounts,
}

impl TorqueTracker {
    /// What the states said so far (`extrapolated`: cycles the robot held its torques).
    pub fn counts(&self) -> ReferenceCounts {
        self.counts
    }

    /// The torques the robot applied last, as `state` reports them.
    pub fn reference(&mut self, state: &RobotState) -> [f64; JOINTS] {
        let reported = state.tau_j_d;
        let usable = reported.iter().all(|x| x.is_finite());
        if let Some(last) = self.last {
            let gap = state.message_id.saturating_sub(last + 1);
            self.counts.extrapolated += gap;
            match self.pending.take() {
                Some(tau) if gap == 0 && usable => {
                    if !(0..JOINTS).all(|i| rounds_to(tau[i], reported[i], 1e-6)) {
                        self.counts.dropped += 1;
                        self.counts.extrapolated += 1;
                    }
                }
                Some(_) => {}
                // Withdrawn: the robot held its torques through that cycle too.
                None => self.counts.extrapolated += 1,
            }
        }
        self.last = Some(state.message_id);
        if usable {
            reported
        } else {
            self.counts.unconfirmed += 1;
            [0.0; JOINTS]
        }
    }

    /// Notes the torques sent in answer to the last state asked about.
    pub fn sent(&mut self, tau: [f64; JOINTS]) {
        self.pending = Some(tau);
    }

    /// Takes back the last torques noted: they were not sent after all (the robot reused
    /// the ones before).
    pub fn withdraw(&mut self) {
        self.pending = None;
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Applied,
    AppliedLate,
    Dropped,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(id: u64, r: &Reference) -> RobotState {
        let mut s = RobotState::decode(&[0u8; crate::wire::STATE_SIZE]).unwrap();
        s.message_id = id;
        // What the robot sends: its doubles rounded to single precision.
        let f = |x: f64| f64::from(x as f32);
        s.q_d = r.q.map(f);
        s.dq_d = r.v.map(f);
        s.ddq_d = r.a.map(f);
        s
    }

    /// A smooth motion's command at time `t` (a cubic: jerk 6 rad/s³ on every joint).
    fn command(t: f64) -> [f64; JOINTS] {
        std::array::from_fn(|i| 0.1 * i as f64 + 0.3 * t + 2.0 * t * t + t * t * t)
    }

    #[test]
    fn a_state_tells_applied_dropped_and_unanswered_cycles_apart() {
        // The robot's side, exactly: command k answers state k; state k carries the
        // reference after cycle k - 1.
        let q0 = command(0.0);
        let mut tracker = ReferenceTracker::new(q0, false);
        let mut robot = Reference::at_rest(q0);
        let mut first = true;
        // Cycle 10's command is dropped; cycles 20 and 21 go unanswered.
        for k in 0u64..40 {
            if k == 21 {
                robot = robot.extrapolated(DT);
                continue;
            }
            let ours = tracker.reference(&state(k, &robot));
            assert_eq!(ours, robot, "cycle {k}");
            let c = command(k as f64 * DT);
            tracker.sent(k, c, false);
            robot = if k == 10 || k == 20 {
                robot.extrapolated(DT)
            } else if first {
                Reference::at_rest(c)
            } else {
                robot.after(&c, DT)
            };
            first = false;
        }
        let n = tracker.counts();
        assert_eq!(
            (n.dropped, n.extrapolated, n.unconfirmed),
            (2, 3, 0),
            "{n:?}"
        );
    }

    #[test]
    fn a_robot_without_a_reference_leaves_the_commands_as_sent() {
        let mut tracker = ReferenceTracker::new([0.0; JOINTS], false);
        let mut ours = Reference::at_rest([0.0; JOINTS]);
        for k in 0u64..10 {
            // The state's derivatives say nothing (zeros), its position is the last
            // command: the command stands, unconfirmed.
            let mut s = state(k, &ours);
            s.dq_d = [0.0; JOINTS];
            s.ddq_d = [0.0; JOINTS];
            let r = tracker.reference(&s);
            assert_eq!(r, ours);
            let c = command(k as f64 * DT);
            tracker.sent(k, c, false);
            ours = if k == 0 {
                Reference::at_rest(c)
            } else {
                ours.after(&c, DT)
            };
        }
        assert!(tracker.counts().unconfirmed >= 8, "{:?}", tracker.counts());
    }
}
