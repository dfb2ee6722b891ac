//! A robot's recording and its report on disk, the same for every robot cps records
//! (a Franka's `execute`/`record`/`guide`, ROS 2's `send --record`/`record`): `rec.csv`
//! with `rec.report.json` beside it, both checked before anything moves.

use std::path::{Path, PathBuf};

use cps_outcome::InputError;
use cps_outcome::results_dir::{FileKind, check_file_target};

/// The recording's file and its report beside it: `rec.csv` → `rec.report.json`.
pub fn report_path(record: &Path) -> PathBuf {
    let stem = record
        .file_stem()
        .map_or("recording".into(), |s| s.to_string_lossy().into_owned());
    record.with_file_name(format!("{stem}.report.json"))
}

/// Checks before anything moves that the recording and its report may be written.
pub fn check_record_target(record: &Path, force: bool) -> Result<(), InputError> {
    check_file_target(record, FileKind::TrajectoryCsv, force)?;
    check_file_target(&report_path(record), FileKind::RecordingReport, force)
}
