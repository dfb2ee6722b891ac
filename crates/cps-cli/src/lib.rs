//! The command line's internals as a library: the experiment file format, the result
//! directory, the runners, figures and reports, and each subcommand's implementation.
//!
//! `cps-cli`'s `main.rs` is a thin layer over these modules (arguments, terminal,
//! Ctrl-C, exit codes); the fuzzer (`cps-fuzz`) reaches the file parsers through them.
//! This is not yet a stable API: the experiments library (`cps-experiment`, planned)
//! takes the file format, the runs and the result model out of here.
//!
//! ```
//! // Doctests run in the crate's folder.
//! let path = std::path::Path::new("../../experiments/viapoint.toml");
//! let exp = cps_cli::experiment::load(path, None, &cps_cli::budget::Ceilings::default())?;
//! assert_eq!(exp.config.task.via.len(), 4);
//! # Ok::<(), cps_cli::experiment::InputError>(())
//! ```
#![allow(missing_docs)]

/// Prints a line to stdout, ignoring a closed pipe (`cps-cli fk ... | head` must not panic).
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

pub use cps_experiment::{budget, experiment, pipelines, results_dir, robot_file};

pub mod cmaes_bench;
pub mod energy_run;
pub mod imitation_run;
pub mod joint_run;
pub mod movement;
pub mod output;
pub mod plots;
pub mod pose_run;
pub mod report;
pub mod robot;
pub mod runner;
pub mod scaling_run;
pub mod scene;
pub mod simserve;
