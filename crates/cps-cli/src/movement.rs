//! `cps-cli imitate` and `cps-cli rollout`: DMP models from demonstrations (CSV) and
//! trajectories from models (JSON), for users who want the DMP layer alone. The work is
//! `cps_movement::movement`'s; this is arguments, output files and the terminal.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, ValueEnum};
use cps_dmp::{Combine, Formulation, Lambda, Regression};
use cps_experiment::InputError;
use cps_movement::lerobot::Pick;
use cps_movement::movement::{ImitationSpec, RolloutSpec, imitate_files, rollout_file};
use cps_outcome::files::{table_csv, write_file};
use cps_outcome::results_dir::{FileKind, check_file_targets};
use cps_report::figures::draw_file;

use crate::cli_error;

/// Regression method of `imitate`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Method {
    /// Schaal's locally weighted regression.
    Lwr,
    /// Ridge regression (thesis eq. 51).
    Ridge,
    /// Jerk-regularised ridge regression (thesis eq. 52).
    Jerk,
}

/// Forcing-term formulation.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum FormulationArg {
    /// Ijspeert et al. 2013 (the thesis's): the forcing term scales with goal − start.
    Ijspeert,
    /// Hoffmann/Pastor 2009: independent of goal − start (start ≈ goal works).
    Robust,
}

/// How several demonstrations are combined.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CombineArg {
    /// Average the time-normalised demonstrations, then fit.
    Mean,
    /// One regression over all samples.
    Stack,
}

/// Which episodes of a LeRobot dataset given as a demonstration become demonstrations.
#[derive(Args, Debug)]
pub struct LeRobotArgs {
    /// A LeRobot dataset's episodes (from 0, comma-separated; default: all).
    #[arg(long, value_delimiter = ',')]
    episodes: Option<Vec<usize>>,
    /// A LeRobot dataset's feature: `observation.state` or `action` (or another vector).
    #[arg(long, default_value = "observation.state")]
    feature: String,
    /// The robot whose joints the feature's entries are matched to by name (default: the
    /// dataset's robot_type when cps knows it, else every entry).
    #[arg(long)]
    robot: Option<String>,
}

impl LeRobotArgs {
    /// The pick these arguments make.
    pub fn pick(&self) -> Pick {
        Pick {
            episodes: self.episodes.clone(),
            feature: self.feature.clone(),
            robot: self.robot.clone(),
        }
    }
}

/// Arguments of `cps-cli imitate`.
#[derive(Args, Debug)]
pub struct ImitateArgs {
    /// Demonstration CSV files: a header row, the time in seconds first, then one column
    /// per dimension — or any trajectory cps writes (its positions are read), or a LeRobot
    /// dataset's folder (its episodes, see --episodes).
    #[arg(required = true)]
    demos: Vec<PathBuf>,
    #[command(flatten)]
    lerobot: LeRobotArgs,
    /// The position columns to imitate, by name, comma-separated (default: every column
    /// of a plain demonstration; the columns with a `_vel` column beside them in a
    /// trajectory cps wrote).
    #[arg(long, value_delimiter = ',')]
    columns: Option<Vec<String>>,
    /// Gaussian basis functions per dimension.
    #[arg(long, default_value_t = 25)]
    bases: usize,
    /// Regression method.
    #[arg(long, value_enum, default_value = "ridge")]
    method: Method,
    /// Regularisation λ, or `auto` for generalised cross-validation (default: 1e-12 for
    /// ridge as in the thesis, auto for jerk).
    #[arg(long, allow_hyphen_values = true)]
    lambda: Option<String>,
    /// Duration of the model in seconds (default: the demonstrations' mean duration).
    #[arg(long, allow_hyphen_values = true)]
    tau: Option<f64>,
    /// Time step of the model's grid in seconds (default: the first demonstration's mean
    /// sampling interval).
    #[arg(long, allow_hyphen_values = true)]
    dt: Option<f64>,
    /// Forcing-term formulation (robust keeps the shape from a new start or goal).
    #[arg(long, value_enum, default_value = "robust")]
    formulation: FormulationArg,
    /// How several demonstrations are combined.
    #[arg(long, value_enum, default_value = "mean")]
    combine: CombineArg,
    #[command(flatten)]
    output: Output,
}

/// Where a command writes a file and its figure.
#[derive(Args, Debug)]
pub struct Output {
    /// The file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Also draw the result (PNG, or SVG by extension).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print the answer as JSON.
    #[arg(long)]
    pub json: bool,
    /// Replace existing files of the kind cps writes there.
    #[arg(long)]
    pub force: bool,
}

/// Arguments of `cps-cli rollout`.
#[derive(Args, Debug)]
pub struct RolloutArgs {
    /// The model file written by `imitate`.
    model: PathBuf,
    /// New start, one value per dimension, comma-separated.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    start: Option<Vec<f64>>,
    /// New goal, one value per dimension, comma-separated.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    goal: Option<Vec<f64>>,
    /// New duration in seconds.
    #[arg(long, allow_hyphen_values = true)]
    tau: Option<f64>,
    /// New time step in seconds.
    #[arg(long, allow_hyphen_values = true)]
    dt: Option<f64>,
    /// Where to write the trajectory (CSV).
    #[arg(long)]
    out: PathBuf,
    /// Also draw the trajectory (PNG, or SVG by extension).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Replace existing output files (only files of the kind cps writes there).
    #[arg(long)]
    force: bool,
}

fn parse_lambda(arg: Option<&str>, method: Method) -> Result<Lambda, InputError> {
    match arg {
        None => Ok(match method {
            Method::Jerk => Lambda::Auto,
            _ => Lambda::Fixed(1e-12),
        }),
        Some("auto") => Ok(Lambda::Auto),
        Some(v) => match v.parse::<f64>() {
            Ok(x) if x.is_finite() && x >= 0.0 => Ok(Lambda::Fixed(x)),
            _ => Err(InputError(format!(
                "--lambda: `{v}` is neither `auto` nor a finite number ≥ 0"
            ))),
        },
    }
}

/// `cps-cli imitate`.
pub fn run_imitate(args: &ImitateArgs) -> Result<ExitCode> {
    let o = &args.output;
    check_file_targets(&o.out, FileKind::Model, o.plot.as_deref(), o.force)?;
    let lambda = parse_lambda(args.lambda.as_deref(), args.method)?;
    let spec = ImitationSpec {
        bases: args.bases,
        regression: match args.method {
            Method::Lwr => Regression::Lwr,
            Method::Ridge => Regression::Ridge { lambda },
            Method::Jerk => Regression::JerkRidge { lambda },
        },
        tau: args.tau,
        dt: args.dt,
        formulation: match args.formulation {
            FormulationArg::Ijspeert => Formulation::Ijspeert2013,
            FormulationArg::Robust => Formulation::GoalRobust,
        },
        combine: match args.combine {
            CombineArg::Mean => Combine::Mean,
            CombineArg::Stack => Combine::Stack,
        },
    };
    let paths: Vec<&Path> = args.demos.iter().map(PathBuf::as_path).collect();
    let pick = args.lerobot.pick();
    let imitated = imitate_files(&paths, args.columns.as_deref(), &pick, &spec)?;
    write_file(&o.out, imitated.model().to_json().as_bytes()).map_err(cli_error)?;
    if let Some(plot) = &o.plot {
        draw_file(&imitated.figure(), plot).map_err(cli_error)?;
    }
    crate::robot::print(&imitated.answer(&o.out), o.json)
}

/// `cps-cli rollout`.
pub fn run_rollout(args: &RolloutArgs) -> Result<ExitCode> {
    check_file_targets(
        &args.out,
        FileKind::TrajectoryCsv,
        args.plot.as_deref(),
        args.force,
    )?;
    let spec = RolloutSpec {
        start: args.start.clone(),
        goal: args.goal.clone(),
        tau: args.tau,
        dt: args.dt,
    };
    let rolled = rollout_file(&args.model, &spec)?;
    let csv = table_csv(&rolled.table()).map_err(cli_error)?;
    write_file(&args.out, &csv).map_err(cli_error)?;
    if let Some(plot) = &args.plot {
        draw_file(&rolled.figure(), plot).map_err(cli_error)?;
    }
    for w in &rolled.warnings {
        eprintln!("warning: {w}");
    }
    let traj = &rolled.trajectory;
    say!(
        "{} samples over {} s written to {}",
        traj.n_samples(),
        rolled.tau,
        args.out.display()
    );
    Ok(ExitCode::SUCCESS)
}
