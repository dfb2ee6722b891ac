//! The discrete DMP: precomputation and rollouts.

use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef, Par};

use crate::discretize::StepCoefficients;
use crate::{CanonicalSystem, DmpConfig, DmpError, GaussianBasis, Trajectory};

/// A discrete DMP with one transformation system per dimension (Ijspeert et al. 2013):
///
/// `tau ż = alpha_z (beta_z (g - y) - z) + f(x)`, `tau ẏ = z`, with the forcing term
/// `f(x) = (g - y0) · x · Σ psi_i(x) w_i / Σ psi_i(x)` and `x` the phase of a
/// [`CanonicalSystem`]. All dimensions share phase, basis and `tau`.
///
/// Integration: the linear transformation system is discretised exactly, with the
/// forcing term interpolated linearly between grid samples (see the `discretize`
/// module): unconditionally stable, exact without forcing, second order in `dt`.
///
/// Weights are passed as one slice, dimension-major: `w[d * n_basis + i]` is basis `i` of
/// dimension `d` (the thesis's `(nr_dmps, nr_bfs)` layout).
///
/// When `g == y0` in a dimension the forcing term vanishes there and the DMP can only
/// stay at `y0`; [`DiscreteDmp::amplitude`] exposes `g - y0` so callers can say so.
#[derive(Debug, Clone)]
pub struct DiscreteDmp {
    config: DmpConfig,
    start: Vec<f64>,
    goal: Vec<f64>,
    basis: GaussianBasis,
    times: Vec<f64>,
    phases: Vec<f64>,
    /// Features, (K+1) × N, column-major.
    features: Vec<f64>,
    coefficients: StepCoefficients,
}

impl DiscreteDmp {
    /// Builds the DMP and precomputes everything that does not depend on the weights.
    pub fn new(config: DmpConfig, start: &[f64], goal: &[f64]) -> Result<Self, DmpError> {
        config.validate()?;
        if start.is_empty() {
            return Err(DmpError::NoDimensions);
        }
        if goal.len() != start.len() {
            return Err(DmpError::DimensionMismatch {
                what: "goal",
                got: goal.len(),
                expected: start.len(),
            });
        }
        for (what, v) in [("start", start), ("goal", goal)] {
            if let Some((index, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                return Err(DmpError::NotFinite { what, index, value });
            }
        }
        let k = config.n_steps();
        let h = config.step();
        let cs = CanonicalSystem {
            alpha_x: config.alpha_x,
            tau: config.tau,
        };
        let times: Vec<f64> = (0..=k).map(|i| i as f64 * h).collect();
        let phases: Vec<f64> = times.iter().map(|&t| cs.phase(t)).collect();
        let basis = GaussianBasis::new(config.n_basis, config.alpha_x);
        let n = config.n_basis;
        let mut features = vec![0.0; (k + 1) * n];
        let mut row = vec![0.0; n];
        for (s, &x) in phases.iter().enumerate() {
            basis.features(x, &mut row);
            for (i, &v) in row.iter().enumerate() {
                features[i * (k + 1) + s] = v;
            }
        }
        let coefficients = StepCoefficients::new(config.alpha_z, config.beta_z, config.tau, h);
        Ok(Self {
            config,
            start: start.to_vec(),
            goal: goal.to_vec(),
            basis,
            times,
            phases,
            features,
            coefficients,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &DmpConfig {
        &self.config
    }

    /// Number of dimensions.
    pub fn dims(&self) -> usize {
        self.start.len()
    }

    /// Basis functions per dimension.
    pub fn n_basis(&self) -> usize {
        self.config.n_basis
    }

    /// Length of the weight vector: `dims * n_basis`.
    pub fn n_weights(&self) -> usize {
        self.dims() * self.n_basis()
    }

    /// Number of samples on the grid (`round(tau/dt) + 1`).
    pub fn n_samples(&self) -> usize {
        self.times.len()
    }

    /// Sample times in seconds.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// The phase `x` at each sample.
    pub fn phases(&self) -> &[f64] {
        &self.phases
    }

    /// The basis functions.
    pub fn basis(&self) -> &GaussianBasis {
        &self.basis
    }

    /// Start position `y0`.
    pub fn start(&self) -> &[f64] {
        &self.start
    }

    /// Goal position `g`.
    pub fn goal(&self) -> &[f64] {
        &self.goal
    }

    /// `g - y0` of dimension `dim`, the factor the forcing term is scaled by.
    pub fn amplitude(&self, dim: usize) -> f64 {
        self.goal[dim] - self.start[dim]
    }

    /// The forcing features of basis `i` at every sample: `x ψ_i(x) / Σ ψ(x)`.
    pub fn feature_column(&self, i: usize) -> &[f64] {
        let n = self.n_samples();
        &self.features[i * n..(i + 1) * n]
    }

    /// A zeroed trajectory on this DMP's grid, to reuse with [`Self::rollout_into`].
    pub fn new_trajectory(&self) -> Trajectory {
        Trajectory::zeros(self.dims(), self.times.clone())
    }

    /// Rolls out the DMP for `weights` into a new trajectory.
    ///
    /// # Panics
    /// If `weights.len() != n_weights()`.
    pub fn rollout(&self, weights: &[f64]) -> Trajectory {
        let mut traj = self.new_trajectory();
        self.rollout_into(weights, &mut traj);
        traj
    }

    /// Rolls out the DMP for `weights` into `traj` without allocating.
    ///
    /// # Panics
    /// If `weights.len() != n_weights()` or `traj` was not made by [`Self::new_trajectory`]
    /// of a DMP with the same grid and dimensions.
    pub fn rollout_into(&self, weights: &[f64], traj: &mut Trajectory) {
        let (n, dims, ns) = (self.n_basis(), self.dims(), self.n_samples());
        assert_eq!(
            weights.len(),
            dims * n,
            "weight vector length must be dims * n_basis"
        );
        assert!(
            traj.dims() == dims && traj.n_samples() == ns,
            "trajectory shape mismatch"
        );
        // 1. Forcing features times weights: F = Φ W, (K+1) × dims, one GEMM.
        let phi = MatRef::from_column_major_slice(&self.features, ns, n);
        let w = MatRef::from_column_major_slice(weights, n, dims);
        let f = MatMut::from_column_major_slice_mut(&mut traj.forcing, ns, dims);
        matmul(f, Accum::Replace, phi, w, 1.0, Par::Seq);
        // 2. The recurrence, four dimensions at a time so independent chains overlap.
        let mut d0 = 0;
        while d0 < dims {
            let width = (dims - d0).min(LANES);
            self.integrate_group(d0, width, traj);
            d0 += width;
        }
    }

    /// Rolls out a population: `weights` holds `out.len()` weight vectors back to back.
    ///
    /// # Panics
    /// If `weights.len() != out.len() * n_weights()` or a trajectory has the wrong shape.
    pub fn rollout_batch(&self, weights: &[f64], out: &mut [Trajectory]) {
        let nw = self.n_weights();
        assert_eq!(weights.len(), out.len() * nw, "population weight length");
        for (w, traj) in weights.chunks_exact(nw).zip(out.iter_mut()) {
            self.rollout_into(w, traj);
        }
    }

    /// Integrates dimensions `d0 .. d0 + width` (width ≤ LANES) reading the unscaled
    /// forcing from `traj.forcing` and writing position, velocity, acceleration and the
    /// scaled forcing.
    fn integrate_group(&self, d0: usize, width: usize, traj: &mut Trajectory) {
        let ns = self.n_samples();
        let c = &self.coefficients;
        let (az, bz, tau) = (self.config.alpha_z, self.config.beta_z, self.config.tau);
        let kk = az * bz;
        let (inv_tau, inv_tau2) = (1.0 / tau, 1.0 / (tau * tau));
        let mut y = [0.0; LANES];
        let mut z = [0.0; LANES];
        let mut g = [0.0; LANES];
        let mut amp = [0.0; LANES];
        for j in 0..LANES {
            let d = d0 + j.min(width - 1);
            y[j] = self.start[d];
            g[j] = self.goal[d];
            amp[j] = g[j] - y[j];
        }
        let base: [usize; LANES] = std::array::from_fn(|j| (d0 + j.min(width - 1)) * ns);
        // Scale the forcing in place: f = (g - y0) · Φ w.
        for j in 0..width {
            for v in &mut traj.forcing[base[j]..base[j] + ns] {
                *v *= amp[j];
            }
        }
        let mut u = [0.0; LANES];
        for j in 0..LANES {
            u[j] = kk * g[j] + traj.forcing[base[j]];
        }
        for s in 0..ns {
            let mut u_next = [0.0; LANES];
            for j in 0..LANES {
                let idx = base[j] + s;
                traj.position[idx] = y[j];
                traj.velocity[idx] = z[j] * inv_tau;
                traj.acceleration[idx] = (u[j] - kk * y[j] - az * z[j]) * inv_tau2;
                if s + 1 < ns {
                    u_next[j] = kk * g[j] + traj.forcing[idx + 1];
                }
                let yn = c.e[0][0] * y[j] + c.e[0][1] * z[j] + c.b0[0] * u[j] + c.b1[0] * u_next[j];
                let zn = c.e[1][0] * y[j] + c.e[1][1] * z[j] + c.b0[1] * u[j] + c.b1[1] * u_next[j];
                y[j] = yn;
                z[j] = zn;
            }
            u = u_next;
        }
    }
}

/// Dimensions integrated together (padding lanes repeat the last real dimension and are
/// written identically, so they are harmless).
const LANES: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;

    fn thesis_dmp(tau: f64) -> DiscreteDmp {
        DiscreteDmp::new(
            DmpConfig::new(25, tau, 0.01),
            &[0.75, 0.02, 1.87],
            &[0.55, -0.57, 1.45],
        )
        .unwrap()
    }

    #[test]
    fn zero_weights_converge_to_the_goal() {
        let dmp = thesis_dmp(10.0);
        let traj = dmp.rollout(&vec![0.0; dmp.n_weights()]);
        let last = traj.n_samples() - 1;
        for d in 0..3 {
            // Critically damped spring: the error shrinks monotonically, and after tau it is
            // (1 + 12.5) e^-12.5 ≈ 5e-5 of the distance.
            let err: Vec<f64> = traj
                .position(d)
                .iter()
                .map(|y| (y - dmp.goal()[d]).abs())
                .collect();
            assert!(err.windows(2).all(|e| e[1] <= e[0]));
            assert!(err[last] < 5.1e-5 * dmp.amplitude(d).abs());
            assert!(traj.velocity(d)[last].abs() < 1e-4);
        }
    }

    #[test]
    fn unforced_rollout_matches_the_analytic_solution() {
        // Critically damped: y(t) = g + (y0 - g)(1 + ω t) e^{-ω t}, ω = alpha_z / (2 tau).
        let dmp = thesis_dmp(10.0);
        let traj = dmp.rollout(&vec![0.0; dmp.n_weights()]);
        let w = 25.0 / 2.0 / 10.0;
        for (s, &t) in traj.times().iter().enumerate() {
            for d in 0..3 {
                let (y0, g) = (dmp.start()[d], dmp.goal()[d]);
                let y = g + (y0 - g) * (1.0 + w * t) * (-w * t).exp();
                let v = (y0 - g) * (-w * w * t) * (-w * t).exp();
                let a = (y0 - g) * w * w * (w * t - 1.0) * (-w * t).exp();
                assert!((traj.position(d)[s] - y).abs() < 1e-13);
                assert!((traj.velocity(d)[s] - v).abs() < 1e-13);
                assert!((traj.acceleration(d)[s] - a).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn rollout_is_affine_in_the_weights() {
        let dmp = thesis_dmp(10.0);
        let nw = dmp.n_weights();
        let w1: Vec<f64> = (0..nw)
            .map(|i| ((i * 37 % 11) as f64 - 5.0) * 30.0)
            .collect();
        let w2: Vec<f64> = (0..nw)
            .map(|i| ((i * 13 % 7) as f64 - 3.0) * 100.0)
            .collect();
        let (a, b) = (0.3, -1.7);
        let mix: Vec<f64> = w1.iter().zip(&w2).map(|(x, y)| a * x + b * y).collect();
        let t0 = dmp.rollout(&vec![0.0; nw]);
        let (t1, t2, tm) = (dmp.rollout(&w1), dmp.rollout(&w2), dmp.rollout(&mix));
        for d in 0..3 {
            for s in 0..t0.n_samples() {
                let lin = |q: fn(&Trajectory, usize) -> &[f64]| {
                    let z = q(&t0, d)[s];
                    z + a * (q(&t1, d)[s] - z) + b * (q(&t2, d)[s] - z)
                };
                assert!((tm.position(d)[s] - lin(Trajectory::position)).abs() < 1e-9);
                assert!((tm.velocity(d)[s] - lin(Trajectory::velocity)).abs() < 1e-9);
                assert!((tm.acceleration(d)[s] - lin(Trajectory::acceleration)).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn more_than_four_dimensions_roll_out_like_single_ones() {
        let start = [0.0, 1.0, -2.0, 0.5, 3.0, 0.1];
        let goal = [1.0, -1.0, 2.0, 0.7, 2.0, -0.4];
        let cfg = DmpConfig::new(8, 2.0, 0.01);
        let dmp = DiscreteDmp::new(cfg, &start, &goal).unwrap();
        let w: Vec<f64> = (0..dmp.n_weights())
            .map(|i| (i as f64 * 0.7).sin() * 50.0)
            .collect();
        let all = dmp.rollout(&w);
        for d in 0..6 {
            let single = DiscreteDmp::new(cfg, &start[d..=d], &goal[d..=d]).unwrap();
            let t = single.rollout(&w[d * 8..(d + 1) * 8]);
            assert_eq!(t.position(0), all.position(d));
            assert_eq!(t.acceleration(0), all.acceleration(d));
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let cfg = DmpConfig::new(5, 1.0, 0.01);
        assert!(matches!(
            DiscreteDmp::new(cfg, &[0.0, 1.0], &[1.0]),
            Err(DmpError::DimensionMismatch { .. })
        ));
        assert!(matches!(
            DiscreteDmp::new(cfg, &[f64::NAN], &[1.0]),
            Err(DmpError::NotFinite { what: "start", .. })
        ));
        assert!(matches!(
            DiscreteDmp::new(cfg, &[], &[]),
            Err(DmpError::NoDimensions)
        ));
        for (cfg, field) in [
            (DmpConfig { tau: 0.0, ..cfg }, "tau"),
            (DmpConfig { dt: 2.0, ..cfg }, "dt"),
            (DmpConfig { dt: -0.1, ..cfg }, "dt"),
            (DmpConfig { n_basis: 0, ..cfg }, "n_basis"),
            (
                DmpConfig {
                    alpha_z: f64::NAN,
                    ..cfg
                },
                "alpha_z",
            ),
        ] {
            match DiscreteDmp::new(cfg, &[0.0], &[1.0]) {
                Err(DmpError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }
}
