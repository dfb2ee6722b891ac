//! Experiments from Python: `run_experiment(path, …)` runs any experiment file through
//! `cps_experiment::run` — the same entry point, the same numbers as `cps-cli run` — and
//! returns an `Outcome`: the summary as a dict, the tables as numpy columns, the figures'
//! names and captions; with `out=`, the same result directory the command line writes.

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::Mutex;

use cps_experiment::budget::Ceilings;
use cps_experiment::{Event, Observer, RunOptions, experiment};
use cps_outcome::files::table_csv;
use cps_outcome::outcome::{Table as RustTable, Values};
use cps_report::write::{Results, WriteOptions};
use numpy::PyArray1;
use pyo3::exceptions::{PyKeyError, PyRuntimeWarning};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::errors::{IntoPyErr, PyResultExt, file_error, value_error};
use crate::interrupt::{cancelled, detached_keep};

/// JSON text as Python objects (dicts, lists, floats; NaN written as null is None).
pub fn json_to_py<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| value_error(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A named table: columns by name as numpy arrays (numbers: float64, counts and seeds:
/// uint64) or
/// lists of str.
#[pyclass(module = "cps._cps", frozen)]
pub struct Table {
    inner: RustTable,
}

#[pymethods]
impl Table {
    /// The table's name (its CSV file is `<name>.csv`).
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// The column names, in order.
    #[getter]
    fn columns(&self) -> Vec<String> {
        self.inner.columns.iter().map(|c| c.name.clone()).collect()
    }

    fn __len__(&self) -> usize {
        self.inner.rows()
    }

    fn __contains__(&self, name: &str) -> bool {
        self.inner.column(name).is_some()
    }

    fn __getitem__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let Some(c) = self.inner.column(name) else {
            return Err(PyKeyError::new_err(format!(
                "table `{}` has no column `{name}` (it has: {})",
                self.inner.name,
                self.columns().join(", ")
            )));
        };
        Ok(match &c.values {
            Values::Numbers(v) => PyArray1::from_slice(py, v).into_any(),
            // Counts and seeds: uint64, as written (a seed may exceed int64).
            Values::Integers(v) => PyArray1::from_slice(py, v).into_any(),
            Values::Texts(v) => PyList::new(py, v)?.into_any(),
        })
    }

    /// The columns as a dict, in order.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for c in &self.inner.columns {
            d.set_item(&c.name, self.__getitem__(py, &c.name)?)?;
        }
        Ok(d)
    }

    /// The table as the CSV text the command line writes (same bytes).
    fn to_csv(&self) -> PyResult<String> {
        let bytes = table_csv(&self.inner).py()?;
        String::from_utf8(bytes).map_err(|e| value_error(e.to_string()))
    }

    fn __repr__(&self) -> String {
        format!(
            "Table(\"{}\", {} rows: {})",
            self.inner.name,
            self.inner.rows(),
            self.columns().join(", ")
        )
    }
}

/// What a run produced: `summary` (the fields of summary.json), `tables` (name → Table),
/// `figures` (name, caption), `lines` (what the command line prints), `complete`.
#[pyclass(module = "cps._cps", frozen)]
pub struct Outcome {
    inner: cps_experiment::Outcome,
    plots: bool,
}

#[pymethods]
impl Outcome {
    /// Whether the run finished (False when interrupted or when a simulator failed).
    #[getter]
    fn complete(&self) -> bool {
        self.inner.complete()
    }

    /// Why the run stopped early, when a dependency failed (else None).
    #[getter]
    fn failure(&self) -> Option<String> {
        self.inner.failure().map(str::to_string)
    }

    /// The experiment's kind.
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.header.kind
    }

    /// summary.json's content as a dict: the run header, then the kind's fields.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.inner.summary_json())
    }

    /// The tables by name (each also written as `<name>.csv`).
    #[getter]
    fn tables<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for t in &self.inner.tables {
            d.set_item(&t.name, Table { inner: t.clone() })?;
        }
        Ok(d)
    }

    /// The figures as (name, caption) pairs (drawn as `<name>.png`/`.svg` by `save`).
    #[getter]
    fn figures(&self) -> Vec<(String, String)> {
        self.inner
            .figures
            .iter()
            .map(|f| (f.name.clone(), f.caption.clone()))
            .collect()
    }

    /// The lines `cps-cli run` prints at the end.
    #[getter]
    fn lines(&self) -> Vec<String> {
        self.inner.lines.clone()
    }

    /// Writes the result directory `cps-cli run --out` writes: summary.json, the CSVs,
    /// the figures and report.html. An existing directory is replaced only with
    /// `force=True`, and only the files cps wrote there.
    #[pyo3(signature = (out, *, force=false, figures=None))]
    fn save(
        &self,
        py: Python<'_>,
        out: PathBuf,
        force: bool,
        figures: Option<bool>,
    ) -> PyResult<()> {
        let options = WriteOptions {
            figures: figures.unwrap_or(self.plots),
        };
        let results = Results::prepare(&out, force, options).map_err(file_error)?;
        py.detach(|| results.finish(&self.inner)).py()
    }

    fn __repr__(&self) -> String {
        format!(
            "Outcome(kind=\"{}\", experiment=\"{}\", complete={}, tables=[{}])",
            self.inner.header.kind,
            self.inner.header.experiment,
            if self.inner.complete() {
                "True"
            } else {
                "False"
            },
            self.inner
                .tables
                .iter()
                .map(|t| t.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}

/// The latest progress of a run, for the `progress` callback.
#[derive(Debug, Default, Clone)]
struct Progress {
    planned: u64,
    generations: u64,
    best_so_far: f64,
    sigma: f64,
    stage: String,
    changed: bool,
}

/// The observer of a Python run: the cancel flag, and progress for the callback.
struct PyObserver<'a> {
    cancel: &'a cps_robot::StopToken,
    progress: &'a Mutex<Progress>,
}

impl Observer for PyObserver<'_> {
    fn started(&self, generations: u64) {
        let mut p = self.progress.lock().unwrap_or_else(|e| e.into_inner());
        p.planned = generations;
        p.best_so_far = f64::INFINITY;
    }

    fn event(&self, event: Event<'_>) -> ControlFlow<()> {
        {
            let mut p = self.progress.lock().unwrap_or_else(|e| e.into_inner());
            match event {
                Event::Generation {
                    best_so_far, sigma, ..
                } => {
                    p.generations += 1;
                    p.best_so_far = p.best_so_far.min(best_so_far);
                    p.sigma = sigma;
                }
                Event::Stage(s) => s.clone_into(&mut p.stage),
                Event::Working => {}
            }
            p.changed = true;
        }
        if cancelled(self.cancel) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
}

/// Runs an experiment file and returns its `Outcome` (see the module docs).
#[pyfunction]
#[pyo3(signature = (path, *, out=None, seed=None, threads=None, force=false, figures=None, max_memory=4.0, max_work=1e13, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn run_experiment(
    py: Python<'_>,
    path: PathBuf,
    out: Option<PathBuf>,
    seed: Option<u64>,
    threads: Option<usize>,
    force: bool,
    figures: Option<bool>,
    max_memory: f64,
    max_work: f64,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<Outcome> {
    let ceilings = Ceilings::new(max_memory, max_work).map_err(|e| {
        value_error(
            e.0.replace("--max-memory", "max_memory")
                .replace("--max-work", "max_work"),
        )
    })?;
    let exp = experiment::load(&path, seed, &ceilings).py()?;
    let options = RunOptions {
        threads,
        ..RunOptions::default()
    };
    options
        .check()
        .map_err(|e| value_error(e.0.replace("--threads", "threads")))?;
    // The output is checked, and its staging directory made, before any work.
    let results = match &out {
        Some(o) => {
            let written = WriteOptions {
                figures: figures.unwrap_or(exp.plots),
            };
            Some(Results::prepare(o, force, written).map_err(file_error)?)
        }
        None => None,
    };
    let shared = Mutex::new(Progress::default());
    let mut report = |py: Python<'_>| -> PyResult<()> {
        let Some(cb) = &progress else { return Ok(()) };
        let p = {
            let mut guard = shared.lock().unwrap_or_else(|e| e.into_inner());
            if !guard.changed {
                return Ok(());
            }
            guard.changed = false;
            guard.clone()
        };
        let d = PyDict::new(py);
        d.set_item("generations", p.generations)?;
        d.set_item("planned", p.planned)?;
        d.set_item("best_so_far", p.best_so_far)?;
        d.set_item("sigma", p.sigma)?;
        d.set_item("stage", p.stage)?;
        cb.call1((d,)).map(|_| ())
    };
    let (result, interrupt) = detached_keep(py, Some(&mut report), |cancel| {
        let observer = PyObserver {
            cancel,
            progress: &shared,
        };
        // A KeyboardInterrupt stops learning after its generation and brakes a robot that
        // moves.
        let options = RunOptions {
            stop: cancel.clone(),
            ..options.clone()
        };
        // The result directory is written, and moved into place, before the interrupt
        // is raised: what was finished is kept.
        cps_experiment::run_into(&exp, &options, &observer, results)
    })?;
    let outcome = match result {
        Ok(o) => o,
        Err(e) => return Err(interrupt.unwrap_or_else(|| e.py_err())),
    };
    if let Some(e) = interrupt {
        return Err(e);
    }
    if let Some(f) = outcome.failure() {
        PyErr::warn(
            py,
            &py.get_type::<PyRuntimeWarning>(),
            &std::ffi::CString::new(format!(
                "the run failed: {f}; the outcome holds what it made (see its summary; complete says whether it finished)"
            ))
            .unwrap_or_default(),
            1,
        )?;
    }
    Ok(Outcome {
        inner: outcome,
        plots: exp.plots,
    })
}
