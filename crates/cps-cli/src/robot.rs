//! `cps-cli fk`, `ik` and `robot show`: the kinematics from the command line.

use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand, ValueEnum};
use cps_kinematics::robots::{PandaTool, panda, puma560, ur3};
use cps_kinematics::{DhConvention, IkConfig, IkTarget, KinematicsError, SerialChain, solve_ik};
use nalgebra::{IsometryMatrix3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::experiment::InputError;

/// The Panda's tool point.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ToolArg {
    /// The Franka Hand's tool centre point (0.1034 m beyond the flange, turned −45°).
    Hand,
    /// The flange.
    Flange,
}

/// Which robot and tool point a kinematics command works on.
#[derive(Args, Debug)]
pub struct RobotArgs {
    /// Robot: `panda`, `ur3` or `puma560`.
    #[arg(long, default_value = "panda")]
    robot: String,
    /// Tool point of the Panda.
    #[arg(long, value_enum, default_value = "hand")]
    tool: ToolArg,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
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
    /// Joint angles to start from (default: the Panda's ready pose, or zeros).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    seed_q: Option<Vec<f64>>,
}

/// `cps-cli robot ...`.
#[derive(Subcommand, Debug)]
pub enum RobotCommand {
    /// Print a robot's DH table, convention, limits and tool.
    Show {
        /// `panda`, `ur3` or `puma560`.
        name: String,
    },
}

/// The Panda's "ready" configuration (Franka's default start pose).
const PANDA_READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];

fn robot_model(name: &str, tool: ToolArg) -> Result<SerialChain, InputError> {
    match name {
        "panda" => Ok(panda(match tool {
            ToolArg::Hand => PandaTool::HandTcp,
            ToolArg::Flange => PandaTool::Flange,
        })),
        "puma560" => Ok(puma560()),
        "ur3" => Ok(ur3()),
        other => Err(InputError(format!(
            "--robot: unknown robot `{other}` (built in: panda, ur3, puma560)"
        ))),
    }
}

fn kin(e: KinematicsError) -> anyhow::Error {
    InputError(e.to_string()).into()
}

/// `cps-cli fk`.
pub fn fk(args: &FkArgs) -> Result<ExitCode> {
    let arm = robot_model(&args.arm.robot, args.arm.tool)?;
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

/// `cps-cli ik`.
pub fn ik(args: &IkArgs) -> Result<ExitCode> {
    let arm = robot_model(&args.arm.robot, args.arm.tool)?;
    if let Some(v) = args.target.iter().find(|v| !v.is_finite()) {
        return Err(InputError(format!("--target: values must be finite (got {v})")).into());
    }
    let target = match args.target.as_slice() {
        [x, y, z] => IkTarget::Position(Vector3::new(*x, *y, *z)),
        [x, y, z, qx, qy, qz, qw] => {
            let quat = Quaternion::new(*qw, *qx, *qy, *qz);
            if quat.norm() < 1e-9 {
                return Err(InputError("--target: the quaternion has zero length".into()).into());
            }
            let rot = UnitQuaternion::from_quaternion(quat).to_rotation_matrix();
            IkTarget::Pose(IsometryMatrix3::from_parts(
                Translation3::new(*x, *y, *z),
                rot,
            ))
        }
        other => {
            return Err(InputError(format!(
                "--target: give x,y,z or x,y,z,qx,qy,qz,qw ({} values given)",
                other.len()
            ))
            .into());
        }
    };
    let seed = match &args.seed_q {
        Some(q) => q.clone(),
        None if args.arm.robot == "panda" => PANDA_READY.to_vec(),
        None => vec![0.0; arm.dof()],
    };
    let sol = solve_ik(&arm, &target, &seed, &IkConfig::default()).map_err(kin)?;
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

/// `cps-cli robot show`.
pub fn robot(cmd: &RobotCommand) -> Result<ExitCode> {
    let RobotCommand::Show { name } = cmd;
    let arm = robot_model(name, ToolArg::Hand)?;
    let conv = match arm.convention() {
        DhConvention::Standard => "standard DH: T_i = RotZ(θ_i) TransZ(d_i) TransX(a_i) RotX(α_i)",
        DhConvention::Modified => {
            "modified (Craig) DH: T_i = RotX(α_{i−1}) TransX(a_{i−1}) RotZ(θ_i) TransZ(d_i)"
        }
    };
    say!("{name}: {} revolute joints, {conv}", arm.dof());
    say!(
        "{:>5} {:>9} {:>9} {:>10} {:>8} {:>10} {:>10}",
        "joint",
        "a [m]",
        "d [m]",
        "α [rad]",
        "offset",
        "q_min",
        "q_max"
    );
    for (i, l) in arm.links().iter().enumerate() {
        let (lo, hi) = arm
            .limits()
            .map_or(("-".to_string(), "-".to_string()), |(lo, hi)| {
                (format!("{:.4}", lo[i]), format!("{:.4}", hi[i]))
            });
        say!(
            "{:>5} {:>9.4} {:>9.4} {:>10.4} {:>8.4} {:>10} {:>10}",
            i + 1,
            l.a,
            l.d,
            l.alpha,
            l.offset,
            lo,
            hi
        );
    }
    if name == "panda" {
        say!(
            "flange: 0.107 m along joint 7's z axis; Franka Hand TCP: flange turned −45° about z, then 0.1034 m along z"
        );
    }
    Ok(ExitCode::SUCCESS)
}
