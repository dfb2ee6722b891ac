//! Exact discretisation of the transformation system.
//!
//! With `s = (y, z)` the transformation system `tau ż = alpha_z (beta_z (g - y) - z) + f`,
//! `tau ẏ = z` is the linear system `ṡ = A s + B u` with
//! `A = (1/tau) [[0, 1], [-alpha_z beta_z, -alpha_z]]`, `B = (0, 1/tau)` and the input
//! `u = alpha_z beta_z g + f`. Over one step of length `h` the input is interpolated
//! linearly between its samples (first-order hold), and the linear part is integrated
//! exactly with the matrix exponential:
//!
//! `s_{k+1} = E s_k + (Q/h) B u_k + (P - Q/h) B u_{k+1}`, where `E = exp(A h)`,
//! `P = ∫₀ʰ exp(A r) dr` and `Q = ∫₀ʰ r exp(A r) dr`.
//!
//! The scheme is unconditionally stable (E has the continuous system's decay for any h),
//! exact for the unforced system and second-order accurate in the forcing term.

type M2 = [[f64; 2]; 2];

fn mul(a: &M2, b: &M2) -> M2 {
    [
        [
            a[0][0] * b[0][0] + a[0][1] * b[1][0],
            a[0][0] * b[0][1] + a[0][1] * b[1][1],
        ],
        [
            a[1][0] * b[0][0] + a[1][1] * b[1][0],
            a[1][0] * b[0][1] + a[1][1] * b[1][1],
        ],
    ]
}

fn lin(a: f64, x: &M2, b: f64, y: &M2) -> M2 {
    [
        [a * x[0][0] + b * y[0][0], a * x[0][1] + b * y[0][1]],
        [a * x[1][0] + b * y[1][0], a * x[1][1] + b * y[1][1]],
    ]
}

const I2: M2 = [[1.0, 0.0], [0.0, 1.0]];

/// Per-step coefficients of the exact first-order-hold recurrence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StepCoefficients {
    /// `E = exp(A h)`.
    pub e: M2,
    /// Coefficients of `u_k` for (y, z).
    pub b0: [f64; 2],
    /// Coefficients of `u_{k+1}` for (y, z).
    pub b1: [f64; 2],
    /// `alpha_z beta_z`, `alpha_z`, `1/tau` and `1/tau²`, for the physical outputs.
    pub kk: f64,
    pub az: f64,
    pub inv_tau: f64,
    pub inv_tau2: f64,
}

impl StepCoefficients {
    /// Coefficients for gains `alpha_z`, `beta_z`, duration `tau` and step `h` (seconds).
    pub(crate) fn new(alpha_z: f64, beta_z: f64, tau: f64, h: f64) -> Self {
        let k = alpha_z * beta_z;
        let a: M2 = [[0.0, 1.0 / tau], [-k / tau, -alpha_z / tau]];
        let ah = lin(h, &a, 0.0, &I2);
        let norm = ah.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
        let (e, p, q) = if norm < 0.5 {
            series(&ah, h)
        } else {
            closed_form(&a, h, alpha_z, beta_z, tau)
        };
        // Input enters through B = (0, 1/tau): take the second columns.
        let qh = lin(1.0 / h, &q, 0.0, &I2);
        let p_minus = lin(1.0, &p, -1.0, &qh);
        Self {
            e,
            b0: [qh[0][1] / tau, qh[1][1] / tau],
            b1: [p_minus[0][1] / tau, p_minus[1][1] / tau],
            kk: k,
            az: alpha_z,
            inv_tau: 1.0 / tau,
            inv_tau2: 1.0 / (tau * tau),
        }
    }

    /// One step of the state `(y, z)` with inputs `u_k = u0`, `u_{k+1} = u1`:
    /// `(y, z)_{k+1} = E (y, z)_k + b0 u_k + b1 u_{k+1}`.
    #[inline(always)]
    pub(crate) fn advance(&self, y: f64, z: f64, u0: f64, u1: f64) -> (f64, f64) {
        let [[e00, e01], [e10, e11]] = self.e;
        let cy = self.b0[0] * u0 + self.b1[0] * u1;
        let cz = self.b0[1] * u0 + self.b1[1] * u1;
        (cy + (e00 * y + e01 * z), cz + (e10 * y + e11 * z))
    }

    /// `alpha_z beta_z g`, the goal's share of the input `u = alpha_z beta_z g + f`.
    #[inline(always)]
    pub(crate) fn goal_input(&self, g: f64) -> f64 {
        self.kk * g
    }

    /// Physical velocity `ẏ = z / tau`.
    #[inline(always)]
    pub(crate) fn velocity(&self, z: f64) -> f64 {
        z * self.inv_tau
    }

    /// Physical acceleration `ÿ = (u − alpha_z beta_z y − alpha_z z) / tau²`.
    #[inline(always)]
    pub(crate) fn acceleration(&self, u: f64, y: f64, z: f64) -> f64 {
        (u - self.kk * y - self.az * z) * self.inv_tau2
    }
}

/// Samples advanced together by [`BlockCoefficients`]: one SIMD vector of `f64` under
/// AVX-512, two under AVX2.
pub(crate) const BLOCK: usize = 8;

/// [`BLOCK`] steps of the recurrence at once, so that the states of `BLOCK` consecutive
/// samples advance together as independent lanes:
///
/// `s_{k+8} = E⁸ s_k + Σ_{j=0}^{8} Γ_j u_{k+j}`, `Γ_j = E^{7−j} b0 [j ≤ 7] + E^{8−j} b1 [j ≥ 1]`
///
/// (unrolling the one-step recurrence eight times). Lane `l` carries the chain of samples
/// `l, l + 8, l + 16, …`; the critical path is one 2 × 2 product per eight samples instead
/// of one per sample, and the input sums are off it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BlockCoefficients {
    /// `E⁸`.
    pub e: M2,
    /// `Γ_j` for y and z, `j = 0 ..= 8`.
    pub gy: [f64; BLOCK + 1],
    pub gz: [f64; BLOCK + 1],
}

impl BlockCoefficients {
    pub(crate) fn new(c: &StepCoefficients) -> Self {
        // powers[m] = E^m, m = 0 ..= BLOCK.
        let mut powers = [I2; BLOCK + 1];
        for m in 1..=BLOCK {
            powers[m] = mul(&powers[m - 1], &c.e);
        }
        let apply = |m: &M2, b: &[f64; 2]| {
            [
                m[0][0] * b[0] + m[0][1] * b[1],
                m[1][0] * b[0] + m[1][1] * b[1],
            ]
        };
        let mut gy = [0.0; BLOCK + 1];
        let mut gz = [0.0; BLOCK + 1];
        for j in 0..=BLOCK {
            let mut g = [0.0; 2];
            if j < BLOCK {
                let t = apply(&powers[BLOCK - 1 - j], &c.b0);
                g = [g[0] + t[0], g[1] + t[1]];
            }
            if j >= 1 {
                let t = apply(&powers[BLOCK - j], &c.b1);
                g = [g[0] + t[0], g[1] + t[1]];
            }
            gy[j] = g[0];
            gz[j] = g[1];
        }
        Self {
            e: powers[BLOCK],
            gy,
            gz,
        }
    }
}

/// Taylor series for small `‖A h‖`: `E = Σ (Ah)^j / j!`, `P = h Σ (Ah)^j / (j+1)!`,
/// `Q = h² Σ (Ah)^j / (j! (j+2))`.
fn series(ah: &M2, h: f64) -> (M2, M2, M2) {
    let mut term = I2; // (Ah)^j / j!
    let mut e = I2;
    let mut p = I2; // j = 0 term of P/h is I
    let mut q = lin(0.5, &I2, 0.0, &I2); // j = 0 term of Q/h² is I/2
    for j in 1..60 {
        term = lin(1.0 / j as f64, &mul(&term, ah), 0.0, &I2);
        e = lin(1.0, &e, 1.0, &term);
        p = lin(1.0, &p, 1.0 / (j + 1) as f64, &term);
        q = lin(1.0, &q, 1.0 / (j + 2) as f64, &term);
        if term.iter().flatten().all(|v| v.abs() < 1e-18) {
            break;
        }
    }
    (e, lin(h, &p, 0.0, &I2), lin(h * h, &q, 0.0, &I2))
}

/// Closed form for larger steps: the 2×2 exponential through `N = M - (tr M / 2) I`,
/// `N² = q I`, then `P = A⁻¹ (E - I)` and `Q = h A⁻¹ E - A⁻¹ P`.
fn closed_form(a: &M2, h: f64, alpha_z: f64, beta_z: f64, tau: f64) -> (M2, M2, M2) {
    let m = lin(h, a, 0.0, &I2);
    let half_trace = 0.5 * (m[0][0] + m[1][1]);
    // q computed from the parameters so that critical damping gives exactly zero.
    let q = (0.25 * alpha_z * alpha_z - alpha_z * beta_z) * (h / tau) * (h / tau);
    let n = lin(1.0, &m, -half_trace, &I2);
    let (c, s) = if q > 0.0 {
        let r = q.sqrt();
        (r.cosh(), r.sinh() / r)
    } else if q < 0.0 {
        let r = (-q).sqrt();
        (r.cos(), r.sin() / r)
    } else {
        (1.0, 1.0)
    };
    let e = lin(half_trace.exp() * c, &I2, half_trace.exp() * s, &n);
    let k = alpha_z * beta_z;
    // A⁻¹ = (tau / k) [[-alpha_z, -1], [k, 0]]
    let ainv: M2 = [[-alpha_z * tau / k, -tau / k], [tau, 0.0]];
    let p = mul(&ainv, &lin(1.0, &e, -1.0, &I2));
    let q_mat = lin(h, &mul(&ainv, &e), -1.0, &mul(&ainv, &p));
    (e, p, q_mat)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integrates ṡ = A s + B u(t) with classical RK4 on a very fine grid.
    fn rk4(
        alpha_z: f64,
        beta_z: f64,
        tau: f64,
        s0: [f64; 2],
        u: impl Fn(f64) -> f64,
        t_end: f64,
    ) -> [f64; 2] {
        let n = 200_000;
        let dt = t_end / n as f64;
        let f = |t: f64, s: [f64; 2]| {
            [
                s[1] / tau,
                (-alpha_z * beta_z * s[0] - alpha_z * s[1] + u(t)) / tau,
            ]
        };
        let mut s = s0;
        for i in 0..n {
            let t = i as f64 * dt;
            let k1 = f(t, s);
            let k2 = f(
                t + dt / 2.0,
                [s[0] + dt / 2.0 * k1[0], s[1] + dt / 2.0 * k1[1]],
            );
            let k3 = f(
                t + dt / 2.0,
                [s[0] + dt / 2.0 * k2[0], s[1] + dt / 2.0 * k2[1]],
            );
            let k4 = f(t + dt, [s[0] + dt * k3[0], s[1] + dt * k3[1]]);
            for j in 0..2 {
                s[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
        }
        s
    }

    fn step(c: &StepCoefficients, s: [f64; 2], u0: f64, u1: f64) -> [f64; 2] {
        [
            c.e[0][0] * s[0] + c.e[0][1] * s[1] + c.b0[0] * u0 + c.b1[0] * u1,
            c.e[1][0] * s[0] + c.e[1][1] * s[1] + c.b0[1] * u0 + c.b1[1] * u1,
        ]
    }

    #[test]
    fn one_step_is_exact_for_linear_input() {
        // First-order hold is exact when u is linear in time; check series and closed form,
        // critically damped, under- and over-damped.
        for &(az, bz, tau, h) in &[
            (25.0, 6.25, 10.0, 0.01),
            (25.0, 6.25, 1.0, 0.3),
            (25.0, 2.0, 1.0, 0.2),
            (25.0, 12.0, 2.0, 0.05),
            (10.0, 10.0, 0.5, 0.4),
        ] {
            let c = StepCoefficients::new(az, bz, tau, h);
            let u = |t: f64| 3.0 - 40.0 * t;
            let exact = rk4(az, bz, tau, [0.3, -0.2], u, h);
            let got = step(&c, [0.3, -0.2], u(0.0), u(h));
            for j in 0..2 {
                assert!(
                    (exact[j] - got[j]).abs() < 1e-11,
                    "{az} {bz} {tau} {h}: {exact:?} vs {got:?}"
                );
            }
        }
    }

    #[test]
    fn eight_steps_at_once_equal_eight_single_steps() {
        for &(az, bz, tau, h) in &[(25.0, 6.25, 10.0, 0.01), (25.0, 2.0, 1.0, 0.05)] {
            let c = StepCoefficients::new(az, bz, tau, h);
            let b = BlockCoefficients::new(&c);
            let u: Vec<f64> = (0..=BLOCK)
                .map(|j| (j as f64 * 0.9).sin() * 40.0 + 3.0)
                .collect();
            let mut s = [0.3, -0.2];
            for j in 0..BLOCK {
                s = step(&c, s, u[j], u[j + 1]);
            }
            let s0 = [0.3, -0.2];
            let y = b.e[0][0] * s0[0]
                + b.e[0][1] * s0[1]
                + u.iter().zip(&b.gy).map(|(u, g)| u * g).sum::<f64>();
            let z = b.e[1][0] * s0[0]
                + b.e[1][1] * s0[1]
                + u.iter().zip(&b.gz).map(|(u, g)| u * g).sum::<f64>();
            assert!(
                (y - s[0]).abs() < 1e-13 * (1.0 + s[0].abs()),
                "{y} vs {}",
                s[0]
            );
            assert!(
                (z - s[1]).abs() < 1e-13 * (1.0 + s[1].abs()),
                "{z} vs {}",
                s[1]
            );
        }
    }

    #[test]
    fn series_and_closed_form_agree_at_the_threshold() {
        let tau = 1.0;
        let h = 0.5 / 25.0 * tau; // ‖Ah‖ ≈ 0.5
        let a: M2 = [[0.0, 1.0 / tau], [-156.25 / tau, -25.0 / tau]];
        let (e1, p1, q1) = series(&lin(h, &a, 0.0, &I2), h);
        let (e2, p2, q2) = closed_form(&a, h, 25.0, 6.25, tau);
        for (x, y) in [(e1, e2), (p1, p2), (q1, q2)] {
            for i in 0..2 {
                for j in 0..2 {
                    assert!((x[i][j] - y[i][j]).abs() <= 1e-13 * (1.0 + x[i][j].abs()));
                }
            }
        }
    }
}
