//! ROS 2 messages as bytes: plain little-endian CDR (XCDR1, what rmw_fastrtps writes and
//! MCAP's `cdr` encoding means) and their `ros2msg` schema texts, for the messages an
//! exported trajectory needs.
//!
//! CDR: a 4-byte encapsulation header `00 01 00 00` (little-endian), then the fields in
//! order, each primitive aligned to its own size counted from the first byte after the
//! header; a string is a `uint32` length including its NUL, the bytes and the NUL; a
//! sequence is a `uint32` count and its items.

use nalgebra::Isometry3;

/// A CDR message being written.
pub struct Cdr {
    bytes: Vec<u8>,
}

impl Default for Cdr {
    fn default() -> Self {
        Self::new()
    }
}

impl Cdr {
    /// An empty little-endian message (the encapsulation header only).
    pub fn new() -> Self {
        Cdr {
            bytes: vec![0, 1, 0, 0],
        }
    }

    fn align(&mut self, size: usize) {
        while !(self.bytes.len() - 4).is_multiple_of(size) {
            self.bytes.push(0);
        }
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.align(8);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A `string`.
    pub fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.bytes.extend_from_slice(s.as_bytes());
        self.bytes.push(0);
        self
    }

    /// A `string[]`.
    pub fn strings(&mut self, v: &[String]) -> &mut Self {
        self.u32(v.len() as u32);
        for s in v {
            self.string(s);
        }
        self
    }

    /// A `float64[]`.
    pub fn f64s(&mut self, v: &[f64]) -> &mut Self {
        self.u32(v.len() as u32);
        for x in v {
            self.f64(*x);
        }
        self
    }

    /// A `builtin_interfaces/Time` or `Duration` of `ns` nanoseconds.
    pub fn time(&mut self, ns: u64) -> &mut Self {
        self.i32((ns / 1_000_000_000) as i32)
            .u32((ns % 1_000_000_000) as u32)
    }

    /// A `std_msgs/Header`.
    pub fn header(&mut self, stamp_ns: u64, frame_id: &str) -> &mut Self {
        self.time(stamp_ns).string(frame_id)
    }

    /// The finished bytes.
    pub fn finish(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.bytes)
    }
}

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
    let mut m = Cdr::new();
    m.header(0, frame_id)
        .strings(names)
        .u32(points.len() as u32);
    for p in points {
        m.f64s(p.positions)
            .f64s(p.velocities)
            .f64s(p.accelerations)
            .f64s(&[])
            .time(p.time_from_start_ns);
    }
    m.finish()
}

/// `sensor_msgs/msg/JointState` without efforts.
pub fn joint_state(stamp_ns: u64, names: &[String], position: &[f64], velocity: &[f64]) -> Vec<u8> {
    Cdr::new()
        .header(stamp_ns, "")
        .strings(names)
        .f64s(position)
        .f64s(velocity)
        .f64s(&[])
        .finish()
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

    /// The byte layouts verified against mcap_ros2's own encoder (robot-ready notes §3).
    #[test]
    fn bytes_match_the_reference_encoder() {
        assert_eq!(
            Cdr::new().time(1_500_000_000).finish(),
            [0, 1, 0, 0, 1, 0, 0, 0, 0x00, 0x65, 0xcd, 0x1d]
        );
        assert_eq!(string("hi"), [0, 1, 0, 0, 3, 0, 0, 0, 0x68, 0x69, 0]);
        let names = vec!["a".to_string(), "bc".to_string()];
        let m = Cdr::new()
            .header(7_000_000_000, "base")
            .strings(&names)
            .f64s(&[1.0, 2.0])
            .f64s(&[0.25, -0.5])
            .f64s(&[])
            .finish();
        assert_eq!(m.len(), 96);
        let p = &m[4..];
        assert_eq!(p[0..4], 7i32.to_le_bytes());
        assert_eq!(p[8..12], 5u32.to_le_bytes());
        assert_eq!(&p[12..17], b"base\0");
        assert_eq!(p[20..24], 2u32.to_le_bytes());
        assert_eq!(p[40..44], 2u32.to_le_bytes());
        assert_eq!(p[48..56], 1.0f64.to_le_bytes());
        assert_eq!(p[80..88], (-0.5f64).to_le_bytes());
        assert_eq!(p[88..92], 0u32.to_le_bytes());
    }

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
