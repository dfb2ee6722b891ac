//! Why the chunk executor cannot be set up or run — a follower's limits and period, a
//! run's times, a robot without the limits following needs, or the robot itself — and why
//! a chunk cannot be handed to a running loop: typed, so that a front end can tell the
//! cases apart, each with the sentence a user reads.

use cps_kinematics::KinematicsError;
use cps_robot::RobotError;

/// Why chunks cannot be followed (nothing was sent, unless the robot failed while moving).
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum FollowError {
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
    /// The robot refused the run or failed during it.
    #[error(transparent)]
    Robot(#[from] RobotError),
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
