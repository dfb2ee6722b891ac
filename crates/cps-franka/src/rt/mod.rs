//! The realtime loop: one dedicated thread, one state in and one command out per robot
//! tick, every command judged against the reference the robot holds and admitted,
//! limited, or replaced by a controlled stop (the laws, in `rt/laws.rs`).
//!
//! Inside the loop nothing allocates, locks or logs: the recording, the latency samples
//! and the command buffer are allocated before the motion starts, and the loop stops the
//! robot (within the limits) when its recording is full. Time follows the robot's clock:
//! the state's message id counts milliseconds, so a generator sees `t = (id − id₀) · 1 ms`
//! however fast the robot ticks (franky-sim steps at ≈ 850 Hz on two cores), and a state
//! that comes two ids after the last one answered is a 2 ms period, as libfranka's
//! `period` is. A tick the robot made without a state reaching cps is counted as missed; a
//! state superseded by a newer one before cps read it is counted as stale and skipped
//! (the newest is answered); the robot extrapolated both ([`crate::reference`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::error::FrankaError;
mod late;
mod laws;

use crate::limits::{DT, RateLimits};
use crate::reference::ReferenceCounts;
use crate::session::Connection;
use crate::wire::{Command, JOINTS, MoveStatus, RobotMode, RobotState};
use cps_robot::Breach;
use cps_robot::Limited;
use laws::{Law, PositionLaw, TorqueLaw};
pub use laws::{TORQUE_RATE_SHARE, TORQUE_SPEED_GUARD};

/// Whether the loop thread asks for realtime scheduling (libfranka's `RealtimeConfig`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Realtime {
    /// SCHED_FIFO or an error naming why it cannot be had.
    Enforce,
    /// Try SCHED_FIFO, run at normal priority when it is not permitted.
    Ignore,
    /// Run at normal priority (as on a machine where SCHED_FIFO is not permitted, how
    /// most learning researchers run their arm): the robot then loses cycles whenever the
    /// loop waits for a core, which the loop must survive.
    Off,
}

impl Realtime {
    /// The settings by their words, as the command line, experiment files and Python
    /// spell them.
    pub const WORDS: [(&'static str, Realtime); 3] = [
        ("enforce", Realtime::Enforce),
        ("ignore", Realtime::Ignore),
        ("off", Realtime::Off),
    ];

    /// The setting named `word` (`enforce`, `ignore` or `off`).
    pub fn from_word(word: &str) -> Option<Realtime> {
        Self::WORDS
            .iter()
            .find(|(w, _)| *w == word)
            .map(|&(_, r)| r)
    }

    /// Its word.
    pub fn word(self) -> &'static str {
        Self::WORDS
            .iter()
            .find(|(_, r)| *r == self)
            .map_or("enforce", |(w, _)| w)
    }
}

/// Ticks kept free in the recording for a stop (2 s: a brake from full speed takes
/// 0.3 s on the FR3).
pub const BRAKE_RESERVE: usize = 2000;

/// How long a loop waits for the robot's next state before it ends the motion as a lost
/// connection: libfranka's UDP timeout (`Network`'s `udp_timeout`, 1 s). A real robot that
/// hears no command for 20 cycles stops by itself (`communication_constraints_violation`),
/// so waiting longer moves nothing; a shorter wait would end motions that libfranka's own
/// client carries on through a stall of the sender (a simulator descheduled on a busy
/// machine, a switch's hiccup).
pub const STATE_TIMEOUT: Duration = Duration::from_secs(1);

/// Settings of a motion.
#[derive(Debug, Clone, Copy)]
pub struct LoopOptions {
    /// Realtime scheduling of the loop thread.
    pub realtime: Realtime,
    /// A state later than this ends the motion as a lost connection (the robot stops by
    /// itself when commands stop: a real FCI after 20 missed cycles). [`STATE_TIMEOUT`] by
    /// default, as libfranka.
    pub state_timeout: Duration,
    /// Ticks the recording holds (264 bytes each, allocated before the motion); the loop
    /// starts braking [`BRAKE_RESERVE`] ticks before it is full, so the stop is recorded.
    pub max_ticks: usize,
}

impl Default for LoopOptions {
    fn default() -> Self {
        LoopOptions {
            realtime: Realtime::Enforce,
            state_timeout: STATE_TIMEOUT,
            max_ticks: 60_000 + BRAKE_RESERVE,
        }
    }
}

/// One recorded tick: what the robot measured and what cps commanded.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
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
    /// The lowest `control_command_success_rate` the robot reported during the motion
    /// (the share of the last 100 commands that reached it in time; 1.0 = all).
    pub success_rate_min: f64,
    /// Answers withheld: ones a newer state overtook (the robot had closed their cycle:
    /// they would have come late), and each cycle after a command the robot's state showed
    /// dropped, until the next state told whether the robot dropped it or (a simulator)
    /// applied it late.
    pub withheld: u64,
    /// The most robot periods between two states cps answered (1: none lost or skipped).
    pub longest_gap: u64,
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
    /// Commands changed before they were sent to keep a limit: joint commands the robot
    /// would not have accepted from its reference after a lost cycle, brought back onto
    /// the stream ([`cps_robot::Limiter`]); torques limited to the torque or its rate. With
    /// the largest change (rad; N m for torques).
    pub limited: Limited,
    /// What the robot's states said of the commands sent: cycles it extrapolated (or held
    /// its torques through), commands it dropped.
    pub reference: ReferenceCounts,
    /// The robot time (s, on the samples' clock) at which the generator's clock started:
    /// a joint motion holds its start until the robot shows it took a command of it
    /// ([`run_joint_positions`]); None if it never did. See
    /// [`MotionReport::sample_at_clock`].
    pub clock_start: Option<f64>,
}

/// What a motion's loop saw of the robot's cycles: the ones cps did not answer, the ones
/// the robot extrapolated, the commands it limited. Summed over motions with
/// [`Cycles::add`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cycles {
    /// States answered.
    pub answered: usize,
    /// Robot ticks whose state never reached cps.
    pub missed: u64,
    /// States superseded before cps read them (the newest was answered).
    pub stale: u64,
    /// Answers withheld (see [`Timing::withheld`]).
    pub withheld: u64,
    /// Cycles the robot extrapolated (or held its torques through): the missed and stale
    /// ones, and those whose command it dropped.
    pub extrapolated: u64,
    /// Commands the robot dropped (its next state showed its own extrapolation).
    pub dropped: u64,
    /// States whose reported reference agreed wholly with none of the tracker's candidates
    /// (see [`crate::reference::ReferenceTracker`]): on a robot that reports a usable
    /// reference, where a reference was taken from the state itself.
    pub unconfirmed: u64,
    /// Commands changed before they were sent to keep a limit.
    pub limited: usize,
    /// The largest such change (rad; N m for torques).
    pub largest_change: f64,
    /// The lowest share of commands the robot reported received in time (1.0 = all).
    pub success_rate_min: f64,
}

impl Cycles {
    /// Adds another motion's.
    pub fn add(&mut self, other: &Cycles) {
        self.answered += other.answered;
        self.missed += other.missed;
        self.stale += other.stale;
        self.withheld += other.withheld;
        self.extrapolated += other.extrapolated;
        self.dropped += other.dropped;
        self.unconfirmed += other.unconfirmed;
        self.limited += other.limited;
        self.largest_change = self.largest_change.max(other.largest_change);
        self.success_rate_min = self.success_rate_min.min(other.success_rate_min);
    }

    /// As a sentence: "3 cycles extrapolated by the robot (0 states missed, 2 stale, 1
    /// answer withheld as late, 0 commands dropped, 0 states unconfirmed); 12 commands
    /// limited (largest change 0.000041); lowest success rate 0.97".
    pub fn sentence(&self) -> String {
        format!(
            "{} cycles extrapolated by the robot ({} states missed, {} stale, {} answers withheld as late, {} commands dropped, {} states unconfirmed); {} commands limited (largest change {:.6}); lowest success rate {:.2}",
            self.extrapolated,
            self.missed,
            self.stale,
            self.withheld,
            self.dropped,
            self.unconfirmed,
            self.limited,
            self.largest_change,
            self.success_rate_min
        )
    }
}

impl Default for Cycles {
    fn default() -> Self {
        Cycles {
            answered: 0,
            missed: 0,
            stale: 0,
            withheld: 0,
            extrapolated: 0,
            dropped: 0,
            unconfirmed: 0,
            limited: 0,
            largest_change: 0.0,
            success_rate_min: 1.0,
        }
    }
}

impl MotionReport {
    /// The index of the sample that answered the generator's time `t` (s on its clock): the
    /// first at or after it (a state lost, the command for `t` went with the next one the
    /// loop answered); None past the recording's end or if the clock never started.
    pub fn sample_at_clock(&self, t: f64) -> Option<usize> {
        let at = self.clock_start? + t - 1e-9;
        let i = self.samples.partition_point(|s| s.t < at);
        (i < self.samples.len()).then_some(i)
    }

    /// What the loop saw of the robot's cycles.
    pub fn cycles(&self) -> Cycles {
        Cycles {
            answered: self.timing.ticks,
            missed: self.timing.missed,
            stale: self.timing.stale,
            withheld: self.timing.withheld,
            extrapolated: self.reference.extrapolated,
            dropped: self.reference.dropped,
            unconfirmed: self.reference.unconfirmed,
            limited: self.limited.commands,
            largest_change: self.limited.deviation,
            success_rate_min: self.timing.success_rate_min,
        }
    }
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
    if mode == Realtime::Off {
        return Ok(false);
    }
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
            Realtime::Ignore | Realtime::Off => Ok(false),
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

/// The commands of a recording as a robot that got each of them held them, one per
/// millisecond of its clock: every sample's command at its state's id, and for the ids
/// between two samples that got no command from cps (states missed, stale or withheld),
/// the robot's extrapolation of the commands before. What the robot judged each command
/// against: a stream the checks of [`crate::limits`] admit is one such a robot accepted.
pub fn as_held(samples: &[Sample]) -> Vec<[f64; JOINTS]> {
    let Some(first) = samples.first() else {
        return Vec::new();
    };
    let mut r = crate::reference::Reference::at_rest(first.q_c);
    let mut held = vec![first.q_c];
    for w in samples.windows(2) {
        for _ in w[0].id + 1..w[1].id {
            r = r.extrapolated(DT);
            held.push(r.q);
        }
        r = r.after(&w[1].q_c, DT);
        held.push(w[1].q_c);
    }
    held
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
/// time `t` once per robot period (a state that comes two periods after the last one
/// answered asks twice), on a dedicated thread; `t` counts from the first state that shows
/// the robot took a command of the motion in time (until then the motion holds where it
/// starts: a simulator may take a late first command for nothing and the next as the
/// motion's standstill); every command is judged by [`StreamCheck`](crate::limits::StreamCheck)
/// against the reference the robot holds ([`crate::reference`]): sent as it is, limited
/// back onto the stream where a lost cycle made it unacceptable ([`cps_robot::Limiter`]),
/// or replaced by a [`Brake`](crate::limits::Brake) from that reference. `stop` set by another thread (a signal
/// handler) brakes the robot to rest and ends the motion.
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
/// integrate to, so the same [`StreamCheck`](crate::limits::StreamCheck) holds them — velocity, acceleration, jerk, the
/// joint range and the distance a stop needs — and a [`Brake`](crate::limits::Brake) replaces any that would
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
/// limited to the arm's torque and, from the torques the robot applied last (the state's
/// `tau_J_d`), to 95 % of its torque rate (1000 N m/s) before it is sent — as libfranka's
/// rate limiter does — and the limited commands are counted ([`MotionReport::limited`]);
/// a torque that is not a number, or a joint measured faster than
/// [`TORQUE_SPEED_GUARD`] of its speed limit, switches
/// to a damped stop. `stop`
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

// Long on purpose (over 150 lines): the realtime loop, one tick read top to bottom (the
// state, its timing, the law, the send, the record) so that a reader sees in one place
// that nothing in it allocates, locks or logs.
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
    // Everything the loop needs, allocated now, and its pages touched now: a first touch
    // inside the loop is a page fault, which waits on the process's memory map, held at
    // times by threads of normal priority (a stall of milliseconds on a loaded machine).
    let mut samples: Vec<Sample> = cps_robot::prefaulted(options.max_ticks);
    let mut latency_ns: Vec<u32> = cps_robot::prefaulted(options.max_ticks);
    let mut command = Command::default();
    let (controller, generator) = law.modes();
    let motion_id = conn.start_move(controller, generator)?;

    let mut ending: Option<MotionEnd> = None;
    let (mut first_id, mut last_id) = (None::<u64>, None::<u64>);
    let (mut missed, mut stale) = (0u64, 0u64);
    let mut success_rate_min: f64 = 1.0;
    let mut withheld = 0u64;
    let mut longest_gap = 1u64;
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
        let mut periods = 1;
        if let Some(last) = last_id {
            if state.message_id <= last {
                continue; // a duplicate or reordered datagram: already answered
            }
            // Ticks between the last answered state and this one that never reached cps.
            missed += (state.message_id - last - 1).saturating_sub(u64::from(skipped));
            periods = state.message_id - last;
            longest_gap = longest_gap.max(periods);
        }
        last_id = Some(state.message_id);
        if state.control_command_success_rate > 0.0 {
            // Zero while the robot has not started the motion's loop yet.
            success_rate_min = success_rate_min.min(state.control_command_success_rate);
        }
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
        let Some(done) = law.answer(
            &state,
            t,
            (periods, skipped > 0),
            samples.len(),
            brake,
            &mut command,
        ) else {
            withheld += 1;
            continue;
        };
        command.message_id = state.message_id;
        if conn.state_waiting() {
            // The robot has closed this state's cycle already: the answer would come late
            // (dropped by a robot, applied late by a simulator). Not sent; the newer state
            // is answered instead.
            law.withdraw();
            withheld += 1;
            continue;
        }
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
    let outcome = law.outcome();
    let reason = outcome.reason;
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
        success_rate_min,
        withheld,
        longest_gap,
    };
    Ok(MotionReport {
        samples,
        timing,
        ending,
        peak_usage: outcome.peak,
        brake_ticks: outcome.brake_ticks,
        limited: outcome.limited,
        reference: outcome.reference,
        clock_start: outcome.clock_start,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(times_ms: &[u64], clock_start: Option<f64>) -> MotionReport {
        let sample = |&ms: &u64| Sample {
            t: ms as f64 * DT,
            id: 100 + ms,
            q: [0.0; JOINTS],
            dq: [0.0; JOINTS],
            tau: [0.0; JOINTS],
            q_c: [0.0; JOINTS],
            tau_c: [0.0; JOINTS],
            tool: [0.0; 3],
        };
        MotionReport {
            samples: times_ms.iter().map(sample).collect(),
            timing: Timing {
                ticks: times_ms.len(),
                median_us: 0.0,
                p99_us: 0.0,
                max_us: 0.0,
                missed: 0,
                stale: 0,
                realtime: false,
                success_rate_min: 1.0,
                withheld: 0,
                longest_gap: 1,
            },
            ending: MotionEnd::Finished,
            peak_usage: [[0.0; JOINTS]; 3],
            brake_ticks: 0,
            limited: Limited::default(),
            reference: ReferenceCounts::default(),
            clock_start,
        }
    }

    #[test]
    fn the_generators_time_finds_the_sample_that_answered_it() {
        // Opened at rest for 2 ms; the state of 4 ms was lost: its command went with 5 ms's.
        let r = report(&[0, 1, 2, 3, 5, 6], Some(2.0 * DT));
        let at = |ms: u64| r.sample_at_clock(ms as f64 * DT);
        assert_eq!(at(0), Some(2));
        assert_eq!(at(1), Some(3));
        assert_eq!(at(2), Some(4));
        assert_eq!(at(3), Some(4));
        assert_eq!(at(4), Some(5));
        assert_eq!(at(5), None);
        assert_eq!(report(&[0, 1], None).sample_at_clock(0.0), None);
    }
}
