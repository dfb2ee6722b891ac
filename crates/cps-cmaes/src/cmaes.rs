//! The CMA-ES state and its ask/tell step (Hansen 2016, active covariance update).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self, ComputeEigenvectors};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::{CmaesConfig, CmaesError, Parameters, StopRule, Termination};

/// A CMA-ES optimiser driven by [`Cmaes::ask`] and [`Cmaes::tell`].
///
/// One generation: `ask` samples λ candidates `x_k = m + σ B D z_k` with `z_k ~ N(0, I)`
/// drawn from a stream keyed by (seed, generation), so a run does not depend on who
/// evaluates the candidates or in which order; `tell` takes their costs (NaN and ±∞ rank
/// last and are counted) and updates mean, step size, evolution paths and the covariance
/// C with positive and negative (active) weights. B and D (C = B D² Bᵀ) are refreshed
/// every `eigen_gap` generations; C is kept bit-for-bit symmetric and repaired if it ever
/// loses positive definiteness.
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
    c: Mat<f64>,
    b: Mat<f64>,
    d: Vec<f64>,
    bd: Mat<f64>,
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
    defer: bool,
    work: Work,
}

/// Buffers reused every generation.
struct Work {
    /// C as it was when a deferred decomposition became due.
    snapshot: Mat<f64>,
    /// A deferred decomposition waits for `decompose_snapshot`.
    pending: bool,
    /// `Some(ok)` once the deferred decomposition ran.
    ready: Option<bool>,
    order: Vec<usize>,
    yw: Mat<f64>,
    ys: Mat<f64>,
    eigvals: faer::diag::Diag<f64>,
    eigvecs: Mat<f64>,
    stack: MemBuffer,
}

impl Work {
    /// Symmetric eigendecomposition of `c` (lower triangle) into `vals`, `vecs`; false if
    /// `c` is not finite or the solver failed.
    fn eigen(
        c: faer::MatRef<'_, f64>,
        vals: &mut faer::diag::Diag<f64>,
        vecs: &mut Mat<f64>,
        stack: &mut MemBuffer,
    ) -> bool {
        let finite = (0..c.ncols()).all(|j| c.col(j).iter().all(|v| v.is_finite()));
        finite
            && evd::self_adjoint_evd(
                c,
                vals.as_mut(),
                Some(vecs.as_mut()),
                Par::Seq,
                MemStack::new(stack),
                Default::default(),
            )
            .is_ok()
    }

    fn decompose_snapshot(&mut self) -> bool {
        Work::eigen(
            self.snapshot.as_ref(),
            &mut self.eigvals,
            &mut self.eigvecs,
            &mut self.stack,
        )
    }
}

impl std::fmt::Debug for Work {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Work { .. }")
    }
}

/// The `format` of a [`Checkpoint`].
pub const CHECKPOINT_FORMAT: &str = "cps-cmaes-checkpoint";
/// The `version` of a [`Checkpoint`] this build writes and reads.
pub const CHECKPOINT_VERSION: u32 = 1;

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
    bounds: Option<(Vec<f64>, Vec<f64>)>,
    mean: Vec<f64>,
    sigma: f64,
    c: Vec<f64>,
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
    pending_decomposition: Option<Vec<f64>>,
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
        let params = Parameters::new(n, lambda);
        let gap = config
            .eigen_gap
            .unwrap_or_else(|| params.default_eigen_gap());
        let scales = config
            .initial_scales
            .clone()
            .unwrap_or_else(|| vec![1.0; n]);
        let c = Mat::from_fn(
            n,
            n,
            |i, j| if i == j { scales[i] * scales[i] } else { 0.0 },
        );
        let b = Mat::identity(n, n);
        let bd = Mat::from_fn(n, n, |i, j| if i == j { scales[i] } else { 0.0 });
        let (max, min) = scales.iter().fold((0.0f64, f64::INFINITY), |(a, b), s| {
            (a.max(s * s), b.min(s * s))
        });
        let par = Par::Seq;
        let req = evd::self_adjoint_evd_scratch::<f64>(
            n,
            ComputeEigenvectors::Yes,
            par,
            Default::default(),
        );
        Ok(Self {
            gap,
            mean: x0.to_vec(),
            sigma: config.sigma0,
            c,
            b,
            d: scales,
            bd,
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
            defer: false,
            work: Work {
                snapshot: Mat::zeros(n, n),
                pending: false,
                ready: None,
                order: (0..lambda).collect(),
                yw: Mat::zeros(n, lambda),
                ys: Mat::zeros(n, lambda),
                eigvals: faer::diag::Diag::zeros(n),
                eigvecs: Mat::zeros(n, n),
                stack: MemBuffer::new(req),
            },
            params,
            config: config.clone(),
        })
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
        matmul(
            self.y.as_mut(),
            Accum::Replace,
            self.bd.as_ref(),
            self.z.as_ref(),
            1.0,
            Par::Seq,
        );
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
        self.evaluations += lambda as u64;
        self.non_finite += costs.iter().filter(|c| !c.is_finite()).count() as u64;
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
        // Step-size path: C^{-1/2} y_w = B z_w for the decomposition that sampled y.
        let cs = (p.c_sigma * (2.0 - p.c_sigma) * p.mu_eff).sqrt();
        for i in 0..n {
            let bz: f64 = (0..n).map(|j| self.b[(i, j)] * z_w[j]).sum();
            self.p_sigma[i] = (1.0 - p.c_sigma) * self.p_sigma[i] + cs * bz;
        }
        let ps_norm = self.p_sigma.iter().map(|v| v * v).sum::<f64>().sqrt();
        let g1 = (self.generation + 1) as f64;
        let h_sigma = ps_norm / (1.0 - (1.0 - p.c_sigma).powf(2.0 * g1)).sqrt()
            < (1.4 + 2.0 / (n as f64 + 1.0)) * p.chi_n;
        let cc = (p.c_c * (2.0 - p.c_c) * p.mu_eff).sqrt();
        let cc = if h_sigma { cc } else { 0.0 };
        for (pc, y) in self.p_c.iter_mut().zip(&y_w) {
            *pc = (1.0 - p.c_c) * *pc + cc * y;
        }

        // Covariance: rank-one and active rank-μ update, negative weights rescaled by
        // n / ‖C^{-1/2} y‖² = n / ‖z‖².
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
        for j in 0..n {
            for i in j..n {
                self.c[(i, j)] = decay * self.c[(i, j)] + p.c1 * self.p_c[i] * self.p_c[j];
            }
        }
        matmul(
            self.c.as_mut(),
            Accum::Add,
            self.work.yw.as_ref(),
            self.work.ys.transpose(),
            p.c_mu,
            Par::Seq,
        );
        // Bit-for-bit symmetry: keep the lower triangle, mirror it.
        for j in 0..n {
            for i in j + 1..n {
                self.c[(j, i)] = self.c[(i, j)];
            }
        }

        let ratio = (p.c_sigma / p.d_sigma) * (ps_norm / p.chi_n - 1.0);
        self.sigma *= ratio.min(1.0).exp();
        self.generation += 1;

        let median = self.sorted_costs[lambda / 2];
        self.best_history.push(best_now);
        self.median_history.push(median);
        let flat_index = ((0.1 + lambda as f64 / 4.0).ceil() as usize).clamp(1, lambda) - 1;
        if self.sorted_costs[0] == self.sorted_costs[flat_index] {
            self.flat_generations += 1;
        } else {
            self.flat_generations = 0;
        }
        if let Some(ok) = self.work.ready.take() {
            self.apply_eigen(ok, true);
        }
        if self.generation - self.last_decomposition >= self.gap {
            if self.defer {
                self.last_decomposition = self.generation;
                self.work.snapshot.copy_from(self.c.as_ref());
                self.work.pending = true;
            } else {
                self.decompose();
            }
        }
        Ok(())
    }

    /// Defers each due eigendecomposition by one generation so that it can run while the
    /// next population is evaluated ([`Self::evaluate_overlapped`]). The run stays
    /// deterministic (the delay is fixed); sampling uses a decomposition one generation
    /// older, as with any lazy update gap.
    pub(crate) fn defer_decompositions(&mut self) {
        self.defer = true;
    }

    /// Evaluates the current population with `evaluate` while a deferred decomposition, if
    /// one is pending, runs on another rayon worker.
    pub(crate) fn evaluate_overlapped<R: Send>(
        &mut self,
        evaluate: impl FnOnce(&[f64]) -> R + Send,
    ) -> R {
        let (x, work) = (&self.x, &mut self.work);
        if !work.pending {
            return evaluate(x);
        }
        let (r, ok) = rayon::join(|| evaluate(x), || work.decompose_snapshot());
        work.pending = false;
        work.ready = Some(ok);
        r
    }

    /// Refreshes B, D (C = B D² Bᵀ), repairing C if it is not positive definite or not
    /// finite.
    fn decompose(&mut self) {
        self.last_decomposition = self.generation;
        let ok = Work::eigen(
            self.c.as_ref(),
            &mut self.work.eigvals,
            &mut self.work.eigvecs,
            &mut self.work.stack,
        );
        self.apply_eigen(ok, false);
    }

    /// Installs the eigendecomposition held in the work buffers. One computed from a
    /// snapshot (`deferred`) that needs any repair is discarded and C is decomposed
    /// afresh, because C has moved on since the snapshot.
    fn apply_eigen(&mut self, ok: bool, deferred: bool) {
        let n = self.params.n;
        let vals = self.work.eigvals.column_vector();
        let max = vals.iter().fold(0.0f64, |a, &v| a.max(v));
        let floor = max * 1e-16;
        let clean = ok && max > 0.0 && vals.iter().all(|&v| v.is_finite() && v > floor);
        if deferred && !clean {
            self.decompose();
            return;
        }
        if !ok || max.is_nan() || max <= 0.0 || !vals.iter().all(|v| v.is_finite()) {
            // Numerical failure: fall back to the last good decomposition.
            self.repairs += 1;
            self.rebuild_c_from_bd();
            return;
        }
        for i in 0..n {
            self.d[i] = vals[i].max(floor).sqrt();
        }
        self.b.copy_from(self.work.eigvecs.as_ref());
        let min = self.d.iter().fold(f64::INFINITY, |a, &v| a.min(v * v));
        self.condition = max / min;
        for j in 0..n {
            for i in 0..n {
                self.bd[(i, j)] = self.b[(i, j)] * self.d[j];
            }
        }
        if !clean {
            self.repairs += 1;
            self.rebuild_c_from_bd();
        }
    }

    /// C = (B D)(B D)ᵀ, symmetric by construction.
    fn rebuild_c_from_bd(&mut self) {
        let n = self.params.n;
        matmul(
            self.c.as_mut(),
            Accum::Replace,
            self.bd.as_ref(),
            self.bd.transpose(),
            1.0,
            Par::Seq,
        );
        for j in 0..n {
            for i in j + 1..n {
                self.c[(j, i)] = self.c[(i, j)];
            }
        }
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
                (0..n).all(|i| self.sigma * self.p_c[i].abs().max(self.c[(i, i)].sqrt()) < tol)
            }
            StopRule::TolUpSigma(tol) => {
                let dmax = self.d.iter().fold(0.0f64, |a, &v| a.max(v));
                self.sigma / self.config.sigma0 > tol * dmax
            }
            StopRule::ConditionCov(tol) => self.condition > tol,
            StopRule::FlatFitness(k) => self.flat_generations >= k,
            StopRule::Stagnation => {
                let min_len = 120 + (30.0 * n as f64 / lambda as f64).ceil() as usize;
                let hist = self.best_history.len();
                if hist < min_len {
                    return false;
                }
                let len = min_len.max((0.2 * hist as f64).ceil() as usize).min(hist);
                let median = |v: &[f64]| {
                    let mut s = v.to_vec();
                    s.sort_by(f64::total_cmp);
                    s[s.len() / 2]
                };
                let stale = |h: &[f64]| {
                    let w = &h[h.len() - len..];
                    let k = 20.min(w.len());
                    median(&w[w.len() - k..]) >= median(&w[..k])
                };
                stale(&self.best_history) && stale(&self.median_history)
            }
            StopRule::NoEffectAxis => {
                if g == 0 {
                    return false;
                }
                let i = (g % n as u64) as usize;
                (0..n).all(|j| {
                    self.mean[j] == self.mean[j] + 0.1 * self.sigma * self.d[i] * self.b[(j, i)]
                })
            }
            StopRule::NoEffectCoord => {
                g > 0
                    && (0..n).any(|i| {
                        self.mean[i] == self.mean[i] + 0.2 * self.sigma * self.c[(i, i)].sqrt()
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
        let n = self.params.n;
        let flat = |m: &Mat<f64>| -> Vec<f64> {
            (0..n)
                .flat_map(|j| (0..n).map(move |i| (i, j)))
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
            bounds: self
                .config
                .bounds
                .as_ref()
                .map(|b| (b.lower().to_vec(), b.upper().to_vec())),
            mean: self.mean.clone(),
            sigma: self.sigma,
            c: flat(&self.c),
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
            pending_decomposition: self.work.pending.then(|| flat(&self.work.snapshot)),
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
                "must be a cps-cmaes checkpoint of version 1",
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
            bounds: match &cp.bounds {
                Some((l, u)) => Some(crate::Bounds::new(l.clone(), u.clone())?),
                None => None,
            },
        };
        let mut es = Self::new(&config, &cp.mean)?;
        let square = |v: &[f64]| v.len() == n * n;
        if !(square(&cp.c)
            && square(&cp.b)
            && cp.d.len() == n
            && cp.p_sigma.len() == n
            && cp.p_c.len() == n)
            || cp
                .pending_decomposition
                .as_ref()
                .is_some_and(|v| !square(v))
        {
            return Err(bad(
                "has matrices and paths that do not match the mean's length",
                n as f64,
            ));
        }
        let finite = cp.c.iter().chain(&cp.b).chain(&cp.d).all(|v| v.is_finite());
        if !(cp.sigma.is_finite() && cp.sigma > 0.0 && finite) {
            return Err(bad("must hold a finite state with σ > 0", cp.sigma));
        }
        let unflat = |v: &[f64]| Mat::from_fn(n, n, |i, j| v[j * n + i]);
        es.sigma = cp.sigma;
        es.c = unflat(&cp.c);
        es.b = unflat(&cp.b);
        es.d.clone_from(&cp.d);
        for j in 0..n {
            for i in 0..n {
                es.bd[(i, j)] = es.b[(i, j)] * es.d[j];
            }
        }
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
        if let Some(snapshot) = &cp.pending_decomposition {
            es.work.snapshot = unflat(snapshot);
            es.work.pending = true;
        }
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

    /// The covariance matrix C (n × n, symmetric).
    pub fn covariance(&self) -> faer::MatRef<'_, f64> {
        self.c.as_ref()
    }

    /// Condition number of C at the last decomposition.
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

    /// Times C had to be repaired after a decomposition found it not positive definite.
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
