//! `cps-cli imitate` and `cps-cli rollout`: DMP models from demonstrations (CSV) and
//! trajectories from models (JSON), for users who want the DMP layer alone. The work is
//! `cps_movement::movement`'s; this is arguments, output files and the terminal.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use cps_dmp::{Combine, Formulation, Lambda, Method};
use cps_experiment::InputError;
use cps_movement::lerobot::Pick;
use cps_movement::movement::{ImitationSpec, RolloutSpec, imitate_files, rollout_file};
use cps_movement::robot_file::Saved;
use cps_outcome::files::{table_csv, write_file};
use cps_outcome::results_dir::{FileKind, check_file_targets};
use cps_report::figures::draw_file;

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
    /// Regression method: `ridge` (thesis eq. 51), `jerk` (ridge penalising jerk, thesis
    /// eq. 52) or `lwr` (Schaal's locally weighted regression).
    #[arg(long, default_value = "ridge", value_parser = named::<Method, 3>(Method::ALL.map(Method::name)))]
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
    /// Forcing-term formulation: `robust` (Hoffmann/Pastor 2009: independent of goal −
    /// start, keeps the shape from a new start or goal) or `ijspeert` (Ijspeert et al.
    /// 2013, the thesis's: the forcing term scales with goal − start).
    #[arg(long, default_value = "robust", value_parser = named::<Formulation, 2>(Formulation::ALL.map(Formulation::name)))]
    formulation: Formulation,
    /// How several demonstrations are combined: `mean` (average the time-normalised
    /// demonstrations, then fit) or `stack` (one regression over all samples).
    #[arg(long, default_value = "mean", value_parser = named::<Combine, 2>(Combine::ALL.map(Combine::name)))]
    combine: Combine,
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

/// A setting that names itself (cps-dmp's `FromStr`): its names offered in the help.
fn named<T, const N: usize>(names: [&'static str; N]) -> impl TypedValueParser<Value = T>
where
    T: std::str::FromStr<Err = cps_dmp::DmpError> + Clone + Send + Sync + 'static,
{
    PossibleValuesParser::new(names).try_map(|s| s.parse::<T>())
}

/// `--lambda`, when given.
fn parse_lambda(arg: Option<&str>) -> Result<Option<Lambda>, InputError> {
    arg.map(|v| {
        Lambda::parse(v).ok_or_else(|| {
            InputError(format!(
                "--lambda: `{v}` is neither `auto` nor a finite number ≥ 0"
            ))
        })
    })
    .transpose()
}

/// `cps-cli imitate`.
pub fn run_imitate(args: &ImitateArgs) -> Result<ExitCode> {
    let o = &args.output;
    check_file_targets(&o.out, FileKind::Model, o.plot.as_deref(), o.force)?;
    let lambda = parse_lambda(args.lambda.as_deref())?;
    let spec = ImitationSpec {
        bases: args.bases,
        regression: args.method.regression(lambda),
        tau: args.tau,
        dt: args.dt,
        formulation: args.formulation,
        combine: args.combine,
    };
    let paths: Vec<&Path> = args.demos.iter().map(PathBuf::as_path).collect();
    let pick = args.lerobot.pick();
    let imitated = imitate_files(&paths, args.columns.as_deref(), &pick, &spec)?;
    write_file(&o.out, imitated.model().to_json().as_bytes())?;
    if let Some(plot) = &o.plot {
        draw_file(&imitated.figure(), plot)?;
    }
    crate::robot::print(
        &Saved {
            what: &imitated,
            out: &o.out,
        },
        o.json,
    )
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
    let csv = table_csv(&rolled.table())?;
    write_file(&args.out, &csv)?;
    if let Some(plot) = &args.plot {
        draw_file(&rolled.figure(), plot)?;
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
