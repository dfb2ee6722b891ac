//! What the realtime loop runs each tick: a law turns the robot's state into one command,
//! judged against the reference the robot holds ([`crate::reference`]) and limited or
//! replaced by a controlled stop where the robot would not accept it.
//!
//! - `PositionLaw`: joint positions (or velocities, as the positions they integrate to).
//!   The generator is asked once per robot period — a state that comes 2 ms after the
//!   last one answered (a cycle lost or skipped) asks it twice, so a generator stepped
//!   per period (the chunk executor, an online DMP) keeps the robot's time, and a
//!   replayed stream its index — and its last answer goes through the [`Limiter`]
//!   against the robot's reference, then [`late::guard`] (moved to where franka-sim, had
//!   it taken cps's last commands late, accepts it too). A stop, or a command that
//!   cannot be limited, switches to a [`Brake`] from that reference. The motion opens at
//!   rest where the robot stands until a state shows that the robot took a command of it
//!   in time (`control_command_success_rate` above zero): a robot takes its first command as the
//!   motion's standstill, and a simulator that applies a late first one without taking it
//!   (franka-sim) would take the next, already moving, instead. The generator's clock
//!   starts there.
//! - [`TorqueLaw`]: torques, limited to the torque and its rate from the last torques the
//!   robot applied (the state's `tau_J_d`), with a damped stop.
//!
//! Nothing here allocates, locks or logs.

use cps_kinematics::Quantity;

use super::late::{self, Guarded, LateHistory};
use super::{JointPositions, MotionEnd, Torques};
use crate::limits::{Brake, DT, RateLimits, StreamCheck, joint_breach, stream_check};
use crate::reference::{Reference, ReferenceCounts, ReferenceTracker, TorqueTracker};
use crate::wire::{Command, ControllerMode, JOINTS, MotionGeneratorMode, RobotState};
use cps_robot::{Limited, Limiter};

/// The share of a joint's speed limit above which a torque-controlled motion is braked.
pub const TORQUE_SPEED_GUARD: f64 = 0.9;

/// The share of the torque-rate limit torques are limited to (the robot's reference
/// arrives rounded to single precision).
pub const TORQUE_RATE_SHARE: f64 = 0.95;

/// The most periods a motion opens at rest waiting for the robot to show a command taken
/// (a robot that has taken none by then has stopped the motion; one still going reports no
/// success rate at all).
const OPENING_PERIODS_MAX: u64 = cps_robot::MAX_LOST_PERIODS;

/// Damping of the torque-mode stop (N m s/rad), per joint.
const STOP_DAMPING: [f64; JOINTS] = [40.0, 40.0, 40.0, 40.0, 10.0, 10.0, 5.0];

/// How a law's motion went, for the report.
#[derive(Debug, Clone)]
pub(crate) struct Outcome {
    /// Why the law stopped on its own or was stopped, if it was.
    pub reason: Option<MotionEnd>,
    /// Peak usage of velocity, acceleration and jerk (torque: torque, torque rate, speed)
    /// per joint, of every command sent.
    pub peak: [[f64; JOINTS]; 3],
    /// Ticks spent stopping.
    pub brake_ticks: usize,
    /// Commands limited before they were sent.
    pub limited: Limited,
    /// What the states said of the commands sent.
    pub reference: ReferenceCounts,
    /// The robot time the generator's clock started at (None: it never did).
    pub clock_start: Option<f64>,
}

/// What the loop runs: one command per state, and a controlled stop when asked.
pub(crate) trait Law {
    /// The Move's controller and motion generator.
    fn modes(&self) -> (ControllerMode, MotionGeneratorMode);
    /// The robot's state before the Move: where the motion starts.
    fn start(&mut self, state: &RobotState);
    /// Whether the law still follows its generator (not holding, not stopping).
    fn following(&self) -> bool;
    /// Fills `command` for `state` at robot time `t`, `periods` robot periods after the
    /// state answered before (1 for the first; `behind`: states came meanwhile that cps
    /// skipped as stale, so its answer may come late); `tick` counts the states answered;
    /// `brake` asks for a controlled stop for that reason. Whether the command is the
    /// last; None when nothing is to be sent for this state (see
    /// [`ReferenceTracker::unresolved`]).
    fn answer(
        &mut self,
        state: &RobotState,
        t: f64,
        periods: (u64, bool),
        tick: usize,
        brake: Option<MotionEnd>,
        command: &mut Command,
    ) -> Option<bool>;
    /// Takes back the command of the last [`Law::answer`]: it was not sent (a newer state
    /// had come, so it would have reached the robot late).
    fn withdraw(&mut self);
    /// How the motion went.
    fn outcome(self) -> Outcome;
}

// The modes live in place: boxing would allocate inside the loop.
#[derive(Debug, Clone, Copy)]
enum Mode {
    Follow,
    /// The generator finished: its last command is held until the robot's reference is at
    /// rest there (as the check of a whole stream assumes).
    Hold([f64; JOINTS]),
    /// A controlled stop from the robot's reference.
    Brake,
}

/// Joint positions (or velocities, as the positions they integrate to), judged against the
/// robot's reference, limited where a lost cycle made them unacceptable, with a [`Brake`]
/// for anything else.
pub(crate) struct PositionLaw<F> {
    check: StreamCheck,
    tracker: ReferenceTracker,
    /// The references franka-sim may hold had it taken some of cps's commands late
    /// ([`late`]), and whether the last cycle went unanswered for want of a command every
    /// one of them accepts.
    late: LateHistory,
    unmet: bool,
    limiter: Limiter<JOINTS>,
    mode: Mode,
    control: F,
    velocity: bool,
    /// The generator's last command (a velocity motion integrates from it).
    desired: [f64; JOINTS],
    /// The robot time the generator's clock started at; None while the motion opens at
    /// rest, and the periods it has so far.
    origin: Option<f64>,
    opening: u64,
    reason: Option<MotionEnd>,
    brake_ticks: usize,
}

impl<F> PositionLaw<F>
where
    F: FnMut(&RobotState, f64, [f64; JOINTS]) -> JointPositions,
{
    /// `control(state, t, last)`: the command at robot time `t`, `last` the one before.
    pub(crate) fn new(limits: RateLimits, velocity: bool, control: F) -> Self {
        let q0 = [0.0; JOINTS];
        PositionLaw {
            check: stream_check(limits, q0),
            tracker: ReferenceTracker::new(q0, velocity),
            late: LateHistory::new(limits),
            unmet: false,
            limiter: Limiter::new(q0),
            mode: Mode::Follow,
            control,
            velocity,
            desired: q0,
            origin: None,
            opening: 0,
            reason: None,
            brake_ticks: 0,
        }
    }

    /// Asks the generator for every robot period since the last state answered (the
    /// limiter sees each), on its own clock (see the module's text); true when it finished.
    fn generate(&mut self, state: &RobotState, t: f64, periods: u64) -> bool {
        let origin = match self.origin {
            Some(origin) => origin,
            None if state.control_command_success_rate > 0.0
                || self.opening >= OPENING_PERIODS_MAX =>
            {
                *self.origin.insert(t)
            }
            None => {
                self.opening += periods;
                (0..periods).for_each(|_| self.limiter.desire(&self.desired, DT));
                return false;
            }
        };
        for p in (0..periods).rev() {
            let at = t - origin - p as f64 * DT;
            if at < 0.0 {
                // Periods before the clock started: at rest where the motion opened.
                self.limiter.desire(&self.desired, DT);
                continue;
            }
            let step = (self.control)(state, at, self.desired);
            self.desired = step.q;
            self.limiter.desire(&step.q, DT);
            if step.finished {
                return true;
            }
        }
        false
    }

    /// One step of a controlled stop from the robot's reference `r`, admitted (the robot's
    /// own extrapolation if the step is not, which cannot happen for a brake from an
    /// admitted reference; tested); whether it is at rest.
    fn brake_step(&mut self, r: &Reference) -> ([f64; JOINTS], bool) {
        self.brake_ticks += 1;
        let mut brake = Brake::new(*self.check.bounds(), r.q, r.v, r.a);
        let q = brake.step();
        if self.check.admit(&q).is_ok() {
            (q, brake.stopped())
        } else {
            let held = r.extrapolated(DT).q;
            let _ = self.check.admit(&held);
            (held, false)
        }
    }
}

impl<F> Law for PositionLaw<F>
where
    F: FnMut(&RobotState, f64, [f64; JOINTS]) -> JointPositions,
{
    fn modes(&self) -> (ControllerMode, MotionGeneratorMode) {
        let generator = if self.velocity {
            MotionGeneratorMode::JointVelocity
        } else {
            MotionGeneratorMode::JointPosition
        };
        (ControllerMode::JointImpedance, generator)
    }

    fn start(&mut self, state: &RobotState) {
        let q0 = super::start_position(state);
        let limits = *self.check.bounds();
        self.check = stream_check(limits, q0);
        self.tracker = ReferenceTracker::new(q0, self.velocity);
        self.late = LateHistory::new(limits);
        self.unmet = false;
        self.limiter = Limiter::new(q0);
        self.desired = q0;
        self.origin = None;
        self.opening = 0;
    }

    fn following(&self) -> bool {
        matches!(self.mode, Mode::Follow)
    }

    fn answer(
        &mut self,
        state: &RobotState,
        t: f64,
        (periods, behind): (u64, bool),
        _tick: usize,
        brake: Option<MotionEnd>,
        command: &mut Command,
    ) -> Option<bool> {
        let r = self.tracker.reference(state);
        if let Some((id, after)) = self.tracker.confirmed() {
            self.late.anchor(id, after);
        }
        self.check.rebase(&r.q, &r.v, &r.a);
        if let Some(reason) = brake
            && self.following()
        {
            self.reason.get_or_insert(reason);
            self.mode = Mode::Brake;
        }
        if self.tracker.unresolved() {
            // No command this cycle: the next state tells which reference the robot holds.
            // The generator keeps the robot's time all the same.
            match self.mode {
                Mode::Follow => {
                    if self.generate(state, t, periods) {
                        self.mode = Mode::Hold(self.desired);
                    }
                }
                Mode::Hold(q) => (0..periods).for_each(|_| self.limiter.desire(&q, DT)),
                Mode::Brake => {}
            }
            return None;
        }
        let finished = match self.mode {
            Mode::Follow => {
                let finished = self.generate(state, t, periods);
                if finished {
                    self.mode = Mode::Hold(self.desired);
                }
                finished
            }
            Mode::Hold(q) => {
                for _ in 0..periods {
                    self.limiter.desire(&q, DT);
                }
                true
            }
            Mode::Brake => false,
        };
        let (q_c, mut done) = if matches!(self.mode, Mode::Brake) {
            self.brake_step(&r)
        } else {
            let before = self.check;
            match self.limiter.admit(&mut self.check, &r) {
                // A joint-velocity motion's late command averages only its acceleration;
                // a robot whose states do not show its reference (franky-sim) is not
                // franka-sim.
                Ok(q) if !self.velocity && self.tracker.reports_reference() => {
                    let id = state.message_id;
                    let (sent, how) = late::guard(&self.late, id, &before, &mut self.check, &r, q);
                    if how == Guarded::Moved {
                        self.limiter.replace(sent);
                    }
                    if how == Guarded::Unmet && !self.unmet {
                        // No command every history accepts: none this cycle (once). The
                        // robot extrapolates the reference it holds, which each accepts.
                        self.check = before;
                        self.limiter.withdraw();
                        self.unmet = true;
                        return None;
                    }
                    (sent, finished)
                }
                Ok(q) => (q, finished),
                Err(breach) => {
                    // Never sent: a controlled stop from the robot's reference instead.
                    self.reason.get_or_insert(MotionEnd::LimitBrake(breach));
                    self.mode = Mode::Brake;
                    self.brake_step(&r)
                }
            }
        };
        if done && !self.check.at_rest_now() {
            // Not at rest yet: hold the last command (or keep braking) until it is.
            done = false;
        }
        command.q_c = q_c;
        if self.velocity {
            // The velocity the admitted position stands for (zero once at rest).
            command.dq_c = *self.check.last().1;
        }
        command.motion_generation_finished = done;
        self.unmet = false;
        self.tracker.sent(state.message_id, q_c, behind);
        self.late.sent(state.message_id, q_c);
        Some(done)
    }

    fn withdraw(&mut self) {
        self.tracker.withdraw();
        self.late.withdraw();
        self.limiter.withdraw();
    }

    fn outcome(self) -> Outcome {
        Outcome {
            reason: self.reason,
            peak: *self.check.peak_usage(),
            brake_ticks: self.brake_ticks,
            limited: self.limiter.limited(),
            reference: self.tracker.counts(),
            clock_start: self.origin,
        }
    }
}

/// Torques from cps, limited to the arm's torque and, from the last torques the robot
/// applied, its torque rate; with a damped stop.
pub(crate) struct TorqueLaw<F> {
    limits: RateLimits,
    control: F,
    tracker: TorqueTracker,
    stopping: bool,
    at_rest_ticks: usize,
    reason: Option<MotionEnd>,
    brake_ticks: usize,
    limited: Limited,
    /// Peak share of the torque, the torque rate and the speed limit.
    peak: [[f64; JOINTS]; 3],
}

impl<F> TorqueLaw<F> {
    pub(crate) fn new(limits: RateLimits, control: F) -> Self {
        TorqueLaw {
            limits,
            control,
            tracker: TorqueTracker::default(),
            stopping: false,
            at_rest_ticks: 0,
            reason: None,
            brake_ticks: 0,
            limited: Limited::default(),
            peak: [[0.0; JOINTS]; 3],
        }
    }

    fn stop_for(&mut self, reason: MotionEnd) {
        if !self.stopping {
            self.reason.get_or_insert(reason);
            self.stopping = true;
        }
    }
}

impl<F> Law for TorqueLaw<F>
where
    F: FnMut(&RobotState, f64) -> Torques,
{
    fn modes(&self) -> (ControllerMode, MotionGeneratorMode) {
        (
            ControllerMode::ExternalController,
            MotionGeneratorMode::None,
        )
    }

    fn start(&mut self, _state: &RobotState) {
        // The robot holds the arm against gravity itself; the torques start from the ones
        // it reports (tau_J_d) and are limited from them every tick.
        self.tracker = TorqueTracker::default();
    }

    fn following(&self) -> bool {
        !self.stopping
    }

    fn answer(
        &mut self,
        state: &RobotState,
        t: f64,
        _periods: (u64, bool),
        tick: usize,
        brake: Option<MotionEnd>,
        command: &mut Command,
    ) -> Option<bool> {
        if let Some(reason) = brake {
            self.stop_for(reason);
        }
        let l = self.limits;
        if let Some(i) = (0..JOINTS).find(|&i| state.dq[i].abs() > TORQUE_SPEED_GUARD * l.dq_max[i])
        {
            self.stop_for(MotionEnd::LimitBrake(joint_breach(
                i + 1,
                Quantity::Velocity,
                tick,
                state.dq[i],
                TORQUE_SPEED_GUARD * l.dq_max[i],
            )));
        }
        let last = self.tracker.reference(state);
        let mut finished = false;
        let mut tau = [0.0; JOINTS];
        if !self.stopping {
            let c = (self.control)(state, t);
            if let Some(i) = (0..JOINTS).find(|&i| !c.tau[i].is_finite()) {
                self.stop_for(MotionEnd::LimitBrake(joint_breach(
                    i + 1,
                    Quantity::Torque,
                    tick,
                    c.tau[i],
                    l.tau_max[i],
                )));
            } else {
                tau = c.tau;
                finished = c.finished;
            }
        }
        if self.stopping {
            self.brake_ticks += 1;
            for ((x, d), v) in tau.iter_mut().zip(STOP_DAMPING).zip(state.dq) {
                *x = -d * v;
            }
            let still = state.dq.iter().all(|v| v.abs() < 0.02);
            self.at_rest_ticks = if still { self.at_rest_ticks + 1 } else { 0 };
            // At rest for 50 ms, or after 3 s whatever happens (the robot holds itself).
            finished = self.at_rest_ticks >= 50 || self.brake_ticks >= 3000;
        }
        // Within the torque rate from what the robot applied last, then the torque.
        let mut limited = false;
        for (i, t) in tau.iter_mut().enumerate() {
            let step = TORQUE_RATE_SHARE * l.dtau_max[i] * DT;
            let x = t
                .clamp(last[i] - step, last[i] + step)
                .clamp(-l.tau_max[i], l.tau_max[i]);
            if x != *t {
                limited = true;
                self.limited.deviation = self.limited.deviation.max((x - *t).abs());
            }
            self.peak[0][i] = self.peak[0][i].max(x.abs() / l.tau_max[i]);
            self.peak[1][i] = self.peak[1][i].max((x - last[i]).abs() / (l.dtau_max[i] * DT));
            self.peak[2][i] = self.peak[2][i].max(state.dq[i].abs() / l.dq_max[i]);
            *t = x;
        }
        if limited && !self.stopping {
            self.limited.commands += 1;
        }
        command.tau_j_d = tau;
        command.torque_command_finished = finished;
        command.motion_generation_finished = finished;
        self.tracker.sent(tau);
        Some(finished)
    }

    fn withdraw(&mut self) {
        self.tracker.withdraw();
    }

    fn outcome(self) -> Outcome {
        Outcome {
            reason: self.reason,
            peak: self.peak,
            brake_ticks: self.brake_ticks,
            limited: self.limited,
            reference: self.tracker.counts(),
            clock_start: Some(0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::Arm;

    /// A state at rest at `q`, `rate` the share of commands the robot took in time.
    fn state(id: u64, q: [f64; JOINTS], rate: f64) -> RobotState {
        let mut s = RobotState::decode(&[0u8; crate::wire::STATE_SIZE]).unwrap();
        s.message_id = id;
        s.q = q;
        s.q_d = q;
        s.control_command_success_rate = rate;
        s
    }

    /// Answers states `first..=last` (one period apart, robot time `id` ms) with `rate`;
    /// the commands sent.
    fn answer_states<F>(
        law: &mut PositionLaw<F>,
        q0: [f64; JOINTS],
        ids: std::ops::RangeInclusive<u64>,
        rate: f64,
    ) -> Vec<[f64; JOINTS]>
    where
        F: FnMut(&RobotState, f64, [f64; JOINTS]) -> JointPositions,
    {
        ids.map(|id| {
            let mut command = Command::default();
            let sent = law.answer(
                &state(id, q0, rate),
                id as f64 * DT,
                (1, false),
                id as usize,
                None,
                &mut command,
            );
            assert_eq!(sent, Some(false), "state {id} is answered");
            command.q_c
        })
        .collect()
    }

    #[test]
    fn the_motion_opens_at_rest_until_the_robot_shows_a_command_taken() {
        let q0 = [0.1, -0.4, 0.2, -2.0, 0.0, 1.6, 0.8];
        let asked = std::cell::RefCell::new(Vec::new());
        let mut law = PositionLaw::new(RateLimits::of(Arm::Fr3), false, |_: &RobotState, t, _| {
            asked.borrow_mut().push(t);
            JointPositions {
                q: q0.map(|q| q + 1e-3 * t * t * t),
                finished: false,
            }
        });
        law.start(&state(10, q0, 0.0));
        // No command taken yet: the start, at rest, and the generator not asked.
        let opening = answer_states(&mut law, q0, 11..=13, 0.0);
        assert!(opening.iter().all(|q| *q == q0), "{opening:?}");
        assert!(asked.borrow().is_empty(), "{:?}", asked.borrow());
        // The robot shows one taken: the generator's clock starts at that state.
        answer_states(&mut law, q0, 14..=16, 1.0);
        let asked = asked.borrow();
        assert_eq!(asked.len(), 3);
        for (k, t) in asked.iter().enumerate() {
            assert!((t - k as f64 * DT).abs() < 1e-12, "{asked:?}");
        }
    }

    #[test]
    fn a_robot_that_never_shows_a_command_taken_opens_the_motion_at_the_bound() {
        let q0 = [0.0, -0.5, 0.0, -2.2, 0.0, 1.7, 0.7];
        let mut asked = 0;
        let mut law = PositionLaw::new(RateLimits::of(Arm::Fr3), false, |_: &RobotState, _, _| {
            asked += 1;
            JointPositions {
                q: q0,
                finished: false,
            }
        });
        law.start(&state(0, q0, 0.0));
        let last = OPENING_PERIODS_MAX + 5;
        answer_states(&mut law, q0, 1..=last, 0.0);
        drop(law);
        assert_eq!(
            asked, 5,
            "the generator starts after {OPENING_PERIODS_MAX} periods"
        );
    }
}
