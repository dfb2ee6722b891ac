//! A build without ZMQ (the crate's `zmq` feature off): [`Client`] exists so that its
//! callers (the typed `sim` calls, the scene's robot) compile unchanged, and
//! [`Client::connect`] says in words that this build cannot reach a simulator. No value of
//! it can be made.

use std::convert::Infallible;
use std::time::Duration;

use crate::CoppeliaError;
use crate::codec::Value;
use crate::config::{ClientConfig, Protocol};

/// A connection to CoppeliaSim; this build has none ([`Client::connect`] says why).
#[derive(Debug)]
pub struct Client(Infallible);

impl Client {
    /// Refuses: this build has no ZMQ transport.
    pub fn connect(config: ClientConfig) -> Result<Self, CoppeliaError> {
        Err(crate::config::not_built(&config.endpoint))
    }

    /// The dialect in use.
    pub fn protocol(&self) -> Protocol {
        match self.0 {}
    }

    /// The endpoint.
    pub fn endpoint(&self) -> &str {
        match self.0 {}
    }

    /// The time allowed for each call.
    pub fn call_timeout(&self) -> Duration {
        match self.0 {}
    }

    /// Registers `f` as a callback named `name`.
    pub fn register_callback(
        &mut self,
        _name: &str,
        _f: impl FnMut(&[Value]) -> Vec<Value> + Send + 'static,
    ) -> Value {
        match self.0 {}
    }

    /// Protocol v1 only: where the server publishes its step counter.
    pub fn set_step_counter_endpoint(&mut self, _endpoint: &str) {
        match self.0 {}
    }

    /// Protocol v1: stepping on or off.
    pub(crate) fn v1_set_stepping(&mut self, _enabled: bool) -> Result<i64, CoppeliaError> {
        match self.0 {}
    }

    /// Protocol v1: one step.
    pub(crate) fn v1_step(&mut self) -> Result<(), CoppeliaError> {
        match self.0 {}
    }

    /// Calls `func` with `args` and returns its return values.
    pub fn call(&mut self, _func: &str, _args: Vec<Value>) -> Result<Vec<Value>, CoppeliaError> {
        match self.0 {}
    }
}
