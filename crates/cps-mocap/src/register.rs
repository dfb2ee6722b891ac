//! Registration: the rigid transform from the motion-capture frame to the robot's base
//! frame, fitted to three or more points measured in both (the least-squares fit of
//! [`crate::fit::fit`]), refused when the points are collinear or the fit leaves more
//! than a set residual.
//!
//! A calibration file (TOML):
//!
//! ```toml
//! mocap_units = "mm"      # units of the `mocap` coordinates: m, cm or mm; robot's are metres
//! max_residual = 0.005    # metres RMS; the registration is refused above it (default 5 mm)
//!
//! [[points]]
//! name = "table corner"   # optional, for messages
//! mocap = [812.4, 731.0, -402.9]
//! robot = [0.40, -0.30, 0.0]
//! ```

use std::path::Path;

use serde::Deserialize;

use crate::error::MocapError;
use crate::fit::{Rigid, Vec3, fit, norm, planarity, sub};
use crate::take::metres_per_unit;

/// A registration is refused when the points are closer to a line than this (second
/// principal spread over the first).
pub const MIN_PLANARITY: f64 = 0.01;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CalibrationFile {
    mocap_units: Option<String>,
    max_residual: Option<f64>,
    points: Vec<PointPair>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointPair {
    name: Option<String>,
    mocap: [f64; 3],
    robot: [f64; 3],
}

/// Points measured in both frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Where it was read from (for messages).
    pub file: String,
    /// Each point's name.
    pub names: Vec<String>,
    /// The points in the motion-capture frame, metres.
    pub mocap: Vec<Vec3>,
    /// The same points in the robot's base frame, metres.
    pub robot: Vec<Vec3>,
    /// The largest RMS residual accepted, metres.
    pub max_residual: f64,
}

/// A fitted registration.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Registration {
    /// Motion-capture frame → robot frame.
    #[serde(skip)]
    pub transform: Rigid,
    /// RMS distance between the mapped and the measured robot points, metres.
    pub rms_m: f64,
    /// The largest such distance, metres, and the point's name.
    pub max_m: f64,
    /// The point farthest off.
    pub worst: String,
    /// Points used.
    pub points: usize,
}

impl Calibration {
    /// Reads a calibration file.
    pub fn read(path: &Path) -> Result<Self, MocapError> {
        let file = path.display().to_string();
        let text = cps_files::read::read_text(path, cps_files::read::MAX_FILE_BYTES, "calibration")
            .map_err(|e| MocapError::Io {
                file: file.clone(),
                message: e.reason(),
            })?;
        Self::parse(&text, &file)
    }

    /// Parses a calibration file's text.
    pub fn parse(text: &str, file: &str) -> Result<Self, MocapError> {
        let bad = |m: String| MocapError::format(file, m);
        let f: CalibrationFile =
            toml::from_str(text).map_err(|e| bad(e.to_string().trim().replace('\n', " ")))?;
        let units = f.mocap_units.unwrap_or_else(|| "m".into());
        let k = metres_per_unit(&units)
            .ok_or_else(|| bad(format!("`mocap_units` is \"{units}\"; use m, cm or mm")))?;
        let max_residual = f.max_residual.unwrap_or(0.005);
        if !(max_residual.is_finite() && max_residual > 0.0) {
            return Err(bad(format!(
                "`max_residual` must be a positive number of metres (got {max_residual})"
            )));
        }
        if f.points.len() < 3 {
            return Err(bad(format!(
                "{} point(s): a registration needs three or more [[points]] measured in both frames",
                f.points.len()
            )));
        }
        let mut names = Vec::new();
        let (mut mocap, mut robot) = (Vec::new(), Vec::new());
        for (i, p) in f.points.iter().enumerate() {
            if p.mocap.iter().chain(&p.robot).any(|v| !v.is_finite()) {
                return Err(bad(format!(
                    "[[points]] {}: a coordinate is not a finite number",
                    i + 1
                )));
            }
            names.push(p.name.clone().unwrap_or_else(|| format!("point {}", i + 1)));
            mocap.push(p.mocap.map(|v| v * k));
            robot.push(p.robot);
        }
        Ok(Self {
            file: file.to_string(),
            names,
            mocap,
            robot,
            max_residual,
        })
    }

    /// Fits the registration; refused for collinear points or a residual above
    /// `max_residual`.
    pub fn register(&self) -> Result<Registration, MocapError> {
        for (which, pts) in [("motion-capture", &self.mocap), ("robot", &self.robot)] {
            let p = planarity(pts);
            if p < MIN_PLANARITY {
                return Err(MocapError::Input(format!(
                    "{}: the calibration points are collinear in the {which} frame (spread across their line {:.2} % of the spread along it): they leave the rotation about that line free; measure a point off the line",
                    self.file,
                    p * 100.0
                )));
            }
        }
        let (transform, rms) = fit(&self.mocap, &self.robot).ok_or_else(|| {
            MocapError::Input(format!(
                "{}: a registration needs three or more points",
                self.file
            ))
        })?;
        let (worst, max) = self
            .mocap
            .iter()
            .zip(&self.robot)
            .map(|(m, r)| norm(sub(transform.apply(*m), *r)))
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0));
        if rms > self.max_residual {
            return Err(MocapError::Refused(format!(
                "{}: the registration leaves {:.2} mm RMS between the mapped and the measured robot points (at most {:.2} mm is accepted; `{}` is {:.2} mm off): a point measured wrongly, or the frames do not match",
                self.file,
                rms * 1e3,
                self.max_residual * 1e3,
                self.names[worst],
                max * 1e3
            )));
        }
        Ok(Registration {
            transform,
            rms_m: rms,
            max_m: max,
            worst: self.names[worst].clone(),
            points: self.mocap.len(),
        })
    }
}
