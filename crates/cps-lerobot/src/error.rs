//! The one error: a file and what is wrong with it, in a sentence.

use std::path::{Path, PathBuf};

/// What went wrong with which file of a dataset: `"<file>: <fault>"`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {what}", path.display())]
pub struct LeRobotError {
    /// The file (or the dataset's folder) at fault.
    pub path: PathBuf,
    /// What is wrong, in a sentence.
    pub what: String,
}

impl LeRobotError {
    /// An error of `path`.
    pub fn new(path: &Path, what: impl Into<String>) -> Self {
        LeRobotError {
            path: path.to_path_buf(),
            what: what.into(),
        }
    }

    /// `path` could not be read: `missing` (what its absence means) when it is not
    /// there, else the system's words.
    pub fn unread(path: &Path, e: &std::io::Error, missing: &str) -> Self {
        LeRobotError::new(
            path,
            if e.kind() == std::io::ErrorKind::NotFound {
                missing.to_string()
            } else {
                format!("cannot be read: {e}")
            },
        )
    }
}

impl From<cps_files::FileError> for LeRobotError {
    fn from(e: cps_files::FileError) -> Self {
        let path = e.path().map(Path::to_path_buf).unwrap_or_default();
        LeRobotError {
            path,
            what: e.reason(),
        }
    }
}
