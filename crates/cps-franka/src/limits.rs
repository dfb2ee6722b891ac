//! Franka's per-millisecond limits on commanded joint motion, one checker for them used
//! both before a motion (over the whole stream) and while streaming (every tick), and a
//! braking generator that stops any commanded motion within them.
//!
//! The robot differentiates the commanded positions `q_c` once per millisecond: velocity
//! `(q_k − q_{k−1})/Δt`, acceleration and jerk likewise, starting at rest. A command whose
//! derivatives pass a limit ends the motion in a reflex (`joint_motion_generator_velocity_
//! limits_violation`, `…_acceleration_discontinuity`, …). [`StreamCheck`] takes exactly
//! those differences; a stream it admits sample by sample is one the robot accepts.
//!
//! Values: Franka's published joint limits ("Robot and interface specifications"): the
//! Panda's constant table, and the FR3's, whose velocity limit shrinks near the ends of the
//! range (`min(v_max, max(0, −c + sqrt(k (q_end − q))))`, matching the FR3's published
//! "rectangular" velocity table at that table's position bounds). cps evaluates the FR3's
//! curve at the published range itself rather than the slightly wider constants libfranka
//! uses, so it is a little stricter than the robot.

use cps_kinematics::{Quantity, StreamBounds};
use cps_robot::{Breach, Limit};

use crate::wire::JOINTS;

/// Which Franka arm, for its limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arm {
    /// Franka Research 3 (system 5.9+ speaks protocol 10).
    Fr3,
    /// Franka Emika Panda (FER).
    Panda,
}

impl Arm {
    /// `fr3` or `panda`.
    pub fn name(self) -> &'static str {
        match self {
            Arm::Fr3 => "fr3",
            Arm::Panda => "panda",
        }
    }

    /// Every arm, in the order of its names.
    pub const ALL: [Arm; 2] = [Arm::Fr3, Arm::Panda];

    /// The arm named `fr3` or `panda` (or `fer`, the Panda's name since the FR3).
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "fr3" => Some(Arm::Fr3),
            "panda" | "fer" => Some(Arm::Panda),
            _ => None,
        }
    }
}

/// The command period of the FCI (s).
pub const DT: f64 = 1e-3;

/// One arm's limits on the commanded joint signal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateLimits {
    /// The arm.
    pub arm: Arm,
    /// Lower joint bounds (rad).
    pub q_min: [f64; JOINTS],
    /// Upper joint bounds (rad).
    pub q_max: [f64; JOINTS],
    /// Largest speed anywhere in the range (rad/s).
    pub dq_max: [f64; JOINTS],
    /// Acceleration (rad/s²).
    pub ddq_max: [f64; JOINTS],
    /// Jerk (rad/s³).
    pub dddq_max: [f64; JOINTS],
    /// Torque (N m).
    pub tau_max: [f64; JOINTS],
    /// Torque rate (N m/s).
    pub dtau_max: [f64; JOINTS],
    /// FR3: the velocity curve's offset `c` and gain `k` per joint (None for the Panda).
    curve: Option<([f64; JOINTS], [f64; JOINTS])>,
}

impl RateLimits {
    /// The limits of `arm`.
    pub fn of(arm: Arm) -> Self {
        match arm {
            Arm::Fr3 => RateLimits {
                arm,
                q_min: cps_kinematics::robots::FR3_Q_MIN,
                q_max: cps_kinematics::robots::FR3_Q_MAX,
                dq_max: cps_kinematics::robots::FR3_DQ_MAX,
                ddq_max: [10.0; JOINTS],
                dddq_max: [5000.0; JOINTS],
                tau_max: [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0],
                dtau_max: [1000.0; JOINTS],
                curve: Some((
                    [0.30, 0.20, 0.20, 0.30, 0.35, 0.35, 0.35],
                    [12.0, 5.17, 7.0, 8.0, 34.0, 11.0, 34.0],
                )),
            },
            Arm::Panda => RateLimits {
                arm,
                q_min: cps_kinematics::robots::PANDA_Q_MIN,
                q_max: cps_kinematics::robots::PANDA_Q_MAX,
                dq_max: cps_kinematics::robots::PANDA_DQ_MAX,
                ddq_max: [15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0],
                dddq_max: [7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0],
                tau_max: [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0],
                dtau_max: [1000.0; JOINTS],
                curve: None,
            },
        }
    }

    /// The velocity bounds `(lower, upper)` of joint `i` at position `q` (rad/s).
    #[inline]
    pub fn velocity_bounds(&self, i: usize, q: f64) -> (f64, f64) {
        match self.curve {
            None => (-self.dq_max[i], self.dq_max[i]),
            Some((c, k)) => {
                let side = |room: f64| {
                    (-c[i] + (k[i] * room.max(0.0)).sqrt())
                        .max(0.0)
                        .min(self.dq_max[i])
                };
                (-side(q - self.q_min[i]), side(self.q_max[i] - q))
            }
        }
    }

    /// The same limits scaled by `factor` (0 < factor ≤ 1) on velocity, acceleration and
    /// jerk: what a planner aims at so that rounding never reaches the robot's limits.
    pub fn scaled(&self, factor: f64) -> Self {
        let mut s = *self;
        for i in 0..JOINTS {
            s.dq_max[i] *= factor;
            s.ddq_max[i] *= factor;
            s.dddq_max[i] *= factor;
        }
        s
    }
}

/// The rule beyond the contract's joint limits that the 1 kHz loop keeps: where a stop
/// begun at this command would end (worded after it: "… would end at 2.9 rad, beyond the
/// limit 2.8 rad").
pub const STOPPING_RULE: &str = "a stop from this speed would end at";

/// The contract's [`Breach`] of `quantity` at joint `joint` (1-based) by command `command`
/// of a 1 kHz stream (a `value` that is not a number is worded as such): made without
/// allocating, so the realtime loop can build it.
#[inline]
pub fn joint_breach(
    joint: usize,
    quantity: Quantity,
    command: usize,
    value: f64,
    bound: f64,
) -> Breach {
    Breach {
        limit: Limit::Joint { joint, quantity },
        time: command as f64 * DT,
        command,
        value,
        bound,
    }
}

/// Joint `joint`'s (1-based) limit of `quantity`, as the contract names it.
pub fn joint_limit(joint: usize, quantity: Quantity) -> Limit {
    Limit::Joint { joint, quantity }
}

/// The Franka's rules on its commanded joint signal, for the one limit checker
/// ([`cps_kinematics::StreamCheck`]): its range, its speeds (the FR3's shrinking near the
/// ends of the range), accelerations and jerks, refused at any excess, and its extension:
/// where a stop begun at a command would end ([`STOPPING_RULE`]), which must be inside the
/// range. Torques are the robot's own in joint-position control.
impl StreamBounds for RateLimits {
    fn range(&self, joint: usize) -> Option<(f64, f64)> {
        Some((self.q_min[joint], self.q_max[joint]))
    }

    fn velocity(&self, joint: usize, q: f64) -> Option<(f64, f64)> {
        Some(self.velocity_bounds(joint, q))
    }

    fn acceleration(&self, joint: usize) -> Option<f64> {
        Some(self.ddq_max[joint])
    }

    fn jerk(&self, joint: usize) -> Option<f64> {
        Some(self.dddq_max[joint])
    }

    fn rule(&self, i: usize, q: f64, v: f64) -> Option<(&'static str, f64, f64)> {
        // Where a full stop from here would end: the acceleration ramps to its limit at
        // full jerk (ddq/dddq seconds), then brakes at the limit.
        let ramp = self.ddq_max[i] / self.dddq_max[i];
        let stop = q + v * ramp + v * v.abs() / (2.0 * self.ddq_max[i]);
        if stop > self.q_max[i] + 1e-9 {
            Some((STOPPING_RULE, stop, self.q_max[i]))
        } else if stop < self.q_min[i] - 1e-9 {
            Some((STOPPING_RULE, stop, self.q_min[i]))
        } else {
            None
        }
    }
}

/// The derivatives of a commanded joint stream, checked command by command as the robot
/// takes them: the one limit checker with the Franka's rules. No allocation: it lives in
/// the realtime loop.
pub type StreamCheck = cps_kinematics::StreamCheck<[f64; JOINTS], RateLimits>;

/// A check of a stream that starts with the robot at rest at `q0`, one command per
/// millisecond.
pub fn stream_check(limits: RateLimits, q0: [f64; JOINTS]) -> StreamCheck {
    StreamCheck::at_rest(limits, q0, DT)
}

/// Checks a whole stream of commands (one per millisecond) starting at rest at `q0`, then
/// held at its last command for a few periods (so stopping is checked too). Returns the
/// check with its peak usage, or the first breach.
pub fn check_stream(
    limits: RateLimits,
    q0: [f64; JOINTS],
    stream: &[[f64; JOINTS]],
) -> Result<StreamCheck, Breach> {
    let mut c = stream_check(limits, q0);
    let held = stream.last().into_iter().flat_map(|last| [last; 3]);
    for q in stream.iter().chain(held) {
        c.admit(q).map_err(Breach::from)?;
    }
    Ok(c)
}

/// The share of each limit the brake uses.
const BRAKE_MARGIN: f64 = 0.99;

/// Brings a commanded motion to rest within the limits: every joint decelerates along a
/// braking curve (acceleration `−sign(v)·min(a_max, sqrt(2 j_max |v|))`, reached at most
/// at full jerk), never faster than the FR3's position-dependent velocity bound allows,
/// and lands exactly at rest. No allocation.
#[derive(Debug, Clone, Copy)]
pub struct Brake {
    limits: RateLimits,
    q: [f64; JOINTS],
    v: [f64; JOINTS],
    a: [f64; JOINTS],
}

impl Brake {
    /// A brake from the last command's position, velocity and acceleration.
    pub fn new(limits: RateLimits, q: [f64; JOINTS], v: [f64; JOINTS], a: [f64; JOINTS]) -> Self {
        Brake { limits, q, v, a }
    }

    /// A brake from where a [`StreamCheck`] last admitted a command.
    pub fn from_check(check: &StreamCheck) -> Self {
        let (q, v, a) = check.last();
        Brake::new(*check.bounds(), *q, *v, *a)
    }

    /// Whether every joint is at rest.
    pub fn stopped(&self) -> bool {
        self.v.iter().chain(&self.a).all(|x| *x == 0.0)
    }

    /// The next command (one period later).
    pub fn step(&mut self) -> [f64; JOINTS] {
        // 1 % below every limit, so that the robot's differences of the rounded positions
        // never reach one.
        let l = &self.limits.scaled(BRAKE_MARGIN);
        for i in 0..JOINTS {
            let (v, a) = (self.v[i], self.a[i]);
            let jdt = l.dddq_max[i] * DT;
            if v == 0.0 && a == 0.0 {
                continue;
            }
            // Land at rest this period, and zero acceleration the next, if both steps keep
            // the jerk limit.
            let land = -v / DT;
            if (land - a).abs() <= jdt && land.abs() <= jdt && land.abs() <= l.ddq_max[i] {
                self.a[i] = land;
                self.v[i] = 0.0;
                continue;
            }
            if v == 0.0 && a.abs() <= jdt {
                self.a[i] = 0.0;
                continue;
            }
            // The braking curve's acceleration, reached at most at full jerk.
            let target = -v.signum() * l.ddq_max[i].min((2.0 * l.dddq_max[i] * v.abs()).sqrt());
            let mut next = target
                .clamp(a - jdt, a + jdt)
                .clamp(-l.ddq_max[i], l.ddq_max[i]);
            // Never let the speed pass the position-dependent bound.
            let (lo, hi) = self
                .limits
                .velocity_bounds(i, self.q[i] + (v + next * DT) * DT);
            let (lo, hi) = (lo * BRAKE_MARGIN, hi * BRAKE_MARGIN);
            let lo_a = ((lo - v) / DT).max(a - jdt).max(-l.ddq_max[i]);
            let hi_a = ((hi - v) / DT).min(a + jdt).min(l.ddq_max[i]);
            if lo_a <= hi_a {
                next = next.clamp(lo_a, hi_a);
            }
            self.a[i] = next;
            self.v[i] = v + next * DT;
        }
        for i in 0..JOINTS {
            self.q[i] += self.v[i] * DT;
        }
        self.q
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn fr3_curve_meets_the_published_rectangular_table() {
        // Franka's "rectangular" FR3 limits: these velocities hold within these bounds.
        let upper = [2.3093, 1.5133, 2.4937, -0.4461, 2.4800, 4.2094, 2.6895];
        let speed = [2.0, 1.0, 1.5, 1.25, 3.0, 1.5, 3.0];
        let l = RateLimits::of(Arm::Fr3);
        for i in 0..JOINTS {
            let (_, hi) = l.velocity_bounds(i, upper[i]);
            // cps evaluates the curve at the published range, a few mrad inside
            // libfranka's constants: at most 2 % below the table, never above it.
            assert!(
                hi <= speed[i] && hi > 0.98 * speed[i],
                "joint {}: {hi}",
                i + 1
            );
        }
        assert_eq!(l.velocity_bounds(0, 0.0), (-2.62, 2.62));
        assert_eq!(l.velocity_bounds(0, 2.7437).1, 0.0);
    }

    #[test]
    fn a_step_is_refused_naming_joint_time_and_quantity() {
        let l = RateLimits::of(Arm::Fr3);
        let q0 = [0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0];
        let mut stream = vec![q0; 100];
        for q in &mut stream[50..] {
            q[3] += 0.01;
        }
        let b = check_stream(l, q0, &stream).unwrap_err();
        assert_eq!(
            (b.limit, b.command),
            (joint_limit(4, Quantity::Velocity), 50)
        );
        assert_eq!(
            b.to_string(),
            "joint 4 at t = 0.050 s (command 50): velocity 10.000000 rad/s beyond the limit 2.620000 rad/s"
        );
        // A small step passes velocity but not acceleration.
        let mut small = vec![q0; 10];
        small[5][0] += 1e-4;
        assert_eq!(
            check_stream(l, q0, &small).unwrap_err().limit,
            joint_limit(1, Quantity::Acceleration)
        );
        let mut nan = vec![q0; 3];
        nan[2][6] = f64::NAN;
        let b = check_stream(l, q0, &nan).unwrap_err();
        assert!(b.value.is_nan(), "{b:?}");
        assert_eq!(
            b.to_string(),
            "joint 7 at t = 0.002 s (command 2): the commanded position is not a number"
        );
    }

    #[test]
    fn the_brake_stops_any_admissible_motion_within_every_limit() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for arm in [Arm::Fr3, Arm::Panda] {
            let l = RateLimits::of(arm);
            for case in 0..300 {
                // Accelerate with random bounded jerk for a while, as a stream the check admits.
                let mut q = [0.0, 0.0, 0.0, -1.6, 0.0, 2.0, 0.0];
                let mut check = stream_check(l, q);
                let (mut v, mut a) = ([0.0; JOINTS], [0.0; JOINTS]);
                let steps = rng.random_range(1..400);
                for _ in 0..steps {
                    let mut next = q;
                    for i in 0..JOINTS {
                        let j = rng.random_range(-0.9..0.9) * l.dddq_max[i];
                        let na = (a[i] + j * DT).clamp(-0.9 * l.ddq_max[i], 0.9 * l.ddq_max[i]);
                        let nv = (v[i] + na * DT).clamp(-0.5 * l.dq_max[i], 0.5 * l.dq_max[i]);
                        next[i] = q[i] + nv * DT;
                    }
                    if check.admit(&next).is_err() {
                        break;
                    }
                    let (lq, lv, la) = check.last();
                    (q, v, a) = (*lq, *lv, *la);
                }
                let mut brake = Brake::from_check(&check);
                let mut n = 0;
                while !brake.stopped() {
                    let cmd = brake.step();
                    check.admit(&cmd).unwrap_or_else(|b| {
                        panic!("{arm:?} case {case}, brake step {n}: {}", Breach::from(b))
                    });
                    n += 1;
                    assert!(n < 2000, "{arm:?} case {case}: no rest after 2 s");
                }
                // At rest: holding the last command is admissible forever.
                let last = *check.last().0;
                check.admit(&last).unwrap();
                assert!(check.at_rest_now(), "{arm:?} case {case}");
            }
        }
    }
}
