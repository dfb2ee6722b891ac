//! Files written atomically: a table as CSV text and any bytes through a temporary file
//! and a rename. The whole of an outcome as a result directory is `cps-report`'s.

use std::path::Path;

use cps_files::replace::{self, Output, Shape};

use crate::ExperimentError;
use crate::outcome::Table;

/// Writes a table as CSV text (header, then one line per row).
pub fn table_csv(table: &Table) -> Result<Vec<u8>, ExperimentError> {
    table.check().map_err(ExperimentError::Message)?;
    let mut w = csv::Writer::from_writer(Vec::new());
    let encode = |e: csv::Error| ExperimentError::Failed {
        context: format!("cannot encode {}.csv", table.name),
        source: Box::new(e),
    };
    w.write_record(table.columns.iter().map(|c| c.name.as_str()))
        .map_err(encode)?;
    let mut row = Vec::with_capacity(table.columns.len());
    for k in 0..table.rows() {
        row.clear();
        row.extend(table.columns.iter().map(|c| c.cell(k)));
        w.write_record(&row).map_err(encode)?;
    }
    w.into_inner().map_err(|e| ExperimentError::Failed {
        context: format!("cannot encode {}.csv", table.name),
        source: Box::new(e.into_error()),
    })
}

/// Writes one file as [`write_file`] does, but only where nothing was when the command
/// checked its target (`existed`: whether a file was there then, to be replaced): a file
/// that appeared at `path` since is left alone, and the new one is kept beside it under a
/// name the error gives.
pub fn write_file_unless_new_there(
    path: &Path,
    bytes: &[u8],
    existed: bool,
) -> Result<(), ExperimentError> {
    let output = Output::new(path, "file", Shape::file(|_| true), existed);
    replace::write_file(output, bytes)
        .map(drop)
        .map_err(|e| ExperimentError::Message(e.to_string()))
}

/// Writes one file through cps's one writer ([`cps_files::replace`]): beside it, then
/// renamed into place, so a failure never leaves half a file and a reader never sees one.
/// The caller has checked the target (`check_file_target`); a symbolic link in its place
/// is refused, never written through.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExperimentError> {
    write_file_unless_new_there(path, bytes, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file that appears where a long command was to write its result (and that was not
    /// there when the command checked its target) is the user's: it is left alone, and the
    /// result is kept beside it.
    #[test]
    fn a_file_that_appeared_meanwhile_is_not_overwritten() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("robot.toml");
        write_file_unless_new_there(&out, b"first", false).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"first");
        let e = write_file_unless_new_there(&out, b"second", false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("appeared there while cps worked"), "{e}");
        assert_eq!(std::fs::read(&out).unwrap(), b"first");
        let kept = e.rsplit("kept in ").next().unwrap();
        assert_eq!(std::fs::read(kept).unwrap(), b"second");
        // A file that was there (and checked) is replaced.
        write_file_unless_new_there(&out, b"third", true).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"third");
    }
}
