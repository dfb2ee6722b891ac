//! A dataset written as LeRobot's own writer lays it out (format v3.0, no video): the
//! frames of every episode in one parquet file (a row group per episode), the episode
//! index, the tasks, the statistics and `meta/info.json` — into a staging folder renamed
//! into place, so a failure leaves no half-written dataset.

use std::path::Path;

use cps_files::replace::{Output, Shape};

use crate::error::LeRobotError;

// The files themselves (the `parquet` feature); without it, a refusal in words.
#[cfg(not(feature = "parquet"))]
#[path = "write/absent.rs"]
mod files;
#[cfg(feature = "parquet")]
#[path = "write/parquet.rs"]
mod files;
use files::write_into;

/// A vector feature of every frame (float32 in the files).
#[derive(Debug, Clone, PartialEq)]
pub struct NewFeature {
    /// Its key: `observation.state`, `action`, …
    pub name: String,
    /// Its entries' names (the joints').
    pub names: Vec<String>,
}

/// One episode: its task's words and, per feature in the dataset's order, one row of
/// values per frame (frame `k` at `k / fps` s).
#[derive(Debug, Clone, PartialEq)]
pub struct NewEpisode {
    /// What was done.
    pub task: String,
    /// `values[feature][frame][entry]`.
    pub values: Vec<Vec<Vec<f64>>>,
}

impl NewEpisode {
    /// Frames.
    pub fn len(&self) -> usize {
        self.values.first().map_or(0, Vec::len)
    }

    /// Whether it has no frame.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// What a new dataset holds besides its episodes.
#[derive(Debug, Clone, PartialEq)]
pub struct NewDataset {
    /// Frames per second (LeRobot's is a whole number).
    pub fps: u32,
    /// The robot, as LeRobot's `robot_type`.
    pub robot_type: Option<String>,
    /// The features, in the files' order.
    pub features: Vec<NewFeature>,
}

const DATA_FILE: &str = "data/chunk-000/file-000.parquet";
const EPISODES_FILE: &str = "meta/episodes/chunk-000/file-000.parquet";
#[cfg_attr(not(feature = "parquet"), allow(dead_code))]
const BOOKKEEPING: [&str; 4] = ["frame_index", "episode_index", "index", "task_index"];

/// The files cps writes, relative to a dataset's root: all a dataset of cps's holds.
pub const FILES: [&str; 5] = [
    crate::info::INFO_PATH,
    "meta/stats.json",
    crate::dataset::TASKS_PATH,
    EPISODES_FILE,
    DATA_FILE,
];

/// Writes the dataset at `root` (its parent must exist) through cps's one writer
/// ([`cps_files::replace`]). `root` must not exist, or, with `replace`, hold only files cps
/// writes ([`FILES`]): a folder holding anything else, or a symbolic link, is never
/// touched. Every episode needs a frame and every feature a row of its width per frame.
/// The dataset is written beside `root`, the old one moved aside, the new one moved in,
/// and only then the old one's files removed, so a failure leaves the old one whole.
pub fn write(
    root: &Path,
    spec: &NewDataset,
    episodes: &[NewEpisode],
    replace: bool,
) -> Result<(), LeRobotError> {
    check(root, spec, episodes)?;
    if !cfg!(feature = "parquet") {
        return Err(LeRobotError::new(root, crate::NOT_BUILT));
    }
    let output = Output::new(root, "LeRobot dataset", Shape::folder(&FILES), replace);
    let staged = output.stage()?;
    write_into(staged.path(), spec, episodes)?;
    staged.commit()?;
    Ok(())
}

fn check(root: &Path, spec: &NewDataset, episodes: &[NewEpisode]) -> Result<(), LeRobotError> {
    if spec.fps == 0 {
        return Err(LeRobotError::new(root, "fps must be ≥ 1"));
    }
    if spec.features.is_empty() {
        return Err(LeRobotError::new(root, "a dataset needs a feature"));
    }
    if episodes.is_empty() {
        return Err(LeRobotError::new(root, "a dataset needs an episode"));
    }
    for (e, ep) in episodes.iter().enumerate() {
        if ep.values.len() != spec.features.len() || ep.is_empty() {
            return Err(LeRobotError::new(
                root,
                format!(
                    "episode {e}: one row per frame for each of the {} features, and a frame at least",
                    spec.features.len()
                ),
            ));
        }
        for (f, rows) in spec.features.iter().zip(&ep.values) {
            if rows.len() != ep.len() {
                return Err(LeRobotError::new(
                    root,
                    format!(
                        "episode {e}: `{}` has {} frames, not {}",
                        f.name,
                        rows.len(),
                        ep.len()
                    ),
                ));
            }
            if let Some((k, row)) = rows
                .iter()
                .enumerate()
                .find(|(_, r)| r.len() != f.names.len() || r.iter().any(|v| !v.is_finite()))
            {
                return Err(LeRobotError::new(
                    root,
                    format!(
                        "episode {e}, frame {k}: `{}` needs {} finite values, got {:?}",
                        f.name,
                        f.names.len(),
                        row
                    ),
                ));
            }
        }
    }
    Ok(())
}
