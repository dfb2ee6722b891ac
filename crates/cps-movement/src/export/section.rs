//! `[export]` of robot experiments: retime the movement, and write it for ROS 2 and viewers.
//!
//! ```toml
//! [export]
//! retime = "fastest"                       # or "uniform"; absent: the movement's own timing
//! formats = ["ros2-yaml", "mcap", "csv-1khz"]
//! period = 0.01                            # s between exported points (ros2-yaml, mcap)
//! ```

use std::ops::Range;

use serde::Deserialize;
use toml::Spanned;

use super::{ExportFormat, ExportOptions};
use crate::retiming::RetimeMode;
use cps_outcome::InputError;

/// `[export]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExportSection {
    retime: Option<Spanned<String>>,
    #[serde(default)]
    formats: Vec<Spanned<String>>,
    period: Option<Spanned<f64>>,
}

/// `[export]` checked.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportPlan {
    /// Retime the movement before writing it (and report the retimed limit usage).
    pub retime: Option<RetimeMode>,
    /// The formats written, each once.
    pub formats: Vec<ExportFormat>,
    /// Their settings.
    pub options: ExportOptions,
}

impl ExportSection {
    /// Checks the section; `err` names a place of the file.
    pub fn plan(
        &self,
        err: &dyn Fn(&Range<usize>, String) -> InputError,
    ) -> Result<ExportPlan, InputError> {
        let retime = match &self.retime {
            None => None,
            Some(r) if r.get_ref() == "none" => None,
            Some(r) => Some(
                RetimeMode::parse(r.get_ref())
                    .map_err(|m| err(&r.span(), format!("[export] `retime`: {m}, or `none`")))?,
            ),
        };
        let mut formats = Vec::new();
        for f in &self.formats {
            let format = ExportFormat::parse(f.get_ref())
                .map_err(|m| err(&f.span(), format!("[export] `formats`: {m}")))?;
            if formats.contains(&format) {
                return Err(err(
                    &f.span(),
                    format!("[export] `formats`: `{}` is named twice", f.get_ref()),
                ));
            }
            formats.push(format);
        }
        let mut options = ExportOptions::default();
        if let Some(p) = &self.period {
            options.period = *p.get_ref();
            options.check().map_err(|_| {
                err(
                    &p.span(),
                    format!(
                        "[export] `period` must be between 0.0001 and 1 s (got {:?})",
                        p.get_ref()
                    ),
                )
            })?;
        }
        Ok(ExportPlan {
            retime,
            formats,
            options,
        })
    }
}
