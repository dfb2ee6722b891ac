//! cps experiments as a library: read an experiment file, run it, get its outcome as data,
//! write it as a result directory.
//!
//! The layers, in the order a run passes through them (each module imports only the ones
//! above it in this list; `.ci/module-layers.py` checks it):
//!
//! 1. **sections** ([`sections`]): each kind's own sections of the file (`[imitation]`,
//!    `[joint]`, `[contact]`, …) and `[robot]`, each read into its kind's plan by its own
//!    module, every error placed at its file, line and column.
//! 2. **robots** ([`robots`]): the robot a file chooses opened behind the guard of cps's
//!    execution contract (`cps-robot`): in-process, CoppeliaSim, a Franka, ROS 2.
//! 3. **plan** ([`plan`]): the sections checked against the kind, one [`Experiment`];
//!    [`budget`] refuses one that asks more of the machine than a ceiling.
//! 4. **file** ([`experiment`]): `Experiment::from_path` reads and validates a TOML file
//!    of any kind; scenes and robot files come from `cps-movement`.
//! 5. **kinds and run** ([`run()`], [`run_into`]): one entry point for every kind, with
//!    progress and cancellation through an [`Observer`]; the outcome is `cps-outcome`'s
//!    model, written as a result directory by `cps-report` (`cps_report::write`) — never touching a
//!    file cps did not write. Figures and the report need the `figures` feature (default);
//!    without it plotters is not compiled.
//!
//! It re-exports no module of another crate: a user of `cps-outcome`, `cps-report`,
//! `cps-movement` or `cps-drive` depends on it by name; only the types [`run()`] takes and
//! returns ([`Outcome`], [`InputError`], [`ExperimentError`], [`Context`]) are re-exported.
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
//! cps_report::write::save(&outcome, &dir, false, &Default::default())?;
//! assert!(dir.join("summary.json").is_file());
//! # Ok::<(), cps_experiment::ExperimentError>(())
//! ```
#![deny(missing_docs)]

pub mod budget;
pub mod experiment;
mod kinds;
pub mod markers;
mod observer;
pub mod plan;
pub mod robots;
mod run;
pub mod sections;

// Other crates' modules are named by their crate (`cps_movement::limits`, …): a user of
// them depends on cps-movement, cps-drive or cps-outcome, visibly. Only the types `run`
// takes and returns are re-exported.
pub use cps_outcome::{Context, ExperimentError, InputError, Outcome};
pub use observer::{Event, Observer};
pub use plan::{Experiment, Kind};
pub use run::{RunOptions, planned_generations, run, run_into};
