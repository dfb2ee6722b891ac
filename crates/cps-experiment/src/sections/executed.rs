//! `[executed]` of `kind = "viapoint_executed"`: the weights the executed cost adds.

use cps_learn::ViaPointConfig;
use serde::Deserialize;
use toml::Spanned;

use super::Sections;
use crate::InputError;

/// `[executed]` of `kind = "viapoint_executed"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExecutedSection {
    tracking: Option<Spanned<f64>>,
    speed_usage: Option<Spanned<f64>>,
}

/// The checked `[executed]` section: the weights the executed cost adds to `[cost]`'s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExecutedPlan {
    /// Squared tracking errors (default 1e5, as a via point's) and squared peak joint
    /// speed usages (default 0: off).
    pub weights: cps_learn::ExecutedWeights,
}

impl Sections<'_> {
    /// `[executed]` of `kind = "viapoint_executed"`: the tracking weight; the search must
    /// be CMA-ES on 3-D tool positions.
    pub(crate) fn executed_plan(
        &self,
        learner: &ViaPointConfig,
    ) -> Result<ExecutedPlan, InputError> {
        if learner.solver == cps_learn::Solver::Exact {
            return Err(InputError(format!(
                "{}: kind = \"viapoint_executed\" learns with CMA-ES on the executed cost; the exact solver only knows the analytic cost (it is the warm start here): remove [optimizer] solver = \"exact\"",
                self.path.display()
            )));
        }
        if learner.task.start.len() != 3 {
            return Err(InputError(format!(
                "{}: kind = \"viapoint_executed\" executes tool positions: the task needs 3 coordinates (x, y, z), not {}",
                self.path.display(),
                learner.task.start.len()
            )));
        }
        let section = self.executed.map(Spanned::get_ref);
        let weight = |v: Option<&Spanned<f64>>, name: &str, default: f64| match v {
            Some(v) => self.within(
                v,
                &format!("[executed] `{name}`"),
                0.0,
                cps_learn::MAX_WEIGHT,
                "",
            ),
            None => Ok(default),
        };
        Ok(ExecutedPlan {
            weights: cps_learn::ExecutedWeights {
                tracking: weight(section.and_then(|s| s.tracking.as_ref()), "tracking", 1e5)?,
                speed_usage: weight(
                    section.and_then(|s| s.speed_usage.as_ref()),
                    "speed_usage",
                    0.0,
                )?,
            },
        })
    }
}
