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

use cps_chunks::{
    ChunkLog, FollowError, FollowReport, FollowSettings, Followed, Replay, follow, replay_plan,
};
use cps_franka::limits::DT;
use cps_outcome::results_dir::{FileKind, check_file_target};
use cps_outcome::{Ended, InputError};

use crate::error::DriveError;
use crate::franka::ExecutedTo;
use cps_robot::{Policy, Robot, RobotError, StopToken};
use serde_json::{Value, json};

use crate::franka::{
    ExecuteSettings, Executed, ended, guarded_arm, write_recording, write_table_and_report,
};
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
        |s: &cps_chunks::Spread| json!({"mean": s.mean, "std": s.std, "min": s.min, "max": s.max});
    let peaks = |p: &cps_chunks::Peaks| json!({"velocity": p.velocity, "acceleration": p.acceleration, "jerk": p.jerk});
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

/// Where `franka follow` takes its chunks from.
#[derive(Debug, Clone)]
pub enum Chunks {
    /// A recorded stream: the file and its targets' rate (Hz).
    File {
        /// The chunk file.
        path: std::path::PathBuf,
        /// Targets per second.
        rate_hz: f64,
    },
    /// A policy in another process, over UDP.
    Listen(Listen),
}

impl Chunks {
    /// The command line's choice: a file (with its rate) or an address to listen on
    /// (with the senders taken). Errors: neither, or a file without its rate.
    pub fn of(
        file: Option<&Path>,
        rate_hz: Option<f64>,
        listen: Option<std::net::SocketAddr>,
        allow: &[std::net::IpAddr],
    ) -> Result<Chunks, InputError> {
        match (file, listen) {
            (Some(path), None) => Ok(Chunks::File {
                path: path.to_path_buf(),
                rate_hz: rate_hz.ok_or_else(|| {
                    InputError("--rate: give the chunk file's targets per second".into())
                })?,
            }),
            (None, Some(addr)) => Ok(Chunks::Listen(Listen {
                addr,
                allow: allow.to_vec(),
            })),
            _ => Err(InputError(
                "give a chunk file or --listen ADDR, one of them".into(),
            )),
        }
    }
}

/// `franka follow` from `chunks` ([`franka_follow`] or [`franka_follow_live`]; `ready`
/// hears the bound address of a socket).
pub fn franka_follow_from(
    chunks: &Chunks,
    exec: &ExecuteSettings,
    settings: &FollowSettings,
    record: Option<&Path>,
    force: bool,
    ready: &dyn Fn(std::net::SocketAddr),
    stop: &StopToken,
) -> Result<(ExecutedTo, Ended), DriveError> {
    match chunks {
        Chunks::File { path, rate_hz } => {
            franka_follow(path, *rate_hz, exec, settings, record, force, stop)
        }
        Chunks::Listen(at) => franka_follow_live(at, exec, settings, record, force, ready, stop),
    }
}

/// Follows the chunks of `file` (targets at `rate_hz`) on the Franka of `exec` under
/// `settings`; writes the recording, its chunks and its report when `record` is given
/// (checked before anything moves). Returns the answer and how it ended: completed, the
/// stream followed to its end; failed, the robot or the connection; or stopped.
pub fn franka_follow(
    file: &Path,
    rate_hz: f64,
    exec: &ExecuteSettings,
    settings: &FollowSettings,
    record: Option<&Path>,
    force: bool,
    stop: &StopToken,
) -> Result<(ExecutedTo, Ended), DriveError> {
    if let Some(r) = record {
        check_record_target(r, force)?;
        check_file_target(&chunks_path(r), FileKind::ChunkCsv, force)?;
    }
    settings.check().map_err(|e| InputError(e.to_string()))?;
    let chunks = cps_movement::chunks::read_chunks(file, 7, rate_hz)?;
    let name = file.display().to_string();
    let mut robot = guarded_arm(exec, Policy::STRICT)?;
    let q0 = robot.joint_positions()?;
    let plan = replay_plan(robot.model(), &q0, DT, &chunks, settings)
        .map_err(|e| InputError(format!("{name}: {e}")))?;
    let mut source = Replay::new(chunks);
    let run: Followed =
        follow(&mut robot, &mut source, Some(&plan), settings, stop).map_err(|e| match e {
            FollowError::Robot(RobotError::Refused { robot, reason }) => DriveError::Refused {
                sentence: format!(
                    "{name}: refused before sending anything: the executor's commands for these chunks from where the arm stands break a limit: {reason}"
                ),
                source: Box::new(RobotError::Refused { robot, reason }),
            },
            other => DriveError::during(&name, other),
        })?;
    let log: ChunkLog = source.into_log();
    let report = FollowReport::new(&run, &log);
    let franka = robot.inner().reports().last().cloned();
    answer(exec, franka, &report, &log, record, None, Vec::new())
}

/// The answer of a run on a Franka: the recording, its chunks and report written when
/// `record` is given; `extra` lines (a socket's counts) after the report's.
fn answer(
    exec: &ExecuteSettings,
    franka: Option<cps_franka::MotionReport>,
    report: &FollowReport,
    log: &ChunkLog,
    record: Option<&Path>,
    streamed: Option<cps_files::replace::Staged>,
    extra: Vec<(String, Value)>,
) -> Result<(ExecutedTo, Ended), DriveError> {
    let executed = Executed {
        host: exec.host.clone(),
        arm: exec.arm,
        report: franka.ok_or_else(|| DriveError::Failed("the robot sent no report".into()))?,
        approach: 0,
        how: "action chunks followed",
    };
    let mut json = executed.json();
    json["chunks"] = report_json(report);
    for (k, v) in &extra {
        json[k] = v.clone();
    }
    let mut more = Vec::new();
    let at = match record {
        Some(r) => {
            write_recording(r, &executed.report.samples, &json)?;
            match streamed {
                // Written as the chunks came back: put in place.
                Some(staged) => {
                    if let Some(e) = &log.unwritten {
                        return Err(DriveError::Failed(format!(
                            "{}: the chunks could not be written ({e}); the recording and its report are written",
                            chunks_path(r).display()
                        )));
                    }
                    staged.commit()?;
                }
                None => {
                    let chunks: Vec<_> = log.entries.iter().map(|(c, _)| c.clone()).collect();
                    let text = cps_movement::chunks::write_chunks(&chunks, 7);
                    cps_outcome::files::write_file(&chunks_path(r), text.as_bytes())?;
                }
            }
            more.push(format!(
                "  chunks as replayed: {}",
                chunks_path(r).display()
            ));
            r.to_path_buf()
        }
        None => "(not recorded: --record)".into(),
    };
    more.extend(report.lines().into_iter().map(|l| format!("  {l}")));
    let ended = ended(&executed.report.ending);
    let executed = ExecutedTo {
        executed,
        record: at,
        report: json,
        more,
    };
    Ok((executed, ended))
}

/// Where a policy in another process reaches the executor (see [`crate::chunk_socket`]).
#[derive(Debug, Clone)]
pub struct Listen {
    /// The address to listen on (loopback unless `allow` names senders).
    pub addr: std::net::SocketAddr,
    /// The senders taken (empty: loopback only).
    pub allow: Vec<std::net::IpAddr>,
}

/// `franka follow --listen`: chunks from a policy in another process, over UDP, followed
/// live on the Franka of `exec` until the policy ends the stream (or stands idle, or
/// `stop`); written as [`franka_follow`] writes. `ready` is told the bound address before
/// the loop starts.
pub fn franka_follow_live(
    listen: &Listen,
    exec: &ExecuteSettings,
    settings: &FollowSettings,
    record: Option<&Path>,
    force: bool,
    ready: &dyn Fn(std::net::SocketAddr),
    stop: &StopToken,
) -> Result<(ExecutedTo, Ended), DriveError> {
    if let Some(r) = record {
        check_record_target(r, force)?;
        check_file_target(&chunks_path(r), FileKind::ChunkCsv, force)?;
    }
    crate::chunk_socket::check_listen(&listen.addr, &listen.allow).map_err(InputError)?;
    let socket = std::net::UdpSocket::bind(listen.addr)
        .map_err(|e| InputError(format!("--listen {}: {e}", listen.addr)))?;
    let bound = socket.local_addr()?;
    let streamed = record.map(|r| stream_chunks(r, force)).transpose()?;
    let mut live = LiveRun::start(&ChunkRobot::Franka(exec.clone()), *settings, stop.clone())?;
    // Each chunk goes to the chunk file as it comes back (or nowhere, unrecorded), and
    // only its times stay: the memory a stream takes is bounded however long it runs.
    let staged = match streamed {
        Some((staged, sink)) => {
            live.feed().stream_to(sink);
            Some(staged)
        }
        None => {
            live.feed().stream_to(Box::new(|_, _| Ok(())));
            None
        }
    };
    ready(bound);
    let served = crate::chunk_socket::serve(&socket, &listen.allow, live.feed(), stop);
    if served.is_err() {
        live.stop(); // the socket failed: the arm brakes to rest, the recording is kept
    }
    let done = live.finish()?;
    let (counts, failure) = match served {
        Ok(c) => (c, None),
        Err(e) => (Default::default(), Some(format!("--listen {bound}: {e}"))),
    };
    let socket_json = json!({
        "address": bound.to_string(), "chunks": counts.chunks, "states": counts.states,
        "foreign": counts.foreign, "refused": counts.refused, "reasons": counts.reasons,
        "failure": failure,
    });
    let (mut a, mut code) = answer(
        exec,
        done.franka,
        &done.report,
        &done.log,
        record,
        staged,
        vec![("socket".into(), socket_json)],
    )?;
    if let Some(f) = &failure {
        a.more.push(format!(
            "  the socket failed: {f}; the arm was braked to rest"
        ));
        code = code.max(Ended::Failed);
    } else if stop.is_stopped() {
        // Stopped (Ctrl-C, SIGTERM), also before any chunk came: the loop may have seen
        // the stream closed before the stop, and ended as if it had ended.
        code = Ended::Stopped;
    }
    a.more.push(format!(
        "  socket {bound}: {} chunks, {} state requests; {} datagrams from senders not allowed, {} refused",
        counts.chunks, counts.states, counts.foreign, counts.refused
    ));
    for r in &counts.reasons {
        a.more.push(format!("    refused: {r}"));
    }
    Ok((a, code))
}

/// The most targets a recorded live stream's chunk file takes: an hour of 30 Hz chunks of
/// 50 targets is 5.4 million (about 0.8 GB of text).
const MAX_CHUNK_ROWS: usize = 10_000_000;

/// The chunk file of a recording, staged beside its place and written as the chunks come
/// back ([`cps_chunks::ChunkFeed::stream_to`]): its header now, then each chunk's rows.
fn stream_chunks(
    record: &Path,
    force: bool,
) -> Result<(cps_files::replace::Staged, cps_chunks::Sink), DriveError> {
    use cps_files::replace::{Output, Shape};
    use std::io::Write;
    let shape = Shape::file(|p| {
        cps_outcome::results_dir::looks_like(p, cps_outcome::results_dir::FileKind::ChunkCsv)
    });
    let staged = Output::new(&chunks_path(record), "chunk file", shape, force)
        .stage()
        .map_err(InputError::from)?;
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(staged.path())
        .map_err(|e| DriveError::during(staged.path().display().to_string(), e))?;
    let mut out = std::io::BufWriter::new(file);
    writeln!(out, "{}", cps_movement::chunks::header(7))
        .map_err(|e| DriveError::during(staged.path().display().to_string(), e))?;
    // A sender flooding the socket must not fill the disk either: the file stops at its
    // ceiling, and the run says so (the recording and its report are still written).
    let mut rows = 0usize;
    let sink: cps_chunks::Sink = Box::new(move |i, c| {
        rows += c.targets.len();
        if rows > MAX_CHUNK_ROWS {
            return Err(std::io::Error::other(format!(
                "the chunk file reached {MAX_CHUNK_ROWS} targets: a sender floods the stream"
            )));
        }
        cps_movement::chunks::write_chunk(&mut out, i, c)?;
        out.flush()
    });
    Ok((staged, sink))
}

/// Which robot a live chunk stream drives.
#[derive(Debug, Clone)]
pub enum ChunkRobot {
    /// A Franka over the Franka Control Interface (its own clock paces the loop).
    Franka(ExecuteSettings),
    /// The arm simulated with its dynamics (franky-sim's PD and drives), with the Franka
    /// Hand, from `start` (default its ready pose), held to the wall clock.
    Dynamics {
        /// Which arm.
        arm: cps_franka::limits::Arm,
        /// Where it starts (rad).
        start: Option<Vec<f64>>,
        /// The world its commands are checked in (see [`ExecuteSettings::world`]).
        world: Option<std::sync::Arc<cps_robot::Shapes>>,
    },
    /// The in-process robot (it does what it is told), held to the wall clock.
    Kinematic {
        /// Which arm.
        arm: cps_franka::limits::Arm,
        /// Where it starts (rad).
        start: Option<Vec<f64>>,
        /// The world its commands are checked in (see [`ExecuteSettings::world`]).
        world: Option<std::sync::Arc<cps_robot::Shapes>>,
    },
}

/// The robot of a live run, behind its guard.
enum Opened {
    Franka(Box<cps_robot::Guarded<cps_franka::FrankaRobot>>),
    Simulated(Box<cps_robot::Guarded<Box<dyn Robot>>>),
}

impl ChunkRobot {
    fn open(&self) -> Result<Opened, DriveError> {
        let simulated = |arm: cps_franka::limits::Arm,
                         start: &Option<Vec<f64>>,
                         world: &Option<std::sync::Arc<cps_robot::Shapes>>,
                         dynamics: bool| {
            let model = crate::franka::in_world(
                cps_movement::robot_file::load_robot(arm.name(), Some("hand"), None)?,
                world.as_ref(),
            );
            let start = start.clone().unwrap_or_else(|| model.ready.clone());
            if start.len() != 7 || start.iter().any(|x| !x.is_finite()) {
                return Err(DriveError::from(InputError(
                    "start: seven finite joint positions (rad)".into(),
                )));
            }
            let robot: Box<dyn Robot> = if dynamics {
                cps_dynamics::open(model, &start, &cps_dynamics::DynamicsOptions::default())?
            } else {
                Box::new(
                    cps_robot::KinematicRobot::of_model(model, &start, DT)
                        .map_err(|e| InputError(format!("start: {e}")))?,
                )
            };
            let guarded = cps_robot::Guarded::new(robot, Policy::STRICT);
            Ok(Opened::Simulated(Box::new(guarded)))
        };
        match self {
            ChunkRobot::Franka(s) => Ok(Opened::Franka(Box::new(guarded_arm(s, Policy::STRICT)?))),
            ChunkRobot::Dynamics { arm, start, world } => simulated(*arm, start, world, true),
            ChunkRobot::Kinematic { arm, start, world } => simulated(*arm, start, world, false),
        }
    }
}

/// What a live run did.
#[derive(Debug, Clone)]
pub struct LiveOutcome {
    /// The run: measured joints each period, the commands, the counts.
    pub followed: Followed,
    /// Every chunk with its verdict.
    pub log: ChunkLog,
    /// The report.
    pub report: FollowReport,
    /// A Franka's own report (its samples: q, dq, tau, q_d at 1 kHz; timing).
    pub franka: Option<cps_franka::MotionReport>,
}

type Finished = Result<
    (
        Followed,
        cps_chunks::LiveSource,
        Option<cps_franka::MotionReport>,
    ),
    DriveError,
>;

/// A live chunk stream on a robot: the robot's loop runs on a thread of its own from
/// [`LiveRun::start`]; the caller pushes chunks into [`LiveRun::feed`] and reads the
/// robot's state from it; [`LiveRun::finish`] closes the stream (the last chunk is
/// followed, the arm comes to rest) and returns what happened. Dropping it stops the
/// robot (it brakes to rest).
pub struct LiveRun {
    feed: Option<cps_chunks::ChunkFeed>,
    stop: StopToken,
    handle: Option<std::thread::JoinHandle<Finished>>,
}

impl LiveRun {
    /// Opens `robot` (connects a Franka) and starts its loop, following what the feed
    /// gets. Errors, before anything moves: the settings, the robot's address or start.
    pub fn start(
        robot: &ChunkRobot,
        settings: FollowSettings,
        stop: StopToken,
    ) -> Result<LiveRun, DriveError> {
        settings.check().map_err(|e| InputError(e.to_string()))?;
        let opened = robot.open()?;
        let (feed, source) = cps_chunks::live(7);
        let inner = stop.clone();
        let handle = std::thread::Builder::new()
            .name("cps-chunks".into())
            .spawn(move || -> Finished {
                match opened {
                    Opened::Franka(mut r) => {
                        let mut source = source;
                        let run = follow(r.as_mut(), &mut source, None, &settings, &inner)?;
                        let report = r.inner().reports().last().cloned();
                        Ok((run, source, report))
                    }
                    Opened::Simulated(mut r) => {
                        let mut source = source.paced();
                        let run = follow(&mut r, &mut source, None, &settings, &inner)?;
                        Ok((run, source, None))
                    }
                }
            })
            .map_err(|e| DriveError::during("the robot's loop", e))?;
        Ok(LiveRun {
            feed: Some(feed),
            stop,
            handle: Some(handle),
        })
    }

    /// The policy's end: push chunks, read the robot's state.
    pub fn feed(&mut self) -> &mut cps_chunks::ChunkFeed {
        self.feed.as_mut().expect("the feed lives until finish")
    }

    /// Stops the robot (it brakes to rest within its limits); [`LiveRun::finish`] then
    /// returns what was recorded.
    pub fn stop(&self) {
        self.stop.stop();
    }

    /// Closes the stream, waits for the run to end and returns it with its log and
    /// report.
    pub fn finish(mut self) -> Result<LiveOutcome, DriveError> {
        let mut feed = self.feed.take().expect("finished once");
        feed.close();
        let handle = self.handle.take().expect("finished once");
        let (followed, source, franka) = handle
            .join()
            .map_err(|_| DriveError::Failed("the robot's loop panicked".into()))??;
        let log = feed.into_log(source);
        let report = FollowReport::new(&followed, &log);
        Ok(LiveOutcome {
            followed,
            log,
            report,
            franka,
        })
    }
}

/// Checks, before a live run starts, that its recording may be written at `record`
/// (the recording, its report and its chunk file: none is a directory or another kind of
/// file, and none exists unless `force`).
pub fn check_live_record(record: &Path, force: bool) -> Result<(), DriveError> {
    check_record_target(record, force)?;
    check_file_target(&chunks_path(record), FileKind::ChunkCsv, force)?;
    Ok(())
}

/// Writes a live run at `record` (checked before with [`check_live_record`]): the run at
/// the robot's rate — a Franka's own recording (`t, q, dq, tau, q_d, tool`, as `franka
/// execute` writes it), a simulated arm's measured and commanded joints (`t, q1..q7,
/// q_d1..q_d7`) — its report beside it (`<stem>.report.json`: the chunks' report and the
/// ending) and every chunk as it came (`<stem>.chunks.csv`, a replay file).
pub fn write_live(done: &LiveOutcome, record: &Path) -> Result<(), DriveError> {
    let mut json = json!({
        "ending": done.followed.run.ending.sentence(),
        "chunks": report_json(&done.report),
    });
    match &done.franka {
        Some(franka) => {
            json["franka"] = json!({
                "ending": franka.ending.sentence(),
                "timing": crate::franka::timing_json(franka),
            });
            write_recording(record, &franka.samples, &json)?;
        }
        None => write_table_and_report(record, &simulated_table(&done.followed), &json)?,
    }
    let chunks: Vec<_> = done.log.entries.iter().map(|(c, _)| c.clone()).collect();
    let text = cps_movement::chunks::write_chunks(&chunks, 7);
    cps_outcome::files::write_file(&chunks_path(record), text.as_bytes())?;
    Ok(())
}

/// A simulated arm's run as a table: `t`, the measured joints `q1..q7` and the commands
/// `q_d1..q_d7`, one row per command.
fn simulated_table(followed: &Followed) -> cps_outcome::outcome::Table {
    use cps_outcome::outcome::{Column, Format, Table};
    let run = &followed.run;
    let rows = followed.commands.len().min(run.q.len().saturating_sub(1));
    let mut table = Table::new("recording").with(Column::numbers(
        "t",
        run.time[1..=rows].to_vec(),
        Format::Plain,
    ));
    for j in 0..7 {
        let q = run.q[1..=rows].iter().map(|q| q[j]).collect();
        table.push(Column::numbers(format!("q{}", j + 1), q, Format::Plain));
    }
    for j in 0..7 {
        let c = followed.commands[..rows].iter().map(|c| c[j]).collect();
        table.push(Column::numbers(format!("q_d{}", j + 1), c, Format::Plain));
    }
    table
}

impl Drop for LiveRun {
    fn drop(&mut self) {
        if let Some(h) = self.handle.take() {
            self.stop.stop();
            let _ = h.join();
        }
    }
}
