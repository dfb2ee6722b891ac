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
//! to; the last three commands alone, where they answered three consecutive cycles, make a
//! candidate whatever came before them. A state that agrees with none wholly is matched by
//! its derivatives alone (franka-sim may publish one between putting back its position
//! after a late command and applying it), else by its position alone, else taken as it is,
//! to single precision, on a robot whose states agreed before with a clearly accelerating
//! reference (a stalled simulator may take only the newest of the commands waiting for it
//! and apply that one over the whole run since the last it applied: franka-sim). A robot
//! whose state carries no usable reference (franky-sim low-pass filters its `dq_d`, which
//! agrees only where the motion cruises) leaves the commands as sent. Both are counted as
//! unconfirmed.
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
    /// The velocity and acceleration only.
    Derivatives,
    /// Neither.
    None,
}

/// Whether a reference accelerates far above the floors of [`rounds_to`] (a joint at
/// 0.05 rad/s² or more): a state that agrees with it wholly shows the reference the robot
/// holds. A filtered velocity (franky-sim low-pass filters `dq_d`) converges to a constant
/// one, so a state that agrees with a reference cruising or at rest says nothing; under an
/// acceleration it lags.
fn accelerating_clearly(r: &Reference) -> bool {
    r.a.iter().any(|a| a.abs() >= 0.05)
}

fn agreement(r: &Reference, s: &RobotState, velocity_motion: bool) -> Agreement {
    let position = (0..JOINTS).all(|i| rounds_to(r.q[i], s.q_d[i], 1e-9));
    let derivatives = (0..JOINTS)
        .all(|i| rounds_to(r.v[i], s.dq_d[i], 1e-6) && rounds_to(r.a[i], s.ddq_d[i], 1e-3));
    match (position || velocity_motion, derivatives) {
        (true, true) => Agreement::Whole,
        (true, false) if !velocity_motion => Agreement::Position,
        (false, true) => Agreement::Derivatives,
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
    /// States whose reported reference agreed wholly with none of the candidates (see the
    /// module's text for what is taken then).
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
    /// The references right after the last three commands the robot applied, and their
    /// cycles, newest last (None before the first).
    reals: Ring,
    /// A velocity motion: its `q_d` is the robot's integral, so only `dq_d` and `ddq_d`
    /// are compared.
    velocity_motion: bool,
    /// Whether a state of this motion agreed wholly with a clearly accelerating candidate:
    /// the robot reports a usable reference, to be taken where no candidate explains a
    /// state.
    usable: bool,
    /// The last three commands sent and the cycles they answered, newest last: applied on
    /// time in three consecutive cycles, they are the robot's reference by themselves,
    /// whatever came before (how the tracker finds the exact reference again after taking
    /// a state's own).
    recent: [Option<(u64, [f64; JOINTS])>; 3],
    /// The last command, if the last state showed it applied (and told that apart from its
    /// drop): the cycle it answered and the reference right after it.
    confirmed: Option<(u64, Reference)>,
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
            reals: [None; 3],
            velocity_motion,
            usable: false,
            recent: [None; 3],
            confirmed: None,
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

    /// Whether this robot's states carry the reference it holds (a state of this motion
    /// agreed wholly with a clearly accelerating one): a Franka's or franka-sim's, not
    /// franky-sim's, whose `dq_d` is filtered.
    pub fn reports_reference(&self) -> bool {
        self.usable
    }

    /// The last command sent, if the last state showed it taken in its cycle (and that
    /// apart from its drop, which at constant acceleration looks the same): the state it
    /// answered, and the reference right after it.
    pub fn confirmed(&self) -> Option<(u64, Reference)> {
        self.confirmed
    }

    /// Cycles after the base's and before `id` that went without a command.
    fn unanswered_before(&self, id: u64) -> u64 {
        self.base_id.map_or(0, |b| id.saturating_sub(b + 1))
    }

    /// The reference the robot holds when it judges the answer to `state`: the last
    /// command it applied (or the motion's start), extrapolated over every cycle since
    /// that went without one.
    // Long on purpose (over 150 lines): the candidates are tried in the one order the
    // robots' behaviour fixes (see the module's text), each step reading and setting the
    // whole tracker; split, that order would be spread over functions sharing all of it.
    pub fn reference(&mut self, state: &RobotState) -> Reference {
        let agrees = |r: &Reference| agreement(r, state, self.velocity_motion);
        let since = |id: u64| state.message_id.saturating_sub(id + 1);
        self.confirmed = None;
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
                self.reals = [self.reals[1], self.reals[2], Some((alt, id))];
                if self.after_drop {
                    self.counts.dropped -= 1;
                    self.counts.extrapolated -= 1;
                }
                self.counts.applied_late += 1;
            }
            self.alternatives = [None; 2];
            if self.usable && agrees(&self.base) == Agreement::None && !self.torn(state) {
                // Explained by nothing cps sent: the robot's own reference.
                self.counts.unconfirmed += 1;
                self.base = reported(state, self.velocity_motion, self.base.q);
                self.reals = [
                    self.reals[1],
                    self.reals[2],
                    Some((self.base, state.message_id - 1)),
                ];
            }
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
        let push = |ring: Ring, r: Reference, id: u64| [ring[1], ring[2], Some((r, id))];
        // The robot's stories of this command, each as it stands right after it: applied
        // on time, or dropped; a simulator's that applies late commands (franka-sim): the
        // run of cycles it extrapolated since the last command it applied taken back, and
        // this one differenced over the whole run; or every command applied as sent; or the
        // last three commands alone.
        let applied = after(&self.base.extrapolated_by(before, DT), 1);
        let over_run = match self.reals[2] {
            Some((real, id)) => after(&real, sent_id.saturating_sub(id).max(1)),
            None => applied,
        };
        let as_sent = after(&self.as_sent.extrapolated_by(before, DT), 1);
        let dropped = self.base.extrapolated_by(before + 1, DT);
        let own = self.own().unwrap_or(applied);
        let story = |r, kind, reals, alternatives| {
            Some(Story {
                r,
                kind,
                reals,
                alternatives,
            })
        };
        let late = [Some((applied, sent_id)), Some((over_run, sent_id))];
        let mut stories: [Option<Story>; 11] = [None; 11];
        // Applied, one way or another: this command is the newest real reference.
        let taken = |r, kind| story(r, kind, push(self.reals, r, sent_id), [None; 2]);
        stories[..5].copy_from_slice(&[
            taken(applied, Kind::Applied),
            taken(over_run, Kind::AppliedLate),
            taken(as_sent, Kind::AppliedLate),
            taken(own, Kind::Applied),
            story(dropped, Kind::Dropped, self.reals, late),
        ]);
        // A stalled simulator takes only the newest of the commands waiting for it: the
        // ones before it never reached it, and the robot's last real reference is an older
        // one. This command applied over the run from there; or the last command applied so
        // (late, over the run from an older one), and this one after it, or dropped.
        if let (false, Some((newest, newest_id))) = (self.first, self.reals[2]) {
            for k in 0..2 {
                let Some((older, older_id)) = self.reals[k] else {
                    continue;
                };
                let kept: Ring =
                    std::array::from_fn(|i| (i <= k).then_some(self.reals[i]).flatten());
                let r = older.after_over(&q_c, sent_id.saturating_sub(older_id).max(1), DT);
                stories[5 + 3 * k] = story(r, Kind::AppliedLate, push(kept, r, sent_id), [None; 2]);
                let rerun =
                    older.after_over(&newest.q, newest_id.saturating_sub(older_id).max(1), DT);
                let kept = push(kept, rerun, newest_id);
                let r = rerun
                    .extrapolated_by(sent_id - 1 - newest_id, DT)
                    .after(&q_c, DT);
                stories[6 + 3 * k] = story(r, Kind::Applied, push(kept, r, sent_id), [None; 2]);
                let r = rerun.extrapolated_by(sent_id.saturating_sub(newest_id), DT);
                let alternatives = [Some((stories[6 + 3 * k].unwrap().r, sent_id)), None];
                stories[7 + 3 * k] = story(r, Kind::Dropped, kept, alternatives);
            }
        }
        let now = |r: &Reference| r.extrapolated_by(gap, DT);
        let told = |part: Agreement| {
            let mut matching = stories
                .iter()
                .flatten()
                .filter(|s| agrees(&now(&s.r)) == part);
            let first = *matching.next()?;
            // Only where the stories that agree are one reference.
            matching.all(|s| s.r == first.r).then_some(first)
        };
        let chosen = match stories
            .iter()
            .flatten()
            .find(|s| agrees(&now(&s.r)) == Agreement::Whole)
        {
            Some(&s) => {
                self.usable |= accelerating_clearly(&s.r);
                // Applied, and told apart from its drop: the robot took it in its cycle.
                let taken = matches!(s.kind, Kind::Applied | Kind::AppliedLate);
                if taken && agrees(&now(&dropped)) != Agreement::Whole {
                    self.confirmed = Some((sent_id, s.r));
                }
                s
            }
            None => {
                self.counts.unconfirmed += 1;
                // On a robot whose states agreed before, the derivatives alone (a
                // simulator may publish a state between putting back its position after a
                // late command and applying that command: franka-sim); else the position
                // alone, where either tells one story from the others; else, on such a
                // robot, the state's own reference; else the command as applied.
                let reported = reported(state, self.velocity_motion, now(&applied).q);
                self.usable
                    .then(|| told(Agreement::Derivatives))
                    .flatten()
                    .or_else(|| told(Agreement::Position))
                    .or_else(|| {
                        (self.usable && !self.torn(state)).then(|| Story {
                            r: reported,
                            kind: Kind::Reported,
                            reals: push(self.reals, reported, state.message_id - 1),
                            alternatives: [None; 2],
                        })
                    })
                    .unwrap_or(stories[0].unwrap())
            }
        };
        self.counts.extrapolated += before + gap;
        match chosen.kind {
            Kind::Applied | Kind::Reported => {}
            Kind::AppliedLate => self.counts.applied_late += 1,
            Kind::Dropped => {
                self.counts.dropped += 1;
                self.counts.extrapolated += 1;
            }
        }
        self.reals = chosen.reals;
        // A command that may still be applied late (shown dropped, or ending a run of
        // unanswered cycles): unresolved until the next state, where they differ at all.
        self.alternatives = if chosen.kind == Kind::Dropped {
            chosen.alternatives
        } else if behind && chosen.kind == Kind::Applied && over_run != applied {
            late
        } else {
            [None; 2]
        };
        self.alternatives = self.alternatives.map(|a| a.filter(|(r, _)| *r != chosen.r));
        self.after_drop = chosen.kind == Kind::Dropped;
        self.base = if chosen.kind == Kind::Reported {
            chosen.r
        } else {
            now(&chosen.r)
        };
        self.base_id = Some(state.message_id - 1);
        self.as_sent = now(&as_sent);
        self.first = self.first && chosen.kind == Kind::Dropped;
        self.base
    }

    /// Whether `state` shows the position of an earlier command although the robot's
    /// reference moves and cycles have passed since: franka-sim publishes such a state
    /// between putting its position back for a late command and applying that command.
    fn torn(&self, state: &RobotState) -> bool {
        if self.velocity_motion {
            // Its `q_d` is the robot's integral: nothing to compare.
            return false;
        }
        let earlier = |id: u64, q: &[f64; JOINTS]| {
            state.message_id > id + 1 && (0..JOINTS).all(|i| rounds_to(q[i], state.q_d[i], 1e-9))
        };
        state.dq_d.iter().any(|v| v.abs() > 1e-6)
            && (self
                .reals
                .iter()
                .flatten()
                .any(|(r, id)| earlier(*id, &r.q))
                || self.recent.iter().flatten().any(|(id, q)| earlier(*id, q)))
    }

    /// The reference the last three commands sent make by themselves, if they answered
    /// three consecutive cycles (the last one pending).
    fn own(&self) -> Option<Reference> {
        let [Some((i0, c0)), Some((i1, c1)), Some((i2, c2))] = self.recent else {
            return None;
        };
        (i1 == i0 + 1 && i2 == i1 + 1).then(|| Reference::at_rest(c0).after(&c1, DT).after(&c2, DT))
    }

    /// Notes the command sent in answer to the state `message_id` (after
    /// [`ReferenceTracker::reference`] for that state); `behind`: cps skipped stale states
    /// to answer it, so the answer may come late.
    pub fn sent(&mut self, message_id: u64, q_c: [f64; JOINTS], behind: bool) {
        self.pending = Some((message_id, q_c, behind));
        self.recent = [self.recent[1], self.recent[2], Some((message_id, q_c))];
        if self.base_id.is_none() {
            // The motion's first command: the robot held its start until then.
            self.base_id = Some(message_id.saturating_sub(1));
        }
    }

    /// Takes back the last command noted: it was not sent after all.
    pub fn withdraw(&mut self) {
        self.pending = None;
        self.recent = [None, self.recent[0], self.recent[1]];
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
    /// None of them: the state's own reference.
    Reported,
}

/// References with their cycles, newest last.
type Ring = [Option<(Reference, u64)>; 3];

/// One account of what became of a command: the robot's reference right after its cycle,
/// the references after the commands the robot applied, and where it shows the command
/// dropped, the references had it been applied late after all.
#[derive(Debug, Clone, Copy)]
struct Story {
    r: Reference,
    kind: Kind,
    reals: Ring,
    alternatives: [Option<(Reference, u64)>; 2],
}

/// The reference a state reports (`q_d`, `dq_d`, `ddq_d`, to single precision); in a
/// velocity motion, whose `q_d` is the robot's own integral, with the position `q` cps
/// integrates to.
fn reported(state: &RobotState, velocity_motion: bool, q: [f64; JOINTS]) -> Reference {
    Reference {
        q: if velocity_motion { q } else { state.q_d },
        v: state.dq_d,
        a: state.ddq_d,
    }
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

    /// The robot's reference after it applied `c` in cycle `k` (the motion's first command
    /// is its standstill).
    fn applied(r: &Reference, k: u64, c: &[f64; JOINTS]) -> Reference {
        if k == 0 {
            Reference::at_rest(*c)
        } else {
            r.after(c, DT)
        }
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
    fn a_command_is_confirmed_where_its_state_tells_it_from_its_drop() {
        // Under jerk (the cubic) the state after a command shows it applied, not
        // extrapolated: confirmed, with the reference right after it. At constant
        // acceleration the two are the same reference: a command franka-sim has not taken
        // yet looks the same, and none is confirmed.
        let quadratic =
            |t: f64| -> [f64; JOINTS] { std::array::from_fn(|i| 0.1 * i as f64 + t * t) };
        for (jerk, make) in [
            (true, command as fn(f64) -> [f64; JOINTS]),
            (false, quadratic),
        ] {
            let q0 = make(0.0);
            let mut tracker = ReferenceTracker::new(q0, false);
            let mut robot = Reference::at_rest(q0);
            for k in 0u64..20 {
                let ours = tracker.reference(&state(k, &robot));
                assert_eq!(ours, robot);
                // (From rest, the quadratic's acceleration is constant from its third
                // command on.)
                if k >= 5 {
                    let expected = jerk.then_some((k - 1, robot));
                    assert_eq!(tracker.confirmed(), expected, "cycle {k}, jerk {jerk}");
                }
                let c = make(k as f64 * DT);
                tracker.sent(k, c, false);
                robot = applied(&robot, k, &c);
            }
        }
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
            ours = applied(&ours, k, &c);
        }
        assert!(tracker.counts().unconfirmed >= 8, "{:?}", tracker.counts());
    }

    #[test]
    fn a_filtered_velocity_that_once_agreed_at_cruise_is_never_taken() {
        // franky-sim's `dq_d`: the commands' velocity through a first-order low-pass
        // filter (τ = 0.1 s), `ddq_d` its difference. Cruising long enough, it converges
        // onto the commands' velocity and a state agrees wholly; accelerating after, it
        // lags, and the commands as sent stay the reference.
        let mut tracker = ReferenceTracker::new([0.0; JOINTS], false);
        let mut ours = Reference::at_rest([0.0; JOINTS]);
        let mut filtered = [0.0; JOINTS];
        let mut a_filtered = [0.0; JOINTS];
        let mut q = [0.0; JOINTS];
        let mut v = 0.3;
        for k in 0u64..2600 {
            let mut s = state(k, &ours);
            s.dq_d = filtered.map(|x| f64::from(x as f32));
            s.ddq_d = a_filtered.map(|x| f64::from(x as f32));
            let r = tracker.reference(&s);
            let close = (0..JOINTS).all(|i| {
                (r.q[i] - ours.q[i]).abs() < 1e-12
                    && (r.v[i] - ours.v[i]).abs() < 1e-6
                    && (r.a[i] - ours.a[i]).abs() < 1e-3
            });
            assert!(close, "cycle {k}: {r:?} against {ours:?}");
            if k >= 2000 {
                v += 2.0 * DT;
            }
            let c = q.map(|x| x + v * DT);
            tracker.sent(k, c, false);
            ours = applied(&ours, k, &c);
            q = c;
            for i in 0..JOINTS {
                let before = filtered[i];
                filtered[i] += 0.01 * (ours.v[i] - filtered[i]);
                a_filtered[i] = (filtered[i] - before) / DT;
            }
        }
        assert!(
            tracker.counts().unconfirmed >= 500,
            "{:?}",
            tracker.counts()
        );
    }

    /// franka-sim's packet handling, as its limit checker keeps the reference: a command
    /// that comes in its cycle is differenced against the reference; a cycle without one
    /// is extrapolated (the first of a run keeps the reference before it); a command that
    /// comes after its cycle was extrapolated takes the run back and is differenced over
    /// it from there; its receive thread, stalled, takes only the newest of the commands
    /// waiting; and a state published while it puts the position back shows the old
    /// position with the new derivatives.
    struct FrankaSim {
        r: Reference,
        first: bool,
        /// The reference before the run of extrapolated cycles, and its cycle.
        before_run: Option<(Reference, u64)>,
        last_real: u64,
    }

    impl FrankaSim {
        fn new(q0: [f64; JOINTS]) -> Self {
            FrankaSim {
                r: Reference::at_rest(q0),
                first: true,
                before_run: None,
                last_real: 0,
            }
        }
        fn in_time(&mut self, k: u64, q: [f64; JOINTS]) {
            self.r = if self.first {
                Reference::at_rest(q)
            } else {
                self.r.after(&q, DT)
            };
            self.first = false;
            self.before_run = None;
            self.last_real = k;
        }
        fn lost(&mut self) {
            if self.before_run.is_none() {
                self.before_run = Some((self.r, self.last_real));
            }
            self.r = self.r.extrapolated(DT);
        }
        fn late(&mut self, k: u64, q: [f64; JOINTS]) {
            let (r, id) = self.before_run.take().unwrap();
            self.r = r.after_over(&q, k - id, DT);
            self.last_real = k;
        }
    }

    #[test]
    fn franka_sim_s_late_and_lost_commands_are_followed_exactly() {
        // At constant acceleration a dropped command and an applied one leave the same
        // reference, so a state cannot tell them apart: the hard case.
        let command = |k: u64| -> [f64; JOINTS] {
            let t = k as f64 * DT;
            std::array::from_fn(|i| 0.1 * i as f64 + 0.3 * t + 2.0 * t * t)
        };
        let q0 = command(0);
        let mut tracker = ReferenceTracker::new(q0, false);
        let mut sim = FrankaSim::new(q0);
        // The state each cycle publishes, and what the sim still does after publishing it.
        let mut published = state(0, &sim.r);
        let mut after_publish: Option<(u64, [f64; JOINTS])> = None;
        let mut torn_next = false;
        for k in 0u64..60 {
            let s = published;
            let ours = tracker.reference(&s);
            // Every state that shows the sim's reference as it is is followed (to rounding:
            // the stories a state cannot tell apart differ in their last bits).
            let close = |a: &[f64; JOINTS], b: &[f64; JOINTS], tol: f64| {
                (0..JOINTS).all(|i| (a[i] - b[i]).abs() <= tol)
            };
            if !torn_next {
                assert!(
                    close(&ours.q, &sim.r.q, 1e-12)
                        && close(&ours.v, &sim.r.v, 1e-9)
                        && close(&ours.a, &sim.r.a, 1e-6),
                    "cycle {k}: {ours:?} against {:?}",
                    sim.r
                );
            }
            torn_next = false;
            // The late command arrives after the state went out; the command cps sends
            // now meets that (cps cannot know it yet: the next state shows it).
            if let Some((late, q)) = after_publish.take() {
                sim.late(late, q);
            }
            let unresolved = tracker.unresolved();
            let c = command(k);
            // Cycle 30: cps is behind and skips the state (it answers 31, late).
            let answered = !unresolved && k != 30;
            if answered {
                tracker.sent(k, c, k == 31);
            }
            match k {
                // Lost in the stalled receive thread's queue; the next comes late.
                10 if answered => sim.lost(),
                11 | 31 if answered => {
                    sim.lost();
                    after_publish = Some((k, c));
                }
                // Late, and the next state published as the position is put back.
                20 if answered => {
                    sim.lost();
                    let run_start = sim.before_run.unwrap().0.q;
                    sim.late(k, c);
                    published = state(
                        k + 1,
                        &Reference {
                            q: run_start,
                            ..sim.r
                        },
                    );
                    torn_next = true;
                    continue;
                }
                _ if answered => sim.in_time(k, c),
                _ => sim.lost(),
            }
            published = state(k + 1, &sim.r);
        }
        // The torn state is the one unconfirmed; the late commands are told apart where
        // their reference differs from a drop's (at constant acceleration it does not).
        let n = tracker.counts();
        assert!(n.unconfirmed == 1 && n.applied_late >= 1, "{n:?}");
    }
}
