//! An experiment as markers (`cps-cli ros2 show`): its learned path, its via points, start
//! and goal as a `visualization_msgs/MarkerArray` for RViz or Foxglove, with the robot of
//! its `[robot]` at its start (each collision shape the guard checks, namespace
//! `cps_robot/<link>`) and its scene's obstacles (`cps_scene/<name>`). Publishing them is
//! cps-drive's (`ros2_graph::publish_latched`).

use std::path::Path;

use cps_ros2_msg::msg::{Marker, MarkerArray};
use nalgebra::Isometry3;

use crate::{ExperimentError, InputError};

/// An experiment's markers, and what they show.
#[derive(Debug, Clone)]
pub struct Shown {
    /// The markers.
    pub markers: MarkerArray,
    /// Points of the learned path.
    pub path_points: usize,
    /// Via points.
    pub via_points: usize,
    /// The robot's shapes and the scene's obstacles drawn.
    pub robot: RobotShown,
}

/// `ros2 show`: an experiment's markers, published on `topic` for `seconds`, and who saw
/// them.
#[derive(Debug, Clone)]
pub struct Showed {
    /// The markers and what they show.
    pub shown: Shown,
    /// The MarkerArray topic.
    pub topic: String,
    /// The frame of the task's coordinates.
    pub frame: String,
    /// Seconds on the graph.
    pub seconds: f64,
    /// The DDS domain.
    pub domain: u16,
    /// The most viewers subscribed at once.
    pub subscribers: usize,
}

/// `{"topic", "frame", "domain", "markers", "path_points", "via_points", "robot_shapes",
/// "obstacles", "subscribers"}`.
impl serde::Serialize for Showed {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (shapes, obstacles) = self.shown.robot.counts();
        serde_json::json!({
            "topic": self.topic, "frame": self.frame, "domain": self.domain,
            "markers": self.shown.markers.markers.len(), "path_points": self.shown.path_points,
            "via_points": self.shown.via_points, "robot_shapes": shapes, "obstacles": obstacles,
            "subscribers": self.subscribers,
        })
        .serialize(s)
    }
}

/// What was shown, where and to how many viewers; then what of the robot.
impl std::fmt::Display for Showed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = &self.shown;
        writeln!(
            f,
            "showed {} markers ({} path points, {} via points, start and goal) on {} in frame {} for {:.0} s: {} viewer(s) subscribed",
            s.markers.markers.len(),
            s.path_points,
            s.via_points,
            self.topic,
            self.frame,
            self.seconds,
            self.subscribers
        )?;
        write!(f, "{}", s.robot)
    }
}

/// What was drawn of the experiment's robot.
#[derive(Debug, Clone, PartialEq)]
pub enum RobotShown {
    /// The experiment has no `[robot]`: the path alone.
    None,
    /// The robot has no collision geometry: why (its model's note).
    Unchecked(String),
    /// The robot at its initial configuration and the scene's obstacles.
    Shapes {
        /// The robot's name.
        robot: String,
        /// Its shapes drawn.
        links: usize,
        /// The obstacles drawn, by name.
        obstacles: Vec<String>,
    },
}

impl RobotShown {
    /// How many of the robot's shapes and of the obstacles were drawn.
    pub fn counts(&self) -> (usize, usize) {
        match self {
            RobotShown::Shapes {
                links, obstacles, ..
            } => (*links, obstacles.len()),
            _ => (0, 0),
        }
    }
}

impl std::fmt::Display for RobotShown {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RobotShown::None => write!(f, "no [robot] in the experiment: the path alone"),
            RobotShown::Unchecked(note) => write!(f, "{note}"),
            RobotShown::Shapes {
                robot,
                links,
                obstacles,
            } => write!(
                f,
                "the robot `{robot}` at its initial configuration ({links} shapes, namespaces cps_robot/<link>) and {} obstacle(s) ({}; cps_scene/<name>), as triangle lists",
                obstacles.len(),
                obstacles.join(", ")
            ),
        }
    }
}

/// The markers of `experiment` in `frame`: its learned path (`<results>/trajectory.csv`,
/// columns `x,y,z` or the executed tool's; by default `results/<name>`, where `cps-cli
/// run` writes it), its via points, start and goal, and its robot and obstacles.
pub fn experiment_markers(
    experiment: &Path,
    results: Option<&Path>,
    frame: &str,
) -> Result<Shown, ExperimentError> {
    let exp = crate::experiment::load(experiment, None, &crate::budget::Ceilings::default())?;
    let task = &exp.config.task;
    if task.goal.len() != 3 {
        return Err(InputError(format!(
            "{}: its task has {} coordinate(s); markers show 3-D paths",
            experiment.display(),
            task.goal.len()
        ))
        .into());
    }
    let results = results.map_or_else(|| Path::new("results").join(&exp.name), Path::to_path_buf);
    let csv = results.join("trajectory.csv");
    if !csv.is_file() {
        return Err(InputError(format!(
            "{}: no learned path there (run `cps-cli run {} --out {}` first)",
            csv.display(),
            experiment.display(),
            results.display()
        ))
        .into());
    }
    // A Cartesian kind writes x, y, z; a joint-space kind the executed tool's.
    let header = cps_outcome::source::read_text(
        &csv,
        cps_outcome::source::MAX_FILE_BYTES << 4,
        "trajectory",
    )?;
    let columns = if header
        .lines()
        .next()
        .unwrap_or("")
        .split(',')
        .any(|c| c == "tool_x")
    {
        ["tool_x", "tool_y", "tool_z"]
    } else {
        ["x", "y", "z"]
    };
    let names = columns.map(String::from);
    let (_, demo) = cps_movement::movement::read_demo(&csv, Some(&names))?;
    let path: Vec<[f64; 3]> = (0..demo.len())
        .map(|k| {
            let s = demo.sample(k);
            [s[0], s[1], s[2]]
        })
        .collect();
    let point = |p: &[f64]| [p[0], p[1], p[2]];
    let via: Vec<[f64; 3]> = task.via.iter().map(|v| point(&v.position)).collect();
    let mut markers = cps_ros2::markers::path_markers(frame, &path, &via);
    // The task's own start and goal, where the path's ends should be.
    if let Some(m) = markers.markers.iter_mut().find(|m| m.id == 2) {
        m.position = point(&task.start);
    }
    if let Some(m) = markers.markers.iter_mut().find(|m| m.id == 4) {
        m.position = point(&task.goal);
    }
    let (shapes, robot) = robot_markers(exp.robot.as_ref(), frame)?;
    markers.markers.extend(shapes.0.into_iter().chain(shapes.1));
    Ok(Shown {
        markers,
        path_points: path.len(),
        via_points: via.len(),
        robot,
    })
}

/// The markers of the robot's shapes at its initial configuration and of its scene's
/// obstacles, and what was drawn (or why no robot is).
#[allow(clippy::type_complexity)]
fn robot_markers(
    robot: Option<&crate::robots::RobotChoice>,
    frame: &str,
) -> Result<((Vec<Marker>, Vec<Marker>), RobotShown), ExperimentError> {
    let Some(robot) = robot else {
        return Ok((Default::default(), RobotShown::None));
    };
    let Some(shapes) = &robot.model.shapes else {
        return Ok((
            Default::default(),
            RobotShown::Unchecked(robot.model.shapes_note().unwrap_or_default()),
        ));
    };
    let mut frames = Vec::new();
    robot
        .setup
        .chain
        .frames_into(&robot.setup.initial_q, &mut frames)
        .map_err(|e| InputError(format!("[robot] initial_q: {e}")))?;
    let marker =
        |ns: String, id: usize, pose: Isometry3<f64>, shape: &cps_geometry::Shape, color| {
            let surface = shape.surface();
            let corners = surface
                .triangles
                .iter()
                .flat_map(|t| t.map(|i| surface.vertices[i as usize]))
                .collect();
            let q = pose.rotation.coords;
            let t = pose.translation.vector;
            cps_ros2::markers::mesh_marker(
                frame,
                &ns,
                id as i32,
                ([t.x, t.y, t.z], [q.x, q.y, q.z, q.w]),
                corners,
                color,
            )
        };
    let links = shapes
        .bodies()
        .iter()
        .enumerate()
        .map(|(k, b)| {
            marker(
                format!("cps_robot/{}", b.link),
                k,
                frames[b.frame] * b.origin,
                &b.shape,
                LINK,
            )
        })
        .collect::<Vec<_>>();
    let obstacles = shapes
        .obstacles()
        .iter()
        .enumerate()
        .map(|(k, o)| {
            marker(
                format!("cps_scene/{}", o.name),
                k,
                o.pose,
                &o.shape,
                OBSTACLE,
            )
        })
        .collect::<Vec<_>>();
    let shown = RobotShown::Shapes {
        robot: robot.model.name.clone(),
        links: links.len(),
        obstacles: shapes.obstacles().iter().map(|o| o.name.clone()).collect(),
    };
    Ok(((links, obstacles), shown))
}

/// The links' colour (light grey) and the obstacles' (wood, a little transparent).
const LINK: [f32; 4] = [0.80, 0.82, 0.86, 1.0];
const OBSTACLE: [f32; 4] = [0.78, 0.68, 0.52, 0.8];
