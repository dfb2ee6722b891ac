//! An [`Outcome`] as files: `summary.json`, one CSV per table, the documents, one PNG and
//! one SVG per figure and `report.html` (the last two with the `figures` feature) — the
//! same code for every kind, written through a [`Staging`] directory so that the result
//! directory's safety rules ([`cps_outcome::results_dir`]) hold.

use std::path::Path;

use cps_outcome::files::table_csv;
use cps_outcome::outcome::Outcome;
use cps_outcome::results_dir::Staging;
use cps_outcome::{Context, ExperimentError};

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

/// A result directory claimed before a run and filled after it: [`Results::prepare`]
/// checks the target and makes its staging directory before any work (a target that
/// cannot be used fails at once), [`Results::finish`] writes the outcome and moves it into
/// place. The one sequence behind `cps-cli run`, Python's `run_experiment(out=…)` and
/// [`save`]; a results directory dropped without `finish` leaves nothing behind.
#[derive(Debug)]
pub struct Results {
    stage: Staging,
    options: WriteOptions,
}

impl Results {
    /// Claims `out` (see [`cps_outcome::results_dir`] for what `force` allows).
    pub fn prepare(
        out: &Path,
        force: bool,
        options: WriteOptions,
    ) -> Result<Self, cps_outcome::InputError> {
        Ok(Self {
            stage: Staging::prepare(out, force)?,
            options,
        })
    }

    /// Writes every file of `outcome` and moves them into place.
    pub fn finish(self, outcome: &Outcome) -> Result<(), ExperimentError> {
        write_outcome(outcome, &self.stage, &self.options)?;
        self.stage.commit()
    }
}

/// Writes `outcome` as a result directory at `out` (see [`cps_outcome::results_dir`] for what
/// `force` allows): checked, staged, then moved into place. A caller that runs for long
/// should claim the directory with [`Results::prepare`] before the run instead, so that a
/// target that cannot be used fails before any work.
pub fn save(
    outcome: &Outcome,
    out: &Path,
    force: bool,
    options: &WriteOptions,
) -> Result<(), ExperimentError> {
    Results::prepare(out, force, *options)?.finish(outcome)
}
