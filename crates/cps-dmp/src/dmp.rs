//! The discrete DMP: precomputation and rollouts.

use pulp::{Arch, Simd, WithSimd};

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
    /// The same features packed chunk-major for the forcing kernel.
    packed: Vec<f64>,
    coefficients: StepCoefficients,
    arch: Arch,
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
            packed: pack_features(&features, k + 1, n),
            features,
            coefficients,
            arch: Arch::new(),
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
        // 1. Forcing features times weights, F = Φ W, SIMD with runtime dispatch.
        self.arch.dispatch(ForcingProduct {
            packed: &self.packed,
            weights,
            n_basis: n,
            out: &mut traj.forcing,
        });
        // 2. The exact recurrence: vectorised inputs, the sequential chain several
        //    dimensions at a time (plain scalar code: independent chains overlap in the
        //    CPU, which SIMD shuffles would only slow down), vectorised outputs.
        self.arch.dispatch(Elementwise {
            dmp: self,
            pass: Pass::Inputs,
            traj: &mut *traj,
        });
        let mut d0 = 0;
        while d0 < dims {
            let width = (dims - d0).min(LANES);
            let range = d0 * ns..(d0 + width) * ns;
            let start: [f64; LANES] = std::array::from_fn(|j| self.start[d0 + j.min(width - 1)]);
            let pos = traj.position[range.clone()].chunks_exact_mut(ns);
            let vel = traj.velocity[range.clone()].chunks_exact_mut(ns);
            let acc = traj.acceleration[range].chunks_exact(ns);
            let e = self.coefficients.e;
            match width {
                1 => chain::<1>(e, &start, pos, vel, acc),
                2 => chain::<2>(e, &start, pos, vel, acc),
                3 => chain::<3>(e, &start, pos, vel, acc),
                _ => chain::<4>(e, &start, pos, vel, acc),
            }
            d0 += width;
        }
        self.arch.dispatch(Elementwise {
            dmp: self,
            pass: Pass::Outputs,
            traj: &mut *traj,
        });
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
}

/// Dimensions integrated together (and accumulated together in the forcing product).
const LANES: usize = 4;

/// The sequential part of the recurrence for `W` dimensions at once (independent chains
/// overlap in the CPU): `s_{k+1} = E s_k + c_k` with the inputs `c_k = (cy_k, cz_k)`
/// precomputed in `vel` and `acc`. Writes `y_k` to `pos` and the raw `z_k` over `vel`.
#[inline(never)]
fn chain<'a, const W: usize>(
    e: [[f64; 2]; 2],
    start: &[f64; LANES],
    pos: impl Iterator<Item = &'a mut [f64]>,
    vel: impl Iterator<Item = &'a mut [f64]>,
    acc: impl Iterator<Item = &'a [f64]>,
) {
    let [[e00, e01], [e10, e11]] = e;
    let mut pos = pos;
    let mut vel = vel;
    let mut acc = acc;
    let pos: [&mut [f64]; W] = std::array::from_fn(|_| pos.next().expect("lane"));
    let vel: [&mut [f64]; W] = std::array::from_fn(|_| vel.next().expect("lane"));
    let acc: [&[f64]; W] = std::array::from_fn(|_| acc.next().expect("lane"));
    let ns = pos[0].len();
    let mut y: [f64; W] = std::array::from_fn(|j| start[j]);
    let mut z = [0.0; W];
    for k in 0..ns {
        for j in 0..W {
            let (cy, cz) = (vel[j][k], acc[j][k]);
            pos[j][k] = y[j];
            vel[j][k] = z[j];
            let yn = cy + (e00 * y[j] + e01 * z[j]);
            let zn = cz + (e10 * y[j] + e11 * z[j]);
            y[j] = yn;
            z[j] = zn;
        }
    }
}

/// Samples per block of the packed feature matrix.
const CHUNK: usize = 16;

/// Packs Φ ((K+1) × N, column-major) chunk-major: block c holds, for each basis i, the
/// `CHUNK` feature values of samples `c*CHUNK ..`, zero-padded at the end.
fn pack_features(features: &[f64], ns: usize, nb: usize) -> Vec<f64> {
    let chunks = ns.div_ceil(CHUNK);
    let mut packed = vec![0.0; chunks * nb * CHUNK];
    for c in 0..chunks {
        for i in 0..nb {
            for l in 0..CHUNK {
                let k = c * CHUNK + l;
                if k < ns {
                    packed[(c * nb + i) * CHUNK + l] = features[i * ns + k];
                }
            }
        }
    }
    packed
}

/// `out[j] = Φ w_j` for `W` dimensions: `NV` SIMD vectors of accumulators per dimension
/// stay in registers while the N basis functions of a chunk are summed.
#[inline(always)]
fn forcing_kernel<S: Simd, const W: usize, const NV: usize>(
    simd: S,
    packed: &[f64],
    weights: [&[f64]; W],
    out: [&mut [f64]; W],
) {
    let nb = weights[0].len();
    let ns = out[0].len();
    let zero = simd.splat_f64s(0.0);
    for (c, block) in packed.chunks_exact(nb * CHUNK).enumerate() {
        let mut acc = [[zero; NV]; W];
        for i in 0..nb {
            let (v, _) = S::as_simd_f64s(&block[i * CHUNK..(i + 1) * CHUNK]);
            for j in 0..W {
                let w = simd.splat_f64s(weights[j][i]);
                for r in 0..NV {
                    acc[j][r] = simd.mul_add_e_f64s(w, v[r], acc[j][r]);
                }
            }
        }
        let k0 = c * CHUNK;
        let len = CHUNK.min(ns - k0);
        for j in 0..W {
            if len == CHUNK {
                let (ov, _) = S::as_mut_simd_f64s(&mut out[j][k0..k0 + CHUNK]);
                ov[..NV].copy_from_slice(&acc[j]);
            } else {
                let mut tmp = [0.0f64; CHUNK];
                let (tv, _) = S::as_mut_simd_f64s(&mut tmp);
                tv[..NV].copy_from_slice(&acc[j]);
                out[j][k0..k0 + len].copy_from_slice(&tmp[..len]);
            }
        }
    }
}

/// `out[d] = Φ w_d` for every dimension d, dimensions in groups of up to three.
struct ForcingProduct<'a> {
    packed: &'a [f64],
    weights: &'a [f64],
    n_basis: usize,
    out: &'a mut [f64],
}

impl WithSimd for ForcingProduct<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        #[inline(always)]
        fn group<S: Simd, const W: usize>(
            simd: S,
            packed: &[f64],
            w: &[f64],
            out: &mut [f64],
            nb: usize,
        ) {
            let ns = out.len() / W;
            let weights: [&[f64]; W] = std::array::from_fn(|j| &w[j * nb..(j + 1) * nb]);
            let mut it = out.chunks_exact_mut(ns);
            let out: [&mut [f64]; W] = std::array::from_fn(|_| it.next().expect("lane"));
            match S::F64_LANES {
                8 => forcing_kernel::<S, W, 2>(simd, packed, weights, out),
                4 => forcing_kernel::<S, W, 4>(simd, packed, weights, out),
                2 => forcing_kernel::<S, W, 8>(simd, packed, weights, out),
                _ => forcing_kernel::<S, W, 16>(simd, packed, weights, out),
            }
        }
        let nb = self.n_basis;
        let dims = self.weights.len() / nb;
        let ns = self.out.len() / dims;
        let mut d0 = 0;
        while d0 < dims {
            let width = (dims - d0).min(3);
            let w = &self.weights[d0 * nb..(d0 + width) * nb];
            let o = &mut self.out[d0 * ns..(d0 + width) * ns];
            match width {
                1 => group::<S, 1>(simd, self.packed, w, o, nb),
                2 => group::<S, 2>(simd, self.packed, w, o, nb),
                _ => group::<S, 3>(simd, self.packed, w, o, nb),
            }
            d0 += width;
        }
    }
}

/// Which vectorised pass of the recurrence to run over every dimension.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// Scale the forcing by `g − y0` and fold each step's inputs into
    /// `cy_k = b0_y u_k + b1_y u_{k+1}` and `cz_k` (likewise), `u = α_z β_z g + f`, stored
    /// in the velocity and acceleration buffers until [`Pass::Outputs`] overwrites them.
    Inputs,
    /// Physical outputs from the chain's `y` and raw `z`:
    /// `ÿ = (α_z β_z (g − y) − α_z z + f) / τ²`, `ẏ = z / τ`.
    Outputs,
}

/// The element-wise passes around the sequential chain, run under SIMD dispatch.
struct Elementwise<'a> {
    dmp: &'a DiscreteDmp,
    pass: Pass,
    traj: &'a mut Trajectory,
}

impl WithSimd for Elementwise<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, _simd: S) {
        let Self { dmp, pass, traj } = self;
        let ns = dmp.n_samples();
        let c = &dmp.coefficients;
        let cfg = &dmp.config;
        let (az, kk) = (cfg.alpha_z, cfg.alpha_z * cfg.beta_z);
        let (inv_tau, inv_tau2) = (1.0 / cfg.tau, 1.0 / (cfg.tau * cfg.tau));
        let parts = traj
            .position
            .chunks_exact(ns)
            .zip(traj.velocity.chunks_exact_mut(ns))
            .zip(traj.acceleration.chunks_exact_mut(ns))
            .zip(traj.forcing.chunks_exact_mut(ns));
        for (d, (((pos, vel), acc), f)) in parts.enumerate() {
            let g = dmp.goal[d];
            match pass {
                Pass::Inputs => {
                    let amp = g - dmp.start[d];
                    for v in f.iter_mut() {
                        *v *= amp;
                    }
                    let ug = kk * g;
                    let (b0y, b1y, b0z, b1z) = (c.b0[0], c.b1[0], c.b0[1], c.b1[1]);
                    let steps = vel
                        .iter_mut()
                        .zip(acc.iter_mut())
                        .zip(&f[..ns - 1])
                        .zip(&f[1..]);
                    for (((cy, cz), &f0), &f1) in steps {
                        let (u0, u1) = (ug + f0, ug + f1);
                        *cy = b0y * u0 + b1y * u1;
                        *cz = b0z * u0 + b1z * u1;
                    }
                }
                Pass::Outputs => {
                    let kg = kk * g;
                    for (((acc, vel), &y), &f) in
                        acc.iter_mut().zip(vel.iter_mut()).zip(pos).zip(f.iter())
                    {
                        let z = *vel;
                        *acc = (kg - kk * y - az * z + f) * inv_tau2;
                        *vel = z * inv_tau;
                    }
                }
            }
        }
    }
}

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
