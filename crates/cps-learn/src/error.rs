//! The error type of cps-learn.

use cps_cmaes::CmaesError;
use cps_dmp::DmpError;

/// What can go wrong in a learning pipeline.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LearnError {
    /// The DMP could not be built.
    #[error(transparent)]
    Dmp(#[from] DmpError),
    /// The optimiser failed or was misconfigured.
    #[error(transparent)]
    Cmaes(#[from] CmaesError),
    /// The task is not well posed; `field` names the offending input.
    #[error("invalid task: `{field}` {problem}")]
    InvalidTask {
        /// Which input, e.g. `via[2].time`.
        field: String,
        /// What is wrong with it.
        problem: String,
    },
    /// The exact least-squares solve failed (a rank-deficient problem).
    #[error("the exact optimum could not be computed: {0}")]
    Exact(String),
}

impl LearnError {
    pub(crate) fn task(field: impl Into<String>, problem: impl Into<String>) -> Self {
        LearnError::InvalidTask {
            field: field.into(),
            problem: problem.into(),
        }
    }
}
