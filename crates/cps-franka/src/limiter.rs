//! Limiting a joint command to what the robot accepts from the reference it holds.
//!
//! A stream that keeps every limit command by command (checked whole before a motion)
//! still reaches the robot with gaps: a cycle whose command was lost is extrapolated by
//! the robot at constant acceleration, and the stream's next command, judged against that
//! extrapolation, breaks the jerk or acceleration limit as soon as the stream was changing
//! its acceleration (a time-optimal move at 95 % of the limits does, every few
//! milliseconds). libfranka answers with a rate limiter that clamps each command; cps with
//! a [`Limiter`] that brings the robot's reference back onto the stream and then sends the
//! stream unchanged again:
//!
//! 1. a command the robot accepts from its reference is sent unchanged;
//! 2. otherwise the difference between the reference and the stream (position, velocity
//!    and acceleration, as backward differences) is taken out by a **blend**: the
//!    discrete quintic correction that starts with that difference and is zero, with zero
//!    velocity and acceleration, `n` periods later — the polynomial through the last
//!    three reference positions minus the stream's, and three zeros at `n − 2 … n` —
//!    added to the stream. `n` is the shortest of 4, 5, 6, 8 … 30 periods whose whole
//!    blend keeps every limit, the stream assumed to go on at its present acceleration;
//!    the blend is then followed to its end (so the stream is rejoined exactly), unless
//!    another cycle is lost or a step of it no longer keeps a limit;
//! 3. where no blend that short keeps the limits (the stream itself near them), a step of
//!    a **cascade** on the difference — position to velocity on a braking curve,
//!    velocity to acceleration, acceleration to jerk, gains [`CASCADE_GAINS`] — with the
//!    stream's jerk fed forward and within what the stream leaves of each limit, until a
//!    blend fits.
//!
//! Every replaced command is counted, with the largest distance between what was sent
//! and what the stream asked. A command far from where the reference is heading (a
//! generator's jump), beyond the joint range or a stop's reach, or whose replacement
//! breaks a limit, is not limited: the motion brakes.
//!
//! Nothing is allocated: it lives in the realtime loop.

use cps_kinematics::Quantity;
use cps_robot::{Breach, Limit};

use crate::limits::{DT, StreamCheck};
use crate::reference::Reference;
use crate::wire::JOINTS;

/// How far (rad, per joint) a command may be from where the robot's reference is heading
/// and still be limited rather than refused: so the limiter never takes the arm more than
/// this off the stream that was checked (about 4 mm at the tool), where lost cycles of a
/// stream at 95 % of the FR3's limits leave it about 1 mrad off (measured); farther, a
/// generator jumped, or the robot lost so many cycles that it is about to stop the motion
/// itself: the motion brakes.
pub const LIMITABLE_GAP: f64 = 0.005;

/// The blends tried, shortest first (periods).
const BLENDS: [u32; 10] = [4, 5, 6, 8, 10, 12, 15, 20, 25, 30];

/// The cascade's gains (1/s): position → velocity, velocity → acceleration, acceleration
/// → jerk, each stage four times faster than the one it serves; the last one below the
/// period's reciprocal, so its discrete loop does not ring.
pub const CASCADE_GAINS: [f64; 3] = [60.0, 240.0, 960.0];

/// The share of the acceleration and jerk limits the cascade keeps.
const CASCADE_SHARE: f64 = 0.99;

/// What the limiter did over a motion.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Limited {
    /// Commands replaced by a limited one.
    pub commands: usize,
    /// The largest distance between a command sent and the one asked for (rad; N m for
    /// torques).
    pub deviation: f64,
}

/// A blend under way: the errors of the last three positions when it started (oldest
/// first, per joint), its length, and the step it is at.
#[derive(Debug, Clone, Copy)]
struct Blend {
    errors: [[f64; 3]; JOINTS],
    n: u32,
    step: u32,
}

/// The correction of a blend of `n` periods at step `k` (see the module's text): zero from
/// `n − 2` on.
#[inline]
fn correction(errors: &[f64; 3], n: u32, k: u32) -> f64 {
    if k + 2 >= n {
        return 0.0;
    }
    let (n, k) = (f64::from(n), f64::from(k));
    // e(k) = p(k)·Q(k), p(k) = (k − n + 2)(k − n + 1)(k − n), Q the quadratic through
    // e(j)/p(j) at j = −2, −1, 0 (Lagrange).
    let p = |x: f64| (x - n + 2.0) * (x - n + 1.0) * (x - n);
    let q = errors[0] / p(-2.0) * (k * (k + 1.0) / 2.0) - errors[1] / p(-1.0) * (k * (k + 2.0))
        + errors[2] / p(0.0) * ((k + 1.0) * (k + 2.0) / 2.0);
    p(k) * q
}

/// Admits a joint command from the robot's reference, limiting it where a lost cycle made
/// it unacceptable (see the module's text).
#[derive(Debug, Clone, Copy)]
pub struct Limiter {
    /// The stream at the last period and at the one before (positions with their backward
    /// differences).
    desired: Reference,
    before: Reference,
    blend: Option<Blend>,
    /// The last command admitted: the reference is it unless the robot lost a cycle since.
    sent: Option<[f64; JOINTS]>,
    limited: Limited,
}

impl Limiter {
    /// A limiter for a motion starting at rest at `q0`.
    pub fn new(q0: [f64; JOINTS]) -> Self {
        Limiter {
            desired: Reference::at_rest(q0),
            before: Reference::at_rest(q0),
            blend: None,
            sent: None,
            limited: Limited::default(),
        }
    }

    /// What it did so far.
    pub fn limited(&self) -> Limited {
        self.limited
    }

    /// Notes the stream's command for one robot period: every period, also those whose
    /// command the robot never got (so the stream's differences are per period).
    pub fn desire(&mut self, q: &[f64; JOINTS]) {
        self.before = self.desired;
        self.desired = self.desired.after(q);
    }

    /// The command to send for the stream's last command (see [`Limiter::desire`]), given
    /// the reference the robot holds, which `check` has been set to: that command when the
    /// robot accepts it; a limited one when it would not but can be brought back to it;
    /// the breach otherwise (nothing is admitted then).
    pub fn admit(
        &mut self,
        check: &mut StreamCheck,
        reference: &Reference,
    ) -> Result<[f64; JOINTS], Breach> {
        let q = self.choose(check, reference)?;
        self.sent = Some(q);
        Ok(q)
    }

    fn choose(
        &mut self,
        check: &mut StreamCheck,
        reference: &Reference,
    ) -> Result<[f64; JOINTS], Breach> {
        let desired = self.desired.q;
        if self.sent != Some(reference.q) {
            // A cycle lost since: the blend's start no longer holds.
            self.blend = None;
        }
        if let Some(mut blend) = self.blend.take() {
            blend.step += 1;
            if blend.step + 2 < blend.n {
                let q = std::array::from_fn(|i| {
                    desired[i] + correction(&blend.errors[i], blend.n, blend.step)
                });
                if check.admit(&q).is_ok() {
                    self.blend = Some(blend);
                    return Ok(self.count(q));
                }
            }
        }
        let breach = match check.admit(&desired) {
            Ok(()) => return Ok(desired),
            Err(b) => b,
        };
        let rate = matches!(
            breach.limit,
            Limit::Joint {
                quantity: Quantity::Velocity | Quantity::Acceleration | Quantity::Jerk,
                ..
            }
        );
        let heading = reference.extrapolated();
        let near = (0..JOINTS).all(|i| (desired[i] - heading.q[i]).abs() <= LIMITABLE_GAP);
        if !(rate && near) {
            return Err(breach);
        }
        // The reference's last three positions minus the stream's.
        let (r, d) = (reference, &self.before);
        let errors: [[f64; 3]; JOINTS] = std::array::from_fn(|i| {
            let (eq, ev, ea) = (r.q[i] - d.q[i], r.v[i] - d.v[i], r.a[i] - d.a[i]);
            let e1 = eq - ev * DT;
            let e2 = e1 - (ev - ea * DT) * DT;
            [e2, e1, eq]
        });
        for n in BLENDS {
            if self.blend_keeps_limits(check, &errors, n) {
                let q = std::array::from_fn(|i| desired[i] + correction(&errors[i], n, 1));
                check.admit(&q).map_err(|_| breach)?;
                self.blend = Some(Blend { errors, n, step: 1 });
                return Ok(self.count(q));
            }
        }
        let q = self.cascade(check, reference);
        check.admit(&q).map_err(|_| breach)?;
        Ok(self.count(q))
    }

    fn count(&mut self, q: [f64; JOINTS]) -> [f64; JOINTS] {
        self.limited.commands += 1;
        for (x, d) in q.iter().zip(&self.desired.q) {
            self.limited.deviation = self.limited.deviation.max((x - d).abs());
        }
        q
    }

    /// Whether the whole blend of `n` periods (and the stream's two periods after it)
    /// keeps every limit from where `check` stands, the stream going on at its present
    /// acceleration.
    fn blend_keeps_limits(&self, check: &StreamCheck, errors: &[[f64; 3]; JOINTS], n: u32) -> bool {
        let mut trial = *check;
        let mut stream = self.desired;
        for k in 1..=n + 2 {
            if k > 1 {
                stream = stream.extrapolated();
            }
            let q = std::array::from_fn(|i| stream.q[i] + correction(&errors[i], n, k));
            if trial.admit(&q).is_err() {
                return false;
            }
        }
        true
    }

    /// One step of the cascade on the difference between the reference and the stream
    /// (see the module's text).
    fn cascade(&self, check: &StreamCheck, r: &Reference) -> [f64; JOINTS] {
        let l = check.limits();
        let (d, before) = (&self.desired, &self.before);
        let [g_q, g_v, g_a] = CASCADE_GAINS;
        std::array::from_fn(|i| {
            let (jl, al) = (CASCADE_SHARE * l.dddq_max[i], CASCADE_SHARE * l.ddq_max[i]);
            let (eq, ev, ea) = (
                r.q[i] - before.q[i],
                r.v[i] - before.v[i],
                r.a[i] - before.a[i],
            );
            // The stream's jerk now, and what it leaves of each limit to correct with.
            let sigma = (d.a[i] - before.a[i]) / DT;
            let jc = (jl - sigma.abs()).max(0.05 * jl);
            let ac = (al - d.a[i].abs()).max(0.05 * al);
            // Where the difference goes while its acceleration is ramped out.
            let tau = ea.abs() / jc;
            let ev_ahead = ev + ea * tau / 2.0;
            let eq_ahead = eq + ev * tau + ea * tau * tau / 3.0;
            let ramp = ac * ac / (2.0 * jc);
            let braking = -ramp + (ramp * ramp + 2.0 * ac * eq_ahead.abs()).sqrt();
            let w = -(g_q * eq_ahead.abs()).min(braking).copysign(eq_ahead);
            let b = (g_v * (w - ev_ahead)).clamp(-ac, ac);
            let u = (g_a * (b - ea)).clamp(-jc, jc);
            let j = (sigma + u).clamp(-jl, jl);
            let a = (r.a[i] + j * DT).clamp(-al, al);
            r.q[i] + (r.v[i] + a * DT) * DT
        })
    }
}

#[cfg(test)]
// Joint-indexed arrays are read side by side.
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use crate::limits::{Arm, RateLimits, check_stream};

    const FROM: [f64; JOINTS] = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7];

    /// The hardest stream there is: an S-curve at 95 % of the FR3's acceleration and jerk
    /// limits (scaled down joint by joint), whose jerk jumps between 0 and ±95 % of the
    /// limit every few milliseconds; at rest before and after.
    fn stream() -> Vec<[f64; JOINTS]> {
        let jerk = |k: usize| match k {
            1..=2 | 121..=122 => 1.0,
            41..=42 | 81..=82 => -1.0,
            _ => 0.0,
        };
        let mut r = Reference::at_rest(FROM);
        let mut s = vec![FROM];
        for k in 1..200 {
            let mut next = r;
            for i in 0..JOINTS {
                let j = 0.95 * 5000.0 * jerk(k) * (1.0 - 0.07 * i as f64);
                next.a[i] = r.a[i] + j * DT;
                next.v[i] = r.v[i] + next.a[i] * DT;
                next.q[i] = r.q[i] + next.v[i] * DT;
            }
            r = next;
            s.push(r.q);
        }
        s
    }

    /// Runs `stream` to a robot that loses the cycles `lost`, through a limiter; the
    /// commands sent.
    fn run(
        stream: &[[f64; JOINTS]],
        lost: &dyn Fn(usize) -> bool,
    ) -> (Vec<[f64; JOINTS]>, Limited) {
        let limits = RateLimits::of(Arm::Fr3);
        let mut robot = Reference::at_rest(stream[0]);
        let mut limiter = Limiter::new(stream[0]);
        let mut sent = vec![stream[0]];
        for (k, q) in stream.iter().enumerate().skip(1) {
            limiter.desire(q);
            if lost(k) {
                robot = robot.extrapolated();
                sent.push(robot.q);
                continue;
            }
            let mut check = StreamCheck::at_rest(limits, robot.q);
            check.rebase(robot.q, robot.v, robot.a);
            let c = limiter
                .admit(&mut check, &robot)
                .unwrap_or_else(|b| panic!("command {k} refused, not limited: {b}"));
            robot = robot.after(&c);
            sent.push(c);
        }
        (sent, limiter.limited())
    }

    #[test]
    fn lost_cycles_are_limited_back_onto_the_stream_within_the_robots_rules() {
        let limits = RateLimits::of(Arm::Fr3);
        let s = stream();
        check_stream(limits, FROM, &s).unwrap();
        // Cycles lost at every jerk switch and between, in runs of one to three: every
        // command is accepted from the robot's reference (run panics otherwise).
        let (sent, limited) = run(&s, &|k| {
            [2, 3, 20, 41, 42, 43, 60, 61, 81, 100, 121, 122, 123].contains(&k)
        });
        assert!(limited.commands > 0, "{limited:?}");
        assert!(limited.deviation < 1e-3, "{limited:?}");
        // Ends where the stream ends, at rest.
        assert_eq!(sent.last(), s.last());
        // One run of three lost cycles at a jerk switch: back on the stream, the commands
        // equal to it, within 30 ms.
        let (sent, limited) = run(&s, &|k| (41..=43).contains(&k));
        assert!(limited.commands > 0 && limited.commands < 30, "{limited:?}");
        assert_eq!(sent[..41], s[..41]);
        assert_eq!(sent[73..], s[73..]);
        // Without the limiter, the first command after those three breaks a limit.
        let mut robot = Reference::at_rest(s[0]);
        for q in &s[1..41] {
            robot = robot.after(q);
        }
        for _ in 41..=43 {
            robot = robot.extrapolated();
        }
        let mut check = StreamCheck::at_rest(limits, robot.q);
        check.rebase(robot.q, robot.v, robot.a);
        let b = check.admit(&s[44]).unwrap_err();
        assert!(
            matches!(
                b.limit,
                Limit::Joint {
                    quantity: Quantity::Jerk | Quantity::Acceleration,
                    ..
                }
            ),
            "{b}"
        );
    }

    #[test]
    fn random_streams_and_losses_are_limited_and_rejoined() {
        use rand::{Rng, SeedableRng};
        let limits = RateLimits::of(Arm::Fr3);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(61);
        for case in 0..200 {
            // Each joint: S-curves at 95 % of its acceleration and jerk limits (what the
            // retimer makes) — jerk for 2 ms, a plateau of acceleration, jerk back, a
            // cruise, and the same down to rest — of random lengths, signs and scales.
            let mut plans: Vec<Vec<f64>> = Vec::new();
            for i in 0..JOINTS {
                let mut jerks = vec![0.0; rng.random_range(0..30)];
                let j = 0.95 * limits.dddq_max[i] * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                let w =
                    (0.95 * limits.ddq_max[i] / (0.95 * limits.dddq_max[i]) / DT).round() as usize;
                let (plateau, cruise) = (rng.random_range(1..60), rng.random_range(0..80));
                for (sign, len) in [
                    (1.0, w),
                    (0.0, plateau),
                    (-1.0, w),
                    (0.0, cruise),
                    (-1.0, w),
                    (0.0, plateau),
                    (1.0, w),
                ] {
                    jerks.extend(std::iter::repeat_n(sign * j, len));
                }
                plans.push(jerks);
            }
            let mut r = Reference::at_rest(FROM);
            let mut s = vec![FROM];
            for k in 0..plans.iter().map(Vec::len).max().unwrap() {
                let mut next = r;
                for i in 0..JOINTS {
                    let j = plans[i].get(k).copied().unwrap_or(0.0);
                    next.a[i] = r.a[i] + j * DT;
                    next.v[i] = r.v[i] + next.a[i] * DT;
                    next.q[i] = r.q[i] + next.v[i] * DT;
                }
                r = next;
                s.push(r.q);
            }
            let mut brake = crate::limits::Brake::new(limits, r.q, r.v, r.a);
            while !brake.stopped() {
                s.push(brake.step());
            }
            let end = *s.last().unwrap();
            s.extend([end; 100]);
            check_stream(limits, FROM, &s).unwrap_or_else(|b| panic!("case {case}: {b}"));
            // Cycles lost at random, one to three in a row.
            let lost: Vec<bool> = {
                let mut l = vec![false; s.len()];
                let mut k = 1;
                while k < s.len() - 100 {
                    if rng.random_bool(0.05) {
                        for x in l.iter_mut().skip(k).take(rng.random_range(1..=3)) {
                            *x = true;
                        }
                    }
                    k += 4;
                }
                l
            };
            let (sent, limited) = run(&s, &|k| lost[k]);
            // 0.99 mrad at most over these 200 (measured).
            assert!(limited.deviation < 1.5e-3, "case {case}: {limited:?}");
            let n = s.len();
            assert_eq!(
                sent[n - 50..],
                s[n - 50..],
                "case {case}: the stream's end rejoined"
            );
        }
    }

    #[test]
    fn a_jump_is_refused_not_limited() {
        let limits = RateLimits::of(Arm::Fr3);
        let q0 = FROM;
        let mut limiter = Limiter::new(q0);
        let r = Reference::at_rest(q0);
        let mut jump = q0;
        jump[2] += 0.05;
        limiter.desire(&q0);
        limiter.desire(&jump);
        let mut check = StreamCheck::at_rest(limits, q0);
        let b = limiter.admit(&mut check, &r).unwrap_err();
        assert_eq!(b.limit, crate::limits::joint_limit(3, Quantity::Velocity));
        assert_eq!(limiter.limited().commands, 0);
    }
}
