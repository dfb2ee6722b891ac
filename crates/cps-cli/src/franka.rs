//! `cps-cli franka ...`: a Franka over the Franka Control Interface (protocol 10).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use cps_drive::franka::{self, DmpSettings, ExecuteSettings};
use cps_drive::{DriveError, follow, identify};
use cps_outcome::Ended;
use cps_robot::StopToken;

use crate::robot::InScene;
use crate::robot::print;

/// The robot's address, and how to print the answer.
#[derive(Args, Debug)]
pub struct On {
    /// The robot's address (`ip`, or `ip:port` for a port other than 1337).
    #[arg(long)]
    host: String,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// Which arm, and the loop's scheduling.
#[derive(Args, Debug)]
pub struct Arm {
    /// Which arm's limits: `fr3` or `panda`.
    #[arg(long, default_value = "fr3")]
    arm: String,
    /// `enforce`: the loop needs SCHED_FIFO (as libfranka's default); `ignore`: use it
    /// where permitted, else run at normal priority; `off`: run at normal priority.
    #[arg(long, default_value = "enforce")]
    realtime: String,
}

/// `cps-cli franka ...`. Exit codes: 0 done; 1 refused by a check, the robot, or a lost
/// connection (a partial recording is kept, its report says `"complete": false`); 2 bad
/// input; 130 stopped by Ctrl-C or SIGTERM (the robot braked to rest within its limits).
#[derive(Subcommand, Debug)]
pub enum FrankaCommand {
    /// One state: joint positions, velocities, torques, the tool pose, mode and errors.
    State {
        #[command(flatten)]
        on: On,
    },
    /// Execute a joint trajectory (CSV: t, then q1..q7 in rad), or step a joint-space DMP
    /// model (.json) online with phase stopping, at 1 kHz and record what the robot did.
    /// Every command is checked against the arm's limits before the motion starts
    /// (nothing is sent if one fails) and again while streaming.
    Execute(ExecuteArgs),
    /// Follow a learned policy's action chunks recorded in a file (CSV: chunk, arrived_s,
    /// observed_s, k, q1..q7; the targets at --rate), each handed to the chunk executor at
    /// its arrival, or live over UDP (--listen): continuous to the jerk and within every limit at 1 kHz, chunks aligned
    /// to now, bad ones refused, braking to rest when chunks stop. Checked whole first.
    Follow(FollowArgs),
    /// The Franka Hand: `home`, `move W`, `grasp W [--force N]`, `stop`, `state`; each
    /// waits until the fingers settle and prints the hand's state.
    Gripper(GripperArgs),
    /// Identify the robot's joint controller (gains, lag) and drives (rotor inertia,
    /// friction), so that `backend = "dynamics"` with `[robot] calibration` behaves like
    /// it: 9 s of chirps on every joint where the arm stands, within 40 % of its limits,
    /// recorded at 1 kHz, the last 3 s held back to judge the fit.
    Identify(IdentifyArgs),
    /// Record the robot's state at its rate without moving it (guide it by hand in Desk).
    Record(Recording),
    /// Teach by guiding: the arm floats (gravity compensated, lightly damped, pushed back
    /// before its range ends) while you move it by hand; recorded at the robot's rate.
    Guide(GuideArgs),
}

/// Arguments of `cps-cli franka execute`.
#[derive(Args, Debug)]
pub struct ExecuteArgs {
    /// The trajectory file.
    file: PathBuf,
    #[command(flatten)]
    on: On,
    /// The recording (CSV at the robot's rate) to write; its report goes beside it as
    /// `<stem>.report.json`.
    #[arg(long)]
    record: PathBuf,
    #[command(flatten)]
    arm: Arm,
    /// Retime the trajectory to the fastest timing within 95 % of every limit.
    #[arg(long)]
    retime: bool,
    #[command(flatten)]
    scene: InScene,
    /// When the robot is not at the trajectory's start, move there first (at 20 % of
    /// the limits) instead of refusing.
    #[arg(long)]
    approach: bool,
    /// Replace an existing recording.
    #[arg(long)]
    force: bool,
    /// A DMP model: its duration (s; default the model's).
    #[arg(long)]
    tau: Option<f64>,
    /// A DMP model: its goal, seven joint positions (rad; default the model's).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    goal: Option<Vec<f64>>,
    /// A DMP model: the phase slows by 1/(1 + gain · lag in rad) (phase stopping).
    #[arg(long, default_value_t = franka::DEFAULT_ERROR_GAIN)]
    error_gain: f64,
}

/// Arguments of `cps-cli franka follow`.
#[derive(Args, Debug)]
pub struct FollowArgs {
    /// The chunk file (or --listen).
    #[arg(required_unless_present = "listen")]
    file: Option<PathBuf>,
    #[command(flatten)]
    on: On,
    /// Take chunks live from a policy in another process over UDP at this address
    /// (docs/policies.md has the messages; python/examples/chunk_client.py sends them).
    #[arg(long, conflicts_with = "file")]
    listen: Option<std::net::SocketAddr>,
    /// With --listen: the senders' addresses taken (default: loopback only).
    #[arg(long, value_delimiter = ',')]
    allow: Vec<std::net::IpAddr>,
    /// The chunk file's targets per second (a datagram carries its own).
    #[arg(long, required_unless_present = "listen")]
    rate: Option<f64>,
    /// The recording (CSV at the robot's rate), its chunks (`<stem>.chunks.csv`) and
    /// report (`<stem>.report.json`) to write.
    #[arg(long)]
    record: Option<PathBuf>,
    #[command(flatten)]
    arm: Arm,
    #[command(flatten)]
    scene: InScene,
    /// Seconds without a new chunk before the arm brakes to rest.
    #[arg(long, default_value_t = 0.25)]
    stall_timeout: f64,
    /// The largest distance (rad) between the command and where a chunk wants the arm.
    #[arg(long, default_value_t = 0.2)]
    max_gap: f64,
    /// Replace an existing recording.
    #[arg(long)]
    force: bool,
}

/// Arguments of `cps-cli franka gripper`.
#[derive(Args, Debug)]
pub struct GripperArgs {
    /// home, move, grasp, stop or state.
    action: String,
    /// The width in metres (move, grasp).
    width: Option<f64>,
    #[command(flatten)]
    on: On,
    /// Finger speed (m/s).
    #[arg(long, default_value_t = 0.05)]
    speed: f64,
    /// Grasp force (N).
    #[arg(long, default_value_t = 20.0)]
    force: f64,
    /// Grasp tolerance on both sides of the width (m).
    #[arg(long, default_value_t = 0.005)]
    epsilon: f64,
}

/// Arguments of `cps-cli franka identify`.
#[derive(Args, Debug)]
pub struct IdentifyArgs {
    #[command(flatten)]
    on: On,
    /// The calibration file to write (TOML).
    #[arg(long)]
    out: PathBuf,
    /// Also keep the recording (CSV at the robot's rate).
    #[arg(long)]
    record: Option<PathBuf>,
    #[command(flatten)]
    arm: Arm,
    #[command(flatten)]
    scene: InScene,
    /// Replace existing files.
    #[arg(long)]
    force: bool,
}

/// Arguments of `cps-cli franka guide`.
#[derive(Args, Debug)]
pub struct GuideArgs {
    #[command(flatten)]
    rec: Recording,
    /// Damping on every joint (N m s/rad, 0 to 20; default 3 on joints 1-4, 1, 1, 0.5).
    #[arg(long)]
    damping: Option<f64>,
    #[command(flatten)]
    arm: Arm,
}

/// A recording of `franka record` and `franka guide`.
#[derive(Args, Debug)]
pub struct Recording {
    #[command(flatten)]
    on: On,
    /// Seconds to record.
    #[arg(long)]
    duration: f64,
    /// The recording (CSV) to write.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing recording.
    #[arg(long)]
    force: bool,
}

/// `cps-cli franka`.
pub fn franka(cmd: &FrankaCommand, stop: &StopToken) -> Result<ExitCode> {
    match cmd {
        FrankaCommand::State { on } => print(&franka::state(&on.host)?, on.json),
        FrankaCommand::Gripper(a) => {
            let command = franka::gripper_command(&a.action, a.width, a.speed, a.force, a.epsilon)?;
            print(&franka::gripper(&a.on.host, command)?, a.on.json)
        }
        FrankaCommand::Execute(a) => execute(a, stop),
        FrankaCommand::Follow(a) => {
            let exec = ExecuteSettings::parse(&a.on.host, &a.arm.arm, &a.arm.realtime)?
                .in_scene(a.scene.path())?;
            let chunks = follow::Chunks::of(a.file.as_deref(), a.rate, a.listen, &a.allow)?;
            let s = cps_chunks::FollowSettings::with_chunks(a.stall_timeout, a.max_gap);
            let ready = |at| eprintln!("listening for chunks on {at} (udp)");
            let rec = a.record.as_deref();
            let done = follow::franka_follow_from(&chunks, &exec, &s, rec, a.force, &ready, stop);
            finish(done, a.on.json)
        }
        FrankaCommand::Identify(a) => {
            let (arm, rt) = (
                franka::parse_arm(&a.arm.arm)?,
                franka::parse_realtime(&a.arm.realtime)?,
            );
            let settings =
                identify::IdentifySettings::new(&a.on.host, arm, rt).in_scene(a.scene.path())?;
            let done =
                identify::franka_identify(&settings, &a.out, a.record.as_deref(), a.force, stop);
            print(&done?, a.on.json)
        }
        FrankaCommand::Record(r) => finish(
            franka::record(&r.on.host, r.duration, &r.out, r.force, stop),
            r.on.json,
        ),
        FrankaCommand::Guide(a) => {
            let settings = franka::GuideSettings {
                host: a.rec.on.host.clone(),
                arm: franka::parse_arm(&a.arm.arm)?,
                realtime: franka::parse_realtime(&a.arm.realtime)?,
                seconds: a.rec.duration,
                damping: a.damping,
            };
            finish(
                franka::guide(&settings, &a.rec.out, a.rec.force, stop),
                a.rec.on.json,
            )
        }
    }
}

/// `cps-cli franka execute`: a trajectory or a DMP model, at 1 kHz.
fn execute(a: &ExecuteArgs, stop: &StopToken) -> Result<ExitCode> {
    let settings = ExecuteSettings {
        retime: a.retime,
        approach: a.approach,
        ..ExecuteSettings::parse(&a.on.host, &a.arm.arm, &a.arm.realtime)?
            .in_scene(a.scene.path())?
    };
    let online = DmpSettings {
        error_gain: a.error_gain,
        tau: a.tau,
        goal: a.goal.clone(),
    };
    let done = franka::execute_file(&a.file, &settings, &online, &a.record, a.force, stop);
    finish(done, a.on.json)
}

/// Prints a motion's answer and exits with its code.
fn finish<T>(done: Result<(T, Ended), DriveError>, json: bool) -> Result<ExitCode>
where
    T: serde::Serialize + std::fmt::Display,
{
    let (answer, ended) = done?;
    print(&answer, json)?;
    Ok(crate::status(ended))
}
