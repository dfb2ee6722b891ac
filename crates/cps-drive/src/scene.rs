//! The world a command's motions are checked in: a scene file's obstacles around the
//! robot driven (`--scene` on every command that moves a robot; Python's `scene=`).

use std::path::Path;
use std::sync::Arc;

use cps_franka::limits::Arm;
use cps_outcome::InputError;
use cps_robot::Shapes;

use crate::error::DriveError;

/// The world of the scene file at `scene` for the arm `arm`, in the arm's base frame: the
/// scene's robot (its links, its tool) among its obstacles, with the contacts it allows
/// and its margin, for [`crate::franka::ExecuteSettings::world`]. Errors: the file's, in
/// its words, and a scene whose robot is another arm.
pub fn scene_world(scene: &Path, arm: Arm) -> Result<Arc<Shapes>, DriveError> {
    scene_shapes(scene, arm.name())
}

/// The world of the scene file at `scene` for the robot named `robot` (a built-in name,
/// or a robot file's): [`scene_world`] for any robot. Errors: the file's, in its words,
/// and a scene whose robot is another.
pub fn scene_shapes(scene: &Path, robot: &str) -> Result<Arc<Shapes>, DriveError> {
    let s = cps_movement::scene::load_scene(scene)?;
    if s.robot.name != robot {
        return Err(InputError(format!(
            "{}: the scene's robot is `{}`, not the {robot} this command drives",
            scene.display(),
            s.robot.name,
        ))
        .into());
    }
    let shapes = s.robot.shapes.as_ref().ok_or_else(|| {
        InputError(format!(
            "{}: the scene's robot has no collision shapes to check",
            scene.display()
        ))
    })?;
    Ok(Arc::new(shapes.moved(&s.robot.chain.base().inverse())))
}
