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
    /// The robot model or inverse kinematics failed.
    #[error(transparent)]
    Kinematics(#[from] cps_kinematics::KinematicsError),
    /// A robot refused a plan or failed while running it.
    #[error(transparent)]
    Robot(#[from] cps_robot::RobotError),
    /// A way point the robot's tool cannot reach within the joint limits.
    #[error(
        "`{point}` at ({x:.4}, {y:.4}, {z:.4}) is outside the robot's reachable workspace: the closest reachable point within the joint limits is {distance:.4} m away",
        x = position[0], y = position[1], z = position[2]
    )]
    Unreachable {
        /// Which point (`start`, `via[1]`, `goal`).
        point: String,
        /// Its position (metres, world frame).
        position: [f64; 3],
        /// Distance to the closest reachable point found by inverse kinematics (metres).
        distance: f64,
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
