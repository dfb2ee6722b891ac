//! Calibration files: a robot's joint-level controller and drives as `cps-cli identify`
//! found them, read back by an experiment's `[robot] calibration = "robot.toml"` so that
//! the dynamics robot behaves like that robot.
//!
//! ```toml
//! # A robot's calibration, identified by cps
//! [calibration]
//! robot = "fr3"
//! controller = "joint_pd"
//! kp = [4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0]   # N m/rad
//! kv = [450.0, 450.0, 350.0, 350.0, 200.0, 200.0, 200.0]          # N m s/rad
//! lag_ms = 0
//! armature = [0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074]   # kg m²
//! viscous = [0.21, 0.21, 0.21, 0.21, 0.21, 0.21, 0.21]             # N m s/rad
//! coulomb = [1.137, 1.137, 1.137, 1.137, 0.763, 0.44, 0.248]       # N m
//! coulomb_speed = 0.01                                              # rad/s
//!
//! [fit]   # how it was found, for the reader
//! source = "..."
//! ```

use std::path::Path;

use cps_outcome::InputError;
use cps_outcome::results_dir::CALIBRATION_HEADER;
use serde::{Deserialize, Serialize};

/// A calibration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// The identified values.
    pub calibration: Calibrated,
    /// How they were found (read, not used).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitRecord>,
}

/// The identified controller and drives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibrated {
    /// The robot identified (its model's name: `fr3`, `panda`, …).
    pub robot: String,
    /// The controller's kind: `joint_pd`.
    pub controller: String,
    /// Position gains (N m/rad).
    pub kp: Vec<f64>,
    /// Velocity gains (N m s/rad).
    pub kv: Vec<f64>,
    /// How old the command the controller acts on is (ms, whole control periods).
    pub lag_ms: usize,
    /// Rotor inertia (kg m²).
    pub armature: Vec<f64>,
    /// Viscous friction (N m s/rad).
    pub viscous: Vec<f64>,
    /// Coulomb friction (N m).
    pub coulomb: Vec<f64>,
    /// The speed over which Coulomb friction fades to zero (rad/s).
    pub coulomb_speed: f64,
}

/// How a calibration was found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitRecord {
    /// Where the recording came from.
    pub source: String,
    /// Control periods fitted on.
    pub samples: usize,
    /// The controller model's torque residual per joint (N m, RMS).
    pub controller_rms_nm: Vec<f64>,
    /// The drive model's torque residual per joint (N m, RMS).
    pub drive_rms_nm: Vec<f64>,
    /// The calibrated robot's joints against a held-back recording's (mrad, RMS).
    pub held_back_rms_mrad: Vec<f64>,
}

/// Reads a calibration file. Errors name the file, and the line and column of what is
/// wrong in it.
pub fn read_calibration(path: &Path) -> Result<CalibrationFile, InputError> {
    let text = cps_outcome::source::read_text(path, 1 << 20, "calibration")?;
    toml::from_str(&text).map_err(|e| {
        let at = e.span().map_or(String::new(), |s| {
            let line = text[..s.start].matches('\n').count() + 1;
            let column = s.start - text[..s.start].rfind('\n').map_or(0, |i| i + 1) + 1;
            format!(":{line}:{column}")
        });
        InputError(format!(
            "{}{at}: not a calibration file: {}",
            path.display(),
            e.message()
        ))
    })
}

/// `path:line:col` of `key` in the `[calibration]` table of the calibration file at
/// `path` (just the path when the key is not found), for errors about its value.
pub fn place_of(path: &Path, key: &str) -> String {
    let text = cps_outcome::source::read_text(path, 1 << 20, "calibration").unwrap_or_default();
    let mut in_table = false;
    for (i, line) in text.lines().enumerate() {
        let t = line.trim_start();
        if t.starts_with('[') {
            in_table = t.starts_with("[calibration]");
            continue;
        }
        let name = t.split('=').next().unwrap_or("").trim();
        if in_table && t.contains('=') && name == key {
            return format!("{}:{}:{}", path.display(), i + 1, line.len() - t.len() + 1);
        }
    }
    path.display().to_string()
}

/// The file's text: its header line, `comment` lines, then the TOML.
pub fn calibration_text(file: &CalibrationFile, comment: &[String]) -> String {
    let mut text = format!("{CALIBRATION_HEADER}\n");
    for line in comment {
        text.push_str(&format!("# {line}\n"));
    }
    text.push('\n');
    text.push_str(&toml::to_string(file).expect("a calibration serialises"));
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_calibration_reads_back_as_written_and_bad_ones_are_placed() {
        let file = CalibrationFile {
            calibration: Calibrated {
                robot: "fr3".into(),
                controller: "joint_pd".into(),
                kp: vec![4500.0; 7],
                kv: vec![450.0; 7],
                lag_ms: 1,
                armature: vec![0.1; 7],
                viscous: vec![0.2; 7],
                coulomb: vec![1.0; 7],
                coulomb_speed: 0.01,
            },
            fit: None,
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("robot.toml");
        let text = calibration_text(&file, &["made by a test".into()]);
        assert!(text.starts_with(CALIBRATION_HEADER));
        std::fs::write(&path, &text).unwrap();
        assert_eq!(read_calibration(&path).unwrap(), file);
        std::fs::write(&path, text.replace("lag_ms = 1", "lag_ms = -1")).unwrap();
        let e = read_calibration(&path).unwrap_err().0;
        assert!(
            e.contains("robot.toml:") && e.contains("not a calibration file"),
            "{e}"
        );
        let line = text.lines().position(|l| l.starts_with("lag_ms")).unwrap() + 1;
        assert!(e.contains(&format!(":{line}:")), "{e}");
    }
}
