//! One module per experiment kind. Each runs its pipeline (`cps-learn`) and declares its
//! outcome: summary fields, tables, figures, report rows and terminal lines. Nothing here
//! writes a file or draws: [`cps_report::write`] does that for every kind alike.
//!
//! To add a kind: a `Kind` variant and its sections (`experiment.rs`, `plan.rs`), a
//! module here with `pub(crate) fn run(ctx: &Ctx<'_>) -> Result<Outcome, ExperimentError>`,
//! and its line in `run::run`.

use std::ops::ControlFlow;
use std::time::Instant;

use cps_learn::{GenerationRecord, LearnError, ViaPointTask};

use crate::observer::{Event, Observer};
use crate::plan::Experiment;
use crate::{ExperimentError, InputError};
use cps_outcome::outcome::{
    Band, Column, CostArm, Figure, Format, Mark, MarkKind, Panels, Plot, ReportTable, RunHeader,
    Series, Table, Versions,
};

pub(crate) mod clearance;
pub(crate) mod contact;
pub(crate) mod energy;
pub(crate) mod executed;
pub(crate) mod imitation;
pub(crate) mod joint;
pub(crate) mod movement_files;
pub(crate) mod pose;
pub(crate) mod promp;
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
    /// The run's stop: robots brake on it.
    pub stop: &'a cps_robot::StopToken,
    started: Instant,
}

impl<'a> Ctx<'a> {
    /// The context of a run of `exp` that started at `started`.
    pub fn new(
        exp: &'a Experiment,
        pool: &'a rayon::ThreadPool,
        observer: &'a dyn Observer,
        stop: &'a cps_robot::StopToken,
        started: Instant,
    ) -> Self {
        Self {
            exp,
            pool,
            observer,
            stop,
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
            kind: self.exp.kind().name(),
            complete,
            seed: self.exp.config.seed,
            versions: Versions {
                cps: env!("CARGO_PKG_VERSION"),
                commit: env!("CPS_BUILD_COMMIT"),
            },
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

/// The cost figure's arm of one or more searches' histories: the mean best-so-far cost per
/// generation with its 95 % band, and the range of every positive finite cost.
pub(crate) fn cost_arm(label: impl Into<String>, histories: &[&[GenerationRecord]]) -> CostArm {
    let positive = histories
        .iter()
        .flat_map(|h| h.iter().map(|r| r.best_so_far))
        .filter(|v| v.is_finite() && *v > 0.0);
    CostArm {
        label: label.into(),
        repetitions: histories.len(),
        band: cps_learn::history_band(histories),
        range: positive.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v))),
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

/// The report's tables every kind shares, from the file and the summary: the task (start,
/// via points with their times, goal), the settings, and each cost breakdown of the
/// summary (`*cost_terms`) with every term's share.
pub(crate) fn shared_report_tables(
    exp: &Experiment,
    summary: &serde_json::Map<String, serde_json::Value>,
) -> Vec<ReportTable> {
    let c = &exp.config;
    let task = &c.task;
    let point = |p: &[f64]| {
        let v: Vec<String> = p.iter().map(|x| format!("{x:.4}")).collect();
        format!("({}) m", v.join(", "))
    };
    let mut rows = vec![vec![
        "start".to_string(),
        "0 s".to_string(),
        point(&task.start),
    ]];
    for (i, v) in task.via.iter().enumerate() {
        rows.push(vec![
            format!("p{}", i + 1),
            format!("{} s", v.time),
            point(&v.position),
        ]);
    }
    rows.push(vec![
        "goal".into(),
        format!("{} s (τ)", task.dmp.tau),
        point(&task.goal),
    ]);
    let mut tables = vec![ReportTable {
        title: "Task".into(),
        header: ["point", "time", "position"].map(String::from).to_vec(),
        rows,
    }];
    let w = &task.weights;
    let mut settings = vec![
        (
            "DMPs",
            format!(
                "{} basis functions per dimension, τ = {} s, dt = {} s, α_z = {}, β_z = {}, {} formulation",
                task.dmp.n_basis,
                task.dmp.tau,
                task.dmp.dt,
                task.dmp.alpha_z,
                task.dmp.beta_z,
                task.dmp.formulation
            ),
        ),
        (
            "cost weights",
            format!(
                "goal {}, via {}, final velocity {}, acceleration {}, jerk {}",
                w.goal, w.via, w.final_velocity, w.acceleration, w.jerk
            ),
        ),
        (
            "optimizer",
            match c.solver {
                cps_learn::Solver::Exact => "exact least squares".to_string(),
                cps_learn::Solver::LeastSquares => format!(
                    "Levenberg–Marquardt on the cost's residuals{}, up to {} iterations",
                    if c.warm_start {
                        ", from the exact optimum of the quadratic terms"
                    } else {
                        ", from zero weights"
                    },
                    c.generations
                ),
                cps_learn::Solver::Cmaes => format!(
                    "CMA-ES, {} search space, σ0 = {}, population {}, up to {} generations, tol_fun {}, {} repetition(s){}",
                    c.parametrisation.name(),
                    c.sigma0,
                    c.population
                        .map_or("default".to_string(), |p| p.to_string()),
                    c.generations,
                    c.tol_fun.map_or("off".to_string(), |t| t.to_string()),
                    c.repetitions,
                    if c.warm_start { ", warm start" } else { "" }
                ),
            },
        ),
        ("file", exp.source.display().to_string()),
    ];
    if let Some(r) = &exp.robot {
        settings.push((
            "robot",
            format!(
                "{} joints, scene {}, {}",
                r.setup.chain.dof(),
                r.scene,
                r.describe()
            ),
        ));
    }
    tables.push(ReportTable::pairs("Settings", settings));
    for (key, value) in summary {
        let Some(terms) = value.as_object().filter(|_| key.ends_with("cost_terms")) else {
            continue;
        };
        let total: f64 = terms.values().filter_map(serde_json::Value::as_f64).sum();
        let rows = terms
            .iter()
            .filter_map(|(k, v)| v.as_f64().map(|v| (k, v)))
            .map(|(k, v)| {
                vec![
                    k.replace('_', " "),
                    format!("{v:.6e}"),
                    if total > 0.0 {
                        let share = 100.0 * v / total;
                        if share == 0.0 || share >= 0.1 {
                            format!("{share:.1} %")
                        } else {
                            format!("{share:.1e} %")
                        }
                    } else {
                        "–".into()
                    },
                ]
            })
            .chain(std::iter::once(vec![
                "total".into(),
                format!("{total:.6e}"),
                "100 %".into(),
            ]))
            .collect();
        tables.push(ReportTable {
            title: format!("Cost breakdown ({})", key.replace('_', " ")),
            header: ["term", "value", "share"].map(String::from).to_vec(),
            rows,
        });
    }
    tables
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

/// Marks at the way points' times: `start` at 0, `p1…` at the via points' times
/// (scaled by `time_scale`), `goal` at τ; `values` gives each point's values in order.
pub(crate) fn marks(
    task: &ViaPointTask,
    time_scale: f64,
    values: impl IntoIterator<Item = Vec<f64>>,
) -> Vec<Mark> {
    let n = task.via.len();
    let times = std::iter::once(0.0)
        .chain(task.via.iter().map(|v| v.time * time_scale))
        .chain(std::iter::once(task.dmp.tau * time_scale));
    times
        .zip(values)
        .enumerate()
        .map(|(i, (time, values))| {
            let (kind, label) = match i {
                0 => (MarkKind::Start, "start".to_string()),
                i if i > n => (MarkKind::Goal, "goal".to_string()),
                i => (MarkKind::Via, format!("p{i}")),
            };
            Mark {
                time,
                values,
                kind,
                label,
            }
        })
        .collect()
}

/// The way points of a task as marks (start, `p1…`, goal).
pub(crate) fn way_points(task: &ViaPointTask) -> Vec<Mark> {
    let positions = std::iter::once(task.start.clone())
        .chain(task.via.iter().map(|v| v.position.clone()))
        .chain(std::iter::once(task.goal.clone()));
    marks(task, 1.0, positions)
}

/// The search figure, as `cma.plot()` draws it: per generation the best and the median
/// cost of the population (its spread) and the best so far (log scale), and the step size
/// σ, for each named search (the first repetition of each).
pub(crate) fn search_figure(searches: &[(&str, &[GenerationRecord])]) -> Option<Figure> {
    let searches: Vec<_> = searches.iter().filter(|(_, h)| !h.is_empty()).collect();
    if searches.is_empty() {
        return None;
    }
    let mut series = Vec::new();
    for (name, h) in &searches {
        let g: Vec<f64> = h.iter().map(|r| r.generation as f64).collect();
        let col = |f: fn(&GenerationRecord) -> f64, panel: usize| {
            let v: Vec<f64> = h.iter().map(f).collect();
            let nan = vec![f64::NAN; v.len()];
            if panel == 0 {
                vec![v, nan]
            } else {
                vec![nan, v]
            }
        };
        let prefix = if searches.len() > 1 {
            format!("{name}: ")
        } else {
            String::new()
        };
        series.push(Series::new(
            format!("{prefix}best so far"),
            g.clone(),
            col(|r| r.best_so_far, 0),
        ));
        series.push(Series::new(
            format!("{prefix}best of the generation"),
            g.clone(),
            col(|r| r.best, 0),
        ));
        series.push(Series::new(
            format!("{prefix}median of the generation"),
            g.clone(),
            col(|r| r.median, 0),
        ));
        series.push(Series::new(format!("{prefix}σ"), g, col(|r| r.sigma, 1)));
    }
    let mut panels = Panels::new(vec!["cost".into(), "step size σ".into()], series);
    panels.x_name = "generation".into();
    panels.log_y = true;
    Some(Figure {
        name: "search".into(),
        caption: "The search per generation (log scales): the best so far, the best and the median of the population (its spread), and the step size σ.".into(),
        plot: Plot::Panels(panels),
    })
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
    marks: Vec<Mark>,
    coordinates_caption: &str,
    path_caption: &str,
) -> Vec<Figure> {
    position_figures_with(series, Vec::new(), marks, coordinates_caption, path_caption)
}

/// [`position_figures`] with shaded bands in the coordinates figure.
pub(crate) fn position_figures_with(
    series: Vec<Series>,
    bands: Vec<Band>,
    marks: Vec<Mark>,
    coordinates_caption: &str,
    path_caption: &str,
) -> Vec<Figure> {
    let dims = series.first().map_or(0, |s| s.values.len());
    let path = (dims == 3).then(|| Figure {
        name: "path3d".into(),
        caption: path_caption.into(),
        plot: Plot::Path3d {
            series: series.clone(),
            marks: marks.clone(),
        },
    });
    let coordinates = Figure {
        name: "coordinates".into(),
        caption: coordinates_caption.into(),
        plot: Plot::Panels(
            Panels::new(axis_names(dims), series)
                .bands(bands)
                .marks(marks),
        ),
    };
    std::iter::once(coordinates).chain(path).collect()
}

/// A derivative of a trajectory's positions, one panel per coordinate: the velocity
/// (`_vel` columns, m/s) or the acceleration (`_acc` columns, m/s²).
pub(crate) fn derivative_figure(traj: &cps_dmp::Trajectory, acceleration: bool) -> Figure {
    let (derivative, name, unit, columns): (fn(&cps_dmp::Trajectory, usize) -> &[f64], _, _, _) =
        if acceleration {
            (
                cps_dmp::Trajectory::acceleration,
                "acceleration",
                "m/s²",
                "_acc",
            )
        } else {
            (cps_dmp::Trajectory::velocity, "velocity", "m/s", "_vel")
        };
    let dims = traj.dims();
    let series = Series::new(
        "",
        traj.times().to_vec(),
        (0..dims).map(|d| derivative(traj, d).to_vec()).collect(),
    );
    Figure {
        name: name.into(),
        caption: format!(
            "{}{} per coordinate (the trajectory's `{columns}` columns).",
            name[..1].to_uppercase(),
            &name[1..]
        ),
        plot: Plot::Panels(Panels::new(
            (0..dims)
                .map(|d| format!("{} [{unit}]", axis_name(dims, d)))
                .collect(),
            vec![series],
        )),
    }
}

/// The largest of a list (0 for none).
/// The rate at which a robot's controller receives a movement (Franka's 1 kHz).
pub(crate) const CONTROL_RATE: f64 = 1000.0;

/// Every limit of the experiment's robot on a joint trajectory (times and one row of
/// positions each), as its controller would see it at [`CONTROL_RATE`]: the JSON of
/// `cps-cli limits check`.
pub(crate) fn limit_usage(
    robot: &crate::robots::RobotChoice,
    times: &[f64],
    q: Vec<Vec<f64>>,
) -> Result<cps_movement::limits::LimitsReport, ExperimentError> {
    let traj = cps_movement::limits::JointTrajectory {
        names: (1..=robot.setup.chain.dof())
            .map(|j| format!("q{j}"))
            .collect(),
        times: times.to_vec(),
        q,
    };
    cps_movement::limits::check_samples(&robot.model, &traj, CONTROL_RATE).map_err(|e| {
        ExperimentError::Failed {
            context: "checking the movement against the robot's limits".into(),
            source: Box::new(e),
        }
    })
}

/// A report's peak usages in one line: `position 100 %, velocity 25 %, …`, and the verdict.
pub(crate) fn usage_line(report: &cps_movement::limits::LimitsReport) -> String {
    let peaks: Vec<String> = report
        .check
        .joints
        .peak_usage
        .iter()
        .map(|(q, u)| {
            format!(
                "{} {:.0} %",
                q.name(),
                u.iter().fold(0.0_f64, |a, &b| a.max(b))
            )
        })
        .collect();
    format!(
        "every limit at {CONTROL_RATE} Hz ({}): {}",
        peaks.join(", "),
        if report.ok() {
            "within every one".to_string()
        } else {
            format!(
                "{} VIOLATION(S), see summary.json `limit_usage`",
                report.check.violation_count()
            )
        }
    )
}

pub(crate) fn worst(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, &b| a.max(b))
}
