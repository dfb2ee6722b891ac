//! A dataset read: its description, episodes and tasks, and one episode's frames of a
//! feature.

use std::path::{Path, PathBuf};

use crate::error::LeRobotError;
use crate::info::{Feature, Info, fill};
use crate::table::{self, Cell};

/// Where the episodes' index lives, relative to the root.
pub const EPISODES_DIR: &str = "meta/episodes";
/// The tasks' table, relative to the root.
pub const TASKS_PATH: &str = "meta/tasks.parquet";

/// One episode as the index lists it.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeMeta {
    /// Its index (from 0).
    pub index: usize,
    /// Frames.
    pub length: usize,
    /// Its tasks' words.
    pub tasks: Vec<String>,
    /// The data file holding its frames: chunk and file indices.
    pub data_file: (usize, usize),
    /// Its frames' global indices, `from..to`.
    pub frames: std::ops::Range<usize>,
}

/// A LeRobot dataset (format v3.0) in a local folder.
#[derive(Debug, Clone)]
pub struct Dataset {
    root: PathBuf,
    info: Info,
    episodes: Vec<EpisodeMeta>,
    tasks: Vec<String>,
}

/// One episode's frames of one feature.
#[derive(Debug, Clone, PartialEq)]
pub struct Frames {
    /// Each frame's index in its episode (from 0).
    pub frame: Vec<usize>,
    /// Each frame's `timestamp`, seconds from the episode's start, as stored (LeRobot
    /// stores float32: `frame / fps` to within 1e-7 relative).
    pub t: Vec<f64>,
    /// Each frame's values (`t.len()` rows of `names.len()`).
    pub values: Vec<Vec<f64>>,
    /// The entries' names (the feature's, or `<feature>[i]` where it names none).
    pub names: Vec<String>,
}

impl Dataset {
    /// Opens the dataset in the folder `root`: its description, episode index and tasks
    /// (frames are read when asked for).
    pub fn open(root: &Path) -> Result<Dataset, LeRobotError> {
        let info = Info::read(root)?;
        let dir = root.join(EPISODES_DIR);
        let mut files = parquet_files(&dir)?;
        files.sort();
        if files.is_empty() {
            return Err(LeRobotError::new(
                &dir,
                "holds no episode index (chunk-*/file-*.parquet)",
            ));
        }
        let mut episodes = Vec::new();
        for file in &files {
            let rows = table::read(
                file,
                &[
                    "episode_index",
                    "tasks",
                    "length",
                    "data/chunk_index",
                    "data/file_index",
                    "dataset_from_index",
                    "dataset_to_index",
                ],
                None,
            )?;
            for (r, row) in rows.iter().enumerate() {
                episodes.push(episode_meta(row).ok_or_else(|| {
                    LeRobotError::new(
                        file,
                        format!("row {r}: an episode's index, length, data file and frame range must be whole numbers ≥ 0"),
                    )
                })?);
            }
        }
        episodes.sort_by_key(|e| e.index);
        for (k, e) in episodes.iter().enumerate() {
            if e.index != k {
                return Err(LeRobotError::new(
                    &dir,
                    format!(
                        "episode {k} is missing from the index (found {} next)",
                        e.index
                    ),
                ));
            }
        }
        if episodes.len() != info.total_episodes {
            return Err(LeRobotError::new(
                &root.join(crate::info::INFO_PATH),
                format!(
                    "total_episodes is {}, but meta/episodes lists {}",
                    info.total_episodes,
                    episodes.len()
                ),
            ));
        }
        let tasks_path = root.join(TASKS_PATH);
        let mut tasks: Vec<(usize, String)> = Vec::new();
        if tasks_path.is_file() {
            for (r, row) in table::read(&tasks_path, &["task_index", "task"], None)?
                .into_iter()
                .enumerate()
            {
                match (&row[0], &row[1]) {
                    (Cell::Int(i), Cell::Text(t)) if *i >= 0 => {
                        tasks.push((*i as usize, t.clone()))
                    }
                    _ => {
                        return Err(LeRobotError::new(
                            &tasks_path,
                            format!("row {r}: a task is a whole number and its words"),
                        ));
                    }
                }
            }
        }
        tasks.sort();
        Ok(Dataset {
            root: root.to_path_buf(),
            info,
            episodes,
            tasks: tasks.into_iter().map(|(_, t)| t).collect(),
        })
    }

    /// The dataset's folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Its description.
    pub fn info(&self) -> &Info {
        &self.info
    }

    /// Its episodes, by index.
    pub fn episodes(&self) -> &[EpisodeMeta] {
        &self.episodes
    }

    /// Its tasks' words, by task index.
    pub fn tasks(&self) -> &[String] {
        &self.tasks
    }

    /// The feature `name`, if it is a vector of numbers; else a sentence naming the
    /// features that are.
    pub fn numeric_feature(&self, name: &str) -> Result<&Feature, LeRobotError> {
        let info_path = self.root.join(crate::info::INFO_PATH);
        let numeric: Vec<&str> = self
            .info
            .features
            .iter()
            .filter(|(n, f)| f.is_numeric() && !is_bookkeeping(n))
            .map(|(n, _)| n.as_str())
            .collect();
        match self.info.feature(name) {
            None => Err(LeRobotError::new(
                &info_path,
                format!(
                    "has no feature `{name}` (its vectors of numbers: {})",
                    numeric.join(", ")
                ),
            )),
            Some(f) if !f.is_numeric() => Err(LeRobotError::new(
                &info_path,
                format!(
                    "feature `{name}` is {} of shape {:?}, not a vector of numbers (its vectors: {})",
                    f.dtype,
                    f.shape,
                    numeric.join(", ")
                ),
            )),
            Some(f) => Ok(f),
        }
    }

    /// Episode `episode`'s frames of the feature `feature` (a vector of numbers), with
    /// their timestamps, in frame order.
    pub fn frames(&self, episode: usize, feature: &str) -> Result<Frames, LeRobotError> {
        let f = self.numeric_feature(feature)?;
        let meta = self.episodes.get(episode).ok_or_else(|| {
            LeRobotError::new(
                &self.root,
                format!(
                    "has no episode {episode}: its episodes are 0 to {}",
                    self.episodes.len().saturating_sub(1)
                ),
            )
        })?;
        let rel = fill(
            &self.info.data_path,
            &[
                ("chunk_index", meta.data_file.0),
                ("file_index", meta.data_file.1),
                ("episode_index", episode),
            ],
        )
        .map_err(|e| {
            LeRobotError::new(
                &self.root.join(crate::info::INFO_PATH),
                format!("data_path: {e}"),
            )
        })?;
        let path = inside(&self.root, &rel).map_err(|why| {
            LeRobotError::new(
                &self.root.join(crate::info::INFO_PATH),
                format!("data_path gives `{rel}` for episode {episode}: {why}"),
            )
        })?;
        let e = episode as i64;
        let rows = table::read(
            &path,
            &["episode_index", "frame_index", "timestamp", feature],
            Some(("episode_index", e..=e)),
        )?;
        let width = f.width();
        let mut framed = Vec::with_capacity(rows.len());
        for row in &rows {
            let fault = |what: &str| {
                LeRobotError::new(
                    &path,
                    match row[1].index() {
                        Some(k) => format!("episode {episode}, frame {k}: {what}"),
                        None => format!("episode {episode}, a frame without a frame_index: {what}"),
                    },
                )
            };
            let k = row[1]
                .index()
                .ok_or_else(|| fault("frame_index is no whole number"))?;
            let t = row[2]
                .number()
                .ok_or_else(|| fault("timestamp is no number"))?;
            let v = match &row[3] {
                Cell::List(items) => items
                    .iter()
                    .map(Cell::number)
                    .collect::<Option<Vec<f64>>>()
                    .ok_or_else(|| {
                        fault(&format!("`{feature}` holds a value that is no number"))
                    })?,
                c => vec![
                    c.number()
                        .ok_or_else(|| fault(&format!("`{feature}` is no number")))?,
                ],
            };
            if v.len() != width || v.iter().any(|x| !x.is_finite()) {
                return Err(fault(&format!(
                    "`{feature}` has {} values{}, where info.json says {width}",
                    v.len(),
                    if v.iter().any(|x| !x.is_finite()) {
                        " (not all finite)"
                    } else {
                        ""
                    }
                )));
            }
            framed.push((k, t, v));
        }
        if framed.len() != meta.length {
            return Err(LeRobotError::new(
                &path,
                format!(
                    "holds {} frames of episode {episode}, whose index says {}",
                    framed.len(),
                    meta.length
                ),
            ));
        }
        framed.sort_by_key(|(k, _, _)| *k);
        for w in framed.windows(2) {
            if w[1].1 <= w[0].1 {
                return Err(LeRobotError::new(
                    &path,
                    format!(
                        "episode {episode}: timestamps do not increase at frame {} ({} s after {} s)",
                        w[1].0, w[1].1, w[0].1
                    ),
                ));
            }
        }
        let names = f
            .names
            .clone()
            .filter(|n| n.len() == width)
            .unwrap_or_else(|| (0..width).map(|i| format!("{feature}[{i}]")).collect());
        Ok(Frames {
            frame: framed.iter().map(|(k, _, _)| *k).collect(),
            t: framed.iter().map(|(_, t, _)| *t).collect(),
            values: framed.into_iter().map(|(_, _, v)| v).collect(),
            names,
        })
    }
}

/// The columns every frame carries for LeRobot's own bookkeeping.
pub fn is_bookkeeping(name: &str) -> bool {
    matches!(
        name,
        "timestamp" | "frame_index" | "episode_index" | "index" | "task_index"
    )
}

fn episode_meta(row: &[Cell]) -> Option<EpisodeMeta> {
    let tasks = match &row[1] {
        Cell::List(items) => items
            .iter()
            .map(|c| match c {
                Cell::Text(t) => Some(t.clone()),
                _ => None,
            })
            .collect::<Option<Vec<_>>>()?,
        Cell::Null => Vec::new(),
        _ => return None,
    };
    let from = row[5].index()?;
    let to = row[6].index()?;
    Some(EpisodeMeta {
        index: row[0].index()?,
        length: row[2].index()?,
        tasks,
        data_file: (row[3].index()?, row[4].index()?),
        frames: from..to.max(from),
    })
}

fn parquet_files(dir: &Path) -> Result<Vec<PathBuf>, LeRobotError> {
    let mut out = Vec::new();
    let chunks = std::fs::read_dir(dir).map_err(|e| {
        LeRobotError::unread(dir, &e, "missing: a v3.0 dataset lists its episodes there")
    })?;
    for chunk in chunks.flatten() {
        let path = chunk.path();
        if path.is_dir() {
            for file in std::fs::read_dir(&path).into_iter().flatten().flatten() {
                let p = file.path();
                if p.extension().is_some_and(|e| e == "parquet") {
                    out.push(p);
                }
            }
        }
    }
    Ok(out)
}

/// `rel` joined to the dataset's folder, when it stays inside it: a relative path of
/// plain names (no `..`, no root), as LeRobot's templates make. A dataset's description
/// never sends cps to read a file outside the dataset.
pub fn inside(root: &Path, rel: &str) -> Result<PathBuf, &'static str> {
    use std::path::Component;
    let p = Path::new(rel);
    if rel.is_empty() || !p.components().all(|c| matches!(c, Component::Normal(_))) {
        return Err("a dataset's files lie inside its folder (a relative path without `..`)");
    }
    Ok(root.join(p))
}
