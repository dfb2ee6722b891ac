//! `cps.ros2`: a ROS 2 graph over DDS from Python — a joint trajectory sent to a
//! ros2_control controller, a robot's joint states recorded. Everything goes through
//! `cps_drive::ros2`, as `cps-cli ros2` does.

use cps_drive::ros2::{
    self, GraphSettings, Mapping, MappingChoice, RecordSettings, SendSettings, Via,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{array1, array2, joint_trajectory};
use crate::errors::{IntoPyErr, choose};
use crate::experiment::json_to_py;
use crate::interrupt::detached_keep;

/// Sends the joint trajectory `q` (rows, rad) at times `t` (s) to `controller`.
#[pyfunction]
#[pyo3(signature = (t, q, controller, *, via = "action", robot = "panda", joint_names = None, domain = None, period = 0.01, wait = 10.0, service_mapping = "auto", scene = None))]
#[allow(clippy::too_many_arguments)]
pub fn _ros2_send<'py>(
    py: Python<'py>,
    t: &Bound<'py, PyAny>,
    q: &Bound<'py, PyAny>,
    controller: &str,
    via: &str,
    robot: &str,
    joint_names: Option<Vec<String>>,
    domain: Option<u16>,
    period: f64,
    wait: f64,
    service_mapping: &str,
    scene: Option<std::path::PathBuf>,
) -> PyResult<Bound<'py, PyAny>> {
    let service_mapping = choose(
        "service_mapping",
        service_mapping,
        &[
            ("auto", MappingChoice::Auto),
            ("cyclone", MappingChoice::Force(Mapping::Cyclone)),
            ("fastdds", MappingChoice::Force(Mapping::FastDds)),
        ],
    )?;
    let via = choose(
        "via",
        via,
        &[("action", Via::Action), ("topic", Via::Topic)],
    )?;
    let traj = joint_trajectory(t, q, None)?;
    let settings = SendSettings {
        service_mapping,
        controller: controller.to_string(),
        via,
        graph: GraphSettings {
            robot: robot.to_string(),
            joint_names,
            domain,
            scene,
        },
        period,
        wait,
        record: None,
    };
    let (out, interrupt) = detached_keep(py, None, |stop| {
        ros2::send_trajectory("q", &traj, &settings, stop, |_| {})
    })?;
    let (answer, _) = out.map_err(|e| e.py_err())?;
    match interrupt {
        Some(e) => Err(e),
        None => json_to_py(py, &serde_json::json!(answer)),
    }
}

/// Records `sensor_msgs/JointState` on `topic` for `duration` s from the first message.
#[pyfunction]
#[pyo3(signature = (duration, *, topic = "/joint_states", robot = "panda", joint_names = None, domain = None, wait = 10.0, best_effort = false))]
#[allow(clippy::too_many_arguments)]
pub fn _ros2_record<'py>(
    py: Python<'py>,
    duration: f64,
    topic: &str,
    robot: &str,
    joint_names: Option<Vec<String>>,
    domain: Option<u16>,
    wait: f64,
    best_effort: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let settings = RecordSettings {
        topic: topic.to_string(),
        duration,
        graph: GraphSettings {
            robot: robot.to_string(),
            joint_names,
            domain,
            scene: None,
        },
        wait,
        best_effort,
    };
    let (out, interrupt) = detached_keep(py, None, |stop| {
        ros2::record_in_memory(&settings, stop, |_| {})
    })?;
    let (rec, answer) = out.map_err(|e| e.py_err())?;
    let d = PyDict::new(py);
    let (times, _) = rec.times();
    let n = times.len();
    let dof = rec.joints.len();
    d.set_item("t", array1(py, times))?;
    d.set_item(
        "q",
        array2(
            py,
            rec.positions.iter().flatten().copied().collect(),
            n,
            dof,
        )?,
    )?;
    if !rec.velocities.is_empty() {
        d.set_item(
            "dq",
            array2(
                py,
                rec.velocities.iter().flatten().copied().collect(),
                n,
                dof,
            )?,
        )?;
    }
    d.set_item("joints", rec.joints.clone())?;
    d.set_item("report", json_to_py(py, &serde_json::json!(answer))?)?;
    match interrupt {
        Some(e) => Err(e),
        None => Ok(d),
    }
}

/// What is on the graph after watching it `seconds` s (`cps-cli ros2 graph --json`).
#[pyfunction]
#[pyo3(signature = (*, domain = None, seconds = 2.0))]
pub fn _ros2_graph<'py>(
    py: Python<'py>,
    domain: Option<u16>,
    seconds: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let look = cps_drive::ros2_graph::GraphLook { domain, seconds };
    let (out, interrupt) =
        detached_keep(py, None, |stop| cps_drive::ros2_graph::graph(&look, stop))?;
    let seen = out.map_err(|e| e.py_err())?;
    match interrupt {
        Some(e) => Err(e),
        None => json_to_py(py, &cps_drive::ros2_graph::graph_json(&seen.0)),
    }
}
