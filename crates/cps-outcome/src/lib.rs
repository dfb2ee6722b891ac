//! A run's outcome as data, and the files cps writes and reads around it — below every
//! part of cps that records something (experiments, robot commands, motion capture), so
//! that each can write its results without depending on the others.
//!
//! - [`outcome`]: one result model for every run — the header, summary fields, named
//!   tables of typed columns, figures as data, documents, the report's words.
//! - [`results_dir`]: result directories that never touch a file cps did not write: a
//!   manifest of what cps wrote, a staging directory moved into place, `--force` replacing
//!   only cps's own files.
//! - [`files`]: a table as CSV text; any file written through a temporary file and a
//!   rename (never half a file).
//! - [`source`]: bounded reading of input files (size ceilings, regular files only) and
//!   `file:line:column` places for messages.
//! - [`InputError`] (the user's input: exit 2 on the command line) and [`ExperimentError`]
//!   (a failure while running or writing: exit 1).
//!
//! Drawing figures and `report.html` is `cps-report`'s; this crate has no plotting and
//! no robotics.
//!
//! # Example
//! ```
//! use cps_outcome::outcome::{Column, Format, Table};
//! let table = Table::new("trajectory")
//!     .with(Column::numbers("t", vec![0.0, 0.5], Format::Plain))
//!     .with(Column::numbers("x", vec![0.1, 0.2], Format::Plain));
//! let csv = cps_outcome::files::table_csv(&table)?;
//! assert_eq!(String::from_utf8(csv).unwrap(), "t,x\n0,0.1\n0.5,0.2\n");
//! # Ok::<(), cps_outcome::ExperimentError>(())
//! ```
#![deny(missing_docs)]

mod error;
pub mod files;
pub mod outcome;
pub mod results_dir;
pub mod source;

pub use error::{Context, ExperimentError, InputError};
pub use outcome::{Ended, Outcome};
