//! A build without the web server (the crate's `web` feature off): [`StudioServer`]
//! exists so that its callers compile unchanged, and [`StudioServer::start`] says in words
//! that this build cannot serve. No value of it can be made.

use std::convert::Infallible;

use crate::config::{StudioConfig, StudioError};

/// A running studio; this build has none ([`StudioServer::start`] says why).
#[derive(Debug)]
pub struct StudioServer(Infallible);

impl StudioServer {
    /// Refuses: this build has no web server.
    pub fn start(_config: StudioConfig) -> Result<Self, StudioError> {
        Err(StudioError::NotBuilt)
    }

    /// `http://host:port` of the studio.
    pub fn url(&self) -> &str {
        match self.0 {}
    }

    /// Blocks until the server ends.
    pub fn wait(self) {
        match self.0 {}
    }

    /// Stops serving.
    pub fn stop(&mut self) {
        match self.0 {}
    }
}
