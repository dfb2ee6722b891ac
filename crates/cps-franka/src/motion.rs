//! Joint trajectories for the robot: a stream of commands at 1 kHz checked whole before
//! the motion, the approach move to its start, and executing it with a recording.

use std::sync::atomic::AtomicBool;

pub use cps_robot::START_TOLERANCE;
use cps_robot::rest_to_rest;

use crate::error::FrankaError;
use crate::limits::{DT, RateLimits, StreamCheck, check_stream, joint_breach};
use crate::rt::{JointPositions, LoopOptions, MotionReport, run_joint_positions, start_position};
use crate::session::Connection;
use crate::wire::JOINTS;
use cps_kinematics::Quantity;
use cps_robot::Breach;

/// A rest-to-rest move from `from` to `to` along a straight line in joint space, at
/// `fraction` (0 < f ≤ 1) of every joint's velocity (its slowest bound along the line, on
/// the FR3's position-dependent curve), acceleration and jerk limit: cps-robot's
/// [`rest_to_rest`] profile, sampled every millisecond (the first sample one period after
/// `from`, the last exactly `to`).
pub fn approach(
    limits: &RateLimits,
    from: [f64; JOINTS],
    to: [f64; JOINTS],
    fraction: f64,
) -> Vec<[f64; JOINTS]> {
    let profile = rest_to_rest(
        &from,
        &to,
        |i| {
            [
                Some((fraction * slowest_bound(limits, from, to, i)).max(1e-3)),
                Some(fraction * limits.ddq_max[i]),
                Some(fraction * limits.dddq_max[i]),
            ]
        },
        DT,
    );
    profile[1..]
        .iter()
        .map(|q| <[f64; JOINTS]>::try_from(q.as_slice()).expect("seven joints"))
        .collect()
}

/// The smallest speed bound of joint `i` anywhere on the straight line from `from` to `to`
/// (the FR3's velocity curve is lowest near the range's ends; sampled, never above dq_max).
fn slowest_bound(limits: &RateLimits, from: [f64; JOINTS], to: [f64; JOINTS], i: usize) -> f64 {
    let mut vmax = limits.dq_max[i];
    for k in 0..=32 {
        let q = from[i] + (to[i] - from[i]) * k as f64 / 32.0;
        let (lo, hi) = limits.velocity_bounds(i, q);
        vmax = vmax.min(hi).min(-lo);
    }
    vmax
}

/// The slowest an approach may be limited to on any joint (rad/s): closer to a range's end
/// than this allows, the FR3 permits almost no speed and the move would take minutes.
const SLOWEST_APPROACH: f64 = 0.05;

/// How a stream that does not start where the robot is gets there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start {
    /// Refuse it, naming the distance.
    Refuse,
    /// Prepend an [`approach`] at this fraction of the limits.
    Approach(f64),
}

/// A command stream checked against the robot's limits from where the robot is.
#[derive(Debug, Clone)]
pub struct CheckedStream {
    /// Commands, one per millisecond: the approach (if any) then the trajectory.
    pub commands: Vec<[f64; JOINTS]>,
    /// How many of them are the approach.
    pub approach: usize,
    /// Where the robot was when it was checked.
    pub from: [f64; JOINTS],
    /// The check's peak usage (velocity, acceleration, jerk; 1.0 = at the limit).
    pub peak_usage: [[f64; JOINTS]; 3],
}

/// Checks a trajectory of commands at 1 kHz for a robot at rest at `from`; prepends an
/// approach when asked. Nothing is sent: a breach is returned naming joint, time and
/// quantity.
pub fn check_trajectory(
    limits: &RateLimits,
    from: [f64; JOINTS],
    trajectory: &[[f64; JOINTS]],
    start: Start,
) -> Result<CheckedStream, FrankaError> {
    let Some(first) = trajectory.first() else {
        return Err(FrankaError::Input("the trajectory has no samples".into()));
    };
    // Every sample inside the arm's range, before anything else is computed.
    for (k, q) in trajectory.iter().enumerate() {
        for (i, &x) in q.iter().enumerate() {
            let (lo, hi) = (limits.q_min[i], limits.q_max[i]);
            if !x.is_finite() || x < lo || x > hi {
                return Err(FrankaError::Limit(joint_breach(
                    i + 1,
                    Quantity::Position,
                    k,
                    x,
                    if x < lo { lo } else { hi },
                )));
            }
        }
    }
    let (joint, gap) = (0..JOINTS)
        .map(|i| (i, (first[i] - from[i]).abs()))
        .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    let mut commands = Vec::new();
    if gap > START_TOLERANCE || gap.is_nan() {
        match start {
            Start::Refuse => {
                return Err(FrankaError::Input(format!(
                    "the trajectory starts {gap:.4} rad from where the robot is at joint {} (robot {:.4}, trajectory {:.4}); pass --approach to move there first",
                    joint + 1,
                    from[joint],
                    first[joint]
                )));
            }
            Start::Approach(f) => {
                if let Some(i) = (0..JOINTS).find(|&i| {
                    first[i] != from[i] && slowest_bound(limits, from, *first, i) < SLOWEST_APPROACH
                }) {
                    return Err(FrankaError::Input(format!(
                        "joint {} would approach {:.4} rad, so close to the end of its range that the {} allows it almost no speed there; start the trajectory further inside the range",
                        i + 1,
                        first[i],
                        limits.arm.name()
                    )));
                }
                commands = approach(limits, from, *first, f)
            }
        }
    } else if gap > 0.0 {
        // Within the tolerance: blend into the trajectory's start.
        commands = approach(limits, from, *first, 0.5);
    }
    let approach_len = commands.len();
    commands.extend_from_slice(trajectory);
    let check: StreamCheck = check_stream(*limits, from, &commands).map_err(|b: Breach| {
        if b.command >= approach_len {
            let command = b.command - approach_len;
            FrankaError::Limit(Breach {
                command,
                time: command as f64 * DT,
                ..b
            })
        } else {
            FrankaError::Input(format!("the approach move breaks a limit: {b}"))
        }
    })?;
    Ok(CheckedStream {
        commands,
        approach: approach_len,
        from,
        peak_usage: *check.peak_usage(),
    })
}

/// Executes a checked stream: one command per answered tick, on the realtime loop.
/// The robot must still be where the stream was checked from (within 1 µrad), else
/// nothing moves.
pub fn execute_stream(
    conn: &mut Connection,
    limits: RateLimits,
    stream: &CheckedStream,
    options: &LoopOptions,
    stop: &AtomicBool,
) -> Result<MotionReport, FrankaError> {
    let state = conn.read_state()?;
    let now = start_position(&state);
    // The loop checks the first command against where the robot is then: a robot that
    // moved by more than a micro-radian would make it a jump (1 rad/s² at 1 urad).
    if (0..JOINTS).any(|i| (now[i] - stream.from[i]).abs() > 1e-6) {
        return Err(FrankaError::Input(
            "the robot moved since the trajectory was checked; check it again".into(),
        ));
    }
    let commands = &stream.commands;
    let mut k = 0usize;
    let mut options = *options;
    // The stream, a few held commands, and room for a stop.
    options.max_ticks = commands.len() + 10 + crate::rt::BRAKE_RESERVE;
    run_joint_positions(conn, limits, &options, stop, move |_, _| {
        let q = commands[k.min(commands.len() - 1)];
        k += 1;
        JointPositions {
            q,
            finished: k >= commands.len(),
        }
    })
}

/// Records the robot's state at its rate for `duration` without moving it (a robot being
/// guided by hand in Desk's guiding mode, or at rest): one sample per state, `q_c` the
/// robot's desired position. Ends early when `stop` is set; a lost connection ends it
/// with the samples so far and the reason.
pub fn record_states(
    conn: &mut Connection,
    duration: std::time::Duration,
    stop: &AtomicBool,
) -> Result<(Vec<crate::Sample>, Option<String>), FrankaError> {
    let first = conn.read_state()?;
    let ticks = (duration.as_secs_f64() / DT).ceil() as usize;
    let mut samples = Vec::with_capacity(ticks + 1);
    let mut state = first;
    loop {
        let t = (state.message_id - first.message_id) as f64 * DT;
        if t > duration.as_secs_f64() + 1e-9 {
            break;
        }
        samples.push(crate::Sample {
            t,
            id: state.message_id,
            q: state.q,
            dq: state.dq,
            tau: state.tau_j,
            q_c: state.q_d,
            tau_c: [0.0; JOINTS],
            tool: state.tool_position(),
        });
        if stop.load(std::sync::atomic::Ordering::Relaxed) {
            break;
        }
        match conn.newest_state(crate::rt::STATE_TIMEOUT) {
            Ok((s, _)) if s.message_id > state.message_id => state = s,
            Ok(_) => {}
            Err(e) => return Ok((samples, Some(e.to_string()))),
        }
    }
    Ok((samples, None))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::Arm;

    #[test]
    fn approaches_keep_every_limit_and_end_at_the_target() {
        for arm in [Arm::Fr3, Arm::Panda] {
            let l = RateLimits::of(arm);
            let from = [0.0, -0.5, 0.0, -2.0, 0.0, 1.8, 0.7];
            let to = [1.0, 0.3, -0.4, -1.2, 0.5, 2.2, -0.5];
            for f in [0.1, 0.5, 1.0] {
                let a = approach(&l, from, to, f);
                assert_eq!(*a.last().unwrap(), to);
                let c = check_stream(l, from, &a).unwrap_or_else(|b| panic!("{arm:?} {f}: {b}"));
                let peak = c.peak_usage().iter().flatten().copied().fold(0.0, f64::max);
                assert!(
                    peak <= f * 1.001 + 1e-9,
                    "{arm:?} at {f}: peak usage {peak}"
                );
            }
        }
    }

    #[test]
    fn a_distant_start_is_refused_or_approached() {
        let l = RateLimits::of(Arm::Fr3);
        let from = [0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785];
        let mut traj = vec![from; 50];
        for q in &mut traj {
            q[1] += 0.2;
        }
        let e = check_trajectory(&l, from, &traj, Start::Refuse).unwrap_err();
        assert!(
            e.to_string()
                .contains("starts 0.2000 rad from where the robot is at joint 2"),
            "{e}"
        );
        let s = check_trajectory(&l, from, &traj, Start::Approach(0.2)).unwrap();
        assert!(s.approach > 100 && s.commands.len() == s.approach + 50);
        // A Panda trajectory at the Panda's joint-4 bound is outside the FR3's range.
        let mut panda = from;
        panda[3] = -0.0698;
        let e = check_trajectory(&l, from, &[panda], Start::Approach(0.2)).unwrap_err();
        assert!(
            matches!(e, FrankaError::Limit(b) if b.limit == crate::limits::joint_limit(4, Quantity::Position)),
            "{e}"
        );
        // A start a hair inside the FR3's range end, where it allows no speed: refused.
        let mut edge = from;
        edge[0] = 2.7437 - 1e-4;
        let e = check_trajectory(&l, from, &[edge], Start::Approach(0.2)).unwrap_err();
        assert!(
            e.to_string().contains("joint 1 would approach 2.7436 rad"),
            "{e}"
        );
    }
}
