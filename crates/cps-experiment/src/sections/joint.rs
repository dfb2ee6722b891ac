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
    /// The clearance (m) the movement keeps from the robot's own shapes and its world's,
    /// and its weight per m² (None: not part of the cost).
    pub clearance: Option<(f64, f64)>,
}

impl Sections<'_> {
    /// `[joint]`'s weights, by default 1e6 for the position limits and 1e3 for the speeds,
    /// `learn_on` (`"execution"` needs a robot with dynamics, which `dynamics` says) and
    /// `clearance` (a robot with collision shapes, which `shapes` says).
    pub(crate) fn joint_plan(&self, dynamics: bool, shapes: bool) -> Result<JointPlan, InputError> {
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
        let clearance = match section.and_then(|s| s.clearance.as_ref()) {
            Some(c) => {
                let d = self.within(c, "[joint] `clearance`", 0.0, 0.5, " m")?;
                if !shapes {
                    return Err(self.err(
                        &c.span(),
                        "[joint] `clearance` keeps the robot's collision shapes apart, and this experiment's robot has none (a built-in Franka, or a URDF with <collision> elements)".into(),
                    ));
                }
                let w = weight(
                    section.and_then(|s| s.clearance_weight.as_ref()),
                    "clearance_weight",
                    1e6,
                )?;
                Some((d, w))
            }
            None => {
                if let Some(w) = section.and_then(|s| s.clearance_weight.as_ref()) {
                    return Err(self.err(
                        &w.span(),
                        "[joint] `clearance_weight` weighs a `clearance`: give one".into(),
                    ));
                }
                None
            }
        };
        Ok(JointPlan {
            clearance,
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
