//! `ros2 show`: an experiment's learned path, its via points, start and goal as a latched
//! `visualization_msgs/MarkerArray` for RViz or Foxglove, with the robot of its `[robot]`
//! at its start (each collision shape the guard checks, namespace `cps_robot/<link>`) and
//! its scene's obstacles (`cps_scene/<name>`). (Apart from `ros2.rs`, which the robot backend uses,
//! because it reads experiment files.)

use std::path::Path;
use std::time::Duration;

use cps_ros2::node::Qos;
use cps_ros2_msg::msg::Marker;
use nalgebra::Isometry3;
use serde_json::json;

use crate::{ExperimentError, InputError};
use cps_drive::ros2::{node, ros2_error};
use cps_movement::robot_file::Answer;

/// What and where to show.
#[derive(Debug, Clone)]
pub struct ShowSettings {
    /// The MarkerArray topic (`/cps/markers`).
    pub topic: String,
    /// The frame the task's coordinates are in (`world`; the scene's base frame).
    pub frame: String,
    /// Seconds to stay on the graph (the markers are latched: a viewer that joins in
    /// that time still gets them).
    pub seconds: f64,
    /// The DDS domain (None: `ROS_DOMAIN_ID`, else 0).
    pub domain: Option<u16>,
}

/// `ros2 show`: an experiment's learned path (`<results>/trajectory.csv`, columns `x,y,z`;
/// by default `results/<name>`, where `cps-cli run` writes it),
/// its via points, start and goal (from the experiment file) as a latched
/// `visualization_msgs/MarkerArray`, kept on the graph for `settings.seconds` or until
/// `stop`; the answer says how many viewers subscribed.
pub fn show(
    experiment: &Path,
    results: Option<&Path>,
    settings: &ShowSettings,
    stop: &cps_robot::StopToken,
) -> Result<Answer, ExperimentError> {
    if !(settings.seconds.is_finite() && settings.seconds > 0.0 && settings.seconds <= 86_400.0) {
        return Err(InputError(format!(
            "--seconds {}: give seconds in (0, 86400]",
            settings.seconds
        ))
        .into());
    }
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
    let mut markers = cps_ros2::markers::path_markers(&settings.frame, &path, &via);
    // The task's own start and goal, where the path's ends should be.
    if let Some(m) = markers.markers.iter_mut().find(|m| m.id == 2) {
        m.position = point(&task.start);
    }
    if let Some(m) = markers.markers.iter_mut().find(|m| m.id == 4) {
        m.position = point(&task.goal);
    }
    let (shapes, robot_line) = robot_markers(exp.robot.as_ref(), &settings.frame)?;
    let shown = [shapes.0.len(), shapes.1.len()];
    markers.markers.extend(shapes.0.into_iter().chain(shapes.1));
    let node = node(settings.domain)?;
    let mut writer = node
        .publisher::<cps_ros2_msg::msg::MarkerArray>(&settings.topic, Qos::Latched { depth: 1 })
        .map_err(ros2_error)?;
    writer.write(&markers).map_err(ros2_error)?;
    let end = std::time::Instant::now() + Duration::from_secs_f64(settings.seconds);
    while std::time::Instant::now() < end && !stop.is_stopped() {
        std::thread::sleep(Duration::from_millis(50));
    }
    let most = writer.matched_ever();
    let json = json!({
        "topic": settings.topic,
        "frame": settings.frame,
        "domain": node.name().domain,
        "markers": markers.markers.len(),
        "path_points": path.len(),
        "via_points": via.len(),
        "robot_shapes": shown[0],
        "obstacles": shown[1],
        "subscribers": most,
    });
    let lines = vec![
        format!(
            "showed {} markers ({} path points, {} via points, start and goal) on {} in frame {} for {:.0} s: {} viewer(s) subscribed",
            markers.markers.len(),
            path.len(),
            via.len(),
            settings.topic,
            settings.frame,
            settings.seconds,
            most
        ),
        robot_line,
    ];
    Ok(Answer { json, lines })
}

/// The markers of the robot's shapes at its initial configuration and of its scene's
/// obstacles, and a line saying what was drawn (or why no robot is).
#[allow(clippy::type_complexity)]
fn robot_markers(
    robot: Option<&crate::robots::RobotChoice>,
    frame: &str,
) -> Result<((Vec<Marker>, Vec<Marker>), String), ExperimentError> {
    let Some(robot) = robot else {
        return Ok((
            Default::default(),
            "no [robot] in the experiment: the path alone".into(),
        ));
    };
    let Some(shapes) = &robot.model.shapes else {
        return Ok((
            Default::default(),
            robot.model.shapes_note().unwrap_or_default(),
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
    let line = format!(
        "the robot `{}` at its initial configuration ({} shapes, namespaces cps_robot/<link>) and {} obstacle(s) ({}; cps_scene/<name>), as triangle lists",
        robot.model.name,
        links.len(),
        obstacles.len(),
        shapes
            .obstacles()
            .iter()
            .map(|o| o.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(((links, obstacles), line))
}

/// The links' colour (light grey) and the obstacles' (wood, a little transparent).
const LINK: [f32; 4] = [0.80, 0.82, 0.86, 1.0];
const OBSTACLE: [f32; 4] = [0.78, 0.68, 0.52, 0.8];
