//! An [`Outcome`] as files: `summary.json`, one CSV per table, the documents, one PNG and
//! one SVG per figure and `report.html` (the last two with the `figures` feature) — the
//! same code for every kind, written through a [`Staging`] directory so that the result
//! directory's safety rules ([`crate::results_dir`]) hold.

use std::path::Path;

use crate::outcome::{Outcome, Table};
use crate::results_dir::Staging;
use crate::{Context, ExperimentError};

/// What to write besides the data.
#[derive(Debug, Clone, Copy)]
pub struct WriteOptions {
    /// Draw the figures (PNG + SVG) and put them in the report. Without the `figures`
    /// feature nothing is drawn, and the report is not written.
    pub figures: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        Self { figures: true }
    }
}

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

/// Writes every file of `outcome` into `stage` (not yet committed).
pub fn write_outcome(
    outcome: &Outcome,
    stage: &Staging,
    options: &WriteOptions,
) -> Result<(), ExperimentError> {
    let summary = serde_json::to_vec_pretty(&outcome.summary_json())
        .context_with(|| "cannot encode summary.json".into())?;
    stage.write("summary.json", &summary)?;
    for table in &outcome.tables {
        stage.write(&format!("{}.csv", table.name), &table_csv(table)?)?;
    }
    for doc in &outcome.documents {
        stage.write(&doc.name, &doc.bytes)?;
    }
    #[cfg(feature = "figures")]
    {
        if options.figures {
            for figure in &outcome.figures {
                crate::figures::draw(figure, &stage.path(&format!("{}.png", figure.name)))?;
                crate::figures::draw(figure, &stage.path(&format!("{}.svg", figure.name)))?;
            }
        }
        crate::report::write(outcome, stage, options.figures)?;
    }
    #[cfg(not(feature = "figures"))]
    let _ = options;
    Ok(())
}

/// Writes `outcome` as a result directory at `out` (see [`crate::results_dir`] for what
/// `force` allows): checked, staged, then moved into place. A caller that runs for long
/// should call [`Staging::prepare`] before the run instead, so that a target that cannot
/// be used fails before any work.
pub fn save(
    outcome: &Outcome,
    out: &Path,
    force: bool,
    options: &WriteOptions,
) -> Result<(), ExperimentError> {
    let stage = Staging::prepare(out, force)?;
    write_outcome(outcome, &stage, options)?;
    stage.commit()
}
