//! `[joint]` of `kind = "viapoint_joint"`: the weights of the joint-limit penalties, and
//! whether the movement is learned on the robot's executions or on its model.

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
    learn_on: Option<Spanned<String>>,
    clearance: Option<Spanned<f64>>,
    clearance_weight: Option<Spanned<f64>>,
}

/// What a joint-space experiment's cost judges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LearnOn {
    /// The commanded movement, through the robot's model.
    Model,
    /// What the robot does with the command (a robot with dynamics), from the command
    /// learned on the model.
    Execution,
}

/// The limit penalties of a joint-space experiment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointPlan {
    /// Weight of the squared position-limit excess.
    pub limit_weight: f64,
    /// Weight of the squared speed-limit excess.
    pub speed_limit_weight: f64,
    /// What the cost judges: by default the execution on a robot with dynamics, the
    /// model on any other.
    pub learn_on: LearnOn,
}

impl Sections<'_> {
    /// `[joint]`'s weights, by default 1e6 for the position limits and 1e3 for the speeds,
    /// and `learn_on` (`"execution"` needs a robot with dynamics, which `dynamics` says).
    /// `clearance` and `clearance_weight` moved to `[clearance]`: refused with where.
    pub(crate) fn joint_plan(&self, dynamics: bool) -> Result<JointPlan, InputError> {
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
        let learn_on = match section.and_then(|s| s.learn_on.as_ref()) {
            None if dynamics => LearnOn::Execution,
            None => LearnOn::Model,
            Some(v) => {
                match v.get_ref().as_str() {
                    "model" => LearnOn::Model,
                    "execution" if dynamics => LearnOn::Execution,
                    "execution" => {
                        return Err(self.err(
                        &v.span(),
                        "[joint] learn_on = \"execution\" learns on what a simulated robot does, thousands of executions: it needs [robot] backend = \"dynamics\"".into(),
                    ));
                    }
                    other => {
                        return Err(self.err(
                        &v.span(),
                        format!("[joint] learn_on must be \"execution\" or \"model\" (got {other:?})"),
                    ));
                    }
                }
            }
        };
        // Kept by every kind that learns a robot's movement now: named where it went.
        for (v, name) in [
            (
                section.and_then(|s| s.clearance.as_ref()),
                "clearance` is `[clearance] distance",
            ),
            (
                section.and_then(|s| s.clearance_weight.as_ref()),
                "clearance_weight` is `[clearance] weight",
            ),
        ] {
            if let Some(v) = v {
                return Err(self.err(
                    &v.span(),
                    format!("[joint] `{name}` (every kind that learns a robot's movement keeps it): move it there"),
                ));
            }
        }
        Ok(JointPlan {
            learn_on,
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
