//! Experiment files in and out of the studio: a file's via-point task as the page's state
//! (read by the same parser as `cps-cli run`, so its refusals are the command line's,
//! with file, line and column), and the page's state as an experiment file that
//! `cps-cli run` runs.

use std::path::Path;

use cps_experiment::Experiment;
use cps_experiment::budget::Ceilings;
use serde::Serialize;

use crate::api::{ApiError, ViaPointRequest};

/// A file's task as the page edits it.
#[derive(Debug, Clone, Serialize)]
pub struct OpenedTask {
    /// The experiment's name.
    pub name: String,
    /// Start position.
    pub start: Vec<f64>,
    /// Goal position.
    pub goal: Vec<f64>,
    /// Duration, seconds.
    pub tau: f64,
    /// Sample period, seconds.
    pub dt: f64,
    /// Basis functions per dimension.
    pub basis_functions: usize,
    /// Via points: `{time, position}`.
    pub via: Vec<cps_learn::ViaPoint>,
    /// Cost weights.
    pub weights: cps_learn::CostWeights,
}

impl OpenedTask {
    fn of(exp: &Experiment) -> Self {
        let t = &exp.config.task;
        Self {
            name: exp.name.clone(),
            start: t.start.clone(),
            goal: t.goal.clone(),
            tau: t.dmp.tau,
            dt: t.dmp.dt,
            basis_functions: t.dmp.n_basis,
            via: t.via.clone(),
            weights: t.weights,
        }
    }
}

/// The task of experiment `text`, named `name` in messages. Relative files it names (a
/// scene) are not read: the studio reads only what the user gave it.
pub fn open_text(name: &str, text: &str) -> Result<OpenedTask, ApiError> {
    let clean: String = name
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, '.' | '_' | '-'))
        .take(100)
        .collect();
    let path = Path::new("(uploaded)").join(if clean.is_empty() {
        "experiment.toml"
    } else {
        &clean
    });
    let exp =
        Experiment::from_text(&path, text, &Ceilings::default()).map_err(|e| ApiError(e.0))?;
    Ok(OpenedTask::of(&exp))
}

/// The task of the experiment file at `path` (`cps-cli studio FILE`).
pub fn open_path(path: &Path) -> Result<OpenedTask, ApiError> {
    let exp = Experiment::from_path(path, &Ceilings::default()).map_err(|e| ApiError(e.0))?;
    Ok(OpenedTask::of(&exp))
}

/// `request` as a commented `kind = "viapoint"` experiment file named `name`, checked
/// first as the API checks it, written by the experiment file's own writer
/// ([`cps_experiment::experiment::viapoint_toml`]): it reads back to the same experiment.
pub fn save(request: &ViaPointRequest, name: &str) -> Result<String, ApiError> {
    let config = request.config()?;
    let name: String = name
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, '_' | '-'))
        .take(60)
        .collect();
    let name = if name.is_empty() {
        "studio".to_string()
    } else {
        name
    };
    let header = format!(
        "A via-point task saved by cps studio. Run it: cps-cli run {name}.toml\nUnits: metres, seconds."
    );
    cps_experiment::experiment::viapoint_toml(&name, &config, &header).map_err(|e| ApiError(e.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A saved file is read back by the experiment parser (as `cps-cli run` reads it)
    /// into exactly the request's task; the shipped thesis file opens with its task.
    #[test]
    fn saved_files_read_back_exactly_and_shipped_files_open() {
        let request: ViaPointRequest = serde_json::from_str(
            r#"{"start": [0.75, 0.02, 1.87], "goal": [0.55, -0.57, 1.45], "tau": 9.5,
                "solver": "cmaes", "weights": {"jerk": 1e-4, "via": 123456.789},
                "via": [{"time": 1.3, "position": [0.1, 0.2, 0.30000000000000004]}]}"#,
        )
        .unwrap();
        let text = save(&request, "my task!").unwrap();
        assert!(text.contains("name = \"mytask\""), "{text}");
        let back = open_text("my.toml", &text).unwrap();
        let want = request.config().unwrap().task;
        assert_eq!(back.start, want.start);
        assert_eq!(back.goal, want.goal);
        assert_eq!(back.tau, 9.5);
        assert_eq!(back.via, want.via);
        assert_eq!(back.weights, want.weights);
        let exp = Experiment::from_text(Path::new("x.toml"), &text, &Ceilings::default()).unwrap();
        assert_eq!(exp.config.solver, cps_learn::Solver::Cmaes);
        assert_eq!(exp.config.task, want);
        assert_eq!(exp.config, request.config().unwrap());

        let shipped = include_str!("../../../experiments/viapoint.toml");
        let opened = open_text("viapoint.toml", shipped).unwrap();
        assert_eq!(opened.via.len(), 4);
        assert_eq!(opened.goal, vec![0.55, -0.57, 1.45]);
        // The parser's refusal, with the file, line and column.
        let bad = shipped.replace("time = 4.0", "time = 40.0");
        let e = open_text("bad.toml", &bad).unwrap_err().0;
        assert!(e.contains("bad.toml:") && e.contains("via[1]"), "{e}");
    }
}
