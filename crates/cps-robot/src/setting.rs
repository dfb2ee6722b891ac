//! Why a setting of the robot's side cannot be used — a follower's limits and period, a
//! chunk run's times, a clearance margin, a scene's names, a share of lost periods — and
//! why a chunk cannot be handed to a running loop: typed, so that a front end can tell the
//! cases apart, each with the sentence a user reads.

use cps_kinematics::KinematicsError;

/// A setting that cannot be used: which, and why (nothing was sent).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SettingError {
    /// Joint values of one count for limits of another.
    #[error("{given} joint position(s) for {joints} joints' limits")]
    JointCount {
        /// Joint values given.
        given: usize,
        /// Joints the limits are for.
        joints: usize,
    },
    /// A control period that is not positive and finite.
    #[error("the period {0} s is not a period")]
    Period(f64),
    /// A joint's rate limit that is not positive and finite.
    #[error("joint {joint}: the {quantity} limit {value} is not positive")]
    Limit {
        /// The joint, from 1.
        joint: usize,
        /// "velocity", "acceleration" or "jerk".
        quantity: &'static str,
        /// The limit given.
        value: f64,
    },
    /// A joint's starting value that is not finite.
    #[error("joint {joint}: the start {value} is not a position")]
    Start {
        /// The joint, from 1.
        joint: usize,
        /// The value given.
        value: f64,
    },
    /// A time that is not a positive number of seconds.
    #[error("{setting}: {value} is not a positive number of seconds")]
    Seconds {
        /// The setting's name.
        setting: &'static str,
        /// The value given.
        value: f64,
    },
    /// The largest gap a chunk may start from the arm, not a positive distance.
    #[error("max gap: {0} is not a positive distance (rad)")]
    MaxGap(f64),
    /// The share of the limits a follower uses, outside (0, 1].
    #[error("limit share: {0} is not in (0, 1]")]
    LimitShare(f64),
    /// A robot without the limits following chunks needs.
    #[error(
        "the robot `{robot}` has no {quantity} limits, and following chunks within the limits needs velocity, acceleration and jerk limits (a robot file's [limits])"
    )]
    MissingLimits {
        /// The robot's name.
        robot: String,
        /// "velocity", "acceleration" or "jerk".
        quantity: &'static str,
    },
    /// The mass matrix (for the torque-rate limit) cannot be computed.
    #[error("the robot `{robot}`'s mass matrix: {source}")]
    MassMatrix {
        /// The robot's name.
        robot: String,
        /// Why.
        #[source]
        source: KinematicsError,
    },
    /// Recorded chunks that run past the longest run.
    #[error("the chunks run longer than the longest run ({0} s)")]
    RunTooLong(f64),
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

/// Why a chunk could not be handed to the robot's loop ([`crate::ChunkFeed::push`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FeedError {
    /// The feed was closed (the stream ended).
    #[error("the chunk stream was closed")]
    Closed,
    /// As many chunks held as a stream may hold: chunks come faster than the arm takes
    /// them.
    #[error(
        "{0} chunks are held for the one the arm follows: chunks come faster than the arm takes them"
    )]
    Held(usize),
    /// Chunks waiting that the loop has not taken: the robot is not running the stream.
    #[error(
        "{0} chunks are waiting for the robot's loop, which has not taken them: the robot is not running the stream"
    )]
    Waiting(usize),
    /// The run is over: the robot no longer takes chunks.
    #[error("the run is over: the robot no longer takes chunks")]
    Over,
}
