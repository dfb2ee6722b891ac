//! `ros2 show`: an experiment's learned path, its via points, start and goal as a latched
//! `visualization_msgs/MarkerArray` for RViz or Foxglove. (Apart from `ros2.rs`, which
//! the robot backend uses, because it reads experiment files.)

use std::path::Path;
use std::time::Duration;

use cps_ros2::node::Qos;
use serde_json::json;

use crate::robot_file::Answer;
use crate::ros2::{node, ros2_error};
use crate::{ExperimentError, InputError};

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
    let names = ["x", "y", "z"].map(String::from);
    let (_, demo) = crate::movement::read_demo(&csv, Some(&names))?;
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
        "subscribers": most,
    });
    let lines = vec![format!(
        "showed {} markers ({} path points, {} via points, start and goal) on {} in frame {} for {:.0} s: {} viewer(s) subscribed",
        markers.markers.len(),
        path.len(),
        via.len(),
        settings.topic,
        settings.frame,
        settings.seconds,
        most
    )];
    Ok(Answer { json, lines })
}
