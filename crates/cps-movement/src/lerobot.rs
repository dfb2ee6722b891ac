//! LeRobot datasets as demonstrations: which episodes, which feature, and its entries
//! matched to a robot's joints by name; and a dataset described for `cps-cli lerobot
//! show`. Reading the format is `cps-lerobot`'s; recordings written as a dataset are
//! `lerobot_write`'s.

use std::path::Path;

use cps_dmp::Demonstration;
use cps_lerobot::{Dataset, Feature, LeRobotError};
use cps_outcome::InputError;
use serde_json::{Value, json};

use crate::robot_file::load_robot;

/// Demonstrations, each with the words that name it in messages.
pub type Labelled = Vec<(String, Demonstration)>;

/// How far from `frame / fps` LeRobot lets a frame's timestamp be (its `tolerance_s`).
pub const TOLERANCE_S: f64 = 1e-4;

/// Which frames of a dataset become demonstrations.
#[derive(Debug, Clone, PartialEq)]
pub struct Pick {
    /// The episodes (default: every one).
    pub episodes: Option<Vec<usize>>,
    /// The feature: `observation.state` (default) or `action`, or another vector.
    pub feature: String,
    /// The robot whose joints the feature's entries are matched to by name (default: the
    /// dataset's `robot_type` when cps knows that robot; otherwise every entry).
    pub robot: Option<String>,
}

impl Default for Pick {
    fn default() -> Self {
        Pick {
            episodes: None,
            feature: "observation.state".into(),
            robot: None,
        }
    }
}

pub(crate) fn input(e: LeRobotError) -> InputError {
    InputError(e.to_string())
}

/// The picked episodes of the dataset at `root` as demonstrations (one per episode, its
/// timestamps from 0, named `<root> episode <k>`), with the dimensions' names: the entries chosen by `columns` when
/// given, else the robot's joints, else every entry of the feature.
pub fn demonstrations(
    root: &Path,
    pick: &Pick,
    columns: Option<&[String]>,
) -> Result<(Vec<String>, Labelled), InputError> {
    let ds = Dataset::open(root).map_err(input)?;
    let feature = ds.numeric_feature(&pick.feature).map_err(input)?;
    let wanted: Option<Vec<String>> = match (columns, &pick.robot) {
        (Some(c), _) => Some(c.to_vec()),
        (None, Some(robot)) => Some(joint_names(robot)?),
        (None, None) => ds
            .info()
            .robot_type
            .as_deref()
            .and_then(|r| joint_names(plugin_arm(r).unwrap_or(r)).ok())
            .filter(|joints| matches_all(feature, joints)),
    };
    episodes_of(&ds, root, pick, wanted.as_deref())
}

/// The picked episodes of the dataset at `root`, the feature's entries matched by name to
/// `joints` (a robot's joint names, in its order): an experiment's `[demonstrations]
/// lerobot`, whose robot is the experiment's.
pub fn joint_demonstrations(
    root: &Path,
    pick: &Pick,
    joints: &[String],
) -> Result<(Vec<String>, Labelled), InputError> {
    let ds = Dataset::open(root).map_err(input)?;
    ds.numeric_feature(&pick.feature).map_err(input)?;
    episodes_of(&ds, root, pick, Some(joints))
}

fn episodes_of(
    ds: &Dataset,
    root: &Path,
    pick: &Pick,
    wanted: Option<&[String]>,
) -> Result<(Vec<String>, Labelled), InputError> {
    let episodes: Vec<usize> = match &pick.episodes {
        Some(e) if e.is_empty() => {
            return Err(InputError("--episodes: name at least one episode".into()));
        }
        Some(e) => e.clone(),
        None => (0..ds.episodes().len()).collect(),
    };
    let mut demos = Vec::with_capacity(episodes.len());
    let mut names = Vec::new();
    for &e in &episodes {
        let frames = ds.frames(e, &pick.feature).map_err(input)?;
        let take = match wanted {
            Some(w) => select(root, &pick.feature, &frames.names, w)?,
            None => (0..frames.names.len()).collect(),
        };
        names = take.iter().map(|&i| frames.names[i].clone()).collect();
        // LeRobot stores times as float32 and holds them to frame / fps within its
        // tolerance (1e-4 s): on that grid, the grid's exact times.
        let fps = ds.info().fps;
        let on_grid = frames
            .frame
            .iter()
            .zip(&frames.t)
            .all(|(&k, &t)| (t - k as f64 / fps).abs() <= TOLERANCE_S);
        let t0 = frames.t[0];
        let times = if on_grid {
            frames
                .frame
                .iter()
                .map(|&k| (k - frames.frame[0]) as f64 / fps)
                .collect()
        } else {
            frames.t.iter().map(|t| t - t0).collect()
        };
        let rows: Vec<Vec<f64>> = frames
            .values
            .iter()
            .map(|v| take.iter().map(|&i| v[i]).collect())
            .collect();
        let label = format!("{} episode {e}", root.display());
        let demo = Demonstration::new(times, &rows)
            .map_err(|err| InputError(format!("{label}: {err}")))?;
        demos.push((label, demo));
    }
    Ok((names, demos))
}

/// The arm behind a robot type of cps's LeRobot plugin (`lerobot_robot_cps`), which LeRobot
/// writes as a dataset's `robot_type`: `cps_dynamics` and `cps_franka` name a Franka's seven
/// joints `joint1.pos`…`joint7.pos` (the FR3's; a Panda's are named alike).
fn plugin_arm(robot_type: &str) -> Option<&'static str> {
    matches!(robot_type, "cps_dynamics" | "cps_franka").then_some("fr3")
}

/// The robot's joint names (its published ones).
pub(crate) fn joint_names(robot: &str) -> Result<Vec<String>, InputError> {
    Ok(load_robot(robot, None, None)?.published_joint_names())
}

/// An entry named as the joint: its published name, or the generic `joint<i>`, either
/// alone or with LeRobot's `.pos` after it (`joint3.pos`, what its robots and cps's
/// LeRobot plugin name a joint's position).
pub(crate) fn names_joint(entry: &str, joint: &str, i: usize) -> bool {
    let entry = entry.strip_suffix(".pos").unwrap_or(entry);
    entry == joint || entry == format!("joint{}", i + 1)
}

fn matches_all(feature: &Feature, joints: &[String]) -> bool {
    feature.names.as_ref().is_some_and(|names| {
        joints
            .iter()
            .enumerate()
            .all(|(i, j)| names.iter().any(|n| names_joint(n, j, i)))
    })
}

/// The indices of `wanted` among the feature's entry names; a sentence naming both where
/// one is missing.
fn select(
    root: &Path,
    feature: &str,
    names: &[String],
    wanted: &[String],
) -> Result<Vec<usize>, InputError> {
    wanted
        .iter()
        .enumerate()
        .map(|(i, w)| {
            names
                .iter()
                .position(|n| names_joint(n, w, i))
                .ok_or_else(|| {
                    InputError(format!(
                        "{}: `{feature}`'s entries ({}) do not name `{w}`: it is not this robot's joint space (choose another --feature, or its entries with --columns)",
                        root.display(),
                        names.join(", ")
                    ))
                })
        })
        .collect()
}

/// A dataset opened for `cps-cli lerobot show`: it says its rate, robot, tasks, episodes
/// (frames, duration, tasks) and features (type, shape, names) in words and as JSON.
pub fn describe(root: &Path) -> Result<Described, InputError> {
    Ok(Described {
        root: root.to_path_buf(),
        dataset: Dataset::open(root).map_err(input)?,
    })
}

/// A dataset and where it is (`lerobot show`).
#[derive(Debug, Clone)]
pub struct Described {
    /// Its folder.
    pub root: std::path::PathBuf,
    /// The dataset.
    pub dataset: Dataset,
}

impl Described {
    fn duration(&self, frames: usize) -> f64 {
        frames.saturating_sub(1) as f64 / self.dataset.info().fps
    }
}

/// `{"dataset", "format", "fps", "robot_type", "frames", "tasks", "features": [{"name",
/// "dtype", "shape", "names"}], "episodes": [{"episode", "frames", "duration_s", "tasks"}]}`.
impl serde::Serialize for Described {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (ds, info) = (&self.dataset, self.dataset.info());
        let features: Vec<Value> = info
            .features
            .iter()
            .map(
                |(name, f)| json!({"name": name, "dtype": f.dtype, "shape": f.shape, "names": f.names}),
            )
            .collect();
        let episodes: Vec<Value> = ds
            .episodes()
            .iter()
            .map(|e| {
                json!({"episode": e.index, "frames": e.length, "duration_s": self.duration(e.length),
                       "tasks": e.tasks})
            })
            .collect();
        json!({
            "dataset": self.root.display().to_string(),
            "format": info.codebase_version,
            "fps": info.fps,
            "robot_type": info.robot_type,
            "frames": info.total_frames,
            "tasks": ds.tasks(),
            "features": features,
            "episodes": episodes,
        })
        .serialize(s)
    }
}

impl std::fmt::Display for Described {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (ds, info) = (&self.dataset, self.dataset.info());
        let robot = info.robot_type.as_deref();
        write!(
            f,
            "{}: LeRobot {} dataset of {} episodes, {} frames at {} frames/s{}",
            self.root.display(),
            info.codebase_version,
            ds.episodes().len(),
            info.total_frames,
            info.fps,
            robot.map_or(String::new(), |r| format!(", robot `{r}`"))
        )?;
        write!(f, "\nfeatures:")?;
        for (name, feature) in &info.features {
            if cps_lerobot::dataset::is_bookkeeping(name) {
                continue;
            }
            let names = feature
                .names
                .as_ref()
                .map_or(String::new(), |n| format!(" ({})", n.join(", ")));
            write!(
                f,
                "\n  {name}: {} {:?}{names}",
                feature.dtype, feature.shape
            )?;
        }
        write!(f, "\nepisodes:")?;
        for e in ds.episodes() {
            let d = self.duration(e.length);
            write!(
                f,
                "\n  {}: {} frames, {d:.2} s, {}",
                e.index,
                e.length,
                e.tasks.join("; ")
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generic_and_published_names_both_match() {
        assert!(names_joint("panda_joint3", "panda_joint3", 2));
        assert!(names_joint("joint3", "panda_joint3", 2));
        assert!(!names_joint("joint2", "panda_joint3", 2));
        assert!(names_joint("joint3.pos", "fr3_joint3", 2));
        assert!(names_joint("fr3_joint3.pos", "fr3_joint3", 2));
        assert!(!names_joint("joint3.vel", "fr3_joint3", 2));
        let names = vec!["a".to_string(), "joint3".into()];
        let e = select(Path::new("d"), "obs", &names, &["panda_joint2".into()]).unwrap_err();
        assert!(
            e.0.contains("`panda_joint2`") && e.0.contains("a, joint3"),
            "{}",
            e.0
        );
    }
}
