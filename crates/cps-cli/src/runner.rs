//! Runs of the experiment kinds beyond plain via-point learning: what every runner gets
//! from the command line and gives back for the terminal.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use cps_learn::{GenerationRecord, LearnError};
use serde::Serialize;

use crate::experiment::{Experiment, Kind};
use crate::output::Staging;
use crate::{energy_run, imitation_run, joint_run, pose_run, scaling_run};

/// What a run needs from the command line.
pub struct RunContext<'a> {
    /// The worker threads (`--threads`).
    pub pool: &'a rayon::ThreadPool,
    /// The progress display (hidden with `--quiet` or without a terminal).
    pub bar: &'a indicatif::ProgressBar,
    /// Set by Ctrl-C.
    pub interrupted: &'a AtomicBool,
}

impl RunContext<'_> {
    /// After a generation: advance the progress bar; stop on Ctrl-C.
    pub fn generation(&self) -> ControlFlow<()> {
        self.bar.inc(1);
        if self.interrupted.load(Ordering::Relaxed) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
}

/// The fields every `summary.json` opens with.
#[derive(Serialize)]
pub struct RunHeader<'a> {
    experiment: &'a str,
    kind: &'static str,
    complete: bool,
    seed: u64,
    versions: crate::output::Versions,
    threads: usize,
    wall_time_s: f64,
    /// Why the run stopped early when a dependency failed (a simulator died).
    #[serde(skip_serializing_if = "Option::is_none")]
    failure: Option<String>,
}

impl<'a> RunHeader<'a> {
    /// Marks the run as stopped by a failure (`complete` becomes false).
    pub fn failed(mut self, failure: Option<&str>) -> Self {
        if let Some(f) = failure {
            self.complete = false;
            self.failure = Some(f.to_string());
        }
        self
    }

    /// The header of `exp`'s run.
    pub fn new(exp: &'a Experiment, complete: bool, threads: usize, wall: f64) -> Self {
        Self {
            experiment: &exp.name,
            kind: exp.kind.name(),
            complete,
            seed: exp.config.seed,
            versions: crate::output::Versions::now(),
            threads,
            wall_time_s: wall,
            failure: None,
        }
    }

    /// The report's rows for the run itself.
    pub fn rows(&self) -> Vec<(&'static str, String)> {
        vec![
            (
                "experiment",
                format!("{} (kind {})", self.experiment, self.kind),
            ),
            (
                "complete",
                match (&self.failure, self.complete) {
                    (Some(f), _) => format!("no: {f}; the finished part is shown"),
                    (None, true) => "yes".into(),
                    (None, false) => "no: interrupted, the finished part is shown".into(),
                },
            ),
            ("seed", self.seed.to_string()),
            (
                "wall time",
                format!("{:.2} s on {} thread(s)", self.wall_time_s, self.threads),
            ),
        ]
    }
}

/// A library error as the command line reports it: a problem with the file's content
/// (exit 2) or a failure while running (exit 1) in `what`.
pub fn learn_error(e: LearnError, what: &str) -> anyhow::Error {
    match e {
        LearnError::InvalidTask { .. } | LearnError::Dmp(_) | LearnError::Unreachable { .. } => {
            anyhow::Error::new(crate::experiment::InputError(e.to_string()))
        }
        other => anyhow::Error::new(other).context(format!("the {what} failed")),
    }
}

/// The report's row for a search: generations, evaluations, why it ended.
pub fn search_row(s: &cps_learn::SearchStats) -> (&'static str, String) {
    (
        "CMA-ES",
        format!(
            "{} generations, {} evaluations, {}",
            s.generations, s.evaluations, s.termination
        ),
    )
}

/// `cost_history.csv`: one row per generation of each named search.
pub fn write_history(stage: &Staging, searches: &[(&str, &[GenerationRecord])]) -> Result<()> {
    let mut w = csv::Writer::from_path(stage.path("cost_history.csv"))?;
    w.write_record([
        "search",
        "generation",
        "best",
        "median",
        "best_so_far",
        "sigma",
    ])?;
    for (name, history) in searches {
        for h in history.iter() {
            w.write_record([
                name.to_string(),
                h.generation.to_string(),
                format!("{:e}", h.best),
                format!("{:e}", h.median),
                format!("{:e}", h.best_so_far),
                format!("{:e}", h.sigma),
            ])?;
        }
    }
    w.flush()?;
    Ok(())
}

/// What a finished (or interrupted) run reports.
pub struct Finished {
    /// False if interrupted or failed: the results written are marked incomplete.
    pub complete: bool,
    /// Set when a dependency failed mid-run (the results of the finished part are written;
    /// the command exits 1 with this message).
    pub failure: Option<String>,
    /// The lines to print on the terminal (unless `--quiet`).
    pub lines: Vec<String>,
}

/// Runs `exp` (not of kind `viapoint`) and writes its results into `stage`.
pub fn run(
    exp: &Experiment,
    ctx: &RunContext<'_>,
    stage: &Staging,
    wall: &dyn Fn() -> f64,
) -> Result<Finished> {
    match exp.kind {
        Kind::Imitation => imitation_run::run(exp, ctx, stage, wall),
        Kind::Scaling => scaling_run::run(exp, ctx, stage, wall),
        Kind::ViapointJoint => joint_run::run(exp, ctx, stage, wall),
        Kind::ViapointEnergy => energy_run::run(exp, ctx, stage, wall),
        Kind::ViapointPose => pose_run::run(exp, ctx, stage, wall),
        Kind::Viapoint => anyhow::bail!("via-point runs are not run here"),
    }
}
