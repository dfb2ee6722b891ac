//! Via-point learning from Python: `learn_via_points(start, goal, via, …)` with keyword
//! arguments named as in an experiment file's sections, returning a `ViaPointResult`
//! (trajectory, costs, errors, history, the learned DMP).

use std::ops::ControlFlow;

use cps_learn::{
    CostWeights, Parametrisation, Solver, ViaPoint, ViaPointConfig, ViaPointOutcome, ViaPointTask,
    learn_via_points as learn,
};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{array1, opt_vector, vector};
use crate::dmp::{Dmp, Trajectory, names_or_default};
use crate::errors::{PyResultExt, named, value_error};
use crate::interrupt::{cancelled, detached};

/// Via points from `[(time, position), …]` or `[{"time": t, "position": p}, …]`.
fn via_points(via: &Bound<'_, PyAny>, dims: usize) -> PyResult<Vec<ViaPoint>> {
    let mut out = Vec::new();
    for (i, item) in via
        .try_iter()
        .map_err(|_| value_error("via: expected a list of (time, position) pairs"))?
        .enumerate()
    {
        let item = item?;
        let name = format!("via[{i}]");
        let (time, position) = if let Ok(d) = item.cast::<PyDict>() {
            let get = |k: &str| {
                d.get_item(k)?
                    .ok_or_else(|| value_error(format!("{name}: needs the key \"{k}\"")))
            };
            (get("time")?, get("position")?)
        } else {
            let parts: Vec<Bound<'_, PyAny>> = item
                .try_iter()
                .and_then(|it| it.collect())
                .map_err(|_| value_error(format!("{name}: expected (time, position)")))?;
            let [t, p] = <[Bound<'_, PyAny>; 2]>::try_from(parts)
                .map_err(|_| value_error(format!("{name}: expected (time, position)")))?;
            (t, p)
        };
        let time: f64 = time
            .extract()
            .map_err(|_| value_error(format!("{name}.time: expected a number of seconds")))?;
        let position = vector(&position, &format!("{name}.position"), Some(dims))?;
        out.push(ViaPoint { time, position });
    }
    Ok(out)
}

fn cost_weights(cost: Option<&Bound<'_, PyDict>>) -> PyResult<CostWeights> {
    let mut w = CostWeights::thesis();
    if let Some(d) = cost {
        for (k, v) in d.iter() {
            let key: String = k.extract()?;
            let value: f64 = v
                .extract()
                .map_err(|_| value_error(format!("cost[\"{key}\"]: expected a number")))?;
            let slot = match key.as_str() {
                "goal" => &mut w.goal,
                "via" => &mut w.via,
                "final_velocity" => &mut w.final_velocity,
                "acceleration" => &mut w.acceleration,
                "jerk" => &mut w.jerk,
                "obstacle" => &mut w.obstacle,
                other => {
                    return Err(value_error(format!(
                        "cost: `{other}` is not a cost term (the terms: goal, via, final_velocity, acceleration, jerk, obstacle)"
                    )));
                }
            };
            *slot = value;
        }
    }
    Ok(w)
}

/// A via-point learning result: the best repetition's trajectory and numbers, the exact
/// optimum's cost, and the learned DMP.
#[pyclass(module = "cps._cps", frozen)]
pub struct ViaPointResult {
    outcome: ViaPointOutcome,
    names: Vec<String>,
}

#[pymethods]
impl ViaPointResult {
    /// The best repetition's rollout (t, y, yd, ydd).
    #[getter]
    fn trajectory(&self, py: Python<'_>) -> PyResult<Trajectory> {
        Trajectory::of(py, &self.outcome.best_trajectory(), self.names.clone())
    }

    /// The learned DMP (save it, roll it out to a new goal, step it).
    #[getter]
    fn dmp(&self) -> Dmp {
        Dmp::from_parts(
            self.outcome.dmp.clone(),
            self.outcome.best().weights.clone(),
            self.names.clone(),
        )
    }

    /// The best repetition's cost.
    #[getter]
    fn cost(&self) -> f64 {
        self.outcome.best().cost
    }

    /// The cost of the exact least-squares optimum.
    #[getter]
    fn optimum_cost(&self) -> f64 {
        self.outcome.optimum.cost
    }

    /// (cost − optimum) / optimum.
    #[getter]
    fn gap_to_optimum(&self) -> f64 {
        self.outcome.best().gap_to_optimum
    }

    /// The cost term by term: goal, via, final_velocity, acceleration, jerk.
    #[getter]
    fn breakdown<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let b = &self.outcome.best().breakdown;
        let d = PyDict::new(py);
        d.set_item("goal", b.goal)?;
        d.set_item("via", b.via)?;
        d.set_item("final_velocity", b.final_velocity)?;
        d.set_item("acceleration", b.acceleration)?;
        d.set_item("jerk", b.jerk)?;
        Ok(d)
    }

    /// Distance from each via point at its time (metres).
    #[getter]
    fn via_errors<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.outcome.best().errors.via.clone())
    }

    /// Distance from the goal at t = tau.
    #[getter]
    fn goal_error(&self) -> f64 {
        self.outcome.best().errors.goal
    }

    /// Speed at t = tau.
    #[getter]
    fn final_speed(&self) -> f64 {
        self.outcome.best().errors.final_speed
    }

    /// The best repetition's CMA-ES history: arrays `generation`, `best`, `median`,
    /// `best_so_far`, `sigma`.
    #[getter]
    fn history<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let h = &self.outcome.best().history;
        let d = PyDict::new(py);
        let col = |f: fn(&cps_learn::GenerationRecord) -> f64| h.iter().map(f).collect();
        d.set_item("generation", array1(py, col(|r| r.generation as f64)))?;
        d.set_item("best", array1(py, col(|r| r.best)))?;
        d.set_item("median", array1(py, col(|r| r.median)))?;
        d.set_item("best_so_far", array1(py, col(|r| r.best_so_far)))?;
        d.set_item("sigma", array1(py, col(|r| r.sigma)))?;
        Ok(d)
    }

    /// Generations of the best repetition.
    #[getter]
    fn generations(&self) -> u64 {
        self.outcome.best().generations
    }

    /// Evaluations of the best repetition.
    #[getter]
    fn evaluations(&self) -> u64 {
        self.outcome.best().evaluations
    }

    /// Why the best repetition stopped (`tolfun`, `max_generations`, `exact`, …).
    #[getter]
    fn termination(&self) -> String {
        self.outcome.best().termination.clone()
    }

    /// Every repetition: dicts of seed, cost, gap_to_optimum, generations, evaluations,
    /// termination.
    #[getter]
    fn runs<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.outcome
            .runs
            .iter()
            .map(|r| {
                let d = PyDict::new(py);
                d.set_item("seed", r.seed)?;
                d.set_item("cost", r.cost)?;
                d.set_item("gap_to_optimum", r.gap_to_optimum)?;
                d.set_item("generations", r.generations)?;
                d.set_item("evaluations", r.evaluations)?;
                d.set_item("termination", &r.termination)?;
                Ok(d)
            })
            .collect()
    }

    fn __repr__(&self) -> String {
        let b = self.outcome.best();
        format!(
            "ViaPointResult(cost={:.6}, optimum_cost={:.6}, gap={:.2e}, goal_error={:.3e} m, max via error={:.3e} m, termination=\"{}\")",
            b.cost,
            self.outcome.optimum.cost,
            b.gap_to_optimum,
            b.errors.goal,
            b.errors.via.iter().fold(0.0_f64, |a, &v| a.max(v)),
            b.termination
        )
    }
}

/// Learns a movement from `start` to `goal` through `via` points (thesis §4.5.2): DMP
/// weights searched by CMA-ES (or the exact least-squares optimum with `method="exact"`,
/// or Levenberg–Marquardt from the warm start with `method="least_squares"`), the same
/// pipeline as a `kind = "viapoint"` experiment. `evaluation` ("auto", "rollout",
/// "quadratic") is how CMA-ES evaluates candidates; `polish=True` runs
/// Levenberg–Marquardt after CMA-ES.
#[pyfunction]
#[pyo3(signature = (start, goal, via, *, tau=10.0, dt=0.01, bases=25, goal_velocity=None, cost=None, obstacles=None, method="cmaes", parametrisation="anchor_offset", warm_start=false, evaluation="auto", polish=false, sigma0=0.5, population=None, generations=1000, tol_fun=Some(1e-9), repetitions=1, seed=1, threads=None, names=None))]
#[allow(clippy::too_many_arguments)]
pub fn learn_via_points(
    py: Python<'_>,
    start: &Bound<'_, PyAny>,
    goal: &Bound<'_, PyAny>,
    via: &Bound<'_, PyAny>,
    tau: f64,
    dt: f64,
    bases: usize,
    goal_velocity: Option<&Bound<'_, PyAny>>,
    cost: Option<&Bound<'_, PyDict>>,
    obstacles: Option<&Bound<'_, PyAny>>,
    method: &str,
    parametrisation: &str,
    warm_start: bool,
    evaluation: &str,
    polish: bool,
    sigma0: f64,
    population: Option<usize>,
    generations: u64,
    tol_fun: Option<f64>,
    repetitions: usize,
    seed: u64,
    threads: Option<usize>,
    names: Option<Vec<String>>,
) -> PyResult<ViaPointResult> {
    let start = vector(start, "start", None)?;
    let dims = start.len();
    let goal = vector(goal, "goal", Some(dims))?;
    let goal_velocity =
        opt_vector(goal_velocity, "goal_velocity", Some(dims))?.unwrap_or_else(|| vec![0.0; dims]);
    // Obstacles: a list of (position, clearance).
    let mut points = Vec::new();
    if let Some(list) = obstacles {
        for (k, item) in list.try_iter()?.enumerate() {
            let (p, clearance): (Bound<'_, PyAny>, f64) = item?.extract().map_err(|_| {
                value_error(format!("obstacles[{k}]: expected (position, clearance)"))
            })?;
            points.push(cps_learn::PointObstacle {
                position: vector(&p, &format!("obstacles[{k}]"), Some(dims))?,
                clearance,
            });
        }
    }
    let mut weights = cost_weights(cost)?;
    let obstacle_weight_given = cost.is_some_and(|c| c.contains("obstacle").unwrap_or(false));
    if !points.is_empty() && !obstacle_weight_given {
        weights.obstacle = 1e5;
    }
    let task = ViaPointTask {
        start,
        goal,
        goal_velocity,
        via: via_points(via, dims)?,
        dmp: cps_dmp::DmpConfig::new(bases, tau, dt),
        weights,
        obstacles: points,
    };
    let solver: Solver = named("method", method)?;
    let evaluation: cps_learn::Evaluation = named("evaluation", evaluation)?;
    let parametrisation: Parametrisation = named("parametrisation", parametrisation)?;
    // Each setting is checked by its owner (cps-learn), in the words files get too.
    let bad = |e: cps_learn::BadSetting| value_error(e.to_string());
    let sigma0 = ViaPointConfig::check_sigma0(sigma0).map_err(bad)?;
    let population = population
        .map(ViaPointConfig::check_population)
        .transpose()
        .map_err(bad)?;
    let generations = ViaPointConfig::check_generations(generations).map_err(bad)?;
    let tol_fun = match tol_fun {
        Some(t) => ViaPointConfig::check_tol_fun(t).map_err(bad)?,
        None => None,
    };
    let repetitions = ViaPointConfig::check_repetitions(repetitions).map_err(bad)?;
    if let Some(t) = threads
        && !(1..=1024).contains(&t)
    {
        return Err(value_error(format!(
            "threads: must be between 1 and 1024 (got {t})"
        )));
    }
    task.validate().py()?;
    // A three-dimensional task is in the world frame: x, y, z, as the experiments name it.
    let names = match names {
        None if dims == 3 => vec!["x".into(), "y".into(), "z".into()],
        given => names_or_default(given, dims)?,
    };
    let config = ViaPointConfig {
        task,
        parametrisation,
        solver,
        warm_start,
        evaluation,
        polish,
        sigma0,
        population,
        generations,
        tol_fun,
        repetitions,
        seed,
    };
    config
        .check_together()
        .map_err(|e| value_error(e.to_string()))?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        builder = builder.num_threads(t);
    }
    let pool = builder
        .build()
        .map_err(|e| crate::errors::failure(format!("cannot start the worker threads: {e}")))?;
    let outcome = detached(py, |cancel| {
        pool.install(|| {
            learn(&config, &|_, _| {
                if cancelled(cancel) {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            })
        })
    })?
    .py()?;
    Ok(ViaPointResult { outcome, names })
}
