//! `[scaling]` of `kind = "scaling"`: the parametrisations compared.

use cps_learn::Parametrisation;
use serde::Deserialize;
use toml::Spanned;

use super::Sections;
use crate::InputError;

/// `[scaling]` of `kind = "scaling"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScalingSection {
    compare: Option<Spanned<Vec<Parametrisation>>>,
}

/// The parametrisations a scaling experiment compares.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalingPlan {
    /// In order; each runs the experiment's repetitions.
    pub compare: Vec<Parametrisation>,
}

impl Sections<'_> {
    /// `[scaling] compare`, by default the thesis's scaled weights against raw ones.
    pub(crate) fn scaling_plan(&self) -> Result<ScalingPlan, InputError> {
        let compare = match self.scaling.and_then(|s| s.get_ref().compare.as_ref()) {
            Some(c) if c.get_ref().is_empty() => {
                return Err(self.err(
                    &c.span(),
                    "[scaling] `compare` must name at least one parametrisation".into(),
                ));
            }
            Some(c) => c.get_ref().clone(),
            None => vec![Parametrisation::ThesisScaling, Parametrisation::Raw],
        };
        Ok(ScalingPlan { compare })
    }
}
