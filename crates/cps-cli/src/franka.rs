//! `cps-cli franka ...`: a Franka over the Franka Control Interface (protocol 10).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use anyhow::Result;
use clap::Subcommand;
use cps_experiment::franka::{self, ExecuteSettings};
use cps_experiment::robot_file::Answer;

use crate::cli_error;
use crate::robot::print;

/// `cps-cli franka ...`. Exit codes: 0 done; 1 refused by a check, the robot, or a lost
/// connection (a partial recording is kept, its report says `"complete": false`); 2 bad
/// input; 130 stopped by Ctrl-C or SIGTERM (the robot braked to rest within its limits).
#[derive(Subcommand, Debug)]
pub enum FrankaCommand {
    /// One state: joint positions, velocities, torques, the tool pose, mode and errors.
    State {
        /// The robot's address (`ip` or `ip:port`).
        #[arg(long)]
        host: String,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Execute a joint trajectory (CSV: t, then q1..q7 in rad, as `limits check` reads it)
    /// at 1 kHz and record what the robot did. Every command is checked against the arm's
    /// published limits before the motion starts (nothing is sent if one fails) and again
    /// while streaming.
    Execute {
        /// The trajectory file.
        file: PathBuf,
        /// The robot's address.
        #[arg(long)]
        host: String,
        /// The recording (CSV at the robot's rate) to write; its report goes beside it as
        /// `<stem>.report.json`.
        #[arg(long)]
        record: PathBuf,
        /// Which arm's limits: `fr3` or `panda`.
        #[arg(long, default_value = "fr3")]
        arm: String,
        /// Retime the trajectory to the fastest timing within 95 % of every limit.
        #[arg(long)]
        retime: bool,
        /// When the robot is not at the trajectory's start, move there first (at 20 % of
        /// the limits) instead of refusing.
        #[arg(long)]
        approach: bool,
        /// `enforce`: the loop needs SCHED_FIFO (as libfranka's default); `ignore`: use it
        /// where permitted, else run at normal priority.
        #[arg(long, default_value = "enforce")]
        realtime: String,
        /// Replace an existing recording.
        #[arg(long)]
        force: bool,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Record the robot's state at its rate without moving it (guide it by hand in Desk).
    Record {
        /// The robot's address.
        #[arg(long)]
        host: String,
        /// Seconds to record.
        #[arg(long)]
        duration: f64,
        /// The recording (CSV) to write.
        #[arg(long)]
        out: PathBuf,
        /// Replace an existing recording.
        #[arg(long)]
        force: bool,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
}

/// `cps-cli franka`.
pub fn franka(cmd: &FrankaCommand, stop: &AtomicBool) -> Result<ExitCode> {
    match cmd {
        FrankaCommand::State { host, json } => {
            print(&franka::state(host).map_err(cli_error)?, *json)
        }
        FrankaCommand::Execute {
            file,
            host,
            record,
            arm,
            retime,
            approach,
            realtime,
            force,
            json,
        } => {
            let settings = ExecuteSettings {
                host: host.clone(),
                arm: franka::parse_arm(arm)?,
                retime: *retime,
                approach: *approach,
                realtime: franka::parse_realtime(realtime)?,
            };
            franka::check_record_target(record, *force)?;
            let prepared =
                franka::prepare(file, settings.arm, settings.retime).map_err(cli_error)?;
            let done = franka::execute(&prepared, &settings, stop).map_err(cli_error)?;
            let report = done.json();
            franka::write_recording(record, &done.report.samples, &report).map_err(cli_error)?;
            let answer = Answer {
                json: report,
                lines: done.lines(record),
            };
            print(&answer, *json)?;
            Ok(ExitCode::from(franka::exit_code(&done.report.ending)))
        }
        FrankaCommand::Record {
            host,
            duration,
            out,
            force,
            json,
        } => {
            franka::check_record_target(out, *force)?;
            let (report, lines) = franka::record(host, *duration, out, stop).map_err(cli_error)?;
            let complete = report["complete"] == true;
            print(
                &Answer {
                    json: report,
                    lines,
                },
                *json,
            )?;
            let stopped = stop.load(std::sync::atomic::Ordering::Relaxed);
            Ok(ExitCode::from(match (stopped, complete) {
                (true, _) => 130,
                (false, true) => 0,
                (false, false) => 1,
            }))
        }
    }
}
