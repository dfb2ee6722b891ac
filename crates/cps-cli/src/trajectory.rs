//! `cps-cli retime` and `cps-cli export`: a joint trajectory made ready for a robot.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use cps_experiment::InputError;
use cps_movement::export::{ExportFormat, ExportOptions, export_file, usage};
use cps_movement::retiming::{RetimeMode, retime_file};
use cps_outcome::files::{table_csv, write_file};
use cps_outcome::results_dir::{FileKind, check_file_target};

use crate::robot::{RobotArgs, print_titled};

/// A joint trajectory in, a file out.
#[derive(Args, Debug)]
pub struct FileToFile {
    /// The joint trajectory (CSV: time in s, then one position per joint in rad).
    file: PathBuf,
    #[command(flatten)]
    arm: RobotArgs,
    /// The file to write.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing file of the kind cps writes there.
    #[arg(long)]
    force: bool,
}

impl FileToFile {
    /// Writes `bytes` to --out and prints what the library said of them, the file first.
    fn finish<T>(&self, bytes: &[u8], said: &T) -> Result<ExitCode>
    where
        T: serde::Serialize + std::fmt::Display,
    {
        write_file(&self.out, bytes)?;
        let title = format!("{} ({} bytes) written", self.out.display(), bytes.len());
        print_titled(&title, said, self.arm.json)
    }
}

/// Arguments of `cps-cli retime`; `--json` prints `{"mode", "duration_s",
/// "peak_usage_before", "peak_usage_after", …}`.
#[derive(Args, Debug)]
pub struct RetimeArgs {
    #[command(flatten)]
    io: FileToFile,
    /// `fastest`: the time-optimal timing of the path within every limit (TOPP-RA, then
    /// jerk smoothing); `uniform`: the file's own timing slowed (or sped up) by the
    /// smallest factor that keeps every limit. The output has t, positions, `_vel`, `_acc`.
    #[arg(long, default_value = "fastest")]
    mode: String,
    /// The controller's rate in Hz: the output's sampling and the rate limits are checked at.
    #[arg(long, default_value_t = 1000.0)]
    rate: f64,
}

/// `cps-cli retime`.
pub fn retime(args: &RetimeArgs) -> Result<ExitCode> {
    let io = &args.io;
    let mode = RetimeMode::parse(&args.mode).map_err(InputError)?;
    check_file_target(&io.out, FileKind::TrajectoryCsv, io.force)?;
    let report = retime_file(&io.file, &io.arm.load()?, args.rate, mode)?;
    let csv = table_csv(&report.table)?;
    io.finish(&csv, &report)
}

/// Arguments of `cps-cli export`; `--json` prints `{"format", "points", "duration_s",
/// "joint_names", "bytes", "limits_ok", "topics"?}`.
#[derive(Args, Debug)]
pub struct ExportArgs {
    #[command(flatten)]
    io: FileToFile,
    /// `ros2-yaml` (trajectory_msgs/JointTrajectory for `ros2 topic pub` or a
    /// FollowJointTrajectory goal), `mcap` (ROS 2 MCAP with the trajectory, /joint_states,
    /// /tf, /tf_static and /robot_description, for Foxglove or `ros2 bag play`) or
    /// `csv-1khz` (positions, velocities, accelerations at 1 kHz).
    #[arg(long)]
    format: String,
    /// Seconds between exported points (ros2-yaml, mcap).
    #[arg(long, default_value_t = 0.01)]
    period: f64,
}

/// `cps-cli export`.
pub fn export(args: &ExportArgs) -> Result<ExitCode> {
    let io = &args.io;
    let format = ExportFormat::parse(&args.format).map_err(InputError)?;
    check_file_target(&io.out, format.file_kind(), io.force)?;
    let options = ExportOptions {
        period: args.period,
    };
    let exported = export_file(&io.file, &io.arm.load()?, format, &options)?;
    io.finish(&exported.bytes, &exported)?;
    if !io.arm.json {
        usage(format, &io.out)
            .iter()
            .for_each(|line| say!("{line}"));
    }
    Ok(ExitCode::SUCCESS)
}
