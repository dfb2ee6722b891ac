//! A build without the parquet reader (the crate's `parquet` feature off): reading a
//! dataset's files is refused in words.

use std::path::Path;

use super::Cell;
use crate::error::LeRobotError;

/// Refuses: this build reads no parquet.
pub(super) fn read_unguarded(
    path: &Path,
    _columns: &[&str],
    _filter: Option<(&str, std::ops::RangeInclusive<i64>)>,
) -> Result<Vec<Vec<Cell>>, LeRobotError> {
    Err(LeRobotError::new(path, crate::NOT_BUILT))
}
