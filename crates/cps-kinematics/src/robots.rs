//! Robot models with published parameters.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::{DhConvention, DhLink, SerialChain};

/// Which point of the Panda the chain ends at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PandaTool {
    /// The flange (URDF `panda_link8`): 0.107 m along joint 7's z axis.
    Flange,
    /// The Franka Hand's tool centre point: the flange turned by −45° about z, then
    /// 0.1034 m along z.
    HandTcp,
}

/// Franka Emika Panda joint limits in radians (Franka's datasheet, via the thesis).
pub const PANDA_Q_MIN: [f64; 7] = [
    -2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973,
];
/// Upper joint limits in radians.
pub const PANDA_Q_MAX: [f64; 7] = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973];
/// Joint speed limits in rad/s.
pub const PANDA_DQ_MAX: [f64; 7] = [2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61];

/// The Franka Emika Panda in its published modified-DH table (Franka documentation),
/// base at the world origin, ending at `tool`, with position and speed limits.
pub fn panda(tool: PandaTool) -> SerialChain {
    let links = vec![
        DhLink::new(0.0, 0.333, 0.0),
        DhLink::new(0.0, 0.0, -FRAC_PI_2),
        DhLink::new(0.0, 0.316, FRAC_PI_2),
        DhLink::new(0.0825, 0.0, FRAC_PI_2),
        DhLink::new(-0.0825, 0.384, -FRAC_PI_2),
        DhLink::new(0.0, 0.0, FRAC_PI_2),
        DhLink::new(0.088, 0.0, FRAC_PI_2),
    ];
    let flange = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.107),
        UnitQuaternion::identity(),
    );
    let tool = match tool {
        PandaTool::Flange => flange,
        PandaTool::HandTcp => {
            flange
                * Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -FRAC_PI_4),
                )
                * Isometry3::translation(0.0, 0.0, 0.1034)
        }
    };
    SerialChain::new(DhConvention::Modified, links)
        .and_then(|c| c.with_tool(tool).with_limits(&PANDA_Q_MIN, &PANDA_Q_MAX))
        .and_then(|c| c.with_velocity_limits(&PANDA_DQ_MAX))
        .expect("the Panda model is valid")
}

/// The Puma 560 in standard DH (Corke's Robotics Toolbox model `Puma560`), for teaching
/// the standard convention.
pub fn puma560() -> SerialChain {
    let links = vec![
        DhLink::new(0.0, 0.67183, FRAC_PI_2),
        DhLink::new(0.4318, 0.0, 0.0),
        DhLink::new(0.0203, 0.15005, -FRAC_PI_2),
        DhLink::new(0.0, 0.4318, FRAC_PI_2),
        DhLink::new(0.0, 0.0, -FRAC_PI_2),
        DhLink::new(0.0, 0.0, 0.0),
    ];
    SerialChain::new(DhConvention::Standard, links).expect("the Puma table is valid")
}

/// The Universal Robots UR3 in standard DH with Universal Robots' published parameters
/// (d1 = 0.1519, a2 = −0.24365, a3 = −0.21325, d4 = 0.11235, d5 = 0.08535,
/// d6 = 0.0819 m; α = π/2, 0, 0, π/2, −π/2, 0), joint limits ±2π, speed limits 180°/s
/// (base, shoulder, elbow) and 360°/s (wrists) from the UR3 datasheet, tool at the flange.
pub fn ur3() -> SerialChain {
    let links = vec![
        DhLink::new(0.0, 0.1519, FRAC_PI_2),
        DhLink::new(-0.24365, 0.0, 0.0),
        DhLink::new(-0.21325, 0.0, 0.0),
        DhLink::new(0.0, 0.11235, FRAC_PI_2),
        DhLink::new(0.0, 0.08535, -FRAC_PI_2),
        DhLink::new(0.0, 0.0819, 0.0),
    ];
    let (pi, tau) = (std::f64::consts::PI, std::f64::consts::TAU);
    SerialChain::new(DhConvention::Standard, links)
        .and_then(|c| c.with_limits(&[-tau; 6], &[tau; 6]))
        .and_then(|c| c.with_velocity_limits(&[pi, pi, pi, tau, tau, tau]))
        .expect("the UR3 model is valid")
}
