//! Robot kinematics for cps: serial chains, forward and inverse kinematics, inverse
//! controllers, dynamics, limits and retiming.
//!
//! - [`SerialChain`]: revolute joints from a Denavit-Hartenberg table in an explicitly
//!   named convention ([`DhConvention::Standard`] or [`DhConvention::Modified`], never mixed
//!   up) or from URDF-style joints ([`RevoluteJoint`], [`chain_from_urdf`]), with base and
//!   tool transforms, position limits and speed limits.
//! - Forward kinematics ([`SerialChain::fk`], every link frame with
//!   [`SerialChain::fk_frames`]), the geometric Jacobian in the world frame
//!   ([`SerialChain::jacobian`], 6 × n, position rows first) and Yoshikawa's manipulability.
//! - [`controllers`]: pseudo-inverse, damped least squares and transpose steps, and
//!   [`controllers::control_step`], the controller that executes trajectories (damping that
//!   grows near singularities, null-space tasks, limits at every step).
//! - [`solve_ik`]: inverse kinematics (position or full pose) with joint limits and seeded
//!   random restarts; failure carries the best residual. [`check_path`]: is a whole
//!   Cartesian path reachable on one branch?
//! - Robots themselves — the execution contract, the in-process stand-in and executing a
//!   trajectory on a robot — are `cps-robot`'s, built on this crate.
//! - [`ArmModel`]: an arm's mass matrix, Coriolis and gravity torques and tool Jacobian in
//!   fixed-size arrays, for control loops at the robot's rate, and its forward dynamics
//!   ([`ArmModel::forward_dynamics`], the articulated-body algorithm, with rotor inertia and
//!   joint friction) for simulating one.
//! - [`contact`]: the generalized-momentum observer, the external wrench at the tool and a
//!   contact flag.
//! - [`transforms`]: elementary homogeneous transforms (spatial and planar) and the two
//!   Euler-angle conventions, named.
//! - [`robots`]: the Franka Emika Panda (modified DH, flange or Franka Hand TCP, limits),
//!   the UR3 and the Puma 560 (standard DH).
//! - [`sample_workspace`] (seeded reachable tool positions) and Grübler's
//!   [`degrees_of_freedom`], for teaching.
//!
//! This crate does no IO (URDF comes in as text) and has no rayon.
//!
//! # Example
//! ```
//! use cps_kinematics::robots::{panda, PandaTool};
//! # fn main() -> Result<(), cps_kinematics::KinematicsError> {
//! let arm = panda(PandaTool::Flange);
//! let pose = arm.fk(&[0.0; 7])?;
//! // At q = 0 the flange sits 0.088 m forward and 0.926 m above the base.
//! assert!((pose.translation.x - 0.088).abs() < 1e-12);
//! assert!((pose.translation.z - 0.926).abs() < 1e-12);
//! let j = arm.jacobian(&[0.0; 7])?; // 6 x 7
//! assert_eq!(j.ncols(), 7);
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

mod arm_model;
mod chain;
pub mod contact;
pub mod controllers;
mod dynamics;
mod error;
mod fastmath;
mod forward;
mod ik;
mod limits;
pub mod retime;
pub mod robots;
mod spline;
pub mod transforms;
#[cfg(feature = "urdf")]
mod urdf;
mod urdf_collision;
mod workspace;
pub mod xml;

pub use arm_model::{ArmFrames, ArmModel};
pub use chain::{ChainGeometry, ChainPose, DhConvention, DhLink, RevoluteJoint, SerialChain};
pub use controllers::IkTarget;
pub use dynamics::{GRAVITY, LinkInertia};
pub use error::KinematicsError;
pub use ik::{IkConfig, IkSolution, solve_ik};
pub use limits::{
    CARTESIAN_QUANTITIES, CartesianCheck, CartesianLimits, CartesianViolation, CommandCheck,
    Excess, Held, JointBounds, JointLimits, Joints, Judged, LimitCheck, OUTSIDE_SLACK,
    POSITION_TOLERANCE, Quantity, RobotLimits, StreamBounds, StreamCheck, TorqueCheck, Violation,
    beyond_allowed, check_cartesian, check_commands, check_joint_trajectory,
};
pub use retime::{RetimeOptions, Retimed, UniformSlowing, retime};
pub use spline::{JointSpline, PathPoint};
#[cfg(feature = "urdf")]
pub use urdf::{UrdfChain, chain_from_urdf};
pub use urdf_collision::{CollisionElement, CollisionGeometry, disabled_collisions};
pub use workspace::{check_path, degrees_of_freedom, sample_workspace};
