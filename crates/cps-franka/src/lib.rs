//! A client of the Franka Control Interface (FCI) for cps: drive a Franka Research 3 (or
//! a Panda on a protocol-10 system) from Rust at the robot's 1 kHz, never refused for a
//! limit.
//!
//! Three layers, each testable alone:
//! - [`wire`]: protocol version 10 on the wire — the 1377-byte robot state decoded into
//!   [`RobotState`], the 371-byte [`Command`], the TCP requests and replies, the robot
//!   modes, the 41 error flags and `Move`'s statuses as sentences. No sockets.
//! - [`Connection`] (session): connecting with the version check, the TCP commands
//!   (`Move`, `StopMove`, `SetCollisionBehavior`, the impedances, frames, load, error
//!   recovery, `GetRobotModel`), the UDP state; every wait bounded, every failure a typed
//!   [`FrankaError`] naming the host.
//! - [`rt`]: the realtime loop on a dedicated thread (SCHED_FIFO where permitted): one state
//!   in, one command out per tick, no allocation, lock or log inside; missed and stale
//!   states counted; its own latency measured. Joint positions
//!   ([`run_joint_positions`]), joint velocities ([`run_joint_velocities`]) or torques
//!   computed by cps ([`run_torques`], the external controller mode).
//!
//! - [`control`]: torque laws at the robot's rate on the robot's own dynamic model (joint
//!   and Cartesian impedance, force along a direction) and contact sensing from the
//!   measured torques (a momentum observer), for [`run_torques`].
//! - [`guide`]: the arm floating under a light damping, recorded while a person moves it
//!   ([`guide::run_guiding`]).
//! - [`FrankaRobot`]: the arm as a robot of cps's execution contract
//!   ([`cps_robot::Robot`]): a plan's motion streamed at 1 kHz and recorded, so every cps
//!   front end drives a Franka through the same guard and stop token as any robot.
//!
//! Safety sits between them as a wrapper, not inside generators: [`limits::StreamCheck`]
//! takes the robot's own per-millisecond differences of every command (position, velocity
//! — position-dependent on the FR3 — acceleration, jerk, and the distance a stop would
//! need), over the whole stream before a motion ([`check_trajectory`]) and again for every
//! command sent; a command it refuses is never sent and a [`limits::Brake`] stops the
//! robot within the limits instead, as it does on Ctrl-C. Torques are limited to the arm's
//! torque and torque rate before they are sent, and a damped stop replaces them on Ctrl-C.
//!
//! # Example
//! Checking a stream needs no robot; executing it needs one (here the address of a
//! franky-sim or a real FR3):
//! ```
//! use cps_franka::limits::{check_stream, Arm, RateLimits};
//! use cps_franka::{approach, check_trajectory, Start};
//! let limits = RateLimits::of(Arm::Fr3);
//! let home = cps_kinematics::robots::PANDA_READY;
//! let mut goal = home;
//! goal[0] += 0.5;
//! // A rest-to-rest move at 30 % of every limit passes the robot's own check ...
//! let stream = check_trajectory(&limits, home, &approach(&limits, home, goal, 0.3), Start::Refuse).unwrap();
//! assert!(stream.peak_usage.iter().flatten().all(|&u| u <= 0.3 + 1e-9));
//! // ... a jump does not, and the refusal names joint, time and quantity.
//! let err = check_stream(limits, home, &[goal]).unwrap_err();
//! assert_eq!(err.to_string(), "joint 1 at t = 0.000 s (command 0): velocity 500.000000 rad/s beyond the limit 2.620000 rad/s");
//! # fn on_a_robot(stream: &cps_franka::CheckedStream) -> Result<(), cps_franka::FrankaError> {
//! let mut robot = cps_franka::Connection::connect("127.0.0.1", Default::default())?;
//! let stop = std::sync::atomic::AtomicBool::new(false);
//! let report = cps_franka::execute_stream(&mut robot, RateLimits::of(Arm::Fr3), stream, &Default::default(), &stop)?;
//! println!("{}; p99 {} us", report.ending.sentence(), report.timing.p99_us);
//! # Ok(()) }
//! ```
#![deny(missing_docs)]

pub mod control;
mod error;
pub mod gripper;
pub mod guide;
pub mod limits;
mod motion;
pub mod reference;
mod robot;
pub mod rt;
mod session;
pub mod wire;

pub use error::FrankaError;
pub use gripper::{Gripper, GripperCommand, GripperState};
pub use motion::{
    CheckedStream, START_TOLERANCE, Start, approach, check_trajectory, execute_stream,
    record_states,
};
pub use robot::{FrankaRobot, FrankaSettings, MODEL_AGREEMENT, TOOL_AGREEMENT};
pub use rt::{
    Cycles, JointPositions, JointVelocities, LoopOptions, MotionEnd, MotionReport, Realtime,
    Sample, Timing, Torques, run_joint_positions, run_joint_velocities, run_torques,
};
pub use session::{Connection, Timeouts};
pub use wire::{Command, RobotMode, RobotState};
