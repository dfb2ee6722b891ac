//! `cps-cli fk`, `ik` and `robot show`: the kinematics from the command line.

use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use cps_drive::identify::identify_recording;
use cps_experiment::InputError;
use cps_movement::robot_file::{RobotModel, joint_solution, load_robot, tool_pose};
use cps_robot::StopToken;

/// Which robot and tool point a kinematics command works on.
#[derive(Args, Debug)]
pub struct RobotArgs {
    /// Robot: a built-in name (`panda`, `ur3`, `crx10ia`, `puma560`) or a robot file (`.toml` as in
    /// configs/robots/, or `.urdf`).
    #[arg(long, default_value = "panda")]
    pub robot: String,
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
    pub json: bool,
}

impl RobotArgs {
    pub fn load(&self) -> Result<RobotModel, InputError> {
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
        /// A built-in name (`panda`, `ur3`, `crx10ia`, `puma560`) or a `.toml` / `.urdf` robot file.
        robot: String,
        /// Tool point (as for `fk`).
        #[arg(long)]
        tool: Option<String>,
        /// URDF tip link (as for `fk`).
        #[arg(long)]
        tip: Option<String>,
    },
}

/// Prints a command's result as JSON (`--json`) or as its text.
pub fn print<T: serde::Serialize + std::fmt::Display>(result: &T, json: bool) -> Result<ExitCode> {
    if json {
        say!("{}", serde_json::to_string_pretty(result)?);
    } else {
        let text = result.to_string();
        if !text.is_empty() {
            say!("{text}");
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// [`print()`] with a first line that names what the text is about (not in the JSON).
pub fn print_titled<T>(title: &str, result: &T, json: bool) -> Result<ExitCode>
where
    T: serde::Serialize + std::fmt::Display,
{
    if !json {
        say!("{title}");
    }
    print(result, json)
}

/// `cps-cli fk`.
pub fn fk(args: &FkArgs) -> Result<ExitCode> {
    let model = args.arm.load()?;
    let answer = tool_pose(&model, &args.arm.robot, &args.q, args.within_limits)?;
    print(&answer, args.arm.json)
}

/// `cps-cli ik`.
pub fn ik(args: &IkArgs) -> Result<ExitCode> {
    let model = args.arm.load()?;
    let answer = joint_solution(
        &model,
        &args.arm.robot,
        &args.target,
        args.seed_q.as_deref(),
    )?;
    print(&answer, args.arm.json)
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
    let report = cps_movement::limits::check_file(file, &arm.load()?, *rate)?;
    let title = format!("{} on {}:", file.display(), arm.robot);
    print_titled(&title, &report, arm.json)?;
    Ok(ExitCode::from(u8::from(!report.ok())))
}

/// Arguments of `cps-cli collide`.
#[derive(Args, Debug)]
pub struct CollideArgs {
    /// The joint trajectory (CSV: time in s, then one position per joint in rad).
    file: std::path::PathBuf,
    #[command(flatten)]
    arm: RobotArgs,
    /// A scene file: its robot, placed at its base, among its obstacles (instead of
    /// `--robot`).
    #[arg(long, conflicts_with_all = ["robot", "tool", "tip"])]
    scene: Option<std::path::PathBuf>,
    /// The clearance every pair keeps, in metres (default: the scene's, else 0.005).
    #[arg(long, allow_hyphen_values = true)]
    margin: Option<f64>,
    /// The controller's rate in Hz, at which the guard checks (as `limits check`).
    #[arg(long, default_value_t = 1000.0)]
    rate: f64,
}

/// `cps-cli collide`: exit 0 when every pair keeps the margin, 1 on a collision.
pub fn collide(args: &CollideArgs) -> Result<ExitCode> {
    let (model, what) = match &args.scene {
        Some(s) => (
            cps_movement::scene::load_scene(s)?.robot,
            s.display().to_string(),
        ),
        None => (args.arm.load()?, args.arm.robot.clone()),
    };
    let report = cps_movement::collide::check_file(&args.file, &model, args.rate, args.margin)?;
    let title = format!("{} on {what}:", args.file.display());
    print_titled(&title, &report, args.arm.json)?;
    Ok(ExitCode::from(u8::from(!report.ok())))
}

/// Arguments of `cps-cli identify`.
#[derive(Args, Debug)]
pub struct IdentifyArgs {
    /// The recording (CSV).
    recording: std::path::PathBuf,
    /// The robot recorded (its model, with the hand's inertias).
    #[arg(long, default_value = "fr3")]
    robot: String,
    /// The calibration file to write (TOML).
    #[arg(long)]
    out: std::path::PathBuf,
    /// Replace an existing calibration.
    #[arg(long)]
    force: bool,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// `cps-cli identify`: a calibration from a recording.
pub fn identify(a: &IdentifyArgs, stop: &StopToken) -> Result<ExitCode> {
    match identify_recording(&a.recording, &a.robot, &a.out, a.force, stop) {
        Err(e) if stop.is_stopped() => {
            eprintln!("interrupted: {e}");
            Ok(crate::status(cps_outcome::Ended::Stopped))
        }
        done => print(&done?, a.json),
    }
}

/// `cps-cli robot show`.
pub fn robot(cmd: &RobotCommand) -> Result<ExitCode> {
    let RobotCommand::Show { robot, tool, tip } = cmd;
    let model = load_robot(robot, tool.as_deref(), tip.as_deref())?;
    for line in cps_movement::robot_file::Describe::describe(&model) {
        say!("{line}");
    }
    Ok(ExitCode::SUCCESS)
}

/// The scene a command's motions are checked in (`--scene`).
#[derive(clap::Args, Debug)]
pub struct InScene {
    /// A scene file (TOML, as configs/scenes/fr3.toml) whose robot is the one driven: every
    /// command is checked against its obstacles at its margin as well as against the robot
    /// itself (without it, the robot alone); nothing is sent if one comes closer.
    #[arg(long)]
    pub scene: Option<std::path::PathBuf>,
}

impl InScene {
    /// The scene file, if one was given.
    pub fn path(&self) -> Option<&std::path::Path> {
        self.scene.as_deref()
    }
}
