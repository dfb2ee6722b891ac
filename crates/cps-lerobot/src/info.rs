//! `meta/info.json`: the dataset's rate, robot and features.

use std::path::Path;

use serde_json::{Map, Value};

use crate::error::LeRobotError;

/// The folder of a dataset's description, relative to its root.
pub const INFO_PATH: &str = "meta/info.json";

/// One feature of a frame: its type, shape and (for vectors) the names of its entries.
#[derive(Debug, Clone, PartialEq)]
pub struct Feature {
    /// `float32`, `float64`, `int64`, `bool`, `string`, `image`, `video`…
    pub dtype: String,
    /// The shape of one frame's value (`[7]` for a 7-joint state).
    pub shape: Vec<usize>,
    /// The entries' names (`panda_joint1`…), when the dataset gives them.
    pub names: Option<Vec<String>>,
}

impl Feature {
    /// Numbers per frame.
    pub fn width(&self) -> usize {
        self.shape.iter().product()
    }

    /// Whether the feature is a vector of numbers (what a joint-space state or action is).
    pub fn is_numeric(&self) -> bool {
        matches!(
            self.dtype.as_str(),
            "float32" | "float64" | "float16" | "int64" | "int32" | "int16" | "int8"
        ) && self.shape.len() == 1
    }
}

/// The dataset's description.
#[derive(Debug, Clone, PartialEq)]
pub struct Info {
    /// Format version (`v3.0`).
    pub codebase_version: String,
    /// Frames per second.
    pub fps: f64,
    /// The robot that recorded it, as the dataset names it.
    pub robot_type: Option<String>,
    /// The features, in the file's order.
    pub features: Vec<(String, Feature)>,
    /// Episodes.
    pub total_episodes: usize,
    /// Frames in all episodes.
    pub total_frames: usize,
    /// Distinct tasks.
    pub total_tasks: usize,
    /// Where frames live: `data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet`.
    pub data_path: String,
}

impl Info {
    /// Reads `meta/info.json` under `root`.
    pub fn read(root: &Path) -> Result<Info, LeRobotError> {
        let path = root.join(INFO_PATH);
        if !root.is_dir() {
            return Err(LeRobotError::new(
                root,
                "no such folder (a LeRobot dataset is a folder with meta/info.json)",
            ));
        }
        if !path.exists() {
            return Err(LeRobotError::new(
                &path,
                "missing: this folder is not a LeRobot dataset (v3.0 keeps its description in meta/info.json)",
            ));
        }
        let text =
            cps_files::read::read_text(&path, cps_files::read::MAX_FILE_BYTES, "description")?;
        let json: Value = serde_json::from_str(&text)
            .map_err(|e| LeRobotError::new(&path, format!("not JSON: {e}")))?;
        Info::from_json(&json).map_err(|what| LeRobotError::new(&path, what))
    }

    /// The description from the JSON of `meta/info.json`; the error names the key.
    pub fn from_json(json: &Value) -> Result<Info, String> {
        let obj = json
            .as_object()
            .ok_or("the description must be a JSON object")?;
        let version = text(obj, "codebase_version")?;
        if !version.starts_with("v3.") {
            return Err(format!(
                "codebase_version is {version}, and cps reads LeRobot's format v3.0 \
                 (LeRobot converts older datasets with its convert_dataset_v21_to_v30 script)"
            ));
        }
        let fps = obj
            .get("fps")
            .and_then(Value::as_f64)
            .filter(|f| f.is_finite() && *f > 0.0)
            .ok_or("fps must be a number > 0")?;
        let features = obj
            .get("features")
            .and_then(Value::as_object)
            .ok_or("features must be an object of the frames' features")?
            .iter()
            .map(|(name, f)| Ok((name.clone(), feature(name, f)?)))
            .collect::<Result<Vec<_>, String>>()?;
        Ok(Info {
            codebase_version: version.to_string(),
            fps,
            robot_type: obj
                .get("robot_type")
                .and_then(Value::as_str)
                .map(str::to_string),
            features,
            total_episodes: count(obj, "total_episodes")?,
            total_frames: count(obj, "total_frames")?,
            total_tasks: count(obj, "total_tasks")?,
            data_path: text(obj, "data_path")?.to_string(),
        })
    }

    /// The feature called `name`.
    pub fn feature(&self, name: &str) -> Option<&Feature> {
        self.features
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, f)| f)
    }
}

fn text<'a>(obj: &'a Map<String, Value>, key: &str) -> Result<&'a str, String> {
    obj.get(key)
        .and_then(Value::as_str)
        .ok_or_else(|| format!("{key} must be a string"))
}

fn count(obj: &Map<String, Value>, key: &str) -> Result<usize, String> {
    obj.get(key)
        .and_then(Value::as_u64)
        .map(|v| v as usize)
        .ok_or_else(|| format!("{key} must be a whole number ≥ 0"))
}

fn feature(name: &str, f: &Value) -> Result<Feature, String> {
    let dtype = f
        .get("dtype")
        .and_then(Value::as_str)
        .ok_or_else(|| format!("features.{name}.dtype must be a string"))?;
    let shape = f
        .get("shape")
        .and_then(Value::as_array)
        .and_then(|a| {
            a.iter()
                .map(|v| v.as_u64().map(|v| v as usize))
                .collect::<Option<Vec<_>>>()
        })
        .ok_or_else(|| format!("features.{name}.shape must be a list of whole numbers"))?;
    // A list of names, or (datasets of format 2.x) an object with one list.
    let names = match f.get("names") {
        None | Some(Value::Null) => None,
        Some(Value::Array(a)) => Some(a),
        Some(Value::Object(o)) if o.len() == 1 => o.values().next().and_then(Value::as_array),
        Some(_) => None,
    }
    .and_then(|a| {
        a.iter()
            .map(|v| v.as_str().map(str::to_string))
            .collect::<Option<Vec<_>>>()
    });
    Ok(Feature {
        dtype: dtype.to_string(),
        shape,
        names,
    })
}

/// The widest zero padding a path template may ask for (LeRobot's use 3).
const MAX_WIDTH: usize = 20;

/// `template` with `{key}` and `{key:03d}` filled from `values`.
pub fn fill(template: &str, values: &[(&str, usize)]) -> Result<String, String> {
    let mut out = String::new();
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let close = rest[open..]
            .find('}')
            .ok_or_else(|| format!("`{template}` has a `{{` without its `}}`"))?
            + open;
        let field = &rest[open + 1..close];
        let (key, spec) = field.split_once(':').unwrap_or((field, ""));
        let value = values
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, v)| *v)
            .ok_or_else(|| format!("`{template}` asks for `{key}`, which cps does not know"))?;
        let width = spec
            .strip_prefix('0')
            .and_then(|w| w.strip_suffix('d'))
            .and_then(|w| w.parse::<usize>().ok())
            .unwrap_or(0);
        if width > MAX_WIDTH {
            return Err(format!(
                "`{template}` pads `{key}` to {width} digits; a path's numbers have at most {MAX_WIDTH}"
            ));
        }
        out.push_str(&format!("{value:0width$}"));
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn templates_fill_like_python_format() {
        let p = fill(
            "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
            &[("chunk_index", 2), ("file_index", 17)],
        )
        .unwrap();
        assert_eq!(p, "data/chunk-002/file-017.parquet");
        assert_eq!(
            fill("e{episode_index}", &[("episode_index", 1234)]).unwrap(),
            "e1234"
        );
        assert!(fill("x{nope}", &[]).unwrap_err().contains("`nope`"));
        assert!(fill("x{open", &[]).is_err());
    }

    #[test]
    fn an_older_format_is_refused_with_the_way_on() {
        let json = serde_json::json!({"codebase_version": "v2.1", "fps": 30});
        let e = Info::from_json(&json).unwrap_err();
        assert!(
            e.contains("v2.1") && e.contains("convert_dataset_v21_to_v30"),
            "{e}"
        );
    }

    #[test]
    fn names_as_a_list_or_as_an_object_of_one_list() {
        let a = feature(
            "s",
            &serde_json::json!({"dtype": "float32", "shape": [2], "names": ["a", "b"]}),
        )
        .unwrap();
        let b = feature(
            "s",
            &serde_json::json!({"dtype": "float32", "shape": [2], "names": {"motors": ["a", "b"]}}),
        )
        .unwrap();
        assert_eq!(a.names, b.names);
        assert_eq!(a.width(), 2);
        assert!(a.is_numeric());
        let v = feature(
            "v",
            &serde_json::json!({"dtype": "video", "shape": [480, 640, 3], "names": null}),
        )
        .unwrap();
        assert!(!v.is_numeric() && v.names.is_none());
    }
}
