//! `cps-cli retime`, `cps-cli export` and `cps-cli plan`: a joint trajectory made ready
//! for a robot.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use cps_experiment::InputError;
use cps_movement::export::{ExportFormat, ExportOptions, export_file, usage};
use cps_movement::retiming::{RetimeMode, retime_file};
use cps_outcome::files::{table_csv, write_file};
use cps_outcome::outcome::Table;
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

/// Arguments of `cps-cli plan`; `--json` prints `{"waypoints", "length_rad", "duration_s",
/// "clearance_m", "planning_s", …}`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    #[command(flatten)]
    arm: RobotArgs,
    /// A scene file: its robot among its obstacles, at its margin (instead of `--robot`).
    #[arg(long, conflicts_with_all = ["robot", "tool", "tip"])]
    scene: Option<PathBuf>,
    /// Where the path starts: joint angles in radians, comma-separated (with `--join`:
    /// where the robot stands, default the first movement's start).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required_unless_present = "join"
    )]
    from: Vec<f64>,
    /// Where it ends.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required_unless_present_any = ["to_pose", "join"],
        conflicts_with_all = ["to_pose", "join"]
    )]
    to: Vec<f64>,
    /// Or movements (joint trajectory CSVs) to run one after another as one trajectory:
    /// each reached from where the one before ends by a planned transition, the whole
    /// verified.
    #[arg(long, num_args = 1.., conflicts_with = "to_pose")]
    join: Vec<PathBuf>,
    /// Or where the tool ends, `x,y,z[,qx,qy,qz,qw]` (m, world frame): the clear
    /// inverse-kinematics solution nearest `--from`.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    to_pose: Vec<f64>,
    /// The timed path as a joint trajectory (CSV: t, then one position per joint, 1 kHz).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Replace an existing file of the kind cps writes there.
    #[arg(long)]
    force: bool,
    /// The seed of the random configurations (the same seed, the same path).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The most random configurations drawn before giving up.
    #[arg(long, default_value_t = 20_000)]
    samples: usize,
    /// The share of the velocity, acceleration and jerk limits the path is timed at.
    #[arg(long, default_value_t = 0.5)]
    share: f64,
}

/// `cps-cli plan`: exit 0 with a path, 1 when none was found, 2 for a bad end.
pub fn plan(args: &PlanArgs) -> Result<ExitCode> {
    use cps_movement::planning::{End, PlanError, Settings, plan_report, reach};
    use cps_movement::robot_file::ik_target;
    let settings = Settings {
        seed: args.seed,
        samples: args.samples,
        share: args.share,
        ..Settings::default()
    };
    settings.check().map_err(|e| InputError(format!("--{e}")))?;
    if let Some(out) = &args.out {
        check_file_target(out, FileKind::TrajectoryCsv, args.force)?;
    }
    let model = match &args.scene {
        Some(s) => cps_movement::scene::load_scene(s)?.robot,
        None => args.arm.load()?,
    };
    if !args.join.is_empty() {
        let from = (!args.from.is_empty()).then_some(&args.from[..]);
        return match cps_movement::planning::join_report(&model, from, &args.join, &settings) {
            Ok(report) => write_plan(args, &report.table, &report),
            Err(e) if e.is_input() => Err(InputError(format!("--join: {e}")).into()),
            Err(e) => {
                eprintln!("error: {e}");
                Ok(ExitCode::from(1))
            }
        };
    }
    let to = if args.to_pose.is_empty() {
        args.to.clone()
    } else {
        let pose = |m: String| InputError(format!("--to-pose: {m}"));
        let target = ik_target(&args.to_pose).map_err(|e| pose(e.0.replace("--target: ", "")))?;
        reach(&model, &target, &args.from, 32, args.seed).map_err(|e| pose(e.to_string()))?
    };
    let report = match plan_report(&model, &args.from, &to, &settings) {
        Ok(r) => r,
        Err(e @ PlanError::NoPath { .. }) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(1));
        }
        Err(e) => match e.end() {
            Some(End::Start) => return Err(InputError(format!("--from: {e}")).into()),
            Some(End::Goal) => return Err(InputError(format!("--to: {e}")).into()),
            None => return Err(e.into()),
        },
    };
    write_plan(args, &report.table, &report)
}

/// The timed motion to `--out` (when given), the report to the terminal.
fn write_plan<T>(args: &PlanArgs, table: &Table, report: &T) -> Result<ExitCode>
where
    T: serde::Serialize + std::fmt::Display,
{
    let title = match &args.out {
        Some(out) => {
            let csv = table_csv(table)?;
            write_file(out, &csv)?;
            format!("{} ({} bytes) written", out.display(), csv.len())
        }
        None => "a path (no --out: nothing written)".to_string(),
    };
    print_titled(&title, report, args.arm.json)
}
