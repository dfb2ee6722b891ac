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
/// The ready pose of the Panda and the FR3, in radians: Franka's home configuration
/// (q2 = −π/4, q4 = −3π/4, q6 = π/2, q7 = π/4) to three decimals, as franka_ros, MoveIt's
/// `ready` state and the thesis give it. The one copy cps's code and tests use.
pub const PANDA_READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];

/// The thesis's initial configuration of its Panda (configs/scenes/thesis.toml): the arm
/// straight up, the hand turned (q6 = π/2, q7 = π/4). Joint 4 at 0 is just above the
/// Panda's range; a start state, never commanded further out.
pub const PANDA_THESIS_START: [f64; 7] = [
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    std::f64::consts::FRAC_PI_2,
    std::f64::consts::FRAC_PI_4,
];

/// The Franka Emika Panda in its published modified-DH table (Franka documentation),
/// base at the world origin, ending at `tool`, with position and speed limits.
pub fn panda(tool: PandaTool) -> SerialChain {
    let links = panda_links();
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

/// The Panda's (and FR3's) modified-DH table.
fn panda_links() -> Vec<DhLink> {
    vec![
        DhLink::new(0.0, 0.333, 0.0),
        DhLink::new(0.0, 0.0, -FRAC_PI_2),
        DhLink::new(0.0, 0.316, FRAC_PI_2),
        DhLink::new(0.0825, 0.0, FRAC_PI_2),
        DhLink::new(-0.0825, 0.384, -FRAC_PI_2),
        DhLink::new(0.0, 0.0, FRAC_PI_2),
        DhLink::new(0.088, 0.0, FRAC_PI_2),
    ]
}

/// Franka Research 3 joint limits in radians (Franka's "Robot and interface
/// specifications", Limits for Franka Research 3).
pub const FR3_Q_MIN: [f64; 7] = [-2.7437, -1.7837, -2.9007, -3.0421, -2.8065, 0.5445, -3.0159];
/// Upper joint limits in radians.
pub const FR3_Q_MAX: [f64; 7] = [2.7437, 1.7837, 2.9007, -0.1518, 2.8065, 4.5169, 3.0159];
/// The FR3's largest joint speeds in rad/s (reached in the middle of the range; the robot
/// allows less near the range's ends, which `cps-franka` checks).
pub const FR3_DQ_MAX: [f64; 7] = [2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26];

/// The Franka Research 3: the Panda's kinematics (Franka publishes one modified-DH table
/// for both), the FR3's joint range and speeds.
pub fn fr3(tool: PandaTool) -> SerialChain {
    let panda = panda(tool);
    SerialChain::new(DhConvention::Modified, panda_links())
        .map(|c| c.with_tool(panda.tool()))
        .and_then(|c| c.with_limits(&FR3_Q_MIN, &FR3_Q_MAX))
        .and_then(|c| c.with_velocity_limits(&FR3_DQ_MAX))
        .expect("the FR3 model is valid")
}

/// The FR3's limits beyond its joint range and speed: acceleration 10 rad/s², jerk 5000
/// rad/s³ on every joint, torque 87 N m (joints 1–4) and 12 N m (5–7), torque rate 1000
/// N m/s.
pub fn fr3_limits() -> crate::JointLimits {
    crate::JointLimits {
        acceleration: Some(vec![10.0; 7]),
        jerk: Some(vec![5000.0; 7]),
        torque: Some(vec![87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
        torque_rate: Some(vec![1000.0; 7]),
    }
}

/// The Panda's limits beyond its joint range and speed (Franka's control parameters, the
/// thesis's Tables 5 and 6): acceleration [15, 7.5, 10, 12.5, 15, 20, 20] rad/s², jerk
/// [7500, 3750, 5000, 6250, 7500, 10000, 10000] rad/s³, torque 87 N m (joints 1–4) and
/// 12 N m (5–7), torque rate 1000 N m/s; Cartesian translation 1.7 m/s, 13 m/s², 6500
/// m/s³, rotation 2.5 rad/s, 25 rad/s², 12500 rad/s³, elbow 2.175 rad/s, 10 rad/s²,
/// 5000 rad/s³.
pub fn panda_limits() -> (crate::JointLimits, crate::CartesianLimits) {
    (
        crate::JointLimits {
            acceleration: Some(vec![15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]),
            jerk: Some(vec![
                7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0,
            ]),
            torque: Some(vec![87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
            torque_rate: Some(vec![1000.0; 7]),
        },
        crate::CartesianLimits {
            translation: [1.7, 13.0, 6500.0],
            rotation: [2.5, 25.0, 12500.0],
            elbow: [2.175, 10.0, 5000.0],
        },
    )
}

/// The Panda's link inertias (links 1–7, in the modified-DH link frames of [`panda`]):
/// C. Gaz, M. Cognetti, A. Oliva, P. Robuffo Giordano, A. De Luca, "Dynamic Identification
/// of the Franka Emika Panda Robot With Retrieval of Feasible Parameters Using
/// Penalty-Based Optimization", IEEE RA-L 4(4):4147–4154, 2019
/// (doi 10.1109/LRA.2019.2931248), supplementary Tables VIII (mass, centre of mass) and IX
/// (inertia about the centre of mass), column p̂. Link 7's centre of mass is in the frame
/// of joint 7 (the flange is 0.107 m further along z); whether the identified link 7
/// includes a mounted hand is not stated in the paper.
pub fn panda_inertia() -> Vec<crate::LinkInertia> {
    const MASS: [f64; 7] = [
        4.970684, 0.646926, 3.228604, 3.587895, 1.225946, 1.666555, 0.735522,
    ];
    const COM: [[f64; 3]; 7] = [
        [3.875e-3, 2.081e-3, 0.0],
        [-3.141e-3, -2.872e-2, 3.495e-3],
        [2.7518e-2, 3.9252e-2, -6.6502e-2],
        [-5.317e-2, 1.04419e-1, 2.7454e-2],
        [-1.1953e-2, 4.1065e-2, -3.8437e-2],
        [6.0149e-2, -1.4117e-2, -1.0517e-2],
        [1.0517e-2, -4.252e-3, 6.1597e-2],
    ];
    // xx, xy, xz, yy, yz, zz
    const INERTIA: [[f64; 6]; 7] = [
        [
            7.0337e-1, -1.39e-4, 6.772e-3, 7.0661e-1, 1.9169e-2, 9.117e-3,
        ],
        [7.962e-3, -3.925e-3, 1.0254e-2, 2.811e-2, 7.04e-4, 2.5995e-2],
        [
            3.7242e-2, -4.761e-3, -1.1396e-2, 3.6155e-2, -1.2805e-2, 1.083e-2,
        ],
        [
            2.5853e-2, 7.796e-3, -1.332e-3, 1.9552e-2, 8.641e-3, 2.8323e-2,
        ],
        [
            3.5549e-2, -2.117e-3, -4.037e-3, 2.9474e-2, 2.29e-4, 8.627e-3,
        ],
        [1.964e-3, 1.09e-4, -1.158e-3, 4.354e-3, 3.41e-4, 5.433e-3],
        [
            1.2516e-2, -4.28e-4, -1.196e-3, 1.0027e-2, -7.41e-4, 4.815e-3,
        ],
    ];
    (0..7)
        .map(|i| {
            crate::LinkInertia::new(MASS[i], COM[i], INERTIA[i])
                .expect("the published Panda inertias are physical")
        })
        .collect()
}

/// The FR3's link inertias with the Franka Hand (links 1–7, in the modified-DH link frames
/// of [`fr3`]): MuJoCo Menagerie's `franka_fr3` model as franky-sim 1.0.4 simulates it
/// (its `assets/fr3.xml`: each link's mass, centre of mass and principal inertia with
/// their rotation, here as full tensors in the link frame), the hand (0.73 kg) and its two
/// fingers (0.015 kg each, closed) lumped into link 7. Franka publishes no FR3 inertias;
/// a robot's own URDF may differ. Checked against MuJoCo's model in
/// `tests/dynamics_references.rs`.
pub fn fr3_inertia() -> Vec<crate::LinkInertia> {
    // mass (kg), centre of mass (m), inertia about it [xx, xy, xz, yy, yz, zz] (kg m²)
    #[allow(clippy::type_complexity)]
    #[rustfmt::skip]
    const LINKS: [(f64, [f64; 3], [f64; 6]); 7] = [
        // link 1
        (2.92747, [4.128e-07, -0.0181251, -0.038603600000000016], [0.0239272947453272, 1.3317329788107953e-05, -0.00011405132217046329, 0.022482145850047302, -0.0019950291857125674, 0.006350099404625492]),
        // link 2
        (2.93554, [0.003182889999999998, -0.07432219999999999, 0.008814609999999997], [0.04193888988947939, 0.00020260103310274513, 0.004077780185739441, 0.025145189270313572, -0.004225231794533555, 0.061702120840206945]),
        // link 3
        (2.2449, [0.040701599999999956, -0.004820059999999997, -0.02897309999999996], [0.024101442056873063, 0.002404684264507136, -0.002856268891830047, 0.019740547576264283, -0.0021042136745217186, 0.019044510366862537]),
        // link 4
        (2.6156, [-0.04591009999999996, 0.06304929999999995, -0.008518789999999993], [0.03453001857862377, 0.013225509072017213, 0.010151429202577247, 0.02888165694155812, -0.0009763068693925302, 0.04125472447981795]),
        // link 5
        (2.32712, [-0.0016039599999999978, 0.02925359999999996, -0.0972966], [0.0516103145079603, -0.005715182416436148, -0.003567316377181673, 0.047877334885637494, 0.010673987029002994, 0.016423650606401916]),
        // link 6
        (1.81704, [0.0597130999999999, -0.04102950000000002, -0.010169299999999982], [0.005412321871612666, 0.006193448335563139, 0.001421924523039488, 0.014058346410593439, -0.001314072230401392, 0.01608082171779377]),
        // link 7 with the Franka Hand and its fingers
        (1.3871429999999998, [-0.0016765216664566803, 0.007621228667541727, 0.06836735617603923], [0.010170559799783563, 0.000719976729484289, 0.0006396728947933015, 0.010179652955212788, 0.00019046598882967758, 0.0018094573697561018]),
    ];
    LINKS
        .iter()
        .map(|(m, c, i)| {
            crate::LinkInertia::new(*m, *c, *i).expect("MuJoCo's FR3 inertias are physical")
        })
        .collect()
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

/// The UR3's torque limits: 56, 56, 28, 12, 12, 12 N m (Universal Robots'
/// Universal_Robots_ROS2_Description, `config/ur3/joint_limits.yaml`, `max_effort`); UR
/// publishes no acceleration or jerk limits.
pub fn ur3_limits() -> crate::JointLimits {
    crate::JointLimits {
        torque: Some(vec![56.0, 56.0, 28.0, 12.0, 12.0, 12.0]),
        ..crate::JointLimits::default()
    }
}

/// The UR3's links as point masses at their centres of mass (in the standard-DH link frames
/// of [`ur3`]): masses 2, 3.42, 1.26, 0.8, 0.8, 0.35 kg from Universal Robots' support
/// article "DH Parameters for calculations of kinematics and dynamics", which gives no
/// inertia tensors (Universal Robots' ROS description approximates them by cylinders).
pub fn ur3_inertia() -> Vec<crate::LinkInertia> {
    const MASS: [f64; 6] = [2.0, 3.42, 1.26, 0.8, 0.8, 0.35];
    const COM: [[f64; 3]; 6] = [
        [0.0, -0.02, 0.0],
        [0.13, 0.0, 0.1157],
        [0.05, 0.0, 0.0238],
        [0.0, 0.0, 0.01],
        [0.0, 0.0, 0.01],
        [0.0, 0.0, -0.02],
    ];
    MASS.iter()
        .zip(COM)
        .map(|(m, c)| crate::LinkInertia::new(*m, c, [0.0; 6]).expect("a point mass is valid"))
        .collect()
}
