//! The realtime loop: one dedicated thread, one state in and one command out per robot
//! tick, every command admitted by the limit check or replaced by a controlled stop.
//!
//! Inside the loop nothing allocates, locks or logs: the recording, the latency samples
//! and the command buffer are allocated before the motion starts, and the loop stops the
//! robot (within the limits) when its recording is full. Time follows the robot's clock:
//! the state's message id counts milliseconds, so a generator sees `t = (id − id₀) · 1 ms`
//! however fast the robot ticks (franky-sim steps at ≈ 850 Hz on two cores). A tick the
//! robot made without a state reaching cps is counted as missed; a state superseded by a
//! newer one before cps read it is counted as stale and skipped (the newest is answered).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::error::FrankaError;
use crate::limits::{Brake, DT, RateLimits, StreamCheck, joint_breach};
use crate::session::Connection;
use crate::wire::{
    Command, ControllerMode, JOINTS, MotionGeneratorMode, MoveStatus, RobotMode, RobotState,
};
use cps_kinematics::Quantity;
use cps_robot::Breach;

/// Whether the loop thread asks for realtime scheduling (libfranka's `RealtimeConfig`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Realtime {
    /// SCHED_FIFO or an error naming why it cannot be had.
    Enforce,
    /// Try SCHED_FIFO, run at normal priority when it is not permitted.
    Ignore,
}

/// Ticks kept free in the recording for a stop (2 s: a brake from full speed takes
/// 0.3 s on the FR3).
pub const BRAKE_RESERVE: usize = 2000;

/// Settings of a motion.
#[derive(Debug, Clone, Copy)]
pub struct LoopOptions {
    /// Realtime scheduling of the loop thread.
    pub realtime: Realtime,
    /// A state later than this ends the motion as a lost connection (the robot stops by
    /// itself when commands stop: a real FCI after a few missed ticks).
    pub state_timeout: Duration,
    /// Ticks the recording holds (264 bytes each, allocated before the motion); the loop
    /// starts braking [`BRAKE_RESERVE`] ticks before it is full, so the stop is recorded.
    pub max_ticks: usize,
}

impl Default for LoopOptions {
    fn default() -> Self {
        LoopOptions {
            realtime: Realtime::Enforce,
            state_timeout: Duration::from_millis(100),
            max_ticks: 60_000 + BRAKE_RESERVE,
        }
    }
}

/// One recorded tick: what the robot measured and what cps commanded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Robot time since the motion started (s).
    pub t: f64,
    /// The robot state's message id (the robot's tick counter), to align a recording with
    /// other logs.
    pub id: u64,
    /// Measured joint positions.
    pub q: [f64; JOINTS],
    /// Measured joint velocities.
    pub dq: [f64; JOINTS],
    /// Measured joint torques.
    pub tau: [f64; JOINTS],
    /// The commanded joint positions sent at this tick (a velocity motion: the positions
    /// its velocities integrate to; torque control: zeros).
    pub q_c: [f64; JOINTS],
    /// The joint torques cps sent at this tick (torque control; zeros otherwise).
    pub tau_c: [f64; JOINTS],
    /// The end effector's measured position in the base frame.
    pub tool: [f64; 3],
}

/// The loop's own timing: state in → command out, per answered tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Ticks answered.
    pub ticks: usize,
    /// Median latency (µs).
    pub median_us: f64,
    /// 99th percentile (µs).
    pub p99_us: f64,
    /// Largest (µs).
    pub max_us: f64,
    /// Robot ticks without an answer from cps (message ids skipped).
    pub missed: u64,
    /// States superseded before cps read them (skipped for a newer one).
    pub stale: u64,
    /// Whether the loop thread ran with SCHED_FIFO.
    pub realtime: bool,
}

/// How a motion of the 1 kHz loop ended, in the loop's own terms; [`crate::FrankaRobot`]
/// turns it into the contract's [`cps_robot::Ending`] (finished, stopped, failed).
#[derive(Debug, Clone, PartialEq)]
pub enum MotionEnd {
    /// The generator finished and the robot confirmed the motion's end.
    Finished,
    /// Stopped on request (Ctrl-C, SIGTERM): braked to rest within the limits, then ended.
    Stopped,
    /// The generator asked for a command beyond a limit: it was never sent; the robot was
    /// braked to rest from the last admitted command.
    LimitBrake(Breach),
    /// The recording was full: braked to rest.
    RecordingFull,
    /// The robot ended the motion itself (a reflex, the user stop, a preemption).
    Robot {
        /// The Move's final status.
        status: MoveStatus,
        /// The errors in the last state.
        errors: String,
    },
    /// States stopped arriving or the connection broke.
    Lost(String),
}

impl MotionEnd {
    /// Whether the motion ran to its end as planned.
    pub fn complete(&self) -> bool {
        matches!(self, MotionEnd::Finished)
    }

    /// The ending as a sentence.
    pub fn sentence(&self) -> String {
        match self {
            MotionEnd::Finished => "the motion finished".into(),
            MotionEnd::Stopped => "stopped on request: braked to rest within the limits".into(),
            MotionEnd::LimitBrake(b) => {
                format!("a command beyond a limit was not sent ({b}); braked to rest")
            }
            MotionEnd::RecordingFull => "the recording was full: braked to rest".into(),
            MotionEnd::Robot { status, errors } => format!(
                "the robot ended the motion: {} (errors: {errors})",
                status.sentence()
            ),
            MotionEnd::Lost(r) => format!("the connection was lost: {r}"),
        }
    }
}

/// A motion's record: every tick, the timing, how it ended, what was sent.
#[derive(Debug, Clone)]
pub struct MotionReport {
    /// One sample per answered tick.
    pub samples: Vec<Sample>,
    /// The loop's timing.
    pub timing: Timing,
    /// How the motion ended.
    pub ending: MotionEnd,
    /// Peak usage of velocity, acceleration and jerk per joint of every command sent
    /// (1.0 = at the published limit).
    pub peak_usage: [[f64; JOINTS]; 3],
    /// Ticks spent braking.
    pub brake_ticks: usize,
    /// Torque control: commands limited to the torque or torque-rate limit before they
    /// were sent (0 for joint positions and velocities, which are checked, never limited).
    pub clipped: usize,
}

/// A joint position generator's answer for one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointPositions {
    /// The commanded positions.
    pub q: [f64; JOINTS],
    /// True on the last command (the robot is at rest there).
    pub finished: bool,
}

/// Makes the calling thread realtime (SCHED_FIFO) when permitted.
fn make_realtime(mode: Realtime) -> Result<bool, FrankaError> {
    use thread_priority::{
        RealtimeThreadSchedulePolicy, ThreadPriority, ThreadSchedulePolicy,
        set_thread_priority_and_policy, thread_native_id,
    };
    let priority = ThreadPriority::Crossplatform(80u8.try_into().expect("80 is a valid priority"));
    let policy = ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo);
    match set_thread_priority_and_policy(thread_native_id(), priority, policy) {
        Ok(()) => Ok(true),
        Err(e) => match mode {
            Realtime::Enforce => Err(FrankaError::Realtime(format!("{e:?}"))),
            Realtime::Ignore => Ok(false),
        },
    }
}

fn percentile(sorted: &[u32], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    f64::from(sorted[k]) / 1e3
}

/// Where a joint position motion starts: the robot's last desired position (`q_d`, as
/// libfranka's generators start), or its measured one when it reports none.
pub fn start_position(state: &RobotState) -> [f64; JOINTS] {
    if state.q_d.iter().all(|&x| x == 0.0) {
        state.q
    } else {
        state.q_d
    }
}

/// Runs a joint position motion: `control(state, t)` is asked for the command at robot
/// time `t` each tick, on a dedicated thread; every command passes [`StreamCheck`] or is
/// replaced by a [`Brake`] from the last admitted one. `stop` set by another thread (a
/// signal handler) brakes the robot to rest and ends the motion.
///
/// Errors before the motion starts (the robot not ready, the Move refused, realtime not
/// permitted) are returned as errors and nothing moved; everything after the start ends in
/// a [`MotionReport`] whose [`MotionEnd`] says how, with every sample recorded.
pub fn run_joint_positions<F>(
    conn: &mut Connection,
    limits: RateLimits,
    options: &LoopOptions,
    stop: &AtomicBool,
    mut control: F,
) -> Result<MotionReport, FrankaError>
where
    F: FnMut(&RobotState, f64) -> JointPositions + Send,
{
    let law = PositionLaw::new(limits, false, move |s: &RobotState, t, _| control(s, t));
    on_own_thread(conn, options, stop, law)
}

/// Runs a joint velocity motion (the robot's joint velocity generator): `control(state,
/// t)` gives the velocities for each tick. They are admitted as the positions they
/// integrate to, so the same [`StreamCheck`] holds them — velocity, acceleration, jerk, the
/// joint range and the distance a stop needs — and a [`Brake`] replaces any that would
/// break one. The motion finishes once `finished` is answered and the commanded velocity
/// is zero. [`Sample::q_c`] records the integrated positions.
pub fn run_joint_velocities<F>(
    conn: &mut Connection,
    limits: RateLimits,
    options: &LoopOptions,
    stop: &AtomicBool,
    mut control: F,
) -> Result<MotionReport, FrankaError>
where
    F: FnMut(&RobotState, f64) -> JointVelocities + Send,
{
    let law = PositionLaw::new(
        limits,
        true,
        move |s: &RobotState, t, last: [f64; JOINTS]| {
            let v = control(s, t);
            let mut q = last;
            for (x, dq) in q.iter_mut().zip(v.dq) {
                *x += dq * DT;
            }
            JointPositions {
                q,
                finished: v.finished,
            }
        },
    );
    on_own_thread(conn, options, stop, law)
}

/// Runs torques computed by cps (the robot's external controller mode; the robot adds
/// gravity): `control(state, t)` gives the joint torques for each tick. Each command is
/// limited to the arm's torque and torque rate (1000 N m/s) before it is sent — as
/// libfranka's rate limiter does — and the limited commands are counted
/// ([`MotionReport::clipped`]); a torque that is not a number, or a joint measured faster
/// than [`TORQUE_SPEED_GUARD`] of its speed limit, switches to a damped stop. `stop`
/// brakes the same way: `τ = −D·dq` within the rate limit until the arm is at rest, then
/// the motion ends. [`Sample::tau_c`] records what was sent.
pub fn run_torques<F>(
    conn: &mut Connection,
    limits: RateLimits,
    options: &LoopOptions,
    stop: &AtomicBool,
    control: F,
) -> Result<MotionReport, FrankaError>
where
    F: FnMut(&RobotState, f64) -> Torques + Send,
{
    on_own_thread(conn, options, stop, TorqueLaw::new(limits, control))
}

/// The share of a joint's speed limit above which a torque-controlled motion is braked.
pub const TORQUE_SPEED_GUARD: f64 = 0.9;

/// Damping of the torque-mode stop (N m s/rad), per joint.
const STOP_DAMPING: [f64; JOINTS] = [40.0, 40.0, 40.0, 40.0, 10.0, 10.0, 5.0];

/// A joint velocity generator's answer for one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointVelocities {
    /// The commanded velocities (rad/s).
    pub dq: [f64; JOINTS],
    /// True on the last command (the velocities must then be zero).
    pub finished: bool,
}

/// A torque controller's answer for one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Torques {
    /// The commanded joint torques without gravity (N m).
    pub tau: [f64; JOINTS],
    /// True on the last command.
    pub finished: bool,
}

fn on_own_thread<L: Law + Send>(
    conn: &mut Connection,
    options: &LoopOptions,
    stop: &AtomicBool,
    law: L,
) -> Result<MotionReport, FrankaError> {
    std::thread::scope(|scope| {
        scope
            .spawn(move || run_law(conn, options, stop, law))
            .join()
            .unwrap_or_else(|_| {
                Err(FrankaError::Input(
                    "the control loop's thread panicked".into(),
                ))
            })
    })
}

/// What the loop runs: one command per state, and a controlled stop when asked.
trait Law {
    /// The Move's controller and motion generator.
    fn modes(&self) -> (ControllerMode, MotionGeneratorMode);
    /// The robot's state before the Move: where the motion starts.
    fn start(&mut self, state: &RobotState);
    /// Whether the law still follows its generator (not holding, not stopping).
    fn following(&self) -> bool;
    /// Fills `command` for `state` at robot time `t` (the tick's index `tick`); `brake`
    /// asks for a controlled stop for that reason. True when the command is the last.
    fn answer(
        &mut self,
        state: &RobotState,
        t: f64,
        tick: usize,
        brake: Option<MotionEnd>,
        command: &mut Command,
    ) -> bool;
    /// Why the law stopped on its own or was stopped (if it was); the peak usage; the
    /// ticks spent stopping; the commands limited before sending.
    fn outcome(self) -> (Option<MotionEnd>, [[f64; JOINTS]; 3], usize, usize);
}

// The brake lives in place: boxing it would allocate inside the loop.
#[allow(clippy::large_enum_variant)]
enum Mode {
    Follow,
    /// The generator finished in motion: its last command is held until at rest (as the
    /// check of a whole stream assumes), braking instead if holding breaks a limit.
    Hold([f64; JOINTS]),
    Brake(Brake),
}

/// Joint positions (or velocities, as the positions they integrate to) through the
/// [`StreamCheck`], with a [`Brake`] for anything it refuses.
struct PositionLaw<F> {
    check: StreamCheck,
    mode: Mode,
    control: F,
    velocity: bool,
    reason: Option<MotionEnd>,
    brake_ticks: usize,
}

impl<F> PositionLaw<F>
where
    F: FnMut(&RobotState, f64, [f64; JOINTS]) -> JointPositions,
{
    fn new(limits: RateLimits, velocity: bool, control: F) -> Self {
        PositionLaw {
            check: StreamCheck::at_rest(limits, [0.0; JOINTS]),
            mode: Mode::Follow,
            control,
            velocity,
            reason: None,
            brake_ticks: 0,
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
        self.check = StreamCheck::at_rest(*self.check.limits(), start_position(state));
    }

    fn following(&self) -> bool {
        matches!(self.mode, Mode::Follow)
    }

    fn answer(
        &mut self,
        state: &RobotState,
        t: f64,
        _tick: usize,
        brake: Option<MotionEnd>,
        command: &mut Command,
    ) -> bool {
        if let Some(reason) = brake
            && self.following()
        {
            self.reason.get_or_insert(reason);
            self.mode = Mode::Brake(Brake::from_check(&self.check));
        }
        let (desired, finished) = match &mut self.mode {
            Mode::Follow => {
                let step = (self.control)(state, t, self.check.last().0);
                (step.q, step.finished)
            }
            Mode::Hold(q) => (*q, true),
            Mode::Brake(b) => {
                self.brake_ticks += 1;
                let q = b.step();
                (q, b.stopped())
            }
        };
        let (q_c, mut done) = match self.check.admit(&desired) {
            Ok(()) => (desired, finished),
            Err(breach) => {
                // Never sent: brake from the last admitted command instead.
                let mut b = Brake::from_check(&self.check);
                let q = b.step();
                let stopped = b.stopped();
                self.reason.get_or_insert(MotionEnd::LimitBrake(breach));
                self.mode = Mode::Brake(b);
                if self.check.admit(&q).is_err() {
                    // Cannot happen for a brake from an admitted state (tested); hold.
                    (self.check.last().0, false)
                } else {
                    (q, stopped)
                }
            }
        };
        if done && !self.check.at_rest_now() {
            // Not at rest yet: hold the last command (or keep braking) until it is.
            if self.following() {
                self.mode = Mode::Hold(q_c);
            }
            done = false;
        }
        command.q_c = q_c;
        if self.velocity {
            // The velocity the admitted position stands for (zero once at rest).
            command.dq_c = self.check.last().1;
        }
        command.motion_generation_finished = done;
        done
    }

    fn outcome(self) -> (Option<MotionEnd>, [[f64; JOINTS]; 3], usize, usize) {
        (self.reason, self.check.peak_usage(), self.brake_ticks, 0)
    }
}

/// Torques from cps, limited to the arm's torque and torque rate, with a damped stop.
struct TorqueLaw<F> {
    limits: RateLimits,
    control: F,
    last: [f64; JOINTS],
    stopping: bool,
    at_rest_ticks: usize,
    reason: Option<MotionEnd>,
    brake_ticks: usize,
    clipped: usize,
    /// Peak share of the torque, the torque rate and the speed limit.
    peak: [[f64; JOINTS]; 3],
}

impl<F> TorqueLaw<F> {
    fn new(limits: RateLimits, control: F) -> Self {
        TorqueLaw {
            limits,
            control,
            last: [0.0; JOINTS],
            stopping: false,
            at_rest_ticks: 0,
            reason: None,
            brake_ticks: 0,
            clipped: 0,
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
        // The robot holds the arm against gravity itself; cps's torques start from zero.
        self.last = [0.0; JOINTS];
    }

    fn following(&self) -> bool {
        !self.stopping
    }

    fn answer(
        &mut self,
        state: &RobotState,
        t: f64,
        tick: usize,
        brake: Option<MotionEnd>,
        command: &mut Command,
    ) -> bool {
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
        // Within the torque rate, then the torque, of the last command sent.
        let mut limited = false;
        for (i, t) in tau.iter_mut().enumerate() {
            let step = l.dtau_max[i] * DT;
            let x = t
                .clamp(self.last[i] - step, self.last[i] + step)
                .clamp(-l.tau_max[i], l.tau_max[i]);
            limited |= x != *t;
            self.peak[0][i] = self.peak[0][i].max(x.abs() / l.tau_max[i]);
            self.peak[1][i] = self.peak[1][i].max((x - self.last[i]).abs() / step);
            self.peak[2][i] = self.peak[2][i].max(state.dq[i].abs() / l.dq_max[i]);
            *t = x;
        }
        if limited && !self.stopping {
            self.clipped += 1;
        }
        self.last = tau;
        command.tau_j_d = tau;
        command.torque_command_finished = finished;
        command.motion_generation_finished = finished;
        finished
    }

    fn outcome(self) -> (Option<MotionEnd>, [[f64; JOINTS]; 3], usize, usize) {
        (self.reason, self.peak, self.brake_ticks, self.clipped)
    }
}

fn run_law<L: Law>(
    conn: &mut Connection,
    options: &LoopOptions,
    stop: &AtomicBool,
    mut law: L,
) -> Result<MotionReport, FrankaError> {
    let realtime = make_realtime(options.realtime)?;
    let (state, _) = conn.newest_state(options.state_timeout.max(Duration::from_millis(500)))?;
    conn.ensure_ready(&state)?;
    law.start(&state);
    // Everything the loop needs, allocated now.
    let mut samples: Vec<Sample> = Vec::with_capacity(options.max_ticks);
    let mut latency_ns: Vec<u32> = Vec::with_capacity(options.max_ticks);
    let mut command = Command::default();
    let (controller, generator) = law.modes();
    let motion_id = conn.start_move(controller, generator)?;

    let mut ending: Option<MotionEnd> = None;
    let (mut first_id, mut last_id) = (None::<u64>, None::<u64>);
    let (mut missed, mut stale) = (0u64, 0u64);
    let mut last_errors = String::new();
    let mut finished_sent = false;
    loop {
        let (state, skipped) = match conn.newest_state(options.state_timeout) {
            Ok(s) => s,
            Err(e) => {
                ending = Some(MotionEnd::Lost(e.to_string()));
                break;
            }
        };
        let t_in = Instant::now();
        stale += u64::from(skipped);
        let id0 = *first_id.get_or_insert(state.message_id);
        if let Some(last) = last_id {
            if state.message_id <= last {
                continue; // a duplicate or reordered datagram: already answered
            }
            // Ticks between the last answered state and this one that never reached cps.
            missed += (state.message_id - last - 1).saturating_sub(u64::from(skipped));
        }
        last_id = Some(state.message_id);
        if state.robot_mode == RobotMode::Reflex || state.errors.any() {
            // The robot ended the motion; it takes no more commands. Its final status
            // follows on TCP.
            last_errors = state.errors.describe();
            break;
        }
        let t = (state.message_id - id0) as f64 * DT;
        let brake = if !law.following() {
            None
        } else if stop.load(Ordering::Relaxed) {
            Some(MotionEnd::Stopped)
        } else if samples.len() + BRAKE_RESERVE >= options.max_ticks {
            Some(MotionEnd::RecordingFull)
        } else {
            None
        };
        let done = law.answer(&state, t, samples.len(), brake, &mut command);
        command.message_id = state.message_id;
        if let Err(e) = conn.send_command(&command) {
            ending = Some(MotionEnd::Lost(e.to_string()));
            break;
        }
        let ns = t_in.elapsed().as_nanos().min(u128::from(u32::MAX)) as u32;
        if latency_ns.len() < latency_ns.capacity() {
            latency_ns.push(ns);
        }
        if samples.len() < samples.capacity() {
            samples.push(Sample {
                t,
                id: state.message_id,
                q: state.q,
                dq: state.dq,
                tau: state.tau_j,
                q_c: command.q_c,
                tau_c: command.tau_j_d,
                tool: state.tool_position(),
            });
        }
        if done {
            finished_sent = true;
            break;
        }
        if samples.len().is_multiple_of(16) {
            match conn.poll_move_end(motion_id) {
                Ok(None) => {}
                Ok(Some(status)) => {
                    ending = Some(MotionEnd::Robot {
                        status,
                        errors: state.errors.describe(),
                    });
                    break;
                }
                Err(e) => {
                    ending = Some(MotionEnd::Lost(e.to_string()));
                    break;
                }
            }
        }
    }
    let (reason, peak_usage, brake_ticks, clipped) = law.outcome();
    // After the loop: the robot's word on how the motion ended (bounded).
    let ending = match ending {
        Some(e) => e,
        None => match conn.await_move_end(motion_id, Duration::from_secs(2)) {
            Ok(MoveStatus::Success) if finished_sent => reason.unwrap_or(MotionEnd::Finished),
            Ok(status) => MotionEnd::Robot {
                status,
                errors: if last_errors.is_empty() {
                    "none".into()
                } else {
                    last_errors
                },
            },
            Err(e) => MotionEnd::Lost(e.to_string()),
        },
    };
    latency_ns.sort_unstable();
    let timing = Timing {
        ticks: latency_ns.len(),
        median_us: percentile(&latency_ns, 0.5),
        p99_us: percentile(&latency_ns, 0.99),
        max_us: latency_ns.last().map_or(0.0, |&x| f64::from(x) / 1e3),
        missed,
        stale,
        realtime,
    };
    Ok(MotionReport {
        samples,
        timing,
        ending,
        peak_usage,
        brake_ticks,
        clipped,
    })
}
