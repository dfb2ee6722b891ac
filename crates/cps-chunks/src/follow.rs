//! Following a moving reference one control period at a time within velocity,
//! acceleration and jerk limits: the core of the chunk executor (issue 52). Each joint is
//! a cascade — position error to a velocity target (on a braking curve far from the
//! reference), velocity error to an acceleration target, acceleration error to a jerk —
//! with the reference's velocity, acceleration and jerk fed forward, every stage clamped
//! to its limit, and the acceleration target also to what can still be braked to zero
//! jerk-limited before the velocity limit: `v + a²/(2J) + 2|a|·dt ≤ V` ahead of the step.
//!
//! The commands are built from their differences, as the guard measures them: the jerk
//! `j_k` chosen, then `a_k = a_{k−1} + j_k dt`, `v_k = v_{k−1} + a_k dt`,
//! `q_k = q_{k−1} + v_k dt`, so the backward differences of the commanded positions are
//! exactly these, and within the limits by construction. Nothing is allocated after
//! [`Follower::new`].

/// One joint's limits for the follower (positive; rad/s, rad/s², rad/s³).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowLimits {
    /// Velocity.
    pub velocity: f64,
    /// Acceleration.
    pub acceleration: f64,
    /// Jerk.
    pub jerk: f64,
}

use crate::FollowError;

/// The cascade's gains (1/s): position → velocity, velocity → acceleration, acceleration
/// → jerk; each stage four times faster than the one it serves, so the loop is well
/// damped.
pub const GAINS: [f64; 3] = [12.0, 48.0, 192.0];

/// The follower's state and limits (see the module's text).
#[derive(Debug, Clone)]
pub struct Follower {
    dt: f64,
    limits: Vec<FollowLimits>,
    q: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
    /// The reference's acceleration at the last step (its change is the jerk fed forward).
    ra: Vec<f64>,
}

impl Follower {
    /// A follower at rest at `q0`, stepped every `dt` seconds. Errors: a joint count that
    /// differs, a limit or period that is not positive and finite.
    pub fn new(q0: &[f64], limits: &[FollowLimits], dt: f64) -> Result<Follower, FollowError> {
        if q0.len() != limits.len() {
            return Err(FollowError::JointCount {
                given: q0.len(),
                joints: limits.len(),
            });
        }
        if !(dt.is_finite() && dt > 0.0) {
            return Err(FollowError::Period(dt));
        }
        for (j, l) in limits.iter().enumerate() {
            for (what, x) in [
                ("velocity", l.velocity),
                ("acceleration", l.acceleration),
                ("jerk", l.jerk),
            ] {
                if !(x.is_finite() && x > 0.0) {
                    return Err(FollowError::Limit {
                        joint: j + 1,
                        quantity: what,
                        value: x,
                    });
                }
            }
        }
        if let Some(j) = q0.iter().position(|x| !x.is_finite()) {
            return Err(FollowError::Start {
                joint: j + 1,
                value: q0[j],
            });
        }
        Ok(Follower {
            dt,
            limits: limits.to_vec(),
            q: q0.to_vec(),
            v: vec![0.0; q0.len()],
            a: vec![0.0; q0.len()],
            ra: vec![f64::NAN; q0.len()],
        })
    }

    /// The limits it keeps, per joint.
    pub fn limits(&self) -> &[FollowLimits] {
        &self.limits
    }

    /// The last command (rad).
    pub fn position(&self) -> &[f64] {
        &self.q
    }

    /// Its velocity and acceleration (the commands' backward differences).
    pub fn velocity(&self) -> &[f64] {
        &self.v
    }

    /// See [`Follower::velocity`].
    pub fn acceleration(&self) -> &[f64] {
        &self.a
    }

    /// Whether every joint is at rest (velocity and acceleration zero).
    pub fn at_rest(&self) -> bool {
        self.v.iter().chain(&self.a).all(|x| *x == 0.0)
    }

    /// The next command toward the reference `r` with its velocity `rv` and acceleration
    /// `ra` (feed-forward; zeros for a point to hold). Non-finite references are treated
    /// as holding where the command is.
    pub fn step(&mut self, r: &[f64], rv: &[f64], ra: &[f64]) -> &[f64] {
        let dt = self.dt;
        for i in 0..self.q.len() {
            let l = self.limits[i];
            let (q, v, a) = (self.q[i], self.v[i], self.a[i]);
            let (r, rv, ra) = match (r.get(i), rv.get(i), ra.get(i)) {
                (Some(&r), Some(&rv), Some(&ra))
                    if r.is_finite() && rv.is_finite() && ra.is_finite() =>
                {
                    (r, rv, ra)
                }
                _ => (q, 0.0, 0.0),
            };
            // Where the motion goes while its acceleration is brought to zero at full
            // jerk (τ = |a|/J): what the loops below compare with the reference, so that a
            // low jerk limit does not make them overshoot.
            let tau = a.abs() / l.jerk;
            let v_ahead = v + a * tau / 2.0;
            let q_ahead = q + v * tau + a * tau * tau / 3.0;
            // Toward the reference at most as fast as half the acceleration limit can stop
            // at it, jerk-limited (a far target is approached on a braking curve, not
            // overshot): the speed from which braking at A/2, ramped at J, takes |e|.
            let e = r - q_ahead;
            let half = 0.5 * l.acceleration;
            let ramp = half * half / (2.0 * l.jerk);
            let braking = -ramp + (ramp * ramp + 2.0 * half * e.abs()).sqrt();
            let toward = (GAINS[0] * e.abs()).min(braking);
            let vt = (rv + toward.copysign(e)).clamp(-l.velocity, l.velocity);
            // The largest acceleration after this step from which the velocity can still be
            // braked (jerk-limited) within its limit, on either side.
            let room = |side: f64| {
                let j2 = 2.0 * l.jerk;
                let rest = (l.velocity - side * v).max(0.0);
                (-j2 * dt + ((j2 * dt).powi(2) + j2 * rest).sqrt()).max(0.0)
            };
            let at = (ra + GAINS[1] * (vt - v_ahead))
                .clamp(-l.acceleration, l.acceleration)
                .clamp(-room(-1.0), room(1.0));
            let rj = if self.ra[i].is_finite() {
                (ra - self.ra[i]) / dt
            } else {
                0.0
            };
            self.ra[i] = ra;
            let j = (rj + GAINS[2] * (at - a)).clamp(-l.jerk, l.jerk);
            let a = (a + j * dt).clamp(-l.acceleration, l.acceleration);
            let v = v + a * dt;
            // Holding a point, a motion too small to matter is rest: the approach is
            // exponential, and rounding would otherwise leave it a hair from zero for
            // ever. Zeroing it changes the commands' acceleration by |v|/dt and their
            // jerk by |v|/dt² + |a|/dt, far within the limits at these sizes.
            let holding = rv == 0.0 && ra == 0.0;
            let tiny_v = (0.5 * l.jerk * dt * dt).min(1e-9);
            let tiny_a = (0.5 * l.jerk * dt).min(1e-6);
            let (a, v) = if (a.abs() < 1e-15 && v.abs() < 1e-15)
                || (holding && v.abs() <= tiny_v && a.abs() <= tiny_a)
            {
                (0.0, 0.0)
            } else {
                (a, v)
            };
            self.a[i] = a;
            self.v[i] = v;
            self.q[i] = q + v * dt;
        }
        &self.q
    }
}

/// What the follower's and the executor's tests share: the FR3's limits, its period, and
/// the check of commands against them.
#[cfg(test)]
pub(crate) mod testing {
    use super::FollowLimits;

    /// The FR3's limits (its datasheet's, joint 1).
    pub(crate) const FR3: FollowLimits = FollowLimits {
        velocity: 2.62,
        acceleration: 10.0,
        jerk: 5000.0,
    };
    /// A Franka's period.
    pub(crate) const DT: f64 = 0.001;

    /// Checks the backward differences of the commands `q` (from rest) against the
    /// limits.
    pub(crate) fn within_limits(q: &[f64]) {
        let d = |x: &[f64]| {
            x.windows(2)
                .map(|w| (w[1] - w[0]) / DT)
                .collect::<Vec<f64>>()
        };
        let v = d(q);
        let a = d(&[vec![0.0], v.clone()].concat());
        let j = d(&[vec![0.0], a.clone()].concat());
        let peak = |x: &[f64]| x.iter().fold(0.0_f64, |m, y| m.max(y.abs()));
        let (pv, pa, pj) = (peak(&v), peak(&a), peak(&j));
        assert!(pv <= FR3.velocity * (1.0 + 1e-9), "velocity {pv}");
        assert!(pa <= FR3.acceleration * (1.0 + 1e-9), "acceleration {pa}");
        assert!(pj <= FR3.jerk * (1.0 + 1e-9), "jerk {pj}");
    }
}

#[cfg(test)]
mod tests {
    use super::testing::{DT, FR3, within_limits};
    use super::*;

    /// Runs `n` steps toward `reference(t)` and checks every command's backward
    /// differences against the limits; returns the commands.
    fn run(reference: impl Fn(f64) -> f64, n: usize, f: &mut Follower) -> Vec<f64> {
        let mut out = vec![f.position()[0]];
        for k in 1..=n {
            let t = k as f64 * DT;
            let (r, r1, r0) = (reference(t), reference(t + DT), reference(t - DT));
            let rv = (r1 - r0) / (2.0 * DT);
            let ra = (r1 - 2.0 * r + r0) / (DT * DT);
            out.push(f.step(&[r], &[rv], &[ra])[0]);
        }
        within_limits(&out);
        out
    }

    #[test]
    fn a_reachable_path_is_followed_closely_and_within_every_limit() {
        // 0.3 rad at 0.5 Hz: 0.94 rad/s and 3.0 rad/s² at most, well within the FR3's.
        let path = |t: f64| 0.3 * (std::f64::consts::PI * t).sin();
        let mut f = Follower::new(&[0.0], &[FR3], DT).unwrap();
        let q = run(path, 4000, &mut f);
        let worst = (1000..=4000)
            .map(|k| (q[k] - path(k as f64 * DT)).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-3,
            "tracking error {worst} rad after the first second"
        );
    }

    #[test]
    fn jumps_beyond_every_limit_are_followed_within_them() {
        // Chunk boundaries at their worst: a reference that jumps 0.5 rad every 100 ms.
        let steps = |t: f64| 0.5 * ((t / 0.1).floor() % 3.0 - 1.0);
        let mut f = Follower::new(&[0.0], &[FR3], DT).unwrap();
        run(steps, 3000, &mut f);
        // A reference far away, held: reached at rest, no overshoot beyond a millimetre.
        let mut f = Follower::new(&[0.0], &[FR3], DT).unwrap();
        let q = run(|_| 1.0, 5000, &mut f);
        assert!(
            (q[5000] - 1.0).abs() < 1e-6 && f.velocity()[0].abs() < 1e-6,
            "{}",
            q[5000]
        );
        assert!(
            q.iter().all(|&x| x <= 1.0 + 1e-3),
            "overshoot {}",
            q.iter().fold(0.0_f64, |m, &x| m.max(x))
        );
    }

    #[test]
    fn holding_where_it_is_brakes_to_rest_within_the_limits() {
        // At full speed, then the reference stops where the command is (a stalled policy).
        let mut f = Follower::new(&[0.0], &[FR3], DT).unwrap();
        run(|t| 2.0 * t, 2000, &mut f);
        let moving = f.velocity()[0];
        assert!(moving > 1.9, "{moving}");
        let mut q = vec![f.position()[0]];
        for _ in 0..2000 {
            let here = f.position()[0];
            q.push(f.step(&[here], &[0.0], &[0.0])[0]);
        }
        assert!(
            f.at_rest() || f.velocity()[0].abs() < 1e-9,
            "{:?}",
            f.velocity()
        );
        let v: Vec<f64> = q.windows(2).map(|w| (w[1] - w[0]) / DT).collect();
        let a: Vec<f64> = [&[moving][..], &v]
            .concat()
            .windows(2)
            .map(|w| (w[1] - w[0]) / DT)
            .collect();
        assert!(a.iter().all(|x| x.abs() <= FR3.acceleration * (1.0 + 1e-9)));
        // No allocation, no NaN: a reference that is not a number holds.
        let before = f.position()[0];
        assert_eq!(f.step(&[f64::NAN], &[0.0], &[0.0])[0], before);
    }

    #[test]
    fn random_references_never_break_a_limit() {
        // Chunks of random targets (up to ±1.5 rad, 10–50 per second), some with velocities
        // that lie, from random starts: 40 seeded cases of 3 s each.
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..40 {
            let rate = 10.0 + 40.0 * next();
            let targets: Vec<f64> = (0..200).map(|_| 3.0 * next() - 1.5).collect();
            let lie = 5.0 * (next() - 0.5);
            let start = next() - 0.5;
            let mut f = Follower::new(&[start], &[FR3], DT).unwrap();
            let mut out = vec![start];
            for k in 1..=3000 {
                let t = k as f64 * DT;
                let r = targets[((t * rate) as usize).min(199)];
                out.push(f.step(&[r], &[lie], &[0.0])[0]);
            }
            within_limits(&out);
        }
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(
            Follower::new(&[0.0], &[], DT)
                .unwrap_err()
                .to_string()
                .contains("1 joint position(s) for 0")
        );
        assert!(
            Follower::new(&[0.0], &[FR3], 0.0)
                .unwrap_err()
                .to_string()
                .contains("not a period")
        );
        let bad = FollowLimits { jerk: -1.0, ..FR3 };
        assert!(
            Follower::new(&[0.0], &[bad], DT)
                .unwrap_err()
                .to_string()
                .contains("jerk limit -1")
        );
        assert!(
            Follower::new(&[f64::NAN], &[FR3], DT)
                .unwrap_err()
                .to_string()
                .contains("not a position")
        );
    }
}
