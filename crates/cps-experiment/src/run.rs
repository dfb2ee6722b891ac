//! Running an experiment: [`run`] takes a read [`Experiment`] of any kind, runs its
//! pipeline and gives back an [`Outcome`]. Progress and cancellation go through an
//! [`Observer`]; nothing here touches a terminal, a signal or a file.

use std::ops::ControlFlow;
use std::time::Instant;

use cps_learn::LearnError;

use crate::experiment::{Experiment, Kind};
use crate::kinds;
use crate::outcome::{Outcome, RunHeader, Versions};
use crate::{ExperimentError, InputError};

/// How to run (what does not change the results).
#[derive(Debug, Clone, Copy, Default)]
pub struct RunOptions {
    /// Worker threads (default: one per core). The results do not depend on it.
    pub threads: Option<usize>,
}

/// What a run reports while it works.
#[derive(Debug, Clone, Copy)]
pub enum Event<'a> {
    /// A generation of a search finished. Searches of parallel repetitions report from
    /// their own threads, so generations of different repetitions interleave.
    Generation {
        /// Its number within its search (1-based).
        generation: u64,
        /// The best cost found so far by its search.
        best_so_far: f64,
        /// The search's step size.
        sigma: f64,
    },
    /// The run entered a stage (`demonstrations 3/20`, `scaled (1/2)`).
    Stage(&'a str),
}

/// Watches a run: progress and cancellation. Called from the run's worker threads.
pub trait Observer: Sync {
    /// The run starts; `generations` is the number it will report (0 when it reports
    /// stages instead).
    fn started(&self, generations: u64) {
        let _ = generations;
    }

    /// Something happened; return `ControlFlow::Break(())` to stop the run early (its
    /// finished part is still returned, marked incomplete).
    fn event(&self, event: Event<'_>) -> ControlFlow<()> {
        let _ = event;
        ControlFlow::Continue(())
    }

    /// The computing is over (before the outcome is assembled).
    fn finished(&self) {}
}

/// Watches nothing and never stops a run.
impl Observer for () {}

/// The number of generations a run of `exp` reports through [`Event::Generation`] (its
/// search budget; a run that converges early reports fewer), or 0 for a kind that
/// reports stages.
pub fn planned_generations(exp: &Experiment) -> u64 {
    let config = &exp.config;
    match exp.kind {
        Kind::Viapoint => config.generations * config.repetitions as u64,
        Kind::Scaling => {
            config.generations
                * config.repetitions as u64
                * exp.scaling.as_ref().map_or(1, |s| s.compare.len() as u64)
        }
        Kind::Imitation => 0,
        Kind::ViapointJoint => config.generations,
        Kind::ViapointPose => 2 * config.generations,
        Kind::ViapointEnergy => {
            config.generations + 6 * exp.energy.map_or(0, |e| e.speedup_generations)
        }
    }
}

/// What every kind's runner gets.
pub(crate) struct Ctx<'a> {
    /// The experiment.
    pub exp: &'a Experiment,
    /// The worker threads.
    pub pool: &'a rayon::ThreadPool,
    /// The caller's observer.
    pub observer: &'a dyn Observer,
    started: Instant,
}

impl Ctx<'_> {
    /// Seconds since the run started.
    pub fn wall(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// The header of this run, `complete` or not.
    pub fn header(&self, complete: bool) -> RunHeader {
        RunHeader {
            experiment: self.exp.name.clone(),
            kind: self.exp.kind.name(),
            complete,
            seed: self.exp.config.seed,
            versions: Versions::now(),
            threads: self.pool.current_num_threads(),
            wall_time_s: self.wall(),
            failure: None,
        }
    }

    /// A search's generation report passed on to the observer.
    pub fn generation(&self, r: &cps_cmaes::GenerationReport<'_>) -> ControlFlow<()> {
        self.observer.event(Event::Generation {
            generation: r.generation,
            best_so_far: r.best_so_far,
            sigma: r.sigma,
        })
    }
}

/// Runs `exp` and returns its outcome: the same numbers for the same file and seed,
/// whatever the thread count. A run stopped by the observer or by a failing dependency
/// (a simulator that died) still returns what it finished, marked incomplete.
///
/// Errors: the file's content cannot be run ([`ExperimentError::Input`], e.g. a way
/// point the robot cannot reach), or something failed before anything was finished.
pub fn run(
    exp: &Experiment,
    options: &RunOptions,
    observer: &dyn Observer,
) -> Result<Outcome, ExperimentError> {
    let started = Instant::now();
    if let Some(t) = options.threads
        && !(1..=1024).contains(&t)
    {
        return Err(InputError(format!("--threads {t}: must be between 1 and 1024")).into());
    }
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(t) = options.threads {
        builder = builder.num_threads(t);
    }
    let pool = builder.build().map_err(|e| ExperimentError::Failed {
        context: "cannot start the worker threads".into(),
        source: Box::new(e),
    })?;
    let ctx = Ctx {
        exp,
        pool: &pool,
        observer,
        started,
    };
    observer.started(planned_generations(exp));
    match exp.kind {
        Kind::Viapoint => kinds::viapoint::run(&ctx),
        Kind::Imitation => kinds::imitation::run(&ctx),
        Kind::Scaling => kinds::scaling::run(&ctx),
        Kind::ViapointJoint => kinds::joint::run(&ctx),
        Kind::ViapointEnergy => kinds::energy::run(&ctx),
        Kind::ViapointPose => kinds::pose::run(&ctx),
    }
}

/// A learning library error as a run reports it: a problem with the file's content
/// (input) or a failure of the `what` while running.
pub(crate) fn learn_error(e: LearnError, what: &str) -> ExperimentError {
    match e {
        LearnError::InvalidTask { .. } | LearnError::Dmp(_) | LearnError::Unreachable { .. } => {
            InputError(e.to_string()).into()
        }
        other => ExperimentError::Failed {
            context: format!("the {what} failed"),
            source: Box::new(other),
        },
    }
}
