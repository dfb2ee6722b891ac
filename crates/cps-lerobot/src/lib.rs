//! LeRobot datasets (format v3.0) in and out: a folder of `meta/info.json`, an episode
//! index and frames in parquet files, as LeRobot's `LeRobotDataset` writes and reads
//! them.
//!
//! Layers: [`error`] (one error type: the file and the fault), [`info`] (the description:
//! rate, robot, features), [`table`] (parquet columns read by name), [`dataset`] (a
//! dataset's episodes, tasks and one episode's frames of a feature), [`mod@write`] (a new
//! dataset laid out as LeRobot's writer lays it out, without video). Matching a feature's
//! entries to a robot's joints, and demonstrations for imitation, are `cps-movement`'s.
//!
//! # Example
//!
//! ```no_run
//! use std::path::Path;
//! use cps_lerobot::Dataset;
//!
//! let ds = Dataset::open(Path::new("datasets/fr3_reach"))?;
//! println!("{} episodes at {} frames/s", ds.episodes().len(), ds.info().fps);
//! let frames = ds.frames(0, "observation.state")?;
//! println!("{} frames of {}", frames.t.len(), frames.names.join(", "));
//! # Ok::<(), cps_lerobot::LeRobotError>(())
//! ```
#![deny(missing_docs)]

pub mod dataset;
pub mod error;
pub mod info;
pub mod table;
pub mod write;

pub use dataset::{Dataset, EpisodeMeta, Frames};
pub use error::LeRobotError;
pub use info::{Feature, Info};
pub use write::{NewDataset, NewEpisode, NewFeature, write};

/// What a build without the crate's `parquet` feature says of a dataset's files.
#[cfg_attr(feature = "parquet", allow(dead_code))]
const NOT_BUILT: &str = "this build of cps reads and writes no parquet (crate cps-lerobot without its `parquet` feature, as the README's first command builds it); `cargo install --path crates/cps-cli` and the tests build it";
