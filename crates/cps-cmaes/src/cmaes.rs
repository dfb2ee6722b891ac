//! The CMA-ES state and its ask/tell step (Hansen 2016, active covariance update).

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{
    LltRegularization, cholesky_in_place, cholesky_in_place_scratch,
};
use faer::linalg::evd::{self, ComputeEigenvectors};
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::{Accum, Mat, Par};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::{CmaesConfig, CmaesError, Parameters, StopRule, Termination};

/// A CMA-ES optimiser driven by [`Cmaes::ask`] and [`Cmaes::tell`].
///
/// One generation: `ask` samples λ candidates `x_k = m + σ A z_k` with `z_k ~ N(0, I)`
/// drawn from a stream keyed by (seed, generation), so a run does not depend on who
/// evaluates the candidates or in which order; `tell` takes their costs (NaN and ±∞ rank
/// last and are counted) and updates mean, step size, evolution paths and the covariance
/// C with positive and negative (active) weights.
///
/// `A` is the Cholesky factor of C (C = A Aᵀ, lower triangular), refactored after every
/// update, and the step-size path is accumulated in its coordinates, `A⁻¹ y_w = z_w`,
/// instead of those of the symmetric root `C^{-1/2}` — the Cholesky CMA-ES of Krause,
/// Arbonès & Igel (2016), which they show to perform as the eigendecomposition form. A
/// Cholesky factorisation costs n³/3 flops (≈ 15 µs at n = 75); a symmetric
/// eigendecomposition of a covariance close to isotropic costs ≈ 500 µs at n = 75 with
/// faer, so even pycma's lazy refresh every ≈ 5 generations would dominate a generation.
/// C is kept bit-for-bit symmetric; if a factorisation fails (C lost positive
/// definiteness), C is rebuilt from the last factor and the repair is counted.
///
/// With [`CmaesConfig::separable`] C is diagonal (sep-CMA-ES): `D` holds its standard
/// deviations, sampling is `x_k = m + σ D z_k`, and no matrix is stored.
///
/// The eigendecomposition C = B D² Bᵀ serves only the diagnostics — [`Self::condition`]
/// and the stop rules `TolUpSigma`, `ConditionCov` and `NoEffectAxis` — and is refreshed
/// every `eigen_gap` generations (default: `n`, at least the lazy gap
/// `1 / (2 n (c1 + cμ))`).
///
/// [`crate::minimize`] runs the loop with stopping rules and observers; use `ask`/`tell`
/// directly when you need to own the loop.
#[derive(Debug)]
pub struct Cmaes {
    params: Parameters,
    config: CmaesConfig,
    gap: u64,
    mean: Vec<f64>,
    sigma: f64,
    /// Full form: C, its Cholesky factor (lower triangle; zeros above) and the diagnostic
    /// eigenvectors. Separable form: all three are empty.
    c: Mat<f64>,
    a: Mat<f64>,
    b: Mat<f64>,
    /// Full form: square roots of C's eigenvalues (diagnostic). Separable form: the standard
    /// deviations, C = diag(d²).
    d: Vec<f64>,
    separable: bool,
    p_sigma: Vec<f64>,
    p_c: Vec<f64>,
    generation: u64,
    evaluations: u64,
    non_finite: u64,
    repairs: u64,
    last_decomposition: u64,
    condition: f64,
    z: Mat<f64>,
    y: Mat<f64>,
    x: Vec<f64>,
    sorted_costs: Vec<f64>,
    best: Option<(Vec<f64>, f64)>,
    best_history: Vec<f64>,
    median_history: Vec<f64>,
    flat_generations: u64,
    work: Work,
}

/// The separable form's covariance update, on the diagonal only: the same rank-one and
/// active rank-μ terms (steps and weights in `work.ys` / `work.yw`), giving the new
/// variances; `None` if one turns non-positive or non-finite (the update is then not
/// taken: a repair).
fn diagonal_update(
    p: &Parameters,
    work: &Work,
    p_c: &[f64],
    d: &[f64],
    decay: f64,
) -> Option<Vec<f64>> {
    let new: Vec<f64> = (0..p.n)
        .map(|i| {
            let rank_mu: f64 = (0..p.lambda)
                .map(|r| work.yw[(i, r)] * work.ys[(i, r)])
                .sum();
            decay * d[i] * d[i] + p.c1 * p_c[i] * p_c[i] + p.c_mu * rank_mu
        })
        .collect();
    new.iter().all(|v| v.is_finite() && *v > 0.0).then_some(new)
}

/// Copies the lower triangle of `c` onto the upper one: C stays symmetric bit for bit.
fn mirror_lower(c: &mut Mat<f64>) {
    for j in 0..c.ncols() {
        for i in j + 1..c.nrows() {
            c[(j, i)] = c[(i, j)];
        }
    }
}

/// Buffers reused every generation.
struct Work {
    order: Vec<usize>,
    yw: Mat<f64>,
    ys: Mat<f64>,
    /// The factorisation in progress (`a` is replaced only if it succeeds).
    factor: Mat<f64>,
    eigvals: faer::diag::Diag<f64>,
    eigvecs: Mat<f64>,
    stack: MemBuffer,
}

impl std::fmt::Debug for Work {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Work { .. }")
    }
}

/// The `format` of a [`Checkpoint`].
pub const CHECKPOINT_FORMAT: &str = "cps-cmaes-checkpoint";
/// The `version` of a [`Checkpoint`] this build writes and reads.
pub const CHECKPOINT_VERSION: u32 = 2;

/// A run's whole state between two generations, from [`Cmaes::checkpoint`]; with the
/// `serde` feature it (de)serialises (matrices column-major). JSON cannot hold NaN or
/// infinite costs: with costs that may be non-finite use a binary format.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Checkpoint {
    format: String,
    version: u32,
    sigma0: f64,
    population: usize,
    seed: u64,
    eigen_gap: u64,
    initial_scales: Option<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(default))]
    initial_covariance: Option<Vec<f64>>,
    bounds: Option<(Vec<f64>, Vec<f64>)>,
    #[cfg_attr(feature = "serde", serde(default))]
    separable: bool,
    mean: Vec<f64>,
    sigma: f64,
    c: Vec<f64>,
    a: Vec<f64>,
    b: Vec<f64>,
    d: Vec<f64>,
    p_sigma: Vec<f64>,
    p_c: Vec<f64>,
    generation: u64,
    evaluations: u64,
    non_finite: u64,
    repairs: u64,
    last_decomposition: u64,
    condition: f64,
    sorted_costs: Vec<f64>,
    best: Option<(Vec<f64>, f64)>,
    best_history: Vec<f64>,
    median_history: Vec<f64>,
    flat_generations: u64,
}

impl Checkpoint {
    /// The generation the run had completed.
    pub fn generation(&self) -> u64 {
        self.generation
    }
}

impl Cmaes {
    /// A new optimiser centred at `x0`.
    pub fn new(config: &CmaesConfig, x0: &[f64]) -> Result<Self, CmaesError> {
        let n = x0.len();
        config.validate(n)?;
        if let Some(&v) = x0.iter().find(|v| !v.is_finite()) {
            return Err(CmaesError::InvalidConfig {
                field: "x0",
                rule: "must be finite",
                value: v,
            });
        }
        let lambda = config.lambda(n);
        let separable = config.separable;
        let params = if separable {
            Parameters::separable(n, lambda)
        } else {
            Parameters::new(n, lambda)
        };
        // The separable form stores no matrix.
        let m = if separable { 0 } else { n };
        let gap = config
            .eigen_gap
            .unwrap_or_else(|| params.default_eigen_gap().max(n as u64));
        let scales = config
            .initial_scales
            .clone()
            .unwrap_or_else(|| vec![1.0; n]);
        let c = Mat::from_fn(
            m,
            m,
            |i, j| if i == j { scales[i] * scales[i] } else { 0.0 },
        );
        let a = Mat::from_fn(m, m, |i, j| if i == j { scales[i] } else { 0.0 });
        let b = Mat::identity(m, m);
        let (max, min) = scales.iter().fold((0.0f64, f64::INFINITY), |(a, b), s| {
            (a.max(s * s), b.min(s * s))
        });
        let par = Par::Seq;
        let req = if separable {
            StackReq::EMPTY
        } else {
            StackReq::any_of(&[
                evd::self_adjoint_evd_scratch::<f64>(
                    n,
                    ComputeEigenvectors::Yes,
                    par,
                    Default::default(),
                ),
                cholesky_in_place_scratch::<f64>(n, par, Default::default()),
            ])
        };
        let mut es = Self {
            gap,
            mean: x0.to_vec(),
            sigma: config.sigma0,
            c,
            a,
            b,
            d: scales,
            separable,
            p_sigma: vec![0.0; n],
            p_c: vec![0.0; n],
            generation: 0,
            evaluations: 0,
            non_finite: 0,
            repairs: 0,
            last_decomposition: 0,
            condition: max / min,
            z: Mat::zeros(n, lambda),
            y: Mat::zeros(n, lambda),
            x: vec![0.0; n * lambda],
            sorted_costs: Vec::with_capacity(lambda),
            best: None,
            best_history: Vec::new(),
            median_history: Vec::new(),
            flat_generations: 0,
            work: Work {
                order: (0..lambda).collect(),
                yw: Mat::zeros(n, lambda),
                ys: Mat::zeros(n, lambda),
                factor: Mat::zeros(m, m),
                eigvals: faer::diag::Diag::zeros(m),
                eigvecs: Mat::zeros(m, m),
                stack: MemBuffer::new(req),
            },
            params,
            config: config.clone(),
        };
        if let Some(c0) = &config.initial_covariance {
            for i in 0..n {
                for j in 0..n {
                    es.c[(i, j)] = c0[i * n + j];
                }
            }
            mirror_lower(&mut es.c);
            es.factorize();
            if es.repairs > 0 {
                return Err(CmaesError::InvalidConfig {
                    field: "initial_covariance",
                    rule: "must be positive definite (its Cholesky factorisation failed)",
                    value: 0.0,
                });
            }
            es.decompose();
        }
        Ok(es)
    }

    /// Samples a new population and returns it: λ candidates of length n back to back.
    /// Asking again before [`Self::tell`] returns the same candidates.
    pub fn ask(&mut self) -> &[f64] {
        let (n, lambda) = (self.params.n, self.params.lambda);
        let mut rng = ChaCha8Rng::seed_from_u64(self.config.seed);
        rng.set_stream(self.generation);
        for k in 0..lambda {
            for i in 0..n {
                self.z[(i, k)] = StandardNormal.sample(&mut rng);
            }
        }
        if self.separable {
            for k in 0..lambda {
                for i in 0..n {
                    self.y[(i, k)] = self.d[i] * self.z[(i, k)];
                }
            }
        } else {
            triangular::matmul(
                self.y.as_mut(),
                BlockStructure::Rectangular,
                Accum::Replace,
                self.a.as_ref(),
                BlockStructure::TriangularLower,
                self.z.as_ref(),
                BlockStructure::Rectangular,
                1.0,
                Par::Seq,
            );
        }
        for k in 0..lambda {
            let col = self.y.col(k);
            for i in 0..n {
                self.x[k * n + i] = self.mean[i] + self.sigma * col[i];
            }
        }
        &self.x
    }

    /// The current population (as returned by the last [`Self::ask`]).
    pub fn population(&self) -> &[f64] {
        &self.x
    }

    /// Updates the distribution from the costs of the last asked population.
    /// Lower is better; NaN and infinite costs rank last and are counted in
    /// [`Self::non_finite_evaluations`].
    pub fn tell(&mut self, costs: &[f64]) -> Result<(), CmaesError> {
        let p = &self.params;
        let (n, lambda, mu) = (p.n, p.lambda, p.mu);
        if costs.len() != lambda {
            return Err(CmaesError::DimensionMismatch {
                what: "costs",
                got: costs.len(),
                expected: lambda,
            });
        }
        // Counters saturate: a resumed checkpoint may carry any count.
        self.evaluations = self.evaluations.saturating_add(lambda as u64);
        self.non_finite = self
            .non_finite
            .saturating_add(costs.iter().filter(|c| !c.is_finite()).count() as u64);
        let key = |c: f64| if c.is_nan() { f64::INFINITY } else { c };
        let order = &mut self.work.order;
        order.iter_mut().enumerate().for_each(|(i, o)| *o = i);
        order.sort_by(|&a, &b| key(costs[a]).total_cmp(&key(costs[b])).then(a.cmp(&b)));
        self.sorted_costs.clear();
        self.sorted_costs
            .extend(order.iter().map(|&i| key(costs[i])));
        let best_now = self.sorted_costs[0];
        if best_now.is_finite() && self.best.as_ref().is_none_or(|(_, f)| best_now < *f) {
            let k = order[0];
            self.best = Some((self.x[k * n..(k + 1) * n].to_vec(), best_now));
        }

        // Weighted means of the selected steps, in y (= B D z) and z coordinates.
        let mut y_w = vec![0.0; n];
        let mut z_w = vec![0.0; n];
        for (rank, &k) in order.iter().take(mu).enumerate() {
            let w = p.weights[rank];
            let (yc, zc) = (self.y.col(k), self.z.col(k));
            for i in 0..n {
                y_w[i] += w * yc[i];
                z_w[i] += w * zc[i];
            }
        }
        for (m, y) in self.mean.iter_mut().zip(&y_w) {
            *m += p.c_m * self.sigma * y;
        }
        // Step-size path in the coordinates of the factor that sampled y: A⁻¹ y_w = z_w.
        let cs = (p.c_sigma * (2.0 - p.c_sigma) * p.mu_eff).sqrt();
        for (ps, z) in self.p_sigma.iter_mut().zip(&z_w) {
            *ps = (1.0 - p.c_sigma) * *ps + cs * z;
        }
        let ps_norm = self.p_sigma.iter().map(|v| v * v).sum::<f64>().sqrt();
        let g1 = self.generation as f64 + 1.0;
        let h_sigma = ps_norm / (1.0 - (1.0 - p.c_sigma).powf(2.0 * g1)).sqrt()
            < (1.4 + 2.0 / (n as f64 + 1.0)) * p.chi_n;
        let cc = (p.c_c * (2.0 - p.c_c) * p.mu_eff).sqrt();
        let cc = if h_sigma { cc } else { 0.0 };
        for (pc, y) in self.p_c.iter_mut().zip(&y_w) {
            *pc = (1.0 - p.c_c) * *pc + cc * y;
        }

        // Covariance: rank-one and active rank-μ update, negative weights rescaled by
        // n / ‖A⁻¹ y‖² = n / ‖z‖².
        let delta = if h_sigma { 0.0 } else { p.c_c * (2.0 - p.c_c) };
        let sum_w: f64 = p.weights.iter().sum();
        let decay = 1.0 + p.c1 * delta - p.c1 - p.c_mu * sum_w;
        for (rank, &k) in order.iter().enumerate() {
            let mut w = p.weights[rank];
            if w < 0.0 {
                let z2: f64 = self.z.col(k).iter().map(|v| v * v).sum();
                w *= n as f64 / z2.max(f64::MIN_POSITIVE);
            }
            for i in 0..n {
                let yi = self.y[(i, k)];
                self.work.ys[(i, rank)] = yi;
                self.work.yw[(i, rank)] = w * yi;
            }
        }
        if self.separable {
            match diagonal_update(p, &self.work, &self.p_c, &self.d, decay) {
                Some(new) => {
                    for (d, v) in self.d.iter_mut().zip(&new) {
                        *d = v.sqrt();
                    }
                    let (max, min) = new
                        .iter()
                        .fold((0.0f64, f64::INFINITY), |(a, b), &v| (a.max(v), b.min(v)));
                    self.condition = max / min;
                }
                None => self.repairs = self.repairs.saturating_add(1),
            }
        } else {
            for j in 0..n {
                for i in j..n {
                    self.c[(i, j)] = decay * self.c[(i, j)] + p.c1 * self.p_c[i] * self.p_c[j];
                }
            }
            // Only the lower triangle is computed (and then mirrored).
            triangular::matmul(
                self.c.as_mut(),
                BlockStructure::TriangularLower,
                Accum::Add,
                self.work.yw.as_ref(),
                BlockStructure::Rectangular,
                self.work.ys.transpose(),
                BlockStructure::Rectangular,
                p.c_mu,
                Par::Seq,
            );
            mirror_lower(&mut self.c);
        }

        let ratio = (p.c_sigma / p.d_sigma) * (ps_norm / p.chi_n - 1.0);
        self.sigma *= ratio.min(1.0).exp();
        self.generation = self.generation.saturating_add(1);

        let median = self.sorted_costs[lambda / 2];
        self.best_history.push(best_now);
        self.median_history.push(median);
        let flat_index = ((0.1 + lambda as f64 / 4.0).ceil() as usize).clamp(1, lambda) - 1;
        if self.sorted_costs[0] == self.sorted_costs[flat_index] {
            self.flat_generations = self.flat_generations.saturating_add(1);
        } else {
            self.flat_generations = 0;
        }
        if !self.separable {
            self.factorize();
            if self.generation.saturating_sub(self.last_decomposition) >= self.gap {
                self.decompose();
            }
        }
        Ok(())
    }

    /// `C_ii`.
    fn c_ii(&self, i: usize) -> f64 {
        if self.separable {
            self.d[i] * self.d[i]
        } else {
            self.c[(i, i)]
        }
    }

    /// A = chol(C); if C is not finite or not positive definite, C is rebuilt from the
    /// last factor instead (a repair).
    fn factorize(&mut self) {
        let n = self.params.n;
        let finite = (0..n).all(|j| (j..n).all(|i| self.c[(i, j)].is_finite()));
        let f = &mut self.work.factor;
        f.copy_from(self.c.as_ref());
        let ok = finite
            && cholesky_in_place(
                f.as_mut(),
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut self.work.stack),
                Default::default(),
            )
            .is_ok();
        if ok {
            for j in 0..n {
                for i in 0..j {
                    self.a[(i, j)] = 0.0;
                }
                for i in j..n {
                    self.a[(i, j)] = f[(i, j)];
                }
            }
        } else {
            self.repairs = self.repairs.saturating_add(1);
            self.rebuild_c_from_a();
        }
    }

    /// Refreshes the diagnostic eigendecomposition C = B D² Bᵀ and the condition number;
    /// a failed decomposition (C is finite and positive definite here, as it was just
    /// factorised, so this is a solver failure) keeps the previous one.
    fn decompose(&mut self) {
        self.last_decomposition = self.generation;
        let n = self.params.n;
        let w = &mut self.work;
        let ok = evd::self_adjoint_evd(
            self.c.as_ref(),
            w.eigvals.as_mut(),
            Some(w.eigvecs.as_mut()),
            Par::Seq,
            MemStack::new(&mut w.stack),
            Default::default(),
        )
        .is_ok();
        let vals = w.eigvals.column_vector();
        let max = vals.iter().fold(0.0f64, |a, &v| a.max(v));
        if !(ok && max > 0.0 && vals.iter().all(|v| v.is_finite())) {
            return;
        }
        let floor = max * 1e-16;
        for i in 0..n {
            self.d[i] = vals[i].max(floor).sqrt();
        }
        self.b.copy_from(w.eigvecs.as_ref());
        let min = self.d.iter().fold(f64::INFINITY, |a, &v| a.min(v * v));
        self.condition = max / min;
    }

    /// C = A Aᵀ, symmetric by construction.
    fn rebuild_c_from_a(&mut self) {
        triangular::matmul(
            self.c.as_mut(),
            BlockStructure::TriangularLower,
            Accum::Replace,
            self.a.as_ref(),
            BlockStructure::TriangularLower,
            self.a.transpose(),
            BlockStructure::TriangularUpper,
            1.0,
            Par::Seq,
        );
        mirror_lower(&mut self.c);
    }

    /// The first rule in `rules` that fires now, if any.
    pub fn termination(&self, rules: &[StopRule]) -> Option<Termination> {
        rules
            .iter()
            .find(|r| self.fires(r))
            .map(|r| Termination::Rule(r.clone()))
    }

    fn fires(&self, rule: &StopRule) -> bool {
        let p = &self.params;
        let (n, lambda) = (p.n, p.lambda);
        let g = self.generation;
        match *rule {
            StopRule::MaxGenerations(max) => g >= max,
            StopRule::MaxEvaluations(max) => self.evaluations + lambda as u64 > max,
            StopRule::TargetCost(target) => self.best.as_ref().is_some_and(|(_, f)| *f <= target),
            StopRule::TolFun(tol) => {
                let window = 10 + (30.0 * n as f64 / lambda as f64).ceil() as usize;
                if self.best_history.len() < window || self.sorted_costs.is_empty() {
                    return false;
                }
                let recent = &self.best_history[self.best_history.len() - window..];
                let range = |v: &[f64]| {
                    let (lo, hi) = v
                        .iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                            (a.min(x), b.max(x))
                        });
                    hi - lo
                };
                let finite: Vec<f64> = self
                    .sorted_costs
                    .iter()
                    .copied()
                    .filter(|c| c.is_finite())
                    .collect();
                !finite.is_empty() && range(recent) < tol && range(&finite) < tol
            }
            StopRule::TolX(tol) => {
                (0..n).all(|i| self.sigma * self.p_c[i].abs().max(self.c_ii(i).sqrt()) < tol)
            }
            StopRule::TolUpSigma(tol) => {
                let dmax = self.d.iter().fold(0.0f64, |a, &v| a.max(v));
                self.sigma / self.config.sigma0 > tol * dmax
            }
            StopRule::ConditionCov(tol) => self.condition > tol,
            StopRule::FlatFitness(k) => self.flat_generations >= k,
            StopRule::Stagnation => {
                // pycma's tolstagnation: T = 100 + 100 n^1.5 / λ generations; after
                // n (5 + 100/λ) generations, compare the last l = max(T/10, G/10) values
                // with the l before them, in the history of best and of median costs.
                let nf = n as f64;
                let lam = lambda as f64;
                let hist = self.best_history.len();
                let t = 100.0 + 100.0 * nf.powf(1.5) / lam;
                let l = (t / 10.0).max(hist as f64 / 10.0) as usize;
                if (g as f64) <= nf * (5.0 + 100.0 / lam) || hist <= 100 || 2 * l >= hist {
                    return false;
                }
                let median = |v: &[f64]| {
                    let mut s = v.to_vec();
                    s.sort_by(f64::total_cmp);
                    s[s.len() / 2]
                };
                let stale = |h: &[f64]| {
                    let end = h.len();
                    median(&h[end - l..]) >= median(&h[end - 2 * l..end - l])
                };
                stale(&self.best_history) && stale(&self.median_history)
            }
            StopRule::NoEffectAxis => {
                if g == 0 {
                    return false;
                }
                let i = (g % n as u64) as usize;
                if self.separable {
                    // The principal axes are the coordinate axes.
                    return self.mean[i] == self.mean[i] + 0.1 * self.sigma * self.d[i];
                }
                (0..n).all(|j| {
                    self.mean[j] == self.mean[j] + 0.1 * self.sigma * self.d[i] * self.b[(j, i)]
                })
            }
            StopRule::NoEffectCoord => {
                g > 0
                    && (0..n).any(|i| {
                        self.mean[i] == self.mean[i] + 0.2 * self.sigma * self.c_ii(i).sqrt()
                    })
            }
        }
    }

    /// The strategy parameters.
    pub fn parameters(&self) -> &Parameters {
        &self.params
    }

    /// The configuration the run was made with.
    pub fn config(&self) -> &CmaesConfig {
        &self.config
    }

    /// Everything needed to continue this run exactly, between generations (after
    /// [`Self::tell`]): save it (feature `serde`), later [`Self::resume`] it and go on with
    /// [`crate::resume`]; the continued run is bit for bit the uninterrupted one.
    pub fn checkpoint(&self) -> Checkpoint {
        let flat = |m: &Mat<f64>| -> Vec<f64> {
            (0..m.ncols())
                .flat_map(|j| (0..m.nrows()).map(move |i| (i, j)))
                .map(|(i, j)| m[(i, j)])
                .collect()
        };
        Checkpoint {
            format: CHECKPOINT_FORMAT.into(),
            version: CHECKPOINT_VERSION,
            sigma0: self.config.sigma0,
            population: self.params.lambda,
            seed: self.config.seed,
            eigen_gap: self.gap,
            initial_scales: self.config.initial_scales.clone(),
            initial_covariance: self.config.initial_covariance.clone(),
            bounds: self
                .config
                .bounds
                .as_ref()
                .map(|b| (b.lower().to_vec(), b.upper().to_vec())),
            separable: self.separable,
            mean: self.mean.clone(),
            sigma: self.sigma,
            c: flat(&self.c),
            a: flat(&self.a),
            b: flat(&self.b),
            d: self.d.clone(),
            p_sigma: self.p_sigma.clone(),
            p_c: self.p_c.clone(),
            generation: self.generation,
            evaluations: self.evaluations,
            non_finite: self.non_finite,
            repairs: self.repairs,
            last_decomposition: self.last_decomposition,
            condition: self.condition,
            sorted_costs: self.sorted_costs.clone(),
            best: self.best.clone(),
            best_history: self.best_history.clone(),
            median_history: self.median_history.clone(),
            flat_generations: self.flat_generations,
        }
    }

    /// Restores a run from a [`Checkpoint`]; the checkpoint is checked (format, version,
    /// sizes, finite state).
    pub fn resume(checkpoint: &Checkpoint) -> Result<Self, CmaesError> {
        let cp = checkpoint;
        let bad = |rule: &'static str, value: f64| CmaesError::InvalidConfig {
            field: "checkpoint",
            rule,
            value,
        };
        if cp.format != CHECKPOINT_FORMAT || cp.version != CHECKPOINT_VERSION {
            return Err(bad(
                "must be a cps-cmaes checkpoint of version 2",
                f64::from(cp.version),
            ));
        }
        let n = cp.mean.len();
        let config = CmaesConfig {
            sigma0: cp.sigma0,
            population: Some(cp.population),
            seed: cp.seed,
            eigen_gap: Some(cp.eigen_gap),
            initial_scales: cp.initial_scales.clone(),
            initial_covariance: cp.initial_covariance.clone(),
            bounds: match &cp.bounds {
                Some((l, u)) => Some(crate::Bounds::new(l.clone(), u.clone())?),
                None => None,
            },
            separable: cp.separable,
        };
        let mut es = Self::new(&config, &cp.mean)?;
        let m = if cp.separable { 0 } else { n };
        let square = |v: &[f64]| v.len() == m * m;
        if !(square(&cp.c)
            && square(&cp.a)
            && square(&cp.b)
            && cp.d.len() == n
            && cp.p_sigma.len() == n
            && cp.p_c.len() == n)
        {
            return Err(bad(
                "has matrices and paths that do not match the mean's length",
                n as f64,
            ));
        }
        let finite =
            cp.c.iter()
                .chain(&cp.a)
                .chain(&cp.b)
                .chain(&cp.d)
                .all(|v| v.is_finite());
        if !(cp.sigma.is_finite() && cp.sigma > 0.0 && finite) {
            return Err(bad("must hold a finite state with σ > 0", cp.sigma));
        }
        if !cp.p_sigma.iter().chain(&cp.p_c).all(|v| v.is_finite()) {
            return Err(bad("must hold finite evolution paths", f64::NAN));
        }
        // The counters and histories must tell one story: as many history entries as
        // generations, a decomposition and a flat run no later than now, the last
        // generation's costs for the population, a best point of the mean's length.
        let g = cp.generation;
        let consistent = cp.last_decomposition <= g
            && cp.flat_generations <= g
            && cp.best_history.len() as u64 == g
            && cp.median_history.len() as u64 == g
            && (cp.sorted_costs.len() == cp.population || (g == 0 && cp.sorted_costs.is_empty()))
            && cp.best.as_ref().is_none_or(|(x, _)| x.len() == n)
            && cp.condition.is_finite()
            && cp.condition >= 1.0;
        if !consistent {
            return Err(bad(
                "has counters and histories that do not fit together (generation, histories, last decomposition, costs, best point)",
                g as f64,
            ));
        }
        let unflat = |v: &[f64]| Mat::from_fn(m, m, |i, j| v[j * m + i]);
        es.sigma = cp.sigma;
        es.c = unflat(&cp.c);
        es.a = unflat(&cp.a);
        es.b = unflat(&cp.b);
        es.d.clone_from(&cp.d);
        es.p_sigma.clone_from(&cp.p_sigma);
        es.p_c.clone_from(&cp.p_c);
        es.generation = cp.generation;
        es.evaluations = cp.evaluations;
        es.non_finite = cp.non_finite;
        es.repairs = cp.repairs;
        es.last_decomposition = cp.last_decomposition;
        es.condition = cp.condition;
        es.sorted_costs.clone_from(&cp.sorted_costs);
        es.best.clone_from(&cp.best);
        es.best_history.clone_from(&cp.best_history);
        es.median_history.clone_from(&cp.median_history);
        es.flat_generations = cp.flat_generations;
        Ok(es)
    }

    /// The distribution mean.
    pub fn mean(&self) -> &[f64] {
        &self.mean
    }

    /// The step size σ.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// The covariance matrix C (n × n, symmetric); empty (0 × 0) in the separable form,
    /// whose C is [`Self::covariance_diagonal`].
    pub fn covariance(&self) -> faer::MatRef<'_, f64> {
        self.c.as_ref()
    }

    /// The diagonal of C (in either form).
    pub fn covariance_diagonal(&self) -> Vec<f64> {
        (0..self.params.n).map(|i| self.c_ii(i)).collect()
    }

    /// Condition number of C at the last (diagnostic) eigendecomposition, refreshed every
    /// `eigen_gap` generations.
    pub fn condition(&self) -> f64 {
        self.condition
    }

    /// Generations completed.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Objective evaluations told so far.
    pub fn evaluations(&self) -> u64 {
        self.evaluations
    }

    /// Costs told so far that were NaN or infinite.
    pub fn non_finite_evaluations(&self) -> u64 {
        self.non_finite
    }

    /// Times C had to be repaired because its Cholesky factorisation found it not
    /// positive definite (or not finite).
    pub fn repairs(&self) -> u64 {
        self.repairs
    }

    /// The best candidate seen so far and its cost.
    pub fn best(&self) -> Option<(&[f64], f64)> {
        self.best.as_ref().map(|(x, f)| (x.as_slice(), *f))
    }

    /// Costs of the last told generation, sorted ascending (non-finite as +∞).
    pub fn last_costs(&self) -> &[f64] {
        &self.sorted_costs
    }
}
