//! A build without ZMQ (the crate's `zmq` feature off): [`StandInServer`] exists so that
//! its callers compile unchanged, and [`StandInServer::start`] says in words that this
//! build cannot serve. No value of it can be made.

use std::convert::Infallible;

use super::{LogLine, ServerConfig};
use crate::CoppeliaError;

/// A running stand-in server; this build has none ([`StandInServer::start`] says why).
#[derive(Debug)]
pub struct StandInServer(Infallible);

impl StandInServer {
    /// Refuses: this build has no ZMQ transport.
    pub fn start(config: ServerConfig) -> Result<Self, CoppeliaError> {
        config.limits.check()?;
        Err(crate::config::not_built(&config.bind))
    }

    /// The endpoint clients connect to.
    pub fn endpoint(&self) -> &str {
        match self.0 {}
    }

    /// What clients logged since the last call.
    pub fn take_logs(&self) -> Vec<LogLine> {
        match self.0 {}
    }

    /// Requests served.
    pub fn requests(&self) -> u64 {
        match self.0 {}
    }

    /// Peers dropped for breaking the limits or the protocol.
    pub fn dropped_peers(&self) -> u64 {
        match self.0 {}
    }

    /// What was served, in words.
    pub fn served(&self) -> String {
        match self.0 {}
    }

    /// Blocks until the server ends.
    pub fn wait(self) {
        match self.0 {}
    }
}
