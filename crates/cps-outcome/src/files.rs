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
