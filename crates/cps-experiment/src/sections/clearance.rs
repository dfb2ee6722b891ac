//! `[clearance]`: the distance a learned movement keeps between the robot's collision
//! shapes and between them and its world's (its scene's and the file's `[[obstacle]]`s),
//! as a term of the learning cost. Every kind that learns a movement for a robot reads
//! it: the joint kind in its cost (on the model and on the executions), the executed kind
//! on every candidate's recording, and the pose, imitation and ProMP kinds in a last stage
//! on the robot's model ([`cps_learn::keep_clear`]). `self_distance` (default: `distance`)
//! is what the robot's own shapes keep from each other. The guard's own margin is `[robot]
//! margin`; the clearance is what learning aims for, at least the margin.

use serde::Deserialize;
use toml::Spanned;

use super::robot::RobotChoice;
use super::{Kind, Sections};
use crate::InputError;

/// `[clearance]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClearanceSection {
    distance: Spanned<f64>,
    self_distance: Option<Spanned<f64>>,
    weight: Option<Spanned<f64>>,
    iterations: Option<Spanned<u64>>,
}

/// The clearance a kind's learning keeps, and the budget of its keep-clear stage.
pub type ClearancePlan = cps_learn::ClearanceStage;

/// The default weight of the squared shortfall (per m²).
pub const DEFAULT_WEIGHT: f64 = 1e6;
/// The default iteration budget of the keep-clear stage.
pub const DEFAULT_ITERATIONS: u64 = 50;

impl Sections<'_> {
    /// `[clearance]` for `robot`, refused for a kind that learns no robot's movement and
    /// for a robot without collision shapes.
    pub(crate) fn clearance_plan(
        &self,
        robot: Option<&RobotChoice>,
    ) -> Result<Option<ClearancePlan>, InputError> {
        let Some(section) = self.clearance else {
            return Ok(None);
        };
        let s = section.get_ref();
        let learns_for_a_robot = matches!(
            self.kind,
            Kind::ViapointJoint
                | Kind::ViapointExecuted
                | Kind::ViapointPose
                | Kind::Imitation
                | Kind::Promp
        );
        let Some(robot) = robot.filter(|_| learns_for_a_robot) else {
            return Err(self.err(
                &section.span(),
                format!(
                    "[clearance] keeps a robot's collision shapes apart while it learns, and kind = \"{}\" learns no robot's movement here (kinds viapoint_joint, viapoint_executed, imitation, promp, and viapoint_pose with a [robot])",
                    self.kind.name()
                ),
            ));
        };
        let Some(shapes) = robot.model.shapes.clone() else {
            return Err(self.err(
                &section.span(),
                format!(
                    "[clearance]: the robot `{}` has no collision geometry to keep clear with (a built-in Franka, fr3 or panda, or a URDF with <collision> elements)",
                    robot.model.name
                ),
            ));
        };
        let distance = self.within(&s.distance, "[clearance] `distance`", 0.0, 0.5, " m")?;
        let self_distance = match &s.self_distance {
            Some(d) => self.within(d, "[clearance] `self_distance`", 0.0, 0.5, " m")?,
            None => distance,
        };
        let weight = match &s.weight {
            Some(w) => self.within(w, "[clearance] `weight`", 0.0, cps_learn::MAX_WEIGHT, "")?,
            None => DEFAULT_WEIGHT,
        };
        let iterations = match &s.iterations {
            Some(i) if (1..=10_000).contains(i.get_ref()) => *i.get_ref(),
            Some(i) => {
                return Err(self.err(
                    &i.span(),
                    format!(
                        "[clearance] `iterations` must be in [1, 10000] (got {})",
                        i.get_ref()
                    ),
                ));
            }
            None => DEFAULT_ITERATIONS,
        };
        Ok(Some(ClearancePlan {
            clearance: cps_learn::Clearance {
                shapes,
                distance,
                self_distance,
                weight,
                stride: cps_learn::CLEARANCE_STRIDE,
            },
            iterations,
        }))
    }
}
