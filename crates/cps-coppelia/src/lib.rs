//! CoppeliaSim transport for cps (not filled yet).
//!
//! This crate will hold the CoppeliaSim ZMQ remote-API client (protocol v2 with fallback to
//! v1, CBOR through one codec module), the Franka scene interface implementing the
//! robot-backend trait of `cps-kinematics`, and an embedded stand-in server that speaks the
//! same protocol so everything runs where CoppeliaSim is not installed. It is the only crate
//! that knows ZMQ and CBOR.
#![deny(missing_docs)]
