//! Where the simulator is and how the client talks to it: the same in every build.

use std::time::Duration;

#[cfg(not(feature = "zmq"))]
use crate::CoppeliaError;

/// Where the simulator is and how long to wait for it.
#[derive(Debug, Clone, PartialEq)]
pub struct ClientConfig {
    /// ZMQ endpoint, default `tcp://127.0.0.1:23000`.
    pub endpoint: String,
    /// Time allowed to connect and get the first reply. Default 5 s.
    pub connect_timeout: Duration,
    /// Time allowed for each call (a `sim.step` may take several round trips). Default
    /// 10 s.
    pub call_timeout: Duration,
    /// The largest reply accepted; a server declaring more is disconnected before anything
    /// is allocated for it. Default 16 MiB.
    pub max_message_bytes: usize,
}

impl Default for ClientConfig {
    fn default() -> Self {
        Self {
            endpoint: "tcp://127.0.0.1:23000".into(),
            connect_timeout: Duration::from_secs(5),
            call_timeout: Duration::from_secs(10),
            max_message_bytes: crate::DEFAULT_MAX_MESSAGE_BYTES,
        }
    }
}

/// Which dialect the server speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// CoppeliaSim 4.6 and later.
    V2,
    /// CoppeliaSim 4.3 – 4.5: `{func, args}` requests, `success`/`error` replies,
    /// setters as `(handle, relativeTo, value)`, stepping through a PUB/SUB step counter.
    V1,
}

/// The refusal of a build without the `zmq` feature, for `endpoint`.
#[cfg(not(feature = "zmq"))]
pub(crate) fn not_built(endpoint: &str) -> CoppeliaError {
    CoppeliaError::InvalidConfig(format!(
        "{endpoint}: this build of cps has no ZMQ transport to CoppeliaSim (crate cps-coppelia without its `zmq` feature, as the README's first command builds it); `cargo install --path crates/cps-cli` and the tests build it"
    ))
}
