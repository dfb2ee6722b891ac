//! The execution contract of cps: what every robot cps drives implements, and what every
//! caller — the command line, Python, the experiments — drives robots through.
//!
//! - [`Robot`]: read where the robot stands, run a [`Plan`] (joint positions every `dt`
//!   from where it stands; the motion between them a spline from rest to rest) and return
//!   the [`Run`] — what the robot did, point by point, and how it ended. The in-process
//!   [`KinematicRobot`] implements it here; `cps-coppelia` (CoppeliaSim), `cps-franka` (a
//!   Franka at 1 kHz) and `cps-ros2` (a ros2_control controller) implement it in their
//!   crates. Robots that step (simulators) also offer [`Stepped`], on which cps's
//!   closed-loop controller runs ([`execute`]); robots that take a command computed each
//!   period from what they measured offer [`Streaming`] (a DMP stepped online, a learned
//!   policy's action chunks followed: `cps-chunks`).
//! - [`Guarded`]: limits as a wrapper around any robot. Every plan is checked
//!   ([`check()`]: its motion sampled every millisecond against the robot's joint, torque
//!   and Cartesian limits) and refused, or slowed down (at most [`MAX_SLOWING`]×), and a
//!   plan that starts away from the robot is refused or approached from where it stands
//!   ([`APPROACH_SHARE`] of the limits) — one implementation, the same sentences for every
//!   robot ([`Refusal`], [`Breach`]).
//! - [`StopToken`]: a stop handed to the run (Ctrl-C, SIGTERM, a caller's cancel, Python's
//!   KeyboardInterrupt); every robot brakes within its limits and keeps its recording.
//! - [`RobotModel`]: what cps knows of a robot (kinematics, joint names, limits, inertias).
//!
//! This crate does no IO and starts no thread; robots that talk to hardware live in their
//! transport crates.
//!
//! # Example
//! ```
//! use cps_kinematics::robots::{panda, PandaTool};
//! use cps_robot::{Guarded, KinematicRobot, Plan, Policy, Refusal, Robot, RobotError, StopToken};
//! # fn main() -> Result<(), RobotError> {
//! let start = cps_kinematics::robots::PANDA_READY;
//! let robot = KinematicRobot::new(panda(PandaTool::HandTcp), &start, 0.01)?;
//! let mut robot = Guarded::new(robot, Policy::STRICT);
//! // Joint 1 swings by 0.3 rad in 2 s and back to rest, one point every 10 ms.
//! let points: Vec<Vec<f64>> = (0..=200)
//!     .map(|k| {
//!         let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 200.0).cos();
//!         let mut q = start.to_vec();
//!         q[0] += 0.3 * s;
//!         q
//!     })
//!     .collect();
//! let run = robot.run(&Plan::new(0.01, points)?, &StopToken::new())?;
//! assert!(run.ending.complete() && run.len() == 201);
//! assert!((run.q[200][0] - 0.3).abs() < 1e-12);
//! // A jump of 0.5 rad in 10 ms is refused before anything moves, in words.
//! let mut jump = vec![run.q[200].clone(); 2];
//! jump[1][1] += 0.5;
//! match robot.run(&Plan::new(0.01, jump)?, &StopToken::new()) {
//!     Err(RobotError::Refused { reason: Refusal::Limit(b), .. }) => {
//!         assert!(b.to_string().starts_with("joint 2 at t = 0.010 s (command 1): velocity 50.000000 rad/s"), "{b}");
//!     }
//!     other => panic!("{other:?}"),
//! }
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

mod check;
mod collision;
mod cycles;
mod execute;
mod guard;
mod kinematic;
mod model;
mod never;
mod plan;
mod robot;
mod setting;
mod stop;
mod watch;

pub use check::{Breach, Limit, OUTSIDE_SLACK, Verdict, check};
pub use collision::{Collision, DEFAULT_MARGIN, LeftOut, ShapeWatch, Shapes, Why, check_shapes};
pub use cycles::{
    CASCADE_GAINS, CycleLoss, Judge, LIMITABLE_GAP, Limited, Limiter, LinkBreak, LossyLink,
    MAX_LOSS, MAX_LOST_PERIODS, RateCheck, Reference,
};
pub use execute::{CommandPath, ExecutionConfig, Recording, command_path, execute};
pub use guard::{
    APPROACH_SHARE, Around, BLEND_SHARE, Guarded, MAX_SLOWING, OnBreach, OnStart, Policy, Prepared,
    Refusal, SEPTIC_PEAKS, START_TOLERANCE, approach, move_to, rest_to_rest, septic,
};
pub use kinematic::KinematicRobot;
pub use model::RobotModel;
pub use never::{NeverSearch, PairApproach, SplitMix, closest_approaches};
pub use plan::{CHECK_PERIOD, Ending, MAX_POINTS, Plan, Run, SampledMotion};
pub use robot::{
    Generator, Measured, Robot, Stepped, Stepping, Streaming, prefaulted, run_stepped, step_of,
};
pub use setting::SettingError;
pub use stop::{Moving, StopToken};

use cps_kinematics::KinematicsError;

/// What can go wrong when driving a robot.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum RobotError {
    /// The guard refused a plan: nothing was sent.
    #[error("{robot}: refused before sending anything: {reason}")]
    Refused {
        /// The robot (its [`Robot::name`]).
        robot: String,
        /// Why.
        reason: Refusal,
    },
    /// The guard refused one command of a stepped run: it was not sent, the robot holds
    /// the one before and is fine (a caller may put it back and try another movement).
    #[error(
        "{robot}: a command breaks a limit, so it was not sent (the robot holds the one before): {reason}"
    )]
    CommandRefused {
        /// The robot (its [`Robot::name`]).
        robot: String,
        /// The limit it breaks ([`Refusal::Limit`]) or the collision it would make
        /// ([`Refusal::Collision`]).
        reason: Refusal,
    },
    /// The robot, its connection or its controller failed.
    #[error("{robot}: {message}")]
    Robot {
        /// The robot (its [`Robot::name`], or the address it was to be reached at).
        robot: String,
        /// What went wrong.
        message: String,
    },
    /// A plan that cannot be a plan (no points, rows of different lengths, not finite).
    #[error("invalid plan: {0}")]
    Plan(String),
    /// The robot's model or a kinematic computation failed.
    #[error(transparent)]
    Kinematics(#[from] KinematicsError),
    /// A setting of the run cannot be used: nothing was sent.
    #[error("{robot}: {source}")]
    Setting {
        /// The robot (its [`Robot::name`]).
        robot: String,
        /// Which setting, and why.
        #[source]
        source: SettingError,
    },
}
