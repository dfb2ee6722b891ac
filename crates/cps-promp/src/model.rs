//! ProMPs as data: a versioned JSON format (feature `serde`).
//!
//! ```json
//! {
//!   "format": "cps-promp-model", "version": 1,
//!   "dims": 2, "bases": 25, "duration": 2.0,
//!   "basis": { "centers": [0.0, ...], "width": 0.0417 },
//!   "names": ["x", "y"], "demonstrations": 20,
//!   "mean": [[...], [...]],
//!   "covariance": [[...], ...]
//! }
//! ```
//!
//! `mean` holds one row of `bases` weights per dimension; `covariance` is the weights'
//! covariance, `dims · bases` rows of `dims · bases` values, dimension-major like the
//! mean. `basis` is written for readers and checked on loading. A covariance must be
//! symmetric (to 1e-9 of its largest entry) and positive semi-definite.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::{ProMp, ProMpError};

/// The `format` tag of a ProMP file.
pub const PROMP_FORMAT: &str = "cps-promp-model";
/// The version this crate writes and reads.
pub const PROMP_VERSION: u32 = 1;

/// The basis as written in a ProMP file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProMpBasisRecord {
    /// Centres in phase.
    pub centers: Vec<f64>,
    /// The common width.
    pub width: f64,
}

/// A ProMP as stored in a file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProMpModel {
    /// Always [`PROMP_FORMAT`].
    pub format: String,
    /// Always [`PROMP_VERSION`] when written by this crate.
    pub version: u32,
    /// Dimensions.
    pub dims: usize,
    /// Basis functions per dimension.
    pub bases: usize,
    /// Duration in seconds.
    pub duration: f64,
    /// The basis (checked on loading).
    pub basis: ProMpBasisRecord,
    /// Optional names of the dimensions (the demonstrations' columns).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub names: Vec<String>,
    /// How many demonstrations it was fitted to (0: not fitted, e.g. built by hand).
    #[serde(default)]
    pub demonstrations: usize,
    /// One row of `bases` mean weights per dimension.
    pub mean: Vec<Vec<f64>>,
    /// The weight covariance, one row per weight.
    pub covariance: Vec<Vec<f64>>,
}

impl ProMpModel {
    /// The record of `promp` with dimension names and its number of demonstrations.
    pub fn new(promp: &ProMp, names: Vec<String>, demonstrations: usize) -> Self {
        let (centers, width) = promp.basis_layout();
        let cov = promp.weight_cov();
        ProMpModel {
            format: PROMP_FORMAT.into(),
            version: PROMP_VERSION,
            dims: promp.dims(),
            bases: promp.bases(),
            duration: promp.duration(),
            basis: ProMpBasisRecord { centers, width },
            names,
            demonstrations,
            mean: promp
                .weight_mean()
                .chunks(promp.bases())
                .map(<[f64]>::to_vec)
                .collect(),
            covariance: (0..cov.nrows())
                .map(|i| cov.row(i).iter().copied().collect())
                .collect(),
        }
    }

    /// Compact JSON (a covariance of thousands of rows reads badly pretty-printed anyway).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a ProMP serialises")
    }

    /// Parses a ProMP file's text (its shapes are checked by [`Self::to_promp`]).
    pub fn from_json(text: &str) -> Result<Self, ProMpError> {
        let bad = |m: String| ProMpError::Invalid(m);
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| bad(format!("not JSON: {e}")))?;
        match value.get("format").and_then(|v| v.as_str()) {
            Some(PROMP_FORMAT) => {}
            Some(other) => {
                return Err(bad(format!(
                    "format is \"{other}\", expected \"{PROMP_FORMAT}\""
                )));
            }
            None => return Err(bad(format!("no \"format\": not a {PROMP_FORMAT} file"))),
        }
        match value.get("version").and_then(|v| v.as_u64()) {
            Some(v) if v == u64::from(PROMP_VERSION) => {}
            Some(v) => {
                return Err(bad(format!(
                    "version {v} is not supported (this build reads version {PROMP_VERSION})"
                )));
            }
            None => return Err(bad("no \"version\"".into())),
        }
        serde_json::from_value(value).map_err(|e| bad(e.to_string()))
    }

    /// The ProMP, after checking shapes, the basis, symmetry and positive
    /// semi-definiteness.
    pub fn to_promp(&self) -> Result<ProMp, ProMpError> {
        let bad = |m: String| ProMpError::Invalid(m);
        let (d, b) = (self.dims, self.bases);
        if self.mean.len() != d {
            return Err(bad(format!(
                "\"mean\" has {} rows for {d} dimensions",
                self.mean.len()
            )));
        }
        if let Some((k, row)) = self.mean.iter().enumerate().find(|(_, r)| r.len() != b) {
            return Err(bad(format!(
                "\"mean\" row {} has {} values, \"bases\" is {b}",
                k + 1,
                row.len()
            )));
        }
        let n = d.saturating_mul(b);
        if self.covariance.len() != n {
            return Err(bad(format!(
                "\"covariance\" has {} rows; {d} dimensions × {b} bases need {n}",
                self.covariance.len()
            )));
        }
        if let Some((k, row)) = self
            .covariance
            .iter()
            .enumerate()
            .find(|(_, r)| r.len() != n)
        {
            return Err(bad(format!(
                "\"covariance\" row {} has {} values, needs {n}",
                k + 1,
                row.len()
            )));
        }
        if !self.names.is_empty() && self.names.len() != d {
            return Err(bad(format!(
                "{} names for {d} dimensions",
                self.names.len()
            )));
        }
        let promp = ProMp::new(
            d,
            b,
            self.duration,
            self.mean.iter().flatten().copied().collect(),
            self.covariance.iter().flatten().copied().collect(),
        )?;
        let (centers, width) = promp.basis_layout();
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * (1.0 + y.abs());
        if self.basis.centers.len() != centers.len()
            || !self
                .basis
                .centers
                .iter()
                .zip(&centers)
                .all(|(x, y)| close(*x, *y))
            || !close(self.basis.width, width)
        {
            return Err(bad(
                "the stored basis differs from the one \"bases\" defines (evenly spaced centres over [0, 1], width 1/(bases − 1))".into(),
            ));
        }
        check_covariance(promp.weight_cov())?;
        Ok(promp)
    }
}

/// Refuses a weight covariance that is not symmetric or not positive semi-definite.
fn check_covariance(c: &DMatrix<f64>) -> Result<(), ProMpError> {
    let scale = c.amax().max(1e-300);
    let asym = (c - c.transpose()).amax();
    if asym > 1e-9 * scale {
        return Err(ProMpError::Invalid(format!(
            "\"covariance\" is not symmetric (entries differ from their mirror by up to {asym:.3e})"
        )));
    }
    if let Some(i) = (0..c.nrows()).find(|&i| c[(i, i)] < 0.0) {
        return Err(ProMpError::Invalid(format!(
            "\"covariance\": the variance of weight {} is negative ({})",
            i + 1,
            c[(i, i)]
        )));
    }
    let n = c.nrows();
    let jitter = 1e-9 * scale;
    if (c + DMatrix::identity(n, n) * jitter).cholesky().is_none() {
        return Err(ProMpError::Singular(
            "\"covariance\" is not positive semi-definite (it has a clearly negative eigenvalue)"
                .into(),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_promp_round_trips_and_bad_files_are_refused() {
        let cov = DMatrix::from_fn(6, 6, |i, j| {
            0.5f64.powi((i as i32 - j as i32).abs()) * if i == j { 1.0 } else { 0.3 }
        });
        let p = ProMp::new(
            2,
            3,
            1.5,
            vec![0.1, 0.2, 0.3, -1.0, 0.0, 1.0],
            cov.as_slice().to_vec(),
        )
        .unwrap();
        let text = ProMpModel::new(&p, vec!["x".into(), "y".into()], 7).to_json();
        let back = ProMpModel::from_json(&text).unwrap();
        assert_eq!(back.demonstrations, 7);
        assert_eq!(back.to_promp().unwrap(), p);
        let err = |t: String| {
            ProMpModel::from_json(&t)
                .and_then(|m| m.to_promp())
                .unwrap_err()
                .to_string()
        };
        assert!(err(text.replace("\"version\":1", "\"version\":3")).contains("version 3"));
        assert!(err(text.replace("cps-promp-model", "x")).contains("format is \"x\""));
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let mut m = v.clone();
        m["covariance"][0][1] = serde_json::json!(0.9);
        assert!(err(m.to_string()).contains("not symmetric"));
        let mut m = v.clone();
        m["covariance"][0][1] = serde_json::json!(5.0);
        m["covariance"][1][0] = serde_json::json!(5.0);
        assert!(err(m.to_string()).contains("not positive semi-definite"));
        let mut m = v.clone();
        m["mean"][1] = serde_json::json!([1.0]);
        assert!(err(m.to_string()).contains("\"mean\" row 2 has 1 values"));
        let mut m = v;
        m["basis"]["width"] = serde_json::json!(0.1);
        assert!(err(m.to_string()).contains("stored basis differs"));
    }
}
