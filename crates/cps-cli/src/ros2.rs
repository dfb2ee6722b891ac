//! `cps-cli ros2 ...`: a ROS 2 graph over DDS, no ROS installation needed.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use cps_drive::ros2::MappingChoice;
use cps_drive::ros2::{self, GraphSettings, RecordSettings, SendSettings, Via};
use cps_drive::ros2_graph::publish_latched;
use cps_experiment::markers;
use cps_outcome::Ended;
use cps_robot::StopToken;
use indicatif::ProgressBar;

use crate::robot::InScene;
use crate::robot::print;

/// The robot, its joints' names and the domain.
#[derive(Args, Debug)]
pub struct On {
    /// The robot whose limits and joint names (its order) apply.
    #[arg(long, default_value = "panda")]
    robot: String,
    /// Joint names instead of the robot's (comma-separated, in the robot's order).
    #[arg(long, value_delimiter = ',')]
    joint_names: Option<Vec<String>>,
    /// DDS domain (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long, allow_hyphen_values = true, value_parser = cps_ros2::names::parse_domain)]
    domain: Option<u16>,
}

impl On {
    fn graph(&self) -> GraphSettings {
        GraphSettings {
            robot: self.robot.clone(),
            joint_names: self.joint_names.clone(),
            domain: self.domain,
            scene: None,
        }
    }
}

/// `cps-cli ros2 ...`. Exit codes: 0 done; 1 the controller refused, aborted or did not
/// answer in time, or the trajectory broke a limit (nothing sent); 2 bad input; 130
/// stopped by Ctrl-C (a goal is cancelled first; a recording keeps what came).
#[derive(Subcommand, Debug)]
pub enum Ros2Command {
    /// Send a joint trajectory (CSV: t, then one column per joint in rad) to a ros2_control
    /// joint_trajectory_controller, checked against the robot's limits first.
    Send(SendArgs),
    /// Follow a learned policy's recorded action chunks (CSV: chunk, arrived_s,
    /// observed_s, k, then one column per joint; the targets at --rate) on a
    /// joint_trajectory_controller: one replacement trajectory per chunk at its arrival,
    /// continuous for the controller, within every limit, braking to rest if chunks stop.
    Follow(FollowArgs),
    /// Record sensor_msgs/JointState as a cps joint CSV (t, then the robot's joints in its
    /// order, matched by name), with a report beside it.
    Record(RecordArgs),
    /// Show an experiment's learned path, via points, start and goal, its robot and scene
    /// shapes in RViz or Foxglove (visualization_msgs/MarkerArray, latched).
    Show(ShowArgs),
    /// List what is on the graph: the nodes and their middleware, topics with types and
    /// QoS, services and actions with the nodes at each end.
    Graph(GraphArgs),
}

/// `cps-cli ros2 graph`'s arguments.
#[derive(Args, Debug)]
pub struct GraphArgs {
    /// DDS domain (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long, allow_hyphen_values = true, value_parser = cps_ros2::names::parse_domain)]
    domain: Option<u16>,
    /// Seconds to watch before listing (discovery takes about a second).
    #[arg(long, default_value_t = 2.0)]
    seconds: f64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// `cps-cli ros2 follow`'s arguments.
#[derive(Args, Debug)]
pub struct FollowArgs {
    /// The chunk file.
    file: PathBuf,
    /// The controller (`/panda_arm_controller`): its `joint_trajectory` topic.
    #[arg(long)]
    controller: String,
    /// The chunks' targets per second.
    #[arg(long)]
    rate: f64,
    #[command(flatten)]
    on: On,
    #[command(flatten)]
    scene: InScene,
    /// Seconds between the points of each trajectory.
    #[arg(long, default_value_t = 0.01)]
    period: f64,
    /// Seconds to wait for the controller.
    #[arg(long, default_value_t = 10.0)]
    wait: f64,
    /// Seconds without a new chunk before the arm brakes to rest.
    #[arg(long, default_value_t = 0.25)]
    stall_timeout: f64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// `cps-cli ros2 send`'s arguments.
#[derive(Args, Debug)]
pub struct SendArgs {
    /// The trajectory file.
    file: PathBuf,
    /// The controller (`/panda_arm_controller`).
    #[arg(long)]
    controller: String,
    /// Publish on `<controller>/joint_trajectory` (no answer).
    #[arg(long, conflicts_with = "action")]
    topic: bool,
    /// Send a FollowJointTrajectory goal (the default): feedback, result, cancel.
    #[arg(long)]
    action: bool,
    #[command(flatten)]
    on: On,
    #[command(flatten)]
    scene: InScene,
    /// Seconds between the points sent.
    #[arg(long, default_value_t = 0.01)]
    period: f64,
    /// Seconds to wait for the controller.
    #[arg(long, default_value_t = 10.0)]
    wait: f64,
    /// Record the robot's joint states while the goal runs (CSV, with a report of the
    /// tracking and the limits beside it).
    #[arg(long)]
    record: Option<PathBuf>,
    /// The JointState topic recorded.
    #[arg(long, default_value = "/joint_states")]
    joint_states: String,
    /// Replace an existing recording.
    #[arg(long)]
    force: bool,
    /// Request/reply mapping: auto (the controller's middleware's), cyclone or fastdds.
    #[arg(long, default_value = "auto", value_parser = |s: &str| s.parse::<MappingChoice>().map_err(|e| e.to_string()))]
    service_mapping: MappingChoice,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// `cps-cli ros2 record`'s arguments.
#[derive(Args, Debug)]
pub struct RecordArgs {
    /// The JointState topic.
    #[arg(long, default_value = "/joint_states")]
    topic: String,
    /// Seconds to record, from the first message published after it began.
    #[arg(long)]
    duration: f64,
    /// The CSV to write.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    on: On,
    /// Seconds to wait for the first message.
    #[arg(long, default_value_t = 10.0)]
    wait: f64,
    /// Also hear best-effort publishers (they may lose samples).
    #[arg(long)]
    best_effort: bool,
    /// Replace an existing recording.
    #[arg(long)]
    force: bool,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// `cps-cli ros2 show`'s arguments.
#[derive(Args, Debug)]
pub struct ShowArgs {
    /// The experiment file (its via points, start and goal).
    experiment: PathBuf,
    /// Its results directory (default: `results/<name>`, where `run` writes).
    #[arg(long)]
    results: Option<PathBuf>,
    /// The MarkerArray topic.
    #[arg(long, default_value = "/cps/markers")]
    topic: String,
    /// The frame of the task's coordinates.
    #[arg(long, default_value = "world")]
    frame: String,
    /// Seconds to stay on the graph (viewers that join meanwhile get the markers).
    #[arg(long, default_value_t = 30.0)]
    seconds: f64,
    /// DDS domain (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long, allow_hyphen_values = true, value_parser = cps_ros2::names::parse_domain)]
    domain: Option<u16>,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// `cps-cli ros2`.
pub fn ros2(cmd: &Ros2Command, stop: &StopToken) -> Result<ExitCode> {
    let bar = ProgressBar::new(1000).with_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len}")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    match cmd {
        Ros2Command::Graph(a) => {
            let look = cps_drive::ros2_graph::GraphLook {
                domain: a.domain,
                seconds: a.seconds,
            };
            bar.set_message("watching the graph");
            let seen = cps_drive::ros2_graph::graph(&look, stop)?;
            finish(&bar, &seen, Ended::Completed, a.json)
        }
        Ros2Command::Show(a) => finish(&bar, &show(a, stop)?, Ended::Completed, a.json),
        Ros2Command::Send(a) => {
            let s = SendSettings {
                service_mapping: a.service_mapping,
                controller: a.controller.clone(),
                via: if a.topic { Via::Topic } else { Via::Action },
                graph: a.on.graph().in_scene(a.scene.path()),
                period: a.period,
                wait: a.wait,
                record: a.record.as_ref().map(|out| ros2::SendRecord {
                    out: out.clone(),
                    topic: a.joint_states.clone(),
                    force: a.force,
                }),
            };
            bar.set_message("following (‰)");
            let send = |f: f64| bar.set_position((f * 1000.0) as u64);
            let (answer, c) = ros2::send(&a.file, &s, stop, send)?;
            finish(&bar, &answer, c, a.json)
        }
        Ros2Command::Follow(a) => {
            let s = cps_drive::ros2_follow::FollowTopic {
                controller: a.controller.clone(),
                graph: a.on.graph().in_scene(a.scene.path()),
                period: a.period,
                wait: a.wait,
            };
            let gap = cps_chunks::ChunkSettings::default().max_gap_rad;
            let f = cps_chunks::FollowSettings::with_chunks(a.stall_timeout, gap);
            let done = cps_drive::ros2_follow::ros2_follow(&a.file, a.rate, &s, &f, stop);
            let (answer, c) = done?;
            finish(&bar, &answer, c, a.json)
        }
        Ros2Command::Record(a) => {
            let s = RecordSettings {
                topic: a.topic.clone(),
                duration: a.duration,
                graph: a.on.graph(),
                wait: a.wait,
                best_effort: a.best_effort,
            };
            bar.set_length((a.duration * 10.0).ceil() as u64);
            bar.set_message("recording (0.1 s)");
            let tick = |t: f64| bar.set_position((t * 10.0) as u64);
            let (answer, c) = ros2::record(&s, &a.out, a.force, stop, tick)?;
            finish(&bar, &answer, c, a.json)
        }
    }
}

/// Clears the bar, prints the result and exits with how it ended.
fn finish<T>(bar: &ProgressBar, result: &T, ended: Ended, json: bool) -> Result<ExitCode>
where
    T: serde::Serialize + std::fmt::Display,
{
    bar.finish_and_clear();
    print(result, json)?;
    Ok(crate::status(ended))
}

/// `cps-cli ros2 show`: the experiment's markers published, and what was shown.
fn show(a: &ShowArgs, stop: &StopToken) -> Result<markers::Showed> {
    let shown = markers::experiment_markers(&a.experiment, a.results.as_deref(), &a.frame)?;
    let p = publish_latched(&shown.markers, &a.topic, a.seconds, a.domain, stop)?;
    Ok(markers::Showed {
        shown,
        topic: a.topic.clone(),
        frame: a.frame.clone(),
        seconds: a.seconds,
        domain: p.domain,
        subscribers: p.subscribers,
    })
}
