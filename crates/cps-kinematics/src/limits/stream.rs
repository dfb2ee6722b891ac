//! The one limit checker: commands judged one at a time, as the robot receives them.
//!
//! Each command is differenced against the one before it (backward differences over the
//! period, from rest at the start): velocity, acceleration and jerk, and each joint's
//! position, velocity, acceleration and jerk are held to a robot's [`StreamBounds`] —
//! velocity bounds that may depend on the position (the FR3's), and a robot's own rule
//! beyond these (the Franka's distance to stop inside its range) as an extension. Torques
//! (by inverse dynamics, where a robot has inertias) are [`TorqueCheck`]'s, which follows
//! the same commands.
//!
//! [`StreamCheck::admit`] refuses a command that breaks a limit and keeps its state (what
//! the guard, the chunk executor and the Franka's 1 kHz loop do); [`StreamCheck::measure`]
//! moves on whatever the command, and shows every value with its bound (what a plan's
//! check, [`crate::check_joint_trajectory`], does to report every run beyond a limit).
//! The state can be set to the reference a robot holds ([`StreamCheck::rebase`]: after a
//! lost period, the robot's extrapolation). Nothing allocates after construction: the
//! state is held in `S`, a `Vec<f64>` for a robot of any size or an array for a fixed one.

use super::{POSITION_TOLERANCE, Quantity};

/// Storage for one value per joint: a `Vec<f64>` or an array.
pub trait Joints: AsRef<[f64]> + AsMut<[f64]> + Clone + std::fmt::Debug {}

impl Joints for Vec<f64> {}

impl<const N: usize> Joints for [f64; N] {}

/// The bounds a stream of joint commands is held to, per joint (`joint` 0-based). `None`
/// where a robot has no such limit.
pub trait StreamBounds {
    /// The position range `(lower, upper)`.
    fn range(&self, joint: usize) -> Option<(f64, f64)>;
    /// The velocity bounds `(lower, upper)` at position `q` (a robot's may shrink near the
    /// ends of its range).
    fn velocity(&self, joint: usize, q: f64) -> Option<(f64, f64)>;
    /// The acceleration limit (symmetric).
    fn acceleration(&self, joint: usize) -> Option<f64>;
    /// The jerk limit (symmetric).
    fn jerk(&self, joint: usize) -> Option<f64>;
    /// The relative excess over a velocity, acceleration or jerk limit taken as rounding
    /// (a controller that clamps to a limit exactly differs from it by rounding once
    /// differenced); 0 for a robot that refuses any excess.
    fn rounding(&self) -> f64 {
        0.0
    }
    /// A robot's own rule beyond these, on a command `q` and its velocity `v`: the rule's
    /// words, the value and the bound it passes (the Franka: where a stop from here would
    /// end). None: the rule holds, or the robot has none.
    fn rule(&self, _joint: usize, _q: f64, _v: f64) -> Option<(&'static str, f64, f64)> {
        None
    }
}

/// What a value is held to: a joint quantity, or a robot's own rule (in words).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Held {
    /// Position, velocity, acceleration, jerk, torque or torque rate.
    Quantity(Quantity),
    /// A robot's rule beyond these (see [`StreamBounds::rule`]).
    Rule(&'static str),
}

/// One value of a command judged against its bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Judged {
    /// 1-based joint number.
    pub joint: usize,
    /// What it is held to.
    pub held: Held,
    /// The value (signed; for positions the position, for a rule its value).
    pub value: f64,
    /// The bound in the value's direction (for positions the nearer end of the range).
    pub bound: f64,
    /// How far the value reaches (its magnitude; for positions, its distance from the
    /// middle of the range); infinite for a value that is not a number.
    pub reach: f64,
    /// The size of the limit it reaches for (the bound's magnitude; for positions, half
    /// the range).
    pub scale: f64,
    /// How far beyond the bound it is (> 0: beyond; rounding and the position tolerance
    /// taken off); infinite for a value that is not a number.
    pub excess: f64,
}

impl Judged {
    /// The share of the limit used (1 = at it; for positions, how far from the middle of
    /// the range towards a bound): computed on demand, so the realtime loop never divides
    /// for it.
    pub fn usage(&self) -> f64 {
        if self.reach == 0.0 {
            0.0
        } else {
            self.reach / self.scale
        }
    }
}

/// The first value of a command beyond its bound: what [`StreamCheck::admit`] refuses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Excess {
    /// The value, its bound and what it is held to.
    pub judged: Judged,
    /// The command's number in the stream (see [`StreamCheck::numbered_from`]).
    pub command: usize,
    /// Its time (s): its number times the period.
    pub time: f64,
}

/// How far (rad) a joint that starts outside its range may swing beyond where it started
/// while it moves back (the motion between the points of a plan that holds it there a
/// while, then brings it in).
pub const OUTSIDE_SLACK: f64 = 1e-4;

/// Whether a joint at `value`, beyond its `bound`, is allowed there because it started
/// beyond that bound (at `start`) and has not gone further out (by more than
/// [`OUTSIDE_SLACK`]): moving back from outside a bound is allowed, never further out.
pub fn beyond_allowed(start: f64, value: f64, bound: f64) -> bool {
    let started_outside =
        (value > bound) == (start > bound) && (start - bound).abs() > POSITION_TOLERANCE;
    started_outside && (value - bound).abs() <= (start - bound).abs() + OUTSIDE_SLACK
}

/// A position judged against its range (`None`: no range).
fn judge_position(joint: usize, q: f64, range: Option<(f64, f64)>) -> Option<Judged> {
    let (lo, hi) = range?;
    let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    // Not a number reaches infinitely far.
    let off = if q.is_finite() {
        (q - mid).abs()
    } else {
        f64::INFINITY
    };
    Some(Judged {
        joint: joint + 1,
        held: Held::Quantity(Quantity::Position),
        value: q,
        bound: if q < mid { lo } else { hi },
        reach: off,
        scale: half,
        excess: off - half - POSITION_TOLERANCE,
    })
}

/// A value judged against bounds `(lower, upper)` (`lower ≤ 0 ≤ upper`), with `rounding`
/// as relative slack.
fn judge_between(
    joint: usize,
    quantity: Quantity,
    x: f64,
    (lo, hi): (f64, f64),
    rounding: f64,
) -> Judged {
    let bound = if x >= 0.0 { hi } else { lo };
    // Not a number reaches infinitely far.
    let reach = if x.is_finite() {
        x.abs()
    } else {
        f64::INFINITY
    };
    let scale = bound.abs();
    Judged {
        joint: joint + 1,
        held: Held::Quantity(quantity),
        value: x,
        bound,
        reach,
        scale,
        excess: reach - scale * (1.0 + rounding),
    }
}

/// A value judged against a symmetric limit `max`.
fn judge_symmetric(joint: usize, quantity: Quantity, x: f64, max: f64, rounding: f64) -> Judged {
    judge_between(joint, quantity, x, (-max, max), rounding)
}

/// A command stream's state: the last command and its backward differences, where the
/// stream started, and each joint's peak usage of velocity, acceleration and jerk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamCheck<S: Joints, B: StreamBounds> {
    bounds: B,
    dt: f64,
    /// Where the robot stood when the commands began (for the position allowance).
    start: S,
    q: S,
    v: S,
    a: S,
    /// The next command's velocity and acceleration, reused.
    next_v: S,
    next_a: S,
    /// Commands taken so far, and the number of the first.
    taken: usize,
    first: usize,
    peak: [S; 3],
}

impl<S: Joints, B: StreamBounds> StreamCheck<S, B> {
    /// A check of commands every `dt` seconds to a robot at rest at `q0`, held to
    /// `bounds`; the first command is number 0 (see [`StreamCheck::numbered_from`]).
    pub fn at_rest(bounds: B, q0: S, dt: f64) -> Self {
        let mut zero = q0.clone();
        zero.as_mut().fill(0.0);
        StreamCheck {
            bounds,
            dt,
            start: q0.clone(),
            q: q0,
            v: zero.clone(),
            a: zero.clone(),
            next_v: zero.clone(),
            next_a: zero.clone(),
            taken: 0,
            first: 0,
            peak: [zero.clone(), zero.clone(), zero],
        }
    }

    /// The same check, its first command numbered `first` (1 where command 0 is the
    /// robot's standstill before the stream, as in a plan whose first sample is its
    /// start).
    pub fn numbered_from(mut self, first: usize) -> Self {
        self.first = first;
        self
    }

    /// The bounds held to.
    pub fn bounds(&self) -> &B {
        &self.bounds
    }

    /// The period (s).
    pub fn period(&self) -> f64 {
        self.dt
    }

    /// The last command taken (where the robot stood, before any), with its velocity and
    /// acceleration (or the reference set by [`StreamCheck::rebase`]).
    pub fn last(&self) -> (&S, &S, &S) {
        (&self.q, &self.v, &self.a)
    }

    /// Commands taken so far.
    pub fn taken(&self) -> usize {
        self.taken
    }

    /// Each joint's peak usage (1 = at the limit) of velocity, acceleration and jerk over
    /// the commands taken.
    pub fn peak_usage(&self) -> &[S; 3] {
        &self.peak
    }

    /// Whether the last command is at rest (velocity and acceleration zero).
    pub fn at_rest_now(&self) -> bool {
        let (v, a) = (self.v.as_ref(), self.a.as_ref());
        v.iter().chain(a).all(|x| x.abs() < 1e-12)
    }

    /// Judges the next command against this position, velocity and acceleration instead
    /// of the last one's: the reference the robot holds, which after a lost period is the
    /// robot's own extrapolation.
    pub fn rebase(&mut self, q: &[f64], v: &[f64], a: &[f64]) {
        self.q.as_mut().copy_from_slice(q);
        self.v.as_mut().copy_from_slice(v);
        self.a.as_mut().copy_from_slice(a);
    }

    /// Takes `q` as the next command if every joint keeps every limit (moving back from
    /// outside the range where the stream started there is allowed: see
    /// [`beyond_allowed`]); otherwise returns the first value beyond its bound, joint by
    /// joint, and the state stays as it was.
    pub fn admit(&mut self, q: &[f64]) -> Result<(), Excess> {
        self.admit_also(q, |_, _| None)
    }

    /// [`StreamCheck::admit`], with one more judge after the stream's own limits hold:
    /// `also` gets the command's velocity and acceleration, and answers the first value it
    /// finds beyond its bound (a torque, by [`TorqueCheck`]), which refuses the command.
    pub fn admit_also(
        &mut self,
        q: &[f64],
        also: impl FnOnce(&[f64], &[f64]) -> Option<Judged>,
    ) -> Result<(), Excess> {
        self.differences(q);
        let start = self.start.as_ref();
        let mut first = None;
        self.judge(q, |j| {
            let allowed = j.held == Held::Quantity(Quantity::Position)
                && beyond_allowed(start[j.joint - 1], j.value, j.bound);
            if j.excess > 0.0 && !allowed {
                first = Some(j);
                return false;
            }
            true
        });
        if first.is_none() {
            first = also(self.next_v.as_ref(), self.next_a.as_ref());
        }
        match first {
            Some(judged) => Err(self.excess(judged)),
            None => {
                self.take(q);
                Ok(())
            }
        }
    }

    /// Takes `q` as the next command whatever it breaks, showing `visit` each of its
    /// values with its bound, joint by joint.
    pub fn measure(&mut self, q: &[f64], mut visit: impl FnMut(Judged)) {
        self.differences(q);
        self.judge(q, |j| {
            visit(j);
            true
        });
        self.take(q);
    }

    /// The breach `judged` as the next command's.
    fn excess(&self, judged: Judged) -> Excess {
        let command = self.first + self.taken;
        Excess {
            judged,
            command,
            time: command as f64 * self.dt,
        }
    }

    /// The next command's velocity and acceleration, into the reused buffers.
    fn differences(&mut self, q: &[f64]) {
        let dt = self.dt;
        let (q0, v0) = (self.q.as_ref(), self.v.as_ref());
        let (v, a) = (self.next_v.as_mut(), self.next_a.as_mut());
        for j in 0..q0.len().min(q.len()) {
            v[j] = (q[j] - q0[j]) / dt;
            a[j] = (v[j] - v0[j]) / dt;
        }
    }

    /// Shows `visit` every value of command `q` (its differences already taken), joint by
    /// joint, until it answers false.
    fn judge(&self, q: &[f64], mut visit: impl FnMut(Judged) -> bool) {
        let (b, dt, r) = (&self.bounds, self.dt, self.bounds.rounding());
        let (v, a, a0) = (self.next_v.as_ref(), self.next_a.as_ref(), self.a.as_ref());
        for j in 0..self.q.as_ref().len().min(q.len()) {
            let jerk = (a[j] - a0[j]) / dt;
            // Each value is judged only when the ones before it were seen: the realtime
            // loop stops at the first breach.
            if let Some(p) = judge_position(j, q[j], b.range(j))
                && !visit(p)
            {
                return;
            }
            if let Some(vb) = b.velocity(j, q[j])
                && !visit(judge_between(j, Quantity::Velocity, v[j], vb, r))
            {
                return;
            }
            if let Some(m) = b.acceleration(j)
                && !visit(judge_symmetric(j, Quantity::Acceleration, a[j], m, r))
            {
                return;
            }
            if let Some(m) = b.jerk(j)
                && !visit(judge_symmetric(j, Quantity::Jerk, jerk, m, r))
            {
                return;
            }
            if let Some((rule, value, bound)) = b.rule(j, q[j], v[j]) {
                let judged = Judged {
                    joint: j + 1,
                    held: Held::Rule(rule),
                    value,
                    bound,
                    reach: f64::INFINITY,
                    scale: bound.abs(),
                    excess: f64::INFINITY,
                };
                if !visit(judged) {
                    return;
                }
            }
        }
    }

    /// Moves the state on to command `q` (its differences already taken), noting its
    /// peak usages.
    fn take(&mut self, q: &[f64]) {
        let (b, dt) = (&self.bounds, self.dt);
        let n = self.q.as_ref().len().min(q.len());
        let (v, a, a0) = (self.next_v.as_ref(), self.next_a.as_ref(), self.a.as_ref());
        let [pv, pa, pj] = &mut self.peak;
        let (pv, pa, pj) = (pv.as_mut(), pa.as_mut(), pj.as_mut());
        for j in 0..n {
            if let Some((lo, hi)) = b.velocity(j, q[j]) {
                let bound = if v[j] >= 0.0 { hi } else { -lo };
                if bound > 0.0 {
                    pv[j] = pv[j].max(v[j].abs() / bound);
                }
            }
            if let Some(m) = b.acceleration(j) {
                pa[j] = pa[j].max(a[j].abs() / m);
            }
            if let Some(m) = b.jerk(j) {
                pj[j] = pj[j].max(((a[j] - a0[j]) / dt).abs() / m);
            }
        }
        self.q.as_mut()[..n].copy_from_slice(&q[..n]);
        std::mem::swap(&mut self.v, &mut self.next_v);
        std::mem::swap(&mut self.a, &mut self.next_a);
        self.taken += 1;
    }
}

/// A robot model's bounds, one value per joint (infinite where it has none): what a plan,
/// the guard and the in-process robots hold commands to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointBounds<S: Joints> {
    /// Lower and upper position bounds (rad).
    pub lower: S,
    /// Upper position bounds (rad).
    pub upper: S,
    /// Velocity limits (rad/s).
    pub velocity: S,
    /// Acceleration limits (rad/s²).
    pub acceleration: S,
    /// Jerk limits (rad/s³).
    pub jerk: S,
    /// See [`StreamBounds::rounding`].
    pub rounding: f64,
}

impl<S: Joints> JointBounds<S> {
    /// The bounds of `chain` (range and speeds) and `limits` (accelerations and jerks),
    /// in storage shaped like `like` (one value per joint).
    pub fn of(chain: &crate::SerialChain, limits: &super::JointLimits, like: &S) -> Self {
        let fill = |values: Option<&[f64]>, sign: f64| {
            let mut s = like.clone();
            for (k, x) in s.as_mut().iter_mut().enumerate() {
                *x = values
                    .and_then(|v| v.get(k))
                    .map_or(sign * f64::INFINITY, |v| *v);
            }
            s
        };
        let range = chain.limits();
        JointBounds {
            lower: fill(range.map(|r| r.0), -1.0),
            upper: fill(range.map(|r| r.1), 1.0),
            velocity: fill(chain.velocity_limits(), 1.0),
            acceleration: fill(limits.acceleration.as_deref(), 1.0),
            jerk: fill(limits.jerk.as_deref(), 1.0),
            rounding: 0.0,
        }
    }

    /// The same bounds, `rounding` taken as rounding (see [`StreamBounds::rounding`]).
    pub fn with_rounding(mut self, rounding: f64) -> Self {
        self.rounding = rounding;
        self
    }
}

/// `Some(x)` where `x` is a limit (finite).
fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl<S: Joints> StreamBounds for JointBounds<S> {
    fn range(&self, joint: usize) -> Option<(f64, f64)> {
        let (lo, hi) = (self.lower.as_ref()[joint], self.upper.as_ref()[joint]);
        (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
    }

    fn velocity(&self, joint: usize, _q: f64) -> Option<(f64, f64)> {
        finite(self.velocity.as_ref()[joint]).map(|v| (-v, v))
    }

    fn acceleration(&self, joint: usize) -> Option<f64> {
        finite(self.acceleration.as_ref()[joint])
    }

    fn jerk(&self, joint: usize) -> Option<f64> {
        finite(self.jerk.as_ref()[joint])
    }

    fn rounding(&self) -> f64 {
        self.rounding
    }
}

/// Torques along a command stream, by inverse dynamics at each command with its
/// differences, and their rates (the first command's rate taken from itself), judged
/// against a robot's torque and torque-rate limits. Each command's inverse dynamics
/// allocates: this is for plans and simulated robots, not a realtime loop (a Franka
/// limits its own torques).
#[derive(Debug, Clone, Default)]
pub struct TorqueCheck {
    last: Option<Vec<f64>>,
}

impl TorqueCheck {
    /// Whether `robot` has a torque limit to hold and the inertias to compute torques.
    pub fn applies(robot: &super::RobotLimits) -> bool {
        let l = robot.limits;
        (l.torque.is_some() || l.torque_rate.is_some()) && robot.inertia.is_some()
    }

    /// Torques of command `q` with velocity `v` and acceleration `a`, each judged, shown to
    /// `visit` (torque then torque rate, joint by joint) until it answers false. Returns the
    /// torques (to [`TorqueCheck::take`] when the command is taken); None where `robot`
    /// has no torque limit or no inertias.
    pub fn judge(
        &self,
        robot: &super::RobotLimits,
        dt: f64,
        (q, v, a): (&[f64], &[f64], &[f64]),
        mut visit: impl FnMut(Judged) -> bool,
    ) -> Result<Option<Vec<f64>>, crate::KinematicsError> {
        let Some(links) = robot.inertia.filter(|_| TorqueCheck::applies(robot)) else {
            return Ok(None);
        };
        let tau = robot
            .chain
            .inverse_dynamics(links, robot.gravity, q, v, a)?;
        let before = self.last.as_deref().unwrap_or(&tau);
        let l = robot.limits;
        for j in 0..tau.len() {
            let rate = (tau[j] - before[j]) / dt;
            let judged = [
                l.torque
                    .as_ref()
                    .map(|m| judge_symmetric(j, Quantity::Torque, tau[j], m[j], 0.0)),
                l.torque_rate
                    .as_ref()
                    .map(|m| judge_symmetric(j, Quantity::TorqueRate, rate, m[j], 0.0)),
            ];
            for judged in judged.into_iter().flatten() {
                if !visit(judged) {
                    return Ok(Some(tau));
                }
            }
        }
        Ok(Some(tau))
    }

    /// Takes the torques of the command taken (None: none computed).
    pub fn take(&mut self, tau: Option<Vec<f64>>) {
        self.last = tau;
    }
}
