//! `cps-cli lerobot ...`: LeRobot datasets shown, or written from recordings.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use cps_movement::lerobot_write::{Export, write_recordings};

use crate::robot::print;

/// `cps-cli lerobot ...`. Exit codes: 0 done; 2 a dataset that cannot be read.
#[derive(Subcommand, Debug)]
pub enum LeRobotCommand {
    /// A dataset's rate, robot, features (type, shape, entry names) and episodes (frames,
    /// duration, tasks).
    Show {
        /// The dataset's folder (it holds meta/info.json).
        dataset: PathBuf,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Recordings (`franka execute --record`, `franka record`, `franka guide`, `ros2
    /// record`, a joint CSV) written as a new dataset LeRobot's loader opens, one episode
    /// each: joint states (velocities, torques where recorded) and actions (the commands,
    /// or the next state), resampled to --fps, without video.
    Write(WriteArgs),
}

/// Arguments of `cps-cli lerobot write`.
#[derive(Args, Debug)]
pub struct WriteArgs {
    /// The recordings (CSV).
    #[arg(required = true)]
    recordings: Vec<PathBuf>,
    /// The dataset's folder to create.
    #[arg(long)]
    out: PathBuf,
    /// The robot recorded: its joints name the entries.
    #[arg(long, default_value = "fr3")]
    robot: String,
    /// What the episodes did (LeRobot's task).
    #[arg(long)]
    task: String,
    /// Frames per second (default: the first recording's rate).
    #[arg(long)]
    fps: Option<u32>,
    /// Replace a dataset at --out that holds nothing but the files cps writes.
    #[arg(long)]
    force: bool,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// `cps-cli lerobot`.
pub fn lerobot(cmd: &LeRobotCommand) -> Result<ExitCode> {
    match cmd {
        LeRobotCommand::Show { dataset, json } => {
            print(&cps_movement::lerobot::describe(dataset)?, *json)
        }
        LeRobotCommand::Write(a) => {
            let export = Export {
                robot: a.robot.clone(),
                task: a.task.clone(),
                fps: a.fps,
            };
            print(
                &write_recordings(&a.out, &a.recordings, &export, a.force)?,
                a.json,
            )
        }
    }
}
