//! The studio's imitation mode: demonstration CSVs (as `cps-cli imitate` reads them)
//! imitated by a DMP, and with two or more, their ProMP's mean ± 2σ band — the same
//! library calls as the command line, on the uploaded texts.

use std::path::Path;

use cps_dmp::{Combine, Formulation, Lambda, Method};
use cps_movement::movement::{ImitationSpec, imitate_demos, parse_demo};
use serde::{Deserialize, Serialize};

use crate::api::ApiError;

/// The most demonstrations a request may carry.
pub const MAX_DEMOS: usize = 50;

/// `POST /api/imitate`'s body.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImitateRequest {
    /// The demonstration files: `{name, text}` (CSV: time, then one column per
    /// dimension).
    pub demos: Vec<DemoFile>,
    /// Basis functions per dimension (default 25).
    #[serde(default)]
    pub bases: Option<usize>,
    /// `"ridge"` (default), `"jerk"` (ridge penalising jerk) or `"lwr"`.
    #[serde(default)]
    pub method: Option<String>,
    /// λ of the regression (default: 1e-12 for ridge, chosen by cross-validation for
    /// jerk).
    #[serde(default)]
    pub lambda: Option<f64>,
    /// Via points to condition the ProMP on (two or more demonstrations).
    #[serde(default)]
    pub via: Vec<ProMpVia>,
}

/// A via point of the ProMP: where the movement should pass at `time`, within `std`
/// (default 0: exactly).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProMpVia {
    /// Seconds, within the ProMP's duration.
    pub time: f64,
    /// One value per dimension.
    pub position: Vec<f64>,
    /// Standard deviation of the position (default 0).
    #[serde(default)]
    pub std: f64,
}

/// An uploaded demonstration.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DemoFile {
    /// The file's name (for messages).
    pub name: String,
    /// Its CSV text.
    pub text: String,
}

/// A curve over time: `values[k]` at `t[k]`, one value per dimension.
#[derive(Debug, Clone, Serialize)]
pub struct Curve {
    /// Times, seconds.
    pub t: Vec<f64>,
    /// One row per time.
    pub values: Vec<Vec<f64>>,
}

/// The imitation's answer.
#[derive(Debug, Clone, Serialize)]
pub struct ImitateAnswer {
    /// The dimensions' names (the first file's header).
    pub names: Vec<String>,
    /// The demonstrations as read (at most 500 samples each, for drawing).
    pub demos: Vec<Curve>,
    /// The DMP's rollout.
    pub dmp: Curve,
    /// Per dimension: RMSE to what it was fitted to, and the λ used.
    pub rmse: Vec<f64>,
    /// Per dimension: the regression's λ.
    pub lambda: Vec<f64>,
    /// With two or more demonstrations: the ProMP's mean and standard deviation.
    pub promp: Option<Band>,
}

/// Mean and standard deviation per time and dimension.
pub type MeanStd = (Vec<Vec<f64>>, Vec<Vec<f64>>);

/// A ProMP's mean ± σ over time.
#[derive(Debug, Clone, Serialize)]
pub struct Band {
    /// Times, seconds.
    pub t: Vec<f64>,
    /// Mean per time and dimension.
    pub mean: Vec<Vec<f64>>,
    /// Standard deviation per time and dimension.
    pub std: Vec<Vec<f64>>,
    /// Conditioned on the request's via points: mean and standard deviation at the same
    /// times.
    pub conditioned: Option<MeanStd>,
}

fn thin(t: &[f64], rows: &[Vec<f64>]) -> Curve {
    let every = t.len().div_ceil(500).max(1);
    Curve {
        t: t.iter().step_by(every).copied().collect(),
        values: rows.iter().step_by(every).cloned().collect(),
    }
}

/// Imitates the request's demonstrations.
pub fn imitate(request: &ImitateRequest) -> Result<ImitateAnswer, ApiError> {
    if request.demos.is_empty() || request.demos.len() > MAX_DEMOS {
        return Err(ApiError(format!(
            "demos: give 1 to {MAX_DEMOS} demonstration files (got {})",
            request.demos.len()
        )));
    }
    let bases = request.bases.unwrap_or(25);
    if !(2..=200).contains(&bases) {
        return Err(ApiError(format!(
            "bases: must be between 2 and 200 (got {bases})"
        )));
    }
    let lambda = match request.lambda {
        None => None,
        Some(l) => Some(
            Lambda::fixed(l)
                .ok_or_else(|| ApiError(format!("lambda: must be finite and ≥ 0 (got {l})")))?,
        ),
    };
    let method: Method = request
        .method
        .as_deref()
        .unwrap_or("ridge")
        .parse()
        .map_err(|e| ApiError(format!("method: {e}")))?;
    let regression = method.regression(lambda);
    let mut names = Vec::new();
    let mut demos = Vec::new();
    for (i, d) in request.demos.iter().enumerate() {
        let label = if d.name.is_empty() {
            format!("demos[{i}]")
        } else {
            d.name.clone()
        };
        let (header, demo) = parse_demo(Path::new(&label), &d.text).map_err(|e| ApiError(e.0))?;
        if i > 0 && header.len() != names.len() {
            return Err(ApiError(format!(
                "{label}: {} dimensions, but the first demonstration has {}: every demonstration must have the same dimensions",
                header.len(),
                names.len()
            )));
        }
        if i == 0 {
            names = header;
        }
        demos.push(demo);
    }
    let spec = ImitationSpec {
        bases,
        regression,
        tau: None,
        dt: None,
        // The goal-robust default of `imitate` everywhere: the shape kept from any start.
        formulation: Formulation::GoalRobust,
        combine: Combine::Mean,
    };
    let fitted = imitate_demos(names.clone(), &demos, &spec).map_err(|e| ApiError(e.0))?;
    let traj = fitted.fit.dmp.rollout(&fitted.fit.weights);
    let rows: Vec<Vec<f64>> = (0..traj.n_samples())
        .map(|k| (0..traj.dims()).map(|d| traj.position(d)[k]).collect())
        .collect();
    let raw: Vec<(Vec<f64>, Vec<Vec<f64>>)> = demos
        .iter()
        .map(|d| {
            (
                d.times().to_vec(),
                (0..d.len()).map(|k| d.sample(k).to_vec()).collect(),
            )
        })
        .collect();
    // The drawn copies first: the ProMP fit takes the demonstrations.
    let drawn: Vec<Curve> = raw.iter().map(|(t, rows)| thin(t, rows)).collect();
    let promp = if demos.len() >= 2 {
        let labels: Vec<String> = request.demos.iter().map(|d| d.name.clone()).collect();
        let fit = cps_movement::promp::fit_demos(raw, names.clone(), &labels, bases, None)
            .map_err(|e| ApiError(e.0))?;
        let duration = fit.promp.promp.duration();
        let t: Vec<f64> = (0..=200).map(|k| duration * k as f64 / 200.0).collect();
        let (mean, std) = fit.promp.promp.stats(&t).into_iter().unzip();
        let conditioned = if request.via.is_empty() {
            None
        } else {
            let via = cps_movement::promp::ViaPoints {
                at: request.via.iter().map(|v| v.time).collect(),
                positions: request.via.iter().map(|v| v.position.clone()).collect(),
                stds: request.via.iter().map(|v| v.std).collect(),
                ..Default::default()
            };
            let c = cps_movement::promp::condition(fit.promp, &via)
                .map_err(|e| ApiError(format!("via: {}", e.0)))?;
            Some(c.posterior.promp.stats(&t).into_iter().unzip())
        };
        Some(Band {
            t,
            mean,
            std,
            conditioned,
        })
    } else if !request.via.is_empty() {
        return Err(ApiError(
            "via: conditioning needs a ProMP, which needs two or more demonstrations".into(),
        ));
    } else {
        None
    };
    Ok(ImitateAnswer {
        names,
        demos: drawn,
        dmp: thin(traj.times(), &rows),
        rmse: fitted.fit.report.rmse.clone(),
        lambda: fitted.fit.report.lambda.clone(),
        promp,
    })
}
