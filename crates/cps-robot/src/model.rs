//! What cps knows of a robot it drives: its kinematics, joint names and every limit.

use std::sync::Arc;

use cps_kinematics::{CartesianLimits, JointLimits, LinkInertia, RobotLimits, SerialChain};

use crate::collision::Shapes;
use crate::setting::SettingError;

/// A robot's model: the chain (base placed, tool point set), its joint names, its limits
/// beyond the chain's range and speed, and its inertias where known. Robot files
/// (cps-experiment's `robot_file`) make one from a built-in name, TOML or URDF.
#[derive(Debug, Clone)]
pub struct RobotModel {
    /// Its name (built-in name, the file's `name`, or the URDF robot's name).
    pub name: String,
    /// The chain with the chosen tool point and base.
    pub chain: SerialChain,
    /// A configuration to start inverse kinematics from.
    pub ready: Vec<f64>,
    /// Which tool point the chain ends at, in words.
    pub tool: String,
    /// Joint names (URDF) or `joint1..n`.
    pub joint_names: Vec<String>,
    /// Limits beyond the chain's range and speed (empty where the robot's data have none).
    pub limits: JointLimits,
    /// Link inertias for inverse dynamics, when the robot's data give them.
    pub inertia: Option<Vec<LinkInertia>>,
    /// Limits of the tool's (and the elbow's) Cartesian motion, when the robot's data give
    /// them (the Panda's; TOML `[cartesian]`).
    pub cartesian: Option<CartesianLimits>,
    /// Its collision geometry among its scene's obstacles, which the guard checks every
    /// plan against; None where the robot's data have no shapes (then nothing is checked
    /// for collisions, and [`RobotModel::shapes_note`] says so).
    pub shapes: Option<Arc<Shapes>>,
}

impl RobotModel {
    /// A model of `chain` alone: joints named `joint1..n`, no limits beyond the chain's
    /// range and speed, no inertias.
    pub fn of_chain(name: &str, chain: SerialChain) -> Self {
        let n = chain.dof();
        RobotModel {
            name: name.to_string(),
            ready: vec![0.0; n],
            tool: "the chain's tool".into(),
            joint_names: (1..=n).map(|i| format!("joint{i}")).collect(),
            limits: JointLimits::default(),
            inertia: None,
            cartesian: None,
            shapes: None,
            chain,
        }
    }

    /// What a user must know when the robot has no collision geometry: that its plans are
    /// checked against its limits only. None when it has shapes.
    pub fn shapes_note(&self) -> Option<String> {
        self.shapes.is_none().then(|| {
            format!(
                "the robot `{}` has no collision geometry: plans are checked against its limits, not for collisions",
                self.name
            )
        })
    }

    /// The same robot keeping clearance `margin` (m) among the same obstacles. Errors: the
    /// robot has no shapes, or the margin is not a finite distance ≥ 0.
    pub fn with_margin(&self, margin: f64) -> Result<Self, SettingError> {
        let Some(shapes) = &self.shapes else {
            return Err(SettingError::NoShapes(self.name.clone()));
        };
        Ok(RobotModel {
            shapes: Some(Arc::new(shapes.with_margin(margin)?)),
            ..self.clone()
        })
    }

    /// The same robot among `obstacles`, where the pairs in `allowed` may touch, keeping
    /// `margin` when given. A robot without shapes gains none: it stays unchecked (and
    /// says so). Errors: as [`Shapes::with_obstacles`] and [`Shapes::with_margin`].
    pub fn in_scene(
        &self,
        obstacles: Vec<cps_geometry::Obstacle>,
        allowed: Vec<(String, String)>,
        margin: Option<f64>,
    ) -> Result<Self, SettingError> {
        let Some(shapes) = &self.shapes else {
            return Ok(self.clone());
        };
        let mut shapes = shapes.with_obstacles(obstacles, allowed)?;
        if let Some(m) = margin {
            shapes = shapes.with_margin(m)?;
        }
        Ok(RobotModel {
            shapes: Some(Arc::new(shapes)),
            ..self.clone()
        })
    }

    /// The robot's limits and dynamics as checks and retiming take them (gravity along the
    /// world's −z).
    pub fn robot_limits(&self) -> RobotLimits<'_> {
        RobotLimits {
            chain: &self.chain,
            limits: &self.limits,
            inertia: self.inertia.as_deref(),
            gravity: nalgebra::Vector3::from(cps_kinematics::GRAVITY),
            cartesian: self.cartesian.as_ref(),
        }
    }

    /// The joint names the robot's joint states and controllers use: its own (a URDF's), or
    /// `<robot>_joint<i>` for the generic `joint<i>` of a DH robot (`panda_joint1`, as
    /// franka_description names them).
    pub fn published_joint_names(&self) -> Vec<String> {
        let generic = self
            .joint_names
            .iter()
            .enumerate()
            .all(|(i, n)| *n == format!("joint{}", i + 1));
        if generic {
            (1..=self.joint_names.len())
                .map(|i| format!("{}_joint{i}", self.name))
                .collect()
        } else {
            self.joint_names.clone()
        }
    }

    /// The same robot placed and tooled by `chain` (a scene's base and tool point): the
    /// kinematics change, names, limits and inertias stay.
    pub fn with_chain(&self, chain: SerialChain) -> Self {
        RobotModel {
            chain,
            ..self.clone()
        }
    }
}
