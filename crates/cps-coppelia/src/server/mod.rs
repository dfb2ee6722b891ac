//! The stand-in server: CoppeliaSim's ZMQ remote API (protocol v2) served by cps itself,
//! backed by the in-process kinematic robot and a scene of named objects, so clients (ours
//! and the official Python one) run where CoppeliaSim is not installed.
//!
//! What it models: a robot whose joints are `/<robot>_joint1..n` and whose tool point is
//! `/<robot>_tip` (positions from forward kinematics), the robot's base `/<robot>`, and
//! dummies with poses (created, aliased, moved, coloured and removed by clients). Joint
//! positions are set kinematically. Simulation time advances by `dt` per step: with
//! `sim.step` for a client that set stepping, else one step per request while running.
//! It binds loopback by default and never executes code it is sent.
//!
//! The scene and the protocol without the network are [`scene`] (one request in, one
//! reply out: [`RequestHandler`]); what clients log is kept by [`log`]; this module serves
//! them over ZMTP, one connection per peer, within [`ServerLimits`].

mod log;
mod scene;
#[cfg(not(feature = "zmq"))]
#[path = "absent.rs"]
mod serve;
#[cfg(feature = "zmq")]
mod serve;

use std::time::Duration;

use crate::CoppeliaError;
pub use log::LogLine;
pub use scene::{RequestHandler, SceneSetup};
pub use serve::StandInServer;

/// Settings of [`StandInServer::start`].
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// `host:port` to bind (port 0 picks a free one). Default `127.0.0.1:23000`.
    pub bind: String,
    /// The scene.
    pub scene: SceneSetup,
    /// What one peer may ask of the server.
    pub limits: ServerLimits,
}

impl ServerConfig {
    /// A server for `scene` on `bind`, with the default [`ServerLimits`].
    pub fn new(bind: impl Into<String>, scene: SceneSetup) -> Self {
        Self {
            bind: bind.into(),
            scene,
            limits: ServerLimits::default(),
        }
    }
}

/// Bounds that keep one peer from hurting the others.
#[derive(Debug, Clone, PartialEq)]
pub struct ServerLimits {
    /// The largest request (all frames) accepted; a peer declaring more is disconnected
    /// before anything is allocated for it. Default 16 MiB.
    pub max_message_bytes: usize,
    /// Connections served at once; more are closed on arrival. Default 64.
    pub max_connections: usize,
    /// A client silent for longer loses its stepping hold (and its state), so the
    /// simulation runs on for the others. Default 60 s.
    pub client_lease: Duration,
    /// Time a new connection has to finish the ZMTP handshake, and a reply has to be taken
    /// by its client, before the peer is dropped. Default 10 s.
    pub io_timeout: Duration,
}

impl Default for ServerLimits {
    fn default() -> Self {
        Self {
            max_message_bytes: crate::DEFAULT_MAX_MESSAGE_BYTES,
            max_connections: 64,
            client_lease: Duration::from_secs(60),
            io_timeout: Duration::from_secs(10),
        }
    }
}

impl ServerLimits {
    pub(crate) fn check(&self) -> Result<(), CoppeliaError> {
        let bad = |m: &str| Err(CoppeliaError::InvalidConfig(m.into()));
        if !(64..=1 << 30).contains(&self.max_message_bytes) {
            return bad("the message limit must be between 64 bytes and 1 GiB");
        }
        if !(1..=4096).contains(&self.max_connections) {
            return bad("the connection limit must be between 1 and 4096");
        }
        let secs = |d: Duration| d.as_secs_f64();
        if !(0.01..=86_400.0).contains(&secs(self.client_lease)) {
            return bad("the client lease must be between 0.01 s and one day");
        }
        if !(0.01..=3_600.0).contains(&secs(self.io_timeout)) {
            return bad("the I/O timeout must be between 0.01 s and one hour");
        }
        Ok(())
    }
}
