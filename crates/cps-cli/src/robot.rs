//! `cps-cli fk`, `ik` and `robot show`: the kinematics from the command line.

use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use cps_kinematics::{IkConfig, KinematicsError, solve_ik};
use nalgebra::UnitQuaternion;

use cps_experiment::InputError;
use cps_experiment::robot_file::{RobotModel, ik_target, load_robot};

/// Which robot and tool point a kinematics command works on.
#[derive(Args, Debug)]
pub struct RobotArgs {
    /// Robot: a built-in name (`panda`, `ur3`, `puma560`) or a robot file (`.toml` as in
    /// configs/robots/, or `.urdf`).
    #[arg(long, default_value = "panda")]
    robot: String,
    /// Tool point: `hand` or `flange` for the built-in Panda, a `[tools.*]` name for a TOML
    /// robot (default: the file's `default_tool`).
    #[arg(long)]
    tool: Option<String>,
    /// URDF only: the tip link the chain ends at (default: the one leaf reached through
    /// revolute joints).
    #[arg(long)]
    tip: Option<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

impl RobotArgs {
    fn load(&self) -> Result<RobotModel, InputError> {
        load_robot(&self.robot, self.tool.as_deref(), self.tip.as_deref())
    }
}

/// Arguments of `cps-cli fk`; `--json` prints `{"T", "position", "quaternion_xyzw"}`.
#[derive(Args, Debug)]
pub struct FkArgs {
    #[command(flatten)]
    arm: RobotArgs,
    /// Joint angles in radians, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    q: Vec<f64>,
    /// Refuse joint angles outside the robot's limits (exit 2) instead of computing the
    /// pose anyway.
    #[arg(long)]
    within_limits: bool,
}

/// Arguments of `cps-cli ik`; `--json` prints `{"q", "position_error", "rotation_error",
/// "iterations"}`.
#[derive(Args, Debug)]
pub struct IkArgs {
    #[command(flatten)]
    arm: RobotArgs,
    /// Target `x,y,z` (metres, world frame) or a full pose `x,y,z,qx,qy,qz,qw`.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    target: Vec<f64>,
    /// Joint angles to start from, within the limits (default: the robot's ready pose, or
    /// the middle of each joint's range).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    seed_q: Option<Vec<f64>>,
}

/// `cps-cli robot ...`.
#[derive(Subcommand, Debug)]
pub enum RobotCommand {
    /// Print a robot's kinematic description (DH table or URDF joints), limits, base and tool.
    Show {
        /// A built-in name (`panda`, `ur3`, `puma560`) or a `.toml` / `.urdf` robot file.
        robot: String,
        /// Tool point (as for `fk`).
        #[arg(long)]
        tool: Option<String>,
        /// URDF tip link (as for `fk`).
        #[arg(long)]
        tip: Option<String>,
    },
}

fn kin(e: KinematicsError) -> anyhow::Error {
    InputError(e.to_string()).into()
}

/// `cps-cli fk`.
pub fn fk(args: &FkArgs) -> Result<ExitCode> {
    let arm = args.arm.load()?.chain;
    if let Some((j, v)) = args
        .q
        .iter()
        .enumerate()
        .find(|(_, v)| v.abs() > MAX_JOINT_VALUE)
    {
        return Err(InputError(format!(
            "--q: joint {} is {v:?}; joint values must be at most {MAX_JOINT_VALUE} in magnitude",
            j + 1
        ))
        .into());
    }
    if args.within_limits {
        arm.check_within_limits(&args.q)
            .map_err(|e| InputError(format!("--q: {e}")))?;
    }
    let t = arm.fk_matrix(&args.q).map_err(kin)?;
    let pose = arm.fk(&args.q).map_err(kin)?;
    let q = UnitQuaternion::from_rotation_matrix(&pose.rotation);
    let p = pose.translation.vector;
    if args.arm.json {
        let rows: Vec<Vec<f64>> = (0..4)
            .map(|r| (0..4).map(|c| t[(r, c)]).collect())
            .collect();
        let out = serde_json::json!({
            "robot": args.arm.robot,
            "q": args.q,
            "T": rows,
            "position": [p.x, p.y, p.z],
            "quaternion_xyzw": [q.i, q.j, q.k, q.w],
        });
        say!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        say!("tool pose of {} (world frame, metres):", args.arm.robot);
        for r in 0..4 {
            say!(
                "  [{:>10.6} {:>10.6} {:>10.6} {:>10.6}]",
                t[(r, 0)],
                t[(r, 1)],
                t[(r, 2)],
                t[(r, 3)]
            );
        }
        say!("position   {:.6} {:.6} {:.6}", p.x, p.y, p.z);
        say!(
            "quaternion {:.6} {:.6} {:.6} {:.6} (x y z w)",
            q.i,
            q.j,
            q.k,
            q.w
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The largest joint value accepted (radians or metres): beyond it the angle means nothing.
const MAX_JOINT_VALUE: f64 = 1000.0;

/// `cps-cli ik`.
pub fn ik(args: &IkArgs) -> Result<ExitCode> {
    let model = args.arm.load()?;
    let arm = &model.chain;
    let target = ik_target(&args.target)?;
    let seed = args.seed_q.clone().unwrap_or_else(|| model.ready.clone());
    arm.check_within_limits(&seed)
        .map_err(|e| InputError(format!("--seed-q: {e}")))?;
    let sol = solve_ik(arm, &target, &seed, &IkConfig::default()).map_err(kin)?;
    if args.arm.json {
        let out = serde_json::json!({
            "robot": args.arm.robot,
            "q": sol.q,
            "position_error": sol.position_error,
            "rotation_error": sol.rotation_error,
            "iterations": sol.iterations,
            "restarts": sol.restarts,
        });
        say!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let q: Vec<String> = sol.q.iter().map(|v| format!("{v:.6}")).collect();
        say!("q = [{}] rad", q.join(", "));
        say!(
            "position error {:.3e} m, rotation error {:.3e} rad, {} iterations, {} restarts",
            sol.position_error,
            sol.rotation_error,
            sol.iterations,
            sol.restarts
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `cps-cli limits ...`.
#[derive(Subcommand, Debug)]
pub enum LimitsCommand {
    /// Check a joint trajectory (CSV: time in s, then one position per joint in rad)
    /// against the robot's limits as its controller sees it: exit 0 when every limit
    /// holds, 1 when one is violated, 2 for bad input. `--json` prints `{"ok",
    /// "peak_usage", "violations", "not_checked", …}`.
    Check {
        /// The trajectory file.
        file: std::path::PathBuf,
        #[command(flatten)]
        arm: RobotArgs,
        /// The controller's rate in Hz: positions are commanded, and differentiated,
        /// at this rate (a file sampled otherwise is resampled by a cubic spline).
        #[arg(long, default_value_t = 1000.0)]
        rate: f64,
    },
}

/// `cps-cli limits check`.
pub fn limits(cmd: &LimitsCommand) -> Result<ExitCode> {
    let LimitsCommand::Check { file, arm, rate } = cmd;
    let report = cps_experiment::limits::check_file(file, &arm.load()?, *rate)?;
    if arm.json {
        say!("{}", serde_json::to_string_pretty(&report.json())?);
    } else {
        say!("{} on {}:", file.display(), arm.robot);
        for line in report.lines() {
            say!("{line}");
        }
    }
    Ok(if report.check.ok() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `cps-cli robot show`.
pub fn robot(cmd: &RobotCommand) -> Result<ExitCode> {
    let RobotCommand::Show { robot, tool, tip } = cmd;
    let model = load_robot(robot, tool.as_deref(), tip.as_deref())?;
    for line in model.describe() {
        say!("{line}");
    }
    Ok(ExitCode::SUCCESS)
}
