//! A learned policy's action chunks on a Franka from a file (`cps-cli franka follow`): a
//! recorded chunk stream (`chunk, arrived_s, observed_s, k, q1..q7`, the targets at
//! `--rate`) replayed through the chunk executor at 1 kHz, each chunk handed over at its
//! arrival, from where the arm stands. The executor's commands depend on the chunks
//! alone, so they are checked whole by the guard before anything moves.
//!
//! The recording is `franka execute`'s (`t, q, dq, tau, q_d, tool` at 1 kHz) with the
//! chunks beside it in the replay form (`<stem>.chunks.csv`: any run can be replayed) and
//! the report (`<stem>.report.json`): the execution's, with the chunks' (taken, refused
//! and why, targets skipped, inference delay and jitter, acceleration and jerk peaks at
//! the boundaries and overall, stalls).

use std::path::{Path, PathBuf};

use cps_franka::limits::DT;
use cps_movement::robot_file::Answer;
use cps_outcome::results_dir::{FileKind, check_file_target};
use cps_outcome::{ExperimentError, InputError};
use cps_robot::{
    ChunkLog, FollowReport, FollowSettings, Followed, Policy, Replay, Robot, RobotError, StopToken,
    follow, replay_plan,
};
use serde_json::{Value, json};

use crate::franka::{ExecuteSettings, Executed, exit_code, guarded_arm, write_recording};
use crate::recording::check_record_target;

/// The replay file of a recording: `rec.csv` → `rec.chunks.csv`.
pub fn chunks_path(record: &Path) -> PathBuf {
    let stem = record
        .file_stem()
        .map_or("recording".into(), |s| s.to_string_lossy().into_owned());
    record.with_file_name(format!("{stem}.chunks.csv"))
}

/// The chunks' part of a report as JSON.
pub fn report_json(r: &FollowReport) -> Value {
    let spread =
        |s: &cps_robot::Spread| json!({"mean": s.mean, "std": s.std, "min": s.min, "max": s.max});
    let peaks = |p: &cps_robot::Peaks| json!({"velocity": p.velocity, "acceleration": p.acceleration, "jerk": p.jerk});
    json!({
        "came": r.chunks, "taken": r.taken, "refused": r.refused, "skipped_targets": r.skipped,
        "refusals": r.refusals.iter().map(|(i, why)| json!({"chunk": i, "why": why})).collect::<Vec<_>>(),
        "inference_delay_s": spread(&r.delay),
        "interval_s": spread(&r.interval),
        "peaks": peaks(&r.overall),
        "peaks_at_boundaries": peaks(&r.boundaries),
        "limit_share_used": {"velocity": r.usage[0], "acceleration": r.usage[1], "jerk": r.usage[2]},
        "stalls_s": r.stalls,
        "lost_log_entries": r.lost,
    })
}

/// Follows the chunks of `file` (targets at `rate_hz`) on the Franka of `exec` under
/// `settings`; writes the recording, its chunks and its report when `record` is given
/// (checked before anything moves). Returns the answer and the exit code: 0 the stream
/// was followed to its end, 1 the robot or the connection failed, 130 stopped.
pub fn franka_follow(
    file: &Path,
    rate_hz: f64,
    exec: &ExecuteSettings,
    settings: &FollowSettings,
    record: Option<&Path>,
    force: bool,
    stop: &StopToken,
) -> Result<(Answer, u8), ExperimentError> {
    if let Some(r) = record {
        check_record_target(r, force)?;
        check_file_target(&chunks_path(r), FileKind::TrajectoryCsv, force)?;
    }
    settings.check().map_err(InputError)?;
    let chunks = cps_movement::chunks::read_chunks(file, 7, rate_hz)?;
    let name = file.display().to_string();
    let mut robot = guarded_arm(exec, Policy::STRICT)?;
    let q0 = robot
        .joint_positions()
        .map_err(|e| ExperimentError::Message(e.to_string()))?;
    let plan = replay_plan(robot.model(), &q0, DT, &chunks, settings)
        .map_err(|e| InputError(format!("{name}: {e}")))?;
    let mut source = Replay::new(chunks);
    let run: Followed =
        follow(&mut robot, &mut source, Some(&plan), settings, stop).map_err(|e| match e {
            RobotError::Refused { reason, .. } => ExperimentError::Message(format!(
                "{name}: refused before sending anything: the executor's commands for these chunks from where the arm stands break a limit: {reason}"
            )),
            other => ExperimentError::Message(format!("{name}: {other}")),
        })?;
    let log: ChunkLog = source.into_log();
    let report = FollowReport::new(&run, &log);
    let executed = Executed {
        host: exec.host.clone(),
        arm: exec.arm,
        report: robot
            .inner()
            .reports()
            .last()
            .cloned()
            .ok_or_else(|| ExperimentError::Message("the robot sent no report".into()))?,
        approach: 0,
        how: "action chunks followed",
    };
    let mut json = executed.json();
    json["chunks"] = report_json(&report);
    let mut lines = match record {
        Some(r) => {
            write_recording(r, &executed.report.samples, &json)?;
            let chunks: Vec<_> = log.entries.iter().map(|(c, _)| c.clone()).collect();
            let text = cps_movement::chunks::write_chunks(&chunks, 7);
            cps_outcome::files::write_file(&chunks_path(r), text.as_bytes())?;
            let mut l = executed.lines(r);
            l.push(format!(
                "  chunks as replayed: {}",
                chunks_path(r).display()
            ));
            l
        }
        None => executed.lines(Path::new("(not recorded: --record)")),
    };
    lines.extend(report.lines().into_iter().map(|l| format!("  {l}")));
    Ok((Answer { json, lines }, exit_code(&executed.report.ending)))
}
