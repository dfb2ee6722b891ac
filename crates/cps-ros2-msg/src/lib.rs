//! The ROS 2 messages cps speaks and their bytes, with no transport: [`cdr`] writes and
//! reads CDR (the encoding of every rmw, and of a ROS 2 bag's or MCAP file's `cdr`
//! messages), [`msg`] holds the messages as structs (`trajectory_msgs/JointTrajectory`,
//! `control_msgs/FollowJointTrajectory` and the `action_msgs` around it,
//! `sensor_msgs/JointState`, `visualization_msgs/MarkerArray`).
//!
//! A file writer (cps-movement's ROS 2 and MCAP exports) needs only this crate; cps-ros2
//! puts the same messages on a live graph over DDS (`rustdds`), which this crate does not
//! build.
//!
//! # Example
//!
//! ```
//! use cps_ros2_msg::cdr::CdrReader;
//! use cps_ros2_msg::msg::{JointTrajectory, JointTrajectoryPoint, Message, Time};
//!
//! let sent = JointTrajectory {
//!     joint_names: vec!["panda_joint1".into()],
//!     points: vec![JointTrajectoryPoint {
//!         positions: vec![0.5],
//!         time_from_start: Time::from_secs(2.0),
//!         ..Default::default()
//!     }],
//!     ..Default::default()
//! };
//! let bytes = sent.to_cdr();
//! assert_eq!(&bytes[..4], [0, 1, 0, 0]); // little-endian CDR
//! let read = JointTrajectory::decode(&mut CdrReader::with_header(&bytes)?)?;
//! assert_eq!(read, sent);
//! # Ok::<(), cps_ros2_msg::cdr::CdrError>(())
//! ```

pub mod cdr;
pub mod msg;
