//! The error type of cps-cmaes.

/// An error from an objective function (a failed simulation, a bad input, ...).
pub type ObjectiveError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// What an objective returns (as a batch's [`ObjectiveError`]) to end the search instead
/// of failing it: the run stops with [`crate::Termination::Ended`] and keeps what the
/// generations before found. The objective keeps the reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the objective ended the search")]
pub struct EndSearch;

/// What can go wrong when configuring or running CMA-ES.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CmaesError {
    /// A configuration field broke its rule.
    #[error("invalid CMA-ES configuration: `{field}` {rule} (got {value:?})")]
    InvalidConfig {
        /// The field's name as in [`crate::CmaesConfig`].
        field: &'static str,
        /// The rule it broke.
        rule: &'static str,
        /// The value given.
        value: f64,
    },
    /// Two lengths that must agree do not.
    #[error("`{what}` has length {got}, expected {expected}")]
    DimensionMismatch {
        /// Which vector.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The required length.
        expected: usize,
    },
    /// The objective returned an error (not a NaN: NaN costs are ranked last).
    #[error("objective failed at generation {generation}, candidate {index}")]
    Objective {
        /// Generation in which it failed.
        generation: u64,
        /// Index of the candidate in the population.
        index: usize,
        /// The objective's error.
        #[source]
        source: ObjectiveError,
    },
}
