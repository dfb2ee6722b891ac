//! CMA-ES with pycma's shape: `CMAES(x0, sigma0, inopts)` with `ask`, `tell`, `stop`,
//! `result`, `optimize`, and `fmin(f, x0, sigma0, options, …)` with IPOP/BIPOP restarts —
//! the options under pycma's names, so a pycma user changes one import.

use std::ops::ControlFlow;
use std::sync::Mutex;

use cps_cmaes::{
    Bounds, CandidateError, Cmaes, CmaesConfig, GenerationReport, Objective, ObjectiveError,
    Solution, StopRule, Termination, minimize, minimize_bipop, minimize_ipop,
};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::arrays::{any_floats, array1, array2, matrix, vector};
use crate::errors::{IntoPyErr, PyResultExt, value_error};

/// The options cps's CMA-ES takes, under pycma's names, with pycma's defaults where cps
/// has the same rule. `verbose`, `verb_disp` and `verb_log` are accepted and ignored: cps
/// prints and writes nothing.
const OPTIONS: &[&str] = &[
    "seed",
    "popsize",
    "bounds",
    "maxfevals",
    "maxiter",
    "ftarget",
    "tolfun",
    "tolx",
    "tolupsigma",
    "tolconditioncov",
    "tolflatfitness",
    "CMA_diagonal",
    "CMA_stds",
    "C0",
    "verbose",
    "verb_disp",
    "verb_log",
];

/// Options read from `inopts` and keyword arguments (keywords win).
#[derive(Debug, Clone)]
struct Options {
    seed: u64,
    popsize: Option<usize>,
    bounds: Option<(Vec<f64>, Vec<f64>)>,
    maxfevals: Option<u64>,
    maxiter: Option<u64>,
    ftarget: Option<f64>,
    tolfun: f64,
    tolx: f64,
    tolupsigma: f64,
    tolconditioncov: f64,
    tolflatfitness: u64,
    diagonal: bool,
    stds: Option<Vec<f64>>,
    /// A full initial covariance (cps's own option; pycma has none): n × n, row-major.
    c0: Option<Vec<f64>>,
}

/// A count option: a number ≥ 0 (floats such as 1e4 or inf accepted; inf = no limit).
fn count(v: &Bound<'_, PyAny>, key: &str) -> PyResult<Option<u64>> {
    if v.is_none() {
        return Ok(None);
    }
    let x: f64 = v
        .extract()
        .map_err(|_| value_error(format!("{key}: expected a number")))?;
    if x.is_nan() || x < 0.0 {
        return Err(value_error(format!("{key}: must be ≥ 0 (got {x})")));
    }
    Ok(if x.is_infinite() || x >= u64::MAX as f64 {
        None
    } else {
        Some(x.floor() as u64)
    })
}

fn number(v: &Bound<'_, PyAny>, key: &str) -> PyResult<f64> {
    let x: f64 = v
        .extract()
        .map_err(|_| value_error(format!("{key}: expected a number")))?;
    if x.is_nan() {
        return Err(value_error(format!("{key}: must not be NaN")));
    }
    Ok(x)
}

/// One side of `bounds`: None (open), a number for every coordinate, or one per coordinate.
fn bound_side(v: &Bound<'_, PyAny>, name: &str, n: usize, open: f64) -> PyResult<Vec<f64>> {
    if v.is_none() {
        return Ok(vec![open; n]);
    }
    let a = any_floats(v, name)?;
    match a.shape() {
        [] => Ok(vec![a.values()[0]; n]),
        [m] if *m == n => Ok(a.values().to_vec()),
        [1] => Ok(vec![a.values()[0]; n]),
        other => Err(value_error(format!(
            "{name}: expected None, a number or {n} values, got shape {}",
            crate::arrays::shape_text(other)
        ))),
    }
}

impl Options {
    fn read(
        inopts: Option<&Bound<'_, PyDict>>,
        kwargs: Option<&Bound<'_, PyDict>>,
        n: usize,
    ) -> PyResult<Self> {
        let mut o = Options {
            seed: 1,
            popsize: None,
            bounds: None,
            maxfevals: None,
            maxiter: None,
            ftarget: None,
            tolfun: 1e-11,
            tolx: 1e-11,
            tolupsigma: 1e20,
            tolconditioncov: 1e14,
            tolflatfitness: 0,
            diagonal: false,
            stds: None,
            c0: None,
        };
        for dict in [inopts, kwargs].into_iter().flatten() {
            for (k, v) in dict.iter() {
                let key: String = k
                    .extract()
                    .map_err(|_| value_error("options: keys must be strings"))?;
                o.set(&key, &v, n)?;
            }
        }
        Ok(o)
    }

    fn set(&mut self, key: &str, v: &Bound<'_, PyAny>, n: usize) -> PyResult<()> {
        match key {
            "seed" => {
                self.seed = v.extract().map_err(|_| {
                    value_error("seed: expected an integer between 0 and 2**64 - 1")
                })?;
            }
            "popsize" => {
                self.popsize = match count(v, key)? {
                    Some(p) => Some(p as usize),
                    None if v.is_none() => None,
                    None => return Err(value_error("popsize: must be finite")),
                }
            }
            "bounds" => {
                if v.is_none() {
                    self.bounds = None;
                    return Ok(());
                }
                let sides: Vec<Bound<'_, PyAny>> = v
                    .try_iter()
                    .and_then(|it| it.collect())
                    .map_err(|_| value_error("bounds: expected [lower, upper]"))?;
                let [lower, upper] = sides.as_slice() else {
                    return Err(value_error(format!(
                        "bounds: expected [lower, upper], got {} items",
                        sides.len()
                    )));
                };
                self.bounds = Some((
                    bound_side(lower, "bounds[0]", n, f64::NEG_INFINITY)?,
                    bound_side(upper, "bounds[1]", n, f64::INFINITY)?,
                ));
            }
            "maxfevals" => self.maxfevals = count(v, key)?,
            "maxiter" => self.maxiter = count(v, key)?,
            "ftarget" => {
                self.ftarget = if v.is_none() {
                    None
                } else {
                    Some(number(v, key)?)
                }
            }
            "tolfun" => self.tolfun = number(v, key)?,
            "tolx" => self.tolx = number(v, key)?,
            "tolupsigma" => self.tolupsigma = number(v, key)?,
            "tolconditioncov" => self.tolconditioncov = number(v, key)?,
            "tolflatfitness" => self.tolflatfitness = count(v, key)?.unwrap_or(0),
            "CMA_diagonal" => {
                self.diagonal = v
                    .is_truthy()
                    .map_err(|_| value_error("CMA_diagonal: expected True or False"))?
            }
            "CMA_stds" => {
                self.stds = if v.is_none() {
                    None
                } else {
                    Some(vector(v, "CMA_stds", Some(n))?)
                }
            }
            "C0" => {
                self.c0 = if v.is_none() {
                    None
                } else {
                    let m = matrix(v, "C0", Some(n), false)?;
                    if m.rows != n {
                        return Err(value_error(format!(
                            "C0: expected shape ({n}, {n}), got ({}, {})",
                            m.rows, m.cols
                        )));
                    }
                    Some(m.floats.values().to_vec())
                }
            }
            "verbose" | "verb_disp" | "verb_log" => {}
            other => {
                return Err(value_error(format!(
                    "options: `{other}` is not an option of cps's CMA-ES (it takes: {})",
                    OPTIONS.join(", ")
                )));
            }
        }
        Ok(())
    }

    fn config(&self, sigma0: f64) -> PyResult<CmaesConfig> {
        let bounds = match &self.bounds {
            Some((l, u)) => Some(Bounds::new(l.clone(), u.clone()).py()?),
            None => None,
        };
        Ok(CmaesConfig {
            population: self.popsize,
            bounds,
            separable: self.diagonal,
            initial_scales: self.stds.clone(),
            initial_covariance: self.c0.clone(),
            ..CmaesConfig::new(sigma0, self.seed)
        })
    }

    /// pycma's default termination: its `maxiter` default `100 + 150 (n+3)² / √λ`,
    /// `maxfevals`, `ftarget`, tolfun, tolx, tolstagnation and the safety rules.
    fn rules(&self, n: usize, lambda: usize) -> Vec<StopRule> {
        let default_iter =
            100 + (150.0 * ((n + 3) * (n + 3)) as f64 / (lambda as f64).sqrt()) as u64;
        let mut rules = vec![StopRule::MaxGenerations(
            self.maxiter.unwrap_or(default_iter),
        )];
        if let Some(m) = self.maxfevals {
            rules.push(StopRule::MaxEvaluations(m));
        }
        if let Some(f) = self.ftarget {
            rules.push(StopRule::TargetCost(f));
        }
        if self.tolfun > 0.0 {
            rules.push(StopRule::TolFun(self.tolfun));
        }
        if self.tolx > 0.0 {
            rules.push(StopRule::TolX(self.tolx));
        }
        rules.push(StopRule::Stagnation);
        if self.tolflatfitness > 0 {
            rules.push(StopRule::FlatFitness(self.tolflatfitness));
        }
        rules.push(StopRule::TolUpSigma(self.tolupsigma));
        rules.push(StopRule::ConditionCov(self.tolconditioncov));
        rules.push(StopRule::NoEffectAxis);
        rules.push(StopRule::NoEffectCoord);
        rules
    }
}

/// A fired rule as pycma names it in `stop()`, with its value.
fn stop_entry(py: Python<'_>, t: &Termination) -> PyResult<(&'static str, Py<PyAny>)> {
    let f = |x: f64| x.into_pyobject(py).map(|v| v.into_any().unbind());
    let u = |x: u64| x.into_pyobject(py).map(|v| v.into_any().unbind());
    let yes = || {
        true.into_pyobject(py)
            .map(|v| v.to_owned().into_any().unbind())
    };
    Ok(match t {
        Termination::Interrupted => ("interrupted", yes()?),
        Termination::Ended => ("ended", yes()?),
        Termination::Rule(r) => match r {
            StopRule::MaxGenerations(v) => ("maxiter", u(*v)?),
            StopRule::MaxEvaluations(v) => ("maxfevals", u(*v)?),
            StopRule::TargetCost(v) => ("ftarget", f(*v)?),
            StopRule::TolFun(v) => ("tolfun", f(*v)?),
            StopRule::TolX(v) => ("tolx", f(*v)?),
            StopRule::TolUpSigma(v) => ("tolupsigma", f(*v)?),
            StopRule::ConditionCov(v) => ("tolconditioncov", f(*v)?),
            StopRule::FlatFitness(v) => ("tolflatfitness", u(*v)?),
            StopRule::Stagnation => ("tolstagnation", yes()?),
            StopRule::NoEffectAxis => ("noeffectaxis", yes()?),
            StopRule::NoEffectCoord => ("noeffectcoord", yes()?),
        },
    })
}

fn stop_dict<'py>(py: Python<'py>, t: Option<&Termination>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    if let Some(t) = t {
        let (k, v) = stop_entry(py, t)?;
        d.set_item(k, v)?;
    }
    Ok(d)
}

/// The CMA-ES state, with pycma's ask-and-tell interface (`cps.CMAES`).
#[pyclass(module = "cps._cps", name = "_CMAES", subclass)]
pub struct Es {
    es: Cmaes,
    bounds: Option<Bounds>,
    rules: Vec<StopRule>,
    /// The candidates of the last `ask` (in the box, when bounded), row-major.
    asked: Option<Vec<f64>>,
    best: Option<(Vec<f64>, f64, u64)>,
    interrupted: bool,
}

impl Es {
    fn n(&self) -> usize {
        self.es.parameters().n
    }

    fn lambda(&self) -> usize {
        self.es.parameters().lambda
    }

    fn in_box(&self, x: &[f64]) -> Vec<f64> {
        match &self.bounds {
            Some(b) => {
                let mut out = vec![0.0; x.len()];
                b.transform(x, &mut out);
                out
            }
            None => x.to_vec(),
        }
    }

    fn termination(&self) -> Option<Termination> {
        if self.interrupted {
            return Some(Termination::Interrupted);
        }
        self.es.termination(&self.rules)
    }

    /// `tell` with costs already read.
    fn tell_costs(&mut self, costs: &[f64]) -> PyResult<()> {
        self.es.tell(costs).py()?;
        self.asked = None;
        if let Some((x, f)) = self.es.best()
            && self.best.as_ref().is_none_or(|b| f < b.1)
        {
            let x = self.in_box(x);
            self.best = Some((x, f, self.es.evaluations()));
        }
        Ok(())
    }

    fn asked_or_ask(&mut self) -> &[f64] {
        if self.asked.is_none() {
            let pop = self.es.ask().to_vec();
            let n = self.n();
            let x: Vec<f64> = pop.chunks(n).flat_map(|c| self.in_box(c)).collect();
            self.asked = Some(x);
        }
        self.asked.as_deref().expect("asked above")
    }
}

#[pymethods]
impl Es {
    #[new]
    #[pyo3(signature = (x0, sigma0, inopts=None, **kwargs))]
    fn new(
        x0: &Bound<'_, PyAny>,
        sigma0: f64,
        inopts: Option<&Bound<'_, PyDict>>,
        kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let x0 = vector(x0, "x0", None)?;
        let n = x0.len();
        let options = Options::read(inopts, kwargs, n)?;
        let config = options.config(sigma0)?;
        // CMA-ES searches the unbounded space: start at x0's preimage under the box map.
        let start = match &config.bounds {
            Some(b) => {
                let mut y = vec![0.0; n];
                b.inverse(&x0, &mut y)
                    .map_err(|_| value_error("x0: must lie within bounds (lower ≤ x0 ≤ upper)"))?;
                y
            }
            None => x0,
        };
        let es = Cmaes::new(&config, &start).py()?;
        let rules = options.rules(n, es.parameters().lambda);
        Ok(Self {
            bounds: config.bounds.clone(),
            es,
            rules,
            asked: None,
            best: None,
            interrupted: false,
        })
    }

    /// The next population, (popsize, N). Asking again before `tell` returns the same
    /// candidates.
    fn ask<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (n, lambda) = (self.n(), self.lambda());
        let x = self.asked_or_ask().to_vec();
        array2(py, x, lambda, n)
    }

    /// Updates the distribution from the costs `f` of the candidates `X` of the last
    /// `ask` (lower is better; NaN and inf rank last).
    #[pyo3(name = "tell")]
    fn tell_py(&mut self, x: &Bound<'_, PyAny>, f: &Bound<'_, PyAny>) -> PyResult<()> {
        let (n, lambda) = (self.n(), self.lambda());
        let Some(asked) = &self.asked else {
            return Err(value_error(
                "tell: no population to tell; call ask() first (tell takes the candidates ask returned)",
            ));
        };
        let xs = matrix(x, "X", Some(n), false)?;
        if xs.rows != lambda {
            return Err(value_error(format!(
                "X: {} candidates, the population has {lambda}",
                xs.rows
            )));
        }
        if let Some(k) = (0..lambda).find(|&k| xs.row(k) != &asked[k * n..(k + 1) * n]) {
            return Err(value_error(format!(
                "X: candidate {k} is not the one ask() returned; tell takes the asked candidates, unchanged and in order"
            )));
        }
        let costs = any_floats(f, "f")?;
        if costs.values().len() != lambda || costs.shape().len() > 1 {
            return Err(value_error(format!(
                "f: expected {lambda} costs (one per candidate), got shape {}",
                crate::arrays::shape_text(costs.shape())
            )));
        }
        let costs = costs.values().to_vec();
        self.tell_costs(&costs)
    }

    /// The termination conditions met, as a dict (empty while the run goes on), under
    /// pycma's names: `maxiter`, `maxfevals`, `ftarget`, `tolfun`, `tolx`, `tolstagnation`,
    /// `tolupsigma`, `tolconditioncov`, `noeffectaxis`, `noeffectcoord`, `tolflatfitness`.
    fn stop<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        stop_dict(py, self.termination().as_ref())
    }

    /// Runs ask → f → tell until `stop()` (or `iterations` more generations). `f(x)` is
    /// called per candidate with `*args`; with `vectorized=True`, `f(X)` once per
    /// generation with the (popsize, N) array, returning popsize costs. Ctrl-C stops after
    /// the current generation (KeyboardInterrupt). Returns self.
    #[pyo3(signature = (f, iterations=None, args=None, *, vectorized=false, callback=None))]
    fn optimize<'py>(
        slf: Bound<'py, Self>,
        f: &Bound<'py, PyAny>,
        iterations: Option<u64>,
        args: Option<&Bound<'py, PyTuple>>,
        vectorized: bool,
        callback: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, Self>> {
        let py = slf.py();
        let args = args.cloned().unwrap_or_else(|| PyTuple::empty(py));
        let mut done = 0u64;
        loop {
            // No borrow is held while Python code (f, callback) runs: they may use `es`.
            let (x, n, lambda) = {
                let mut es = slf.borrow_mut();
                if es.termination().is_some() || iterations.is_some_and(|it| done >= it) {
                    break;
                }
                (es.asked_or_ask().to_vec(), es.n(), es.lambda())
            };
            let costs = evaluate(py, f, &args, vectorized, &x, n, lambda)?;
            slf.borrow_mut().tell_costs(&costs)?;
            done += 1;
            if let Some(cb) = callback {
                cb.call1((slf.clone(),))?;
            }
            py.check_signals()?;
        }
        Ok(slf)
    }

    /// `(xbest, fbest, evals_best, evaluations, iterations, xfavorite, stds, stop)`, as
    /// pycma's `result` (wrapped as a named tuple by `cps.CMAES.result`).
    fn _result<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let (xbest, fbest, evals_best) = match &self.best {
            Some((x, f, e)) => (Some(array1(py, x.clone())), *f, *e),
            None => (None, f64::INFINITY, 0),
        };
        let items: Vec<Bound<'py, PyAny>> = vec![
            xbest.into_pyobject(py)?.into_any(),
            fbest.into_pyobject(py)?.into_any(),
            evals_best.into_pyobject(py)?.into_any(),
            self.es.evaluations().into_pyobject(py)?.into_any(),
            self.es.generation().into_pyobject(py)?.into_any(),
            self.mean(py).into_any(),
            self.stds(py).into_any(),
            self.stop(py)?.into_any(),
        ];
        PyTuple::new(py, items)
    }

    /// The distribution mean (pycma's `xfavorite`), in the box when bounded.
    #[getter]
    fn mean<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.in_box(self.es.mean()))
    }

    /// The step size σ.
    #[getter]
    fn sigma(&self) -> f64 {
        self.es.sigma()
    }

    /// σ √C_ii per coordinate.
    #[getter]
    fn stds<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let s = self.es.sigma();
        array1(
            py,
            self.es
                .covariance_diagonal()
                .iter()
                .map(|c| s * c.sqrt())
                .collect(),
        )
    }

    /// The covariance matrix C, (N, N).
    #[getter]
    #[pyo3(name = "C")]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let n = self.n();
        let c = self.es.covariance();
        let values = if c.nrows() == n && c.ncols() == n {
            (0..n * n).map(|k| c[(k / n, k % n)]).collect()
        } else {
            let d = self.es.covariance_diagonal();
            (0..n * n)
                .map(|k| if k / n == k % n { d[k / n] } else { 0.0 })
                .collect()
        };
        array2(py, values, n, n)
    }

    /// Generations done (pycma's `countiter`).
    #[getter]
    fn countiter(&self) -> u64 {
        self.es.generation()
    }

    /// Evaluations told (pycma's `countevals`).
    #[getter]
    fn countevals(&self) -> u64 {
        self.es.evaluations()
    }

    /// The population size λ.
    #[getter]
    fn popsize(&self) -> usize {
        self.lambda()
    }

    /// The dimension.
    #[getter]
    #[pyo3(name = "N")]
    fn dimension(&self) -> usize {
        self.n()
    }
}

/// Costs of the candidates `x` (row-major, `lambda` × `n`) from a Python objective.
fn evaluate(
    py: Python<'_>,
    f: &Bound<'_, PyAny>,
    args: &Bound<'_, PyTuple>,
    vectorized: bool,
    x: &[f64],
    n: usize,
    lambda: usize,
) -> PyResult<Vec<f64>> {
    if vectorized {
        let xs = array2(py, x.to_vec(), lambda, n)?;
        let mut call = vec![xs.into_any()];
        call.extend(args.iter());
        let r = f.call1(PyTuple::new(py, call)?)?;
        let costs = any_floats(&r, "the objective's result")?;
        if costs.values().len() != lambda {
            return Err(value_error(format!(
                "the vectorised objective returned {} values for {lambda} candidates",
                costs.values().len()
            )));
        }
        return Ok(costs.values().to_vec());
    }
    let mut out = Vec::with_capacity(lambda);
    for row in x.chunks(n) {
        let mut call = vec![PyArray1::from_slice(py, row).into_any()];
        call.extend(args.iter());
        let r = f.call1(PyTuple::new(py, call)?)?;
        let c: f64 = r.extract().map_err(|_| {
            value_error(format!(
                "the objective returned {}, not a number",
                r.repr().map_or_else(|_| "?".into(), |s| s.to_string())
            ))
        })?;
        out.push(c);
    }
    Ok(out)
}

/// A Python objective for the Rust driver: called in the calling thread (which holds the
/// GIL), per candidate or once per generation; the first Python error is kept and the
/// run stops.
struct PyObjective {
    f: Py<PyAny>,
    args: Py<PyTuple>,
    vectorized: bool,
    error: Mutex<Option<PyErr>>,
    /// (evaluations, best cost, the evaluation that found it), for `evals_best`.
    tally: Mutex<(u64, f64, u64)>,
}

#[derive(Debug)]
struct Raised;

impl std::fmt::Display for Raised {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("the Python objective raised an exception")
    }
}

impl std::error::Error for Raised {}

impl Objective for PyObjective {
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
        cps_cmaes::evaluate_through_batch(self, x)
    }

    fn evaluate_batch(
        &self,
        xs: &[f64],
        dim: usize,
        out: &mut [f64],
    ) -> Result<(), CandidateError> {
        Python::attach(|py| {
            let f = self.f.bind(py);
            let args = self.args.bind(py);
            match evaluate(py, f, args, self.vectorized, xs, dim, out.len()) {
                Ok(costs) => {
                    out.copy_from_slice(&costs);
                    let mut t = self
                        .tally
                        .lock()
                        .unwrap_or_else(std::sync::PoisonError::into_inner);
                    for &c in &costs {
                        t.0 += 1;
                        if c < t.1 {
                            (t.1, t.2) = (c, t.0);
                        }
                    }
                    Ok(())
                }
                Err(e) => {
                    self.error
                        .lock()
                        .unwrap_or_else(std::sync::PoisonError::into_inner)
                        .get_or_insert(e);
                    Err(CandidateError {
                        index: 0,
                        source: Box::new(Raised),
                    })
                }
            }
        })
    }
}

/// Minimises `objective_function` (or `parallel_objective`, called once per generation
/// with the (popsize, N) array) from `x0` with step size `sigma0` — pycma's `fmin`.
/// `restarts` > 0 restarts with IPOP (population doubled each time), or BIPOP with
/// `bipop=True`. Returns `(xbest, fbest, evals_best, evaluations, iterations, xfavorite,
/// stds, stop)` (a named tuple from `cps.fmin`).
#[pyfunction]
#[pyo3(signature = (objective_function, x0, sigma0, options=None, args=None, restarts=0, bipop=false, incpopsize=2.0, parallel_objective=None))]
#[allow(clippy::too_many_arguments)]
pub fn _fmin<'py>(
    py: Python<'py>,
    objective_function: Option<Bound<'py, PyAny>>,
    x0: &Bound<'py, PyAny>,
    sigma0: f64,
    options: Option<&Bound<'py, PyDict>>,
    args: Option<&Bound<'py, PyTuple>>,
    restarts: usize,
    bipop: bool,
    incpopsize: f64,
    parallel_objective: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyTuple>> {
    let (f, vectorized) = match (
        objective_function.filter(|f| !f.is_none()),
        parallel_objective,
    ) {
        (_, Some(p)) if !p.is_none() => (p, true),
        (Some(f), _) => (f, false),
        _ => {
            return Err(value_error(
                "objective_function: give a function (or parallel_objective=f taking the (popsize, N) array)",
            ));
        }
    };
    if incpopsize != 2.0 {
        return Err(value_error(format!(
            "incpopsize: cps's IPOP doubles the population (incpopsize=2); got {incpopsize}"
        )));
    }
    if restarts > 9 {
        return Err(value_error(format!("restarts: at most 9 (got {restarts})")));
    }
    let x0v = vector(x0, "x0", None)?;
    let n = x0v.len();
    let opts = Options::read(options, None, n)?;
    let config = opts.config(sigma0)?;
    let lambda = config.lambda(n);
    let rules = opts.rules(n, lambda);
    let objective = PyObjective {
        f: f.unbind(),
        args: args.cloned().unwrap_or_else(|| PyTuple::empty(py)).unbind(),
        vectorized,
        error: Mutex::new(None),
        tally: Mutex::new((0, f64::INFINITY, 0)),
    };
    let mut interrupt: Option<PyErr> = None;
    let mut observer = |_: &GenerationReport<'_>| match py.check_signals() {
        Ok(()) => ControlFlow::Continue(()),
        Err(e) => {
            interrupt = Some(e);
            ControlFlow::Break(())
        }
    };
    let result: Result<Solution, _> = if restarts == 0 {
        minimize(&objective, &x0v, &config, &rules, &mut observer)
    } else if bipop {
        minimize_bipop(&objective, &x0v, &config, &rules, restarts, &mut observer).map(|r| r.best)
    } else {
        minimize_ipop(&objective, &x0v, &config, &rules, restarts, &mut observer).map(|r| r.best)
    };
    if let Some(e) = objective
        .error
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .take()
    {
        return Err(e);
    }
    if let Some(e) = interrupt {
        return Err(e);
    }
    let sol = result.map_err(IntoPyErr::py_err)?;
    let evals_best = objective
        .tally
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .2;
    let stop = stop_dict(py, Some(&sol.termination))?;
    let items: Vec<Bound<'py, PyAny>> = vec![
        array1(py, sol.best_x).into_any(),
        sol.best_cost.into_pyobject(py)?.into_any(),
        evals_best.into_pyobject(py)?.into_any(),
        sol.evaluations.into_pyobject(py)?.into_any(),
        sol.generations.into_pyobject(py)?.into_any(),
        array1(py, sol.mean).into_any(),
        array1(py, sol.stds).into_any(),
        stop.into_any(),
    ];
    PyTuple::new(py, items)
}
