//! A tool pose as one movement: a position DMP and an orientation DMP on one phase.

use nalgebra::{DMatrix, UnitQuaternion};

use crate::{
    DiscreteDmp, DmpConfig, DmpError, OrientationTrajectory, QuaternionDmp, Retarget, Trajectory,
};

/// Position (3-D) and orientation of a tool, driven by one canonical system: both parts
/// are built from the same [`DmpConfig`] (gains, τ, phase decay, grid), so they share the
/// phase signal sample for sample ([`PoseDmp::phases`]) and end together. Weights:
/// `3 · n_basis` for the position, `3 · n_basis` for the orientation.
#[derive(Debug, Clone)]
pub struct PoseDmp {
    position: DiscreteDmp,
    orientation: QuaternionDmp,
}

/// A pose movement carried to new endpoints ([`PoseDmp::retarget`]).
#[derive(Debug, Clone)]
pub struct RetargetedPose {
    /// The pose DMP (goal-robust form, new endpoints).
    pub dmp: PoseDmp,
    /// Position weights.
    pub position_weights: Vec<f64>,
    /// Orientation weights.
    pub orientation_weights: Vec<f64>,
    /// The rotation applied to both forcing terms.
    pub rotation: DMatrix<f64>,
    /// The scale applied to the position's forcing.
    pub scale: f64,
}

impl PoseDmp {
    /// A pose DMP from (`start`, `start_q`) to (`goal`, `goal_q`), positions of 3
    /// coordinates.
    pub fn new(
        config: DmpConfig,
        start: &[f64],
        goal: &[f64],
        start_q: UnitQuaternion<f64>,
        goal_q: UnitQuaternion<f64>,
    ) -> Result<Self, DmpError> {
        if start.len() != 3 {
            return Err(DmpError::DimensionMismatch {
                what: "pose start position",
                got: start.len(),
                expected: 3,
            });
        }
        let position = DiscreteDmp::new(config, start, goal)?;
        let orientation = QuaternionDmp::new(config, start_q, goal_q)?;
        Ok(Self {
            position,
            orientation,
        })
    }

    /// The position part.
    pub fn position(&self) -> &DiscreteDmp {
        &self.position
    }

    /// The orientation part.
    pub fn orientation(&self) -> &QuaternionDmp {
        &self.orientation
    }

    /// The shared phase at every sample.
    pub fn phases(&self) -> &[f64] {
        self.position.phases()
    }

    /// Both parts rolled out on the shared grid.
    ///
    /// # Panics
    /// If a weight vector has the wrong length.
    pub fn rollout(
        &self,
        position_weights: &[f64],
        orientation_weights: &[f64],
    ) -> (Trajectory, OrientationTrajectory) {
        (
            self.position.rollout(position_weights),
            self.orientation.rollout(orientation_weights),
        )
    }

    /// The pose movement carried to new endpoints: the position by `mode`
    /// ([`DiscreteDmp::retarget`]), the orientation's forcing turned by the same rotation
    /// (a world-frame angular forcing turns with the task; angles are not scaled), both in
    /// the goal-robust form so neither starts with a jump.
    ///
    /// # Panics
    /// If a weight vector has the wrong length.
    #[allow(clippy::too_many_arguments)]
    pub fn retarget(
        &self,
        position_weights: &[f64],
        orientation_weights: &[f64],
        start: &[f64],
        goal: &[f64],
        start_q: UnitQuaternion<f64>,
        goal_q: UnitQuaternion<f64>,
        mode: Retarget,
    ) -> Result<RetargetedPose, DmpError> {
        let moved = self
            .position
            .retarget(position_weights, start, goal, mode)?;
        let (orientation, w) =
            self.orientation
                .goal_robust(orientation_weights, start_q, goal_q)?;
        let nb = self.position.n_basis();
        let r = &moved.rotation;
        let mut turned = vec![0.0; w.len()];
        for i in 0..nb {
            for a in 0..3 {
                turned[a * nb + i] = (0..3).map(|b| r[(a, b)] * w[b * nb + i]).sum();
            }
        }
        Ok(RetargetedPose {
            dmp: PoseDmp {
                position: moved.dmp,
                orientation,
            },
            position_weights: moved.weights,
            orientation_weights: turned,
            rotation: moved.rotation,
            scale: moved.scale,
        })
    }
}
