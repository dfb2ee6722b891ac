//! cps experiments as a library: read an experiment file, run it, get its outcome as data,
//! write it as a result directory.
//!
//! The layers, in the order a run passes through them:
//!
//! 1. **file format** ([`experiment`]): `Experiment::from_path` reads and validates a TOML
//!    file of any kind; every error names the file, line and column. Scenes
//!    ([`scene`]) and robot files ([`robot_file`]) come with it, and [`budget`] refuses
//!    a file that asks more of the machine than a ceiling.
//! 2. **plan** ([`plan`]): each kind's sections as checked plans, and the robot backend
//!    (in-process or CoppeliaSim) a file chooses.
//! 3. **run** ([`run()`]): one entry point for every kind, with progress and
//!    cancellation through an [`Observer`]; no terminal, no signals, no files.
//! 4. **outcome** ([`outcome`]): one result model for every kind — the run header,
//!    summary fields, named tables, named figures, documents and the report's words.
//!
//! [`movement`] holds the DMP layer alone for single movements: demonstrations from CSV,
//! imitation, a model's rollout.
//!
//! 5. **files** ([`files`]): any outcome as `summary.json`, CSVs, figures (PNG + SVG)
//!    and `report.html`, written through [`results_dir`], which never touches a file cps
//!    did not write. Figures and the report need the `figures` feature (default); without
//!    it plotters is not compiled.
//!
//! Running the shipped via-point experiment from Rust:
//!
//! ```
//! use cps_experiment::{Experiment, RunOptions, budget::Ceilings};
//! // Doctests run in the crate's folder.
//! let path = std::path::Path::new("../../experiments/viapoint.toml");
//! let exp = Experiment::from_path(path, &Ceilings::default())?;
//! let outcome = cps_experiment::run(&exp, &RunOptions::default(), &())?;
//! assert!(outcome.complete());
//! let best = outcome.summary["best_cost"].as_f64().unwrap();
//! let optimum = outcome.summary["optimum_cost"].as_f64().unwrap();
//! assert!(best >= optimum * (1.0 - 1e-9) && best < optimum * 1.01);
//! // The trajectory as numbers: one column per quantity.
//! let trajectory = outcome.table("trajectory").unwrap();
//! assert_eq!(trajectory.columns[0].name, "t");
//! // Written as a result directory (summary.json, CSVs, figures, report.html):
//! # let tmp = tempfile::tempdir().unwrap();
//! let dir = tmp.path().join("viapoint"); // a new folder: save creates it
//! cps_experiment::files::save(&outcome, &dir, false, &Default::default())?;
//! assert!(dir.join("summary.json").is_file());
//! # Ok::<(), cps_experiment::ExperimentError>(())
//! ```
#![deny(missing_docs)]

pub mod budget;
pub mod cmaes_bench;
pub mod contact_section;
pub mod experiment;
mod kinds;
mod observer;
pub mod plan;
pub mod robots;
pub mod ros2_show;
mod run;
pub mod sim_pool;

/// Writing an outcome: `cps-outcome`'s files (a table as CSV, atomic writes) and
/// `cps-report`'s result directory (summary, tables, figures, report.html).
pub mod files {
    pub use cps_outcome::files::*;
    pub use cps_report::write::*;
}

pub use cps_drive::{contact, franka, ros2};
pub use cps_movement::{export, limits, mocap, movement, promp, retiming, robot_file, scene};
pub use cps_outcome::{
    Context, ExperimentError, InputError, Outcome, outcome, results_dir, source,
};
#[cfg(feature = "figures")]
pub use cps_report::{figures, report};
pub use observer::{Event, Observer};
pub use plan::{Experiment, Kind};
pub use run::{RunOptions, planned_generations, run};
