//! A joint trajectory for ROS 2, viewers and torque controllers (`cps-cli export`, and the
//! `[export]` section of robot experiments), in three formats:
//!
//! - **`ros2-yaml`**: a `trajectory_msgs/msg/JointTrajectory` in YAML flow style (positions,
//!   velocities and accelerations, so `joint_trajectory_controller` interpolates quintically),
//!   one point per `period`; the same text works for `ros2 topic pub` and, wrapped as
//!   `{trajectory: …}`, for a `control_msgs/action/FollowJointTrajectory` goal. Every number
//!   is written as a YAML float (with a point, signed exponent), as ROS's typed fields need.
//! - **`mcap`**: an MCAP file with the ROS 2 profile (`ros2msg` schemas, CDR messages, the
//!   QoS rosbag2 records): the JointTrajectory on
//!   `/joint_trajectory_controller/joint_trajectory`, and, sampled every `period` along the
//!   motion, `/joint_states` and `/tf`, with `/tf_static` and `/robot_description` (a URDF
//!   whose links are the `/tf` frames) so a viewer such as Foxglove shows the robot moving.
//! - **`csv-1khz`**: `t`, positions, `<joint>_vel`, `<joint>_acc` at 1 kHz, for
//!   libfranka-style controllers.
//!
//! Positions between the file's samples, velocities and accelerations are those of the cubic
//! spline through the samples that starts and ends at rest (the interpolation of
//! `cps-cli limits check`).

pub mod ros2;
mod section;
mod urdf;

#[cfg(feature = "mcap")]
use std::collections::BTreeMap;
use std::path::Path;

use cps_kinematics::JointSpline;
#[cfg(feature = "mcap")]
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use serde_json::{Value, json};

use crate::limits::{JointTrajectory, check_samples, read_joint_trajectory};
use crate::robot_file::RobotModel;
use cps_outcome::InputError;
use cps_outcome::outcome::{Column, Format, Table};
use cps_outcome::results_dir::FileKind;
pub use section::{ExportPlan, ExportSection};
pub use urdf::{Frames, robot_description};

/// The JointTrajectory topic of `joint_trajectory_controller` under its default name.
pub const TRAJECTORY_TOPIC: &str = "/joint_trajectory_controller/joint_trajectory";

/// The largest single argument Linux passes to a program (`MAX_ARG_STRLEN`, 128 KiB): a
/// YAML file beyond it cannot go through `ros2 topic pub "$(cat …)"`.
pub const MAX_ARGUMENT_BYTES: usize = 128 * 1024;

/// An export format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// `trajectory_msgs/msg/JointTrajectory` as YAML.
    Ros2Yaml,
    /// An MCAP file with the ROS 2 profile.
    Mcap,
    /// A 1 kHz CSV of positions, velocities and accelerations.
    Csv1khz,
}

impl ExportFormat {
    /// Every format.
    pub const ALL: [ExportFormat; 3] = [
        ExportFormat::Ros2Yaml,
        ExportFormat::Mcap,
        ExportFormat::Csv1khz,
    ];

    /// `ros2-yaml`, `mcap`, `csv-1khz`.
    pub fn name(self) -> &'static str {
        match self {
            ExportFormat::Ros2Yaml => "ros2-yaml",
            ExportFormat::Mcap => "mcap",
            ExportFormat::Csv1khz => "csv-1khz",
        }
    }

    /// The format of a name, or a sentence listing them.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| {
                format!("export format `{name}`: choose `ros2-yaml`, `mcap` or `csv-1khz`")
            })
    }

    /// The file name an experiment's results use: `trajectory.yaml`, `trajectory.mcap`,
    /// `trajectory_1khz.csv`.
    pub fn file_name(self) -> &'static str {
        match self {
            ExportFormat::Ros2Yaml => "trajectory.yaml",
            ExportFormat::Mcap => "trajectory.mcap",
            ExportFormat::Csv1khz => "trajectory_1khz.csv",
        }
    }

    /// What an existing file of this format looks like (for `--force`).
    pub fn file_kind(self) -> FileKind {
        match self {
            ExportFormat::Ros2Yaml => FileKind::TrajectoryYaml,
            ExportFormat::Mcap => FileKind::Mcap,
            ExportFormat::Csv1khz => FileKind::TrajectoryCsv,
        }
    }
}

/// Settings of an export.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExportOptions {
    /// Seconds between the JointTrajectory's points and between the MCAP's joint states
    /// and transforms (the 1 kHz CSV ignores it).
    pub period: f64,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions { period: 0.01 }
    }
}

impl ExportOptions {
    /// Checks the period: 0.1 ms … 1 s.
    pub fn check(&self) -> Result<(), InputError> {
        if self.period.is_finite() && (1e-4..=1.0).contains(&self.period) {
            Ok(())
        } else {
            Err(InputError(format!(
                "--period {}: give the seconds between exported points, 0.0001 to 1",
                self.period
            )))
        }
    }
}

/// Samples of a trajectory at a fixed period, from its start (time 0) to its end.
#[derive(Debug, Clone)]
pub(crate) struct Samples {
    pub(crate) t: Vec<f64>,
    pub(crate) q: Vec<Vec<f64>>,
    pub(crate) qd: Vec<Vec<f64>>,
    pub(crate) qdd: Vec<Vec<f64>>,
}

/// The spline through the trajectory sampled every `period` (the end always included).
pub(crate) fn sample(traj: &JointTrajectory, period: f64) -> Samples {
    let spline = JointSpline::new(&traj.times, &traj.q)
        .expect("a read trajectory has increasing, finite times");
    let t0 = traj.times[0];
    let span = traj.times[traj.times.len() - 1] - t0;
    let steps = (span / period - 1e-9).ceil().max(1.0) as usize;
    let mut s = Samples {
        t: Vec::with_capacity(steps + 1),
        q: Vec::with_capacity(steps + 1),
        qd: Vec::with_capacity(steps + 1),
        qdd: Vec::with_capacity(steps + 1),
    };
    for k in 0..=steps {
        let t = (k as f64 * period).min(span);
        let p = spline.point(t0 + t);
        s.t.push(t);
        s.q.push(p.q);
        s.qd.push(p.d1);
        s.qdd.push(p.d2);
    }
    s
}

/// The joint names an export uses: the robot's, or `<robot>_joint<i>` for the generic
/// `joint<i>` of DH robots (`panda_joint1`, as franka_description names them).
pub fn joint_names(robot: &RobotModel) -> Vec<String> {
    robot.published_joint_names()
}

/// A number as a YAML float that PyYAML and ROS read as `float64`: always with a point and,
/// with an exponent, a signed one (`1.0e-7`).
fn yaml_float(v: f64) -> String {
    let s = format!("{v:?}");
    match s.split_once('e') {
        Some((m, e)) => {
            let m = if m.contains('.') {
                m.to_string()
            } else {
                format!("{m}.0")
            };
            let e = if e.starts_with('-') {
                e.to_string()
            } else {
                format!("+{e}")
            };
            format!("{m}e{e}")
        }
        None => s,
    }
}

fn yaml_list(v: &[f64]) -> String {
    let cells: Vec<String> = v.iter().map(|x| yaml_float(*x)).collect();
    format!("[{}]", cells.join(", "))
}

fn nanoseconds(t: f64) -> u64 {
    (t * 1e9).round().max(0.0) as u64
}

fn yaml_duration(t: f64) -> String {
    let ns = nanoseconds(t);
    format!(
        "{{sec: {}, nanosec: {}}}",
        ns / 1_000_000_000,
        ns % 1_000_000_000
    )
}

/// The JointTrajectory in YAML flow style.
fn ros2_yaml(names: &[String], s: &Samples) -> String {
    let quoted: Vec<String> = names
        .iter()
        .map(|n| format!("'{}'", n.replace('\'', "''")))
        .collect();
    let mut out = format!(
        "{{header: {{stamp: {{sec: 0, nanosec: 0}}, frame_id: ''}},\n joint_names: [{}],\n points: [\n",
        quoted.join(", ")
    );
    for k in 0..s.t.len() {
        out.push_str(&format!(
            "  {{positions: {}, velocities: {}, accelerations: {}, time_from_start: {}}}{}\n",
            yaml_list(&s.q[k]),
            yaml_list(&s.qd[k]),
            yaml_list(&s.qdd[k]),
            yaml_duration(s.t[k]),
            if k + 1 < s.t.len() { "," } else { "" }
        ));
    }
    out.push_str(" ]}\n");
    out
}

/// The 1 kHz table.
fn csv_table(names: &[String], s: &Samples) -> Table {
    let mut table =
        Table::new("trajectory_1khz").with(Column::numbers("t", s.t.clone(), Format::Plain));
    for (suffix, rows) in [("", &s.q), ("_vel", &s.qd), ("_acc", &s.qdd)] {
        for (j, name) in names.iter().enumerate() {
            table.push(Column::numbers(
                format!("{name}{suffix}"),
                rows.iter().map(|r| r[j]).collect(),
                Format::Plain,
            ));
        }
    }
    table
}

/// Messages per topic of an MCAP export.
type TopicCounts = Vec<(&'static str, usize)>;

/// The MCAP file's bytes and its messages per topic; in a build without the crate's
/// `mcap` feature (the README's first command), a refusal in words.
#[cfg(not(feature = "mcap"))]
fn mcap_bytes(
    _robot: &RobotModel,
    _names: &[String],
    _s: &Samples,
) -> Result<(Vec<u8>, TopicCounts), String> {
    Err("this build of cps writes no MCAP (crate cps-movement without its `mcap` feature, as the README's first command builds it); `cargo install --path crates/cps-cli` and the tests build it".into())
}

/// The MCAP file's bytes and its messages per topic.
#[cfg(feature = "mcap")]
fn mcap_bytes(
    robot: &RobotModel,
    names: &[String],
    s: &Samples,
) -> Result<(Vec<u8>, TopicCounts), String> {
    mcap_file(robot, names, s).map_err(|e| e.to_string())
}

#[cfg(feature = "mcap")]
fn mcap_file(
    robot: &RobotModel,
    names: &[String],
    s: &Samples,
) -> Result<(Vec<u8>, TopicCounts), mcap::McapError> {
    let frames = Frames::new(&robot.name, names.len());
    let urdf = robot_description(robot, names, &frames);
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .library(format!("cps {}", env!("CARGO_PKG_VERSION")))
        .compression(None)
        .create(std::io::Cursor::new(Vec::new()))?;
    let mut schema = BTreeMap::new();
    for (name, text) in ros2::schemas() {
        schema.insert(name, w.add_schema(name, "ros2msg", text.as_bytes())?);
    }
    let topics: [(&str, &str, u32, bool); 5] = [
        ("/robot_description", "std_msgs/msg/String", 1, true),
        ("/tf_static", "tf2_msgs/msg/TFMessage", 1, true),
        (
            TRAJECTORY_TOPIC,
            "trajectory_msgs/msg/JointTrajectory",
            1,
            false,
        ),
        ("/joint_states", "sensor_msgs/msg/JointState", 10, false),
        ("/tf", "tf2_msgs/msg/TFMessage", 100, false),
    ];
    let mut channel = Vec::new();
    for (topic, ty, depth, latched) in topics {
        let metadata = BTreeMap::from([(
            "offered_qos_profiles".to_string(),
            ros2::qos(depth, latched),
        )]);
        channel.push(w.add_channel(schema[ty], topic, "cdr", &metadata)?);
    }
    let mut counts: Vec<(&'static str, usize)> = topics.iter().map(|t| (t.0, 0)).collect();
    let mut put = |w: &mut mcap::Writer<_>, c: usize, time: u64, data: &[u8]| {
        counts[c].1 += 1;
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel[c],
                sequence: counts[c].1 as u32,
                log_time: time,
                publish_time: time,
            },
            data,
        )
    };
    let (base, joints, tail) = robot.chain.axis_joints();
    put(&mut w, 0, 0, &ros2::string(&urdf))?;
    let fixed = [
        (frames.world.clone(), frames.base.clone(), base),
        (
            frames.links[names.len() - 1].clone(),
            frames.tool.clone(),
            tail,
        ),
    ];
    put(&mut w, 1, 0, &ros2::tf_message(0, &fixed))?;
    let points: Vec<ros2::TrajectoryPoint> = (0..s.t.len())
        .map(|k| ros2::TrajectoryPoint {
            positions: &s.q[k],
            velocities: &s.qd[k],
            accelerations: &s.qdd[k],
            time_from_start_ns: nanoseconds(s.t[k]),
        })
        .collect();
    put(&mut w, 2, 0, &ros2::joint_trajectory("", names, &points))?;
    let parents: Vec<&String> = std::iter::once(&frames.base).chain(&frames.links).collect();
    for k in 0..s.t.len() {
        let stamp = nanoseconds(s.t[k]);
        put(
            &mut w,
            3,
            stamp,
            &ros2::joint_state(stamp, names, &s.q[k], &s.qd[k]),
        )?;
        let moving: Vec<(String, String, Isometry3<f64>)> = joints
            .iter()
            .zip(&s.q[k])
            .enumerate()
            .map(|(i, (j, q))| {
                let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), *q);
                (parents[i].clone(), frames.links[i].clone(), j.origin * turn)
            })
            .collect();
        put(&mut w, 4, stamp, &ros2::tf_message(stamp, &moving))?;
    }
    w.finish()?;
    Ok((w.into_inner().into_inner(), counts))
}

/// An exported trajectory: the file's bytes and what it holds.
#[derive(Debug, Clone)]
pub struct Exported {
    /// The format.
    pub format: ExportFormat,
    /// The file's content.
    pub bytes: Vec<u8>,
    /// `{"format", "points", "duration_s", "period_s", "joint_names", "bytes", "limits_ok",
    /// "topics"? (MCAP: messages per topic)}`.
    pub json: Value,
    /// The same in words, with how to use the file.
    pub lines: Vec<String>,
}

/// Its `json`.
impl serde::Serialize for Exported {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.json.serialize(s)
    }
}

/// Its `lines`.
impl std::fmt::Display for Exported {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.lines.join("\n"))
    }
}

/// Exports a trajectory in memory for `robot`.
pub fn export_samples(
    robot: &RobotModel,
    traj: &JointTrajectory,
    format: ExportFormat,
    options: &ExportOptions,
) -> Result<Exported, InputError> {
    options.check()?;
    let names = joint_names(robot);
    let period = match format {
        ExportFormat::Csv1khz => 0.001,
        _ => options.period,
    };
    let s = sample(traj, period);
    let duration = s.t[s.t.len() - 1];
    let fail = |e: String| InputError(format!("cannot write the {} export: {e}", format.name()));
    let mut topics = None;
    let bytes = match format {
        ExportFormat::Ros2Yaml => ros2_yaml(&names, &s).into_bytes(),
        ExportFormat::Csv1khz => cps_outcome::files::table_csv(&csv_table(&names, &s))
            .map_err(|e| fail(e.to_string()))?,
        ExportFormat::Mcap => {
            let (bytes, counts) = mcap_bytes(robot, &names, &s).map_err(fail)?;
            topics = Some(counts);
            bytes
        }
    };
    let limits = check_samples(robot, traj, 1000.0).map_err(|e| InputError(e.to_string()))?;
    let mut json = json!({
        "format": format.name(),
        "points": s.t.len(),
        "duration_s": duration,
        "period_s": period,
        "joint_names": names,
        "bytes": bytes.len(),
        "limits_ok": limits.ok(),
    });
    let mut lines = vec![format!(
        "{} points over {duration:.3} s every {} ms for joints {}",
        s.t.len(),
        period * 1e3,
        names.join(", ")
    )];
    if let Some(counts) = &topics {
        json["topics"] = counts
            .iter()
            .map(|(t, n)| (t.to_string(), json!(n)))
            .collect::<serde_json::Map<_, _>>()
            .into();
        for (t, n) in counts {
            lines.push(format!("  {t}: {n} message(s)"));
        }
    }
    if !limits.ok() {
        lines.push(format!(
            "note: the trajectory breaks {} limit(s) of the robot at 1 kHz (`cps-cli limits check` names them; `cps-cli retime` fixes the timing)",
            limits.check.violation_count()
        ));
    }
    if format == ExportFormat::Ros2Yaml && bytes.len() > MAX_ARGUMENT_BYTES {
        lines.push(format!(
            "note: {} KiB is more than one shell argument carries (128 KiB): give a larger --period, or pipe it (`ros2 topic pub --stdin`, ROS 2 Jazzy and later)",
            bytes.len() / 1024
        ));
    }
    Ok(Exported {
        format,
        bytes,
        json,
        lines,
    })
}

/// Reads a joint trajectory file and exports it for `robot`.
pub fn export_file(
    path: &Path,
    robot: &RobotModel,
    format: ExportFormat,
    options: &ExportOptions,
) -> Result<Exported, InputError> {
    options.check()?;
    let traj = read_joint_trajectory(path, robot.chain.dof())?;
    export_samples(robot, &traj, format, options)
}

/// How to use a written export, a line each.
pub fn usage(format: ExportFormat, file: &Path) -> Vec<String> {
    let f = file.display();
    match format {
        ExportFormat::Ros2Yaml => vec![
            "send it with:".into(),
            format!(
                "  ros2 topic pub --once {TRAJECTORY_TOPIC} trajectory_msgs/msg/JointTrajectory \"$(cat {f})\""
            ),
            format!(
                "  ros2 action send_goal /joint_trajectory_controller/follow_joint_trajectory control_msgs/action/FollowJointTrajectory \"{{trajectory: $(cat {f})}}\""
            ),
        ],
        ExportFormat::Mcap => vec![format!(
            "open {f} in Foxglove (3D panel: URDF from /robot_description, frames from /tf) or play it with `ros2 bag play {f}`"
        )],
        ExportFormat::Csv1khz => vec![],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaml_floats_always_read_back_as_floats() {
        assert_eq!(yaml_float(0.0), "0.0");
        assert_eq!(yaml_float(-0.0), "-0.0");
        assert_eq!(yaml_float(2.0), "2.0");
        assert_eq!(yaml_float(1e-7), "1.0e-7");
        assert_eq!(yaml_float(-2.5e-12), "-2.5e-12");
        assert_eq!(yaml_float(3e20), "3.0e+20");
        assert_eq!(yaml_float(0.125), "0.125");
        for v in [1e-7, -2.5e-12, 3e20, 0.1, -1234.5678] {
            assert_eq!(yaml_float(v).parse::<f64>().unwrap(), v);
        }
    }

    #[test]
    fn durations_split_into_seconds_and_nanoseconds() {
        assert_eq!(yaml_duration(0.0), "{sec: 0, nanosec: 0}");
        assert_eq!(yaml_duration(1.75), "{sec: 1, nanosec: 750000000}");
        assert_eq!(yaml_duration(2.001), "{sec: 2, nanosec: 1000000}");
    }
}
