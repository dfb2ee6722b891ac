//! CoppeliaSim transport for cps: the ZMQ remote-API client and a stand-in server.
//!
//! - [`Client`]: CoppeliaSim's ZMQ remote API, protocol v2 (CoppeliaSim 4.6+) with v1
//!   detected, CBOR through one codec module, every call bounded by a timeout, a broken
//!   socket rebuilt on the next call; typed wrappers for the `sim` functions cps uses
//!   ([`Client::get_object`], [`Client::set_joint_position`], [`Client::step`], …).
//! - [`FrankaScene`]: the thesis's scene names (`/Panda_joint1..7`, `/Panda_tip`, way points
//!   `/p0` … `/pT`) and the scene's robot as a `cps-robot` [`cps_robot::Robot`] (stepped, or
//!   whole plans through cps's scene script).
//! - [`StandInServer`]: the same protocol served by cps, backed by the in-process
//!   kinematic robot, for machines without CoppeliaSim (tests, CI, students).
//!
//! This is the only crate that knows ZMQ (its wire protocol, ZMTP, in [`zmtp`], every
//! frame bounded before it is stored) and CBOR.
//!
//! # Example
//! ```
//! use cps_coppelia::{Client, ClientConfig, SceneSetup, ServerConfig, StandInServer};
//! use cps_kinematics::robots::{panda, PandaTool};
//! # fn main() -> Result<(), cps_coppelia::CoppeliaError> {
//! let scene = SceneSetup {
//!     robot_name: "Panda".into(),
//!     chain: panda(PandaTool::HandTcp),
//!     initial_q: cps_kinematics::robots::PANDA_READY.to_vec(),
//!     dummies: vec![],
//!     dt: 0.05,
//!     ik_following: false,
//!     step_cost: std::time::Duration::ZERO,
//!     script: true,
//! };
//! let server = StandInServer::start(ServerConfig::new("127.0.0.1:0", scene))?;
//! let mut sim = Client::connect(ClientConfig { endpoint: server.endpoint().into(), ..ClientConfig::default() })?;
//! let joint = sim.get_object("/Panda_joint1")?;
//! sim.set_joint_position(joint, 0.3)?;
//! assert_eq!(sim.get_joint_position(joint)?, 0.3);
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

#[cfg(not(feature = "zmq"))]
#[path = "client_absent.rs"]
mod client;
#[cfg(feature = "zmq")]
mod client;
pub mod codec;
mod config;
mod error;
pub mod executor;
mod franka;
mod server;
pub mod sim;
#[cfg(feature = "zmq")]
pub mod zmtp;

pub use client::Client;
pub use config::{ClientConfig, Protocol};
pub use error::CoppeliaError;
pub use franka::{FrankaScene, STOP_POLL};
pub use server::{LogLine, RequestHandler, SceneSetup, ServerConfig, ServerLimits, StandInServer};

/// The largest ZMQ message either side accepts by default (16 MiB): a peer declaring more
/// is disconnected before anything is allocated for it.
pub const DEFAULT_MAX_MESSAGE_BYTES: usize = 16 << 20;
