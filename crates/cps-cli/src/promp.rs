//! `cps-cli promp fit|condition|sample|stats`: probabilistic movement primitives from
//! demonstrations. The work is `cps_movement::promp`'s; this is arguments and files.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use cps_experiment::InputError;
use cps_movement::promp::{
    NamedProMp, ViaPoints, condition, fit_files, write_samples, write_stats,
};
use cps_movement::robot_file::{Saved, SaysSaved};
use cps_outcome::files::write_file;
use cps_outcome::outcome::Figure;
use cps_outcome::results_dir::{FileKind, check_file_targets};
use cps_report::figures::draw_file;

use crate::movement::Output;
use crate::robot::print;

/// A ProMP file and a time grid.
#[derive(Args, Debug)]
pub struct OnGrid {
    /// The ProMP file (JSON, from `promp fit` or `promp condition`).
    model: PathBuf,
    /// Time step of the written grid, seconds.
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true)]
    dt: f64,
    /// Where to write (`sample`: a folder, one CSV per sample; `stats`: a CSV file).
    #[arg(long)]
    out: PathBuf,
    /// Replace cps's own files already there.
    #[arg(long)]
    force: bool,
}

/// `cps-cli promp …`.
#[derive(Subcommand, Debug)]
pub enum ProMpCommand {
    /// Fit a ProMP (JSON) to two or more demonstrations (CSV, read as `imitate` reads them).
    Fit(FitArgs),
    /// Condition a ProMP on via points (repeat --at and --position for several).
    Condition(ConditionArgs),
    /// Draw seeded samples: one CSV per sample (t, then one column per dimension).
    Sample {
        #[command(flatten)]
        grid: OnGrid,
        /// How many samples.
        #[arg(long, default_value_t = 10)]
        n: usize,
        /// Seed (the same seed, the same samples).
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// The mean and standard deviation over time: t, each mean, then each `_std`.
    Stats(OnGrid),
}

/// Arguments of `promp fit`.
#[derive(Args, Debug)]
pub struct FitArgs {
    /// Demonstration files, or LeRobot datasets' folders (as `imitate`).
    #[arg(required = true)]
    demos: Vec<PathBuf>,
    #[command(flatten)]
    lerobot: crate::movement::LeRobotArgs,
    /// The position columns, by name, comma-separated (default as `imitate`).
    #[arg(long, value_delimiter = ',')]
    columns: Option<Vec<String>>,
    /// Basis functions per dimension.
    #[arg(long, default_value_t = 20)]
    bases: usize,
    /// Duration every demonstration is normalised to, seconds (default: their mean).
    #[arg(long, allow_hyphen_values = true)]
    duration: Option<f64>,
    #[command(flatten)]
    output: Output,
}

/// Arguments of `promp condition`.
#[derive(Args, Debug)]
pub struct ConditionArgs {
    /// The ProMP file.
    model: PathBuf,
    /// Time of a via point, seconds.
    #[arg(long, required = true, allow_hyphen_values = true)]
    at: Vec<f64>,
    /// Its position, one value per dimension, comma-separated.
    #[arg(long, required = true, allow_hyphen_values = true)]
    position: Vec<String>,
    /// Standard deviation of the positions: one for all or one per via point (0: exact).
    #[arg(long, allow_hyphen_values = true)]
    std: Vec<f64>,
    /// A velocity per via point, comma-separated (optional).
    #[arg(long, allow_hyphen_values = true)]
    velocity: Vec<String>,
    /// Standard deviation of the velocities (0: exact).
    #[arg(long, allow_hyphen_values = true)]
    velocity_std: Vec<f64>,
    #[command(flatten)]
    output: Output,
}

impl Output {
    /// Checks the targets before any work.
    fn check(&self) -> Result<(), InputError> {
        check_file_targets(&self.out, FileKind::ProMp, self.plot.as_deref(), self.force)
    }

    /// Writes the ProMP file and its figure, then prints what was saved.
    fn finish<T: SaysSaved>(
        &self,
        promp: &NamedProMp,
        figure: Figure,
        what: &T,
    ) -> Result<ExitCode> {
        write_file(&self.out, promp.to_json().as_bytes())?;
        if let Some(plot) = &self.plot {
            draw_file(&figure, plot)?;
        }
        print(
            &Saved {
                what,
                out: &self.out,
            },
            self.json,
        )
    }
}

/// `cps-cli promp …`.
pub fn promp(command: &ProMpCommand) -> Result<ExitCode> {
    match command {
        ProMpCommand::Fit(a) => {
            a.output.check()?;
            let paths: Vec<&Path> = a.demos.iter().map(PathBuf::as_path).collect();
            let pick = a.lerobot.pick();
            let fit = fit_files(&paths, a.columns.as_deref(), &pick, a.bases, a.duration)?;
            a.output.finish(&fit.promp, fit.figure(), &fit)
        }
        ProMpCommand::Condition(a) => {
            a.output.check()?;
            let via = ViaPoints::parse(&a.at, &a.position, &a.std, &a.velocity, &a.velocity_std)?;
            let c = condition(NamedProMp::read(&a.model)?, &via)?;
            a.output.finish(&c.posterior, c.figure(), &c)
        }
        ProMpCommand::Sample { grid, n, seed } => {
            let done = write_samples(&grid.model, &grid.out, grid.force, *n, *seed, grid.dt);
            say!("{}", done?);
            Ok(ExitCode::SUCCESS)
        }
        ProMpCommand::Stats(g) => {
            say!("{}", write_stats(&g.model, &g.out, g.force, g.dt)?);
            Ok(ExitCode::SUCCESS)
        }
    }
}
