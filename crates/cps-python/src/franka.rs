//! `cps.Franka`: a Franka over the Franka Control Interface from Python — its state, a
//! joint trajectory executed at 1 kHz and recorded, the state recorded, the arm guided by
//! hand and recorded, the hand.
//! Everything goes through `cps_drive::franka`, as `cps-cli franka` does.

use cps_drive::franka::{self, ExecuteSettings};
use cps_franka::Sample;
use cps_franka::limits::Arm;
use cps_franka::rt::Realtime;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{array1, array2, joint_trajectory, matrix, vector};
use crate::errors::{IntoPyErr, choose, value_error};
use crate::experiment::json_to_py;
use crate::interrupt::detached_keep;

/// A Franka robot (FR3, or a Panda on a protocol-10 system) at `host`.
///
/// `Franka(host, arm="fr3", realtime="enforce", scene=None)`: `realtime="ignore"` runs the
/// 1 kHz loop without SCHED_FIFO where it is not permitted, `"off"` never asks for it;
/// `scene` (a scene file, its robot the arm) checks every command against its obstacles
/// as well as the arm itself. Nothing connects until a method is called; each call
/// connects, does its work and disconnects.
#[pyclass(module = "cps._cps", name = "Franka")]
pub struct Franka {
    host: String,
    arm: Arm,
    realtime: Realtime,
    /// The world every command is checked in (the arm among the scene's obstacles), if a
    /// scene was given.
    world: Option<std::sync::Arc<cps_robot::Shapes>>,
    /// The recording of the last execution that Ctrl-C interrupted.
    last: Option<Py<PyDict>>,
}

/// The recording as a dict of arrays: `t` (n,), `q`, `dq`, `tau`, `q_d` (n, 7), `tool` (n, 3).
fn recording<'py>(py: Python<'py>, samples: &[Sample]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let n = samples.len();
    d.set_item("t", array1(py, samples.iter().map(|s| s.t).collect()))?;
    let seven = |f: fn(&Sample) -> [f64; 7]| samples.iter().flat_map(f).collect::<Vec<f64>>();
    d.set_item("q", array2(py, seven(|s| s.q), n, 7)?)?;
    d.set_item("dq", array2(py, seven(|s| s.dq), n, 7)?)?;
    d.set_item("tau", array2(py, seven(|s| s.tau), n, 7)?)?;
    d.set_item("q_d", array2(py, seven(|s| s.q_c), n, 7)?)?;
    d.set_item(
        "tool",
        array2(py, samples.iter().flat_map(|s| s.tool).collect(), n, 3)?,
    )?;
    Ok(d)
}

/// A recording in memory as the recording's arrays with its `report`, or the error; an
/// interruption (Ctrl-C) is raised after the recording was made.
fn recorded<'py>(
    py: Python<'py>,
    out: Result<(Vec<Sample>, serde_json::Value), cps_drive::DriveError>,
    interrupt: Option<PyErr>,
) -> PyResult<Bound<'py, PyDict>> {
    let (samples, report) = out.map_err(|e| e.py_err())?;
    let d = recording(py, &samples)?;
    d.set_item("report", json_to_py(py, &report)?)?;
    match interrupt {
        Some(e) => Err(e),
        None => Ok(d),
    }
}

/// A Cartesian impedance of `stiffness` (N/m, N m/rad), critically damped, checked.
fn impedance_gains(stiffness: (f64, f64)) -> PyResult<cps_franka::control::CartesianGains> {
    let gains = cps_franka::control::CartesianGains {
        translation: [stiffness.0; 3],
        rotation: [stiffness.1; 3],
        damping_ratio: 1.0,
        nullspace: 5.0,
    };
    cps_franka::control::CartesianImpedance::new(gains, [0.0; 7])
        .map_err(|e| value_error(format!("stiffness: {e}")))?;
    Ok(gains)
}

impl Franka {
    /// This robot with its torques measured at `drive`.
    fn at(&self, drive: &str) -> PyResult<cps_drive::contact::RobotAt> {
        Ok(cps_drive::contact::RobotAt {
            host: self.host.clone(),
            arm: self.arm,
            realtime: self.realtime,
            drive: cps_dynamics::Drive::parse(drive).ok_or_else(|| {
                cps_outcome::InputError(format!(
                    "drive: `{drive}` is not one of {}",
                    cps_dynamics::Drive::NAMES
                ))
                .py_err()
            })?,
            world: self.world.clone(),
        })
    }
}

#[pymethods]
impl Franka {
    #[new]
    #[pyo3(signature = (host, arm = "fr3", realtime = "enforce", scene = None))]
    fn new(
        host: &str,
        arm: &str,
        realtime: &str,
        scene: Option<std::path::PathBuf>,
    ) -> PyResult<Self> {
        if host.trim().is_empty() {
            return Err(value_error("host: give the robot's address"));
        }
        let arm = crate::errors::arm_named(arm)?;
        Ok(Franka {
            host: host.to_string(),
            arm,
            realtime: choose("realtime", realtime, &Realtime::WORDS)?,
            world: (scene.as_deref())
                .map(|s| cps_drive::scene::scene_world(s, arm))
                .transpose()
                .map_err(|e| e.py_err())?,
            last: None,
        })
    }

    /// The robot's address.
    #[getter]
    fn host(&self) -> String {
        self.host.clone()
    }

    /// The recording of the last execution Ctrl-C stopped (the robot braked to rest), or
    /// None.
    #[getter]
    fn last_recording(&self, py: Python<'_>) -> Option<Py<PyDict>> {
        self.last.as_ref().map(|d| d.clone_ref(py))
    }

    fn __repr__(&self) -> String {
        format!("cps.Franka({:?}, arm={:?})", self.host, self.arm.name())
    }

    /// One state as a dict: `q`, `dq`, `tau_J`, `q_d`, `O_T_EE` (column-major 4x4),
    /// `tool_position`, `robot_mode`, `errors`, `control_command_success_rate`.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let host = self.host.clone();
        let state = py.detach(|| franka::state(&host)).map_err(|e| e.py_err())?;
        json_to_py(py, &serde_json::json!(state))
    }

    /// Executes the joint trajectory `q` (n, 7) at times `t` (n,) at 1 kHz: resampled (or
    /// `retime=True`: the fastest timing within 95 % of every limit), checked against the
    /// arm's limits from where the robot is before anything is sent (a `CpsError` naming
    /// joint, time and quantity otherwise; `approach=True` moves to the start first), every
    /// command checked again while streaming. Returns the recording (`t`, `q`, `dq`, `tau`,
    /// `q_d`, `tool` arrays) with `report` (loop timing, tracking, limit usage, `complete`
    /// and how it ended). Ctrl-C brakes the robot to rest within its limits, keeps the
    /// recording in `last_recording` and raises KeyboardInterrupt.
    #[pyo3(signature = (t, q, *, retime = false, approach = false))]
    fn execute<'py>(
        &mut self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        retime: bool,
        approach: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let traj = joint_trajectory(t, q, Some(7))?;
        let prepared =
            franka::prepare_samples("q", &traj, self.arm, retime).map_err(|e| e.py_err())?;
        let settings = ExecuteSettings {
            host: self.host.clone(),
            arm: self.arm,
            retime,
            approach,
            realtime: self.realtime,
            world: self.world.clone(),
        };
        let (done, interrupt) =
            detached_keep(py, None, |stop| franka::execute(&prepared, &settings, stop))?;
        let done = done.map_err(|e| e.py_err())?;
        let d = recording(py, &done.report.samples)?;
        d.set_item("report", json_to_py(py, &done.json())?)?;
        d.set_item("complete", done.complete())?;
        if let Some(e) = interrupt {
            self.last = Some(d.unbind());
            return Err(e);
        }
        Ok(d)
    }

    /// Records the robot's state at its rate for `duration` seconds without moving it (a
    /// robot guided by hand in Desk): the recording's arrays and `report`.
    fn record<'py>(&self, py: Python<'py>, duration: f64) -> PyResult<Bound<'py, PyDict>> {
        let host = self.host.clone();
        let (out, interrupt) = detached_keep(py, None, |stop| {
            franka::record_samples(&host, duration, stop)
        })?;
        recorded(py, out, interrupt)
    }

    /// Teaching by guiding: the arm floats (gravity compensated by the robot, `damping` N m
    /// s/rad on every joint, or cps's light defaults; pushed back before its range ends)
    /// for `duration` seconds while you move it by hand, recorded at the robot's rate: the
    /// recording's arrays and `report`. Ctrl-C ends it early (the arm comes to a damped
    /// rest) and raises KeyboardInterrupt.
    #[pyo3(signature = (duration, *, damping = None))]
    fn guide<'py>(
        &self,
        py: Python<'py>,
        duration: f64,
        damping: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let settings = franka::GuideSettings {
            host: self.host.clone(),
            arm: self.arm,
            realtime: self.realtime,
            seconds: duration,
            damping,
        };
        let (out, interrupt) =
            detached_keep(py, None, |stop| franka::guide_samples(&settings, stop))?;
        recorded(py, out, interrupt)
    }

    /// A movement that touches, in torque mode: move above the surface (`above`, m),
    /// approach along `direction` at `speed` until the estimated force exceeds `detect` N
    /// (at most `search` m), then follow `waypoints` — rows `(t, dx, dy, dz, force)` from
    /// the moment of contact, learned as a DMP over the offset and the force — with the
    /// force held along the direction and the phase slowed by the force error; let go,
    /// lift `retreat` m. A force above `ceiling` drops it and retreats. `drive`: "link" (a
    /// Franka's torque sensors) or "franky-sim". Returns arrays per 1 ms tick (`t`,
    /// `stage`, `target`, `tool`, `force`, `pressing`, `desired`, `phase`) and `summary`.
    #[pyo3(signature = (waypoints, *, above, direction = [0.0, 0.0, -1.0], search = 0.15, speed = 0.03, detect = 3.0, ceiling = 30.0, retreat = 0.05, error_gain = 0.2, stiffness = (2000.0, 150.0), force_gains = (0.2, 5.0, 30.0), drive = "link"))]
    #[allow(clippy::too_many_arguments)]
    fn contact<'py>(
        &self,
        py: Python<'py>,
        waypoints: &Bound<'py, PyAny>,
        above: [f64; 3],
        direction: [f64; 3],
        search: f64,
        speed: f64,
        detect: f64,
        ceiling: f64,
        retreat: f64,
        error_gain: f64,
        stiffness: (f64, f64),
        force_gains: (f64, f64, f64),
        drive: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        use cps_drive::contact::{ContactPlan, ContactWaypoint, ForcePrimitive};
        let rows = matrix(waypoints, "waypoints", Some(5), false)?;
        let points: Vec<ContactWaypoint> = rows
            .rows_vec()
            .iter()
            .map(|r| ContactWaypoint {
                t: r[0],
                offset: [r[1], r[2], r[3]],
                force: r[4],
            })
            .collect();
        let primitive = ForcePrimitive::from_waypoints(&points).map_err(|e| e.py_err())?;
        let gains = impedance_gains(stiffness)?;
        let plan = ContactPlan {
            above,
            direction,
            search,
            speed,
            detect,
            ceiling,
            retreat,
            error_gain,
            gains,
            force_gains,
            sensing: Default::default(),
            primitive,
        };
        plan.check().map_err(|e| e.py_err())?;
        let robot = self.at(drive)?;
        let (out, interrupt) = detached_keep(py, None, |stop| {
            cps_drive::contact::contact_on_robot(&robot, &plan, stop)
        })?;
        let out = out.map_err(|e| e.py_err())?;
        let k = &out.ticks;
        let n = k.len();
        let d = PyDict::new(py);
        d.set_item("t", array1(py, k.iter().map(|x| x.t).collect()))?;
        d.set_item(
            "stage",
            k.iter().map(|x| x.stage.name()).collect::<Vec<_>>(),
        )?;
        let three = |f: fn(&cps_drive::contact::ContactTick) -> [f64; 3]| {
            k.iter().flat_map(f).collect::<Vec<f64>>()
        };
        d.set_item("target", array2(py, three(|x| x.target), n, 3)?)?;
        d.set_item("tool", array2(py, three(|x| x.tool), n, 3)?)?;
        d.set_item("force", array2(py, three(|x| x.force), n, 3)?)?;
        d.set_item(
            "pressing",
            array1(py, k.iter().map(|x| x.pressing).collect()),
        )?;
        d.set_item("desired", array1(py, k.iter().map(|x| x.desired).collect()))?;
        d.set_item("phase", array1(py, k.iter().map(|x| x.phase).collect()))?;
        let (force_rms, peak, path_rms) = out.measures(direction);
        let summary = serde_json::json!({
            "ending": out.ending.sentence(),
            "motion": out.report.ending.sentence(),
            "done": out.ending == cps_drive::contact::ContactEnding::Done,
            "contact_time_s": out.contact.map(|c| c.0),
            "contact_point_m": out.contact.map(|c| c.1),
            "force_rms_error_n": force_rms,
            "peak_force_n": peak,
            "path_rms_error_m": path_rms,
            "loop_p99_us": out.report.timing.p99_us,
        });
        d.set_item("summary", json_to_py(py, &summary)?)?;
        if let Some(e) = interrupt {
            return Err(e);
        }
        Ok(d)
    }

    /// Follows tool positions `positions` (n, 3; m, base frame) at times `t` (n,; from 0)
    /// with a Cartesian impedance in torque mode (`stiffness` = (N/m, N m/rad), critically
    /// damped), the tool's orientation held; the first position within 5 cm of the tool.
    /// Returns the recording's arrays with `target`, `tool_model` (n, 3) and `wrench` (n, 6:
    /// the estimated force and moment the world exerts on the tool), and `report`.
    #[pyo3(signature = (t, positions, *, stiffness = (2000.0, 150.0), drive = "link"))]
    fn impedance<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        positions: &Bound<'py, PyAny>,
        stiffness: (f64, f64),
        drive: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let times = vector(t, "t", None)?;
        let rows = matrix(positions, "positions", Some(3), false)?;
        let points: Vec<[f64; 3]> = rows.rows_vec().iter().map(|r| [r[0], r[1], r[2]]).collect();
        let gains = impedance_gains(stiffness)?;
        let robot = self.at(drive)?;
        let (out, interrupt) = detached_keep(py, None, |stop| {
            cps_drive::contact::follow_with_impedance(&robot, &times, &points, gains, stop.flag())
        })?;
        let out = out.map_err(|e| e.py_err())?;
        let d = recording(py, &out.report.samples)?;
        let n = out.target.len();
        d.set_item(
            "target",
            array2(py, out.target.iter().flatten().copied().collect(), n, 3)?,
        )?;
        d.set_item(
            "tool_model",
            array2(py, out.tool.iter().flatten().copied().collect(), n, 3)?,
        )?;
        d.set_item(
            "wrench",
            array2(py, out.wrench.iter().flatten().copied().collect(), n, 6)?,
        )?;
        let report = serde_json::json!({
            "complete": out.report.ending.complete(),
            "ending": out.report.ending.sentence(),
            "p99_us": out.report.timing.p99_us,
        });
        d.set_item("report", json_to_py(py, &report)?)?;
        if let Some(e) = interrupt {
            return Err(e);
        }
        Ok(d)
    }

    /// The Franka Hand: `action` is "home", "move", "grasp", "stop" or "state"; `width`
    /// (m) for move and grasp. Waits until the fingers settle; returns the hand's state
    /// (`width`, `max_width`, `is_grasped`, `temperature`, and for a grasp `grasped`).
    #[pyo3(signature = (action, width = None, *, speed = 0.05, force = 20.0, epsilon = 0.005))]
    fn gripper<'py>(
        &self,
        py: Python<'py>,
        action: &str,
        width: Option<f64>,
        speed: f64,
        force: f64,
        epsilon: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let command =
            franka::gripper_command(action, width, speed, force, epsilon).map_err(|e| {
                value_error(e.0.replace("--force", "force").replace("--speed", "speed"))
            })?;
        let host = self.host.clone();
        let hand = py
            .detach(|| franka::gripper(&host, command))
            .map_err(|e| e.py_err())?;
        json_to_py(py, &serde_json::json!(hand))
    }
}

/// `cps.identify(recording, *, out, robot="fr3", force=False)`: a robot's joint controller
/// (gains, lag) and drives (rotor inertia, friction) identified from a recording at 1 kHz
/// (`t`, `q1..7`, `dq1..7`, `tau1..7`, `q_d1..7`, as `Franka.execute` and `cps-cli franka
/// execute` write it), its last quarter held back to judge the fit; the calibration is
/// written to `out` for `[robot] calibration`. Returns `{"out", "calibration", "fit"}`
/// as `cps-cli identify --json` prints it.
#[pyfunction]
#[pyo3(signature = (recording, *, out, robot = "fr3", force = false))]
pub fn identify<'py>(
    py: Python<'py>,
    recording: std::path::PathBuf,
    out: std::path::PathBuf,
    robot: &str,
    force: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let robot = robot.to_string();
    let answer = crate::interrupt::detached(py, |stop| {
        cps_drive::identify::identify_recording(&recording, &robot, &out, force, stop)
    })?
    .map_err(|e| e.py_err())?;
    json_to_py(py, &serde_json::json!(answer))
}
