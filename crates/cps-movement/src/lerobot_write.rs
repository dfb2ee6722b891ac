//! Recordings written as a LeRobot dataset (`cps-cli lerobot write`, `cps.lerobot.write`):
//! a Franka recording's or a joint CSV's columns as features, resampled onto the frame
//! grid. Laying out the files is `cps-lerobot`'s.

use std::path::Path;

use cps_outcome::InputError;
use serde_json::json;

use crate::lerobot::{input, names_joint};
use crate::robot_file::load_robot;

/// How recordings become a dataset ([`write_recordings`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Export {
    /// The robot recorded: its joints name the entries, its name is the `robot_type`.
    pub robot: String,
    /// What every episode did (LeRobot's task).
    pub task: String,
    /// Frames per second (default: the first recording's own rate, rounded).
    pub fps: Option<u32>,
}

/// One recording's columns: states, and where the file has them velocities, torques
/// and commands, each `samples × 7`-like rows on the recording's own times.
struct Recorded {
    times: Vec<f64>,
    groups: Vec<(&'static str, Vec<Vec<f64>>)>,
}

/// The feature each column group becomes.
const FEATURES: [(&str, &str); 4] = [
    ("q", "observation.state"),
    ("dq", "observation.velocity"),
    ("tau", "observation.effort"),
    ("q_d", "action"),
];

fn read_recording(path: &Path, joints: &[String]) -> Result<Recorded, InputError> {
    let text = cps_outcome::source::read_text(path, crate::movement::MAX_DEMO_BYTES, "recording")?;
    let header: Vec<String> = text
        .lines()
        .next()
        .unwrap_or("")
        .split(',')
        .map(|c| c.trim().to_string())
        .collect();
    let has = |c: &str| header.iter().any(|h| h == c);
    let n = joints.len();
    // A Franka recording (`franka execute --record`, `record`, `guide`): q1..7, dq, tau,
    // q_d; else a joint CSV (`ros2 record`, a trajectory): the joints by name, `_vel`.
    let franka = (1..=n).all(|j| has(&format!("q{j}")));
    let groups: Vec<(&str, Vec<String>)> = if franka {
        FEATURES
            .iter()
            .map(|(p, _)| (*p, (1..=n).map(|j| format!("{p}{j}")).collect::<Vec<_>>()))
            .filter(|(_, cols)| cols.iter().all(|c| has(c)))
            .collect()
    } else {
        let named: Vec<String> = joints
            .iter()
            .enumerate()
            .map(|(i, j)| {
                header
                    .iter()
                    .find(|h| names_joint(h, j, i))
                    .cloned()
                    .ok_or_else(|| {
                        InputError(format!(
                            "{}: no column names joint `{j}` (its columns: {}): give a Franka recording (t, q1..{n}, …) or a joint CSV with the robot's joint names (--robot)",
                            path.display(),
                            header.join(", ")
                        ))
                    })
            })
            .collect::<Result<_, _>>()?;
        let vel: Vec<String> = named.iter().map(|c| format!("{c}_vel")).collect();
        let mut g = vec![("q", named)];
        if vel.iter().all(|c| has(c)) {
            g.push(("dq", vel));
        }
        g
    };
    let mut times = Vec::new();
    let mut out = Vec::new();
    for (prefix, cols) in groups {
        let (_, demo) = crate::movement::parse_demo_columns(path, &text, Some(&cols))?;
        times = demo.times().to_vec();
        out.push((
            prefix,
            (0..demo.len()).map(|k| demo.sample(k).to_vec()).collect(),
        ));
    }
    Ok(Recorded { times, groups: out })
}

/// `rows` (on `times`) linearly interpolated at `k / fps` for every frame within them.
fn on_grid(times: &[f64], rows: &[Vec<f64>], fps: f64) -> Vec<Vec<f64>> {
    let t0 = times[0];
    let frames = ((times[times.len() - 1] - t0) * fps + 1e-9).floor() as usize + 1;
    let mut at = 0;
    (0..frames)
        .map(|k| {
            let t = t0 + k as f64 / fps;
            while at + 1 < times.len() - 1 && times[at + 1] <= t {
                at += 1;
            }
            if times.len() == 1 {
                return rows[0].clone();
            }
            let (a, b) = (times[at], times[at + 1]);
            let w = ((t - a) / (b - a)).clamp(0.0, 1.0);
            rows[at]
                .iter()
                .zip(&rows[at + 1])
                .map(|(x, y)| x + (y - x) * w)
                .collect()
        })
        .collect()
}

/// Recordings (one episode each) written as a LeRobot v3.0 dataset at `out`: the
/// joints' positions as `observation.state`, their velocities and torques where
/// recorded, and the commands as `action` — or, where a recording has none, the next
/// frame's state. Every recording is resampled onto the dataset's frame grid. `force`
/// replaces a dataset cps wrote at `out` (nothing else: see `cps_lerobot::write`), once
/// the new one is written.
pub fn write_recordings<P: AsRef<Path>>(
    out: &Path,
    recordings: &[P],
    export: &Export,
    force: bool,
) -> Result<Written, InputError> {
    if recordings.is_empty() {
        return Err(InputError("give at least one recording".into()));
    }
    let model = load_robot(&export.robot, None, None)?;
    let joints = model.published_joint_names();
    let read: Vec<Recorded> = recordings
        .iter()
        .map(|p| read_recording(p.as_ref(), &joints))
        .collect::<Result<_, _>>()?;
    let first: Vec<&str> = read[0].groups.iter().map(|(p, _)| *p).collect();
    for (r, path) in read.iter().zip(recordings) {
        let these: Vec<&str> = r.groups.iter().map(|(p, _)| *p).collect();
        if these != first {
            return Err(InputError(format!(
                "{}: has {} where {} has {}: every episode of a dataset has the same features",
                path.as_ref().display(),
                these.join(", "),
                recordings[0].as_ref().display(),
                first.join(", ")
            )));
        }
        if r.times.len() < 2 {
            return Err(InputError(format!(
                "{}: a recording needs two samples or more",
                path.as_ref().display()
            )));
        }
    }
    let fps = match export.fps {
        Some(0) => return Err(InputError("--fps: a whole number ≥ 1".into())),
        Some(f) => f,
        None => {
            let t = &read[0].times;
            let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
            steps.sort_by(f64::total_cmp);
            let rate = 1.0 / steps[steps.len() / 2];
            if !(rate.is_finite() && rate >= 0.5) {
                return Err(InputError(format!(
                    "{}: its samples are {} s apart: give --fps",
                    recordings[0].as_ref().display(),
                    cps_files::number(steps[steps.len() / 2], 6)
                )));
            }
            rate.round().max(1.0) as u32
        }
    };
    // Frames are counted before they are made: every recording's span at the rate.
    let frames: f64 = read
        .iter()
        .map(|r| (r.times[r.times.len() - 1] - r.times[0]) * f64::from(fps) + 1.0)
        .sum();
    cps_files::count::within(
        frames,
        cps_files::count::MAX_ROWS,
        &format!("--fps {fps}: the episodes' frames"),
        "LeRobot's datasets run at tens of frames per second: give a lower --fps",
    )?;
    let commanded = first.contains(&"q_d");
    let mut features: Vec<cps_lerobot::NewFeature> = read[0]
        .groups
        .iter()
        .filter(|(p, _)| *p != "q_d")
        .map(|(p, _)| cps_lerobot::NewFeature {
            name: FEATURES
                .iter()
                .find(|(k, _)| k == p)
                .map_or("", |(_, n)| n)
                .to_string(),
            names: joints.clone(),
        })
        .collect();
    features.push(cps_lerobot::NewFeature {
        name: "action".into(),
        names: joints.clone(),
    });
    let episodes: Vec<cps_lerobot::NewEpisode> = read
        .iter()
        .map(|r| {
            let mut values: Vec<Vec<Vec<f64>>> = r
                .groups
                .iter()
                .filter(|(p, _)| *p != "q_d")
                .map(|(_, rows)| on_grid(&r.times, rows, f64::from(fps)))
                .collect();
            let action = match r.groups.iter().find(|(p, _)| *p == "q_d") {
                Some((_, rows)) => on_grid(&r.times, rows, f64::from(fps)),
                None => values[0]
                    .iter()
                    .skip(1)
                    .chain(values[0].last())
                    .cloned()
                    .collect(),
            };
            values.push(action);
            cps_lerobot::NewEpisode {
                task: export.task.clone(),
                values,
            }
        })
        .collect();
    let spec = cps_lerobot::NewDataset {
        fps,
        robot_type: Some(model.name.clone()),
        features,
    };
    cps_lerobot::write(out, &spec, &episodes, force).map_err(input)?;
    Ok(Written {
        dataset: out.to_path_buf(),
        fps,
        robot_type: model.name,
        episodes: episodes.iter().map(cps_lerobot::NewEpisode::len).collect(),
        features: spec.features.into_iter().map(|f| f.name).collect(),
        commanded,
    })
}

/// A dataset written by [`write_recordings`] (`lerobot write`).
#[derive(Debug, Clone)]
pub struct Written {
    /// Its folder.
    pub dataset: std::path::PathBuf,
    /// Frames per second.
    pub fps: u32,
    /// The robot recorded.
    pub robot_type: String,
    /// Each episode's frames.
    pub episodes: Vec<usize>,
    /// Its features.
    pub features: Vec<String>,
    /// Whether the actions are the commands (else the next frame's state).
    pub commanded: bool,
}

/// `{"dataset", "fps", "robot_type", "episodes", "features", "action"}`.
impl serde::Serialize for Written {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let action = if self.commanded {
            "commands"
        } else {
            "next state"
        };
        json!({"dataset": self.dataset.display().to_string(), "fps": self.fps,
            "robot_type": self.robot_type, "episodes": self.episodes,
            "features": self.features, "action": action})
        .serialize(s)
    }
}

impl std::fmt::Display for Written {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let frames: Vec<String> = self.episodes.iter().map(usize::to_string).collect();
        let action = if self.commanded {
            "the commanded joints"
        } else {
            "the next frame's state (no commands recorded)"
        };
        write!(
            f,
            "{} episode(s) of {} frames at {} frames/s written to {} ({}; action: {action})",
            self.episodes.len(),
            frames.join(", "),
            self.fps,
            self.dataset.display(),
            self.features.join(", ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resampling_is_exact_on_the_grid_and_linear_between() {
        let t = [0.0, 0.001, 0.002, 0.003, 0.004];
        let rows: Vec<Vec<f64>> = t.iter().map(|x| vec![x * 1000.0]).collect();
        assert_eq!(on_grid(&t, &rows, 1000.0), rows);
        assert_eq!(
            on_grid(&t, &rows, 500.0),
            vec![vec![0.0], vec![2.0], vec![4.0]]
        );
        let g = on_grid(&[0.0, 0.3], &[vec![0.0], vec![3.0]], 10.0);
        assert_eq!(g.len(), 4);
        assert!((g[2][0] - 2.0).abs() < 1e-12);
    }
}
