//! The ProMP: basis, fitting, moments over time, conditioning, sampling.

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// What can go wrong with a ProMP.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ProMpError {
    /// A setting or an input out of its range; the message names it.
    #[error("{0}")]
    Invalid(String),
    /// A covariance that is not positive definite where it must be (conditioning on
    /// contradicting exact via points, sampling a broken distribution).
    #[error("{0}")]
    Singular(String),
}

fn invalid(m: String) -> ProMpError {
    ProMpError::Invalid(m)
}

/// A via point to condition on: at time `time` (s), a position and optionally a velocity,
/// each with its covariance (dims × dims; zero: met exactly).
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Time (s), within `[0, duration]`.
    pub time: f64,
    /// Desired position per dimension.
    pub position: Option<Vec<f64>>,
    /// Its covariance (dims × dims, row-major).
    pub position_cov: Vec<f64>,
    /// Desired velocity per dimension.
    pub velocity: Option<Vec<f64>>,
    /// Its covariance (dims × dims, row-major).
    pub velocity_cov: Vec<f64>,
}

impl Observation {
    /// A position with the same standard deviation `std` in every dimension (0: exact).
    pub fn position(time: f64, position: Vec<f64>, std: f64) -> Self {
        let d = position.len();
        Observation {
            time,
            position_cov: diagonal(d, std * std),
            position: Some(position),
            velocity: None,
            velocity_cov: Vec::new(),
        }
    }

    /// Adds a velocity with standard deviation `std` in every dimension.
    pub fn with_velocity(mut self, velocity: Vec<f64>, std: f64) -> Self {
        self.velocity_cov = diagonal(velocity.len(), std * std);
        self.velocity = Some(velocity);
        self
    }
}

fn diagonal(d: usize, v: f64) -> Vec<f64> {
    let mut m = vec![0.0; d * d];
    for i in 0..d {
        m[i * d + i] = v;
    }
    m
}

/// A probabilistic movement primitive; see the crate documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct ProMp {
    dims: usize,
    bases: usize,
    duration: f64,
    width: f64,
    mean: DVector<f64>,
    cov: DMatrix<f64>,
}

/// Ridge added to the weight covariance of a fit (relative to its largest diagonal entry,
/// and at least this absolute value), so that it stays positive definite.
const COV_RIDGE: f64 = 1e-10;

impl ProMp {
    /// A ProMP of `dims` dimensions and `bases` basis functions per dimension over
    /// `duration` seconds, with weight mean `mean` (dimension-major: all of dimension 0's
    /// weights, then dimension 1's, …) and covariance `cov` (row-major, square).
    pub fn new(
        dims: usize,
        bases: usize,
        duration: f64,
        mean: Vec<f64>,
        cov: Vec<f64>,
    ) -> Result<Self, ProMpError> {
        if dims == 0 || bases < 2 || dims * bases > 10_000 {
            return Err(invalid(format!(
                "a ProMP needs at least 1 dimension and 2 basis functions, at most 10000 weights (got {dims} × {bases})"
            )));
        }
        if !(duration.is_finite() && duration > 0.0) {
            return Err(invalid(format!(
                "the duration must be finite and > 0 (got {duration})"
            )));
        }
        let n = dims * bases;
        if mean.len() != n || cov.len() != n * n {
            return Err(invalid(format!(
                "{dims} dimensions × {bases} basis functions need {n} mean weights and a {n} × {n} covariance (got {} and {})",
                mean.len(),
                cov.len()
            )));
        }
        if mean.iter().chain(&cov).any(|v| !v.is_finite()) {
            return Err(invalid(
                "the weight mean and covariance must be finite".into(),
            ));
        }
        Ok(ProMp {
            dims,
            bases,
            duration,
            width: 1.0 / (bases - 1) as f64,
            mean: DVector::from_vec(mean),
            cov: DMatrix::from_row_slice(n, n, &cov),
        })
    }

    /// Dimensions.
    pub fn dims(&self) -> usize {
        self.dims
    }

    /// Basis functions per dimension.
    pub fn bases(&self) -> usize {
        self.bases
    }

    /// Duration (s).
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// The weight mean (dimension-major).
    pub fn weight_mean(&self) -> &[f64] {
        self.mean.as_slice()
    }

    /// The weight covariance.
    pub fn weight_cov(&self) -> &DMatrix<f64> {
        &self.cov
    }

    /// The normalised basis at phase `z` and its derivative with respect to `z`.
    ///
    /// The centres are `Δ = h` apart, so neighbouring bumps differ by the factor
    /// `exp((z − cᵢ)/h − ½)`, which itself shrinks by `e⁻¹` per step: three exponentials
    /// per phase instead of one per bump, walking out from the nearest centre (whose bump
    /// is ≥ e^-1/8) so the far ones underflow harmlessly to zero.
    fn basis(&self, z: f64) -> (DVector<f64>, DVector<f64>) {
        let mut psi = DVector::zeros(self.bases);
        let mut dpsi = DVector::zeros(self.bases);
        self.basis_into(z, psi.as_mut_slice(), dpsi.as_mut_slice());
        (psi, dpsi)
    }

    /// [`Self::basis`] into `psi` and `dpsi` (`bases` long each), allocating nothing.
    fn basis_into(&self, z: f64, psi: &mut [f64], dpsi: &mut [f64]) {
        let n = self.bases;
        let h = self.width;
        let centre = |i: usize| i as f64 / (n - 1) as f64;
        let k = ((z / h).round().max(0.0) as usize).min(n - 1);
        let g = psi;
        let u = (z - centre(k)) / h;
        g[k] = (-0.5 * u * u).exp();
        let shrink = (-1.0f64).exp();
        let mut ratio = (u - 0.5).exp();
        for i in k + 1..n {
            g[i] = g[i - 1] * ratio;
            ratio *= shrink;
        }
        let mut ratio = (-u - 0.5).exp();
        for i in (0..k).rev() {
            g[i] = g[i + 1] * ratio;
            ratio *= shrink;
        }
        let (mut s, mut ds) = (0.0, 0.0);
        for i in 0..n {
            dpsi[i] = -g[i] * (z - centre(i)) / (h * h);
            s += g[i];
            ds += dpsi[i];
        }
        for i in 0..n {
            dpsi[i] = (dpsi[i] * s - g[i] * ds) / (s * s);
            g[i] /= s;
        }
    }

    /// The same basis by one exponential per bump (the definition; tests compare).
    #[cfg(test)]
    fn basis_direct(&self, z: f64) -> DVector<f64> {
        let n = self.bases;
        let h = self.width;
        let g = DVector::from_fn(n, |i, _| {
            let c = i as f64 / (n - 1) as f64;
            (-(z - c) * (z - c) / (2.0 * h * h)).exp()
        });
        let s = g.sum();
        g / s
    }

    /// `Φ` (dims × dims·bases) of positions and of velocities (per second) at time `t`:
    /// position = `Φ w`, velocity = `Φ̇ w`.
    pub fn features(&self, t: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let (psi, dpsi) = self.basis(t / self.duration);
        let (d, n) = (self.dims, self.bases);
        let mut p = DMatrix::zeros(d, d * n);
        let mut v = DMatrix::zeros(d, d * n);
        for k in 0..d {
            for i in 0..n {
                p[(k, k * n + i)] = psi[i];
                v[(k, k * n + i)] = dpsi[i] / self.duration;
            }
        }
        (p, v)
    }

    /// Mean position and velocity at time `t` (s).
    pub fn mean_at(&self, t: f64) -> (Vec<f64>, Vec<f64>) {
        self.mean_path(&[t])
    }

    /// Mean positions and velocities at the times `times` (s): two `times.len() × dims`
    /// row-major arrays, the basis computed once per time and summed against each
    /// dimension's weights (no feature matrix built).
    pub fn mean_path(&self, times: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (d, n) = (self.dims, self.bases);
        let mut p = Vec::with_capacity(times.len() * d);
        let mut v = Vec::with_capacity(times.len() * d);
        let (mut psi, mut dpsi) = (vec![0.0; n], vec![0.0; n]);
        for &t in times {
            self.basis_into(t / self.duration, &mut psi, &mut dpsi);
            for w in self.mean.as_slice().chunks_exact(n) {
                p.push(psi.iter().zip(w).map(|(a, b)| a * b).sum::<f64>());
                v.push(dpsi.iter().zip(w).map(|(a, b)| a * b).sum::<f64>() / self.duration);
            }
        }
        (p, v)
    }

    /// Positions `Φ w` and velocities `Φ̇ w` of the movement of weights `w` (`dims ·
    /// bases`, dimension-major) at the times `times` (s): two `times.len() × dims`
    /// row-major arrays, to the last bit the products of [`Self::features`] with `w`, with
    /// no feature matrix built. Called per candidate by the learners that search weights.
    pub fn path(&self, w: &[f64], times: &[f64]) -> Result<(Vec<f64>, Vec<f64>), ProMpError> {
        let (d, n) = (self.dims, self.bases);
        if w.len() != d * n {
            return Err(invalid(format!(
                "{} weights for a ProMP of {d} dimensions × {n} bases",
                w.len()
            )));
        }
        let mut p = Vec::with_capacity(times.len() * d);
        let mut v = Vec::with_capacity(times.len() * d);
        let (mut psi, mut dpsi) = (vec![0.0; n], vec![0.0; n]);
        for &t in times {
            self.basis_into(t / self.duration, &mut psi, &mut dpsi);
            for wk in w.chunks_exact(n) {
                let (mut pk, mut vk) = (0.0, 0.0);
                for i in 0..n {
                    pk += psi[i] * wk[i];
                    vk += dpsi[i] / self.duration * wk[i];
                }
                p.push(pk);
                v.push(vk);
            }
        }
        Ok((p, v))
    }

    /// Covariance of position and of velocity at time `t` (dims × dims each).
    pub fn covariance_at(&self, t: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let (p, v) = self.features(t);
        (
            &p * &self.cov * p.transpose(),
            &v * &self.cov * v.transpose(),
        )
    }

    /// The position basis at the times `t`: one row of `bases` values per time.
    pub fn basis_matrix(&self, times: &[f64]) -> DMatrix<f64> {
        let mut psi = DMatrix::zeros(times.len(), self.bases);
        for (r, &t) in times.iter().enumerate() {
            let (row, _) = self.basis(t / self.duration);
            psi.row_mut(r).copy_from(&row.transpose());
        }
        psi
    }

    /// Positions of the trajectory with weights `w` at the times `t`: one row per time.
    pub fn trajectory(&self, w: &[f64], times: &[f64]) -> Vec<Vec<f64>> {
        self.trajectories(&[w.to_vec()], times)
            .chunks(self.dims)
            .map(<[f64]>::to_vec)
            .collect()
    }

    /// The trajectories of several weight vectors at the times `t`, by one matrix product
    /// for all, flat: sample-major, then time, then dimension (`out[(s · T + k) · dims +
    /// d]`).
    pub fn trajectories(&self, weights: &[Vec<f64>], times: &[f64]) -> Vec<f64> {
        let (d, b, t) = (self.dims, self.bases, times.len());
        let psi = self.basis_matrix(times);
        // Columns: sample-major, then dimension.
        let w = DMatrix::from_fn(b, weights.len() * d, |i, c| weights[c / d][(c % d) * b + i]);
        let y = psi * w;
        let mut out = vec![0.0; weights.len() * t * d];
        for (c, col) in y.column_iter().enumerate() {
            let (s, k) = (c / d, c % d);
            for (r, v) in col.iter().enumerate() {
                out[(s * t + r) * d + k] = *v;
            }
        }
        out
    }

    /// `count` seeded samples' trajectories at the times `t` ([`Self::sample`] then
    /// [`Self::trajectories`]; flat, sample-major, then time, then dimension).
    pub fn sample_trajectories(
        &self,
        count: usize,
        seed: u64,
        times: &[f64],
    ) -> Result<Vec<f64>, ProMpError> {
        Ok(self.trajectories(&self.sample(count, seed)?, times))
    }

    /// The ProMP of demonstrations `(times, positions)` (one row of `dims` values per time,
    /// at least 2 samples, increasing times), each time-normalised to `[0, duration]`, with
    /// `bases` basis functions per dimension. Each demonstration's weights come from ridge
    /// regression (λ = 1e-8 times the Gram matrix's trace over its size); the mean and the
    /// sample covariance of the weights are the ProMP. At least 2 demonstrations.
    pub fn fit(
        demos: &[(Vec<f64>, Vec<Vec<f64>>)],
        bases: usize,
        duration: f64,
    ) -> Result<Self, ProMpError> {
        if demos.len() < 2 {
            return Err(invalid(format!(
                "a ProMP needs at least 2 demonstrations to learn their spread (got {})",
                demos.len()
            )));
        }
        let dims = demos[0].1.first().map_or(0, Vec::len);
        let n = dims * bases;
        let mut shell = ProMp::new(dims, bases, duration, vec![0.0; n], vec![0.0; n * n])?;
        let mut weights = Vec::with_capacity(demos.len());
        type Factor = nalgebra::Cholesky<f64, nalgebra::Dyn>;
        let mut cached: Option<(Vec<f64>, DMatrix<f64>, Factor)> = None;
        for (k, (t, y)) in demos.iter().enumerate() {
            let name = format!("demonstration {}", k + 1);
            if t.len() != y.len() || t.len() < 2 {
                return Err(invalid(format!(
                    "{name}: needs at least 2 samples with one time each (got {} times, {} rows)",
                    t.len(),
                    y.len()
                )));
            }
            if let Some(r) = y.iter().position(|r| r.len() != dims) {
                return Err(invalid(format!(
                    "{name}: sample {} has {} values, the first demonstration {dims}",
                    r + 1,
                    y[r].len()
                )));
            }
            if let Some(i) = t.windows(2).position(|w| w[1] <= w[0] || w[1].is_nan()) {
                return Err(invalid(format!(
                    "{name}: times must increase (sample {} at {} follows {})",
                    i + 2,
                    t[i + 1],
                    t[i]
                )));
            }
            if t.iter().chain(y.iter().flatten()).any(|v| !v.is_finite()) {
                return Err(invalid(format!("{name}: every value must be finite")));
            }
            let (t0, span) = (t[0], t[t.len() - 1] - t[0]);
            let normalised: Vec<f64> = t.iter().map(|x| (x - t0) / span * duration).collect();
            // Demonstrations sampled alike share the basis and its factorisation.
            if cached.as_ref().is_none_or(|(c, _, _)| *c != normalised) {
                let psi = shell.basis_matrix(&normalised);
                let gram = psi.tr_mul(&psi);
                let lambda = 1e-8 * gram.trace() / bases as f64;
                let a = gram + DMatrix::identity(bases, bases) * lambda;
                let chol = a.cholesky().ok_or_else(|| {
                    ProMpError::Singular(format!("{name}: the regression is singular"))
                })?;
                cached = Some((normalised, psi, chol));
            }
            let (_, psi, chol) = cached.as_ref().expect("just filled");
            let targets = DMatrix::from_fn(t.len(), dims, |r, d| y[r][d]);
            let wd = chol.solve(&psi.tr_mul(&targets));
            let w = DVector::from_column_slice(wd.as_slice());
            weights.push(w);
        }
        let m = weights.len() as f64;
        let mean = weights.iter().fold(DVector::zeros(n), |a, w| a + w) / m;
        let mut cov = DMatrix::zeros(n, n);
        for w in &weights {
            let d = w - &mean;
            cov += &d * d.transpose();
        }
        cov /= m - 1.0;
        let ridge = (COV_RIDGE * cov.diagonal().max()).max(COV_RIDGE);
        for i in 0..n {
            cov[(i, i)] += ridge;
        }
        shell.mean = mean;
        shell.cov = cov;
        Ok(shell)
    }

    /// The ProMP given the via points `obs` (all at once): Gaussian conditioning of the
    /// weights on each observed position (and velocity) with its covariance.
    pub fn condition(&self, obs: &[Observation]) -> Result<ProMp, ProMpError> {
        let d = self.dims;
        let mut rows: Vec<DMatrix<f64>> = Vec::new();
        let mut targets: Vec<f64> = Vec::new();
        let mut noise: Vec<DMatrix<f64>> = Vec::new();
        for (k, o) in obs.iter().enumerate() {
            let name = format!("via point {}", k + 1);
            if !(o.time.is_finite() && (0.0..=self.duration).contains(&o.time)) {
                return Err(invalid(format!(
                    "{name}: the time {} s must lie within the movement, 0 to {} s",
                    o.time, self.duration
                )));
            }
            let (p, v) = self.features(o.time);
            for (what, value, cov, phi) in [
                ("position", &o.position, &o.position_cov, p),
                ("velocity", &o.velocity, &o.velocity_cov, v),
            ] {
                let Some(value) = value else { continue };
                if value.len() != d || cov.len() != d * d {
                    return Err(invalid(format!(
                        "{name}: the {what} needs {d} values and a {d} × {d} covariance (got {} and {})",
                        value.len(),
                        cov.len()
                    )));
                }
                if value.iter().chain(cov).any(|x| !x.is_finite()) {
                    return Err(invalid(format!("{name}: the {what} must be finite")));
                }
                let c = DMatrix::from_row_slice(d, d, cov);
                if (0..d).any(|i| c[(i, i)] < 0.0) || (&c - c.transpose()).amax() > 1e-12 {
                    return Err(invalid(format!(
                        "{name}: the {what} covariance must be symmetric with variances ≥ 0"
                    )));
                }
                rows.push(phi);
                targets.extend_from_slice(value);
                noise.push(c);
            }
        }
        if rows.is_empty() {
            return Ok(self.clone());
        }
        let m = targets.len();
        let n = self.dims * self.bases;
        let mut phi = DMatrix::zeros(m, n);
        let mut sigma = DMatrix::zeros(m, m);
        let mut at = 0;
        for (r, c) in rows.iter().zip(&noise) {
            phi.rows_mut(at, d).copy_from(r);
            sigma.view_mut((at, at), (d, d)).copy_from(c);
            at += d;
        }
        let y = DVector::from_vec(targets);
        // Φ Σ_w (m × n): Σ_w is symmetric, so row r of it is the combination of Σ_w's
        // columns (contiguous) by row r of Φ, which is zero outside one dimension's block.
        let mut pc_t = DMatrix::<f64>::zeros(n, m);
        for r in 0..m {
            let mut col = pc_t.column_mut(r);
            for (j, &coef) in phi.row(r).iter().enumerate() {
                if coef != 0.0 {
                    col.axpy(coef, &self.cov.column(j), 1.0);
                }
            }
        }
        let s = &sigma + &phi * &pc_t;
        let s = (&s + s.transpose()) * 0.5;
        let chol = s.cholesky().ok_or_else(|| {
            ProMpError::Singular(
                "the via points contradict each other or leave no freedom (their combined covariance is singular): give them some covariance or fewer constraints"
                    .into(),
            )
        })?;
        // μ' = μ + (ΦΣ)ᵀ S⁻¹ (y − Φμ);  Σ' = Σ − (ΦΣ)ᵀ S⁻¹ (ΦΣ).
        let mean = &self.mean + &pc_t * chol.solve(&(y - &phi * &self.mean));
        let g = chol.solve(&pc_t.transpose());
        let mut cov = self.cov.clone();
        cov.gemm(-1.0, &pc_t, &g, 1.0);
        for j in 0..n {
            for i in j + 1..n {
                let v = 0.5 * (cov[(i, j)] + cov[(j, i)]);
                cov[(i, j)] = v;
                cov[(j, i)] = v;
            }
        }
        Ok(ProMp {
            dims: self.dims,
            bases: self.bases,
            duration: self.duration,
            width: self.width,
            mean,
            cov,
        })
    }

    /// `count` weight vectors drawn from the ProMP with seed `seed` (the same seed, the
    /// same samples).
    pub fn sample(&self, count: usize, seed: u64) -> Result<Vec<Vec<f64>>, ProMpError> {
        let n = self.dims * self.bases;
        let factor = self.square_root()?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        Ok((0..count)
            .map(|_| {
                let z = DVector::from_fn(n, |_, _| StandardNormal.sample(&mut rng));
                (&self.mean + &factor * z).as_slice().to_vec()
            })
            .collect())
    }

    /// A factor `L` with `L Lᵀ = Σ_w`: Cholesky with a relative jitter of 1e-12 or, when
    /// conditioning left the covariance singular up to rounding (exact via points), the
    /// symmetric square root with eigenvalues below zero by rounding set to zero.
    fn square_root(&self) -> Result<DMatrix<f64>, ProMpError> {
        let n = self.dims * self.bases;
        let scale = self.cov.diagonal().amax().max(1e-300);
        let jittered = &self.cov + DMatrix::identity(n, n) * (1e-12 * scale);
        if let Some(c) = jittered.cholesky() {
            return Ok(c.l());
        }
        let eig = ((&self.cov + self.cov.transpose()) * 0.5).symmetric_eigen();
        let min = eig.eigenvalues.min();
        if min < -1e-8 * scale {
            return Err(ProMpError::Singular(format!(
                "the weight covariance is not positive semi-definite (an eigenvalue of {min:.3e} against variances up to {scale:.3e})"
            )));
        }
        let roots = eig.eigenvalues.map(|v| v.max(0.0).sqrt());
        Ok(&eig.eigenvectors * DMatrix::from_diagonal(&roots))
    }
}

/// Where CMA-ES should start when it searches the weights of a ProMP
/// ([`ProMp::search_start`]): the mean `x0`, the step size `sigma0` and the covariance
/// `C0` (row-major), with `sigma0² · C0` the ProMP's weight covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct SearchStart {
    /// The weight mean.
    pub x0: Vec<f64>,
    /// `sqrt(trace(Σ_w) / n)`: the root-mean-square standard deviation of the weights.
    pub sigma0: f64,
    /// `Σ_w / sigma0²` (its diagonal averages 1), row-major.
    pub covariance: Vec<f64>,
}

/// One ProMP's share in a co-activation ([`blend`]): the ProMP and its activation
/// `α(t) ≥ 0` over time.
pub struct Activation<'a> {
    /// The ProMP.
    pub promp: &'a ProMp,
    /// Its activation at time `t` (s); 0 switches it off.
    pub alpha: &'a dyn Fn(f64) -> f64,
}

/// The position distribution of co-activated ProMPs at one time ([`blend`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Blended {
    /// Time (s).
    pub time: f64,
    /// Mean position per dimension.
    pub mean: Vec<f64>,
    /// Covariance of the position (dims × dims).
    pub cov: DMatrix<f64>,
}

impl Blended {
    /// Standard deviation per dimension.
    pub fn std(&self) -> Vec<f64> {
        (0..self.cov.nrows())
            .map(|i| self.cov[(i, i)].max(0.0).sqrt())
            .collect()
    }
}

/// Co-activation of ProMPs (Paraschos et al. 2013, section 2.2): at each time the
/// position's distribution is the product of the parts' distributions, each raised to its
/// activation, `Σ* = (Σ αᵢ Σᵢ⁻¹)⁻¹` and `μ* = Σ* Σ αᵢ Σᵢ⁻¹ μᵢ`. A part with a small
/// variance at a time (a via point it was conditioned on) dominates there; with
/// activations that cross over (a sigmoid and its complement) the movement is handed from
/// one ProMP to the next. Each covariance gets a ridge of 1e-12 of its trace so that exact
/// via points (zero variance) stay invertible.
///
/// Every part must have the same dimensions, and every time with a positive activation
/// must lie within that part's duration; at each time some activation must be positive.
pub fn blend(parts: &[Activation<'_>], times: &[f64]) -> Result<Vec<Blended>, ProMpError> {
    let Some(first) = parts.first() else {
        return Err(invalid("a blend needs at least one ProMP".into()));
    };
    let d = first.promp.dims;
    if let Some(k) = parts.iter().position(|p| p.promp.dims != d) {
        return Err(invalid(format!(
            "ProMP {} has {} dimensions, ProMP 1 has {d}: blended ProMPs must share their dimensions",
            k + 1,
            parts[k].promp.dims
        )));
    }
    let mut out = Vec::with_capacity(times.len());
    for &t in times {
        let mut precision = DMatrix::<f64>::zeros(d, d);
        let mut info = DVector::<f64>::zeros(d);
        for (k, part) in parts.iter().enumerate() {
            let a = (part.alpha)(t);
            if !(a.is_finite() && a >= 0.0) {
                return Err(invalid(format!(
                    "ProMP {}: its activation at t = {t} s is {a}; activations must be finite and ≥ 0",
                    k + 1
                )));
            }
            if a == 0.0 {
                continue;
            }
            let p = part.promp;
            if !(0.0..=p.duration).contains(&t) {
                return Err(invalid(format!(
                    "ProMP {}: t = {t} s is active but outside its movement, 0 to {} s",
                    k + 1,
                    p.duration
                )));
            }
            let (phi, _) = p.features(t);
            let mut cov = &phi * &p.cov * phi.transpose();
            let ridge = 1e-12 * cov.trace().max(1e-300);
            for i in 0..d {
                cov[(i, i)] += ridge;
            }
            let inv = cov.cholesky().map(|c| c.inverse()).ok_or_else(|| {
                ProMpError::Singular(format!(
                    "ProMP {}: its position covariance at t = {t} s is not positive definite",
                    k + 1
                ))
            })?;
            info += &inv * (&phi * &p.mean) * a;
            precision += inv * a;
        }
        let cov = precision
            .clone()
            .cholesky()
            .map(|c| c.inverse())
            .ok_or_else(|| {
                invalid(format!(
                    "at t = {t} s every activation is 0: some ProMP must be active at each time"
                ))
            })?;
        let mean = &cov * info;
        out.push(Blended {
            time: t,
            mean: mean.as_slice().to_vec(),
            cov,
        });
    }
    Ok(out)
}

impl ProMp {
    /// The start of a CMA-ES search over this ProMP's weights: its mean as `x0`, and its
    /// covariance split into a step size and a shape (see [`SearchStart`]). A covariance
    /// that conditioning left singular gets a ridge of 1e-10 of its mean variance, so the
    /// shape stays positive definite.
    pub fn search_start(&self) -> SearchStart {
        let n = self.mean.len();
        let mean_var = (self.cov.trace() / n as f64).max(1e-300);
        let sigma0 = mean_var.sqrt();
        let mut c = &self.cov / mean_var;
        for i in 0..n {
            c[(i, i)] += 1e-10;
        }
        let c = (&c + c.transpose()) * 0.5;
        SearchStart {
            x0: self.mean.as_slice().to_vec(),
            sigma0,
            covariance: c.transpose().as_slice().to_vec(),
        }
    }

    /// Mean and standard deviation of the position, per dimension, at each time.
    pub fn stats(&self, times: &[f64]) -> Vec<(Vec<f64>, Vec<f64>)> {
        times
            .iter()
            .map(|&t| {
                let (phi, _) = self.features(t);
                let mean = (&phi * &self.mean).as_slice().to_vec();
                let cov = &phi * &self.cov * phi.transpose();
                let std = (0..self.dims)
                    .map(|i| cov[(i, i)].max(0.0).sqrt())
                    .collect();
                (mean, std)
            })
            .collect()
    }

    /// The centres of the basis functions in phase (evenly spaced over `[0, 1]`) and their
    /// common width `h` (`ψᵢ ∝ exp(−(z − cᵢ)² / (2h²))`).
    pub fn basis_layout(&self) -> (Vec<f64>, f64) {
        let n = self.bases;
        (
            (0..n).map(|i| i as f64 / (n - 1) as f64).collect(),
            self.width,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_recurrent_basis_equals_the_definition() {
        for bases in [2, 3, 10, 25, 200] {
            let p = ProMp::new(1, bases, 1.0, vec![0.0; bases], vec![0.0; bases * bases]).unwrap();
            for k in 0..=400 {
                let z = -0.1 + 1.2 * k as f64 / 400.0;
                let (a, b) = (p.basis(z).0, p.basis_direct(z));
                let gap = (&a - &b).amax();
                assert!(gap < 1e-13, "{bases} bases, z = {z}: {gap}");
            }
        }
    }

    #[test]
    fn the_mean_path_is_the_feature_matrix_times_the_mean() {
        let (d, n) = (3, 7);
        let mean: Vec<f64> = (0..d * n).map(|i| (i as f64 * 0.7).sin()).collect();
        let p = ProMp::new(d, n, 2.5, mean, vec![0.0; d * n * d * n]).unwrap();
        let times: Vec<f64> = (0..=50).map(|k| -0.1 + 2.7 * k as f64 / 50.0).collect();
        let (pos, vel) = p.mean_path(&times);
        for (r, &t) in times.iter().enumerate() {
            let (phi, dphi) = p.features(t);
            let (a, b) = (&phi * &p.mean, &dphi * &p.mean);
            for k in 0..d {
                assert!((pos[r * d + k] - a[k]).abs() < 1e-13, "t = {t}, dim {k}");
                assert!((vel[r * d + k] - b[k]).abs() < 1e-12, "t = {t}, dim {k}");
            }
        }
    }

    #[test]
    fn a_weighted_path_is_the_feature_matrix_times_the_weights_to_the_last_bit() {
        let (d, n) = (3, 9);
        let p = ProMp::new(d, n, 4.0, vec![0.0; d * n], vec![0.0; d * n * d * n]).unwrap();
        let w: Vec<f64> = (0..d * n).map(|i| (i as f64 * 1.3).cos() - 0.2).collect();
        let times: Vec<f64> = (0..=80).map(|k| 4.0 * k as f64 / 80.0).collect();
        let (pos, vel) = p.path(&w, &times).unwrap();
        let wv = DVector::from_column_slice(&w);
        for (r, &t) in times.iter().enumerate() {
            let (phi, dphi) = p.features(t);
            let (a, b) = (&phi * &wv, &dphi * &wv);
            for k in 0..d {
                assert_eq!(pos[r * d + k].to_bits(), a[k].to_bits(), "t = {t}, dim {k}");
                assert_eq!(vel[r * d + k].to_bits(), b[k].to_bits(), "t = {t}, dim {k}");
            }
        }
        let e = p.path(&w[1..], &times).unwrap_err().to_string();
        assert_eq!(e, "26 weights for a ProMP of 3 dimensions × 9 bases");
    }
}
