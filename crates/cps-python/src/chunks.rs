//! `cps.ChunkExecutor`: a learned policy's action chunks followed on a robot from Python
//! in the same process — the robot's loop on a thread of its own (`cps_drive::follow::
//! LiveRun`), chunks pushed from any Python thread as numpy arrays, the robot's state read
//! back, the recording and report when the stream is closed.

use std::sync::Mutex;

use cps_chunks::{Chunk, FollowSettings};
use cps_drive::follow::{ChunkRobot, LiveOutcome, LiveRun, report_json};
use cps_franka::rt::Realtime;
use cps_robot::StopToken;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{array1, array2, matrix, opt_vector};
use crate::errors::{IntoPyErr, choose, failure, value_error};
use crate::experiment::json_to_py;

/// Follows a learned policy's action chunks on a robot, within every limit.
///
/// `ChunkExecutor(robot="dynamics", arm="fr3", host=None, rate=50.0, start=None,
/// stall_timeout=0.25, max_gap=0.2, idle_end=5.0, max_duration=300.0,
/// realtime="enforce", record=None, force=False, limit_share=0.95, scene=None)`: `robot` is
/// `"franka"` (at `host`), `"dynamics"` (the arm with franky-sim's PD and drives,
/// simulated in real time) or `"kinematic"` (it does what it is told); `limit_share` is
/// the share of the robot's velocity, acceleration and jerk limits the executor may use,
/// in (0, 1]; `scene` a scene file (`configs/scenes/`) whose obstacles every command is
/// checked against — a command that would touch one is not sent, the arm is braked and
/// the run ends. The robot's loop starts at once; `push` chunks predicted from `state()`
/// (or `observe()`), and `close()` ends the stream (the last chunk is followed, the arm comes to rest) and
/// returns the recording; with `record` (a path, checked before the loop starts) it is
/// also written there, with its report and chunks beside it, however the run ends. A
/// `with` block closes it; an exception in it stops the robot.
#[pyclass(module = "cps._cps", name = "ChunkExecutor")]
pub struct ChunkExecutor {
    live: Mutex<Option<LiveRun>>,
    rate: f64,
    stop: StopToken,
    /// Where the run is written when it closes.
    record: Option<std::path::PathBuf>,
}

fn outcome<'py>(py: Python<'py>, done: &LiveOutcome) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let run = &done.followed;
    let n = run.commands.len();
    // The measured joints after each command (entry 0 is the start).
    let measured: Vec<f64> = run
        .run
        .q
        .iter()
        .skip(1)
        .take(n)
        .flatten()
        .copied()
        .collect();
    let rows = measured.len() / 7;
    // The robot's own times of those entries.
    d.set_item("t", array1(py, run.run.time[1..=rows].to_vec()))?;
    d.set_item("q", array2(py, measured, rows, 7)?)?;
    let commands: Vec<f64> = run.commands.iter().take(rows).flatten().copied().collect();
    d.set_item("q_d", array2(py, commands, rows, 7)?)?;
    d.set_item("report", json_to_py(py, &report_json(&done.report))?)?;
    d.set_item("lines", done.report.lines())?;
    d.set_item("ending", run.run.ending.sentence())?;
    // Every chunk as it came, with what became of it: the run's replay.
    let chunks = pyo3::types::PyList::empty(py);
    for (c, verdict) in &done.log.entries {
        let e = PyDict::new(py);
        e.set_item("observed_s", c.observed_s)?;
        e.set_item("arrived_s", c.arrived_s)?;
        e.set_item("rate", c.rate_hz)?;
        let h = c.targets.len();
        let flat: Vec<f64> = c.targets.iter().flatten().copied().collect();
        e.set_item("targets", array2(py, flat, h, 7)?)?;
        let v = match verdict {
            Some(cps_chunks::ChunkVerdict::Taken { skipped }) => format!("taken, {skipped} past"),
            Some(cps_chunks::ChunkVerdict::Refused(why)) => format!("refused: {why}"),
            None => "not judged (the run ended)".into(),
        };
        e.set_item("verdict", v)?;
        chunks.append(e)?;
    }
    d.set_item("chunks", chunks)?;
    Ok(d)
}

impl ChunkExecutor {
    fn with_live<T>(&self, f: impl FnOnce(&mut LiveRun) -> PyResult<T>) -> PyResult<T> {
        let mut guard = self
            .live
            .lock()
            .map_err(|_| failure("the executor was poisoned by a panic"))?;
        match guard.as_mut() {
            Some(l) => f(l),
            None => Err(failure("the chunk stream is closed")),
        }
    }
}

#[pymethods]
impl ChunkExecutor {
    #[new]
    #[pyo3(signature = (robot = "dynamics", arm = "fr3", host = None, rate = 50.0, start = None, stall_timeout = 0.25, max_gap = 0.2, idle_end = 5.0, max_duration = 300.0, realtime = "enforce", record = None, force = false, limit_share = 0.95, scene = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        robot: &str,
        arm: &str,
        host: Option<String>,
        rate: f64,
        start: Option<&Bound<'_, PyAny>>,
        stall_timeout: f64,
        max_gap: f64,
        idle_end: f64,
        max_duration: f64,
        realtime: &str,
        record: Option<std::path::PathBuf>,
        force: bool,
        limit_share: f64,
        scene: Option<std::path::PathBuf>,
    ) -> PyResult<Self> {
        if let Some(r) = &record {
            cps_drive::follow::check_live_record(r, force).map_err(|e| e.py_err())?;
        }
        let arm = crate::errors::arm_named(arm)?;
        if !(rate.is_finite() && rate > 0.0) {
            return Err(value_error(format!(
                "rate: {rate} is not a number of targets per second"
            )));
        }
        let start = opt_vector(start, "start", Some(7))?;
        let world = scene
            .map(|p| cps_drive::scene::scene_world(&p, arm))
            .transpose()
            .map_err(|e| e.py_err())?;
        let which = match robot {
            "franka" => {
                let host = host.ok_or_else(|| value_error("host: a Franka needs its address"))?;
                if start.is_some() {
                    return Err(value_error(
                        "start: a Franka starts where it stands; move it there first",
                    ));
                }
                ChunkRobot::Franka(cps_drive::franka::ExecuteSettings {
                    host,
                    arm,
                    retime: false,
                    approach: false,
                    realtime: choose("realtime", realtime, &Realtime::WORDS)?,
                    world,
                })
            }
            "dynamics" => ChunkRobot::Dynamics { arm, start, world },
            "kinematic" => ChunkRobot::Kinematic { arm, start, world },
            other => {
                return Err(value_error(format!(
                    "robot: `{other}` is not franka, dynamics or kinematic"
                )));
            }
        };
        let mut settings = FollowSettings::default();
        settings.chunks.stall_timeout_s = stall_timeout;
        settings.chunks.max_gap_rad = max_gap;
        settings.idle_end_s = idle_end;
        settings.max_duration_s = max_duration;
        settings.limit_share = limit_share;
        let stop = StopToken::new();
        let live = py
            .detach(|| LiveRun::start(&which, settings, stop.clone()))
            .map_err(|e| e.py_err())?;
        Ok(ChunkExecutor {
            live: Mutex::new(Some(live)),
            rate,
            stop,
            record,
        })
    }

    /// The robot's time on the executor's clock (s since its loop started; NaN before
    /// the first period) and its measured joints (rad): what a chunk is predicted from.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<(f64, Bound<'py, PyAny>)> {
        let s = self.with_live(|l| Ok(l.feed().state()))?;
        Ok(match s {
            Some((t, q)) => (t, array1(py, q).into_any()),
            None => (f64::NAN, array1(py, vec![f64::NAN; 7]).into_any()),
        })
    }

    /// Everything the robot measured in its last control period: a dict of `t` (s on the
    /// executor's clock; NaN before the first period), `q` joint positions (rad), `dq`
    /// velocities (rad/s), `tau` torques (N m: a Franka's measured link-side torques, the
    /// simulated drives' torques), and `q_d` the command in force (rad), each (7,).
    fn observe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let seen = self.with_live(|l| Ok(l.feed().observe()))?;
        let d = PyDict::new(py);
        let nan = || vec![f64::NAN; 7];
        let (t, q, dq, tau, q_d) = match seen {
            Some(o) => (o.t, o.q, o.dq, o.tau, o.command),
            None => (f64::NAN, nan(), nan(), nan(), nan()),
        };
        d.set_item("t", t)?;
        d.set_item("q", array1(py, q))?;
        d.set_item("dq", array1(py, dq))?;
        d.set_item("tau", array1(py, tau))?;
        d.set_item("q_d", array1(py, q_d))?;
        Ok(d)
    }

    /// Hands a chunk to the robot's loop: `targets` (H, 7) joint positions (rad) at
    /// `rate` targets per second (default the executor's), predicted from the state at
    /// `observed_at` (the time `state()` gave); `velocities` (H, 7) where the policy
    /// predicts them. A chunk that is not a chunk raises ValueError in a sentence; one
    /// the executor refuses (too far, late, out of range) is in the report.
    #[pyo3(signature = (targets, observed_at, rate = None, velocities = None))]
    fn push(
        &self,
        targets: &Bound<'_, PyAny>,
        observed_at: f64,
        rate: Option<f64>,
        velocities: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let t = matrix(targets, "targets", Some(7), false)?.rows_vec();
        let v = velocities
            .map(|v| matrix(v, "velocities", Some(7), false).map(|m| m.rows_vec()))
            .transpose()?;
        let rate = rate.unwrap_or(self.rate);
        self.with_live(|l| {
            let now = l.feed().state().map_or(observed_at, |(t, _)| t);
            let chunk = Chunk::new(observed_at, now.max(observed_at), rate, t, v, 7)
                .map_err(|e| value_error(format!("the chunk: {e}")))?;
            l.feed().push(chunk).map_err(|e| failure(e.to_string()))
        })
    }

    /// Whether the robot's loop still runs.
    #[getter]
    fn running(&self) -> PyResult<bool> {
        self.with_live(|l| Ok(l.feed().running()))
    }

    /// Stops the robot (it brakes to rest within its limits); `close()` then returns what
    /// was recorded.
    fn stop(&self) {
        self.stop.stop();
    }

    /// Ends the stream: the last chunk is followed to its end, the arm comes to rest, the
    /// run ends. Returns the recording: `t` (n,), `q` measured and `q_d` commanded
    /// (n, 7) at the robot's rate, `report` (chunks taken, refused and why, skipped,
    /// inference delay and jitter, acceleration and jerk peaks at boundaries and
    /// overall, stalls), `lines` (the report in words), `ending`, and `chunks`: every chunk
    /// as it came (`observed_s`, `arrived_s`, `rate`, `targets`, `verdict`), the run's
    /// replay; `record`, where it was written (None without `record`).
    fn close<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let live = self
            .live
            .lock()
            .map_err(|_| failure("the executor was poisoned by a panic"))?
            .take()
            .ok_or_else(|| failure("the chunk stream is already closed"))?;
        let done = py.detach(|| live.finish()).map_err(|e| e.py_err())?;
        if let Some(r) = &self.record {
            py.detach(|| cps_drive::follow::write_live(&done, r))
                .map_err(|e| e.py_err())?;
        }
        let d = outcome(py, &done)?;
        d.set_item(
            "record",
            self.record.as_ref().map(|r| r.display().to_string()),
        )?;
        Ok(d)
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (kind, _value, _traceback))]
    fn __exit__(
        &self,
        py: Python<'_>,
        kind: Option<&Bound<'_, PyAny>>,
        _value: Option<&Bound<'_, PyAny>>,
        _traceback: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        if kind.is_some() {
            self.stop.stop();
        }
        let open = self.live.lock().map(|l| l.is_some()).unwrap_or(false);
        if open {
            self.close(py)?;
        }
        Ok(false)
    }
}

/// The commands the chunk executor makes of a recorded chunk stream, every millisecond
/// from rest at `start` (what `ChunkExecutor` and `cps-cli franka follow` send for it,
/// whatever the robot measures): for tuning a policy's execution offline and comparing
/// with other executors.
///
/// `chunks`: a list of `(observed_s, arrived_s, targets)` with `targets` (H, 7) rad at
/// `rate` targets per second, in the order they came. Returns `t` (n,) and `q_d` (n, 7),
/// the first row `start` at t = 0. Errors (ValueError, in a sentence): a chunk that is not
/// a chunk, a start of the wrong length, a stream that runs longer than `max_duration`.
#[pyfunction]
#[pyo3(signature = (start, chunks, rate = 50.0, arm = "fr3", stall_timeout = 0.25, max_gap = 0.2, max_duration = 300.0))]
#[allow(clippy::too_many_arguments)]
pub fn chunk_commands<'py>(
    py: Python<'py>,
    start: &Bound<'py, PyAny>,
    chunks: Vec<(f64, f64, Bound<'py, PyAny>)>,
    rate: f64,
    arm: &str,
    stall_timeout: f64,
    max_gap: f64,
    max_duration: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let arm = crate::errors::arm_named(arm)?;
    let q0 = crate::arrays::vector(start, "start", Some(7))?;
    let mut list = Vec::with_capacity(chunks.len());
    for (i, (observed, arrived, targets)) in chunks.iter().enumerate() {
        let t = matrix(targets, &format!("chunks[{i}] targets"), Some(7), false)?.rows_vec();
        list.push(
            Chunk::new(*observed, *arrived, rate, t, None, 7)
                .map_err(|e| value_error(format!("chunks[{i}]: {e}")))?,
        );
    }
    let model = cps_movement::robot_file::load_robot(arm.name(), Some("hand"), None)
        .map_err(|e| e.py_err())?;
    let mut settings = FollowSettings::default();
    settings.chunks.stall_timeout_s = stall_timeout;
    settings.chunks.max_gap_rad = max_gap;
    settings.max_duration_s = max_duration;
    let dt = cps_franka::limits::DT;
    let plan = py
        .detach(|| cps_chunks::replay_plan(&model, &q0, dt, &list, &settings))
        .map_err(|e| value_error(e.to_string()))?;
    let limits = cps_chunks::follow_limits(&model, settings.limit_share, &q0)
        .map_err(|e| value_error(e.to_string()))?;
    let n = plan.points().len();
    let d = PyDict::new(py);
    d.set_item(
        "velocity_limits",
        array1(py, limits.iter().map(|l| l.velocity).collect()),
    )?;
    d.set_item(
        "acceleration_limits",
        array1(py, limits.iter().map(|l| l.acceleration).collect()),
    )?;
    d.set_item(
        "jerk_limits",
        array1(py, limits.iter().map(|l| l.jerk).collect()),
    )?;
    d.set_item("t", array1(py, (0..n).map(|k| k as f64 * dt).collect()))?;
    let flat: Vec<f64> = plan.points().iter().flatten().copied().collect();
    d.set_item("q_d", array2(py, flat, n, 7)?)?;
    Ok(d)
}
