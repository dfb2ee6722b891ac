//! One module per experiment kind. Each runs its pipeline (`cps-learn`) and declares its
//! outcome: summary fields, tables, figures, report rows and terminal lines. Nothing here
//! writes a file or draws: [`crate::files`] does that for every kind alike.
//!
//! To add a kind: a `Kind` variant and its sections (`experiment.rs`, `plan.rs`), a
//! module here with `pub(crate) fn run(ctx: &Ctx<'_>) -> Result<Outcome, ExperimentError>`,
//! and its line in `run::run`.

use std::ops::ControlFlow;
use std::time::Instant;

use cps_learn::{GenerationRecord, LearnError, ViaPointTask};

use crate::observer::{Event, Observer};
use crate::outcome::{Column, CostArm, Figure, Format, Plot, RunHeader, Series, Table, Versions};
use crate::plan::Experiment;
use crate::{ExperimentError, InputError};

pub(crate) mod energy;
pub(crate) mod imitation;
pub(crate) mod joint;
pub(crate) mod pose;
pub(crate) mod scaling;
pub(crate) mod viapoint;

/// What every kind's runner gets.
pub(crate) struct Ctx<'a> {
    /// The experiment.
    pub exp: &'a Experiment,
    /// The worker threads.
    pub pool: &'a rayon::ThreadPool,
    /// The caller's observer.
    pub observer: &'a dyn Observer,
    started: Instant,
}

impl<'a> Ctx<'a> {
    /// The context of a run of `exp` that started at `started`.
    pub fn new(
        exp: &'a Experiment,
        pool: &'a rayon::ThreadPool,
        observer: &'a dyn Observer,
        started: Instant,
    ) -> Self {
        Self {
            exp,
            pool,
            observer,
            started,
        }
    }

    /// Seconds since the run started.
    pub fn wall(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// The header of this run, `complete` or not.
    pub fn header(&self, complete: bool) -> RunHeader {
        RunHeader {
            experiment: self.exp.name.clone(),
            kind: self.exp.kind.name(),
            complete,
            seed: self.exp.config.seed,
            versions: Versions::now(),
            threads: self.pool.current_num_threads(),
            wall_time_s: self.wall(),
            failure: None,
        }
    }

    /// A search's generation report passed on to the observer.
    pub fn generation(&self, r: &cps_cmaes::GenerationReport<'_>) -> ControlFlow<()> {
        self.observer.event(Event::Generation {
            generation: r.generation,
            best_so_far: r.best_so_far,
            sigma: r.sigma,
        })
    }
}

/// A learning library error as a run reports it: a problem with the file's content
/// (input) or a failure of the `what` while running.
pub(crate) fn learn_error(e: LearnError, what: &str) -> ExperimentError {
    match e {
        LearnError::InvalidTask { .. } | LearnError::Dmp(_) | LearnError::Unreachable { .. } => {
            InputError(e.to_string()).into()
        }
        other => ExperimentError::Failed {
            context: format!("the {what} failed"),
            source: Box::new(other),
        },
    }
}

/// `cost_history.csv` of named searches: one row per generation of each.
pub(crate) fn history_table(searches: &[(&str, &[GenerationRecord])]) -> Table {
    let rows = searches
        .iter()
        .flat_map(|(name, h)| h.iter().map(move |r| (*name, r)));
    let (mut search, mut generation, mut best, mut median, mut so_far, mut sigma) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for (name, r) in rows {
        search.push(name.to_string());
        generation.push(r.generation);
        best.push(r.best);
        median.push(r.median);
        so_far.push(r.best_so_far);
        sigma.push(r.sigma);
    }
    Table::new("cost_history")
        .with(Column::texts("search", search))
        .with(Column::integers("generation", generation))
        .with(Column::numbers("best", best, Format::ShortestSci))
        .with(Column::numbers("median", median, Format::ShortestSci))
        .with(Column::numbers("best_so_far", so_far, Format::ShortestSci))
        .with(Column::numbers("sigma", sigma, Format::ShortestSci))
}

/// The report's row for a search: generations, evaluations, why it ended.
pub(crate) fn search_row(s: &cps_learn::SearchStats) -> (&'static str, String) {
    (
        "CMA-ES",
        format!(
            "{} generations, {} evaluations, {}",
            s.generations, s.evaluations, s.termination
        ),
    )
}

/// The CSV name of task-space dimension `d` of `dims`: `x`, `y`, `z` for three, `y0`, …
/// otherwise.
pub(crate) fn axis_name(dims: usize, d: usize) -> String {
    if dims == 3 {
        ["x", "y", "z"][d].to_string()
    } else {
        format!("y{d}")
    }
}

/// `x [m]`, `y [m]`, `z [m]` for three dimensions, `y0 [m]`, … otherwise.
pub(crate) fn axis_names(dims: usize) -> Vec<String> {
    (0..dims)
        .map(|d| {
            if dims == 3 {
                format!("{} [m]", ["x", "y", "z"][d])
            } else {
                format!("y{d} [m]")
            }
        })
        .collect()
}

/// The way points of a task as `(time, position)` marks.
pub(crate) fn way_points(task: &ViaPointTask) -> Vec<(f64, Vec<f64>)> {
    let mut points: Vec<(f64, Vec<f64>)> = vec![(0.0, task.start.clone())];
    points.extend(task.via.iter().map(|v| (v.time, v.position.clone())));
    points.push((task.dmp.tau, task.goal.clone()));
    points
}

/// The cost figure of one search, when it ran generations.
pub(crate) fn cost_figure(
    caption: &str,
    arms: Vec<CostArm>,
    optimum: Option<f64>,
) -> Option<Figure> {
    (arms.iter().any(|a| !a.band.is_empty()) || optimum.is_some()).then(|| Figure {
        name: "cost".into(),
        caption: caption.into(),
        plot: Plot::Cost { arms, optimum },
    })
}

/// The position figures: `coordinates` (one panel per coordinate, with `marks`) and, for
/// three dimensions, `path3d`.
pub(crate) fn position_figures(
    series: Vec<Series>,
    marks: Vec<(f64, Vec<f64>)>,
    coordinates_caption: &str,
    path_caption: &str,
) -> Vec<Figure> {
    let dims = series.first().map_or(0, |s| s.values.len());
    let mut figures = Vec::new();
    if dims == 3 {
        figures.push(Figure {
            name: "path3d".into(),
            caption: path_caption.into(),
            plot: Plot::Path3d {
                series: series.clone(),
                marks: marks.iter().map(|m| m.1.clone()).collect(),
            },
        });
    }
    figures.insert(
        0,
        Figure {
            name: "coordinates".into(),
            caption: coordinates_caption.into(),
            plot: Plot::Panels {
                names: axis_names(dims),
                series,
                marks,
            },
        },
    );
    figures
}

/// The largest of a list (0 for none).
pub(crate) fn worst(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, &b| a.max(b))
}

/// Solver name as summaries write it.
pub(crate) fn solver_name(s: cps_learn::Solver) -> &'static str {
    match s {
        cps_learn::Solver::Cmaes => "cmaes",
        cps_learn::Solver::Exact => "exact",
    }
}
