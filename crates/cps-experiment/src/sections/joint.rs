//! `[joint]` of `kind = "viapoint_joint"`: the weights of the joint-limit penalties.

use serde::Deserialize;
use toml::Spanned;

use super::Sections;
use crate::InputError;

/// `[joint]` of `kind = "viapoint_joint"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSection {
    limit_weight: Option<Spanned<f64>>,
    speed_limit_weight: Option<Spanned<f64>>,
}

/// The limit penalties of a joint-space experiment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointPlan {
    /// Weight of the squared position-limit excess.
    pub limit_weight: f64,
    /// Weight of the squared speed-limit excess.
    pub speed_limit_weight: f64,
}

impl Sections<'_> {
    /// `[joint]`'s weights, by default 1e6 for the position limits and 1e3 for the speeds.
    pub(crate) fn joint_plan(&self) -> Result<JointPlan, InputError> {
        let section = self.joint.map(Spanned::get_ref);
        let weight = |v: Option<&Spanned<f64>>, name: &str, default: f64| match v {
            Some(v) => self.within(
                v,
                &format!("[joint] `{name}`"),
                0.0,
                cps_learn::MAX_WEIGHT,
                "",
            ),
            None => Ok(default),
        };
        Ok(JointPlan {
            limit_weight: weight(
                section.and_then(|s| s.limit_weight.as_ref()),
                "limit_weight",
                1e6,
            )?,
            speed_limit_weight: weight(
                section.and_then(|s| s.speed_limit_weight.as_ref()),
                "speed_limit_weight",
                1e3,
            )?,
        })
    }
}
