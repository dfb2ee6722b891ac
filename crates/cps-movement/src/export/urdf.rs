//! A robot as URDF text (`/robot_description`) whose link frames are the frames the export
//! publishes on `/tf`, with a stick figure (cylinders between the joints) to look at.

use std::fmt::Write;

use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use crate::robot_file::RobotModel;

/// Frame names of an exported robot.
#[derive(Debug, Clone)]
pub struct Frames {
    /// The fixed world frame.
    pub world: String,
    /// The robot's base.
    pub base: String,
    /// The link moved by each joint.
    pub links: Vec<String>,
    /// The tool point.
    pub tool: String,
}

impl Frames {
    /// `<prefix>_base`, `<prefix>_link<i>`, `<prefix>_tool` and `world`.
    pub fn new(prefix: &str, dof: usize) -> Self {
        Frames {
            world: "world".into(),
            base: format!("{prefix}_base"),
            links: (1..=dof).map(|i| format!("{prefix}_link{i}")).collect(),
            tool: format!("{prefix}_tool"),
        }
    }
}

/// `xyz="…" rpy="…"` of a transform (URDF's fixed-axis roll, pitch, yaw).
fn origin(t: &Isometry3<f64>) -> String {
    let v = t.translation.vector;
    let (r, p, y) = t.rotation.euler_angles();
    format!(
        "<origin xyz=\"{:?} {:?} {:?}\" rpy=\"{:?} {:?} {:?}\"/>",
        v.x, v.y, v.z, r, p, y
    )
}

/// A cylinder from this frame's origin to `to` (in this frame), and a ball at the origin.
fn stick(to: &Vector3<f64>) -> String {
    let mut s = String::from("<visual><geometry><sphere radius=\"0.045\"/></geometry></visual>");
    let length = to.norm();
    if length > 1e-6 {
        let turn = UnitQuaternion::rotation_between(&Vector3::z(), to).unwrap_or_else(|| {
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        });
        let at = Isometry3::from_parts((to * 0.5).into(), turn);
        let _ = write!(
            s,
            "<visual>{}<geometry><cylinder radius=\"0.03\" length=\"{length:?}\"/></geometry></visual>",
            origin(&at)
        );
    }
    s
}

/// The URDF of `robot`, with joints named `joint_names` and links named by `frames`.
pub fn robot_description(robot: &RobotModel, joint_names: &[String], frames: &Frames) -> String {
    let (base, joints, tail) = robot.chain.axis_joints();
    let range = robot.chain.limits();
    let speed = robot.chain.velocity_limits();
    let torque = robot.limits.torque.as_deref();
    let mut s = format!(
        "<?xml version=\"1.0\"?>\n<robot name=\"{}\">\n  <link name=\"{}\"/>\n",
        xml_escape(&robot.name),
        frames.world
    );
    let _ = writeln!(
        s,
        "  <joint name=\"{0}_fixed\" type=\"fixed\"><parent link=\"{1}\"/><child link=\"{0}\"/>{2}</joint>",
        frames.base,
        frames.world,
        origin(&base)
    );
    let first = joints[0].origin.translation.vector;
    let _ = writeln!(
        s,
        "  <link name=\"{}\">{}</link>",
        frames.base,
        stick(&first)
    );
    let parents = std::iter::once(&frames.base).chain(&frames.links);
    for (i, (joint, parent)) in joints.iter().zip(parents).enumerate() {
        let (lower, upper) = range.map_or((-1e3, 1e3), |(lo, hi)| (lo[i], hi[i]));
        let _ = writeln!(
            s,
            "  <joint name=\"{}\" type=\"revolute\"><parent link=\"{parent}\"/><child link=\"{}\"/>{}<axis xyz=\"0 0 1\"/><limit lower=\"{lower:?}\" upper=\"{upper:?}\" effort=\"{:?}\" velocity=\"{:?}\"/></joint>",
            xml_escape(&joint_names[i]),
            frames.links[i],
            origin(&joint.origin),
            torque.map_or(0.0, |t| t[i]),
            speed.map_or(0.0, |v| v[i]),
        );
        let next = joints
            .get(i + 1)
            .map_or(tail.translation.vector, |j| j.origin.translation.vector);
        let _ = writeln!(
            s,
            "  <link name=\"{}\">{}</link>",
            frames.links[i],
            stick(&next)
        );
    }
    let _ = writeln!(
        s,
        "  <joint name=\"{0}_fixed\" type=\"fixed\"><parent link=\"{1}\"/><child link=\"{0}\"/>{2}</joint>\n  <link name=\"{0}\"/>\n</robot>",
        frames.tool,
        frames.links[frames.links.len() - 1],
        origin(&tail)
    );
    s
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
