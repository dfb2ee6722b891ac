//! Runs of the experiment kinds beyond plain via-point learning: what every runner gets
//! from the command line and gives back for the terminal.

use std::sync::atomic::AtomicBool;

use anyhow::Result;

use crate::experiment::{Kind, ViaPointExperiment};
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

/// What a finished (or interrupted) run reports.
pub struct Finished {
    /// False if interrupted: the results written are marked incomplete.
    pub complete: bool,
    /// The lines to print on the terminal (unless `--quiet`).
    pub lines: Vec<String>,
}

/// Runs `exp` (not of kind `viapoint`) and writes its results into `stage`.
pub fn run(
    exp: &ViaPointExperiment,
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
