//! `[promp]` of `kind = "promp"`: the ProMP's basis and the new via point it is
//! conditioned on.

use serde::Deserialize;
use toml::Spanned;

use super::Sections;
use super::imitation::ImitationPlan;
use crate::InputError;

/// `[promp]` of `kind = "promp"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProMpSection {
    basis_functions: Option<Spanned<usize>>,
    via: Spanned<ProMpVia>,
}

/// `[promp.via]`: the new via point.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProMpVia {
    time: Spanned<f64>,
    position: Spanned<Vec<f64>>,
    #[serde(default)]
    std: Option<Spanned<f64>>,
}

/// A ProMP experiment's settings beyond the imitation pipeline's.
#[derive(Debug, Clone, PartialEq)]
pub struct ProMpPlan {
    /// Basis functions per dimension.
    pub bases: usize,
    /// The via point's time (s, within the demonstrations' mean duration).
    pub time: f64,
    /// Its position (m).
    pub position: Vec<f64>,
    /// Its standard deviation (m; 0: exact).
    pub std: f64,
}

impl Sections<'_> {
    /// `[promp]`: the basis and the via point, within the demonstrations' duration `tau`
    /// and a 10 m reach; a ProMP needs at least 2 demonstrations.
    pub(crate) fn promp_plan(
        &self,
        tau: f64,
        imitation: Option<&ImitationPlan>,
    ) -> Result<ProMpPlan, InputError> {
        let Some(section) = self.promp else {
            return Err(InputError(format!(
                "{}: kind = \"promp\" needs a [promp] section with the new via point: [promp.via] time = …, position = [x, y, z]",
                self.path.display()
            )));
        };
        let s = section.get_ref();
        if let Some(p) = imitation
            && p.demonstrations < 2
        {
            let span = self
                .demonstrations
                .and_then(|d| d.get_ref().count.as_ref())
                .map_or(section.span(), Spanned::span);
            return Err(self.err(
                &span,
                "a ProMP learns the spread of several demonstrations: [demonstrations] `count` must be at least 2".into(),
            ));
        }
        let bases = match &s.basis_functions {
            Some(n) if !(2..=1000).contains(n.get_ref()) => {
                return Err(self.err(
                    &n.span(),
                    format!(
                        "[promp] `basis_functions` must be between 2 and 1000 (got {})",
                        n.get_ref()
                    ),
                ));
            }
            Some(n) => *n.get_ref(),
            None => 20,
        };
        let v = s.via.get_ref();
        let time = self.within(
            &v.time,
            "[promp.via] `time`",
            0.0,
            tau,
            " s (the movement's duration)",
        )?;
        let position = v.position.get_ref().clone();
        if position.len() != 3 || position.iter().any(|x| !x.is_finite() || x.abs() > 10.0) {
            return Err(self.err(
                &v.position.span(),
                format!(
                    "[promp.via] `position` must be three finite coordinates within 10 m (got {position:?})"
                ),
            ));
        }
        let std = match &v.std {
            Some(s) => self.within(s, "[promp.via] `std`", 0.0, 10.0, " m")?,
            None => 0.0,
        };
        Ok(ProMpPlan {
            bases,
            time,
            position,
            std,
        })
    }
}
