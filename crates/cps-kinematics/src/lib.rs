//! Robot kinematics for cps (not filled yet).
//!
//! This crate will hold the robot maths: homogeneous transforms, Denavit-Hartenberg chains
//! in the standard and the modified (Craig) convention, forward kinematics, geometric
//! Jacobians, damped pseudo-inverse and transpose controllers, inverse kinematics with
//! joint limits, robot models (Franka Panda first) and the small robot-backend trait with
//! an in-process kinematic robot. It does no IO and has no rayon.
#![deny(missing_docs)]
