//! Rhythmic (periodic) DMPs (Ijspeert et al. 2013, thesis eq. 46/47).
//!
//! Phase `φ(t) = t / τ` (radians; one period lasts `2π τ` seconds), von Mises basis
//! `ψ_i(φ) = exp(h (cos(φ − c_i) − 1))` with centres `c_i = 2π i / N` and width `h`,
//! forcing `f(φ) = r Σ ψ_i w_i / Σ ψ_i` with amplitude `r`, and the transformation system
//! `τ ż = α_z (β_z (g − y) − z) + f`, `τ ẏ = z` around the anchor `g` (the oscillation's
//! centre). It is integrated with the same exact first-order-hold scheme as the discrete
//! DMP. Scaling `r` scales the oscillation about `g`; changing `τ` changes the period.

use crate::DmpError;
use crate::config::{at_least_one, positive};
use crate::discretize::StepCoefficients;

/// A rhythmic DMP with one transformation system per dimension.
#[derive(Debug, Clone, PartialEq)]
pub struct RhythmicDmp {
    /// `α_z` (default 25).
    pub alpha_z: f64,
    /// `β_z` (default `α_z / 4`).
    pub beta_z: f64,
    /// Period / (2π) in seconds.
    pub tau: f64,
    /// Width `h` of the von Mises basis functions (default `2.5 N`).
    pub width: f64,
    /// Number of basis functions per dimension.
    pub n_basis: usize,
    /// Anchor `g` per dimension (the centre of the oscillation).
    pub anchor: Vec<f64>,
    /// Amplitude `r` per dimension (1 after learning; scale it to scale the movement).
    pub amplitude: Vec<f64>,
    /// Weights, dimension-major (`w[d * n_basis + i]`).
    pub weights: Vec<f64>,
    /// Start position per dimension.
    pub start: Vec<f64>,
    /// Start velocity per dimension (units per second); learning sets the demonstration's,
    /// so the rollout is on its limit cycle from the first sample.
    pub start_velocity: Vec<f64>,
}

/// A sampled rhythmic trajectory: `position[d][k]`, `velocity[d][k]` at `times[k]`.
#[derive(Debug, Clone, PartialEq)]
pub struct RhythmicRollout {
    /// Sample times in seconds.
    pub times: Vec<f64>,
    /// Positions, dimension-major.
    pub position: Vec<Vec<f64>>,
    /// Physical velocities, dimension-major.
    pub velocity: Vec<Vec<f64>>,
}

fn basis(phi: f64, n: usize, h: f64, out: &mut [f64]) -> f64 {
    let mut sum = 0.0;
    for (i, o) in out.iter_mut().enumerate().take(n) {
        let c = std::f64::consts::TAU * i as f64 / n as f64;
        *o = (h * ((phi - c).cos() - 1.0)).exp();
        sum += *o;
    }
    sum
}

impl RhythmicDmp {
    fn check(&self) -> Result<usize, DmpError> {
        let dims = self.anchor.len();
        positive("alpha_z", self.alpha_z)?;
        positive("beta_z", self.beta_z)?;
        positive("tau", self.tau)?;
        positive("width", self.width)?;
        at_least_one("n_basis", self.n_basis)?;
        if dims == 0 {
            return Err(DmpError::NoDimensions);
        }
        for (what, len) in [
            ("amplitude", self.amplitude.len()),
            ("start", self.start.len()),
            ("start_velocity", self.start_velocity.len()),
        ] {
            if len != dims {
                return Err(DmpError::DimensionMismatch {
                    what,
                    got: len,
                    expected: dims,
                });
            }
        }
        if self.weights.len() != dims * self.n_basis {
            return Err(DmpError::DimensionMismatch {
                what: "weights",
                got: self.weights.len(),
                expected: dims * self.n_basis,
            });
        }
        Ok(dims)
    }

    /// The forcing term of dimension `d` at phase `phi`.
    pub fn forcing(&self, d: usize, phi: f64) -> f64 {
        let mut psi = vec![0.0; self.n_basis];
        let sum = basis(phi, self.n_basis, self.width, &mut psi);
        let w = &self.weights[d * self.n_basis..(d + 1) * self.n_basis];
        self.amplitude[d] * psi.iter().zip(w).map(|(p, w)| p * w).sum::<f64>() / sum
    }

    /// Rolls out `duration` seconds on a grid of `round(duration / dt)` steps.
    pub fn rollout(&self, duration: f64, dt: f64) -> Result<RhythmicRollout, DmpError> {
        let dims = self.check()?;
        if !(dt.is_finite() && dt > 0.0 && duration.is_finite() && duration >= dt) {
            return Err(DmpError::InvalidConfig {
                field: "dt",
                rule: "must be finite, > 0 and at most the duration",
                value: dt,
            });
        }
        let steps = (duration / dt).round() as usize;
        let h = duration / steps as f64;
        let c = StepCoefficients::new(self.alpha_z, self.beta_z, self.tau, h);
        let times: Vec<f64> = (0..=steps).map(|k| k as f64 * h).collect();
        let n = self.n_basis;
        // Forcing per sample (shared basis evaluation for all dimensions).
        let mut f = vec![vec![0.0; steps + 1]; dims];
        let mut psi = vec![0.0; n];
        for (k, &t) in times.iter().enumerate() {
            let sum = basis(t / self.tau, n, self.width, &mut psi);
            for (d, fd) in f.iter_mut().enumerate() {
                let w = &self.weights[d * n..(d + 1) * n];
                fd[k] =
                    self.amplitude[d] * psi.iter().zip(w).map(|(p, w)| p * w).sum::<f64>() / sum;
            }
        }
        let mut position = vec![vec![0.0; steps + 1]; dims];
        let mut velocity = vec![vec![0.0; steps + 1]; dims];
        for d in 0..dims {
            let ug = c.goal_input(self.anchor[d]);
            let (mut y, mut z) = (self.start[d], self.start_velocity[d] * self.tau);
            for k in 0..=steps {
                position[d][k] = y;
                velocity[d][k] = c.velocity(z);
                let next = (k + 1).min(steps);
                (y, z) = c.advance(y, z, ug + f[d][k], ug + f[d][next]);
            }
        }
        Ok(RhythmicRollout {
            times,
            position,
            velocity,
        })
    }

    /// Learns a rhythmic DMP from one period of a periodic movement: `times` and `rows`
    /// cover exactly one period, the last sample being the first of the next period (so
    /// `rows[last] ≈ rows[0]`). The period `P = t_last − t_0` sets `τ = P / 2π`; the
    /// anchor is the period's mean; the amplitude is 1. The period is resampled onto
    /// `samples` points, differentiated with periodic fourth-order central differences, and
    /// the weights solve the ridge regression (λ) of the forcing target on the normalised
    /// basis.
    pub fn learn(
        times: &[f64],
        rows: &[Vec<f64>],
        n_basis: usize,
        samples: usize,
        lambda: f64,
    ) -> Result<Self, DmpError> {
        let demo = crate::Demonstration::new(times.to_vec(), rows)?;
        if samples < 8 {
            return Err(DmpError::InvalidConfig {
                field: "samples",
                rule: "must be at least 8",
                value: samples as f64,
            });
        }
        if !(lambda.is_finite() && lambda >= 0.0) {
            return Err(DmpError::InvalidConfig {
                field: "lambda",
                rule: "must be finite and ≥ 0",
                value: lambda,
            });
        }
        let dims = demo.dims();
        let period = demo.duration();
        let tau = period / std::f64::consts::TAU;
        // samples + 1 points over [0, P]: drop the last (it repeats the first).
        let closed = demo.resample(samples + 1);
        let y: Vec<Vec<f64>> = closed.iter().map(|v| v[..samples].to_vec()).collect();
        let h = period / samples as f64;
        let (alpha_z, beta_z) = (25.0, 25.0 / 4.0);
        let width = 2.5 * n_basis as f64;
        let m = samples;
        // Normalised basis rows, m × N.
        let mut phi = vec![0.0; m * n_basis];
        for k in 0..m {
            let row = &mut phi[k * n_basis..(k + 1) * n_basis];
            let sum = basis(k as f64 * h / tau, n_basis, width, row);
            row.iter_mut().for_each(|v| *v /= sum);
        }
        let mut gram = faer::Mat::<f64>::zeros(n_basis, n_basis);
        for k in 0..m {
            let row = &phi[k * n_basis..(k + 1) * n_basis];
            for i in 0..n_basis {
                for j in 0..n_basis {
                    gram[(i, j)] += row[i] * row[j];
                }
            }
        }
        for i in 0..n_basis {
            gram[(i, i)] += lambda;
        }
        let at = |v: &[f64], k: isize| v[k.rem_euclid(m as isize) as usize];
        let mut weights = Vec::with_capacity(dims * n_basis);
        let mut anchor = Vec::with_capacity(dims);
        let mut start_velocity = Vec::with_capacity(dims);
        let mut rhs = faer::Mat::<f64>::zeros(n_basis, dims);
        for (d, yd) in y.iter().enumerate() {
            let g = yd.iter().sum::<f64>() / m as f64;
            anchor.push(g);
            for k in 0..m as isize {
                let (ym2, ym1, y0, yp1, yp2) = (
                    at(yd, k - 2),
                    at(yd, k - 1),
                    at(yd, k),
                    at(yd, k + 1),
                    at(yd, k + 2),
                );
                let v = (ym2 - yp2 + 8.0 * (yp1 - ym1)) / (12.0 * h);
                let a = (16.0 * (ym1 + yp1) - (ym2 + yp2) - 30.0 * y0) / (12.0 * h * h);
                if k == 0 {
                    start_velocity.push(v);
                }
                let f = tau * tau * a - alpha_z * (beta_z * (g - y0) - tau * v);
                let row = &phi[k as usize * n_basis..(k as usize + 1) * n_basis];
                for i in 0..n_basis {
                    rhs[(i, d)] += row[i] * f;
                }
            }
        }
        let sol = match gram.llt(faer::Side::Lower) {
            Ok(l) => faer::linalg::solvers::Solve::solve(&l, &rhs),
            Err(_) => {
                return Err(DmpError::NumericalFailure(
                    "the rhythmic regression is singular; use λ > 0 or fewer basis functions"
                        .into(),
                ));
            }
        };
        for d in 0..dims {
            weights.extend((0..n_basis).map(|i| sol[(i, d)]));
        }
        Ok(Self {
            alpha_z,
            beta_z,
            tau,
            width,
            n_basis,
            anchor,
            amplitude: vec![1.0; dims],
            weights,
            start: y.iter().map(|v| v[0]).collect(),
            start_velocity,
        })
    }
}
