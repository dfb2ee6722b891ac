//! ROS 2 messages as bytes for MCAP files: plain little-endian CDR (XCDR1, what rmw
//! writes and MCAP's `cdr` encoding means; written by `cps_ros2_msg::cdr`, which also speaks
//! them on a live graph) and their `ros2msg` schema texts, for the messages an exported
//! trajectory needs.

use nalgebra::Isometry3;

use cps_ros2_msg::cdr::CdrWriter as Cdr;
use cps_ros2_msg::msg::{self, Message};

/// One point of a `trajectory_msgs/JointTrajectory`.
pub struct TrajectoryPoint<'a> {
    /// Positions (rad).
    pub positions: &'a [f64],
    /// Velocities (rad/s).
    pub velocities: &'a [f64],
    /// Accelerations (rad/s²).
    pub accelerations: &'a [f64],
    /// Time from the trajectory's start (ns).
    pub time_from_start_ns: u64,
}

/// `trajectory_msgs/msg/JointTrajectory` (header stamp 0: start on receipt).
pub fn joint_trajectory(frame_id: &str, names: &[String], points: &[TrajectoryPoint]) -> Vec<u8> {
    msg::JointTrajectory {
        header: msg::Header {
            stamp: msg::Time::default(),
            frame_id: frame_id.to_string(),
        },
        joint_names: names.to_vec(),
        points: points
            .iter()
            .map(|p| msg::JointTrajectoryPoint {
                positions: p.positions.to_vec(),
                velocities: p.velocities.to_vec(),
                accelerations: p.accelerations.to_vec(),
                effort: vec![],
                time_from_start: msg::Time::from_nanos(p.time_from_start_ns),
            })
            .collect(),
    }
    .to_cdr()
}

/// `sensor_msgs/msg/JointState` without efforts.
pub fn joint_state(stamp_ns: u64, names: &[String], position: &[f64], velocity: &[f64]) -> Vec<u8> {
    msg::JointState {
        header: msg::Header {
            stamp: msg::Time::from_nanos(stamp_ns),
            frame_id: String::new(),
        },
        name: names.to_vec(),
        position: position.to_vec(),
        velocity: velocity.to_vec(),
        effort: vec![],
    }
    .to_cdr()
}

/// `tf2_msgs/msg/TFMessage`: `(parent, child, parent → child)` transforms at one stamp.
pub fn tf_message(stamp_ns: u64, transforms: &[(String, String, Isometry3<f64>)]) -> Vec<u8> {
    let mut m = Cdr::new();
    m.u32(transforms.len() as u32);
    for (parent, child, t) in transforms {
        let (v, r) = (t.translation.vector, t.rotation.quaternion());
        m.header(stamp_ns, parent)
            .string(child)
            .f64(v.x)
            .f64(v.y)
            .f64(v.z)
            .f64(r.i)
            .f64(r.j)
            .f64(r.k)
            .f64(r.w);
    }
    m.finish()
}

/// `std_msgs/msg/String`.
pub fn string(data: &str) -> Vec<u8> {
    Cdr::new().string(data).finish()
}

const TIME: &str = "int32 sec\nuint32 nanosec\n";
const HEADER: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";

/// A message definition with its dependencies, as rosbag2 writes `ros2msg` schemas: the
/// main text, then each dependency once after a line of 80 `=` and `MSG: pkg/Type`.
fn definition(main: &str, deps: &[(&str, &str)]) -> String {
    let mut s = main.to_string();
    for (name, text) in deps {
        s.push_str(&"=".repeat(80));
        s.push_str(&format!("\nMSG: {name}\n{text}"));
    }
    s
}

/// `(type name, ros2msg schema text)` of every message an export writes.
pub fn schemas() -> [(&'static str, String); 4] {
    [
        (
            "trajectory_msgs/msg/JointTrajectory",
            definition(
                "std_msgs/Header header\nstring[] joint_names\nJointTrajectoryPoint[] points\n",
                &[
                    ("std_msgs/Header", HEADER),
                    ("builtin_interfaces/Time", TIME),
                    (
                        "trajectory_msgs/JointTrajectoryPoint",
                        "float64[] positions\nfloat64[] velocities\nfloat64[] accelerations\nfloat64[] effort\nbuiltin_interfaces/Duration time_from_start\n",
                    ),
                    ("builtin_interfaces/Duration", TIME),
                ],
            ),
        ),
        (
            "sensor_msgs/msg/JointState",
            definition(
                "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
                &[
                    ("std_msgs/Header", HEADER),
                    ("builtin_interfaces/Time", TIME),
                ],
            ),
        ),
        (
            "tf2_msgs/msg/TFMessage",
            definition(
                "geometry_msgs/TransformStamped[] transforms\n",
                &[
                    (
                        "geometry_msgs/TransformStamped",
                        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
                    ),
                    ("std_msgs/Header", HEADER),
                    ("builtin_interfaces/Time", TIME),
                    (
                        "geometry_msgs/Transform",
                        "Vector3 translation\nQuaternion rotation\n",
                    ),
                    ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
                    (
                        "geometry_msgs/Quaternion",
                        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
                    ),
                ],
            ),
        ),
        ("std_msgs/msg/String", "string data\n".to_string()),
    ]
}

/// The `offered_qos_profiles` channel metadata rosbag2 writes: reliable, keep-last of
/// `depth`, volatile or (`latched`) transient-local; policies as integers, which every
/// ROS 2 release reads.
pub fn qos(depth: u32, latched: bool) -> String {
    let zero = "\n    sec: 0\n    nsec: 0";
    format!(
        "- history: 1\n  depth: {depth}\n  reliability: 1\n  durability: {}\n  deadline:{zero}\n  lifespan:{zero}\n  liveliness: 1\n  liveliness_lease_duration:{zero}\n  avoid_ros_namespace_conventions: false",
        if latched { 1 } else { 2 }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemas_separate_dependencies_as_rosbag2_does() {
        let [(name, text), ..] = schemas();
        assert_eq!(name, "trajectory_msgs/msg/JointTrajectory");
        assert!(text.starts_with(
            "std_msgs/Header header\nstring[] joint_names\nJointTrajectoryPoint[] points\n"
        ));
        assert!(text.contains(&format!("{}\nMSG: std_msgs/Header\n", "=".repeat(80))));
        assert_eq!(text.matches("MSG: ").count(), 4);
    }
}
