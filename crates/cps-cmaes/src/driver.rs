//! The loop around ask/tell: objectives, observers, budgets and the result.

use std::ops::ControlFlow;

use rayon::prelude::*;

use crate::{Cmaes, CmaesConfig, CmaesError, ObjectiveError, StopRule, Termination};

/// A cost to minimise. `evaluate` takes `&self` so a population can be evaluated in
/// parallel; it returns an error when the evaluation itself failed (a dead simulator),
/// while a NaN or infinite cost is a valid answer that ranks last.
pub trait Objective: Sync {
    /// The cost of one candidate.
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError>;

    /// The costs of a population: `xs` holds `out.len()` candidates of length `dim` back
    /// to back. The default evaluates them in parallel with rayon (in the current thread
    /// pool) and reports the failure with the lowest index, so errors are deterministic
    /// too. Override it to reuse per-thread buffers.
    fn evaluate_batch(
        &self,
        xs: &[f64],
        dim: usize,
        out: &mut [f64],
    ) -> Result<(), CandidateError> {
        let results: Vec<Result<f64, ObjectiveError>> =
            xs.par_chunks_exact(dim).map(|x| self.evaluate(x)).collect();
        for (index, (r, o)) in results.into_iter().zip(out.iter_mut()).enumerate() {
            *o = r.map_err(|source| CandidateError { index, source })?;
        }
        Ok(())
    }
}

/// One candidate's cost through `objective`'s batch evaluation: the `evaluate` of an
/// objective whose work is done a batch at a time (its own `evaluate_batch`).
pub fn evaluate_through_batch<O: Objective + ?Sized>(
    objective: &O,
    x: &[f64],
) -> Result<f64, ObjectiveError> {
    let mut out = [0.0];
    objective
        .evaluate_batch(x, x.len(), &mut out)
        .map_err(|e| e.source)?;
    Ok(out[0])
}

/// A failed evaluation inside a batch.
#[derive(Debug)]
pub struct CandidateError {
    /// Index of the candidate in the population.
    pub index: usize,
    /// What went wrong.
    pub source: ObjectiveError,
}

/// An [`Objective`] made from a closure returning a cost.
#[derive(Debug, Clone, Copy)]
pub struct FnObjective<F>(pub F);

impl<F: Fn(&[f64]) -> f64 + Sync> Objective for FnObjective<F> {
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
        Ok((self.0)(x))
    }
}

/// What an observer sees after each generation.
#[derive(Debug, Clone, Copy)]
pub struct GenerationReport<'a> {
    /// Generations completed.
    pub generation: u64,
    /// Evaluations spent.
    pub evaluations: u64,
    /// Best cost of this generation (+∞ if none was finite).
    pub best_cost: f64,
    /// Median cost of this generation.
    pub median_cost: f64,
    /// Best cost so far.
    pub best_so_far: f64,
    /// Step size σ after the update.
    pub sigma: f64,
    /// Condition number of C at the last decomposition.
    pub condition: f64,
    /// The distribution mean after the update.
    pub mean: &'a [f64],
}

/// Watches a run; return `ControlFlow::Break(())` to stop it (reported as
/// [`Termination::Interrupted`]).
pub trait Observer {
    /// Called after every generation.
    fn observe(&mut self, report: &GenerationReport<'_>) -> ControlFlow<()>;
}

/// An observer that does nothing.
#[derive(Debug, Default, Clone, Copy)]
pub struct NoObserver;

impl Observer for NoObserver {
    fn observe(&mut self, _: &GenerationReport<'_>) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
}

impl<F: FnMut(&GenerationReport<'_>) -> ControlFlow<()>> Observer for F {
    fn observe(&mut self, report: &GenerationReport<'_>) -> ControlFlow<()> {
        self(report)
    }
}

/// The outcome of [`minimize`].
#[derive(Debug, Clone)]
pub struct Solution {
    /// The best candidate evaluated.
    pub best_x: Vec<f64>,
    /// Its cost (+∞ if no evaluation was finite).
    pub best_cost: f64,
    /// The final distribution mean.
    pub mean: Vec<f64>,
    /// The final step size.
    pub sigma: f64,
    /// The final distribution's standard deviation per coordinate, `σ √C_ii` (in the
    /// search's own, unbounded coordinates).
    pub stds: Vec<f64>,
    /// Generations run.
    pub generations: u64,
    /// Objective evaluations spent.
    pub evaluations: u64,
    /// Evaluations that returned NaN or an infinite cost.
    pub non_finite_evaluations: u64,
    /// Covariance repairs (numerical loss of positive definiteness).
    pub repairs: u64,
    /// Why the run ended.
    pub termination: Termination,
}

/// Minimises `objective` from `x0` until one of `rules` fires or `observer` stops it.
///
/// `rules` must contain a budget ([`StopRule::MaxGenerations`] or
/// [`StopRule::MaxEvaluations`]) so that every run ends. The population is evaluated
/// with [`Objective::evaluate_batch`], in parallel in the current rayon pool; the result
/// is the same for any number of threads.
pub fn minimize<O: Objective + ?Sized>(
    objective: &O,
    x0: &[f64],
    config: &CmaesConfig,
    rules: &[StopRule],
    observer: &mut dyn Observer,
) -> Result<Solution, CmaesError> {
    config.validate(x0.len())?;
    // With bounds the search runs on the unbounded space, from the preimage of x0.
    let start = match &config.bounds {
        Some(bounds) => {
            let mut z0 = vec![0.0; x0.len()];
            bounds.inverse(x0, &mut z0)?;
            z0
        }
        None => x0.to_vec(),
    };
    let mut es = Cmaes::new(config, &start)?;
    resume(&mut es, objective, rules, observer)
}

/// Continues a run: a new one from [`Cmaes::new`], or one restored from a
/// [`crate::Checkpoint`] with [`Cmaes::resume`], which then goes on exactly as the
/// uninterrupted run would have (budgets count from the run's start). Within bounds
/// (the configuration's), candidates are mapped into the box before evaluation and the
/// returned best point and mean are in the box.
pub fn resume<O: Objective + ?Sized>(
    es: &mut Cmaes,
    objective: &O,
    rules: &[StopRule],
    observer: &mut dyn Observer,
) -> Result<Solution, CmaesError> {
    if !rules
        .iter()
        .any(|r| matches!(r, StopRule::MaxGenerations(_) | StopRule::MaxEvaluations(_)))
    {
        return Err(CmaesError::InvalidConfig {
            field: "rules",
            rule: "must contain a MaxGenerations or MaxEvaluations budget",
            value: rules.len() as f64,
        });
    }
    match es.config().bounds.clone() {
        Some(bounds) => {
            let wrapped = Bounded {
                inner: objective,
                bounds: &bounds,
            };
            let mut sol = search(es, &wrapped, rules, observer)?;
            let (best, mean) = (sol.best_x.clone(), sol.mean.clone());
            bounds.transform(&best, &mut sol.best_x);
            bounds.transform(&mean, &mut sol.mean);
            Ok(sol)
        }
        None => search(es, objective, rules, observer),
    }
}

/// The CMA-ES loop of [`minimize`] and [`resume`], on the unbounded space.
fn search<O: Objective + ?Sized>(
    es: &mut Cmaes,
    objective: &O,
    rules: &[StopRule],
    observer: &mut dyn Observer,
) -> Result<Solution, CmaesError> {
    let n = es.parameters().n;
    let mut costs = vec![0.0; es.parameters().lambda];
    let termination = loop {
        if let Some(t) = es.termination(rules) {
            break t;
        }
        let generation = es.generation();
        es.ask();
        if let Err(e) = objective.evaluate_batch(es.population(), n, &mut costs) {
            if e.source.is::<crate::EndSearch>() {
                break Termination::Ended;
            }
            return Err(CmaesError::Objective {
                generation,
                index: e.index,
                source: e.source,
            });
        }
        es.tell(&costs)?;
        let sorted = es.last_costs();
        let report = GenerationReport {
            generation: es.generation(),
            evaluations: es.evaluations(),
            best_cost: sorted[0],
            median_cost: sorted[sorted.len() / 2],
            best_so_far: es.best().map_or(f64::INFINITY, |(_, f)| f),
            sigma: es.sigma(),
            condition: es.condition(),
            mean: es.mean(),
        };
        if observer.observe(&report).is_break() {
            break Termination::Interrupted;
        }
    };
    let (best_x, best_cost) = match es.best() {
        Some((x, f)) => (x.to_vec(), f),
        None => (es.mean().to_vec(), f64::INFINITY),
    };
    Ok(Solution {
        best_x,
        best_cost,
        mean: es.mean().to_vec(),
        sigma: es.sigma(),
        stds: es
            .covariance_diagonal()
            .iter()
            .map(|c| es.sigma() * c.sqrt())
            .collect(),
        generations: es.generation(),
        evaluations: es.evaluations(),
        non_finite_evaluations: es.non_finite_evaluations(),
        repairs: es.repairs(),
        termination,
    })
}

/// The result of [`minimize_ipop`]: the overall best and every run.
#[derive(Debug, Clone)]
pub struct RestartSolution {
    /// The best candidate over all runs; `evaluations`, `non_finite_evaluations`,
    /// `repairs` and `generations` are totals; `termination` is the last run's.
    pub best: Solution,
    /// Each run in order (run r has population λ₀ · 2^r).
    pub runs: Vec<Solution>,
}

/// Runs [`minimize`] repeatedly with the settings `plan(run, spent_large, spent_small)`
/// returns (`None` ends the sequence), until the target, the budget or an interruption.
/// The second element of a plan says whether the run belongs to the large-population
/// regime (for BIPOP's budget bookkeeping).
fn restarts<O: Objective + ?Sized>(
    objective: &O,
    x0: &[f64],
    rules: &[StopRule],
    observer: &mut dyn Observer,
    mut plan: impl FnMut(usize, u64, u64) -> Option<(CmaesConfig, bool)>,
) -> Result<RestartSolution, CmaesError> {
    let mut runs: Vec<Solution> = Vec::new();
    let (mut spent, mut large, mut small) = (0u64, 0u64, 0u64);
    for r in 0.. {
        let Some((cfg, is_large)) = plan(r, large, small) else {
            break;
        };
        let budget: Vec<StopRule> = rules
            .iter()
            .map(|rule| match rule {
                StopRule::MaxEvaluations(max) => {
                    StopRule::MaxEvaluations(max.saturating_sub(spent))
                }
                other => other.clone(),
            })
            .collect();
        let run = minimize(objective, x0, &cfg, &budget, observer)?;
        spent += run.evaluations;
        if is_large {
            large += run.evaluations;
        } else {
            small += run.evaluations;
        }
        let done = matches!(
            run.termination,
            Termination::Interrupted
                | Termination::Ended
                | Termination::Rule(StopRule::TargetCost(_))
                | Termination::Rule(StopRule::MaxEvaluations(_))
        );
        runs.push(run);
        if done {
            break;
        }
    }
    let best_run = runs
        .iter()
        .min_by(|a, b| a.best_cost.total_cmp(&b.best_cost))
        .expect("at least one run");
    let last = runs.last().expect("at least one run");
    let best = Solution {
        best_x: best_run.best_x.clone(),
        best_cost: best_run.best_cost,
        mean: best_run.mean.clone(),
        sigma: best_run.sigma,
        stds: best_run.stds.clone(),
        generations: runs.iter().map(|r| r.generations).sum(),
        evaluations: spent,
        non_finite_evaluations: runs.iter().map(|r| r.non_finite_evaluations).sum(),
        repairs: runs.iter().map(|r| r.repairs).sum(),
        termination: last.termination.clone(),
    };
    Ok(RestartSolution { best, runs })
}

/// Validates `config` for dimension `n` and returns its population λ₀ (the default when
/// unset), the starting point of every restart schedule.
fn base_population(config: &CmaesConfig, n: usize) -> Result<usize, CmaesError> {
    config.validate(n)?;
    Ok(config
        .population
        .unwrap_or_else(|| crate::Parameters::default_lambda(n)))
}

/// The seed of restart `r`: `seed + r · 0x9E37_79B9_7F4A_7C15` (wrapping).
fn restart_seed(seed: u64, r: usize) -> u64 {
    seed.wrapping_add((r as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// IPOP-CMA-ES (Auger & Hansen 2005): runs [`minimize`] and, while a run ends by a rule
/// other than the target, the budget or an interruption, restarts it from the same `x0`
/// and σ₀ with the population doubled, up to `max_restarts` times. Run r uses the seed
/// `seed + r · 0x9E37_79B9_7F4A_7C15` (wrapping), so the whole sequence is reproducible.
/// A [`StopRule::MaxEvaluations`] budget counts over all runs together.
pub fn minimize_ipop<O: Objective + ?Sized>(
    objective: &O,
    x0: &[f64],
    config: &CmaesConfig,
    rules: &[StopRule],
    max_restarts: usize,
    observer: &mut dyn Observer,
) -> Result<RestartSolution, CmaesError> {
    let lambda0 = base_population(config, x0.len())?;
    restarts(objective, x0, rules, observer, |r, _, _| {
        (r <= max_restarts).then(|| {
            let cfg = CmaesConfig {
                population: Some(lambda0 << r.min(20)),
                seed: restart_seed(config.seed, r),
                ..config.clone()
            };
            (cfg, true)
        })
    })
}

/// An objective seen through a boundary transformation: candidates are mapped into the
/// box before the inner objective sees them.
struct Bounded<'a, O: ?Sized> {
    inner: &'a O,
    bounds: &'a crate::Bounds,
}

impl<O: Objective + ?Sized> Objective for Bounded<'_, O> {
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
        let mut y = vec![0.0; x.len()];
        self.bounds.transform(x, &mut y);
        self.inner.evaluate(&y)
    }

    fn evaluate_batch(
        &self,
        xs: &[f64],
        dim: usize,
        out: &mut [f64],
    ) -> Result<(), CandidateError> {
        let mut ys = vec![0.0; xs.len()];
        for (x, y) in xs.chunks_exact(dim).zip(ys.chunks_exact_mut(dim)) {
            self.bounds.transform(x, y);
        }
        self.inner.evaluate_batch(&ys, dim, out)
    }
}

/// BIPOP-CMA-ES (Hansen 2009): after a first run with the default population, restarts
/// alternate between two regimes, each time choosing the one that has spent fewer
/// evaluations: the large regime doubles the population at each of its runs (as IPOP,
/// σ₀ unchanged, up to `max_large_restarts` of them), the small regime draws
/// `λ = ⌊λ₀ (λ_large / (2 λ₀))^{u²}⌋` and `σ = σ₀ · 10^{−2u}` with `u` uniform in [0, 1)
/// (seeded, reproducible), where `λ_large` is the last large population. Ends when the
/// large regime has used its restarts, or by the target, the budget or an interruption.
pub fn minimize_bipop<O: Objective + ?Sized>(
    objective: &O,
    x0: &[f64],
    config: &CmaesConfig,
    rules: &[StopRule],
    max_large_restarts: usize,
    observer: &mut dyn Observer,
) -> Result<RestartSolution, CmaesError> {
    use rand::{Rng, SeedableRng};
    let lambda0 = base_population(config, x0.len())?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(restart_seed(config.seed, usize::MAX));
    let mut large_runs = 0usize;
    restarts(
        objective,
        x0,
        rules,
        observer,
        |r, spent_large, spent_small| {
            let seed = restart_seed(config.seed, r);
            if r == 0 {
                return Some((
                    CmaesConfig {
                        seed,
                        ..config.clone()
                    },
                    true,
                ));
            }
            let lambda_large = lambda0 << (large_runs + 1).min(20);
            if spent_small < spent_large {
                let u: f64 = rng.random();
                let ratio = lambda_large as f64 / (2.0 * lambda0 as f64);
                let lambda = ((lambda0 as f64) * ratio.powf(u * u)).floor().max(2.0) as usize;
                let cfg = CmaesConfig {
                    population: Some(lambda),
                    sigma0: config.sigma0 * 10f64.powf(-2.0 * rng.random::<f64>()),
                    seed,
                    ..config.clone()
                };
                Some((cfg, false))
            } else if large_runs < max_large_restarts {
                large_runs += 1;
                let cfg = CmaesConfig {
                    population: Some(lambda0 << large_runs.min(20)),
                    seed,
                    ..config.clone()
                };
                Some((cfg, true))
            } else {
                None
            }
        },
    )
}
