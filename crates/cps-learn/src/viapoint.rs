//! Via-point learning: CMA-ES over DMP weights (Rueckert & d'Avella 2013), with the exact
//! least-squares optimum as a reference, a solver and a warm start.

use std::ops::ControlFlow;
use std::time::Instant;

use cps_cmaes::{
    CandidateError, CmaesConfig, GenerationReport, Objective, ObjectiveError, StopRule, minimize,
};
use cps_dmp::{DiscreteDmp, Trajectory};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::lsq;
use crate::search::BufferPool;
pub use crate::search::{GenerationRecord, SearchStats};
use crate::{
    CostBreakdown, ExactOptimum, LearnError, Parametrisation, QuadraticCost, SearchSpace,
    TaskErrors, ViaPointTask, exact_optimum,
};

/// How the weights are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Solver {
    /// CMA-ES, the general method (works for costs that are not quadratic). Default.
    #[default]
    Cmaes,
    /// The exact least-squares optimum (only for costs without a simulator in the loop).
    Exact,
    /// Levenberg–Marquardt on the cost's residuals, from the warm start: for costs that
    /// are sums of squares but not quadratic (obstacles, forward kinematics, orientations).
    /// Converges in tens of steps to the nearest minimum; CMA-ES searches more widely.
    LeastSquares,
}

/// How CMA-ES evaluates a candidate's cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Evaluation {
    /// The quadratic form whenever the cost is quadratic (no obstacles), else a rollout.
    /// Default.
    #[default]
    Auto,
    /// Roll out the DMP and sum the cost along the movement, every candidate.
    Rollout,
    /// The cost's exact quadratic form in the parameters ([`QuadraticCost`]): the same
    /// value to rounding, for `n²` multiply-adds instead of a rollout. Only for costs
    /// without obstacles.
    Quadratic,
}

/// A name that is none of a setting's names: `"magic" is not one of "cmaes", "exact",
/// "least_squares"`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("\"{value}\" is not one of {}", known.iter().map(|k| format!("\"{k}\"")).collect::<Vec<_>>().join(", "))]
pub struct UnknownName {
    /// What was given.
    pub value: String,
    /// The names known.
    pub known: Vec<&'static str>,
}

/// A setting with one name per value, the same in experiment files, summaries, Python and
/// the studio: the one place its names are written.
macro_rules! names {
    ($ty:ident { $($variant:ident => $name:literal),+ $(,)? }) => {
        impl $ty {
            /// Every value, in the order of its names.
            pub const ALL: &'static [$ty] = &[$($ty::$variant),+];

            /// Its name (as experiment files spell it).
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl std::str::FromStr for $ty {
            type Err = UnknownName;

            fn from_str(s: &str) -> Result<Self, UnknownName> {
                $ty::ALL.iter().copied().find(|v| v.name() == s).ok_or_else(|| UnknownName {
                    value: s.to_string(),
                    known: $ty::ALL.iter().map(|v| v.name()).collect(),
                })
            }
        }
    };
}

names!(Solver {
    Cmaes => "cmaes",
    Exact => "exact",
    LeastSquares => "least_squares",
});

names!(Parametrisation {
    Raw => "raw",
    ThesisScaling => "thesis_scaling",
    AnchorOffset => "anchor_offset",
});

names!(Evaluation {
    Auto => "auto",
    Rollout => "rollout",
    Quadratic => "quadratic",
});

/// Everything a via-point learning run needs.
#[derive(Debug, Clone, PartialEq)]
pub struct ViaPointConfig {
    /// The task and its cost.
    pub task: ViaPointTask,
    /// The search space CMA-ES works in. Default: [`Parametrisation::AnchorOffset`].
    pub parametrisation: Parametrisation,
    /// CMA-ES or the exact solve.
    pub solver: Solver,
    /// Start CMA-ES at the exact optimum instead of θ = 0 (zero weights).
    pub warm_start: bool,
    /// How CMA-ES evaluates a candidate: a rollout, or the cost's quadratic form.
    pub evaluation: Evaluation,
    /// After CMA-ES, Levenberg–Marquardt from its best until converged (it only takes
    /// steps that lower the cost): CMA-ES finds the basin, the polish its bottom.
    pub polish: bool,
    /// Initial CMA-ES step size in the units of the search space (metres for
    /// `AnchorOffset`).
    pub sigma0: f64,
    /// Population size; `None` = `4 + ⌊3 ln n⌋` (16 for 75 weights).
    pub population: Option<usize>,
    /// Generation budget per repetition.
    pub generations: u64,
    /// Stop a repetition early when the best costs of the last `10 + 30n/λ` generations
    /// and the current population all lie within this range (CMA-ES's tolfun); `None` = off.
    pub tol_fun: Option<f64>,
    /// Independent repetitions, each with its own seed derived from `seed`.
    pub repetitions: usize,
    /// Master seed.
    pub seed: u64,
}

/// A via-point learner's setting outside its range: which, the rule, and the value given.
/// Every front end (experiment files, Python, the studio) checks through
/// [`ViaPointConfig`]'s `check_*` functions and adds its own place to the sentence.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("`{field}` must be {rule} (got {got})")]
pub struct BadSetting {
    /// The setting's name, as files and keyword arguments spell it.
    pub field: &'static str,
    /// Its range, in words.
    pub rule: &'static str,
    /// The value given.
    pub got: String,
}

impl BadSetting {
    /// `value` when `ok`, else the sentence for `field` and its `rule`.
    fn unless<T: std::fmt::Debug>(
        ok: bool,
        field: &'static str,
        rule: &'static str,
        value: T,
    ) -> Result<T, Self> {
        if ok {
            Ok(value)
        } else {
            Err(Self {
                field,
                rule,
                got: format!("{value:?}"),
            })
        }
    }
}

/// Settings each within its range that do not go together (in the words of an experiment
/// file's `[optimizer]` and of Python's keywords alike).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SettingConflict {
    /// `polish` with a solver other than CMA-ES.
    #[error(
        "`polish` = true polishes a CMA-ES result, and `method` is not \"cmaes\": remove `polish` (least squares is already the polish)"
    )]
    PolishWithoutCmaes,
    /// The quadratic evaluation of a cost with obstacles.
    #[error(
        "`evaluation` = \"quadratic\" needs a quadratic cost, and the obstacle term is not one: use evaluation = \"rollout\" (or leave it out: \"auto\" picks the rollout here)"
    )]
    QuadraticWithObstacles,
    /// The exact solver for a cost with obstacles.
    #[error(
        "`method` = \"exact\" leaves the obstacle term out (it is not quadratic in the weights): use method = \"cmaes\" (warm_start = true starts it at the exact, obstacle-free optimum)"
    )]
    ExactWithObstacles,
}

impl ViaPointConfig {
    /// Defaults for a task: anchor-offset space, CMA-ES from zero weights, σ₀ = 0.5 (task
    /// units), default population, 1000 generations, tolfun 1e-9, one repetition, seed 1.
    pub fn new(task: ViaPointTask) -> Self {
        Self {
            task,
            parametrisation: Parametrisation::default(),
            solver: Solver::default(),
            warm_start: false,
            evaluation: Evaluation::default(),
            polish: false,
            sigma0: 0.5,
            population: None,
            generations: 1000,
            tol_fun: Some(1e-9),
            repetitions: 1,
            seed: 1,
        }
    }

    /// σ₀: finite, > 0 and at most 1e6.
    pub fn check_sigma0(v: f64) -> Result<f64, BadSetting> {
        let ok = v.is_finite() && v > 0.0 && v <= 1e6;
        BadSetting::unless(ok, "sigma0", "finite, > 0 and at most 1e6", v)
    }

    /// The population: 2 to 100 000.
    pub fn check_population(p: usize) -> Result<usize, BadSetting> {
        BadSetting::unless(
            (2..=100_000).contains(&p),
            "population",
            "between 2 and 100000",
            p,
        )
    }

    /// The generation budget: 1 to 10⁸.
    pub fn check_generations(g: u64) -> Result<u64, BadSetting> {
        BadSetting::unless(
            (1..=100_000_000).contains(&g),
            "generations",
            "between 1 and 1e8",
            g,
        )
    }

    /// tolfun: finite and ≥ 0; 0 turns it off.
    pub fn check_tol_fun(t: f64) -> Result<Option<f64>, BadSetting> {
        let ok = t.is_finite() && (0.0..=1e300).contains(&t);
        BadSetting::unless(ok, "tol_fun", "finite and ≥ 0", t).map(|t| (t > 0.0).then_some(t))
    }

    /// Repetitions: 1 to 10 000.
    pub fn check_repetitions(r: usize) -> Result<usize, BadSetting> {
        BadSetting::unless(
            (1..=10_000).contains(&r),
            "repetitions",
            "between 1 and 10000",
            r,
        )
    }

    /// Every setting within its range (the task is [`ViaPointTask::validate`]'s).
    pub fn validate(&self) -> Result<(), BadSetting> {
        Self::check_sigma0(self.sigma0)?;
        if let Some(p) = self.population {
            Self::check_population(p)?;
        }
        Self::check_generations(self.generations)?;
        if let Some(t) = self.tol_fun {
            Self::check_tol_fun(t)?;
        }
        Self::check_repetitions(self.repetitions)?;
        Ok(())
    }

    /// Whether the settings go together (each is [`ViaPointConfig::validate`]'s).
    pub fn check_together(&self) -> Result<(), SettingConflict> {
        let obstacles = !self.task.obstacles.is_empty();
        if self.polish && self.solver != Solver::Cmaes {
            Err(SettingConflict::PolishWithoutCmaes)
        } else if obstacles && self.evaluation == Evaluation::Quadratic {
            Err(SettingConflict::QuadraticWithObstacles)
        } else if obstacles && self.solver == Solver::Exact {
            Err(SettingConflict::ExactWithObstacles)
        } else {
            Ok(())
        }
    }

    /// The seed of repetition `r`: a SplitMix64 hash of (seed, r), so repetitions are
    /// independent streams and adding repetitions does not change the earlier ones.
    pub fn repetition_seed(&self, r: usize) -> u64 {
        let mut z = self
            .seed
            .wrapping_add((r as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// The result of one repetition.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunResult {
    /// The repetition's seed.
    pub seed: u64,
    /// Best parameters θ found.
    pub params: Vec<f64>,
    /// The corresponding DMP weights (dimension-major).
    pub weights: Vec<f64>,
    /// Their cost.
    pub cost: f64,
    /// The cost term by term.
    pub breakdown: CostBreakdown,
    /// Errors in task units.
    pub errors: TaskErrors,
    /// `(cost − optimum) / optimum`.
    pub gap_to_optimum: f64,
    /// Generations run.
    pub generations: u64,
    /// Cost evaluations (rollouts, or the quadratic form: [`Evaluation`]).
    pub evaluations: u64,
    /// Evaluations whose cost was NaN or infinite.
    pub non_finite_evaluations: u64,
    /// Why the run ended (`max_generations`, `tolfun`, `exact`, `interrupted`, …).
    pub termination: String,
    /// Per-generation history.
    pub history: Vec<GenerationRecord>,
    /// Wall time of this repetition in seconds.
    pub seconds: f64,
}

/// The result of [`learn_via_points`].
#[derive(Debug, Clone)]
pub struct ViaPointOutcome {
    /// The exact least-squares optimum (the reference every run is measured against).
    pub optimum: ExactOptimum,
    /// One result per repetition.
    pub runs: Vec<RunResult>,
    /// Index of the repetition with the lowest cost.
    pub best_run: usize,
    /// The DMP the weights belong to.
    pub dmp: DiscreteDmp,
    /// How the searches evaluated candidates: [`Evaluation::Rollout`] or
    /// [`Evaluation::Quadratic`] (never `Auto`). Every reported cost is a rollout's.
    pub evaluation: Evaluation,
}

impl ViaPointOutcome {
    /// The best repetition.
    pub fn best(&self) -> &RunResult {
        &self.runs[self.best_run]
    }

    /// The trajectory of the best repetition's weights.
    pub fn best_trajectory(&self) -> Trajectory {
        self.dmp.rollout(&self.best().weights)
    }

    /// True if any repetition was interrupted.
    pub fn interrupted(&self) -> bool {
        self.runs.iter().any(|r| r.termination == "interrupted")
    }
}

/// The via-point cost as a CMA-ES [`Objective`] over the parameters θ of a
/// [`SearchSpace`]: θ → weights → rollout → cost. Populations are evaluated with batch
/// rollouts ([`ViaPointTask::costs_batched`]), groups of candidates in parallel.
#[derive(Debug)]
pub struct ViaPointObjective<'a> {
    task: &'a ViaPointTask,
    dmp: &'a DiscreteDmp,
    space: &'a SearchSpace,
    /// Weight and trajectory buffers of finished jobs, reused by the next ones.
    buffers: BufferPool<(Vec<f64>, Vec<Trajectory>)>,
}

impl<'a> ViaPointObjective<'a> {
    /// The objective of `task`, whose DMP is `dmp` (from [`ViaPointTask::build_dmp`]), in
    /// the search space `space`.
    pub fn new(task: &'a ViaPointTask, dmp: &'a DiscreteDmp, space: &'a SearchSpace) -> Self {
        Self {
            task,
            dmp,
            space,
            buffers: BufferPool::default(),
        }
    }
}

impl Objective for ViaPointObjective<'_> {
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
        Ok(self.task.cost(&self.dmp.rollout(&self.space.weights(x))))
    }

    fn evaluate_batch(
        &self,
        xs: &[f64],
        dim: usize,
        out: &mut [f64],
    ) -> Result<(), CandidateError> {
        // Batch rollouts of groups of candidates (each chunk of the feature matrix read once
        // per group), groups in parallel, buffers reused across jobs and generations.
        let nw = self.dmp.n_weights();
        xs.par_chunks(dim * GROUP)
            .zip(out.par_chunks_mut(GROUP))
            .for_each(|(group, costs)| {
                let m = costs.len();
                self.buffers.with(
                    || (vec![0.0; GROUP * nw], Vec::new()),
                    |(w, trajs)| {
                        let w = &mut w[..m * nw];
                        for (theta, w) in group.chunks_exact(dim).zip(w.chunks_exact_mut(nw)) {
                            self.space.to_weights(theta, w);
                        }
                        trajs.resize_with(m, || self.dmp.new_trajectory());
                        self.task.costs_batched(self.dmp, w, &mut trajs[..m], costs);
                    },
                );
            });
        Ok(())
    }
}

/// Candidates rolled out together by [`ViaPointObjective`].
const GROUP: usize = 8;

/// A [`QuadraticCost`] as a CMA-ES [`Objective`]: groups of candidates in parallel.
pub(crate) struct QuadraticObjective<'a>(pub(crate) &'a QuadraticCost);

impl Objective for QuadraticObjective<'_> {
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
        Ok(self.0.cost(x, &mut Vec::new()))
    }

    fn evaluate_batch(
        &self,
        xs: &[f64],
        dim: usize,
        out: &mut [f64],
    ) -> Result<(), CandidateError> {
        // A candidate is ~n² multiply-adds (a few microseconds): groups of 16 amortise
        // the hand-over to a worker.
        xs.par_chunks(dim * 16)
            .zip(out.par_chunks_mut(16))
            .for_each(|(group, costs)| {
                let mut scratch = Vec::with_capacity(dim);
                for (x, c) in group.chunks_exact(dim).zip(costs) {
                    *c = self.0.cost(x, &mut scratch);
                }
            });
        Ok(())
    }
}

/// Learns a via-point movement.
///
/// Computes the exact optimum first (it is cheap: one rollout per weight plus a QR), then
/// runs the configured solver once per repetition, repetitions in parallel in the current
/// rayon pool. `progress(repetition, report)` is called after every generation and may
/// return `ControlFlow::Break(())` to stop (e.g. on Ctrl-C); the runs then end with
/// termination `interrupted`. The results do not depend on the number of threads.
pub fn learn_via_points(
    config: &ViaPointConfig,
    progress: &(dyn Fn(usize, &GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<ViaPointOutcome, LearnError> {
    let task = &config.task;
    let dmp = task.build_dmp()?;
    if config.repetitions == 0 {
        return Err(LearnError::task("repetitions", "must be at least 1"));
    }
    let space = SearchSpace::new(config.parametrisation, &dmp);
    let optimum = exact_optimum(task, &dmp, &space)?;
    let evaluation = match (config.evaluation, task.obstacles.is_empty()) {
        (Evaluation::Quadratic, false) => {
            return Err(LearnError::task(
                "evaluation",
                "\"quadratic\" needs a quadratic cost, and obstacles make it not one: use \"rollout\" (or \"auto\")",
            ));
        }
        (Evaluation::Auto | Evaluation::Quadratic, true) if config.solver == Solver::Cmaes => {
            Evaluation::Quadratic
        }
        _ => Evaluation::Rollout,
    };
    let quadratic = match evaluation {
        Evaluation::Quadratic => Some(QuadraticCost::of_task(task, &dmp, &space)?),
        _ => None,
    };
    let rollouts = ViaPointObjective::new(task, &dmp, &space);
    let objective: &dyn Objective = match &quadratic {
        Some(q) => &QuadraticObjective(q),
        None => &rollouts,
    };
    let finish = |seed: u64,
                  params: Vec<f64>,
                  stats: (u64, u64, u64, String, Vec<GenerationRecord>),
                  started: Instant| {
        let weights = space.weights(&params);
        let traj = dmp.rollout(&weights);
        let breakdown = task.breakdown(&traj);
        let cost = breakdown.total();
        RunResult {
            seed,
            params,
            weights,
            cost,
            breakdown,
            errors: task.errors(&traj),
            gap_to_optimum: (cost - optimum.cost) / optimum.cost,
            generations: stats.0,
            evaluations: stats.1,
            non_finite_evaluations: stats.2,
            termination: stats.3,
            history: stats.4,
            seconds: started.elapsed().as_secs_f64(),
        }
    };
    let runs: Result<Vec<RunResult>, LearnError> = (0..config.repetitions)
        .into_par_iter()
        .map(|rep| {
            let seed = config.repetition_seed(rep);
            let started = Instant::now();
            if config.solver == Solver::Exact {
                let stats = (
                    0,
                    space.len() as u64 + 1,
                    0,
                    "exact".to_string(),
                    Vec::new(),
                );
                return Ok(finish(seed, optimum.params.clone(), stats, started));
            }
            let x0 = if config.warm_start {
                optimum.params.clone()
            } else {
                vec![0.0; space.len()]
            };
            let (best_x, run) = if config.solver == Solver::LeastSquares {
                let residuals = lsq::TaskResiduals {
                    task,
                    dmp: &dmp,
                    space: &space,
                };
                let settings = lsq::settings(config.generations);
                lsq::levenberg_marquardt(&residuals, x0, settings, &|r| progress(rep, r))?
            } else {
                let (x, stats) =
                    run_cmaes(objective, x0, None, config, seed, &|r| progress(rep, r))?;
                if config.polish && !stats.interrupted() {
                    let residuals = lsq::TaskResiduals {
                        task,
                        dmp: &dmp,
                        space: &space,
                    };
                    lsq::polish(&residuals, x, stats, &|r| progress(rep, r))?
                } else {
                    (x, stats)
                }
            };
            let stats = (
                run.generations,
                run.evaluations,
                run.non_finite_evaluations,
                run.termination,
                run.history,
            );
            Ok(finish(seed, best_x, stats, started))
        })
        .collect();
    let runs = runs?;
    let best_run = runs
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.cost.total_cmp(&b.1.cost).then(a.0.cmp(&b.0)))
        .map(|(i, _)| i)
        .unwrap_or(0);
    Ok(ViaPointOutcome {
        optimum,
        runs,
        best_run,
        dmp,
        evaluation,
    })
}

/// A cost that evaluates a candidate in reusable buffers (a rollout, a simulation).
pub(crate) trait BufferedCost: Sync {
    /// The buffers one evaluation needs.
    type Buffers: Send;
    /// Fresh buffers.
    fn buffers(&self) -> Self::Buffers;
    /// The cost of candidate `x`, computed in `buffers`.
    fn cost(&self, x: &[f64], buffers: &mut Self::Buffers) -> f64;
}

/// A [`BufferedCost`] as a CMA-ES [`Objective`]: the population is evaluated in parallel,
/// each candidate in pooled buffers.
pub(crate) struct Buffered<C: BufferedCost>(C, BufferPool<C::Buffers>);

impl<C: BufferedCost> Buffered<C> {
    pub(crate) fn new(cost: C) -> Self {
        Self(cost, BufferPool::default())
    }
}

impl<C: BufferedCost> Objective for Buffered<C> {
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
        Ok(self.1.with(|| self.0.buffers(), |b| self.0.cost(x, b)))
    }

    fn evaluate_batch(
        &self,
        xs: &[f64],
        dim: usize,
        out: &mut [f64],
    ) -> Result<(), CandidateError> {
        xs.par_chunks_exact(dim)
            .zip(out.par_iter_mut())
            .for_each(|(x, o)| *o = self.1.with(|| self.0.buffers(), |b| self.0.cost(x, b)));
        Ok(())
    }
}

/// One CMA-ES run with a via-point learner's settings (σ₀, population, budget, tolfun,
/// the safety stopping rules), recording the history: the one CMA-ES loop every learner
/// uses, on a model or on a pool of robots. The result is the best of the best sample, the
/// final mean and the start: the final mean is often better than every sample, and a warm
/// start must never end worse than where it began. With [`Solver::Exact`] there is no
/// search: `x0` is returned.
///
/// `start_cost` is the start's cost when the caller has judged it already (an execution
/// on a robot): the best so far begins there, and the final mean is not judged again
/// (each judgement costs an execution) — the result is the best sample if it beats the
/// start, else the start. An objective that returns [`cps_cmaes::EndSearch`] ends the
/// search with what the generations before found (`termination = "ended"`; the objective
/// knows why).
pub fn run_cmaes(
    objective: &dyn Objective,
    x0: Vec<f64>,
    start_cost: Option<f64>,
    config: &ViaPointConfig,
    seed: u64,
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<(Vec<f64>, SearchStats), LearnError> {
    if config.solver == Solver::Exact {
        return Ok((x0, SearchStats::exact()));
    }
    let cmaes = CmaesConfig {
        population: config.population,
        ..CmaesConfig::new(config.sigma0, seed)
    };
    let mut rules = vec![StopRule::MaxGenerations(config.generations)];
    if let Some(tol) = config.tol_fun {
        rules.push(StopRule::TolFun(tol));
    }
    rules.extend(StopRule::safety_defaults());
    let mut history = Vec::new();
    let mut observer = |r: &GenerationReport<'_>| {
        let r = GenerationReport {
            best_so_far: start_cost.map_or(r.best_so_far, |c| c.min(r.best_so_far)),
            ..*r
        };
        history.push(GenerationRecord {
            generation: r.generation,
            best: r.best_cost,
            median: r.median_cost,
            best_so_far: r.best_so_far,
            sigma: r.sigma,
        });
        progress(&r)
    };
    let sol = minimize(objective, &x0, &cmaes, &rules, &mut observer)?;
    let best_x = match start_cost {
        Some(c) if sol.best_cost < c => sol.best_x,
        Some(_) => x0,
        None => [sol.best_x, sol.mean, x0]
            .into_iter()
            .map(|x| (objective.evaluate(&x).unwrap_or(f64::INFINITY), x))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, x)| x)
            .unwrap_or_default(),
    };
    Ok((
        best_x,
        SearchStats {
            generations: sol.generations,
            evaluations: sol.evaluations,
            non_finite_evaluations: sol.non_finite_evaluations,
            termination: sol.termination.name().to_string(),
            history,
        },
    ))
}

/// Mean and 95 % band (mean ± 1.96 · std / √n) of the best-so-far cost per generation
/// over repetitions, given their histories (e.g. `runs.iter().map(|r| &r.history[..])`).
/// Runs that stopped early keep their final value.
pub fn history_band(histories: &[&[GenerationRecord]]) -> Vec<(f64, f64, f64)> {
    let len = histories.iter().map(|r| r.len()).max().unwrap_or(0);
    let n = histories.len() as f64;
    (0..len)
        .map(|g| {
            let vals: Vec<f64> = histories
                .iter()
                .filter_map(|r| r.get(g).or(r.last()).map(|h| h.best_so_far))
                .collect();
            let mean = vals.iter().sum::<f64>() / n;
            let var = if vals.len() > 1 {
                vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
            } else {
                0.0
            };
            let half = 1.96 * var.sqrt() / n.sqrt();
            (mean, mean - half, mean + half)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::de::IntoDeserializer;
    use serde::de::value::{Error, StrDeserializer};

    /// One vocabulary: experiment files (serde) read exactly the names the settings print
    /// and parse, and an unknown name lists them all.
    #[test]
    fn names_are_the_files_names() {
        for &s in Solver::ALL {
            let d: StrDeserializer<'_, Error> = s.name().into_deserializer();
            assert_eq!(Solver::deserialize(d), Ok(s));
            assert_eq!(s.to_string().parse::<Solver>(), Ok(s));
        }
        for &e in Evaluation::ALL {
            let d: StrDeserializer<'_, Error> = e.name().into_deserializer();
            assert_eq!(Evaluation::deserialize(d), Ok(e));
            assert_eq!(e.name().parse::<Evaluation>(), Ok(e));
        }
        assert_eq!(
            "magic".parse::<Solver>().unwrap_err().to_string(),
            "\"magic\" is not one of \"cmaes\", \"exact\", \"least_squares\""
        );
    }

    /// One check per setting, in the words every front end shows (it adds its place).
    #[test]
    fn settings_are_checked_once_in_words() {
        let bad = |r: Result<(), BadSetting>| r.unwrap_err().to_string();
        let task = || ViaPointConfig::new(crate::ViaPointTask::thesis());
        assert_eq!(task().validate(), Ok(()));
        let mut c = task();
        c.sigma0 = 0.0;
        assert_eq!(
            bad(c.validate()),
            "`sigma0` must be finite, > 0 and at most 1e6 (got 0.0)"
        );
        let mut c = task();
        c.population = Some(1);
        assert_eq!(
            bad(c.validate()),
            "`population` must be between 2 and 100000 (got 1)"
        );
        let mut c = task();
        c.generations = 0;
        assert_eq!(
            bad(c.validate()),
            "`generations` must be between 1 and 1e8 (got 0)"
        );
        let mut c = task();
        c.tol_fun = Some(f64::NAN);
        assert_eq!(
            bad(c.validate()),
            "`tol_fun` must be finite and ≥ 0 (got NaN)"
        );
        let mut c = task();
        c.repetitions = 10_001;
        assert_eq!(
            bad(c.validate()),
            "`repetitions` must be between 1 and 10000 (got 10001)"
        );
        assert_eq!(ViaPointConfig::check_tol_fun(0.0), Ok(None));
    }
}
