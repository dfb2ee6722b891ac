//! numpy in and out. Inputs are read once into float64 arrays in C order — borrowed, not
//! copied, when they already are; converted by numpy when they are lists, integers,
//! float32 or non-contiguous views — and checked for shape and finiteness, every error
//! naming the argument. Outputs are new numpy arrays of shape (samples, dims).

use numpy::{
    PyArray1, PyArray2, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use crate::errors::value_error;

/// A float64 array read from a Python argument (borrowed when possible).
pub struct Floats<'py> {
    array: PyReadonlyArrayDyn<'py, f64>,
}

impl Floats<'_> {
    /// The array's shape.
    pub fn shape(&self) -> &[usize] {
        self.array.shape()
    }

    /// The values in C order.
    pub fn values(&self) -> &[f64] {
        self.array
            .as_slice()
            .expect("floats() returns C-contiguous arrays")
    }
}

/// Reads `obj` (argument `name`) as a float64 array of finite values.
pub fn floats<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Floats<'py>> {
    let floats = any_floats(obj, name)?;
    if let Some(i) = floats.values().iter().position(|v| !v.is_finite()) {
        let place = flat_place(i, floats.shape());
        return Err(value_error(format!(
            "{name}{place} is {}; every value must be finite",
            floats.values()[i]
        )));
    }
    Ok(floats)
}

/// Reads `obj` (argument `name`) as a float64 array; NaN and infinities allowed.
pub fn any_floats<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Floats<'py>> {
    let py = obj.py();
    let array = match obj.cast::<PyArrayDyn<f64>>() {
        Ok(a) if a.is_c_contiguous() => a.clone(),
        _ => {
            let np = py.import("numpy")?;
            let a = np.call_method1("asarray", (obj,)).map_err(|e| {
                value_error(format!("{name}: not an array of numbers ({})", e.value(py)))
            })?;
            let kind: String = a.getattr("dtype")?.getattr("kind")?.extract()?;
            if !matches!(kind.as_str(), "i" | "u" | "f") {
                let dtype = a.getattr("dtype")?.str()?.to_string();
                return Err(value_error(format!(
                    "{name}: expected real numbers, got an array of dtype {dtype}"
                )));
            }
            let c = np.call_method1("ascontiguousarray", (a, np.getattr("float64")?))?;
            c.cast_into::<PyArrayDyn<f64>>()
                .map_err(|e| value_error(format!("{name}: {e}")))?
        }
    };
    Ok(Floats {
        array: array.readonly(),
    })
}

/// `[k]` or `[k, d]` of flat index `i` in an array of `shape`.
fn flat_place(i: usize, shape: &[usize]) -> String {
    let mut rest = i;
    let mut idx = vec![0; shape.len()];
    for (d, &n) in shape.iter().enumerate().rev() {
        if n > 0 {
            idx[d] = rest % n;
            rest /= n;
        }
    }
    let parts: Vec<String> = idx.iter().map(usize::to_string).collect();
    format!("[{}]", parts.join(", "))
}

/// Reads a vector of `len` values (any length when `None`).
pub fn vector(obj: &Bound<'_, PyAny>, name: &str, len: Option<usize>) -> PyResult<Vec<f64>> {
    let a = floats(obj, name)?;
    let shape = a.shape();
    let n = match shape {
        [] => 1,
        [n] => *n,
        _ => {
            return Err(value_error(format!(
                "{name}: expected a vector (1-D), got shape {}",
                shape_text(shape)
            )));
        }
    };
    if let Some(want) = len
        && n != want
    {
        return Err(value_error(format!(
            "{name}: expected {want} values, got {n}"
        )));
    }
    Ok(a.values().to_vec())
}

/// Reads an optional vector argument.
pub fn opt_vector(
    obj: Option<&Bound<'_, PyAny>>,
    name: &str,
    len: Option<usize>,
) -> PyResult<Option<Vec<f64>>> {
    match obj {
        Some(o) if !o.is_none() => vector(o, name, len).map(Some),
        _ => Ok(None),
    }
}

/// A matrix argument: rows of `cols` values (any width when `None`). A vector is one
/// column when `vector_is_column`, else an error.
pub struct Matrix<'py> {
    /// The values, row-major.
    pub floats: Floats<'py>,
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
}

impl Matrix<'_> {
    /// Row `k`.
    pub fn row(&self, k: usize) -> &[f64] {
        &self.floats.values()[k * self.cols..(k + 1) * self.cols]
    }

    /// The rows as vectors.
    pub fn rows_vec(&self) -> Vec<Vec<f64>> {
        (0..self.rows).map(|k| self.row(k).to_vec()).collect()
    }
}

/// Reads a matrix argument (see [`Matrix`]).
pub fn matrix<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    cols: Option<usize>,
    vector_is_column: bool,
) -> PyResult<Matrix<'py>> {
    let floats = floats(obj, name)?;
    let (rows, c) = match *floats.shape() {
        [n] if vector_is_column => (n, 1),
        [r, c] => (r, c),
        _ => {
            return Err(value_error(format!(
                "{name}: expected a 2-D array of shape (samples, dims), got shape {}",
                shape_text(floats.shape())
            )));
        }
    };
    if let Some(want) = cols
        && c != want
    {
        return Err(value_error(format!(
            "{name}: expected {want} columns, got shape ({rows}, {c})"
        )));
    }
    Ok(Matrix {
        floats,
        rows,
        cols: c,
    })
}

/// `(a, b, c)`.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => {
            let parts: Vec<String> = shape.iter().map(usize::to_string).collect();
            format!("({})", parts.join(", "))
        }
    }
}

/// Whether `obj` is a list or tuple (several demonstrations rather than one array).
pub fn is_sequence_of_arrays(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    if !(obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>()) {
        return Ok(false);
    }
    let Ok(first) = obj.get_item(0) else {
        return Ok(false);
    };
    let np = obj.py().import("numpy")?;
    let ndim: usize = np.call_method1("ndim", (first,))?.extract()?;
    Ok(ndim >= 1)
}

/// A new 1-D array.
pub fn array1(py: Python<'_>, values: Vec<f64>) -> Bound<'_, PyArray1<f64>> {
    PyArray1::from_vec(py, values)
}

/// A new (rows, cols) array from row-major values.
pub fn array2(
    py: Python<'_>,
    values: Vec<f64>,
    rows: usize,
    cols: usize,
) -> PyResult<Bound<'_, PyArray2<f64>>> {
    PyArray1::from_vec(py, values).reshape([rows, cols])
}

/// A (samples, dims) array from per-dimension series of equal length.
pub fn samples_by_dims<'py, 'a>(
    py: Python<'py>,
    series: impl ExactSizeIterator<Item = &'a [f64]>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let series: Vec<&[f64]> = series.collect();
    let dims = series.len();
    let n = series.first().map_or(0, |s| s.len());
    let mut out = vec![0.0; n * dims];
    for (d, s) in series.iter().enumerate() {
        for (k, v) in s.iter().enumerate() {
            out[k * dims + d] = *v;
        }
    }
    array2(py, out, n, dims)
}

/// A joint trajectory from times `t` (samples,) and positions `q` (samples, `cols` or any
/// number of joints), columns named `q1`, `q2`, …
pub fn joint_trajectory(
    t: &Bound<'_, PyAny>,
    q: &Bound<'_, PyAny>,
    cols: Option<usize>,
) -> PyResult<cps_movement::limits::JointTrajectory> {
    let times = vector(t, "t", None)?;
    let rows = matrix(q, "q", cols, false)?;
    if rows.rows != times.len() {
        return Err(value_error(format!(
            "q: {} rows for {} times in t",
            rows.rows,
            times.len()
        )));
    }
    Ok(cps_movement::limits::JointTrajectory {
        names: (1..=rows.cols).map(|j| format!("q{j}")).collect(),
        times,
        q: rows.rows_vec(),
    })
}
