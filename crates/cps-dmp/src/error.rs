//! The error type of cps-dmp.

/// What can go wrong when building or running a DMP.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DmpError {
    /// A configuration field broke its rule (e.g. `tau` must be > 0).
    #[error("invalid DMP configuration: `{field}` {rule} (got {value:?})")]
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
    /// A demonstration that cannot be learned from; the reason names the sample.
    #[error("invalid demonstration: {reason}")]
    InvalidDemonstration {
        /// What is wrong, with the sample or demonstration number.
        reason: String,
    },
    /// In the Ijspeert form the forcing term scales with `g − y0`; a dimension that moves
    /// but ends where it starts cannot be learned there.
    #[error(
        "dimension {dim} moves over {range:.3e} but ends {amplitude:.3e} from where it starts: the Ijspeert form scales the forcing term by g − y0 and would need huge weights; use the goal-robust formulation"
    )]
    DegenerateAmplitude {
        /// 0-based dimension.
        dim: usize,
        /// `g − y0` of the demonstration.
        amplitude: f64,
        /// Range of the demonstration in that dimension.
        range: f64,
    },
    /// A linear-algebra step failed (e.g. a singular regression without regularisation).
    #[error("numerical failure: {0}")]
    NumericalFailure(String),
    /// A model file that cannot be loaded: another format or version, an unknown
    /// formulation, inconsistent shapes.
    #[error("invalid model: {reason}")]
    InvalidModel {
        /// What is wrong.
        reason: String,
    },
    /// A movement that cannot be carried to new endpoints in the asked way.
    #[error("{0}")]
    CannotRetarget(String),
    /// An obstacle where the movement must be: at its start or its goal.
    #[error("{0}")]
    BlockedEndpoint(String),
    /// A name that is none of a setting's ([`crate::Formulation`], [`crate::Method`],
    /// [`crate::Combine`]); `now`: the present name of a former one.
    #[error("{}", match now {
        Some(n) => format!("\"{given}\" is now called \"{n}\""),
        None => format!("\"{given}\" is not one of {}",
            known.iter().map(|k| format!("\"{k}\"")).collect::<Vec<_>>().join(", ")),
    })]
    UnknownName {
        /// The setting (`formulation`, `method`, `combine`).
        setting: &'static str,
        /// The name given.
        given: String,
        /// The names known.
        known: Vec<&'static str>,
        /// The present name, when `given` was a former one.
        now: Option<&'static str>,
    },
    /// A DMP needs at least one dimension.
    #[error("a DMP needs at least one dimension")]
    NoDimensions,
}
