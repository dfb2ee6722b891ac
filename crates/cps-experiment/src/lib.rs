//! cps experiments as a library: the experiment file format (`[experiment] kind`, the
//! via-point sections and each kind's own), scenes and robot files, what a file asks of
//! the machine (memory and work, refused beyond a ceiling), and result directories that
//! never touch a file cps did not write.
//!
//! Reading is the first layer of file format → plan → run → outcome → files: an
//! [`Experiment`] is a typed, validated experiment whose errors name
//! the file, line and column. Running a kind and the result model still live in
//! `cps-cli` and move here next (issue 16).
//!
//! ```
//! use cps_experiment::{Experiment, budget::Ceilings};
//! // Doctests run in the crate's folder.
//! let path = std::path::Path::new("../../experiments/viapoint.toml");
//! let exp = Experiment::from_path(path, &Ceilings::default())?;
//! assert_eq!(exp.config.task.via.len(), 4);
//! let need = exp.estimate.expect("estimated when read");
//! assert!(need.memory_bytes < 1e9);
//! # Ok::<(), cps_experiment::InputError>(())
//! ```
#![deny(missing_docs)]

pub mod budget;
mod error;
pub mod experiment;
pub mod pipelines;
pub mod results_dir;
pub mod robot_file;
pub mod scene;

pub use error::{Context, ExperimentError, InputError};
pub use experiment::{Experiment, Kind};
