//! Why a setting of the robot's side cannot be used — a clearance margin, a scene's names,
//! a share of lost periods: typed, so that a front end can tell the cases apart, each with
//! the sentence a user reads.

/// A setting that cannot be used: which, and why (nothing was sent).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SettingError {
    /// A clearance margin asked of a robot without collision geometry.
    #[error("the robot `{0}` has no collision geometry to keep a margin with")]
    NoShapes(String),
    /// A clearance margin that is not a finite distance ≥ 0.
    #[error("the clearance margin must be a finite distance ≥ 0 m, not {0}")]
    Margin(f64),
    /// Two obstacles of one name.
    #[error("two obstacles are named `{0}`")]
    DuplicateObstacle(String),
    /// An obstacle named as one of the robot's links.
    #[error("the obstacle `{0}` has the name of one of the robot's links")]
    ObstacleNamedAsLink(String),
    /// An allowed contact naming neither a link nor an obstacle.
    #[error(
        "a contact names `{name}`, which is neither one of the robot's links ({links}) nor an obstacle"
    )]
    UnknownContactName {
        /// The name given.
        name: String,
        /// The robot's links, comma-separated.
        links: String,
    },
    /// A share of lost periods outside [0, `max`] ([`crate::MAX_LOSS`]).
    #[error("a share of lost periods of {share} is outside [0, {max}]")]
    LossShare {
        /// The share given.
        share: f64,
        /// The largest share.
        max: f64,
    },
}
