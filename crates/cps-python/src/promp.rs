//! ProMPs from Python: `cps.ProMP.fit(demos, bases)`, moments over time, conditioning on
//! via points, seeded samples.

use cps_promp::{Observation, ProMp, ProMpError};
use numpy::{PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{array1, array2, matrix, vector};
use crate::errors::value_error;

/// `(x0, sigma0, C0)` of `search_start`.
type SearchStart<'py> = (
    Bound<'py, numpy::PyArray1<f64>>,
    f64,
    Bound<'py, PyArray2<f64>>,
);

/// Two arrays: positions and velocities.
type Pair<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

fn py_err(e: ProMpError) -> PyErr {
    value_error(e.to_string())
}

/// A probabilistic movement primitive: a Gaussian over basis weights (`cps_promp`).
#[pyclass(module = "cps._cps", name = "ProMP", frozen)]
pub struct PyProMp {
    inner: ProMp,
}

impl PyProMp {
    /// Times as a vector, each within the movement.
    fn times(&self, t: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let times = vector(t, "t", None)?;
        let d = self.inner.duration();
        if let Some(x) = times.iter().find(|x| !(0.0..=d).contains(*x)) {
            return Err(value_error(format!(
                "t: {x} s is outside the movement, 0 to {d} s"
            )));
        }
        Ok(times)
    }

    /// Rows of `dims` values for each time, as a (times, dims) array.
    fn per_time<'py>(
        &self,
        py: Python<'py>,
        times: &[f64],
        f: impl Fn(f64) -> Vec<f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let d = self.inner.dims();
        let flat = times.iter().flat_map(|&t| f(t)).collect();
        array2(py, flat, times.len(), d)
    }
}

#[pymethods]
impl PyProMp {
    /// The ProMP of demonstrations, a list of `(t, y)` with `t` (n,) increasing and `y`
    /// (n, dims); each is time-normalised to `duration` (default: their mean length) and
    /// fitted with `bases` basis functions per dimension.
    #[staticmethod]
    #[pyo3(signature = (demos, *, bases=20, duration=None))]
    fn fit(demos: &Bound<'_, PyAny>, bases: usize, duration: Option<f64>) -> PyResult<Self> {
        let mut data = Vec::new();
        for (k, item) in demos.try_iter()?.enumerate() {
            let item = item?;
            let (t, y): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item
                .extract()
                .map_err(|_| value_error(format!("demos[{k}]: expected a pair (t, y)")))?;
            let t = vector(&t, &format!("demos[{k}] t"), None)?;
            let y = matrix(&y, &format!("demos[{k}] y"), None, false)?;
            data.push((t, y.rows_vec()));
        }
        let duration = duration.unwrap_or_else(|| {
            data.iter()
                .map(|(t, _)| t.last().copied().unwrap_or(0.0) - t.first().copied().unwrap_or(0.0))
                .sum::<f64>()
                / data.len().max(1) as f64
        });
        Ok(PyProMp {
            inner: ProMp::fit(&data, bases, duration).map_err(py_err)?,
        })
    }

    /// Dimensions.
    #[getter]
    fn dims(&self) -> usize {
        self.inner.dims()
    }

    /// Basis functions per dimension.
    #[getter]
    fn bases(&self) -> usize {
        self.inner.bases()
    }

    /// Duration (s).
    #[getter]
    fn duration(&self) -> f64 {
        self.inner.duration()
    }

    /// The weight mean (dimension-major), shape (dims·bases,).
    #[getter]
    fn weight_mean<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        array1(py, self.inner.weight_mean().to_vec())
    }

    /// The weight covariance, shape (dims·bases, dims·bases).
    #[getter]
    fn weight_cov<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let c = self.inner.weight_cov();
        array2(py, c.transpose().as_slice().to_vec(), c.nrows(), c.ncols())
    }

    /// `(Φ, Φ̇)` at time `t`: position = Φ w, velocity = Φ̇ w; each (dims, dims·bases).
    fn features<'py>(&self, py: Python<'py>, t: f64) -> PyResult<Pair<'py>> {
        let (p, v) = self.inner.features(t);
        let out = |m: nalgebra::DMatrix<f64>| {
            array2(py, m.transpose().as_slice().to_vec(), m.nrows(), m.ncols())
        };
        Ok((out(p)?, out(v)?))
    }

    /// Mean position and velocity at the times `t`: two (len(t), dims) arrays.
    fn mean<'py>(&self, py: Python<'py>, t: &Bound<'py, PyAny>) -> PyResult<Pair<'py>> {
        let times = self.times(t)?;
        let (p, v) = self.inner.mean_path(&times);
        let d = self.inner.dims();
        Ok((
            array2(py, p, times.len(), d)?,
            array2(py, v, times.len(), d)?,
        ))
    }

    /// Standard deviation of position and velocity at the times `t`: two (len(t), dims)
    /// arrays.
    fn std<'py>(&self, py: Python<'py>, t: &Bound<'py, PyAny>) -> PyResult<Pair<'py>> {
        let times = self.times(t)?;
        let sd =
            |m: nalgebra::DMatrix<f64>| m.diagonal().iter().map(|v| v.max(0.0).sqrt()).collect();
        Ok((
            self.per_time(py, &times, |x| sd(self.inner.covariance_at(x).0))?,
            self.per_time(py, &times, |x| sd(self.inner.covariance_at(x).1))?,
        ))
    }

    /// The ProMP given a via point at `time`: `position` with standard deviation `std` (0:
    /// exact) and optionally `velocity` with `velocity_std`. Chain calls, or pass several
    /// at once as `points=[(time, position, std), …]`.
    #[pyo3(signature = (time=None, position=None, std=0.0, *, velocity=None, velocity_std=0.0, points=None))]
    #[allow(clippy::too_many_arguments)]
    fn condition(
        &self,
        time: Option<f64>,
        position: Option<&Bound<'_, PyAny>>,
        std: f64,
        velocity: Option<&Bound<'_, PyAny>>,
        velocity_std: f64,
        points: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let d = self.inner.dims();
        let mut obs = Vec::new();
        if let Some(t) = time {
            let p = match position {
                Some(p) => vector(p, "position", Some(d))?,
                None => return Err(value_error("position: give the via point's position")),
            };
            let mut o = Observation::position(t, p, std);
            if let Some(v) = velocity {
                o = o.with_velocity(vector(v, "velocity", Some(d))?, velocity_std);
            }
            obs.push(o);
        }
        if let Some(list) = points {
            for (k, item) in list.try_iter()?.enumerate() {
                let (t, p, s): (f64, Bound<'_, PyAny>, f64) = item?.extract().map_err(|_| {
                    value_error(format!("points[{k}]: expected (time, position, std)"))
                })?;
                obs.push(Observation::position(
                    t,
                    vector(&p, &format!("points[{k}]"), Some(d))?,
                    s,
                ));
            }
        }
        if obs.is_empty() {
            return Err(value_error(
                "give a via point (time, position) or points=[…]",
            ));
        }
        if obs.iter().any(|o| {
            !(o.position_cov
                .iter()
                .chain(&o.velocity_cov)
                .all(|v| *v >= 0.0))
        }) {
            return Err(value_error("std: standard deviations must be ≥ 0"));
        }
        Ok(PyProMp {
            inner: self.inner.condition(&obs).map_err(py_err)?,
        })
    }

    /// `n` trajectories drawn with `seed`, at the times `t`: shape (n, len(t), dims).
    #[pyo3(signature = (n, t, *, seed=0))]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        n: usize,
        t: &Bound<'py, PyAny>,
        seed: u64,
    ) -> PyResult<Bound<'py, PyAny>> {
        if n == 0 || n > 1_000_000 {
            return Err(value_error(format!(
                "n: between 1 and 1000000 samples (got {n})"
            )));
        }
        let times = self.times(t)?;
        let d = self.inner.dims();
        let samples = self
            .inner
            .sample_trajectories(n, seed, &times)
            .map_err(py_err)?;
        let a = numpy::PyArray1::from_vec(py, samples);
        Ok(a.reshape([n, times.len(), d])?.into_any())
    }

    /// Where CMA-ES should start when it searches this ProMP's weights:
    /// `(x0, sigma0, C0)` with `sigma0² · C0` the weight covariance (`C0`'s diagonal
    /// averages 1). `cps.CMAES(x0, sigma0, {"C0": C0})` starts in the ProMP's shape.
    fn search_start<'py>(&self, py: Python<'py>) -> PyResult<SearchStart<'py>> {
        let s = self.inner.search_start();
        let n = s.x0.len();
        Ok((array1(py, s.x0), s.sigma0, array2(py, s.covariance, n, n)?))
    }

    /// Co-activation of ProMPs (Paraschos et al. 2013): at each time in `t`, the product
    /// of the ProMPs' position distributions, each raised to its activation.
    /// `activations`: one array per ProMP with its activation (≥ 0) at each time of `t`.
    /// Returns `(mean, std)`, each (len(t), dims).
    #[staticmethod]
    fn blend<'py>(
        py: Python<'py>,
        promps: Vec<Bound<'py, PyProMp>>,
        activations: Vec<Bound<'py, PyAny>>,
        t: &Bound<'py, PyAny>,
    ) -> PyResult<Pair<'py>> {
        if promps.len() != activations.len() {
            return Err(value_error(format!(
                "{} ProMPs but {} activations: give one activation array per ProMP",
                promps.len(),
                activations.len()
            )));
        }
        let times = vector(t, "t", None)?;
        let alphas: Vec<Vec<f64>> = activations
            .iter()
            .enumerate()
            .map(|(k, a)| vector(a, &format!("activations[{k}]"), Some(times.len())))
            .collect::<PyResult<_>>()?;
        // Each activation as a function of time: its value at that time of `t` (looked up
        // by the time's bits; blend asks only at those times).
        let lookup: Vec<Box<dyn Fn(f64) -> f64>> = alphas
            .iter()
            .map(|a| {
                let at: std::collections::HashMap<u64, f64> = times
                    .iter()
                    .map(|t| t.to_bits())
                    .zip(a.iter().copied())
                    .collect();
                Box::new(move |x: f64| at.get(&x.to_bits()).copied().unwrap_or(0.0))
                    as Box<dyn Fn(f64) -> f64>
            })
            .collect();
        let parts: Vec<cps_promp::Activation<'_>> = promps
            .iter()
            .zip(&lookup)
            .map(|(p, f)| cps_promp::Activation {
                promp: &p.get().inner,
                alpha: f.as_ref(),
            })
            .collect();
        let out = cps_promp::blend(&parts, &times).map_err(py_err)?;
        let d = promps.first().map_or(0, |p| p.get().inner.dims());
        let mean = out.iter().flat_map(|b| b.mean.clone()).collect();
        let std = out.iter().flat_map(|b| b.std()).collect();
        Ok((
            array2(py, mean, times.len(), d)?,
            array2(py, std, times.len(), d)?,
        ))
    }

    /// The ProMP as the JSON text of a cps ProMP file (what `cps-cli promp` reads).
    fn to_json(&self) -> String {
        cps_promp::ProMpModel::new(&self.inner, Vec::new(), 0).to_json()
    }

    /// A ProMP from the JSON text of a cps ProMP file.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        let model = cps_promp::ProMpModel::from_json(text).map_err(py_err)?;
        Ok(PyProMp {
            inner: model.to_promp().map_err(py_err)?,
        })
    }

    /// Writes the ProMP file `cps-cli promp` reads. An existing file is replaced only with
    /// `force=True`, and only if it is a cps ProMP file.
    #[pyo3(signature = (path, *, force=false))]
    fn save(&self, path: std::path::PathBuf, force: bool) -> PyResult<()> {
        use cps_outcome::results_dir::{FileKind, check_file_targets};
        check_file_targets(&path, FileKind::ProMp, None, force)
            .map_err(crate::errors::file_error)?;
        cps_outcome::files::write_file(&path, self.to_json().as_bytes())
            .map_err(|e| value_error(e.to_string()))
    }

    /// Reads a ProMP file written by `save` or `cps-cli promp fit|condition`.
    #[staticmethod]
    fn load(path: std::path::PathBuf) -> PyResult<Self> {
        let named =
            cps_movement::promp::NamedProMp::read(&path).map_err(|e| value_error(e.to_string()))?;
        Ok(PyProMp { inner: named.promp })
    }

    fn __repr__(&self) -> String {
        format!(
            "ProMP(dims={}, bases={}, duration={})",
            self.inner.dims(),
            self.inner.bases(),
            self.inner.duration()
        )
    }
}
