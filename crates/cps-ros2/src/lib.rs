//! cps on a live ROS 2 graph, with no ROS installation: a DDS participant (RTPS through
//! `rustdds`) that speaks ROS 2's names and messages in cps's own CDR, to send a joint
//! trajectory to a ros2_control `joint_trajectory_controller` (its topic, or its
//! `FollowJointTrajectory` action with feedback, result and cancel), to record
//! `sensor_msgs/JointState` in a robot model's joint order, and to show a path as
//! `visualization_msgs/MarkerArray`.
//!
//! The messages and their CDR bytes are crate cps-ros2-msg's ([`cps_ros2_msg`]), which
//! builds no transport. Layers here: [`names`] (ROS names → DDS topics),
//! [`discovery`] (the graph's announcements), [`node`] (the participant, writers and
//! readers, announced on the graph), [`service`] (a service client on Cyclone's or Fast
//! DDS's request/reply mapping), [`graph`] (what cps sees of the graph), then what is done
//! with them: [`publish`], [`action`], [`record`], [`markers`], and [`robot`]: a ros2_control
//! controller as a robot of cps's execution contract ([`robot::Ros2Robot`]) and the one
//! place a plan becomes a `JointTrajectory` ([`robot::trajectory_message`]). Files and
//! words (a joint CSV, the report) live in the experiments layer.
//!
//! # Example
//!
//! ```no_run
//! use std::time::Duration;
//! use cps_ros2::{names::NodeName, node::Node};
//! use cps_ros2_msg::msg::{JointTrajectory, JointTrajectoryPoint, Time};
//!
//! let node = Node::new(NodeName::from_env("cps", None)?)?;
//! let trajectory = JointTrajectory {
//!     joint_names: (1..=7).map(|i| format!("panda_joint{i}")).collect(),
//!     points: vec![JointTrajectoryPoint {
//!         positions: cps_kinematics::robots::PANDA_READY.to_vec(),
//!         time_from_start: Time::from_secs(2.0),
//!         ..Default::default()
//!     }],
//!     ..Default::default()
//! };
//! let sent = cps_ros2::publish::publish(
//!     &node,
//!     "/panda_arm_controller/joint_trajectory",
//!     &trajectory,
//!     cps_ros2::node::Qos::Reliable { depth: 1 },
//!     Duration::from_secs(5),
//! )?;
//! println!("a subscriber was matched after {:.2} s", sent.matched_after_s);
//! # Ok::<(), cps_ros2::Ros2Error>(())
//! ```

pub mod action;
pub mod discovery;
pub mod graph;
pub mod markers;
pub mod names;
pub mod node;
pub mod publish;
pub mod record;
pub mod robot;
pub mod service;

/// What went wrong on the graph.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// A name, domain or argument that cannot be used.
    #[error("{0}")]
    Input(String),
    /// No peer answered in time (no subscriber, no action server, no result, no message).
    #[error("{0}")]
    NoPeer(String),
    /// The DDS layer failed (sockets, a domain's ports taken).
    #[error("DDS: {0}")]
    Dds(String),
}
