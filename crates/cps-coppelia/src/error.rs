//! The error type of cps-coppelia.

/// What can go wrong talking to CoppeliaSim (or the stand-in server).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CoppeliaError {
    /// No reply within the timeout: the simulator is not running, not reachable, or hung.
    #[error(
        "{endpoint}: no reply to `{function}` within {timeout_ms} ms (is CoppeliaSim running with the ZMQ remote API?)"
    )]
    Timeout {
        /// The endpoint, e.g. `tcp://127.0.0.1:23000`.
        endpoint: String,
        /// The function called.
        function: String,
        /// The timeout that expired.
        timeout_ms: u64,
    },
    /// The connection failed (refused, reset, broken pipe).
    #[error("{endpoint}: connection failed during `{function}`: {message}")]
    Connection {
        /// The endpoint.
        endpoint: String,
        /// The function called.
        function: String,
        /// The transport's message.
        message: String,
    },
    /// The server answered with an error.
    #[error("{endpoint}: `{function}` failed on the server: {message}")]
    Remote {
        /// The endpoint.
        endpoint: String,
        /// The function called.
        function: String,
        /// The server's message, with CoppeliaSim's `_=NL=_` / `_=TB=_` placeholders undone.
        message: String,
    },
    /// A reply that does not follow the protocol, or does not hold what the function
    /// returns.
    #[error("{endpoint}: unexpected reply to `{function}`: {message}")]
    Protocol {
        /// The endpoint.
        endpoint: String,
        /// The function called.
        function: String,
        /// What was wrong.
        message: String,
    },
    /// An invalid setting (endpoint, timeout, bind address).
    #[error("invalid setting: {0}")]
    InvalidConfig(String),
}

impl From<CoppeliaError> for cps_robot::RobotError {
    fn from(e: CoppeliaError) -> Self {
        let robot = match &e {
            CoppeliaError::Timeout { endpoint, .. }
            | CoppeliaError::Connection { endpoint, .. }
            | CoppeliaError::Remote { endpoint, .. }
            | CoppeliaError::Protocol { endpoint, .. } => format!("CoppeliaSim at {endpoint}"),
            CoppeliaError::InvalidConfig(_) => "CoppeliaSim".into(),
        };
        cps_robot::RobotError::Robot {
            robot,
            message: e.to_string(),
        }
    }
}
