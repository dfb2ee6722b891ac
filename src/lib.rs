//! cps: motor-control learning for robot arms.
//!
//! This facade re-exports the workspace's crates so one dependency gives you all of them:
//!
//! - [`dmp`] (`cps-dmp`): Dynamic Movement Primitives and their rollouts.
//! - [`promp`] (`cps-promp`): probabilistic movement primitives — learned from
//!   demonstrations, conditioned on via points, sampled.
//! - [`cmaes`] (`cps-cmaes`): CMA-ES with deterministic parallel evaluation.
//! - [`learn`] (`cps-learn`): the learning pipelines (via-point, imitation, joint space,
//!   effort, pose).
//! - [`kinematics`] (`cps-kinematics`): robot maths: chains from DH tables or URDF, FK,
//!   Jacobians, IK, inverse dynamics, limits, retiming, controllers.
//! - [`robot`] (`cps-robot`): the execution contract every robot implements (a plan run
//!   from where the robot stands, limits checked by one guard, a stop token) and the
//!   in-process robot.
//! - [`plan`] (`cps-plan`): collision-free joint paths between two configurations, around
//!   the robot itself and its scene, timed and verified as the guard checks a plan.
//! - [`chunks`] (`cps-chunks`): the chunk executor — a learned policy's action chunks
//!   followed on a streaming robot within its limits, from a recording or live.
//! - [`dynamics`] (`cps-dynamics`): a robot arm with dynamics as a robot: forward dynamics
//!   integrated at 1 kHz under a joint-level controller (franky-sim's PD, computed torque,
//!   joint impedance).
//! - [`coppelia`] (`cps-coppelia`): CoppeliaSim's ZMQ remote API (client, stand-in
//!   server, the scene as a robot).
//! - [`franka`] (`cps-franka`): the Franka Control Interface (protocol 10): a robot
//!   driven at 1 kHz, every command checked against its published limits.
//! - [`ros2`] (`cps-ros2`): a ROS 2 graph over DDS without ROS: trajectories to
//!   ros2_control, joint states recorded.
//! - [`ros2_msg`] (`cps-ros2-msg`): the ROS 2 messages and their CDR bytes, no transport.
//! - [`mocap`] (`cps-mocap`): motion-capture takes (C3D, Motive CSV) made demonstrations.
//! - [`geometry`] (`cps-geometry`): shapes, meshes as convex hulls, signed distances.
//! - [`lerobot`] (`cps-lerobot`): LeRobot datasets (v3.0): read with placed errors,
//!   written from recordings.
//! - [`files`] (`cps-files`): the one reader (regular files, size ceilings, counts
//!   estimated before allocating) and the one writer (outputs replaced safely).
//! - [`outcome`] (`cps-outcome`), [`report`] (`cps-report`), [`movement`]
//!   (`cps-movement`), [`drive`] (`cps-drive`): a run's outcome as data and as files; robot,
//!   scene, trajectory and demonstration files; robots driven from files.
//! - [`experiment`] (`cps-experiment`): experiments as a library — read an experiment
//!   file of any kind, run it, get its outcome as data (summary, tables, figures), write
//!   it as a result directory.
//!
//! See ARCHITECTURE.md for how they fit, and `cps-cli` for the command line.
//!
//! # Example
//! ```
//! use cps::dmp::{DiscreteDmp, DmpConfig};
//! # fn main() -> Result<(), cps::dmp::DmpError> {
//! let dmp = DiscreteDmp::new(DmpConfig::new(10, 1.0, 0.01), &[0.0], &[1.0])?;
//! let traj = dmp.rollout(&vec![0.0; 10]);
//! assert_eq!(traj.n_samples(), 101);
//! # Ok(())
//! # }
//! ```
//!
//! An experiment file, as `cps-cli run` runs it (doctests run in the workspace's folder):
//! ```
//! use cps::experiment::{Experiment, RunOptions, budget::Ceilings};
//! let exp = Experiment::from_path("experiments/viapoint.toml".as_ref(), &Ceilings::default())?;
//! let outcome = cps::experiment::run(&exp, &RunOptions::default(), &())?;
//! assert!(outcome.summary["gap_to_optimum"].as_f64().unwrap() < 0.01);
//! let t = outcome.table("trajectory").unwrap();
//! assert_eq!(t.rows(), 1001);
//! # Ok::<(), cps::experiment::ExperimentError>(())
//! ```
#![deny(missing_docs)]

pub use cps_chunks as chunks;
pub use cps_cmaes as cmaes;
pub use cps_coppelia as coppelia;
pub use cps_dmp as dmp;
pub use cps_drive as drive;
pub use cps_dynamics as dynamics;
pub use cps_experiment as experiment;
pub use cps_files as files;
pub use cps_franka as franka;
pub use cps_geometry as geometry;
pub use cps_kinematics as kinematics;
pub use cps_learn as learn;
pub use cps_lerobot as lerobot;
pub use cps_mocap as mocap;
pub use cps_movement as movement;
pub use cps_outcome as outcome;
pub use cps_plan as plan;
pub use cps_promp as promp;
pub use cps_report as report;
pub use cps_robot as robot;
pub use cps_ros2 as ros2;
pub use cps_ros2_msg as ros2_msg;

// The Rust examples of README.md and docs/experiments.md are tested as written.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeExamples;

#[cfg(doctest)]
#[doc = include_str!("../docs/experiments.md")]
pub struct ExperimentsExamples;
