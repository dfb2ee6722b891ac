//! A build without the parquet writer (the crate's `parquet` feature off): writing a
//! dataset is refused in words, before anything is written.

use std::path::Path;

use super::{NewDataset, NewEpisode};
use crate::error::LeRobotError;

/// Refuses: this build writes no parquet.
pub(super) fn write_into(
    dir: &Path,
    _spec: &NewDataset,
    _episodes: &[NewEpisode],
) -> Result<(), LeRobotError> {
    Err(LeRobotError::new(dir, crate::NOT_BUILT))
}
