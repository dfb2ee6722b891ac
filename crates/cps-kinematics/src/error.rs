//! The error type of cps-kinematics.

/// What can go wrong with a robot model or a kinematic query.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum KinematicsError {
    /// A joint vector of the wrong length.
    #[error("expected {expected} joint values, got {got}")]
    JointCount {
        /// Joints of the robot.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A joint value is NaN or infinite.
    #[error("joint {joint} is not finite ({value})")]
    NotFinite {
        /// 1-based joint number.
        joint: usize,
        /// The value.
        value: f64,
    },
    /// A joint value outside the chain's position limits where limits were asked for.
    #[error("joint {joint} = {value} is outside its limits [{lower}, {upper}]")]
    OutsideLimits {
        /// 1-based joint number.
        joint: usize,
        /// The value (radians).
        value: f64,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// Inverse kinematics found no configuration within the tolerances; the best one
    /// missed by these residuals.
    #[error(
        "target not reached: best position error {position_error:.3e} m, rotation error {rotation_error:.3e} rad after {iterations} iterations"
    )]
    Unreachable {
        /// Distance from the target position of the best configuration, metres.
        position_error: f64,
        /// Rotation angle between the target and the best orientation, radians (0 for
        /// position-only targets).
        rotation_error: f64,
        /// Iterations spent over all restarts.
        iterations: usize,
    },
    /// A setting out of its range; the message names it and the rule.
    #[error("invalid setting: {0}")]
    InvalidConfig(String),
    /// A Cartesian path that the robot cannot follow within its limits.
    #[error("path sample {sample} (t = {time:.3} s) is not reachable: {reason}")]
    PathUnreachable {
        /// 0-based index of the first failing sample.
        sample: usize,
        /// Its time in seconds.
        time: f64,
        /// Why: the IK residual or the joint jump needed.
        reason: String,
    },
    /// No timing of a path keeps every limit (retiming).
    #[error("no timing of the path keeps every limit: at t = {time:.3} s of the path, {reason}")]
    Infeasible {
        /// Time of the offending point on the path's original clock (s).
        time: f64,
        /// Which limit, which joint and why.
        reason: String,
    },
    /// A robot model that cannot be a serial chain (no joints, bad limits, NaN parameters).
    #[error("invalid robot model: {0}")]
    InvalidModel(String),
}
