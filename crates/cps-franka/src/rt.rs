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
use crate::limits::{Brake, Breach, DT, RateLimits, StreamCheck};
use crate::session::Connection;
use crate::wire::{
    Command, ControllerMode, JOINTS, MotionGeneratorMode, MoveStatus, RobotMode, RobotState,
};

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
    /// Ticks the recording holds (256 bytes each, allocated before the motion); the loop
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
    /// Measured joint positions.
    pub q: [f64; JOINTS],
    /// Measured joint velocities.
    pub dq: [f64; JOINTS],
    /// Measured joint torques.
    pub tau: [f64; JOINTS],
    /// The commanded joint positions sent at this tick.
    pub q_c: [f64; JOINTS],
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

/// How a motion ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
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

impl Ending {
    /// Whether the motion ran to its end as planned.
    pub fn complete(&self) -> bool {
        matches!(self, Ending::Finished)
    }

    /// The ending as a sentence.
    pub fn sentence(&self) -> String {
        match self {
            Ending::Finished => "the motion finished".into(),
            Ending::Stopped => "stopped on request: braked to rest within the limits".into(),
            Ending::LimitBrake(b) => {
                format!("a command beyond a limit was not sent ({b}); braked to rest")
            }
            Ending::RecordingFull => "the recording was full: braked to rest".into(),
            Ending::Robot { status, errors } => format!(
                "the robot ended the motion: {} (errors: {errors})",
                status.sentence()
            ),
            Ending::Lost(r) => format!("the connection was lost: {r}"),
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
    pub ending: Ending,
    /// Peak usage of velocity, acceleration and jerk per joint of every command sent
    /// (1.0 = at the published limit).
    pub peak_usage: [[f64; JOINTS]; 3],
    /// Ticks spent braking.
    pub brake_ticks: usize,
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
/// a [`MotionReport`] whose [`Ending`] says how, with every sample recorded.
pub fn run_joint_positions<F>(
    conn: &mut Connection,
    limits: RateLimits,
    options: &LoopOptions,
    stop: &AtomicBool,
    control: F,
) -> Result<MotionReport, FrankaError>
where
    F: FnMut(&RobotState, f64) -> JointPositions + Send,
{
    std::thread::scope(|scope| {
        scope
            .spawn(move || joint_position_loop(conn, limits, options, stop, control))
            .join()
            .unwrap_or_else(|_| {
                Err(FrankaError::Input(
                    "the control loop's thread panicked".into(),
                ))
            })
    })
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

fn joint_position_loop<F>(
    conn: &mut Connection,
    limits: RateLimits,
    options: &LoopOptions,
    stop: &AtomicBool,
    mut control: F,
) -> Result<MotionReport, FrankaError>
where
    F: FnMut(&RobotState, f64) -> JointPositions,
{
    let realtime = make_realtime(options.realtime)?;
    let (state, _) = conn.newest_state(options.state_timeout.max(Duration::from_millis(500)))?;
    conn.ensure_ready(&state)?;
    let q0 = start_position(&state);
    // Everything the loop needs, allocated now.
    let mut samples: Vec<Sample> = Vec::with_capacity(options.max_ticks);
    let mut latency_ns: Vec<u32> = Vec::with_capacity(options.max_ticks);
    let mut check = StreamCheck::at_rest(limits, q0);
    let mut command = Command::default();
    let motion_id = conn.start_move(
        ControllerMode::JointImpedance,
        MotionGeneratorMode::JointPosition,
    )?;

    let mut mode = Mode::Follow;
    let mut ending: Option<Ending> = None;
    let mut brake_reason: Option<Ending> = None;
    let (mut first_id, mut last_id) = (None::<u64>, None::<u64>);
    let (mut missed, mut stale, mut brake_ticks) = (0u64, 0u64, 0usize);
    let mut last_errors = String::new();
    let mut finished_sent = false;
    loop {
        let (state, skipped) = match conn.newest_state(options.state_timeout) {
            Ok(s) => s,
            Err(e) => {
                ending = Some(Ending::Lost(e.to_string()));
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
        if matches!(mode, Mode::Follow) {
            if stop.load(Ordering::Relaxed) {
                brake_reason = Some(Ending::Stopped);
            } else if samples.len() + BRAKE_RESERVE >= options.max_ticks {
                brake_reason = Some(Ending::RecordingFull);
            }
            if brake_reason.is_some() {
                mode = Mode::Brake(Brake::from_check(&check));
            }
        }
        let (desired, finished) = match &mut mode {
            Mode::Follow => {
                let step = control(&state, t);
                (step.q, step.finished)
            }
            Mode::Hold(q) => (*q, true),
            Mode::Brake(b) => {
                brake_ticks += 1;
                let q = b.step();
                (q, b.stopped())
            }
        };
        let (q_c, mut done) = match check.admit(&desired) {
            Ok(()) => (desired, finished),
            Err(breach) => {
                // Never sent: brake from the last admitted command instead.
                let mut b = Brake::from_check(&check);
                let q = b.step();
                let stopped = b.stopped();
                if check.admit(&q).is_err() {
                    // Cannot happen for a brake from an admitted state (tested); hold.
                    let (last, _, _) = check.last();
                    brake_reason.get_or_insert(Ending::LimitBrake(breach));
                    mode = Mode::Brake(b);
                    (last, false)
                } else {
                    brake_reason.get_or_insert(Ending::LimitBrake(breach));
                    mode = Mode::Brake(b);
                    (q, stopped)
                }
            }
        };
        if done && !check.at_rest_now() {
            // Not at rest yet: hold the last command (or keep braking) until it is.
            if matches!(mode, Mode::Follow) {
                mode = Mode::Hold(q_c);
            }
            done = false;
        }
        command.message_id = state.message_id;
        command.q_c = q_c;
        command.motion_generation_finished = done;
        if let Err(e) = conn.send_command(&command) {
            ending = Some(Ending::Lost(e.to_string()));
            break;
        }
        let ns = t_in.elapsed().as_nanos().min(u128::from(u32::MAX)) as u32;
        if latency_ns.len() < latency_ns.capacity() {
            latency_ns.push(ns);
        }
        if samples.len() < samples.capacity() {
            samples.push(Sample {
                t,
                q: state.q,
                dq: state.dq,
                tau: state.tau_j,
                q_c,
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
                    ending = Some(Ending::Robot {
                        status,
                        errors: state.errors.describe(),
                    });
                    break;
                }
                Err(e) => {
                    ending = Some(Ending::Lost(e.to_string()));
                    break;
                }
            }
        }
    }
    // After the loop: the robot's word on how the motion ended (bounded).
    let ending = match ending {
        Some(e) => e,
        None => match conn.await_move_end(motion_id, Duration::from_secs(2)) {
            Ok(MoveStatus::Success) if finished_sent => brake_reason.unwrap_or(Ending::Finished),
            Ok(status) => Ending::Robot {
                status,
                errors: if last_errors.is_empty() {
                    "none".into()
                } else {
                    last_errors
                },
            },
            Err(e) => Ending::Lost(e.to_string()),
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
        peak_usage: check.peak_usage(),
        brake_ticks,
    })
}
