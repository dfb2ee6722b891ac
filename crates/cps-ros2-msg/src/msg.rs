//! The ROS 2 messages cps speaks, as structs with their CDR bytes: what a trajectory
//! controller takes (`trajectory_msgs/JointTrajectory`, `control_msgs/FollowJointTrajectory`
//! and the `action_msgs` around it), what a robot publishes (`sensor_msgs/JointState`) and
//! what RViz or Foxglove draws (`visualization_msgs/MarkerArray`).
//!
//! Layouts are those of the ROS 2 releases from Humble on (common_interfaces,
//! rcl_interfaces, control_msgs 4 – 6). FollowJointTrajectory's feedback grew an `index`
//! field after Jazzy; cps reads the feedback's fields up to `error`, which every release
//! has in the same place, and ignores the rest.

use crate::cdr::{CdrError, CdrReader, CdrWriter};

/// A message type: its DDS type name and its CDR bytes.
pub trait Message: Sized {
    /// The DDS type name rmw gives it (`trajectory_msgs::msg::dds_::JointTrajectory_`).
    const TYPE: &'static str;
    /// Writes its fields.
    fn encode(&self, w: &mut CdrWriter);
    /// Reads its fields.
    fn decode(r: &mut CdrReader) -> Result<Self, CdrError>;

    /// The sample's bytes, encapsulation header included.
    fn to_cdr(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.encode(&mut w);
        w.finish()
    }
}

/// `builtin_interfaces/Time` or `Duration`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, below 1e9.
    pub nanosec: u32,
}

impl Time {
    /// `ns` nanoseconds (at most 2^31 − 1 s).
    pub fn from_nanos(ns: u64) -> Self {
        Time {
            sec: (ns / 1_000_000_000) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// The nearest nanosecond to `s` seconds (`s` ≥ 0, finite).
    pub fn from_secs(s: f64) -> Self {
        Self::from_nanos((s * 1e9).round() as u64)
    }

    /// In seconds.
    pub fn secs(self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }

    fn encode(self, w: &mut CdrWriter) {
        w.i32(self.sec).u32(self.nanosec);
    }

    fn decode(r: &mut CdrReader, field: &'static str) -> Result<Self, CdrError> {
        let (sec, nanosec) = r.time(field)?;
        Ok(Time { sec, nanosec })
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Header {
    /// When the data were taken (zero: "now", for a trajectory "start on receipt").
    pub stamp: Time,
    /// The coordinate frame.
    pub frame_id: String,
}

impl Header {
    fn encode(&self, w: &mut CdrWriter) {
        self.stamp.encode(w);
        w.string(&self.frame_id);
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(Header {
            stamp: Time::decode(r, "header.stamp")?,
            frame_id: r.string("header.frame_id")?,
        })
    }
}

/// `trajectory_msgs/JointTrajectoryPoint`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointTrajectoryPoint {
    /// Positions (rad or m), one per joint.
    pub positions: Vec<f64>,
    /// Velocities, one per joint or none.
    pub velocities: Vec<f64>,
    /// Accelerations, one per joint or none.
    pub accelerations: Vec<f64>,
    /// Efforts, one per joint or none.
    pub effort: Vec<f64>,
    /// When the point is to be reached, from the trajectory's start.
    pub time_from_start: Time,
}

impl JointTrajectoryPoint {
    fn encode(&self, w: &mut CdrWriter) {
        w.f64s(&self.positions)
            .f64s(&self.velocities)
            .f64s(&self.accelerations)
            .f64s(&self.effort);
        self.time_from_start.encode(w);
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(JointTrajectoryPoint {
            positions: r.f64s("positions")?,
            velocities: r.f64s("velocities")?,
            accelerations: r.f64s("accelerations")?,
            effort: r.f64s("effort")?,
            time_from_start: Time::decode(r, "time_from_start")?,
        })
    }
}

/// `trajectory_msgs/JointTrajectory`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointTrajectory {
    /// Stamp zero: the controller starts it on receipt.
    pub header: Header,
    /// The joints, in the order of every point's values.
    pub joint_names: Vec<String>,
    /// The points, `time_from_start` increasing.
    pub points: Vec<JointTrajectoryPoint>,
}

impl Message for JointTrajectory {
    const TYPE: &'static str = "trajectory_msgs::msg::dds_::JointTrajectory_";

    fn encode(&self, w: &mut CdrWriter) {
        self.header.encode(w);
        w.strings(&self.joint_names).u32(self.points.len() as u32);
        for p in &self.points {
            p.encode(w);
        }
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        let header = Header::decode(r)?;
        let joint_names = r.strings("joint_names")?;
        let n = r.count("points", 4 * 4 + 8)?;
        let points = (0..n)
            .map(|_| JointTrajectoryPoint::decode(r))
            .collect::<Result<_, _>>()?;
        Ok(JointTrajectory {
            header,
            joint_names,
            points,
        })
    }
}

/// `sensor_msgs/JointState`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointState {
    /// When the state was measured.
    pub header: Header,
    /// The joints' names, in any order.
    pub name: Vec<String>,
    /// Positions, one per name (or none).
    pub position: Vec<f64>,
    /// Velocities, one per name (or none).
    pub velocity: Vec<f64>,
    /// Efforts, one per name (or none).
    pub effort: Vec<f64>,
}

impl Message for JointState {
    const TYPE: &'static str = "sensor_msgs::msg::dds_::JointState_";

    fn encode(&self, w: &mut CdrWriter) {
        self.header.encode(w);
        w.strings(&self.name)
            .f64s(&self.position)
            .f64s(&self.velocity)
            .f64s(&self.effort);
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(JointState {
            header: Header::decode(r)?,
            name: r.strings("name")?,
            position: r.f64s("position")?,
            velocity: r.f64s("velocity")?,
            effort: r.f64s("effort")?,
        })
    }
}

/// A goal's id (`unique_identifier_msgs/UUID`, 16 bytes).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct GoalId(pub [u8; 16]);

impl GoalId {
    /// A version-4 UUID made from 128 bits the caller chose.
    pub fn from_bits(bits: u128) -> Self {
        let mut b = bits.to_le_bytes();
        b[6] = (b[6] & 0x0f) | 0x40;
        b[8] = (b[8] & 0x3f) | 0x80;
        GoalId(b)
    }
}

impl std::fmt::Display for GoalId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, b) in self.0.iter().enumerate() {
            if matches!(i, 4 | 6 | 8 | 10) {
                f.write_str("-")?;
            }
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

/// A ROS 2 action's types: the stem of its DDS type names and how its goal, result and
/// feedback are written and read. The action's services and topics
/// (`…_SendGoal_Request_`, `…_GetResult_Response_`, `…_FeedbackMessage_`) wrap them with a
/// goal id as rosidl does.
pub trait Action {
    /// The stem: `control_msgs::action::dds_::FollowJointTrajectory`.
    const TYPE: &'static str;
    /// What is asked.
    type Goal;
    /// What the server answers at the end.
    type Result;
    /// What the server says while it works.
    type Feedback;
    /// Writes a goal's fields.
    fn encode_goal(goal: &Self::Goal, w: &mut CdrWriter);
    /// Reads a result's fields.
    fn decode_result(r: &mut CdrReader) -> Result<Self::Result, CdrError>;
    /// Reads a feedback's fields.
    fn decode_feedback(r: &mut CdrReader) -> Result<Self::Feedback, CdrError>;
}

/// The DDS type name of one of action `A`'s parts (`SendGoal_Request`, `FeedbackMessage`).
pub fn action_type<A: Action>(part: &str) -> String {
    format!("{}_{part}_", A::TYPE)
}

/// `control_msgs/FollowJointTrajectory`'s goal, with its tolerances left to the
/// controller's own (empty) and no multi-DOF part.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FollowJointTrajectoryGoal {
    /// The movement.
    pub trajectory: JointTrajectory,
    /// How late the goal may be reached (zero: the controller's default).
    pub goal_time_tolerance: Time,
}

impl FollowJointTrajectoryGoal {
    fn encode(&self, w: &mut CdrWriter) {
        self.trajectory.encode(w);
        // multi_dof_trajectory: an empty header, no joints, no points.
        Header::default().encode(w);
        w.u32(0).u32(0);
        // path_tolerance, component_path_tolerance, goal_tolerance, component_goal_tolerance.
        w.u32(0).u32(0).u32(0).u32(0);
        self.goal_time_tolerance.encode(w);
    }
}

/// `…/_action/send_goal`'s reply (the body after any service header).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GoalAnswer {
    /// Whether the server took the goal.
    pub accepted: bool,
    /// When it did.
    pub stamp: Time,
}

impl GoalAnswer {
    /// Reads one.
    pub fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(GoalAnswer {
            accepted: r.bool("accepted")?,
            stamp: Time::decode(r, "stamp")?,
        })
    }
}

/// The DDS type name of `action_msgs/CancelGoal`'s request.
pub const CANCEL_REQUEST_TYPE: &str = "action_msgs::srv::dds_::CancelGoal_Request_";
/// The DDS type name of `action_msgs/CancelGoal`'s reply.
pub const CANCEL_REPLY_TYPE: &str = "action_msgs::srv::dds_::CancelGoal_Response_";

/// A goal's state (`action_msgs/GoalStatus`'s `status`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GoalStatus {
    /// 0: not known.
    Unknown,
    /// 1.
    Accepted,
    /// 2.
    Executing,
    /// 3.
    Canceling,
    /// 4.
    Succeeded,
    /// 5.
    Canceled,
    /// 6.
    Aborted,
    /// A value ROS does not define.
    Other(i8),
}

impl GoalStatus {
    /// From the wire's `int8`.
    pub fn from_i8(v: i8) -> Self {
        match v {
            0 => GoalStatus::Unknown,
            1 => GoalStatus::Accepted,
            2 => GoalStatus::Executing,
            3 => GoalStatus::Canceling,
            4 => GoalStatus::Succeeded,
            5 => GoalStatus::Canceled,
            6 => GoalStatus::Aborted,
            v => GoalStatus::Other(v),
        }
    }

    /// The word for it.
    pub fn word(self) -> String {
        match self {
            GoalStatus::Unknown => "unknown".into(),
            GoalStatus::Accepted => "accepted".into(),
            GoalStatus::Executing => "executing".into(),
            GoalStatus::Canceling => "canceling".into(),
            GoalStatus::Succeeded => "succeeded".into(),
            GoalStatus::Canceled => "canceled".into(),
            GoalStatus::Aborted => "aborted".into(),
            GoalStatus::Other(v) => format!("status {v}"),
        }
    }
}

/// `…/_action/get_result`'s reply (the body after any service header): how the goal
/// ended and the action's result.
#[derive(Debug, Clone, PartialEq)]
pub struct GoalResult<R> {
    /// How the goal ended.
    pub status: GoalStatus,
    /// The action's result.
    pub result: R,
}

impl<R> GoalResult<R> {
    /// Reads one whose result `result` reads.
    pub fn decode(
        r: &mut CdrReader,
        result: impl FnOnce(&mut CdrReader) -> Result<R, CdrError>,
    ) -> Result<Self, CdrError> {
        Ok(GoalResult {
            status: GoalStatus::from_i8(r.u8("status")? as i8),
            result: result(r)?,
        })
    }
}

/// `control_msgs/action/FollowJointTrajectory`, the action ros2_control's
/// joint_trajectory_controller serves.
#[derive(Debug, Clone, Copy)]
pub struct FollowJointTrajectory;

/// FollowJointTrajectory's result.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FollowJointTrajectoryResult {
    /// 0 successful, −1 invalid goal, −2 invalid joints, −3 old header timestamp, −4 path
    /// tolerance, −5 goal tolerance violated.
    pub error_code: i32,
    /// The controller's words.
    pub error_string: String,
}

impl Action for FollowJointTrajectory {
    const TYPE: &'static str = "control_msgs::action::dds_::FollowJointTrajectory";
    type Goal = FollowJointTrajectoryGoal;
    type Result = FollowJointTrajectoryResult;
    type Feedback = Feedback;

    fn encode_goal(goal: &FollowJointTrajectoryGoal, w: &mut CdrWriter) {
        goal.encode(w);
    }

    fn decode_result(r: &mut CdrReader) -> Result<FollowJointTrajectoryResult, CdrError> {
        Ok(FollowJointTrajectoryResult {
            error_code: r.i32("error_code")?,
            error_string: r.string("error_string")?,
        })
    }

    fn decode_feedback(r: &mut CdrReader) -> Result<Feedback, CdrError> {
        Feedback::decode(r)
    }
}

/// FollowJointTrajectory's `error_code` in words.
pub fn error_code_word(code: i32) -> &'static str {
    match code {
        0 => "successful",
        -1 => "invalid goal",
        -2 => "invalid joints",
        -3 => "old header timestamp",
        -4 => "path tolerance violated",
        -5 => "goal tolerance violated",
        _ => "an error code FollowJointTrajectory does not define",
    }
}

/// `action_msgs/CancelGoal`'s reply (the body after any service header).
#[derive(Debug, Clone, PartialEq)]
pub struct CancelAnswer {
    /// 0 none, 1 rejected, 2 unknown goal id, 3 goal terminated.
    pub return_code: i8,
    /// The goals now canceling.
    pub goals_canceling: Vec<GoalId>,
}

impl CancelAnswer {
    /// Reads one.
    pub fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        let return_code = r.u8("return_code")? as i8;
        let n = r.count("goals_canceling", 24)?;
        let mut goals_canceling = Vec::with_capacity(n);
        for _ in 0..n {
            goals_canceling.push(GoalId(r.array("goal_id")?));
            Time::decode(r, "stamp")?;
        }
        Ok(CancelAnswer {
            return_code,
            goals_canceling,
        })
    }
}

/// FollowJointTrajectory's feedback: what the controller is doing now.
#[derive(Debug, Clone, PartialEq)]
pub struct Feedback {
    /// When.
    pub header: Header,
    /// The joints, in the order of the points' values.
    pub joint_names: Vec<String>,
    /// Where the trajectory is now.
    pub desired: JointTrajectoryPoint,
    /// Where the robot is.
    pub actual: JointTrajectoryPoint,
    /// Their difference.
    pub error: JointTrajectoryPoint,
}

impl Feedback {
    /// Reads one (the fields up to `error`; later ones differ between releases).
    pub fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(Feedback {
            header: Header::decode(r)?,
            joint_names: r.strings("joint_names")?,
            desired: JointTrajectoryPoint::decode(r)?,
            actual: JointTrajectoryPoint::decode(r)?,
            error: JointTrajectoryPoint::decode(r)?,
        })
    }
}

/// An RGBA colour, each in 0 … 1.
pub type Rgba = [f32; 4];

/// `visualization_msgs/Marker`, the kinds cps draws (lines, spheres, arrows, text).
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Frame and stamp.
    pub header: Header,
    /// Namespace: markers with the same `ns` and `id` replace each other.
    pub ns: String,
    /// Id within the namespace.
    pub id: i32,
    /// 0 arrow, 1 cube, 2 sphere, 4 line strip, 5 line list, 7 sphere list, 9 text.
    pub kind: i32,
    /// 0 add or modify, 2 delete, 3 delete all.
    pub action: i32,
    /// Position (m).
    pub position: [f64; 3],
    /// Orientation `[x, y, z, w]`.
    pub orientation: [f64; 4],
    /// Size (m): line width in x for lines; diameters for spheres; height in z for text.
    pub scale: [f64; 3],
    /// Colour.
    pub color: Rgba,
    /// How long it is shown (zero: until replaced).
    pub lifetime: Time,
    /// Points of a line strip, line list or sphere list.
    pub points: Vec<[f64; 3]>,
    /// Text of a text marker.
    pub text: String,
}

impl Default for Marker {
    fn default() -> Self {
        Marker {
            header: Header::default(),
            ns: String::new(),
            id: 0,
            kind: 0,
            action: 0,
            position: [0.0; 3],
            orientation: [0.0, 0.0, 0.0, 1.0],
            scale: [1.0; 3],
            color: [1.0; 4],
            lifetime: Time::default(),
            points: Vec::new(),
            text: String::new(),
        }
    }
}

impl Marker {
    fn encode(&self, w: &mut CdrWriter) {
        self.header.encode(w);
        w.string(&self.ns)
            .i32(self.id)
            .i32(self.kind)
            .i32(self.action);
        for v in self
            .position
            .iter()
            .chain(&self.orientation)
            .chain(&self.scale)
        {
            w.f64(*v);
        }
        for c in self.color {
            w.f32(c);
        }
        self.lifetime.encode(w);
        w.u8(0); // frame_locked
        w.u32(self.points.len() as u32);
        for p in &self.points {
            w.f64(p[0]).f64(p[1]).f64(p[2]);
        }
        w.u32(0); // colors
        w.string(""); // texture_resource
        Header::default().encode(w); // texture: sensor_msgs/CompressedImage
        w.string("").bytes(&[]);
        w.u32(0); // uv_coordinates
        w.string(&self.text);
        w.string(""); // mesh_resource
        w.string("").bytes(&[]); // mesh_file
        w.u8(0); // mesh_use_embedded_materials
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        let header = Header::decode(r)?;
        let ns = r.string("ns")?;
        let (id, kind, action) = (r.i32("id")?, r.i32("type")?, r.i32("action")?);
        let mut v = [0.0; 10];
        for x in &mut v {
            *x = r.f64("pose and scale")?;
        }
        let mut color = [0.0; 4];
        for c in &mut color {
            *c = r.f32("color")?;
        }
        let lifetime = Time::decode(r, "lifetime")?;
        r.bool("frame_locked")?;
        let n = r.count("points", 24)?;
        let mut points = Vec::with_capacity(n);
        for _ in 0..n {
            points.push([r.f64("points")?, r.f64("points")?, r.f64("points")?]);
        }
        let n = r.count("colors", 16)?;
        for _ in 0..4 * n {
            r.f32("colors")?;
        }
        r.string("texture_resource")?;
        Header::decode(r)?;
        r.string("texture.format")?;
        r.bytes("texture.data")?;
        let n = r.count("uv_coordinates", 8)?;
        for _ in 0..2 * n {
            r.f32("uv_coordinates")?;
        }
        let text = r.string("text")?;
        r.string("mesh_resource")?;
        r.string("mesh_file.filename")?;
        r.bytes("mesh_file.data")?;
        r.bool("mesh_use_embedded_materials")?;
        Ok(Marker {
            header,
            ns,
            id,
            kind,
            action,
            position: [v[0], v[1], v[2]],
            orientation: [v[3], v[4], v[5], v[6]],
            scale: [v[7], v[8], v[9]],
            color,
            lifetime,
            points,
            text,
        })
    }
}

/// `visualization_msgs/MarkerArray`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MarkerArray {
    /// The markers.
    pub markers: Vec<Marker>,
}

impl Message for MarkerArray {
    const TYPE: &'static str = "visualization_msgs::msg::dds_::MarkerArray_";

    fn encode(&self, w: &mut CdrWriter) {
        w.u32(self.markers.len() as u32);
        for m in &self.markers {
            m.encode(w);
        }
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        let n = r.count("markers", 100)?;
        let markers = (0..n)
            .map(|_| Marker::decode(r))
            .collect::<Result<_, _>>()?;
        Ok(MarkerArray { markers })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip<M: Message + PartialEq + std::fmt::Debug>(m: &M) {
        let bytes = m.to_cdr();
        let mut r = CdrReader::with_header(&bytes).unwrap();
        assert_eq!(&M::decode(&mut r).unwrap(), m);
        assert_eq!(r.remaining(), 0);
        // Every cut of the sample is refused, never a panic.
        for cut in 4..bytes.len() {
            let mut r = CdrReader::with_header(&bytes[..cut]).unwrap();
            if let Ok(short) = M::decode(&mut r) {
                assert_ne!(&short, m, "a sample cut at {cut} bytes read as whole");
            }
        }
    }

    #[test]
    fn messages_read_back_what_they_wrote() {
        let point = |t: f64| JointTrajectoryPoint {
            positions: vec![t, -t],
            velocities: vec![1.0, 2.0],
            accelerations: vec![],
            effort: vec![],
            time_from_start: Time::from_secs(t),
        };
        roundtrip(&JointTrajectory {
            header: Header {
                stamp: Time::from_nanos(5),
                frame_id: "base".into(),
            },
            joint_names: vec!["a".into(), "b".into()],
            points: vec![point(0.0), point(0.5)],
        });
        roundtrip(&JointState {
            header: Header::default(),
            name: vec!["j1".into()],
            position: vec![0.25],
            velocity: vec![],
            effort: vec![-1.0],
        });
        roundtrip(&MarkerArray {
            markers: vec![Marker {
                ns: "path".into(),
                kind: 4,
                points: vec![[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]],
                text: "goal".into(),
                ..Marker::default()
            }],
        });
    }

    #[test]
    fn goal_ids_are_version_4_uuids() {
        let id = GoalId::from_bits(u128::MAX);
        let s = id.to_string();
        assert_eq!(s.len(), 36);
        assert_eq!(&s[14..15], "4");
        assert!(matches!(&s[19..20], "8" | "9" | "a" | "b"), "{s}");
    }
}
