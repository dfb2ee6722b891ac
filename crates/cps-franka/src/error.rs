//! Errors of the Franka client, each naming the host and what went wrong.

use std::time::Duration;

use crate::wire::WireError;
use cps_robot::Breach;

/// What went wrong talking to a Franka.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FrankaError {
    /// No TCP connection within the timeout, or refused.
    #[error(
        "{host}: cannot reach the robot's command port ({reason}); is it on, the FCI activated in Desk, and the address right?"
    )]
    Unreachable {
        /// The address tried.
        host: String,
        /// The system's words.
        reason: String,
    },
    /// Something answered, but not as a Franka does.
    #[error("{host}: this is not a Franka Control Interface ({reason})")]
    NotARobot {
        /// The address.
        host: String,
        /// What was wrong.
        reason: String,
    },
    /// The robot speaks another protocol version.
    #[error(
        "{host}: the robot speaks FCI protocol version {robot}, cps speaks {ours} (libfranka 0.18-0.21, FR3 system 5.9 or later); update the robot's system or use a libfranka of its version"
    )]
    VersionMismatch {
        /// The address.
        host: String,
        /// The robot's version.
        robot: u16,
        /// cps's version.
        ours: u16,
    },
    /// No answer within a bounded time.
    #[error("{host}: no {what} within {:.0} ms", after.as_secs_f64() * 1e3)]
    Timeout {
        /// The address.
        host: String,
        /// What was awaited.
        what: &'static str,
        /// How long cps waited.
        after: Duration,
    },
    /// The connection broke.
    #[error("{host}: the connection to the robot was lost ({reason})")]
    ConnectionLost {
        /// The address.
        host: String,
        /// What happened.
        reason: String,
    },
    /// The robot refused or aborted a command.
    #[error("{host}: {command} refused: {sentence}")]
    Rejected {
        /// The address.
        host: String,
        /// The command's name.
        command: &'static str,
        /// The robot's status as a sentence.
        sentence: String,
    },
    /// The robot is in a reflex or reports errors: a motion would be refused.
    #[error(
        "{host}: {mode}; active errors: {errors}. Clear it (cps-cli franka recover, or Desk) before moving"
    )]
    Reflex {
        /// The address.
        host: String,
        /// The robot mode's sentence.
        mode: &'static str,
        /// The active errors.
        errors: String,
    },
    /// A command stream that breaks a limit, refused before anything was sent.
    #[error("refused before sending anything: {0}")]
    Limit(Breach),
    /// Bad input from the caller (a trajectory of the wrong shape, a bad option).
    #[error("{0}")]
    Input(String),
    /// A setting of the robot's side that cannot be used (a share of lost commands).
    #[error(transparent)]
    Setting(#[from] cps_robot::SettingError),
    /// A malformed message from the robot.
    #[error("{host}: {source}")]
    Wire {
        /// The address.
        host: String,
        /// The decoding error.
        source: WireError,
    },
    /// The loop thread could not be made realtime.
    #[error(
        "cannot run the control loop with realtime priority ({0}); run as a user allowed SCHED_FIFO (rtprio in /etc/security/limits.conf) or pass --realtime ignore"
    )]
    Realtime(String),
}
