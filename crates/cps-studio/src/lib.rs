//! cps studio: a local web workbench. Drag a via point, and the movement is learned again
//! and redrawn — the exact solver while dragging (milliseconds), CMA-ES on release.
//!
//! The server binds loopback by default, serves only the page embedded in this crate (no
//! file, nothing from the internet) and a small JSON API ([`api`]), bounds every request's
//! size and work, and shares the machine's cores fairly between browser tabs: learning
//! runs on a blocking pool behind a semaphore of one permit per core, granted in arrival
//! order. `cps-cli studio` starts it.
//!
//! # Example
//! ```
//! use cps_studio::{StudioConfig, StudioServer, api};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // The API without HTTP: the thesis's start and goal, one via point.
//! let request: api::ViaPointRequest = serde_json::from_str(
//!     r#"{"start": [0.75, 0.02, 1.87], "goal": [0.55, -0.57, 1.45], "tau": 10,
//!         "via": [{"time": 4, "position": [1.12, 0.37, 1.45]}]}"#,
//! )?;
//! let answer = api::viapoint(&request, None, &|| false)?;
//! assert!(answer.via_errors_m[0] < 1e-3 && answer.goal_error_m < 1e-3);
//! // The server, on a free loopback port.
//! let server = StudioServer::start(StudioConfig::new("127.0.0.1:0"))?;
//! assert!(server.url().starts_with("http://127.0.0.1:"));
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

pub mod api;
#[cfg(feature = "web")]
mod assets;
mod config;
pub mod files;
#[cfg(feature = "web")]
mod http;
#[cfg(not(feature = "web"))]
#[path = "http_absent.rs"]
mod http;
pub mod imitation;
pub mod robot;

pub use config::{StudioConfig, StudioError};
pub use http::StudioServer;
