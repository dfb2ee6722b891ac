//! `cps.mocap`: motion-capture takes from Python — a take's markers as arrays, and a take
//! made a demonstration (the tool's pose over time) through `cps_movement::mocap`, as
//! `cps-cli mocap import` does.

use std::path::{Path, PathBuf};

use cps_mocap::demo::Words;
use numpy::PyArrayMethods;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{array1, array2};
use crate::errors::IntoPyErr;
use crate::experiment::json_to_py;

/// A take's markers (file units, NaN where missing), residuals, analog channels and
/// rigid bodies.
#[pyfunction]
pub fn _mocap_take<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let t = py
        .detach(|| cps_movement::mocap::read(&path))
        .map_err(|e| e.py_err())?;
    let d = PyDict::new(py);
    let (f, m) = (t.frames, t.markers());
    d.set_item("labels", t.labels.clone())?;
    d.set_item("rate", t.rate)?;
    d.set_item("frames", f)?;
    d.set_item("first_frame", t.first_frame)?;
    d.set_item("units", t.units.clone())?;
    d.set_item("metres_per_unit", t.metres_per_unit)?;
    let xyz: Vec<f64> = t.xyz.iter().flatten().map(|&v| f64::from(v)).collect();
    d.set_item(
        "points",
        numpy::PyArray1::from_vec(py, xyz).reshape([f, m, 3])?,
    )?;
    let r: Vec<f64> = t.residual.iter().map(|&v| f64::from(v)).collect();
    d.set_item("residuals", array2(py, r, f, m)?)?;
    if let Some(a) = &t.analog {
        let a_d = PyDict::new(py);
        a_d.set_item("labels", a.labels.clone())?;
        a_d.set_item("units", a.units.clone())?;
        a_d.set_item("rate", a.rate)?;
        let rows = a.values.len() / a.channels().max(1);
        a_d.set_item("values", array2(py, a.values.clone(), rows, a.channels())?)?;
        d.set_item("analog", a_d)?;
    }
    let bodies = PyDict::new(py);
    for b in &t.rigid_bodies {
        let bd = PyDict::new(py);
        bd.set_item(
            "position",
            array2(py, b.position.iter().flatten().copied().collect(), f, 3)?,
        )?;
        bd.set_item(
            "quaternion",
            array2(py, b.quaternion.iter().flatten().copied().collect(), f, 4)?,
        )?;
        bodies.set_item(&b.name, bd)?;
    }
    d.set_item("rigid_bodies", bodies)?;
    d.set_item("notes", t.notes.clone())?;
    Ok(d)
}

/// A take made a demonstration: `t`, `position`, `quaternion` (`[qx, qy, qz, qw]`) and
/// the report.
#[pyfunction]
#[pyo3(signature = (path, markers = None, *, rigid_body = None, origin = "centroid", axes = None, to_robot = None, y_up = false, max_gap = 10, cutoff = 10.0, outlier_mm = 20.0, frames = None))]
#[allow(clippy::too_many_arguments)]
pub fn _mocap_read<'py>(
    py: Python<'py>,
    path: PathBuf,
    markers: Option<Vec<String>>,
    rigid_body: Option<String>,
    origin: &str,
    axes: Option<Vec<String>>,
    to_robot: Option<PathBuf>,
    y_up: bool,
    max_gap: usize,
    cutoff: Option<f64>,
    outlier_mm: f64,
    frames: Option<(usize, usize)>,
) -> PyResult<Bound<'py, PyDict>> {
    let bad = |m: String| pyo3::exceptions::PyValueError::new_err(m);
    if markers.is_none() && rigid_body.is_none() {
        return Err(bad(
            "read() needs markers=[...] (three or more) or rigid_body=NAME; cps.mocap.take(path) gives the raw markers".into(),
        ));
    }
    let settings = Words {
        markers: markers.unwrap_or_default(),
        rigid_body,
        origin: origin.to_string(),
        axes,
        y_up,
        max_gap,
        cutoff_hz: cutoff.unwrap_or(0.0),
        outlier_mm,
        frames: frames.map(|(a, b)| format!("{a}..{b}")),
    }
    .settings()
    .map_err(|e| bad(e.to_string()))?;
    let demo = py
        .detach(|| {
            cps_movement::mocap::demonstration(&path, &settings, to_robot.as_deref().map(Path::new))
        })
        .map_err(|e| e.py_err())?;
    let d = PyDict::new(py);
    let n = demo.t.len();
    d.set_item("t", array1(py, demo.t.clone()))?;
    d.set_item(
        "position",
        array2(py, demo.position.iter().flatten().copied().collect(), n, 3)?,
    )?;
    d.set_item(
        "quaternion",
        array2(
            py,
            demo.quaternion.iter().flatten().copied().collect(),
            n,
            4,
        )?,
    )?;
    let report = serde_json::to_value(&demo.report).unwrap_or_default();
    d.set_item("report", json_to_py(py, &report)?)?;
    Ok(d)
}
