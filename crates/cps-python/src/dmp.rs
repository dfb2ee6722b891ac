//! DMPs for Python: `DMP` (discrete, both formulations; retargeting, obstacle avoidance),
//! `imitate`, `sequence`, `Trajectory`, `Stepper` (online stepping), `RhythmicDMP` and
//! `QuaternionDMP`. Models are saved and
//! loaded as the JSON files `cps-cli imitate` writes and `cps-cli rollout` reads.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use cps_dmp::{
    Combine, Coupling, Demonstration, DiscreteDmp, DmpConfig, DmpModel, DynamicPotential,
    FitReport, Imitator, Lambda, Method, OnlineDmp, QuaternionDmp, Regression, Retarget,
    RhythmicDmp, SteeringAngle, StepInput,
};
use cps_outcome::results_dir::{FileKind, check_file_targets};
use nalgebra::{Quaternion, UnitQuaternion};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::arrays::{
    array1, array2, is_sequence_of_arrays, matrix, opt_vector, samples_by_dims, vector,
};
use crate::errors::{IntoPyErr, PyResultExt, file_error, named, value_error};
use crate::interrupt::run;

fn lambda(arg: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Lambda>> {
    let Some(arg) = arg.filter(|a| !a.is_none()) else {
        return Ok(None);
    };
    if let Ok(s) = arg.extract::<String>() {
        return if s == "auto" {
            Ok(Some(Lambda::Auto))
        } else {
            Err(value_error(format!(
                "lambda_: \"{s}\" is neither \"auto\" nor a number ≥ 0"
            )))
        };
    }
    match arg.extract::<f64>() {
        Ok(v) => Lambda::fixed(v).map(Some).ok_or_else(|| {
            value_error(format!(
                "lambda_: {v} is neither \"auto\" nor a finite number ≥ 0"
            ))
        }),
        Err(_) => Err(value_error("lambda_: expected \"auto\" or a number ≥ 0")),
    }
}

/// One sampled movement: `t` (samples,), `y`, `yd`, `ydd` (samples, dims). Unpacks as
/// `t, y, yd, ydd = dmp.rollout()`.
#[pyclass(module = "cps._cps", frozen)]
pub struct Trajectory {
    /// Sample times in seconds.
    #[pyo3(get)]
    t: Py<PyArray1<f64>>,
    /// Positions, (samples, dims).
    #[pyo3(get)]
    y: Py<PyArray2<f64>>,
    /// Velocities, (samples, dims).
    #[pyo3(get)]
    yd: Py<PyArray2<f64>>,
    /// Accelerations, (samples, dims).
    #[pyo3(get)]
    ydd: Py<PyArray2<f64>>,
    /// Names of the dimensions.
    #[pyo3(get)]
    names: Vec<String>,
}

impl Trajectory {
    pub(crate) fn of(
        py: Python<'_>,
        traj: &cps_dmp::Trajectory,
        names: Vec<String>,
    ) -> PyResult<Self> {
        let dims = traj.dims();
        Ok(Self {
            t: array1(py, traj.times().to_vec()).unbind(),
            y: samples_by_dims(py, (0..dims).map(|d| traj.position(d)))?.unbind(),
            yd: samples_by_dims(py, (0..dims).map(|d| traj.velocity(d)))?.unbind(),
            ydd: samples_by_dims(py, (0..dims).map(|d| traj.acceleration(d)))?.unbind(),
            names,
        })
    }
}

#[pymethods]
impl Trajectory {
    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let items = PyTuple::new(
            py,
            [
                self.t.bind(py).as_any(),
                self.y.bind(py).as_any(),
                self.yd.bind(py).as_any(),
                self.ydd.bind(py).as_any(),
            ],
        )?;
        items.try_iter().map(Bound::into_any)
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let shape = self.y.bind(py).shape().to_vec();
        format!(
            "Trajectory({} samples × {} dims: {})",
            shape[0],
            shape[1],
            self.names.join(", ")
        )
    }
}

/// Dimension names given by the user, or `y0`, `y1`, … .
pub(crate) fn names_or_default(names: Option<Vec<String>>, dims: usize) -> PyResult<Vec<String>> {
    match names {
        Some(n) if n.len() != dims => Err(value_error(format!(
            "names: {} names for {dims} dimensions",
            n.len()
        ))),
        Some(n) => Ok(n),
        None => Ok((0..dims).map(|d| format!("y{d}")).collect()),
    }
}

/// A discrete DMP with its weights: one transformation system per dimension sharing the
/// phase, the Gaussian basis and τ (Ijspeert et al. 2013; thesis §2.2).
#[pyclass(module = "cps._cps", name = "DMP", frozen)]
pub struct Dmp {
    pub(crate) dmp: DiscreteDmp,
    pub(crate) weights: Vec<f64>,
    pub(crate) names: Vec<String>,
    fit: Option<FitReport>,
    /// Trajectories reused by `rollout_batch`.
    scratch: Mutex<Vec<cps_dmp::Trajectory>>,
}

/// Rollouts per group in `rollout_batch` (the batch kernel's groups are 8 wide).
const BATCH: usize = 16;

impl Dmp {
    /// A DMP object from its parts (names `y0…` when empty).
    pub fn from_parts(dmp: DiscreteDmp, weights: Vec<f64>, names: Vec<String>) -> Self {
        let names = if names.is_empty() {
            (0..dmp.dims()).map(|d| format!("y{d}")).collect()
        } else {
            names
        };
        Self {
            dmp,
            weights,
            names,
            fit: None,
            scratch: Mutex::new(Vec::new()),
        }
    }

    fn model(&self) -> DmpModel {
        DmpModel::new(&self.dmp, &self.weights, self.names.clone())
    }

    fn from_model_text(text: &str, place: &str) -> PyResult<Self> {
        let in_file = |e: cps_dmp::DmpError| value_error(format!("{place}: {e}"));
        let model = DmpModel::from_json(text).map_err(in_file)?;
        let (dmp, weights) = model.to_dmp().map_err(in_file)?;
        Ok(Self::from_parts(dmp, weights, model.names))
    }

    fn weights_from(&self, w: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let (dims, nb) = (self.dmp.dims(), self.dmp.n_basis());
        let m = matrix(w, "weights", Some(nb), false).or_else(|_| {
            // A flat vector of dims × bases values is accepted too.
            let v = vector(w, "weights", Some(dims * nb))?;
            let flat = PyArray1::from_vec(w.py(), v).into_any();
            matrix(
                &flat.call_method1("reshape", ((dims, nb),))?,
                "weights",
                Some(nb),
                false,
            )
        })?;
        if m.rows != dims {
            return Err(value_error(format!(
                "weights: expected shape ({dims}, {nb}) (dims, bases), got ({}, {})",
                m.rows, m.cols
            )));
        }
        Ok(m.floats.values().to_vec())
    }
}

#[pymethods]
impl Dmp {
    #[new]
    #[pyo3(signature = (start, goal, *, tau=1.0, dt=0.01, bases=25, weights=None, formulation="ijspeert", alpha_z=25.0, beta_z=None, alpha_x=None, names=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        start: &Bound<'_, PyAny>,
        goal: &Bound<'_, PyAny>,
        tau: f64,
        dt: f64,
        bases: usize,
        weights: Option<&Bound<'_, PyAny>>,
        formulation: &str,
        alpha_z: f64,
        beta_z: Option<f64>,
        alpha_x: Option<f64>,
        names: Option<Vec<String>>,
    ) -> PyResult<Self> {
        let start = vector(start, "start", None)?;
        let goal = vector(goal, "goal", Some(start.len()))?;
        let config = DmpConfig {
            alpha_z,
            beta_z: beta_z.unwrap_or(alpha_z / 4.0),
            alpha_x: alpha_x.unwrap_or(alpha_z / 3.0),
            formulation: named("formulation", formulation)?,
            ..DmpConfig::new(bases, tau, dt)
        };
        let dmp = DiscreteDmp::new(config, &start, &goal).py()?;
        let names = names_or_default(names, dmp.dims())?;
        let mut out = Self::from_parts(dmp, Vec::new(), names);
        out.weights = match weights {
            Some(w) if !w.is_none() => out.weights_from(w)?,
            _ => vec![0.0; out.dmp.n_weights()],
        };
        Ok(out)
    }

    /// Number of dimensions.
    #[getter]
    fn dims(&self) -> usize {
        self.dmp.dims()
    }

    /// Basis functions per dimension.
    #[getter]
    fn bases(&self) -> usize {
        self.dmp.n_basis()
    }

    /// Duration in seconds.
    #[getter]
    fn tau(&self) -> f64 {
        self.dmp.config().tau
    }

    /// Time step of the grid in seconds (exactly tau / round(tau / dt)).
    #[getter]
    fn dt(&self) -> f64 {
        self.dmp.config().step()
    }

    /// `alpha_z`, `beta_z`, `alpha_x`.
    #[getter]
    fn gains(&self) -> (f64, f64, f64) {
        let c = self.dmp.config();
        (c.alpha_z, c.beta_z, c.alpha_x)
    }

    /// `"ijspeert"` or `"robust"`.
    #[getter]
    fn formulation(&self) -> &'static str {
        self.dmp.config().formulation.name()
    }

    /// Start per dimension.
    #[getter]
    fn start<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.dmp.start().to_vec())
    }

    /// Goal per dimension.
    #[getter]
    fn goal<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.dmp.goal().to_vec())
    }

    /// The weights, (dims, bases).
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        array2(
            py,
            self.weights.clone(),
            self.dmp.dims(),
            self.dmp.n_basis(),
        )
    }

    /// Names of the dimensions.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.names.clone()
    }

    /// The grid's sample times.
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.dmp.times().to_vec())
    }

    /// The fit report of a DMP made by `imitate` (else None): `rmse`, `max_error`,
    /// `lambda`, `integrated_squared_jerk`, `demo_integrated_squared_jerk` (per dimension)
    /// and `condition_number`.
    #[getter]
    fn fit<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(f) = &self.fit else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("rmse", array1(py, f.rmse.clone()))?;
        d.set_item("max_error", array1(py, f.max_error.clone()))?;
        d.set_item("lambda", array1(py, f.lambda.clone()))?;
        d.set_item("condition_number", f.condition_number)?;
        d.set_item(
            "integrated_squared_jerk",
            array1(py, f.integrated_squared_jerk.clone()),
        )?;
        d.set_item(
            "demo_integrated_squared_jerk",
            array1(py, f.demo_integrated_squared_jerk.clone()),
        )?;
        Ok(Some(d))
    }

    /// Rolls the DMP out on its grid: a `Trajectory` (t, y, yd, ydd). `start`, `goal`,
    /// `tau`, `dt` and `weights` replace the model's for this rollout.
    #[pyo3(signature = (*, start=None, goal=None, tau=None, dt=None, weights=None))]
    fn rollout(
        &self,
        py: Python<'_>,
        start: Option<&Bound<'_, PyAny>>,
        goal: Option<&Bound<'_, PyAny>>,
        tau: Option<f64>,
        dt: Option<f64>,
        weights: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Trajectory> {
        let dims = self.dmp.dims();
        let start = opt_vector(start, "start", Some(dims))?;
        let goal = opt_vector(goal, "goal", Some(dims))?;
        let w = match weights {
            Some(w) if !w.is_none() => Some(self.weights_from(w)?),
            _ => None,
        };
        let weights = w.as_deref().unwrap_or(&self.weights);
        let traj = if start.is_none() && goal.is_none() && tau.is_none() && dt.is_none() {
            self.dmp.rollout(weights)
        } else {
            let mut config = *self.dmp.config();
            config.tau = tau.unwrap_or(config.tau);
            config.dt = dt.unwrap_or(config.dt);
            let start = start.as_deref().unwrap_or(self.dmp.start());
            let goal = goal.as_deref().unwrap_or(self.dmp.goal());
            for w in self.dmp.shape_warnings(&self.names, start, goal) {
                let message = w.replace("--formulation robust", "formulation=\"robust\"");
                pyo3::PyErr::warn(
                    py,
                    &py.get_type::<pyo3::exceptions::PyUserWarning>(),
                    &std::ffi::CString::new(message).unwrap_or_default(),
                    1,
                )?;
            }
            let dmp = if config == *self.dmp.config() {
                self.dmp.with_endpoints(start, goal).py()?
            } else {
                DiscreteDmp::new(config, start, goal).py()?
            };
            dmp.rollout(weights)
        };
        Trajectory::of(py, &traj, self.names.clone())
    }

    /// The movement carried to a new `start` and `goal` without distorting it (see
    /// `cps_dmp::Retarget`): `mode="rotate"` (default) turns the shape so its start→goal
    /// direction points at the new goal, size kept; `"similar"` also scales it by the
    /// ratio of the start→goal distances (the whole movement under a similarity
    /// transform); `"translate"` keeps shape and size as they are. Returns a goal-robust
    /// DMP.
    #[pyo3(signature = (start, goal, *, mode="rotate"))]
    fn retarget(
        &self,
        start: &Bound<'_, PyAny>,
        goal: &Bound<'_, PyAny>,
        mode: &str,
    ) -> PyResult<Self> {
        let dims = self.dmp.dims();
        let start = vector(start, "start", Some(dims))?;
        let goal = vector(goal, "goal", Some(dims))?;
        let mode = match mode {
            "rotate" => Retarget::Rotate,
            "similar" => Retarget::Similar,
            "translate" => Retarget::Translate,
            other => {
                return Err(value_error(format!(
                    "mode: `{other}` is not a way to retarget (\"rotate\", \"similar\" or \"translate\")"
                )));
            }
        };
        let moved = self.dmp.retarget(&self.weights, &start, &goal, mode).py()?;
        let mut out = Self::from_parts(moved.dmp, Vec::new(), self.names.clone());
        out.weights = moved.weights;
        Ok(out)
    }

    /// The rollout with point obstacles avoided online: `obstacles` (k, dims) positions
    /// (2 or more dimensions), `avoidance="steering"` (Hoffmann et al. 2009, γ = 1000,
    /// β = 20/π) or `"potential"` (Park et al. 2008, λ = 10, β = 2); `gains=(a, b)`
    /// replaces the two gains.
    #[pyo3(signature = (obstacles, *, avoidance="steering", gains=None))]
    fn rollout_avoiding(
        &self,
        py: Python<'_>,
        obstacles: &Bound<'_, PyAny>,
        avoidance: &str,
        gains: Option<(f64, f64)>,
    ) -> PyResult<Trajectory> {
        let dims = self.dmp.dims();
        let o = matrix(obstacles, "obstacles", Some(dims), false)?;
        let rows: Vec<Vec<f64>> = o
            .floats
            .values()
            .chunks(dims)
            .map(<[f64]>::to_vec)
            .collect();
        let mut terms: Vec<Box<dyn Coupling>> = Vec::new();
        for (i, p) in rows.iter().enumerate() {
            cps_dmp::check_endpoints(
                self.dmp.start(),
                self.dmp.goal(),
                p,
                0.0,
                &format!("obstacles[{i}]"),
            )
            .py()?;
            let term: Box<dyn Coupling> = match (avoidance, gains) {
                ("steering", None) => Box::new(SteeringAngle::new(p).py()?),
                ("steering", Some((g, b))) => Box::new(SteeringAngle::with_gains(p, g, b).py()?),
                ("potential", None) => Box::new(DynamicPotential::new(p).py()?),
                ("potential", Some((l, b))) => {
                    Box::new(DynamicPotential::with_gains(p, l, b).py()?)
                }
                (other, _) => {
                    return Err(value_error(format!(
                        "avoidance: `{other}` is not a coupling term (\"steering\" or \"potential\")"
                    )));
                }
            };
            terms.push(term);
        }
        let all = cps_dmp::Couplings(terms);
        let traj = py.detach(|| self.dmp.rollout_coupled(&self.weights, &all));
        Trajectory::of(py, &traj, self.names.clone())
    }

    /// Rolls out many weight sets at once: `weights` (m, dims, bases) or (m, dims·bases);
    /// returns the positions, (m, samples, dims). The GIL is released meanwhile.
    fn rollout_batch<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let nw = self.dmp.n_weights();
        let np = py.import("numpy")?;
        let flat = np
            .call_method1("reshape", (weights, (-1_i64, nw as i64)))
            .map_err(|e| {
                value_error(format!(
                    "weights: expected shape (m, {}, {}) or (m, {nw}) ({})",
                    self.dmp.dims(),
                    self.dmp.n_basis(),
                    e.value(py)
                ))
            })?;
        let w = matrix(&flat, "weights", Some(nw), false)?;
        let m = w.rows;
        let (ns, dims) = (self.dmp.n_samples(), self.dmp.dims());
        let values = w.floats.values();
        let out = py.detach(|| {
            // Groups of BATCH rollouts into trajectories kept between calls: allocating
            // them anew each call costs more than the rollouts (page faults).
            let mut scratch = self
                .scratch
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            scratch.resize_with(BATCH.min(m), || self.dmp.new_trajectory());
            let mut out = vec![0.0; m * ns * dims];
            for (g, group) in values.chunks(BATCH * nw).enumerate() {
                let trajs = &mut scratch[..group.len() / nw];
                self.dmp.rollout_batch(group, trajs);
                for (j, tr) in trajs.iter().enumerate() {
                    let i = g * BATCH + j;
                    for d in 0..dims {
                        for (k, v) in tr.position(d).iter().enumerate() {
                            out[(i * ns + k) * dims + d] = *v;
                        }
                    }
                }
            }
            out
        });
        PyArray1::from_vec(py, out).reshape([m, ns, dims])
    }

    /// The same DMP with other weights ((dims, bases) or dims·bases values).
    fn with_weights(&self, weights: &Bound<'_, PyAny>) -> PyResult<Self> {
        let mut out = Self::from_parts(self.dmp.clone(), Vec::new(), self.names.clone());
        out.weights = self.weights_from(weights)?;
        Ok(out)
    }

    /// A `Stepper` that runs this DMP one control period at a time.
    #[pyo3(signature = (*, error_gain=1.0))]
    fn stepper(&self, error_gain: f64) -> PyResult<Stepper> {
        if !(error_gain.is_finite() && error_gain >= 0.0) {
            return Err(value_error(format!(
                "error_gain: must be finite and ≥ 0 (got {error_gain})"
            )));
        }
        Ok(Stepper {
            inner: OnlineDmp::new(&self.dmp, &self.weights).with_error_gain(error_gain),
        })
    }

    /// The model as the JSON text of a cps model file.
    fn to_json(&self) -> String {
        self.model().to_json()
    }

    /// A DMP from the JSON text of a cps model file.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        Self::from_model_text(text, "model")
    }

    /// Writes the model file `cps-cli rollout` reads. An existing file is replaced only
    /// with `force=True`, and only if it is a cps model file.
    #[pyo3(signature = (path, *, force=false))]
    fn save(&self, py: Python<'_>, path: PathBuf, force: bool) -> PyResult<()> {
        check_file_targets(&path, FileKind::Model, None, force).map_err(file_error)?;
        let text = self.to_json();
        py.detach(|| cps_outcome::files::write_file(&path, text.as_bytes()))
            .py()
    }

    /// Reads a model file written by `save` or `cps-cli imitate`.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let (model, dmp, weights) = cps_movement::movement::read_model(&path).py()?;
        Ok(Self::from_parts(dmp, weights, model.names))
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let ctor = py.import("cps")?.getattr("DMP")?.getattr("from_json")?;
        let text = slf.get().to_json();
        PyTuple::new(py, [ctor, PyTuple::new(py, [text])?.into_any()])
    }

    fn __repr__(&self) -> String {
        let c = self.dmp.config();
        format!(
            "DMP(dims={}, bases={}, tau={}, dt={}, formulation=\"{}\", names=[{}])",
            self.dmp.dims(),
            c.n_basis,
            c.tau,
            c.step(),
            c.formulation.name(),
            self.names.join(", ")
        )
    }
}

/// A DMP advanced one control period at a time (`step`), with live goal and τ changes,
/// coupling terms and phase stopping.
#[pyclass(module = "cps._cps")]
pub struct Stepper {
    inner: OnlineDmp,
}

#[pymethods]
impl Stepper {
    /// Advances by `dt` seconds. `coupling`: an additive term per dimension (units of the
    /// forcing term), e.g. an obstacle's push; `tracking_error` (metres, ≥ 0) slows the
    /// phase by 1 / (1 + error_gain · e).
    #[pyo3(signature = (dt, *, coupling=None, tracking_error=0.0))]
    fn step(
        &mut self,
        dt: f64,
        coupling: Option<&Bound<'_, PyAny>>,
        tracking_error: f64,
    ) -> PyResult<()> {
        let dims = self.inner.position().len();
        let coupling = opt_vector(coupling, "coupling", Some(dims))?;
        if !(tracking_error.is_finite() && tracking_error >= 0.0) {
            return Err(value_error(format!(
                "tracking_error: must be finite and ≥ 0 (got {tracking_error})"
            )));
        }
        let input = StepInput {
            coupling: coupling.as_deref(),
            tracking_error,
        };
        self.inner.step_with(dt, input).py()
    }

    /// Changes the goal from the next step on.
    fn set_goal(&mut self, goal: &Bound<'_, PyAny>) -> PyResult<()> {
        let goal = vector(goal, "goal", Some(self.inner.position().len()))?;
        self.inner.set_goal(&goal).py()
    }

    /// Changes the duration τ from the next step on.
    fn set_tau(&mut self, tau: f64) -> PyResult<()> {
        self.inner.set_tau(tau).py()
    }

    /// Position per dimension.
    #[getter]
    fn position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.inner.position().to_vec())
    }

    /// Velocity per dimension.
    #[getter]
    fn velocity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.inner.velocity())
    }

    /// Acceleration per dimension.
    #[getter]
    fn acceleration<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.inner.acceleration().to_vec())
    }

    /// The phase x (1 at the start, exp(−alpha_x) at t = tau).
    #[getter]
    fn phase(&self) -> f64 {
        self.inner.phase()
    }

    /// Time since the start in seconds.
    #[getter]
    fn time(&self) -> f64 {
        self.inner.time()
    }

    /// The current goal.
    #[getter]
    fn goal<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.inner.goal().to_vec())
    }

    /// The current duration τ.
    #[getter]
    fn tau(&self) -> f64 {
        self.inner.tau()
    }
}

/// Demonstrations from `t` and `y`: one (t: (n,), y: (n, dims)) pair or lists of them.
fn demonstrations(t: &Bound<'_, PyAny>, y: &Bound<'_, PyAny>) -> PyResult<Vec<Demonstration>> {
    let pairs: Vec<(Bound<'_, PyAny>, Bound<'_, PyAny>)> = if is_sequence_of_arrays(t)? {
        let (ts, ys): (Vec<Bound<'_, PyAny>>, Vec<Bound<'_, PyAny>>) = (
            t.try_iter()?.collect::<PyResult<_>>()?,
            y.try_iter()?.collect::<PyResult<_>>()?,
        );
        if ts.len() != ys.len() {
            return Err(value_error(format!(
                "t and y: {} time arrays for {} position arrays (one pair per demonstration)",
                ts.len(),
                ys.len()
            )));
        }
        ts.into_iter().zip(ys).collect()
    } else {
        vec![(t.clone(), y.clone())]
    };
    let many = pairs.len() > 1;
    let mut demos = Vec::with_capacity(pairs.len());
    let mut dims = None;
    for (i, (t, y)) in pairs.iter().enumerate() {
        let (tn, yn) = if many {
            (format!("t[{i}]"), format!("y[{i}]"))
        } else {
            ("t".to_string(), "y".to_string())
        };
        let times = vector(t, &tn, None)?;
        let m = matrix(y, &yn, None, true)?;
        if m.rows != times.len() {
            return Err(value_error(format!(
                "{yn}: {} samples (rows) for {} time stamps in {tn}",
                m.rows,
                times.len()
            )));
        }
        if let Some(d) = dims
            && d != m.cols
        {
            return Err(value_error(format!(
                "{yn}: {} dimensions, but y[0] has {d}",
                m.cols
            )));
        }
        dims = Some(m.cols);
        let demo = Demonstration::new(times, &m.rows_vec())
            .map_err(|e| value_error(format!("{yn}: {e}")))?;
        demos.push(demo);
    }
    if demos.is_empty() {
        return Err(value_error("t and y: no demonstration given"));
    }
    Ok(demos)
}

/// Imitators (the grid, basis and Gram matrix of a configuration) of the last few
/// configurations used: a notebook imitating again and again with one setting pays for
/// them once. The results are the same bits as with a new one.
static IMITATORS: Mutex<Vec<(DmpConfig, Arc<Imitator>)>> = Mutex::new(Vec::new());

/// How many configurations [`IMITATORS`] keeps.
const IMITATORS_KEPT: usize = 8;

fn imitator(config: DmpConfig) -> Result<Arc<Imitator>, cps_dmp::DmpError> {
    let cache = || {
        IMITATORS
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    };
    if let Some((_, im)) = cache().iter().find(|(c, _)| *c == config) {
        return Ok(Arc::clone(im));
    }
    let im = Arc::new(Imitator::new(DiscreteDmp::new(config, &[0.0], &[1.0])?));
    let mut kept = cache();
    kept.insert(0, (config, Arc::clone(&im)));
    kept.truncate(IMITATORS_KEPT);
    Ok(im)
}

/// Learns a DMP from one demonstration (`t` (n,), `y` (n, dims)) or several (lists of
/// them); the same method, defaults and fit report as `cps-cli imitate`.
#[pyfunction]
#[pyo3(signature = (t, y, *, bases=25, method="ridge", lambda_=None, tau=None, dt=None, formulation="robust", combine="mean", names=None))]
#[allow(clippy::too_many_arguments)]
pub fn imitate(
    py: Python<'_>,
    t: &Bound<'_, PyAny>,
    y: &Bound<'_, PyAny>,
    bases: usize,
    method: &str,
    lambda_: Option<&Bound<'_, PyAny>>,
    tau: Option<f64>,
    dt: Option<f64>,
    formulation: &str,
    combine: &str,
    names: Option<Vec<String>>,
) -> PyResult<Dmp> {
    let demos = demonstrations(t, y)?;
    let regression = named::<Method>("method", method)?.regression(lambda(lambda_)?);
    let combine: Combine = named("combine", combine)?;
    let tau = tau.unwrap_or_else(|| {
        demos.iter().map(Demonstration::duration).sum::<f64>() / demos.len() as f64
    });
    let first = &demos[0];
    let dt = dt.unwrap_or_else(|| first.duration() / (first.len() - 1) as f64);
    let config = DmpConfig {
        formulation: named("formulation", formulation)?,
        ..DmpConfig::new(bases, tau, dt)
    };
    config.validate().py()?;
    let names = names_or_default(names, first.dims())?;
    // The regression's size; generalised cross-validation repeats it per candidate λ.
    let samples: usize = demos.iter().map(Demonstration::len).sum();
    let gcv = matches!(
        regression,
        Regression::Ridge {
            lambda: Lambda::Auto
        } | Regression::JerkRidge {
            lambda: Lambda::Auto
        }
    );
    let size = (samples * bases * first.dims()) as f64 * if gcv { 50.0 } else { 2.0 };
    let fit = run(py, size, |_| {
        imitator(config).and_then(|im| im.imitate(&demos, regression, combine))
    })?
    .map_err(|e| match e {
        // The way past it, in Python's words.
        e @ cps_dmp::DmpError::DegenerateAmplitude { .. } => {
            crate::errors::value_error(format!("{e}: pass formulation=\"robust\""))
        }
        other => other.py_err(),
    })?;
    let mut out = Dmp::from_parts(fit.dmp, fit.weights, names);
    out.fit = Some(fit.report);
    Ok(out)
}

/// A rhythmic (periodic) DMP (Ijspeert et al. 2013; thesis eq. 46/47). One period lasts
/// 2π·tau seconds; scale `amplitude` to scale the oscillation about `anchor`.
#[pyclass(module = "cps._cps", name = "RhythmicDMP")]
pub struct Rhythmic {
    inner: RhythmicDmp,
}

#[pymethods]
impl Rhythmic {
    /// Learns one period from a demonstration (`t` (n,), `y` (n, dims), last sample ≈
    /// first): the period's mean is the anchor, the amplitude 1.
    #[staticmethod]
    #[pyo3(signature = (t, y, *, bases=30, samples=400, lambda_=1e-10))]
    fn learn(
        t: &Bound<'_, PyAny>,
        y: &Bound<'_, PyAny>,
        bases: usize,
        samples: usize,
        lambda_: f64,
    ) -> PyResult<Self> {
        let times = vector(t, "t", None)?;
        let m = matrix(y, "y", None, true)?;
        if m.rows != times.len() {
            return Err(value_error(format!(
                "y: {} samples (rows) for {} time stamps in t",
                m.rows,
                times.len()
            )));
        }
        let inner = RhythmicDmp::learn(&times, &m.rows_vec(), bases, samples, lambda_).py()?;
        Ok(Self { inner })
    }

    /// Rolls out `duration` seconds with time step `dt`: (t, y, yd), y and yd (samples, dims).
    fn rollout<'py>(
        &self,
        py: Python<'py>,
        duration: f64,
        dt: f64,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let r = self.inner.rollout(duration, dt).py()?;
        let y = samples_by_dims(py, r.position.iter().map(Vec::as_slice))?;
        let yd = samples_by_dims(py, r.velocity.iter().map(Vec::as_slice))?;
        PyTuple::new(
            py,
            [array1(py, r.times).into_any(), y.into_any(), yd.into_any()],
        )
    }

    /// Period / 2π in seconds (settable: changes the speed).
    #[getter]
    fn tau(&self) -> f64 {
        self.inner.tau
    }

    #[setter]
    fn set_tau(&mut self, tau: f64) -> PyResult<()> {
        if !(tau.is_finite() && tau > 0.0) {
            return Err(value_error(format!(
                "tau: must be finite and > 0 (got {tau})"
            )));
        }
        self.inner.tau = tau;
        Ok(())
    }

    /// The oscillation's centre per dimension (settable).
    #[getter]
    fn anchor<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.inner.anchor.clone())
    }

    #[setter]
    fn set_anchor(&mut self, v: &Bound<'_, PyAny>) -> PyResult<()> {
        self.inner.anchor = vector(v, "anchor", Some(self.inner.anchor.len()))?;
        Ok(())
    }

    /// Amplitude per dimension (1 after learning; settable).
    #[getter]
    fn amplitude<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.inner.amplitude.clone())
    }

    #[setter]
    fn set_amplitude(&mut self, v: &Bound<'_, PyAny>) -> PyResult<()> {
        self.inner.amplitude = vector(v, "amplitude", Some(self.inner.anchor.len()))?;
        Ok(())
    }

    /// The weights, (dims, bases).
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let dims = self.inner.anchor.len();
        array2(py, self.inner.weights.clone(), dims, self.inner.n_basis)
    }

    fn __repr__(&self) -> String {
        format!(
            "RhythmicDMP(dims={}, bases={}, period={:.6} s)",
            self.inner.anchor.len(),
            self.inner.n_basis,
            self.inner.tau * std::f64::consts::TAU
        )
    }
}

/// A unit quaternion from `[x, y, z, w]` (scipy's order).
fn quaternion(v: &[f64], name: &str) -> PyResult<UnitQuaternion<f64>> {
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm.is_nan() || norm <= 1e-9 {
        return Err(value_error(format!(
            "{name}: a quaternion [x, y, z, w] must not be zero"
        )));
    }
    Ok(UnitQuaternion::from_quaternion(Quaternion::new(
        v[3], v[0], v[1], v[2],
    )))
}

fn xyzw(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.i, q.j, q.k, q.w]
}

/// An orientation DMP on unit quaternions (Ude et al. 2014). Quaternions are `[x, y, z,
/// w]` arrays, scipy's order.
#[pyclass(module = "cps._cps", name = "QuaternionDMP", frozen)]
pub struct Orientation {
    inner: QuaternionDmp,
    weights: Vec<f64>,
}

#[pymethods]
impl Orientation {
    #[new]
    #[pyo3(signature = (start, goal, *, tau=1.0, dt=0.01, bases=25, weights=None))]
    fn new(
        start: &Bound<'_, PyAny>,
        goal: &Bound<'_, PyAny>,
        tau: f64,
        dt: f64,
        bases: usize,
        weights: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let start = quaternion(&vector(start, "start", Some(4))?, "start")?;
        let goal = quaternion(&vector(goal, "goal", Some(4))?, "goal")?;
        let inner = QuaternionDmp::new(DmpConfig::new(bases, tau, dt), start, goal).py()?;
        let weights = match weights {
            Some(w) if !w.is_none() => {
                let m = matrix(w, "weights", Some(bases), false)?;
                if m.rows != 3 {
                    return Err(value_error(format!(
                        "weights: expected shape (3, {bases}), got ({}, {})",
                        m.rows, m.cols
                    )));
                }
                m.floats.values().to_vec()
            }
            _ => vec![0.0; inner.n_weights()],
        };
        Ok(Self { inner, weights })
    }

    /// Learns from an orientation demonstration: `t` (n,), `q` (n, 4) as [x, y, z, w].
    #[staticmethod]
    #[pyo3(signature = (t, q, *, bases=25, tau=None, dt=None, lambda_=1e-10))]
    fn learn(
        t: &Bound<'_, PyAny>,
        q: &Bound<'_, PyAny>,
        bases: usize,
        tau: Option<f64>,
        dt: Option<f64>,
        lambda_: f64,
    ) -> PyResult<Self> {
        let times = vector(t, "t", None)?;
        let m = matrix(q, "q", Some(4), false)?;
        if m.rows != times.len() || times.len() < 3 {
            return Err(value_error(format!(
                "q: {} orientations for {} time stamps (at least 3 needed)",
                m.rows,
                times.len()
            )));
        }
        let qs = (0..m.rows)
            .map(|k| quaternion(m.row(k), &format!("q[{k}]")))
            .collect::<PyResult<Vec<_>>>()?;
        let duration = times[times.len() - 1] - times[0];
        let tau = tau.unwrap_or(duration);
        let dt = dt.unwrap_or(duration / (times.len() - 1) as f64);
        let (inner, weights) =
            QuaternionDmp::learn(DmpConfig::new(bases, tau, dt), &times, &qs, lambda_).py()?;
        Ok(Self { inner, weights })
    }

    /// Rolls out on the grid: (t, q (samples, 4) as [x, y, z, w], omega (samples, 3) rad/s).
    /// `goal` replaces the goal orientation for this rollout.
    #[pyo3(signature = (*, goal=None))]
    fn rollout<'py>(
        &self,
        py: Python<'py>,
        goal: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let r = match opt_vector(goal, "goal", Some(4))? {
            Some(g) => self
                .inner
                .with_goal(quaternion(&g, "goal")?)
                .rollout(&self.weights),
            None => self.inner.rollout(&self.weights),
        };
        let n = r.times.len();
        let q: Vec<f64> = r.orientation.iter().flat_map(xyzw).collect();
        let w: Vec<f64> = r
            .angular_velocity
            .iter()
            .flat_map(|v| [v.x, v.y, v.z])
            .collect();
        PyTuple::new(
            py,
            [
                array1(py, r.times).into_any(),
                array2(py, q, n, 4)?.into_any(),
                array2(py, w, n, 3)?.into_any(),
            ],
        )
    }

    /// Start orientation [x, y, z, w].
    #[getter]
    fn start<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, xyzw(&self.inner.start()).to_vec())
    }

    /// Goal orientation [x, y, z, w].
    #[getter]
    fn goal<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, xyzw(&self.inner.goal()).to_vec())
    }

    /// The weights, (3, bases).
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        array2(py, self.weights.clone(), 3, self.weights.len() / 3)
    }
}

/// Several DMPs run one after the other as one movement, continuous in position,
/// velocity and acceleration at every junction (`junction="c2"`, the default; `"c1"`
/// leaves the acceleration's jump, for comparison). Each later DMP starts where the
/// previous one ends; its goal and duration are its own. Returns a `Trajectory`.
#[pyfunction]
#[pyo3(signature = (dmps, *, junction="c2"))]
pub fn sequence(py: Python<'_>, dmps: Vec<Bound<'_, Dmp>>, junction: &str) -> PyResult<Trajectory> {
    let junction = match junction {
        "c2" => cps_dmp::Junction::C2,
        "c1" => cps_dmp::Junction::C1,
        other => {
            return Err(value_error(format!(
                "junction: `{other}` is not a junction (\"c2\" or \"c1\")"
            )));
        }
    };
    let Some(first) = dmps.first() else {
        return Err(value_error("dmps: give at least one DMP"));
    };
    let names = first.get().names.clone();
    let parts: Vec<(&DiscreteDmp, &[f64])> = dmps
        .iter()
        .map(|d| (&d.get().dmp, d.get().weights.as_slice()))
        .collect();
    let s = py
        .detach(|| cps_dmp::sequence_with(&parts, junction))
        .py()?;
    Trajectory::of(py, &s.trajectory, names)
}
