//! Learned DMPs as data: a versioned JSON format (feature `serde`).
//!
//! ```json
//! {
//!   "format": "cps-dmp-model", "version": 2, "kind": "discrete",
//!   "formulation": "ijspeert",
//!   "config": { "alpha_z": 25.0, "beta_z": 6.25, "alpha_x": 8.33, "n_basis": 25,
//!               "tau": 10.0, "dt": 0.01 },
//!   "basis": { "centers": [...], "widths": [...] },
//!   "start": [...], "goal": [...], "weights": [[...], ...],
//!   "names": ["x", "y", "z"]
//! }
//! ```
//!
//! `weights` holds one row of `n_basis` values per dimension. `basis` is written for
//! readers and checked on loading against the basis the configuration defines, so a file
//! edited inconsistently is refused rather than silently reinterpreted.
//!
//! Version 1 differed only in the formulation's names (`"ijspeert2013"`, `"goal_robust"`,
//! [`Formulation::former_name`]); its files are read as written, and written back as
//! version 2.

use serde::{Deserialize, Serialize};

use crate::{DiscreteDmp, DmpConfig, DmpError, Formulation};

/// The `format` tag of a model file.
pub const MODEL_FORMAT: &str = "cps-dmp-model";
/// The version this crate writes (it reads this one and version 1).
pub const MODEL_VERSION: u32 = 2;

/// The basis as written in a model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BasisRecord {
    /// Centres in phase.
    pub centers: Vec<f64>,
    /// Widths.
    pub widths: Vec<f64>,
}

/// A discrete DMP with its weights, as stored in a model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DmpModel {
    /// Always [`MODEL_FORMAT`].
    pub format: String,
    /// Always [`MODEL_VERSION`] when written by this crate.
    pub version: u32,
    /// `"discrete"`.
    pub kind: String,
    /// The forcing-term formulation.
    pub formulation: Formulation,
    /// Gains, basis count, τ and dt.
    pub config: ConfigRecord,
    /// The basis (checked on loading).
    pub basis: BasisRecord,
    /// Start `y0` per dimension.
    pub start: Vec<f64>,
    /// Goal `g` per dimension.
    pub goal: Vec<f64>,
    /// One row of `n_basis` weights per dimension.
    pub weights: Vec<Vec<f64>>,
    /// Optional names of the dimensions (e.g. CSV column headers).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub names: Vec<String>,
}

/// [`DmpConfig`] without the formulation (stored at the top level).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigRecord {
    /// `alpha_z`.
    pub alpha_z: f64,
    /// `beta_z`.
    pub beta_z: f64,
    /// `alpha_x`.
    pub alpha_x: f64,
    /// Basis functions per dimension.
    pub n_basis: usize,
    /// Duration in seconds.
    pub tau: f64,
    /// Time step in seconds.
    pub dt: f64,
}

impl DmpModel {
    /// The record of `dmp` with `weights` (dimension-major) and optional dimension names.
    ///
    /// # Panics
    /// If `weights.len() != dmp.n_weights()`.
    pub fn new(dmp: &DiscreteDmp, weights: &[f64], names: Vec<String>) -> Self {
        assert_eq!(weights.len(), dmp.n_weights(), "weight vector length");
        let c = dmp.config();
        Self {
            format: MODEL_FORMAT.into(),
            version: MODEL_VERSION,
            kind: "discrete".into(),
            formulation: c.formulation,
            config: ConfigRecord {
                alpha_z: c.alpha_z,
                beta_z: c.beta_z,
                alpha_x: c.alpha_x,
                n_basis: c.n_basis,
                tau: c.tau,
                dt: c.dt,
            },
            basis: BasisRecord {
                centers: dmp.basis().centers().to_vec(),
                widths: dmp.basis().widths().to_vec(),
            },
            start: dmp.start().to_vec(),
            goal: dmp.goal().to_vec(),
            weights: weights.chunks(c.n_basis).map(<[f64]>::to_vec).collect(),
            names,
        }
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a model serialises")
    }

    /// Parses and checks a model file's text.
    pub fn from_json(text: &str) -> Result<Self, DmpError> {
        let bad = |reason: String| DmpError::InvalidModel { reason };
        let mut value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| bad(format!("not JSON: {e}")))?;
        match value.get("format").and_then(|v| v.as_str()) {
            Some(MODEL_FORMAT) => {}
            Some(other) => {
                return Err(bad(format!(
                    "format is \"{other}\", expected \"{MODEL_FORMAT}\""
                )));
            }
            None => return Err(bad(format!("no \"format\": not a {MODEL_FORMAT} file"))),
        }
        let version = match value.get("version").and_then(|v| v.as_u64()) {
            Some(v) if v == 1 || v == u64::from(MODEL_VERSION) => v,
            Some(v) => {
                return Err(bad(format!(
                    "version {v} is not supported (this build reads versions 1 and {MODEL_VERSION})"
                )));
            }
            None => return Err(bad("no \"version\"".into())),
        };
        if let Some(kind) = value.get("kind").and_then(|v| v.as_str())
            && kind != "discrete"
        {
            return Err(bad(format!("kind \"{kind}\" is not a discrete DMP")));
        }
        if let Some(f) = value.get("formulation").and_then(|v| v.as_str()) {
            // A version 1 file names its formulation by its former name.
            let known = Formulation::ALL.iter().find(|k| match version {
                1 => k.former_name() == f,
                _ => k.name() == f,
            });
            let formulation = match known {
                Some(k) => *k,
                None if version == 1 => {
                    return Err(bad(format!(
                        "unknown formulation \"{f}\" (a version 1 file knows \"ijspeert2013\", \"goal_robust\")"
                    )));
                }
                None => match f.parse::<Formulation>() {
                    Ok(k) => k,
                    Err(e) => return Err(bad(format!("formulation {e}"))),
                },
            };
            value["formulation"] = serde_json::Value::from(formulation.name());
        }
        // Read, a version 1 file is the version 2 file it stands for (an object: its
        // format was read above).
        value["version"] = serde_json::Value::from(MODEL_VERSION);
        serde_json::from_value(value).map_err(|e| bad(e.to_string()))
    }

    /// The DMP and its weights, after checking shapes and the basis.
    pub fn to_dmp(&self) -> Result<(DiscreteDmp, Vec<f64>), DmpError> {
        let bad = |reason: String| DmpError::InvalidModel { reason };
        let c = &self.config;
        let config = DmpConfig {
            alpha_z: c.alpha_z,
            beta_z: c.beta_z,
            alpha_x: c.alpha_x,
            n_basis: c.n_basis,
            tau: c.tau,
            dt: c.dt,
            formulation: self.formulation,
        };
        let dmp = DiscreteDmp::new(config, &self.start, &self.goal)?;
        if self.weights.len() != dmp.dims() {
            return Err(bad(format!(
                "{} weight rows for {} dimensions",
                self.weights.len(),
                dmp.dims()
            )));
        }
        if let Some((d, row)) = self
            .weights
            .iter()
            .enumerate()
            .find(|(_, r)| r.len() != c.n_basis)
        {
            return Err(bad(format!(
                "weight row {d} has {} values, n_basis is {}",
                row.len(),
                c.n_basis
            )));
        }
        let weights: Vec<f64> = self.weights.iter().flatten().copied().collect();
        if let Some(i) = weights.iter().position(|w| !w.is_finite()) {
            return Err(bad(format!("weight {i} is not finite")));
        }
        let close = |a: &[f64], b: &[f64]| {
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(x, y)| (x - y).abs() <= 1e-9 * (1.0 + y.abs()))
        };
        if !close(&self.basis.centers, dmp.basis().centers())
            || !close(&self.basis.widths, dmp.basis().widths())
        {
            return Err(bad(
                "the stored basis differs from the one alpha_x and n_basis define".into(),
            ));
        }
        if !self.names.is_empty() && self.names.len() != dmp.dims() {
            return Err(bad(format!(
                "{} names for {} dimensions",
                self.names.len(),
                dmp.dims()
            )));
        }
        Ok((dmp, weights))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_model_round_trips_and_bad_files_are_refused() {
        let cfg = DmpConfig {
            formulation: Formulation::GoalRobust,
            ..DmpConfig::new(5, 2.0, 0.01)
        };
        let dmp = DiscreteDmp::new(cfg, &[0.0, 1.0], &[1.0, 0.5]).unwrap();
        let w: Vec<f64> = (0..10).map(|i| i as f64 * 0.3 - 1.0).collect();
        let text = DmpModel::new(&dmp, &w, vec!["x".into(), "y".into()]).to_json();
        let (back, wb) = DmpModel::from_json(&text).unwrap().to_dmp().unwrap();
        assert_eq!(wb, w);
        assert_eq!(back.config(), dmp.config());
        assert_eq!(back.rollout(&wb).position(1), dmp.rollout(&w).position(1));
        let err = |t: String| {
            DmpModel::from_json(&t)
                .and_then(|m| m.to_dmp().map(|_| m))
                .unwrap_err()
                .to_string()
        };
        assert!(text.contains("\"formulation\": \"robust\""), "{text}");
        assert!(
            err(text.replace("\"version\": 2", "\"version\": 3"))
                .contains("version 3 is not supported")
        );
        assert!(
            err(text.replace("\"robust\"", "\"pastor\""))
                .contains("formulation \"pastor\" is not one of \"ijspeert\", \"robust\"")
        );
        // The former names: refused in a version 2 file with the present one, read in a
        // version 1 file (and only there).
        assert!(
            err(text.replace("\"robust\"", "\"goal_robust\""))
                .contains("formulation \"goal_robust\" is now called \"robust\"")
        );
        let v1 = text
            .replace("\"version\": 2", "\"version\": 1")
            .replace("\"robust\"", "\"goal_robust\"");
        let old = DmpModel::from_json(&v1).unwrap();
        assert_eq!(old.formulation, Formulation::GoalRobust);
        assert_eq!(old.version, MODEL_VERSION);
        assert_eq!(old.to_dmp().unwrap().0.config(), dmp.config());
        assert!(
            err(v1.replace("\"goal_robust\"", "\"robust\"")).contains("a version 1 file knows")
        );
        assert!(err(text.replace("cps-dmp-model", "other")).contains("format is \"other\""));
        assert!(err("[1, 2]".into()).contains("no \"format\""));
        assert!(err(text.replace("\"tau\": 2.0", "\"tau\": -2.0")).contains("tau"));
        let m: serde_json::Value = serde_json::from_str(&text).unwrap();
        let mut short = m.clone();
        short["weights"][1] = serde_json::json!([1.0]);
        assert!(err(short.to_string()).contains("weight row 1 has 1 values"));
        let mut moved = m;
        moved["basis"]["centers"][2] = serde_json::json!(0.123);
        assert!(err(moved.to_string()).contains("stored basis differs"));
    }
}
