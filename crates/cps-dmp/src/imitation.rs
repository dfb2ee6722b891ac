//! Imitation learning: DMP weights by regression onto demonstrations (thesis §3.2.3).
//!
//! Pipeline, per dimension:
//! 1. **Resampling.** Each demonstration keeps its own time stamps. Its time is mapped
//!    linearly onto `[0, τ]` (time normalisation: the model's τ is a duration you choose;
//!    the demonstration's own duration by default in the CLI) and its positions are
//!    interpolated linearly onto the DMP grid.
//! 2. **Derivatives** on the uniform grid by finite differences: fourth-order central
//!    (five points) in the interior, second-order next to and at the ends (one-sided).
//! 3. **Forcing target** (eq. 48): `f = τ² ÿ − α_z (β_z (g − y) − τ ẏ)` with `y0`, `g` the
//!    trajectory's first and last samples, turned into the target of the weighted basis
//!    `Φ w` by the formulation: `f / (g − y0)` (Ijspeert) or `f / (α_z β_z) + (g − y0) x`
//!    (goal-robust).
//! 4. **Regression** of that target on the features `Φ[k, i] = x_k ψ_i(x_k) / Σ_j ψ_j(x_k)`:
//!    - locally weighted regression (Schaal et al. 2003): per basis function,
//!      `w_i = Σ_k ψ_i x_k t_k / Σ_k ψ_i x_k²`;
//!    - ridge (eq. 51, with the transpose the thesis dropped): `w = (ΦᵀΦ + λ I)⁻¹ Φᵀ t`,
//!      λ = 1e-12 by default as in the thesis;
//!    - jerk-regularised ridge (eq. 52): `w = (ΦᵀΦ + λ P)⁻¹ Φᵀ t` with
//!      `P = Δt · ΓᵀΓ` and `Γ[k, i] = d³Φ_i/dt³ (t_k)` computed exactly by Taylor
//!      arithmetic (no symbolic maths), so `λ wᵀ P w` is λ times the integrated squared
//!      jerk of the weighted basis.
//!
//!    With [`Lambda::Auto`], λ minimises the generalised cross-validation score
//!    `GCV(λ) = n ‖t − Φ w_λ‖² / (n − tr H_λ)²` (Golub, Heath & Wahba 1979), evaluated
//!    exactly for every λ through one generalised eigendecomposition.
//!
//! Several demonstrations are either averaged sample by sample after time normalisation
//! ([`Combine::Mean`]) or stacked into one regression ([`Combine::Stack`]); the model's
//! `y0` and `g` are the mean start and end.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

use crate::jet::Jet;
use crate::{DiscreteDmp, DmpConfig, DmpError, Formulation, Trajectory};

/// A recorded movement: strictly increasing time stamps (seconds) and one position per
/// time stamp.
#[derive(Debug, Clone, PartialEq)]
pub struct Demonstration {
    times: Vec<f64>,
    /// Row-major samples: `values[k * dims + d]`.
    values: Vec<f64>,
    dims: usize,
}

impl Demonstration {
    /// A demonstration from its time stamps and rows of positions. Needs at least 3
    /// samples, finite values, strictly increasing times and rows of one length.
    pub fn new(times: Vec<f64>, rows: &[Vec<f64>]) -> Result<Self, DmpError> {
        let bad = |reason: String| Err(DmpError::InvalidDemonstration { reason });
        if times.len() != rows.len() {
            return bad(format!(
                "{} time stamps for {} samples",
                times.len(),
                rows.len()
            ));
        }
        if times.len() < 3 {
            return bad(format!("needs at least 3 samples, got {}", times.len()));
        }
        let dims = rows[0].len();
        if dims == 0 {
            return bad("samples have no coordinates".into());
        }
        for (k, row) in rows.iter().enumerate() {
            if row.len() != dims {
                return bad(format!(
                    "sample {k} has {} values, the first has {dims}",
                    row.len()
                ));
            }
            if let Some(d) = row.iter().position(|v| !v.is_finite()) {
                return bad(format!(
                    "sample {k}, coordinate {d} is not finite ({})",
                    row[d]
                ));
            }
            if !times[k].is_finite() {
                return bad(format!("time stamp {k} is not finite ({})", times[k]));
            }
            if k > 0 && times[k] <= times[k - 1] {
                return bad(format!(
                    "time stamps must increase strictly: sample {k} at {} s follows {} s",
                    times[k],
                    times[k - 1]
                ));
            }
        }
        Ok(Self {
            times,
            values: rows.iter().flatten().copied().collect(),
            dims,
        })
    }

    /// Number of coordinates per sample.
    pub fn dims(&self) -> usize {
        self.dims
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Always false (a demonstration has at least 3 samples).
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// Time stamps in seconds.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// Sample `k`.
    pub fn sample(&self, k: usize) -> &[f64] {
        &self.values[k * self.dims..(k + 1) * self.dims]
    }

    /// Duration from the first to the last time stamp, in seconds.
    pub fn duration(&self) -> f64 {
        self.times[self.len() - 1] - self.times[0]
    }

    /// The positions at `n ≥ 2` evenly spaced normalised times from the first to the last
    /// time stamp, by linear interpolation; dimension-major (`out[d][k]`).
    pub fn resample(&self, n: usize) -> Vec<Vec<f64>> {
        let (t0, span) = (self.times[0], self.duration());
        let last = self.len() - 1;
        let mut out = vec![vec![0.0; n]; self.dims];
        // Evenly spaced time stamps (the usual recording) locate each sample directly.
        let step = span / last as f64;
        let tol = 1e-9 * span;
        let even = self
            .times
            .iter()
            .enumerate()
            .all(|(k, &t)| (t - (t0 + step * k as f64)).abs() <= tol);
        let scale = last as f64 / (n - 1) as f64;
        let mut seg = 0;
        for k in 0..n {
            let (i, u) = if even {
                let pos = k as f64 * scale;
                // pos ≥ 0, so truncation is the floor.
                let i = (pos as usize).min(last - 1);
                (i, pos - i as f64)
            } else {
                let t = t0 + span * (k as f64 / (n - 1) as f64);
                while seg + 1 < last && self.times[seg + 1] < t {
                    seg += 1;
                }
                let (ta, tb) = (self.times[seg], self.times[seg + 1]);
                (seg, ((t - ta) / (tb - ta)).clamp(0.0, 1.0))
            };
            let (a, b) = (self.sample(i), self.sample(i + 1));
            for (o, (pa, pb)) in out.iter_mut().zip(a.iter().zip(b)) {
                o[k] = pa + u * (pb - pa);
            }
        }
        out
    }
}

/// The regularisation weight λ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lambda {
    /// A given λ ≥ 0.
    Fixed(f64),
    /// Chosen per dimension by generalised cross-validation.
    Auto,
}

/// How the weights are regressed (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Regression {
    /// Schaal's locally weighted regression, one basis function at a time.
    Lwr,
    /// Ridge regression (thesis eq. 51).
    Ridge {
        /// Regularisation weight.
        lambda: Lambda,
    },
    /// Ridge regression penalising the jerk of the weighted basis (thesis eq. 52).
    JerkRidge {
        /// Regularisation weight.
        lambda: Lambda,
    },
}

impl Default for Regression {
    /// Ridge with the thesis's λ = 1e-12.
    fn default() -> Self {
        Regression::Ridge {
            lambda: Lambda::Fixed(1e-12),
        }
    }
}

impl Lambda {
    /// `"auto"` or a number ≥ 0, as a file or the command line gives it; None when it is
    /// neither.
    pub fn parse(text: &str) -> Option<Lambda> {
        match text {
            "auto" => Some(Lambda::Auto),
            v => v.parse::<f64>().ok().and_then(Lambda::fixed),
        }
    }

    /// A given λ when it is finite and ≥ 0.
    pub fn fixed(x: f64) -> Option<Lambda> {
        (x.is_finite() && x >= 0.0).then_some(Lambda::Fixed(x))
    }
}

/// A [`Regression`] by name, without its λ: `lwr`, `ridge`, `jerk`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// [`Regression::Lwr`].
    Lwr,
    /// [`Regression::Ridge`]. Default.
    #[default]
    Ridge,
    /// [`Regression::JerkRidge`].
    Jerk,
}

impl Method {
    /// Every method, in the order of its names.
    pub const ALL: [Method; 3] = [Method::Lwr, Method::Ridge, Method::Jerk];

    /// Its name, the same on the command line, in Python and in the studio.
    pub fn name(self) -> &'static str {
        match self {
            Method::Lwr => "lwr",
            Method::Ridge => "ridge",
            Method::Jerk => "jerk",
        }
    }

    /// The regression with λ given, or the method's default: the thesis's 1e-12 for
    /// ridge, generalised cross-validation for jerk (LWR has none).
    pub fn regression(self, lambda: Option<Lambda>) -> Regression {
        match self {
            Method::Lwr => Regression::Lwr,
            Method::Ridge => Regression::Ridge {
                lambda: lambda.unwrap_or(Lambda::Fixed(1e-12)),
            },
            Method::Jerk => Regression::JerkRidge {
                lambda: lambda.unwrap_or(Lambda::Auto),
            },
        }
    }
}

crate::names::names!(Method, "method");

/// How several demonstrations are combined.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Combine {
    /// Average the time-normalised demonstrations sample by sample, then fit the mean.
    #[default]
    Mean,
    /// One regression over the samples of all demonstrations.
    Stack,
}

impl Combine {
    /// Every way, in the order of its names.
    pub const ALL: [Combine; 2] = [Combine::Mean, Combine::Stack];

    /// Its name: `mean` or `stack`.
    pub fn name(self) -> &'static str {
        match self {
            Combine::Mean => "mean",
            Combine::Stack => "stack",
        }
    }
}

crate::names::names!(Combine, "combine");

/// How well a learned DMP reproduces what it was taught.
#[derive(Debug, Clone, PartialEq)]
pub struct FitReport {
    /// Root-mean-square position error of the model's rollout against the (mean)
    /// demonstration on the grid, per dimension.
    pub rmse: Vec<f64>,
    /// Largest position error, per dimension.
    pub max_error: Vec<f64>,
    /// λ used per dimension (0 for LWR).
    pub lambda: Vec<f64>,
    /// Condition number of the regression matrix (`ΦᵀΦ + λP` of the first dimension; the
    /// Gram matrix `ΦᵀΦ` for LWR).
    pub condition_number: f64,
    /// Integrated squared jerk `∫ (d³y/dt³)² dt` of the model's rollout, per dimension
    /// (finite differences of the acceleration).
    pub integrated_squared_jerk: Vec<f64>,
    /// The same for the (mean) demonstration on the grid.
    pub demo_integrated_squared_jerk: Vec<f64>,
}

/// A learned DMP with its weights and fit report.
#[derive(Debug, Clone)]
pub struct Imitation {
    /// The model (configuration, grid, start = mean first sample, goal = mean last sample).
    pub dmp: DiscreteDmp,
    /// Weights, dimension-major as [`DiscreteDmp::rollout`] takes them.
    pub weights: Vec<f64>,
    /// The fit diagnostics.
    pub report: FitReport,
    /// The (mean) demonstration resampled to the grid, dimension-major.
    pub reference: Vec<Vec<f64>>,
}

/// Learns a DMP with `config` from `demos`.
pub fn imitate(
    config: &DmpConfig,
    demos: &[Demonstration],
    regression: Regression,
    combine: Combine,
) -> Result<Imitation, DmpError> {
    config.validate()?;
    let dmp0 = DiscreteDmp::new(*config, &[0.0], &[1.0])?;
    Imitator::new(dmp0).imitate(demos, regression, combine)
}

/// Imitation with the DMP grid, Gram matrix and jerk penalty precomputed, for repeated
/// fits with one configuration.
#[derive(Debug, Clone)]
pub struct Imitator {
    template: DiscreteDmp,
    gram: Mat<f64>,
    gram_eigen: std::sync::OnceLock<Vec<f64>>,
    jerk: std::sync::OnceLock<Mat<f64>>,
}

impl Imitator {
    /// Precomputes for the grid and basis of `dmp` (its endpoints are ignored).
    pub fn new(dmp: DiscreteDmp) -> Self {
        let (ns, nb) = (dmp.n_samples(), dmp.n_basis());
        let phi = faer::MatRef::from_column_major_slice(&dmp.grid().features, ns, nb);
        let gram = phi.transpose() * phi;
        Self {
            template: dmp,
            gram,
            gram_eigen: std::sync::OnceLock::new(),
            jerk: std::sync::OnceLock::new(),
        }
    }

    /// `Δt · ΓᵀΓ` with `Γ[k, i]` the exact third time derivative of feature i at sample k.
    fn jerk_penalty(&self) -> &Mat<f64> {
        self.jerk.get_or_init(|| {
            let dmp = &self.template;
            let cfg = dmp.config();
            let (ns, nb) = (dmp.n_samples(), dmp.n_basis());
            let (c, h) = (dmp.basis().centers(), dmp.basis().widths());
            let mut gamma = Mat::<f64>::zeros(ns, nb);
            let mut psi = vec![Jet::constant(0.0); nb];
            for (k, &t) in dmp.times().iter().enumerate() {
                let x = Jet::variable(t).scale(-cfg.alpha_x / cfg.tau).exp();
                let mut sum = Jet::constant(0.0);
                for i in 0..nb {
                    let d = x.offset(-c[i]);
                    psi[i] = d.mul(d).scale(-h[i]).exp();
                    sum = sum.add(psi[i]);
                }
                let xs = x.div(sum);
                for i in 0..nb {
                    gamma[(k, i)] = xs.mul(psi[i]).derivative(3);
                }
            }
            let step = cfg.step();
            (gamma.transpose() * &gamma) * faer::Scale(step)
        })
    }

    /// Eigenvalues of the Gram matrix ΦᵀΦ, ascending (computed once).
    fn gram_eigenvalues(&self) -> &[f64] {
        self.gram_eigen.get_or_init(|| {
            self.gram
                .self_adjoint_eigenvalues(Side::Lower)
                .unwrap_or_else(|_| vec![f64::NAN; self.gram.nrows()])
        })
    }

    /// Penalised least squares with λ by cross-validation, per dimension; returns the
    /// condition number of the first dimension's system.
    fn penalised(
        &self,
        p: &Mat<f64>,
        m: f64,
        rhs: &Mat<f64>,
        tt: &[f64],
        weights: &mut [f64],
        lambdas: &mut [f64],
    ) -> Result<f64, DmpError> {
        let nb = self.template.n_basis();
        let n = m * self.template.n_samples() as f64;
        let gram = &self.gram * faer::Scale(m);
        let mut condition = f64::NAN;
        for (d, t2) in tt.iter().enumerate() {
            let r = rhs.col(d).as_mat().to_owned();
            let lam = gcv_lambda(&gram, p, &r, *t2, n)?;
            let a = &gram + p * faer::Scale(lam);
            let sol = solve_spd(&a, &r)?;
            for i in 0..nb {
                weights[d * nb + i] = sol[(i, 0)];
            }
            lambdas[d] = lam;
            if d == 0 {
                condition = condition_number(&a);
            }
        }
        Ok(condition)
    }

    /// The per-dimension targets of one trajectory (dimension-major positions on the grid).
    fn targets(&self, y: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, DmpError> {
        let dmp = &self.template;
        let cfg = dmp.config();
        let h = cfg.step();
        let (tau, az, bz) = (cfg.tau, cfg.alpha_z, cfg.beta_z);
        let x = dmp.phases();
        y.iter()
            .enumerate()
            .map(|(d, yd)| {
                let n = yd.len();
                let (y0, g) = (yd[0], yd[n - 1]);
                let (lo, hi) = yd
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                        (a.min(v), b.max(v))
                    });
                let range = hi - lo;
                let (v, a) = derivatives(yd, h);
                let f = (0..n).map(|k| tau * tau * a[k] - az * (bz * (g - yd[k]) - tau * v[k]));
                Ok(match cfg.formulation {
                    Formulation::Ijspeert2013 => {
                        let amp = g - y0;
                        if range == 0.0 {
                            vec![0.0; n]
                        } else if amp.abs() < 1e-3 * range {
                            return Err(DmpError::DegenerateAmplitude {
                                dim: d,
                                amplitude: amp,
                                range,
                            });
                        } else {
                            f.map(|f| f / amp).collect()
                        }
                    }
                    Formulation::GoalRobust => f
                        .zip(x)
                        .map(|(f, &x)| f / (az * bz) + (g - y0) * x)
                        .collect(),
                })
            })
            .collect()
    }

    /// Learns the weights from `demos` (see the module documentation).
    pub fn imitate(
        &self,
        demos: &[Demonstration],
        regression: Regression,
        combine: Combine,
    ) -> Result<Imitation, DmpError> {
        let fit = self.fit(demos, regression, combine)?;
        let ns = self.template.n_samples();
        let dims = fit.reference.len();
        let start: Vec<f64> = (0..dims).map(|d| fit.reference[d][0]).collect();
        let goal: Vec<f64> = (0..dims).map(|d| fit.reference[d][ns - 1]).collect();
        let dmp = self.template.with_endpoints(&start, &goal)?;
        let traj = dmp.rollout(&fit.weights);
        let report = report(
            &traj,
            &fit.reference,
            fit.lambdas,
            fit.condition,
            self.template.config().step(),
        );
        Ok(Imitation {
            dmp,
            weights: fit.weights,
            report,
            reference: fit.reference,
        })
    }

    /// Only the weights of [`Imitator::imitate`] (no validation rollout, no report), for
    /// loops that fit many times.
    pub fn weights(
        &self,
        demos: &[Demonstration],
        regression: Regression,
        combine: Combine,
    ) -> Result<Vec<f64>, DmpError> {
        Ok(self.fit(demos, regression, combine)?.weights)
    }

    fn fit(
        &self,
        demos: &[Demonstration],
        regression: Regression,
        combine: Combine,
    ) -> Result<Fit, DmpError> {
        let Some(first) = demos.first() else {
            return Err(DmpError::InvalidDemonstration {
                reason: "no demonstrations".into(),
            });
        };
        let dims = first.dims();
        if let Some((i, d)) = demos.iter().enumerate().find(|(_, d)| d.dims() != dims) {
            return Err(DmpError::InvalidDemonstration {
                reason: format!(
                    "demonstration {} has {} coordinates, the first has {dims}",
                    i + 1,
                    d.dims()
                ),
            });
        }
        let ns = self.template.n_samples();
        let nb = self.template.n_basis();
        let resampled: Vec<Vec<Vec<f64>>> = demos.iter().map(|d| d.resample(ns)).collect();
        let mean: Vec<Vec<f64>> = if resampled.len() == 1 {
            resampled[0].clone()
        } else {
            (0..dims)
                .map(|d| {
                    (0..ns)
                        .map(|k| {
                            resampled.iter().map(|r| r[d][k]).sum::<f64>() / demos.len() as f64
                        })
                        .collect()
                })
                .collect()
        };
        let fitted: Vec<Vec<Vec<f64>>> = match combine {
            Combine::Mean => vec![self.targets(&mean)?],
            Combine::Stack => resampled
                .iter()
                .map(|r| self.targets(r))
                .collect::<Result<_, _>>()?,
        };
        let m = fitted.len() as f64;
        let mut weights = vec![0.0; dims * nb];
        let mut lambdas = vec![0.0; dims];
        // Φᵀ T for every dimension at once (summed over stacked targets), and Σ ‖t‖².
        let mut rhs = Mat::<f64>::zeros(nb, dims);
        let mut tt = vec![0.0; dims];
        let features = &self.template.grid().features;
        for t in &fitted {
            let cols: Vec<&[f64]> = t.iter().map(Vec::as_slice).collect();
            let mut out = vec![0.0; nb * dims];
            project(features, ns, &cols, &mut out);
            for d in 0..dims {
                for i in 0..nb {
                    rhs[(i, d)] += out[i * dims + d];
                }
                tt[d] += t[d].iter().map(|v| v * v).sum::<f64>();
            }
        }
        let lambda_of = |lambda: Lambda| match lambda {
            Lambda::Fixed(l) if l.is_finite() && l >= 0.0 => Ok(Some(l)),
            Lambda::Fixed(l) => Err(DmpError::InvalidConfig {
                field: "lambda",
                rule: "must be finite and ≥ 0",
                value: l,
            }),
            Lambda::Auto => Ok(None),
        };
        let condition = match regression {
            Regression::Lwr => {
                let basis = self.template.basis();
                let x = self.template.phases();
                for (i, (&c, &h)) in basis.centers().iter().zip(basis.widths()).enumerate() {
                    let (mut num, mut den) = (vec![0.0; dims], 0.0);
                    for (k, &xk) in x.iter().enumerate() {
                        let psi = (-h * (xk - c) * (xk - c)).exp();
                        den += psi * xk * xk;
                        for t in &fitted {
                            for d in 0..dims {
                                num[d] += psi * xk * t[d][k];
                            }
                        }
                    }
                    for d in 0..dims {
                        weights[d * nb + i] = if den > 0.0 { num[d] / (m * den) } else { 0.0 };
                    }
                }
                let ev = self.gram_eigenvalues();
                ev[nb - 1] / ev[0]
            }
            Regression::Ridge { lambda } => match lambda_of(lambda)? {
                // One factorisation serves every dimension.
                Some(lam) => {
                    let a = &self.gram * faer::Scale(m)
                        + Mat::<f64>::identity(nb, nb) * faer::Scale(lam);
                    let sol = solve_spd(&a, &rhs)?;
                    for d in 0..dims {
                        for i in 0..nb {
                            weights[d * nb + i] = sol[(i, d)];
                        }
                    }
                    lambdas.fill(lam);
                    let ev = self.gram_eigenvalues();
                    (m * ev[nb - 1] + lam) / (m * ev[0] + lam)
                }
                None => self.penalised(
                    &Mat::identity(nb, nb),
                    m,
                    &rhs,
                    &tt,
                    &mut weights,
                    &mut lambdas,
                )?,
            },
            Regression::JerkRidge { lambda } => {
                let p = self.jerk_penalty();
                match lambda_of(lambda)? {
                    Some(lam) => {
                        let a = &self.gram * faer::Scale(m) + p * faer::Scale(lam);
                        let sol = solve_spd(&a, &rhs)?;
                        for d in 0..dims {
                            for i in 0..nb {
                                weights[d * nb + i] = sol[(i, d)];
                            }
                        }
                        lambdas.fill(lam);
                        condition_number(&a)
                    }
                    None => self.penalised(p, m, &rhs, &tt, &mut weights, &mut lambdas)?,
                }
            }
        };
        if let Some(i) = weights.iter().position(|v| !v.is_finite()) {
            return Err(DmpError::NumericalFailure(format!(
                "weight {i} came out non-finite; try a larger λ"
            )));
        }
        Ok(Fit {
            weights,
            lambdas,
            condition,
            reference: mean,
        })
    }
}

/// What a regression produced, before validation.
struct Fit {
    weights: Vec<f64>,
    lambdas: Vec<f64>,
    condition: f64,
    reference: Vec<Vec<f64>>,
}

/// `out[i * T + j] = Φ_iᵀ t_j` for every feature column `i` of the column-major `features`
/// (`ns` rows) and every target `t_j`: each feature value is loaded once for all targets.
/// SIMD with runtime dispatch.
fn project(features: &[f64], ns: usize, targets: &[&[f64]], out: &mut [f64]) {
    struct Project<'a> {
        features: &'a [f64],
        ns: usize,
        targets: &'a [&'a [f64]],
        out: &'a mut [f64],
    }
    impl pulp::WithSimd for Project<'_> {
        type Output = ();
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, simd: S) {
            let nt = self.targets.len();
            for (i, col) in self.features.chunks_exact(self.ns).enumerate() {
                for j0 in (0..nt).step_by(3) {
                    let width = (nt - j0).min(3);
                    let (ch, ct) = S::as_simd_f64s(col);
                    let heads: [&[S::f64s]; 3] = std::array::from_fn(|j| {
                        S::as_simd_f64s(self.targets[j0 + j.min(width - 1)]).0
                    });
                    let zero = simd.splat_f64s(0.0);
                    let (mut a0, mut a1, mut a2) = ([zero; 2], [zero; 2], [zero; 2]);
                    let pairs = ch.len() / 2;
                    for p in 0..pairs {
                        let (k0, k1) = (2 * p, 2 * p + 1);
                        let (x0, x1) = (ch[k0], ch[k1]);
                        a0[0] = simd.mul_add_e_f64s(x0, heads[0][k0], a0[0]);
                        a1[0] = simd.mul_add_e_f64s(x0, heads[1][k0], a1[0]);
                        a2[0] = simd.mul_add_e_f64s(x0, heads[2][k0], a2[0]);
                        a0[1] = simd.mul_add_e_f64s(x1, heads[0][k1], a0[1]);
                        a1[1] = simd.mul_add_e_f64s(x1, heads[1][k1], a1[1]);
                        a2[1] = simd.mul_add_e_f64s(x1, heads[2][k1], a2[1]);
                    }
                    if ch.len() % 2 == 1 {
                        let k = ch.len() - 1;
                        a0[0] = simd.mul_add_e_f64s(ch[k], heads[0][k], a0[0]);
                        a1[0] = simd.mul_add_e_f64s(ch[k], heads[1][k], a1[0]);
                        a2[0] = simd.mul_add_e_f64s(ch[k], heads[2][k], a2[0]);
                    }
                    let acc = [a0, a1, a2];
                    for (j, acc) in acc.iter().enumerate().take(width) {
                        let t = self.targets[j0 + j];
                        let tail = &t[t.len() - ct.len()..];
                        let mut total = simd.reduce_sum_f64s(simd.add_f64s(acc[0], acc[1]));
                        for (x, y) in ct.iter().zip(tail) {
                            total += x * y;
                        }
                        self.out[i * nt + j0 + j] = total;
                    }
                }
            }
        }
    }
    assert!(targets.iter().all(|t| t.len() == ns), "target lengths");
    pulp::Arch::new().dispatch(Project {
        features,
        ns,
        targets,
        out,
    });
}

/// First and second derivatives on a uniform grid of step `h`: fourth-order central
/// differences (five points) inside, second-order ones next to the ends and second-order
/// one-sided differences at the ends.
fn derivatives(y: &[f64], h: f64) -> (Vec<f64>, Vec<f64>) {
    let n = y.len();
    let mut v = vec![0.0; n];
    let mut a = vec![0.0; n];
    let (i2h, ih2) = (0.5 / h, 1.0 / (h * h));
    let (i12h, i12h2) = (1.0 / (12.0 * h), 1.0 / (12.0 * h * h));
    for k in (1..n - 1).filter(|&k| k < 2 || k + 2 >= n) {
        v[k] = (y[k + 1] - y[k - 1]) * i2h;
        a[k] = (y[k + 1] - 2.0 * y[k] + y[k - 1]) * ih2;
    }
    if n >= 5 {
        for (k, w) in y.windows(5).enumerate() {
            let (ym2, ym1, y0, yp1, yp2) = (w[0], w[1], w[2], w[3], w[4]);
            v[k + 2] = (ym2 - yp2 + 8.0 * (yp1 - ym1)) * i12h;
            a[k + 2] = (16.0 * (ym1 + yp1) - (ym2 + yp2) - 30.0 * y0) * i12h2;
        }
    }
    v[0] = (-3.0 * y[0] + 4.0 * y[1] - y[2]) * i2h;
    v[n - 1] = (3.0 * y[n - 1] - 4.0 * y[n - 2] + y[n - 3]) * i2h;
    if n >= 4 {
        a[0] = (2.0 * y[0] - 5.0 * y[1] + 4.0 * y[2] - y[3]) * ih2;
        a[n - 1] = (2.0 * y[n - 1] - 5.0 * y[n - 2] + 4.0 * y[n - 3] - y[n - 4]) * ih2;
    } else {
        a[0] = a[1];
        a[n - 1] = a[n - 2];
    }
    (v, a)
}

/// ∫ (d³y/dt³)² dt from a sampled acceleration.
fn integrated_squared_jerk(acc: &[f64], h: f64) -> f64 {
    acc.windows(2)
        .map(|w| ((w[1] - w[0]) / h).powi(2) * h)
        .sum()
}

fn report(
    traj: &Trajectory,
    reference: &[Vec<f64>],
    lambda: Vec<f64>,
    condition: f64,
    h: f64,
) -> FitReport {
    let dims = reference.len();
    let mut rmse = Vec::with_capacity(dims);
    let mut max_error = Vec::with_capacity(dims);
    let mut jerk = Vec::with_capacity(dims);
    let mut demo_jerk = Vec::with_capacity(dims);
    for (d, r) in reference.iter().enumerate() {
        let e: Vec<f64> = traj.position(d).iter().zip(r).map(|(a, b)| a - b).collect();
        rmse.push((e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt());
        max_error.push(e.iter().fold(0.0f64, |m, v| m.max(v.abs())));
        jerk.push(integrated_squared_jerk(traj.acceleration(d), h));
        demo_jerk.push(integrated_squared_jerk(&derivatives(r, h).1, h));
    }
    FitReport {
        rmse,
        max_error,
        lambda,
        condition_number: condition,
        integrated_squared_jerk: jerk,
        demo_integrated_squared_jerk: demo_jerk,
    }
}

/// Solves `a x = b` for symmetric positive (semi)definite `a`: Cholesky, or, when that
/// fails, the eigendecomposition with eigenvalues below `1e-14 λ_max` dropped.
fn solve_spd(a: &Mat<f64>, b: &Mat<f64>) -> Result<Mat<f64>, DmpError> {
    if let Ok(llt) = a.llt(Side::Lower) {
        return Ok(llt.solve(b));
    }
    let eig = a.self_adjoint_eigen(Side::Lower).map_err(|_| {
        DmpError::NumericalFailure("the eigendecomposition did not converge".into())
    })?;
    let (u, s) = (eig.U(), eig.S().column_vector());
    let smax = s.iter().fold(0.0f64, |m, &v| m.max(v));
    let mut c = u.transpose() * b;
    for i in 0..c.nrows() {
        let v = s[i];
        c[(i, 0)] = if v > 1e-14 * smax { c[(i, 0)] / v } else { 0.0 };
    }
    Ok(u * c)
}

/// `λ_max / λ_min` of a symmetric matrix (∞ if singular).
fn condition_number(a: &Mat<f64>) -> f64 {
    match a.self_adjoint_eigenvalues(Side::Lower) {
        Ok(v) => {
            let (lo, hi) = (v[0], v[v.len() - 1]);
            if lo > 0.0 { hi / lo } else { f64::INFINITY }
        }
        Err(_) => f64::NAN,
    }
}

/// The λ minimising `GCV(λ) = n RSS(λ) / (n − tr H(λ))²` for the penalised least squares
/// `min ‖t − Φw‖² + λ wᵀPw` with Gram `c = ΦᵀΦ`, `rhs = Φᵀt`, `tt = ‖t‖²`, `n` rows.
///
/// With `c = L Lᵀ` and `L⁻¹ P L⁻ᵀ = V Λ Vᵀ`, the fit in the basis `b = Vᵀ L⁻¹ rhs` has
/// `tr H = Σ 1/(1 + λΛ_i)` and `RSS = RSS(0) + Σ b_i² (λΛ_i / (1 + λΛ_i))²`, so every λ
/// costs O(N). A log grid over twenty decades, then golden-section refinement.
fn gcv_lambda(
    c: &Mat<f64>,
    p: &Mat<f64>,
    rhs: &Mat<f64>,
    tt: f64,
    n: f64,
) -> Result<f64, DmpError> {
    let nb = c.nrows();
    let trace = (0..nb).map(|i| c[(i, i)]).sum::<f64>();
    let jitter = Mat::<f64>::identity(nb, nb) * faer::Scale(1e-13 * trace / nb as f64);
    let llt = (c + &jitter).llt(Side::Lower).map_err(|_| {
        DmpError::NumericalFailure("the Gram matrix ΦᵀΦ is not positive definite".into())
    })?;
    let l = llt.L();
    // M = L⁻¹ P L⁻ᵀ by two triangular solves.
    let mut x = p.clone();
    faer::linalg::triangular_solve::solve_lower_triangular_in_place(l, x.as_mut(), faer::Par::Seq);
    let mut m = x.transpose().to_owned();
    faer::linalg::triangular_solve::solve_lower_triangular_in_place(l, m.as_mut(), faer::Par::Seq);
    let eig = m.self_adjoint_eigen(Side::Lower).map_err(|_| {
        DmpError::NumericalFailure("the eigendecomposition did not converge".into())
    })?;
    let mut z = rhs.clone();
    faer::linalg::triangular_solve::solve_lower_triangular_in_place(l, z.as_mut(), faer::Par::Seq);
    let b = eig.U().transpose() * z;
    let lam: Vec<f64> = eig.S().column_vector().iter().map(|v| v.max(0.0)).collect();
    let b2: Vec<f64> = (0..nb).map(|i| b[(i, 0)] * b[(i, 0)]).collect();
    let rss0 = (tt - b2.iter().sum::<f64>()).max(0.0);
    let score = |log_l: f64| {
        let l = 10f64.powf(log_l);
        let (mut rss, mut dof) = (rss0, 0.0);
        for i in 0..nb {
            let s = 1.0 / (1.0 + l * lam[i]);
            dof += s;
            rss += b2[i] * (1.0 - s) * (1.0 - s);
        }
        n * rss / ((n - dof) * (n - dof))
    };
    let lmax = lam
        .iter()
        .fold(0.0f64, |m, &v| m.max(v))
        .max(f64::MIN_POSITIVE);
    let (lo, hi) = ((1e-10 / lmax).log10(), (1e10 / lmax).log10());
    let steps = 200;
    let grid = |i: usize| lo + (hi - lo) * i as f64 / steps as f64;
    let best = (0..=steps)
        .min_by(|&a, &b| score(grid(a)).total_cmp(&score(grid(b))))
        .unwrap_or(0);
    // Golden-section search in the bracketing grid cells.
    let (mut a, mut b) = (grid(best.saturating_sub(1)), grid((best + 1).min(steps)));
    let r = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..40 {
        let (c1, c2) = (b - r * (b - a), a + r * (b - a));
        if score(c1) < score(c2) {
            b = c2;
        } else {
            a = c1;
        }
    }
    Ok(10f64.powf(0.5 * (a + b)))
}
