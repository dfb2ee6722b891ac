//! A run's [`Outcome`](cps_outcome::Outcome) as a result directory: `summary.json`, one
//! CSV per table, the documents, each figure as PNG and SVG, and `report.html` — written
//! for every kind by the same code ([`write::write_outcome`], [`write::save`]), staged and
//! moved into place by `cps-outcome`'s result directories.
//!
//! - [`figures`] (feature `figures`): every [`Plot`](cps_outcome::outcome::Plot) drawn the
//!   same way (axis names with units, the legend beside the data, start/via/goal marks).
//! - [`report`] (feature `figures`): one self-contained page per run that opens offline.
//!
//! Without the `figures` feature plotters is not compiled, and only the data is written.
//!
//! # Example
//! ```
//! use cps_outcome::outcome::{Column, Format, Outcome, Report, RunHeader, Table, Versions};
//! # let tmp = tempfile::tempdir().unwrap();
//! let outcome = Outcome {
//!     header: RunHeader {
//!         experiment: "demo".into(),
//!         kind: "viapoint",
//!         complete: true,
//!         seed: 1,
//!         versions: Versions { cps: "0.1.0", commit: "unknown" },
//!         threads: 1,
//!         wall_time_s: 0.1,
//!         failure: None,
//!     },
//!     summary: Default::default(),
//!     tables: vec![Table::new("trajectory").with(Column::numbers("t", vec![0.0, 1.0], Format::Plain))],
//!     figures: vec![],
//!     documents: vec![],
//!     report: Report::default(),
//!     lines: vec![],
//! };
//! let dir = tmp.path().join("run");
//! cps_report::write::save(&outcome, &dir, false, &Default::default())?;
//! assert!(dir.join("summary.json").is_file() && dir.join("trajectory.csv").is_file());
//! # Ok::<(), cps_outcome::ExperimentError>(())
//! ```
#![deny(missing_docs)]

#[cfg(feature = "figures")]
pub mod figures;
#[cfg(feature = "figures")]
pub mod report;
pub mod write;

pub use write::{WriteOptions, save, write_outcome};
