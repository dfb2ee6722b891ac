//! Files written atomically: a table as CSV text and any bytes through a temporary file
//! and a rename. The whole of an outcome as a result directory is `cps-report`'s.

use std::path::Path;

use crate::outcome::Table;
use crate::{Context, ExperimentError};

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
    if existed {
        return write_file(path, bytes);
    }
    let name = path
        .file_name()
        .map_or("file".into(), |n| n.to_string_lossy().into_owned());
    let kept = path.with_file_name(format!("{name}.cps-new-{}", std::process::id()));
    write_file(&kept, bytes)?;
    // A hard link is made only where no file is: the no-replace rename of every Unix.
    match std::fs::hard_link(&kept, path) {
        Ok(()) => {
            std::fs::remove_file(&kept).ok();
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            Err(ExperimentError::Message(format!(
                "{}: a file appeared there while cps worked, and cps did not write it, so it is left alone; the result is in {}",
                path.display(),
                kept.display()
            )))
        }
        Err(_) => {
            // A file system without hard links: rename, after a last look.
            if std::fs::symlink_metadata(path).is_ok() {
                return Err(ExperimentError::Message(format!(
                    "{}: a file appeared there while cps worked, and cps did not write it, so it is left alone; the result is in {}",
                    path.display(),
                    kept.display()
                )));
            }
            std::fs::rename(&kept, path).context_with(|| format!("cannot write {}", path.display()))
        }
    }
}

/// Writes one file through a temporary file beside it and a rename, so a failure never
/// leaves half a file and a reader never sees one. The temporary name is fresh (an
/// existing file there is never overwritten).
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExperimentError> {
    use std::io::Write;
    let name = path
        .file_name()
        .map_or("file".into(), |n| n.to_string_lossy().into_owned());
    let tmp = path.with_file_name(format!(".{name}.cps-tmp-{}", std::process::id()));
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .context_with(|| format!("cannot write {}", path.display()))?;
    let written = f.write_all(bytes).and_then(|()| f.sync_all());
    drop(f);
    if let Err(e) = written.and_then(|()| std::fs::rename(&tmp, path)) {
        std::fs::remove_file(&tmp).ok();
        return Err(ExperimentError::Failed {
            context: format!("cannot write {}", path.display()),
            source: Box::new(e),
        });
    }
    Ok(())
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
        let kept = d
            .path()
            .join(format!("robot.toml.cps-new-{}", std::process::id()));
        assert_eq!(std::fs::read(kept).unwrap(), b"second");
        // A file that was there (and checked) is replaced.
        write_file_unless_new_there(&out, b"third", true).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"third");
    }
}
