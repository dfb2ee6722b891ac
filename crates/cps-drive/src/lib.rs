//! Driving robots from files and words, through cps's execution contract (`cps-robot`):
//! every motion is a plan checked by the guard and run with a stop token.
//!
//! - [`franka`]: `cps-cli franka …` and Python's `cps.Franka`: a joint trajectory file
//!   made 1 kHz commands (retimed, resampled or taken as it is) and executed with its
//!   recording and report; a DMP model stepped online with phase stopping; the robot's
//!   state recorded; teaching by hand; the gripper.
//! - [`follow`]: `cps-cli franka follow`: a learned policy's recorded action chunks
//!   replayed through the chunk executor at 1 kHz, recorded with the chunks beside; a live
//!   stream ([`follow::LiveRun`]) on a Franka, the dynamics or the in-process robot.
//! - [`chunk_socket`]: chunks from another process over UDP (`franka follow --listen`).
//! - [`ros2`]: `cps-cli ros2 send|record` and `cps.ros2`: a joint trajectory checked and
//!   sent to a ros2_control controller (its topic or its FollowJointTrajectory action),
//!   joint states recorded with a report.
//! - [`ros2_follow`]: `cps-cli ros2 follow`: recorded chunks to a joint_trajectory_controller,
//!   one replacement trajectory per chunk, continuous for the controller.
//! - [`ros2_graph`]: `cps-cli ros2 graph`: the nodes, topics, services and actions cps
//!   sees, with their middleware and QoS; what a command says when its controller is
//!   missing.
//! - [`contact`]: movements that touch — force primitives and the hybrid contact task on
//!   a Franka in torque mode.
//! - [`identify`]: `cps-cli franka identify` and `cps-cli identify`: a robot's joint
//!   controller and drives identified from a recording, for the dynamics robot.
//! - [`recording`]: a recording and its report on disk, the same for every robot.
//! - [`stand_in`]: `cps-cli sim serve` and `sim pool`: stand-in CoppeliaSim servers for a
//!   scene file, their options checked, served until a stop.
//!
//! Its realtime closures (the online DMP's, the contact task's, the chunk executor's) run inside cps-franka's
//! 1 kHz loop: nothing in them allocates, locks or logs.
//!
//! # Example
//! Bad input is named before anything connects:
//! ```
//! let e = cps_drive::franka::parse_arm("ur5").unwrap_err();
//! assert!(e.0.contains("not a Franka arm"));
//! ```
#![deny(missing_docs)]

pub use error::DriveError;

pub mod chunk_socket;
pub mod contact;
pub mod error;
pub mod follow;
pub mod franka;
pub mod identify;
pub mod recording;
pub mod ros2;
pub mod ros2_follow;
pub mod ros2_graph;
pub mod said;
pub mod scene;
pub mod stand_in;
