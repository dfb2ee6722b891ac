//! Robot kinematics for cps (first part: DH chains, forward kinematics, Jacobians).
//!
//! - [`SerialChain`]: a serial chain of revolute joints from a Denavit-Hartenberg table in
//!   an explicitly named convention ([`DhConvention::Standard`] or
//!   [`DhConvention::Modified`], never mixed up), with base and tool transforms.
//! - Forward kinematics ([`SerialChain::fk`], every joint frame with
//!   [`SerialChain::fk_frames`]), the geometric Jacobian in the world frame
//!   ([`SerialChain::jacobian`], 6 × n, position rows first) and Yoshikawa's manipulability.
//! - [`controllers`]: pseudo-inverse, damped least squares and transpose steps.
//! - [`solve_ik`]: inverse kinematics (position or full pose) with joint limits and seeded
//!   random restarts; failure carries the best residual.
//! - [`robots`]: the Franka Emika Panda (modified DH, flange or Franka Hand TCP, limits),
//!   the UR3 and the Puma 560 (standard DH).
//! - [`sample_workspace`] (seeded reachable tool positions) and Grübler's
//!   [`degrees_of_freedom`], for teaching.
//!
//! Still to come (issue "cps-kinematics"): null-space use and limits in the controllers,
//! path reachability checks, URDF and TOML models, the robot-backend trait and the in-process
//! robot. This crate does no IO and has no rayon.
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

mod chain;
pub mod controllers;
mod error;
mod ik;
pub mod robots;
mod workspace;

pub use chain::{ChainPose, DhConvention, DhLink, SerialChain};
pub use error::KinematicsError;
pub use ik::{IkConfig, IkSolution, IkTarget, solve_ik};
pub use workspace::{degrees_of_freedom, sample_workspace};
