//! `cps.lerobot`: LeRobot datasets (format v3.0) from Python — shown, read as
//! demonstrations, written from recordings or arrays — through `cps_movement::lerobot`
//! and `cps_lerobot`, as `cps-cli lerobot` and `imitate DIR` do.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use crate::arrays::{array1, array2, matrix};
use crate::errors::{IntoPyErr, value_error};
use crate::experiment::json_to_py;

/// A dataset's description (`cps-cli lerobot show --json`).
#[pyfunction]
pub fn _lerobot_show(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyAny>> {
    let answer = py
        .detach(|| cps_movement::lerobot::describe(&path))
        .map_err(|e| e.py_err())?;
    json_to_py(py, &serde_json::json!(answer))
}

/// The picked episodes as `(names, [(t, y), …])`.
#[pyfunction]
#[pyo3(signature = (path, episodes=None, feature="observation.state".to_string(), robot=None, columns=None))]
pub fn _lerobot_demos(
    py: Python<'_>,
    path: PathBuf,
    episodes: Option<Vec<usize>>,
    feature: String,
    robot: Option<String>,
    columns: Option<Vec<String>>,
) -> PyResult<Bound<'_, PyTuple>> {
    let pick = cps_movement::lerobot::Pick {
        episodes,
        feature,
        robot,
    };
    let (names, demos) = py
        .detach(|| cps_movement::lerobot::demonstrations(&path, &pick, columns.as_deref()))
        .map_err(|e| e.py_err())?;
    let list = PyList::empty(py);
    for (_, d) in &demos {
        let rows: Vec<f64> = (0..d.len()).flat_map(|k| d.sample(k).to_vec()).collect();
        let y = array2(py, rows, d.len(), d.dims())?;
        list.append(PyTuple::new(
            py,
            [array1(py, d.times().to_vec()).into_any(), y.into_any()],
        )?)?;
    }
    PyTuple::new(py, [names.into_pyobject(py)?.into_any(), list.into_any()])
}

/// Recordings written as a dataset (`cps-cli lerobot write`).
#[pyfunction]
#[pyo3(signature = (out, recordings, robot, task, fps=None, force=false))]
pub fn _lerobot_write(
    py: Python<'_>,
    out: PathBuf,
    recordings: Vec<PathBuf>,
    robot: String,
    task: String,
    fps: Option<u32>,
    force: bool,
) -> PyResult<Bound<'_, PyAny>> {
    let export = cps_movement::lerobot_write::Export { robot, task, fps };
    let answer = py
        .detach(|| cps_movement::lerobot_write::write_recordings(&out, &recordings, &export, force))
        .map_err(|e| e.py_err())?;
    json_to_py(py, &serde_json::json!(answer))
}

/// Episodes given as arrays written as a dataset: `episodes` a list of dicts feature →
/// (frames, entries) array, `names` feature → entry names (its keys in the files' order),
/// `tasks` one per episode.
#[pyfunction]
#[pyo3(signature = (out, episodes, names, fps, tasks, robot_type=None))]
pub fn _lerobot_write_arrays(
    py: Python<'_>,
    out: PathBuf,
    episodes: &Bound<'_, PyList>,
    names: &Bound<'_, PyDict>,
    fps: u32,
    tasks: Vec<String>,
    robot_type: Option<String>,
) -> PyResult<()> {
    let mut features = Vec::new();
    for (k, v) in names.iter() {
        features.push(cps_lerobot::NewFeature {
            name: k.extract()?,
            names: v.extract()?,
        });
    }
    if tasks.len() != episodes.len() {
        return Err(value_error(format!(
            "tasks: one per episode ({} episodes, {} tasks)",
            episodes.len(),
            tasks.len()
        )));
    }
    let mut eps = Vec::new();
    for (e, (item, task)) in episodes.iter().zip(tasks).enumerate() {
        let d = item.cast::<PyDict>().map_err(|_| {
            value_error(format!(
                "episodes[{e}]: a dict of feature → (frames, entries) array"
            ))
        })?;
        let mut values = Vec::new();
        for f in &features {
            let a = d.get_item(&f.name)?.ok_or_else(|| {
                value_error(format!("episodes[{e}]: no `{}` (names gives it)", f.name))
            })?;
            let m = matrix(
                &a,
                &format!("episodes[{e}][{:?}]", f.name),
                Some(f.names.len()),
                false,
            )?;
            values.push(m.rows_vec());
        }
        eps.push(cps_lerobot::NewEpisode { task, values });
    }
    let spec = cps_lerobot::NewDataset {
        fps,
        robot_type,
        features,
    };
    py.detach(|| cps_lerobot::write(&out, &spec, &eps, false))
        .map_err(|e| value_error(e.to_string()))
}
