//! The error type of cps-dmp.

/// What can go wrong when building or running a DMP.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DmpError {
    /// A configuration field broke its rule (e.g. `tau` must be > 0).
    #[error("invalid DMP configuration: `{field}` {rule} (got {value})")]
    InvalidConfig {
        /// The field's name as in [`crate::DmpConfig`].
        field: &'static str,
        /// The rule it broke, in words.
        rule: &'static str,
        /// The value given.
        value: f64,
    },
    /// Start and goal (or another per-dimension vector) differ in length.
    #[error("`{what}` has {got} values, expected {expected} (one per dimension)")]
    DimensionMismatch {
        /// Which vector.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The number of dimensions.
        expected: usize,
    },
    /// A start or goal coordinate is NaN or infinite.
    #[error("`{what}`[{index}] is not finite ({value})")]
    NotFinite {
        /// Which vector.
        what: &'static str,
        /// The offending index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A DMP needs at least one dimension.
    #[error("a DMP needs at least one dimension")]
    NoDimensions,
}
