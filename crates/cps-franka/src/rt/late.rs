//! Commands a simulator that applies late commands accepts as well as the robot does.
//!
//! A real Franka drops a command that misses its cycle; franka-sim applies it, rewinding
//! the extrapolation it had made of the run of cycles the command ends and differencing
//! the command over that whole run (see [`crate::reference`]). Where that run holds a cycle
//! cps did not answer (a state it skipped behind a loaded machine, an answer withheld),
//! the command's velocity is the run's average, which lags the stream's by half the run
//! times its acceleration; the next command, differenced over one cycle, then carries that
//! lag as a jump of acceleration (half the run plus one, times the stream's acceleration)
//! and of jerk. franka-sim's receive thread, stalled on a loaded machine, may take such a
//! command several cycles late, after a state that showed the run extrapolated — which,
//! at constant acceleration, is the state the command applied would show too: nothing
//! tells cps in time which reference franka-sim will judge the next command against.
//! (Measured on S-curves at 48 % of the acceleration limit: a command answered after a
//! skipped state and one after three more, both taken 5 ms late: the next judged at
//! −11.9 rad/s² against 10; a command in its cycle after a skipped state, the next late
//! after two more: the one after judged at 5 692 rad/s³ against 5 000. Reflexes both.)
//!
//! So each command is judged against every reference franka-sim may hold
//! ([`LateHistory`]): the robot's (what the states show,
//! [`crate::reference::ReferenceTracker`]), and, for each command after a run of cycles
//! cps did not answer whose fate no state has shown yet, the history in which it came in
//! its cycle (differenced over one cycle from franka-sim's extrapolation of the run) and
//! the one in which it came late (differenced over the run from the command before) —
//! but none in which franka-sim would have refused a command already, which would have
//! stopped the motion. A state that shows the last command taken in its cycle (told apart
//! from its drop) leaves one history; two commands after the last run they merge anyway.
//! Where the robot's command would break a limit against one of them, it is moved, joint
//! by joint, to the nearest position every one accepts ([`guard`]); where none is, nothing
//! is sent for that cycle (once in a row), and the robot extrapolates the reference it
//! holds, which each accepts. Only on a robot whose states show the reference it holds
//! (franka-sim, a Franka; not franky-sim, which applies every command as it comes and
//! filters what it reports): on a Franka, which drops a late command, the histories are
//! phantoms, and a command moved for them keeps every limit of the robot's own. Nothing
//! here allocates.

use crate::limits::{DT, RateLimits, StreamCheck};
use crate::reference::Reference;
use crate::wire::JOINTS;
use cps_kinematics::StreamBounds;

/// The share of each limit a moved command is placed within (the checks then judge it
/// exactly against every reference).
const MARGIN: f64 = 0.98;

/// How many of franka-sim's possible histories are kept (two for each command after a run
/// of unanswered cycles whose fate no state has shown yet; they merge two commands later).
const STORIES: usize = 8;

/// A history franka-sim may hold: the reference right after the last command it recorded,
/// and the state that command answered.
type Story = (Reference, u64);

/// The histories franka-sim may hold, given the commands cps sent since the last one a
/// state showed taken in its cycle: each command after a run of cycles cps did not answer
/// either came in its cycle (differenced over one cycle from franka-sim's extrapolation of
/// the run) or late (differenced over the whole run from the command before it).
#[derive(Debug, Clone, Copy)]
pub(crate) struct LateHistory {
    limits: RateLimits,
    stories: [Option<Story>; STORIES],
    /// The last command's state (None before the motion's first).
    last: Option<u64>,
    /// Both as they were before the last command (it may be withdrawn).
    undo: ([Option<Story>; STORIES], Option<u64>),
}

/// Whether two references judge every command alike (to rounding).
fn same(x: &Reference, y: &Reference) -> bool {
    let close = |a: &[f64; JOINTS], b: &[f64; JOINTS], tol: f64| {
        a.iter().zip(b).all(|(p, q)| (p - q).abs() <= tol)
    };
    close(&x.q, &y.q, 1e-12) && close(&x.v, &y.v, 1e-9) && close(&x.a, &y.a, 1e-6)
}

/// Puts `story` among `stories` (all after the same command) unless one alike is there or
/// they are full.
fn keep(stories: &mut [Option<Story>; STORIES], story: Story) {
    if stories.iter().flatten().any(|s| same(&s.0, &story.0)) {
        return;
    }
    if let Some(free) = stories.iter_mut().find(|s| s.is_none()) {
        *free = Some(story);
    }
}

impl LateHistory {
    /// A motion held to `limits` (as franka-sim judges it).
    pub(crate) fn new(limits: RateLimits) -> Self {
        LateHistory {
            limits,
            stories: [None; STORIES],
            last: None,
            undo: ([None; STORIES], None),
        }
    }

    /// Notes the command `q` sent in answer to state `id`.
    pub(crate) fn sent(&mut self, id: u64, q: [f64; JOINTS]) {
        self.undo = (self.stories, self.last);
        let mut next = [None; STORIES];
        if self.last.is_none() {
            // The motion's first command is its standstill.
            keep(&mut next, (Reference::at_rest(q), id));
        }
        // A history in which franka-sim would have refused the command is none it holds:
        // it would have stopped the motion there.
        let taken = |from: &Reference, periods: u64| {
            let mut c = StreamCheck::at_rest(self.limits, from.q, periods as f64 * DT);
            c.rebase(&from.q, &from.v, &from.a);
            c.admit(&q).is_ok()
        };
        for (r, at) in self.stories.into_iter().flatten() {
            let run = id.saturating_sub(at + 1);
            let extrapolated = r.extrapolated_by(run, DT);
            if taken(&extrapolated, 1) {
                keep(&mut next, (extrapolated.after(&q, DT), id));
            }
            if run > 0 && taken(&r, run + 1) {
                keep(&mut next, (r.after_over(&q, run + 1, DT), id));
            }
        }
        self.stories = next;
        self.last = Some(id);
    }

    /// The robot showed the command answering state `id` taken in its cycle, `r` the
    /// reference right after it: that one history is franka-sim's.
    pub(crate) fn anchor(&mut self, id: u64, r: Reference) {
        if self.last == Some(id) {
            self.stories = [None; STORIES];
            self.stories[0] = Some((r, id));
        }
    }

    /// Takes back the last command noted: it was not sent after all.
    pub(crate) fn withdraw(&mut self) {
        (self.stories, self.last) = self.undo;
    }

    /// The references a command answering state `id` may be judged against over one cycle,
    /// besides `r` (the robot's): each history extrapolated over the cycles since its last
    /// command. (A command late after a run of unanswered cycles is differenced over the
    /// run, which only averages: the robot's rules judge it.)
    fn others(&self, id: u64, r: &Reference) -> [Option<Reference>; STORIES] {
        let mut out = [None; STORIES];
        for (slot, (h, at)) in out.iter_mut().zip(self.stories.iter().flatten()) {
            let h = h.extrapolated_by(id.saturating_sub(at + 1), DT);
            if !same(&h, r) {
                *slot = Some(h);
            }
        }
        out
    }
}

/// What [`guard`] did with a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Guarded {
    /// Every reference accepts it as it is (or there is only the robot's).
    Kept,
    /// Moved to where every reference accepts it.
    Moved,
    /// No command every reference accepts: the robot's was kept.
    Unmet,
}

/// The command to send in answer to state `id`: `q`, which `check` admitted against the
/// robot's reference `r` (`before`: the check as it was, rebased on `r`, before it did),
/// unless franka-sim, in one of the histories it may hold ([`LateHistory`]), would refuse
/// it; then the nearest command every one accepts, `check` moved on to it.
pub(crate) fn guard(
    late: &LateHistory,
    id: u64,
    before: &StreamCheck,
    check: &mut StreamCheck,
    r: &Reference,
    q: [f64; JOINTS],
) -> ([f64; JOINTS], Guarded) {
    let others = late.others(id, r);
    let accepts = |h: &Reference, x: &[f64; JOINTS]| {
        let mut theirs = *before;
        theirs.rebase(&h.q, &h.v, &h.a);
        theirs.admit(x).is_ok()
    };
    if others.iter().flatten().all(|h| accepts(h, &q)) {
        return (q, Guarded::Kept);
    }
    let bounds = before.bounds();
    let mut moved = q;
    for (i, x) in moved.iter_mut().enumerate() {
        let (mut lo, mut hi) = window(bounds, r, i);
        for h in others.iter().flatten() {
            let (l, u) = window(bounds, h, i);
            (lo, hi) = (lo.max(l), hi.min(u));
        }
        if lo > hi {
            return (q, Guarded::Unmet);
        }
        *x = x.clamp(lo, hi);
    }
    let mut ours = *before;
    if ours.admit(&moved).is_ok() && others.iter().flatten().all(|h| accepts(h, &moved)) {
        *check = ours;
        (moved, Guarded::Moved)
    } else {
        (q, Guarded::Unmet)
    }
}

/// The positions of joint `i` a command may take one cycle after the reference `r` within
/// [`MARGIN`] of its velocity, acceleration and jerk limits, and within its range.
fn window<B: StreamBounds>(bounds: &B, r: &Reference, i: usize) -> (f64, f64) {
    let (q, v, a) = (r.q[i], r.v[i], r.a[i]);
    let mut lo = f64::NEG_INFINITY;
    let mut hi = f64::INFINITY;
    let mut within = |l: f64, h: f64| {
        lo = lo.max(l);
        hi = hi.min(h);
    };
    if let Some((l, h)) = bounds.range(i) {
        within(l, h);
    }
    if let Some((l, h)) = bounds.velocity(i, q) {
        within(q + MARGIN * l * DT, q + MARGIN * h * DT);
    }
    if let Some(m) = bounds.acceleration(i) {
        let c = q + v * DT;
        within(c - MARGIN * m * DT * DT, c + MARGIN * m * DT * DT);
    }
    if let Some(m) = bounds.jerk(i) {
        let c = q + v * DT + a * DT * DT;
        within(c - MARGIN * m * DT.powi(3), c + MARGIN * m * DT.powi(3));
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::{Arm, RateLimits, stream_check};

    /// A stream from rest at constant acceleration on joint 1 (`a` rad/s²).
    fn stream(a: f64) -> impl Fn(u64) -> [f64; JOINTS] {
        move |k| {
            let t = k as f64 * DT;
            let mut q = [0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.8];
            q[0] = 0.5 * a * t * t;
            q
        }
    }

    /// franka-sim's history after the commands `answered` (each the stream's at its state),
    /// those in `late` taken late: a late one is differenced over the run since the command
    /// before it, one in its cycle over one cycle from the run's extrapolation. None where
    /// franka-sim would have refused one of them (and stopped the motion).
    fn franka_sim(
        stream: &dyn Fn(u64) -> [f64; JOINTS],
        answered: &[u64],
        late: &[u64],
    ) -> Option<Story> {
        let limits = RateLimits::of(Arm::Fr3);
        let mut r = Reference::at_rest(stream(answered[0]));
        let mut at = answered[0];
        for &k in &answered[1..] {
            let run = k - at - 1;
            let (from, periods) = if late.contains(&k) {
                (r, run + 1)
            } else {
                (r.extrapolated_by(run, DT), 1)
            };
            let mut c = StreamCheck::at_rest(limits, from.q, periods as f64 * DT);
            c.rebase(&from.q, &from.v, &from.a);
            c.admit(&stream(k)).ok()?;
            r = from.after_over(&stream(k), periods, DT);
            at = k;
        }
        Some((r, at))
    }

    /// The cases measured on franka-sim (the failures this module answers, their numbers):
    /// joint 1 at ±4.75 rad/s², cps answering after runs of unanswered cycles, franka-sim
    /// taking some of those answers late. The stream's next command is accepted by the
    /// robot's reference but refused by one of franka-sim's histories; the guard sends one
    /// every history accepts, a few µrad from it.
    #[test]
    fn a_command_every_history_accepts_is_sent_where_the_stream_s_would_trip_franka_sim() {
        let limits = RateLimits::of(Arm::Fr3);
        // (acceleration, the states answered after 0..=25, the next state, the late ones)
        let cases: [(f64, &[u64], u64, &[u64]); 2] = [
            // 26 skipped, 27 answered; 28–30 skipped or withheld; 31 answered; both late:
            // the next judged at −11.9 rad/s² (the velocity discontinuity).
            (-4.75, &[27, 31], 32, &[27, 31]),
            // 26 skipped, 27 in its cycle; 28–29 skipped; 30 late: the next judged at
            // 5 692 rad/s³ (the acceleration discontinuity).
            (4.75, &[27, 30], 31, &[30]),
        ];
        for (a, answered, next, late_ones) in cases {
            let stream = stream(a);
            let all: Vec<u64> = (0..=25).chain(answered.iter().copied()).collect();
            let mut late = LateHistory::new(limits);
            for &k in &all {
                late.sent(k, stream(k));
            }
            // The robot's reference: every command in its cycle, the runs extrapolated.
            let (robot, at) = franka_sim(&stream, &all, &[]).unwrap();
            let robot = robot.extrapolated_by(next - at - 1, DT);
            let (theirs, at) = franka_sim(&stream, &all, late_ones).unwrap();
            let theirs = theirs.extrapolated_by(next - at - 1, DT);
            let mut check = stream_check(limits, stream(0));
            check.rebase(&robot.q, &robot.v, &robot.a);
            let before = check;
            let q = stream(next);
            assert!(
                check.admit(&q).is_ok(),
                "{a}: the robot takes the stream's command"
            );
            let admits = |h: &Reference, x: &[f64; JOINTS]| {
                let mut c = before;
                c.rebase(&h.q, &h.v, &h.a);
                c.admit(x).is_ok()
            };
            assert!(!admits(&theirs, &q), "{a}: franka-sim refuses it");
            let (sent, how) = guard(&late, next, &before, &mut check, &robot, q);
            assert_eq!(how, Guarded::Moved, "{a}");
            // Every history franka-sim may hold accepts it (every choice of late ones).
            for mask in 0..4u32 {
                let chosen: Vec<u64> = answered
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| mask & (1 << i) != 0)
                    .map(|(_, k)| *k)
                    .collect();
                // (One in which franka-sim refused a command before stopped the motion.)
                if let Some((h, at)) = franka_sim(&stream, &all, &chosen) {
                    let h = h.extrapolated_by(next - at - 1, DT);
                    assert!(admits(&h, &sent), "{a}: late {chosen:?}");
                }
            }
            assert!(admits(&robot, &sent));
            // Only joint 1 moves, by a few µrad; the check moved on to what was sent.
            assert!(
                (sent[0] - q[0]).abs() < 1e-5 && sent[0] != q[0],
                "{}",
                sent[0] - q[0]
            );
            assert_eq!(sent[1..], q[1..]);
            assert_eq!(check.last().0, &sent);
            // A state that showed the last command taken in its cycle leaves the robot's.
            let mut shown = late;
            shown.anchor(
                *answered.last().unwrap(),
                franka_sim(&stream, &all, &[]).unwrap().0,
            );
            let mut copy = before;
            assert_eq!(
                guard(&shown, next, &before, &mut copy, &robot, q),
                (q, Guarded::Kept)
            );
        }
    }

    #[test]
    fn a_withdrawn_command_is_taken_back() {
        let mut late = LateHistory::new(RateLimits::of(Arm::Fr3));
        let at = |x: f64| [x, x, x, -1.5 + x, x, 1.5 + x, 0.8 + x];
        late.sent(1, at(0.0));
        late.sent(3, at(1e-7));
        let kept = (late.stories, late.last);
        late.sent(6, at(3e-7));
        assert_eq!(late.stories.iter().flatten().count(), 4);
        late.withdraw();
        assert_eq!((late.stories, late.last), kept);
    }
}
