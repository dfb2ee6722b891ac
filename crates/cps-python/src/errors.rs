//! Rust errors as Python exceptions: bad input is a `ValueError` with the sentence the
//! command line prints; a failure while working is a `cps.CpsError` (a `RuntimeError`).

use cps_cmaes::CmaesError;
use cps_dmp::DmpError;
use cps_experiment::{ExperimentError, InputError};
use cps_kinematics::KinematicsError;
use cps_learn::LearnError;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    cps,
    CpsError,
    PyRuntimeError,
    "A failure while cps was working (not a problem with the input): an inverse-kinematics target no configuration reaches, a run that could not be written, a simulator that died."
);

/// `ValueError(message)`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// The option named `value` among `options` for the argument `arg`, or a `ValueError`
/// listing the choices.
pub fn choose<T: Copy>(arg: &str, value: &str, options: &[(&str, T)]) -> PyResult<T> {
    options
        .iter()
        .find(|(name, _)| *name == value)
        .map(|(_, v)| *v)
        .ok_or_else(|| {
            let names: Vec<String> = options.iter().map(|(n, _)| format!("\"{n}\"")).collect();
            value_error(format!(
                "{arg}: \"{value}\" is not one of {}",
                names.join(", ")
            ))
        })
}

/// A setting by the name its type parses (`FromStr` in the setting's crate, one
/// vocabulary everywhere); refused with its keyword first.
pub fn named<T>(keyword: &str, name: &str) -> PyResult<T>
where
    T: std::str::FromStr,
    T::Err: std::fmt::Display,
{
    name.parse()
        .map_err(|e: T::Err| value_error(format!("{keyword}: {e}")))
}

/// `cps.CpsError(message)`.
pub fn failure(message: impl Into<String>) -> PyErr {
    CpsError::new_err(message.into())
}

/// File-target messages name the command line's options (`--out`, `--force`); in Python
/// they are the keywords `out` and `force=True`.
pub fn file_error(e: InputError) -> PyErr {
    value_error(
        e.0.replace("pass --force", "pass force=True")
            .replace("--force", "force=True")
            .replace("--out ", "out ")
            .replace("another --out", "another out"),
    )
}

/// The whole cause chain of an error, as the command line prints it.
fn chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let next = s.to_string();
        if !text.contains(&next) {
            text.push_str(": ");
            text.push_str(&next);
        }
        source = s.source();
    }
    text
}

/// A CMA-ES configuration field under the name pycma's users know.
pub fn option_name(field: &str) -> &str {
    match field {
        "population" => "popsize",
        "initial_scales" => "CMA_stds",
        "initial_covariance" => "C0",
        "separable" => "CMA_diagonal",
        other => other,
    }
}

/// Conversions of every cps error type.
pub trait IntoPyErr {
    /// The Python exception for this error.
    fn py_err(self) -> PyErr;
}

impl IntoPyErr for InputError {
    fn py_err(self) -> PyErr {
        value_error(self.0)
    }
}

impl IntoPyErr for DmpError {
    fn py_err(self) -> PyErr {
        // Every DMP error is about its input: a field, a shape, a demonstration, a model.
        match self {
            DmpError::InvalidConfig { field, rule, value } => {
                value_error(format!("{}: {rule} (got {value:?})", dmp_option(field)))
            }
            other => value_error(other.to_string()),
        }
    }
}

/// A DMP configuration field under the keyword name of the Python functions.
fn dmp_option(field: &str) -> &str {
    match field {
        "n_basis" => "bases",
        "lambda" => "lambda_",
        other => other,
    }
}

impl IntoPyErr for CmaesError {
    fn py_err(self) -> PyErr {
        match self {
            CmaesError::InvalidConfig { field, rule, value } => {
                value_error(format!("{}: {rule} (got {value:?})", option_name(field)))
            }
            CmaesError::DimensionMismatch { .. } => value_error(self.to_string()),
            other => failure(chain(&other)),
        }
    }
}

impl IntoPyErr for KinematicsError {
    fn py_err(self) -> PyErr {
        match self {
            KinematicsError::Unreachable { .. } => failure(self.to_string()),
            other => value_error(other.to_string()),
        }
    }
}

impl IntoPyErr for LearnError {
    fn py_err(self) -> PyErr {
        match self {
            LearnError::Dmp(e) => e.py_err(),
            LearnError::Cmaes(e) => e.py_err(),
            LearnError::Kinematics(e) => e.py_err(),
            LearnError::Exact(_) | LearnError::Robot(_) => failure(self.to_string()),
            other => value_error(other.to_string()),
        }
    }
}

impl IntoPyErr for ExperimentError {
    fn py_err(self) -> PyErr {
        match self {
            ExperimentError::Input(e) => e.py_err(),
            other => failure(chain(&other)),
        }
    }
}

impl IntoPyErr for cps_drive::DriveError {
    fn py_err(self) -> PyErr {
        match self {
            cps_drive::DriveError::Input(e) => e.py_err(),
            e if e.is_input() => value_error(e.to_string()),
            other => failure(chain(&other)),
        }
    }
}

/// `.py()` on results of cps's crates.
pub trait PyResultExt<T> {
    /// The result with its error as a Python exception.
    fn py(self) -> PyResult<T>;
}

impl<T, E: IntoPyErr> PyResultExt<T> for Result<T, E> {
    fn py(self) -> PyResult<T> {
        self.map_err(IntoPyErr::py_err)
    }
}

/// The arm by its name, as cps-franka reads it everywhere (`fr3`, `panda`, `fer`).
pub(crate) fn arm_named(name: &str) -> PyResult<cps_franka::limits::Arm> {
    use cps_franka::limits::Arm;
    Arm::from_name(name).ok_or_else(|| {
        let names: Vec<String> = Arm::ALL
            .iter()
            .map(|a| format!("\"{}\"", a.name()))
            .collect();
        value_error(format!(
            "arm: \"{name}\" is not one of {}",
            names.join(", ")
        ))
    })
}
