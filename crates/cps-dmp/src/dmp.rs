//! The discrete DMP: precomputation and rollouts.

use std::sync::Arc;

use pulp::{Arch, Simd, WithSimd};

use crate::discretize::{BLOCK, BlockCoefficients, StepCoefficients};
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
    packed: PackedFeatures,
    coefficients: StepCoefficients,
    block: BlockCoefficients,
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

    /// The same grid and basis under another configuration that shares them (only the
    /// formulation may differ) and other endpoints.
    pub(crate) fn with_config_and_endpoints(
        &self,
        config: DmpConfig,
        start: &[f64],
        goal: &[f64],
    ) -> Result<Self, DmpError> {
        debug_assert_eq!(
            DmpConfig {
                formulation: self.config.formulation,
                ..config
            },
            self.config
        );
        Self::checked(config, start, goal, Arc::clone(&self.grid))
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
        // Everything runs inside one runtime-dispatched SIMD context (AVX-512, AVX2+FMA or
        // scalar): 1. the forcing term f = (g − y0) Φ w + b x of every dimension by a
        // register-blocked product, 2. the exact recurrence eight samples at a time.
        self.arch.dispatch(Rollouts {
            dmp: self,
            weights,
            out: std::slice::from_mut(traj),
        });
    }

    /// Rolls out a population: `weights` holds `out.len()` weight vectors back to back.
    /// Faster than one [`Self::rollout_into`] per candidate: each chunk of the feature
    /// matrix is read from memory once for the whole population.
    ///
    /// # Panics
    /// If `weights.len() != out.len() * n_weights()` or a trajectory has the wrong shape.
    pub fn rollout_batch(&self, weights: &[f64], out: &mut [Trajectory]) {
        assert_eq!(
            weights.len(),
            out.len() * self.n_weights(),
            "population weight length"
        );
        assert!(
            out.iter()
                .all(|t| t.dims() == self.dims() && t.n_samples() == self.n_samples()),
            "trajectory shape mismatch"
        );
        self.arch.dispatch(Rollouts {
            dmp: self,
            weights,
            out,
        });
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
        // Column-major features (and their packed copy for the forcing kernel).
        let mut row = vec![0.0; n];
        let mut features = vec![0.0; (k + 1) * n];
        for (s, &x) in phases.iter().enumerate() {
            basis.features(x, &mut row);
            for (i, &v) in row.iter().enumerate() {
                features[i * (k + 1) + s] = v;
            }
        }
        let coefficients = StepCoefficients::new(config.alpha_z, config.beta_z, config.tau, h);
        Grid {
            block: BlockCoefficients::new(&coefficients),
            packed: PackedFeatures::new(&features, k + 1, n),
            basis,
            times,
            phases,
            features,
            coefficients,
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

/// Samples per block of the packed feature matrix.
const CHUNK: usize = 32;

/// Φ packed for the forcing kernel, chunk-major: chunk `c` holds, for each basis `i` in
/// its band `lo_c .. hi_c`, the `CHUNK` feature values of samples `c CHUNK ..`
/// (zero-padded at the end). The band leaves out the basis functions whose features are
/// exactly zero (underflowed Gaussians) at every sample of the chunk, so the product is
/// the same to the bit while a quarter less is read. The data start on a cache line:
/// a vector load never straddles two.
#[derive(Debug)]
struct PackedFeatures {
    data: Vec<f64>,
    /// Index in `data` of the first, cache-line-aligned value.
    origin: usize,
    /// Per chunk: its band of basis functions and the offset of its values.
    chunks: Vec<(usize, usize, usize)>,
}

impl PackedFeatures {
    fn new(features: &[f64], ns: usize, nb: usize) -> Self {
        let column = |i: usize| &features[i * ns..(i + 1) * ns];
        let mut chunks = Vec::new();
        let mut len = 0;
        for k0 in (0..ns).step_by(CHUNK) {
            let k1 = (k0 + CHUNK).min(ns);
            let live = |i: &usize| column(*i)[k0..k1].iter().any(|&v| v != 0.0);
            let lo = (0..nb).find(live).unwrap_or(0);
            let hi = (0..nb).rev().find(live).map_or(lo, |i| i + 1);
            chunks.push((lo, hi, len));
            len += (hi - lo) * CHUNK;
        }
        let align = 64 / std::mem::size_of::<f64>();
        let mut data = vec![0.0; len + align];
        let origin = data.as_ptr().align_offset(64).min(align);
        for (c, &(lo, hi, at)) in chunks.iter().enumerate() {
            let k0 = c * CHUNK;
            let k1 = (k0 + CHUNK).min(ns);
            for i in lo..hi {
                let start = origin + at + (i - lo) * CHUNK;
                data[start..start + (k1 - k0)].copy_from_slice(&column(i)[k0..k1]);
            }
        }
        Self {
            data,
            origin,
            chunks,
        }
    }

    /// Chunk `c`: its band and its `(hi − lo) CHUNK` values.
    fn chunk(&self, c: usize) -> (usize, usize, &[f64]) {
        let (lo, hi, at) = self.chunks[c];
        let start = self.origin + at;
        (lo, hi, &self.data[start..start + (hi - lo) * CHUNK])
    }
}

/// Chunk `c` of `out[j] = Φ w_j` for `W` dimensions (weights already scaled by their
/// `g − y0`): `NV` SIMD vectors of samples per dimension are accumulated in registers over
/// the chunk's band of basis functions (12 accumulators under AVX-512 and AVX2: enough
/// independent FMA chains to keep both FMA units busy), and each loaded vector of features
/// serves all `W` dimensions.
#[inline(always)]
fn forcing_kernel<S: Simd, const W: usize, const NV: usize>(
    simd: S,
    packed: &PackedFeatures,
    c: usize,
    weights: [&[f64]; W],
    out: [&mut [f64]; W],
) {
    let ns = out[0].len();
    let sub = NV * S::F64_LANES;
    let zero = simd.splat_f64s(0.0);
    let (lo, hi, block) = packed.chunk(c);
    for h in 0..CHUNK / sub {
        let k0 = c * CHUNK + h * sub;
        if k0 >= ns {
            break;
        }
        let mut acc = [[zero; NV]; W];
        for (band, i) in (lo..hi).enumerate() {
            let at = band * CHUNK + h * sub;
            let (v, _) = S::as_simd_f64s(&block[at..at + sub]);
            for (j, weights) in weights.iter().enumerate() {
                let w = simd.splat_f64s(weights[i]);
                for r in 0..NV {
                    acc[j][r] = simd.mul_add_e_f64s(w, v[r], acc[j][r]);
                }
            }
        }
        let len = sub.min(ns - k0);
        for j in 0..W {
            if len == sub {
                let (ov, _) = S::as_mut_simd_f64s(&mut out[j][k0..k0 + sub]);
                ov[..NV].copy_from_slice(&acc[j]);
            } else {
                let mut tmp = [0.0f64; CHUNK];
                let (tv, _) = S::as_mut_simd_f64s(&mut tmp[..sub]);
                tv[..NV].copy_from_slice(&acc[j]);
                out[j][k0..k0 + len].copy_from_slice(&tmp[..len]);
            }
        }
    }
}

/// Chunk `c` of the forcing term `f_d = Φ w_d` of every dimension (`scaled`: the weights
/// times `g − y0`, dimension-major; `out`: dimension-major, `ns` samples each),
/// dimensions in groups of up to three sharing each loaded vector of features.
#[inline(always)]
fn forcing_chunk<S: Simd>(
    simd: S,
    packed: &PackedFeatures,
    c: usize,
    scaled: &[f64],
    nb: usize,
    out: &mut [f64],
) {
    #[inline(always)]
    fn group<S: Simd, const W: usize>(
        simd: S,
        packed: &PackedFeatures,
        c: usize,
        w: &[f64],
        out: &mut [f64],
    ) {
        let nb = w.len() / W;
        let ns = out.len() / W;
        let weights: [&[f64]; W] = std::array::from_fn(|j| &w[j * nb..(j + 1) * nb]);
        let mut it = out.chunks_exact_mut(ns);
        let out: [&mut [f64]; W] = std::array::from_fn(|_| it.next().expect("lane"));
        match S::F64_LANES {
            8 | 4 => forcing_kernel::<S, W, 4>(simd, packed, c, weights, out),
            2 => forcing_kernel::<S, W, 8>(simd, packed, c, weights, out),
            _ => forcing_kernel::<S, W, 16>(simd, packed, c, weights, out),
        }
    }
    let dims = scaled.len() / nb;
    let ns = out.len() / dims;
    let mut d0 = 0;
    while d0 < dims {
        let width = (dims - d0).min(3);
        let w = &scaled[d0 * nb..(d0 + width) * nb];
        let o = &mut out[d0 * ns..(d0 + width) * ns];
        match width {
            1 => group::<S, 1>(simd, packed, c, w, o),
            2 => group::<S, 2>(simd, packed, c, w, o),
            _ => group::<S, 3>(simd, packed, c, w, o),
        }
        d0 += width;
    }
}

/// Rollouts inside the dispatched SIMD context: `weights` holds `out.len()` weight
/// vectors back to back.
struct Rollouts<'a> {
    dmp: &'a DiscreteDmp,
    weights: &'a [f64],
    out: &'a mut [Trajectory],
}

impl WithSimd for Rollouts<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let Self { dmp, weights, out } = self;
        let (nb, dims, ns) = (dmp.n_basis(), dmp.dims(), dmp.n_samples());
        let nw = nb * dims;
        let grid = &dmp.grid;
        // 1. f = (g − y0) Φ w + b x. The weights scaled once; then chunk by chunk of Φ,
        //    every candidate, so that a chunk is read from memory once and then from the
        //    L1 cache (a single rollout is bound by reading Φ).
        let scaled: Vec<f64> = weights
            .iter()
            .enumerate()
            .map(|(i, w)| w * dmp.forcing_scale((i % nw) / nb).0)
            .collect();
        for c in 0..grid.packed.chunks.len() {
            for (w, traj) in scaled.chunks_exact(nw).zip(out.iter_mut()) {
                forcing_chunk(simd, &grid.packed, c, w, nb, &mut traj.forcing);
            }
        }
        // 2. Per candidate and dimension: the phase term of the goal-robust form, then
        //    the recurrence.
        for traj in out.iter_mut() {
            for d in 0..dims {
                let range = d * ns..(d + 1) * ns;
                let f = &mut traj.forcing[range.clone()];
                let off = dmp.forcing_scale(d).1;
                if off != 0.0 {
                    for (f, &x) in f.iter_mut().zip(&grid.phases) {
                        *f = fma::<S>(off, x, *f);
                    }
                }
                block_chain::<S>(
                    simd,
                    grid,
                    dmp.start[d],
                    dmp.goal[d],
                    f,
                    &mut traj.position[range.clone()],
                    &mut traj.velocity[range.clone()],
                    &mut traj.acceleration[range],
                );
            }
        }
    }
}

/// The exact recurrence of one dimension from `y0` at rest towards the goal `g`, with
/// forcing `f`, writing position, physical velocity `z / τ` and acceleration
/// `(α_z β_z (g − y) − α_z z + f) / τ²`. The state is kept relative to the goal
/// (`ỹ = y − g`), where the constant goal input vanishes: at rest on the goal without
/// forcing the state stays exactly zero. After the first [`BLOCK`] samples (one step
/// at a time) the states of [`BLOCK`] consecutive samples advance together by
/// [`BlockCoefficients`]: every operation is a SIMD operation over the block, and the
/// chain through the state is eight times shorter. The last samples that a whole block
/// cannot reach are again stepped one at a time.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn block_chain<S: Simd>(
    simd: S,
    grid: &Grid,
    y0: f64,
    g: f64,
    f: &[f64],
    pos: &mut [f64],
    vel: &mut [f64],
    acc: &mut [f64],
) {
    let c = &grid.coefficients;
    let ns = f.len();
    // The first block one step at a time (the whole grid if it is shorter than two
    // blocks).
    let head = if ns < 2 * BLOCK { ns } else { BLOCK };
    let mut y = [0.0; BLOCK];
    let mut z = [0.0; BLOCK];
    let (mut ys, mut zs) = (y0 - g, 0.0);
    for k in 0..head {
        pos[k] = g + ys;
        vel[k] = c.velocity(zs);
        acc[k] = c.acceleration(f[k], ys, zs);
        if k < BLOCK {
            (y[k], z[k]) = (ys, zs);
        }
        if k + 1 < ns {
            (ys, zs) = c.advance(ys, zs, f[k], f[k + 1]);
        }
    }
    if head < BLOCK {
        return;
    }
    // Advance the block at `base` to `base + BLOCK` and write it, while the inputs of
    // the new block (up to sample base + 2 BLOCK − 1) exist.
    let end = match S::F64_LANES {
        8 => advance_blocks::<S, 1>(simd, grid, g, f, &mut y, &mut z, pos, vel, acc),
        4 => advance_blocks::<S, 2>(simd, grid, g, f, &mut y, &mut z, pos, vel, acc),
        2 => advance_blocks::<S, 4>(simd, grid, g, f, &mut y, &mut z, pos, vel, acc),
        _ => advance_blocks::<S, 8>(simd, grid, g, f, &mut y, &mut z, pos, vel, acc),
    };
    // The remaining samples, one step at a time from the last one written.
    let (mut ys, mut zs) = (y[BLOCK - 1], z[BLOCK - 1]);
    for k in end..ns {
        (ys, zs) = c.advance(ys, zs, f[k - 1], f[k]);
        pos[k] = g + ys;
        vel[k] = c.velocity(zs);
        acc[k] = c.acceleration(f[k], ys, zs);
    }
}

/// The block recurrence of [`block_chain`] on `NV` SIMD vectors per block (`NV` ×
/// lanes = [`BLOCK`]): `y`, `z` hold the states of samples `0 .. BLOCK` on entry and of
/// the last block written on return; returns the first sample not written.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn advance_blocks<S: Simd, const NV: usize>(
    simd: S,
    grid: &Grid,
    g: f64,
    f: &[f64],
    y: &mut [f64; BLOCK],
    z: &mut [f64; BLOCK],
    pos: &mut [f64],
    vel: &mut [f64],
    acc: &mut [f64],
) -> usize {
    let (c, b) = (&grid.coefficients, &grid.block);
    let ns = f.len();
    let splat = |v: f64| simd.splat_f64s(v);
    let vectors = |s: &[f64]| -> [S::f64s; NV] {
        let (v, _) = S::as_simd_f64s(s);
        std::array::from_fn(|r| v[r])
    };
    let [[e00, e01], [e10, e11]] = b.e.map(|row| row.map(splat));
    let (gy, gz) = (b.gy.map(splat), b.gz.map(splat));
    let zero = splat(0.0);
    let (inv_tau, inv_tau2, kk, az, gv) = (
        splat(c.inv_tau),
        splat(c.inv_tau2),
        splat(c.kk),
        splat(c.az),
        splat(g),
    );
    let mut yv = vectors(&y[..]);
    let mut zv = vectors(&z[..]);
    let mut base = 0;
    while base + 2 * BLOCK <= ns {
        // The input sums Σ_j Γ_j u_{k+j} as two interleaved partial sums (shorter FMA
        // chains), over a window of fixed length so the loop unrolls without checks.
        let window: &[f64; 2 * BLOCK] = f[base..base + 2 * BLOCK].try_into().expect("window");
        let (mut ya, mut yb) = ([zero; NV], [zero; NV]);
        let (mut za, mut zb) = ([zero; NV], [zero; NV]);
        for jj in 0..BLOCK / 2 {
            for (j, y, z) in [(2 * jj, &mut ya, &mut za), (2 * jj + 1, &mut yb, &mut zb)] {
                let fj = vectors(&window[j..j + BLOCK]);
                for r in 0..NV {
                    y[r] = simd.mul_add_e_f64s(gy[j], fj[r], y[r]);
                    z[r] = simd.mul_add_e_f64s(gz[j], fj[r], z[r]);
                }
            }
        }
        let fj = vectors(&window[BLOCK..]);
        for r in 0..NV {
            ya[r] = simd.mul_add_e_f64s(gy[BLOCK], fj[r], ya[r]);
            za[r] = simd.mul_add_e_f64s(gz[BLOCK], fj[r], za[r]);
        }
        for r in 0..NV {
            let (yr, zr) = (yv[r], zv[r]);
            let (sy, sz) = (simd.add_f64s(ya[r], yb[r]), simd.add_f64s(za[r], zb[r]));
            yv[r] = simd.mul_add_e_f64s(e00, yr, simd.mul_add_e_f64s(e01, zr, sy));
            zv[r] = simd.mul_add_e_f64s(e10, yr, simd.mul_add_e_f64s(e11, zr, sz));
        }
        base += BLOCK;
        let range = base..base + BLOCK;
        let fb = vectors(&f[range.clone()]);
        let (pb, _) = S::as_mut_simd_f64s(&mut pos[range.clone()]);
        for r in 0..NV {
            pb[r] = simd.add_f64s(gv, yv[r]);
        }
        let (vb, _) = S::as_mut_simd_f64s(&mut vel[range.clone()]);
        for r in 0..NV {
            vb[r] = simd.mul_f64s(zv[r], inv_tau);
        }
        let (ab, _) = S::as_mut_simd_f64s(&mut acc[range]);
        for r in 0..NV {
            // (f − kk ỹ − az z) / τ²
            let t = simd.negate_mul_add_e_f64s(kk, yv[r], fb[r]);
            ab[r] = simd.mul_f64s(simd.negate_mul_add_e_f64s(az, zv[r], t), inv_tau2);
        }
    }
    let (ys, _) = S::as_mut_simd_f64s(&mut y[..]);
    ys[..NV].copy_from_slice(&yv);
    let (zs, _) = S::as_mut_simd_f64s(&mut z[..]);
    zs[..NV].copy_from_slice(&zv);
    base + BLOCK
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

    /// The plain one-step recurrence on the plain feature matrix: the reference for the
    /// packed, blocked SIMD rollout.
    fn naive_rollout(dmp: &DiscreteDmp, w: &[f64]) -> Trajectory {
        let (nb, ns) = (dmp.n_basis(), dmp.n_samples());
        let c = StepCoefficients::new(
            dmp.config.alpha_z,
            dmp.config.beta_z,
            dmp.config.tau,
            dmp.config.step(),
        );
        let mut t = dmp.new_trajectory();
        for d in 0..dmp.dims() {
            let (a, b) = dmp.forcing_scale(d);
            let f: Vec<f64> = (0..ns)
                .map(|k| {
                    let phi: f64 = (0..nb)
                        .map(|i| dmp.feature_column(i)[k] * w[d * nb + i])
                        .sum();
                    a * phi + b * dmp.phases()[k]
                })
                .collect();
            let ug = c.goal_input(dmp.goal[d]);
            let (mut y, mut z) = (dmp.start[d], 0.0);
            for k in 0..ns {
                t.position[d * ns + k] = y;
                t.velocity[d * ns + k] = c.velocity(z);
                t.acceleration[d * ns + k] = c.acceleration(ug + f[k], y, z);
                t.forcing[d * ns + k] = f[k];
                if k + 1 < ns {
                    (y, z) = c.advance(y, z, ug + f[k], ug + f[k + 1]);
                }
            }
        }
        t
    }

    fn assert_close(got: &Trajectory, want: &Trajectory, what: &str) {
        type Quantity = fn(&Trajectory, usize) -> &[f64];
        let quantities: [(&str, Quantity); 4] = [
            ("position", Trajectory::position),
            ("velocity", Trajectory::velocity),
            ("acceleration", Trajectory::acceleration),
            ("forcing", Trajectory::forcing),
        ];
        for d in 0..want.dims() {
            for (name, q) in quantities {
                let scale = q(want, d).iter().fold(1.0f64, |m, v| m.max(v.abs()));
                for (k, (g, w)) in q(got, d).iter().zip(q(want, d)).enumerate() {
                    assert!(
                        (g - w).abs() <= 1e-12 * scale,
                        "{what}: {name} of dimension {d} at sample {k}: {g} vs {w}"
                    );
                }
            }
        }
    }

    #[test]
    fn blocked_rollout_equals_the_plain_recurrence_on_any_grid_length() {
        // Grids shorter than two blocks, exactly one or two blocks, and every remainder.
        for formulation in [Formulation::Ijspeert2013, Formulation::GoalRobust] {
            for ns in (3..=41).chain([64, 65, 1001]) {
                let cfg = DmpConfig {
                    formulation,
                    ..DmpConfig::new(7, 0.01 * (ns - 1) as f64, 0.01)
                };
                let dmp = DiscreteDmp::new(cfg, &[0.3, -1.0], &[1.2, -0.4]).unwrap();
                let w: Vec<f64> = (0..dmp.n_weights())
                    .map(|i| (i as f64 * 1.3).sin() * 200.0)
                    .collect();
                assert_close(
                    &dmp.rollout(&w),
                    &naive_rollout(&dmp, &w),
                    &format!("{formulation:?}, {} samples", dmp.n_samples()),
                );
            }
        }
    }

    #[test]
    fn every_simd_level_and_the_batch_give_the_same_rollout() {
        let dmp = thesis_dmp(10.0);
        let nw = dmp.n_weights();
        let pop: Vec<f64> = (0..3 * nw)
            .map(|i| (i as f64 * 0.37).cos() * 150.0)
            .collect();
        let want: Vec<Trajectory> = pop
            .chunks_exact(nw)
            .map(|w| naive_rollout(&dmp, w))
            .collect();
        let mut out: Vec<Trajectory> = (0..3).map(|_| dmp.new_trajectory()).collect();
        fn op<'a>(dmp: &'a DiscreteDmp, pop: &'a [f64], out: &'a mut [Trajectory]) -> Rollouts<'a> {
            Rollouts {
                dmp,
                weights: pop,
                out,
            }
        }
        pulp::Scalar::new().vectorize(op(&dmp, &pop, &mut out));
        for (got, want) in out.iter().zip(&want) {
            assert_close(got, want, "scalar");
        }
        #[cfg(target_arch = "x86_64")]
        {
            if let Some(simd) = pulp::x86::V3::try_new() {
                simd.vectorize(|| op(&dmp, &pop, &mut out).with_simd(simd));
                for (got, want) in out.iter().zip(&want) {
                    assert_close(got, want, "AVX2");
                }
            }
            if let Some(simd) = pulp::x86::V4::try_new() {
                simd.vectorize(|| op(&dmp, &pop, &mut out).with_simd(simd));
                for (got, want) in out.iter().zip(&want) {
                    assert_close(got, want, "AVX-512");
                }
            }
        }
        dmp.rollout_batch(&pop, &mut out);
        for (got, w) in out.iter().zip(pop.chunks_exact(nw)) {
            assert_eq!(got, &dmp.rollout(w), "batch = one rollout per candidate");
        }
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
