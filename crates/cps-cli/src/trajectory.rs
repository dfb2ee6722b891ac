//! `cps-cli retime` and `cps-cli export`: a joint trajectory made ready for a robot.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use cps_experiment::files::{table_csv, write_file};
use cps_experiment::results_dir::{FileKind, check_file_target};
use cps_experiment::retiming::{RetimeMode, retime_file};

use crate::cli_error;
use crate::robot::{RobotArgs, print};

/// Arguments of `cps-cli retime`; `--json` prints `{"mode", "duration_s", "peak_usage_before",
/// "peak_usage_after", …}`.
#[derive(Args, Debug)]
pub struct RetimeArgs {
    /// The joint trajectory (CSV: time in s, then one position per joint in rad).
    file: PathBuf,
    #[command(flatten)]
    arm: RobotArgs,
    /// `fastest`: the time-optimal timing of the path within every limit (TOPP-RA, then
    /// jerk smoothing); `uniform`: the file's own timing slowed (or sped up) by the
    /// smallest factor that keeps every limit.
    #[arg(long, default_value = "fastest")]
    mode: String,
    /// The controller's rate in Hz: the output's sampling and the rate limits are checked at.
    #[arg(long, default_value_t = 1000.0)]
    rate: f64,
    /// The retimed trajectory (CSV: t, positions, `_vel`, `_acc`).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing trajectory CSV at --out.
    #[arg(long)]
    force: bool,
}

/// `cps-cli retime`.
pub fn retime(args: &RetimeArgs) -> Result<ExitCode> {
    let mode = RetimeMode::parse(&args.mode).map_err(cps_experiment::InputError)?;
    check_file_target(&args.out, FileKind::TrajectoryCsv, args.force)?;
    let report = retime_file(&args.file, &args.arm.load()?, args.rate, mode)?;
    write_file(&args.out, &table_csv(&report.table).map_err(cli_error)?).map_err(cli_error)?;
    let mut lines = report.lines();
    lines.push(format!(
        "{} samples at {} Hz written to {}",
        report.table.rows(),
        args.rate,
        args.out.display()
    ));
    let answer = cps_experiment::robot_file::Answer {
        json: report.json(),
        lines,
    };
    print(&answer, args.arm.json)
}
