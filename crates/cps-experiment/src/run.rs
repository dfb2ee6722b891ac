//! Running an experiment: [`run`] takes a read [`Experiment`] of any kind, runs its
//! pipeline and gives back an [`Outcome`]. Progress and cancellation go through an
//! [`Observer`]; nothing here touches a terminal or a signal. [`run_into`] is the run
//! with its result directory, as the command line and Python do it.

use std::time::Instant;

use crate::kinds::{self, Ctx};
use crate::observer::Observer;
use crate::plan::{Experiment, Kind, KindPlan};
use crate::{ExperimentError, InputError};
use cps_outcome::outcome::Outcome;

/// How to run (what does not change the results).
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Worker threads (default: one per core). The results do not depend on it.
    pub threads: Option<usize>,
    /// Stops the run: a robot that moves brakes within its limits (the observer's
    /// `Break` stops learning between generations; this reaches a motion under way). The
    /// host program's Ctrl-C handler, Python's KeyboardInterrupt, a caller's cancel.
    pub stop: cps_robot::StopToken,
}

impl RunOptions {
    /// Whether the options can be used (threads between 1 and 1024).
    pub fn check(&self) -> Result<(), InputError> {
        match self.threads {
            Some(t) if !(1..=1024).contains(&t) => Err(InputError(format!(
                "--threads {t}: must be between 1 and 1024"
            ))),
            _ => Ok(()),
        }
    }

    /// The threads a run uses: the option, or one per core.
    pub fn threads(&self) -> usize {
        self.threads.unwrap_or_else(|| {
            std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
        })
    }
}

/// A run into a result directory claimed before it ([`Results::prepare`](cps_report::write::Results::prepare),
/// so that a target that cannot be used fails before any work): the run, then its files
/// written and moved into place. An interrupted run keeps what it finished (`"complete":
/// false`); a run that fails writes nothing. Without `results` it is [`run`].
pub fn run_into(
    exp: &Experiment,
    options: &RunOptions,
    observer: &dyn Observer,
    results: Option<cps_report::write::Results>,
) -> Result<Outcome, ExperimentError> {
    let outcome = run(exp, options, observer)?;
    if let Some(results) = results {
        results.finish(&outcome)?;
    }
    Ok(outcome)
}

/// The number of generations a run of `exp` reports through [`crate::Event::Generation`] (its
/// search budget; a run that converges early reports fewer), or 0 for a kind that
/// reports stages.
pub fn planned_generations(exp: &Experiment) -> u64 {
    let config = &exp.config;
    match exp.kind() {
        Kind::Viapoint => config.generations * config.repetitions as u64,
        Kind::Scaling => {
            config.generations
                * config.repetitions as u64
                * exp.scaling().map_or(1, |s| s.compare.len() as u64)
        }
        Kind::Imitation | Kind::Promp => 0,
        Kind::ViapointJoint => config.generations,
        Kind::ViapointPose => 2 * config.generations,
        // The speed-up measurement reports `Event::Working`, not generations.
        Kind::ViapointEnergy => config.generations,
        Kind::ViapointExecuted => config.generations,
        Kind::Contact => 0,
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
    options.check()?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(t) = options.threads {
        builder = builder.num_threads(t);
    }
    let pool = builder.build().map_err(|e| ExperimentError::Failed {
        context: "cannot start the worker threads".into(),
        source: Box::new(e),
    })?;
    let ctx = Ctx::new(exp, &pool, observer, &options.stop, started);
    observer.started(planned_generations(exp));
    let mut outcome = match &exp.plan {
        KindPlan::Viapoint => kinds::viapoint::run(&ctx),
        KindPlan::Imitation(_) => kinds::imitation::run(&ctx),
        KindPlan::Promp(_, plan) => kinds::promp::run(&ctx, plan),
        KindPlan::Scaling(plan) => kinds::scaling::run(&ctx, plan),
        KindPlan::ViapointJoint(plan) => kinds::joint::run(&ctx, *plan),
        KindPlan::ViapointEnergy(plan) => kinds::energy::run(&ctx, plan),
        KindPlan::ViapointPose(plan) => kinds::pose::run(&ctx, plan),
        KindPlan::ViapointExecuted(plan) => kinds::executed::run(&ctx, plan),
        KindPlan::Contact(spec) => kinds::contact::run(&ctx, spec),
    }?;
    // Every report also lists the task, the settings and the cost breakdowns (a contact
    // experiment learns no via points: its report has its own).
    if exp.kind() != Kind::Contact {
        let shared = kinds::shared_report_tables(exp, &outcome.summary);
        outcome.report.tables.extend(shared);
    }
    if exp.robot.as_ref().is_none_or(|r| r.enforce_limits) {
        fail_on_broken_limits(&mut outcome);
    }
    Ok(outcome)
}

/// A learned movement that breaks a limit of its robot is a failed run, not a result: its
/// trajectory would be refused by `cps-cli limits check`, `ros2 send` and `franka
/// execute`. The outcome keeps everything, and says why it failed.
/// Every executed movement of a kind counts: the summary's `limit_usage`, and each one
/// nested in it (an imitation per method, a movement per run).
fn fail_on_broken_limits(outcome: &mut Outcome) {
    if outcome.header.failure.is_some() {
        return;
    }
    let summary = serde_json::Value::Object(outcome.summary.clone());
    let Some((place, usage)) = broken_limits(&summary, String::new()) else {
        return;
    };
    let violations = usage
        .get("violations")
        .and_then(|v| v.as_array())
        .map_or(&[][..], Vec::as_slice);
    let count = violations.len();
    let first = violations
        .first()
        .map(|v| {
            format!(
                " (first: joint {} {} at {} s)",
                v.get("joint").unwrap_or(&serde_json::Value::Null),
                v.get("quantity").and_then(|q| q.as_str()).unwrap_or("?"),
                v.get("time").unwrap_or(&serde_json::Value::Null),
            )
        })
        .unwrap_or_default();
    outcome.header.failure = Some(format!(
        "the learned movement breaks its robot's limits at 1 kHz: {count} violation(s){first}, listed in summary.json `{place}limit_usage`; `limits check`, `ros2 send` and `franka execute` would refuse its trajectory"
    ));
}

/// The first `limit_usage` in `value` that says `"ok": false`, with its place
/// (`imitations[1].`).
fn broken_limits(value: &serde_json::Value, at: String) -> Option<(String, &serde_json::Value)> {
    match value {
        serde_json::Value::Object(map) => {
            if let Some(u) = map.get("limit_usage")
                && u.get("ok") == Some(&serde_json::Value::Bool(false))
            {
                return Some((at, u));
            }
            map.iter()
                .filter(|(k, _)| *k != "limit_usage")
                .find_map(|(k, v)| broken_limits(v, format!("{at}{k}.")))
        }
        serde_json::Value::Array(items) => items
            .iter()
            .enumerate()
            .find_map(|(i, v)| broken_limits(v, format!("{}[{i}].", at.trim_end_matches('.')))),
        _ => None,
    }
}
