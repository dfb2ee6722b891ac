//! The discrete DMP: precomputation and rollouts.

use std::sync::Arc;

use pulp::{Arch, Simd, WithSimd};

use crate::discretize::StepCoefficients;
use crate::{CanonicalSystem, DmpConfig, DmpError, Formulation, GaussianBasis, Trajectory};

/// A discrete DMP with one transformation system per dimension:
///
/// `tau ż = alpha_z (beta_z (g - y) - z) + f(x)`, `tau ẏ = z`, with `x` the phase of a
/// [`CanonicalSystem`] and the forcing term `f` of the configured [`Formulation`]
/// (default Ijspeert et al. 2013: `f(x) = (g - y0) · x · Σ psi_i(x) w_i / Σ psi_i(x)`).
/// All dimensions share phase, basis and `tau`.
///
/// Integration: the linear transformation system is discretised exactly, with the
/// forcing term interpolated linearly between grid samples (see the `discretize`
/// module): unconditionally stable, exact without forcing, second order in `dt`.
///
/// Weights are passed as one slice, dimension-major: `w[d * n_basis + i]` is basis `i` of
/// dimension `d` (the thesis's `(nr_dmps, nr_bfs)` layout).
///
/// In the Ijspeert form, when `g == y0` in a dimension the forcing term vanishes there and
/// the DMP can only stay at `y0`; [`DiscreteDmp::amplitude`] exposes `g - y0` so callers
/// can say so, and imitation refuses such a dimension with advice to use
/// [`Formulation::GoalRobust`], whose forcing term does not scale with `g − y0`.
#[derive(Debug, Clone)]
pub struct DiscreteDmp {
    config: DmpConfig,
    start: Vec<f64>,
    goal: Vec<f64>,
    /// Everything that depends only on the configuration, shared between DMPs that differ
    /// only in start and goal (cloning a DMP is cheap).
    grid: Arc<Grid>,
    arch: Arch,
}

/// The weight- and endpoint-independent precomputation of a [`DiscreteDmp`].
#[derive(Debug)]
pub(crate) struct Grid {
    pub(crate) basis: GaussianBasis,
    pub(crate) times: Vec<f64>,
    pub(crate) phases: Vec<f64>,
    /// Features, (K+1) × N, column-major.
    pub(crate) features: Vec<f64>,
    /// The same features packed chunk-major for the forcing kernel.
    packed: Vec<f64>,
    /// The same features row-major ((K+1) rows of N) for the streaming batch rollout.
    rows: Vec<f64>,
    coefficients: StepCoefficients,
}

impl DiscreteDmp {
    /// Builds the DMP and precomputes everything that does not depend on the weights.
    pub fn new(config: DmpConfig, start: &[f64], goal: &[f64]) -> Result<Self, DmpError> {
        config.validate()?;
        let grid = Arc::new(Grid::new(&config));
        Self::checked(config, start, goal, grid)
    }

    /// The same DMP (configuration, grid, basis) with other endpoints, without redoing the
    /// precomputation.
    pub fn with_endpoints(&self, start: &[f64], goal: &[f64]) -> Result<Self, DmpError> {
        Self::checked(self.config, start, goal, Arc::clone(&self.grid))
    }

    fn checked(
        config: DmpConfig,
        start: &[f64],
        goal: &[f64],
        grid: Arc<Grid>,
    ) -> Result<Self, DmpError> {
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
        Ok(Self {
            config,
            start: start.to_vec(),
            goal: goal.to_vec(),
            grid,
            arch: Arch::new(),
        })
    }

    /// The precomputed grid.
    pub(crate) fn grid(&self) -> &Grid {
        &self.grid
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
        self.grid.times.len()
    }

    /// Sample times in seconds.
    pub fn times(&self) -> &[f64] {
        &self.grid.times
    }

    /// The phase `x` at each sample.
    pub fn phases(&self) -> &[f64] {
        &self.grid.phases
    }

    /// The basis functions.
    pub fn basis(&self) -> &GaussianBasis {
        &self.grid.basis
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

    /// The forcing term of dimension `dim` is `f = a · (Φ w) + b · x` with `(a, b)` from
    /// this method: `(g − y0, 0)` in the [`Formulation::Ijspeert2013`] form,
    /// `(α_z β_z, −α_z β_z (g − y0))` in the [`Formulation::GoalRobust`] form.
    pub fn forcing_scale(&self, dim: usize) -> (f64, f64) {
        let amp = self.amplitude(dim);
        match self.config.formulation {
            Formulation::Ijspeert2013 => (amp, 0.0),
            Formulation::GoalRobust => {
                let k = self.config.alpha_z * self.config.beta_z;
                (k, -k * amp)
            }
        }
    }

    /// The forcing features of basis `i` at every sample: `x ψ_i(x) / Σ ψ(x)`.
    pub fn feature_column(&self, i: usize) -> &[f64] {
        let n = self.n_samples();
        &self.grid.features[i * n..(i + 1) * n]
    }

    /// A zeroed trajectory on this DMP's grid, to reuse with [`Self::rollout_into`].
    pub fn new_trajectory(&self) -> Trajectory {
        Trajectory::zeros(self.dims(), self.grid.times.clone())
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
            packed: &self.grid.packed,
            weights,
            n_basis: n,
            out: &mut traj.forcing,
        });
        // 2. The exact recurrence, several dimensions at a time: the chain through the
        //    state is sequential, so independent dimensions overlap in the CPU, and the
        //    inputs and physical outputs of each step are computed off the critical path.
        let mut d0 = 0;
        while d0 < dims {
            let width = (dims - d0).min(LANES);
            match width {
                1 => self.chain::<1>(d0, traj),
                2 => self.chain::<2>(d0, traj),
                3 => self.chain::<3>(d0, traj),
                _ => self.chain::<4>(d0, traj),
            }
            d0 += width;
        }
    }

    /// The recurrence for dimensions `d0 .. d0 + W`, reading the unscaled forcing `Φ w`
    /// from `traj.forcing` and writing position, physical velocity and acceleration and the
    /// scaled forcing `f = (g − y0) Φ w`. One step of one dimension:
    ///
    /// `u_k = α_z β_z g + f_k`, `ÿ_k = (u_k − α_z β_z y_k − α_z z_k) / τ²`, `ẏ_k = z_k / τ`,
    /// `(y, z)_{k+1} = E (y, z)_k + b0 u_k + b1 u_{k+1}`.
    #[inline(always)]
    fn chain<const W: usize>(&self, d0: usize, traj: &mut Trajectory) {
        let ns = self.n_samples();
        let c = &self.grid.coefficients;
        let range = d0 * ns..(d0 + W) * ns;
        let mut pos = traj.position[range.clone()].chunks_exact_mut(ns);
        let mut vel = traj.velocity[range.clone()].chunks_exact_mut(ns);
        let mut acc = traj.acceleration[range.clone()].chunks_exact_mut(ns);
        let mut frc = traj.forcing[range].chunks_exact_mut(ns);
        let pos: [&mut [f64]; W] = std::array::from_fn(|_| pos.next().expect("lane"));
        let vel: [&mut [f64]; W] = std::array::from_fn(|_| vel.next().expect("lane"));
        let acc: [&mut [f64]; W] = std::array::from_fn(|_| acc.next().expect("lane"));
        let frc: [&mut [f64]; W] = std::array::from_fn(|_| frc.next().expect("lane"));
        let (amp, off): ([f64; W], [f64; W]) = (
            std::array::from_fn(|j| self.forcing_scale(d0 + j).0),
            std::array::from_fn(|j| self.forcing_scale(d0 + j).1),
        );
        let x = &self.grid.phases;
        let ug: [f64; W] = std::array::from_fn(|j| c.goal_input(self.goal[d0 + j]));
        let mut y: [f64; W] = std::array::from_fn(|j| self.start[d0 + j]);
        let mut z = [0.0; W];
        let mut f: [f64; W] = std::array::from_fn(|j| amp[j] * frc[j][0] + off[j] * x[0]);
        for k in 0..ns {
            let next = (k + 1).min(ns - 1);
            for j in 0..W {
                let f1 = amp[j] * frc[j][next] + off[j] * x[next];
                let (u0, u1) = (ug[j] + f[j], ug[j] + f1);
                pos[j][k] = y[j];
                vel[j][k] = c.velocity(z[j]);
                acc[j][k] = c.acceleration(u0, y[j], z[j]);
                frc[j][k] = f[j];
                (y[j], z[j]) = c.advance(y[j], z[j], u0, u1);
                f[j] = f1;
            }
        }
    }

    /// Rolls out up to [`BATCH_LANES`] weight vectors at once without storing their
    /// trajectories, for costs that can be accumulated sample by sample (the fast path of
    /// population evaluation). `weights` holds `m ≤ BATCH_LANES` weight vectors back to back;
    /// `visitor.visit(k, d, y, v, a)` is called for every sample `k` (in order) and
    /// dimension `d` with the position, physical velocity and acceleration of every lane.
    /// Lanes `m..` repeat the last vector. Mark the visitor's `visit` `#[inline(always)]`:
    /// it then runs inside the SIMD context too.
    ///
    /// The arithmetic is the same exact recurrence as [`Self::rollout_into`]; results agree
    /// to rounding (the forcing sum may be fused differently).
    ///
    /// # Panics
    /// If `weights` is empty, longer than `BATCH_LANES` vectors or not a whole number of them.
    pub fn rollout_stream<V: StreamVisitor>(&self, weights: &[f64], visitor: &mut V) {
        let nw = self.n_weights();
        let m = weights.len() / nw;
        assert!(
            (1..=BATCH_LANES).contains(&m) && weights.len() == m * nw,
            "rollout_stream takes 1 to {BATCH_LANES} weight vectors"
        );
        self.arch.dispatch(Stream {
            dmp: self,
            weights,
            m,
            visit: visitor,
        });
    }

    /// Rolls out a population: `weights` holds `out.len()` weight vectors back to back.
    /// (Measured: storing the streaming kernel's lanes costs more than it saves, so this is
    /// one [`Self::rollout_into`] per candidate; use [`Self::rollout_stream`] when only
    /// costs are needed.)
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

impl Grid {
    fn new(config: &DmpConfig) -> Self {
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
        // Row-major (for the streaming rollout) and column-major (for the forcing kernel).
        let mut rows = vec![0.0; (k + 1) * n];
        let mut features = vec![0.0; (k + 1) * n];
        for (s, (&x, row)) in phases.iter().zip(rows.chunks_exact_mut(n)).enumerate() {
            basis.features(x, row);
            for (i, &v) in row.iter().enumerate() {
                features[i * (k + 1) + s] = v;
            }
        }
        let coefficients = StepCoefficients::new(config.alpha_z, config.beta_z, config.tau, h);
        Grid {
            packed: pack_features(&features, k + 1, n),
            basis,
            times,
            phases,
            rows,
            features,
            coefficients,
        }
    }
}

/// Candidates rolled out together by [`DiscreteDmp::rollout_stream`].
pub const BATCH_LANES: usize = 8;

/// One value per lane of [`DiscreteDmp::rollout_stream`].
pub type Lanes = [f64; BATCH_LANES];

/// The streaming batch rollout: lanes are candidates, so every operation is a SIMD
/// operation over [`BATCH_LANES`] candidates, and nothing is stored.
struct Stream<'a, V> {
    dmp: &'a DiscreteDmp,
    weights: &'a [f64],
    m: usize,
    visit: &'a mut V,
}

/// Receives the samples of [`DiscreteDmp::rollout_stream`].
pub trait StreamVisitor {
    /// Sample `k` of dimension `d`: position, physical velocity and acceleration per lane.
    fn visit(&mut self, k: usize, d: usize, y: &Lanes, v: &Lanes, a: &Lanes);
}

impl<F: FnMut(usize, usize, &Lanes, &Lanes, &Lanes)> StreamVisitor for F {
    #[inline(always)]
    fn visit(&mut self, k: usize, d: usize, y: &Lanes, v: &Lanes, a: &Lanes) {
        self(k, d, y, v, a)
    }
}

impl<V: StreamVisitor> WithSimd for Stream<'_, V> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, _simd: S) {
        let Self {
            dmp,
            weights,
            m,
            visit,
        } = self;
        let (nb, dims) = (dmp.n_basis(), dmp.dims());
        let nw = nb * dims;
        // Weights transposed to [d][i][lane], pre-multiplied by g − y0.
        let mut wt = vec![[0.0; BATCH_LANES]; nw];
        for d in 0..dims {
            let amp = dmp.forcing_scale(d).0;
            for i in 0..nb {
                for (l, w) in wt[d * nb + i].iter_mut().enumerate() {
                    *w = amp * weights[l.min(m - 1) * nw + d * nb + i];
                }
            }
        }
        // Dimensions in groups of up to three share each broadcast feature value.
        let mut d0 = 0;
        while d0 < dims {
            let width = (dims - d0).min(3);
            let wg = &wt[d0 * nb..(d0 + width) * nb];
            match width {
                1 => stream_group::<S, V, 1>(dmp, d0, wg, visit),
                2 => stream_group::<S, V, 2>(dmp, d0, wg, visit),
                _ => stream_group::<S, V, 3>(dmp, d0, wg, visit),
            }
            d0 += width;
        }
    }
}

/// `a * b + c`, fused wherever the dispatched SIMD level has FMA (all but the scalar
/// fallback).
#[inline(always)]
fn fma<S: Simd>(a: f64, b: f64, c: f64) -> f64 {
    if S::IS_SCALAR {
        a * b + c
    } else {
        a.mul_add(b, c)
    }
}

/// `Φ(k) · w + off · x` for `W` dimensions at once: each feature value is broadcast once for all of
/// them, and two partial sums per dimension shorten the FMA chains (more would spill
/// registers; successive steps' sums are independent and overlap anyway).
#[inline(always)]
fn stream_forcing<S: Simd, const W: usize>(
    row: &[f64],
    wt: &[Lanes],
    off: &[f64; W],
    x: f64,
) -> [Lanes; W] {
    let nb = row.len();
    const P: usize = 2;
    let mut part = [[[0.0; BATCH_LANES]; P]; W];
    for (p, o) in part.iter_mut().zip(off) {
        p[0] = [o * x; BATCH_LANES];
    }
    let full = nb - nb % P;
    for i0 in (0..full).step_by(P) {
        for q in 0..P {
            let phi = row[i0 + q];
            for (j, part) in part.iter_mut().enumerate() {
                let w = &wt[j * nb + i0 + q];
                for l in 0..BATCH_LANES {
                    part[q][l] = fma::<S>(phi, w[l], part[q][l]);
                }
            }
        }
    }
    for i in full..nb {
        let phi = row[i];
        for (j, part) in part.iter_mut().enumerate() {
            let w = &wt[j * nb + i];
            for l in 0..BATCH_LANES {
                part[0][l] = fma::<S>(phi, w[l], part[0][l]);
            }
        }
    }
    let mut f = [[0.0; BATCH_LANES]; W];
    for j in 0..W {
        for l in 0..BATCH_LANES {
            f[j][l] = part[j][0][l] + part[j][1][l];
        }
    }
    f
}

/// The streaming rollout of dimensions `d0 .. d0 + W` (weights `wt` of these dimensions).
#[inline(always)]
fn stream_group<S: Simd, V: StreamVisitor, const W: usize>(
    dmp: &DiscreteDmp,
    d0: usize,
    wt: &[Lanes],
    visit: &mut V,
) {
    let (nb, ns) = (dmp.n_basis(), dmp.n_samples());
    let c = &dmp.grid.coefficients;
    let row = |k: usize| &dmp.grid.rows[k * nb..(k + 1) * nb];
    let ug: [f64; W] = std::array::from_fn(|j| c.goal_input(dmp.goal[d0 + j]));
    let mut y: [Lanes; W] = std::array::from_fn(|j| [dmp.start[d0 + j]; BATCH_LANES]);
    let mut z = [[0.0; BATCH_LANES]; W];
    let off: [f64; W] = std::array::from_fn(|j| dmp.forcing_scale(d0 + j).1);
    // f = a Φw + b x: the accumulators of Φw start at b x. (No closures here: they are
    // not reliably inlined into the SIMD context, and outside it `mul_add` becomes a slow
    // software call.)
    let x = &dmp.grid.phases;
    let mut f = stream_forcing::<S, W>(row(0), wt, &off, x[0]);
    for k in 0..ns {
        let next = (k + 1).min(ns - 1);
        let f_next = stream_forcing::<S, W>(row(next), wt, &off, x[next]);
        for j in 0..W {
            let (yd, zd, f0, f1) = (y[j], z[j], f[j], f_next[j]);
            let mut v = [0.0; BATCH_LANES];
            let mut a = [0.0; BATCH_LANES];
            for l in 0..BATCH_LANES {
                let (u0, u1) = (ug[j] + f0[l], ug[j] + f1[l]);
                v[l] = c.velocity(zd[l]);
                a[l] = c.acceleration(u0, yd[l], zd[l]);
                (y[j][l], z[j][l]) = c.advance(yd[l], zd[l], u0, u1);
            }
            visit.visit(k, d0 + j, &yd, &v, &a);
        }
        f = f_next;
    }
}

/// Dimensions integrated together in one recurrence loop.
const LANES: usize = 4;

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
