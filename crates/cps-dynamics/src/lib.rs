//! A robot arm with dynamics, as a cps robot: what a robot does with a motion, not only
//! what it is told.
//!
//! [`DynamicsRobot`] integrates an arm's forward dynamics (cps-kinematics's
//! [`ArmModel::forward_dynamics`](cps_kinematics::ArmModel::forward_dynamics), with rotor
//! inertia and joint friction) every control period (1 ms) under a joint-level
//! [`Controller`] — franky-sim's PD ([`Controller::franky_sim`]), computed torque, or
//! joint impedance — with the drives' torque limits, gravity cancelled by the robot as a
//! Franka does, and optional seeded measurement noise. It implements
//! [`cps_robot::Robot`] (plans), [`cps_robot::Stepped`] and [`cps_robot::Streaming`], so
//! every experiment kind can run on it, and it is deterministic: the same plan and seed
//! give the same run, bit for bit.
//!
//! - [`arm`]: the simulated arm and its [`Integrator`] (semi-implicit Euler as MuJoCo's
//!   default, or RK4).
//! - [`controller`]: the joint-level controllers.
//! - [`robot`]: the robot, [`DynamicsRobot`].
//! - [`options`]: a dynamics robot from a robot model and words ([`open`]), as an
//!   experiment's `[robot] backend = "dynamics"` builds one.
//!
//! # Example
//! ```
//! use cps_dynamics::{Arm, Controller, DynamicsRobot, DynamicsSettings};
//! use cps_kinematics::ArmModel;
//! use cps_kinematics::contact::JointFriction;
//! use cps_kinematics::robots::{PandaTool, panda, panda_inertia};
//! use cps_robot::{Plan, Robot, RobotModel, StopToken};
//!
//! let chain = panda(PandaTool::HandTcp);
//! let dynamics = ArmModel::<7>::new(&chain, &panda_inertia()).unwrap();
//! let start = cps_kinematics::robots::PANDA_READY;
//! let arm = Arm::at_rest(dynamics, JointFriction::none(), [87.0; 7], start);
//! let settings = DynamicsSettings {
//!     controller: Controller::franky_sim(),
//!     control_period: 0.001,
//!     dt: 0.01,
//!     noise: 0.0,
//!     seed: 0,
//!     reflexes: true,
//!     lag: 0,
//! };
//! let mut robot = DynamicsRobot::new(RobotModel::of_chain("panda", chain), arm, settings).unwrap();
//! // Joint 1 turns 0.2 rad in one second; the PD lags, then settles.
//! let points = (0..=100)
//!     .map(|k| {
//!         let s = k as f64 / 100.0;
//!         let mut q = start.to_vec();
//!         q[0] += 0.2 * s * s * (3.0 - 2.0 * s);
//!         q
//!     })
//!     .collect();
//! let run = robot.run(&Plan::new(0.01, points).unwrap(), &StopToken::new()).unwrap();
//! assert_eq!(run.q.len(), 101);
//! assert!((run.q[100][0] - start[0] - 0.2).abs() < 0.01);
//! ```
#![deny(missing_docs)]

pub mod arm;
pub mod controller;
pub mod identify;
pub mod options;
pub mod robot;

pub use arm::{
    Arm, FRANKY_SIM_ARMATURE, FRANKY_SIM_COULOMB_SPEED, FRANKY_SIM_FRICTION, Integrator,
};
pub use controller::{CONTROLLERS, Controller, Desired, FRANKY_SIM_KP};
pub use identify::{
    Calibration, Chirps, Identified, MAX_MISSED_PERIODS, MIN_EXCITATION, Recorded, excitation,
    identify, predict, predict_until,
};
pub use options::{Drive, DynamicsOptions, default_gains, open};
pub use robot::{DynamicsRobot, DynamicsSettings, MAX_LAG, REFLEX_MARGIN};
