//! `kind = "imitation"`: the thesis's imitation pipeline (demonstrations learned from
//! perturbed via points, executed, time-normalised, averaged and imitated).

use cps_dmp::DmpModel;
use cps_learn::{ImitationConfig, ImitationOutcome, ImitationStage, ViaPoint};
use cps_robot::Recording;
use serde::Serialize;

use super::clearance::KeptClearSummary;
use super::movement_files::movement_files;
use super::{Ctx, learn_error};
use super::{marks, position_figures, usage_line};
use crate::ExperimentError;
use crate::observer::Event;
use cps_outcome::outcome::{
    Column, Document, Figure, Format, Outcome, Report, ReportTable, Series, Table, fields,
};

#[derive(Serialize)]
struct Summary<'a> {
    backend: String,
    scene: &'a str,
    learner: &'static str,
    demonstrations: DemoCounts,
    dropped: Vec<Dropped>,
    runs: Vec<DemoSummary>,
    imitations: Vec<FitSummary>,
    mean_integrated_squared_jerk_m2_s5: Option<f64>,
    stage_seconds: Vec<(&'static str, f64)>,
}

#[derive(Serialize)]
struct DemoCounts {
    requested: usize,
    kept: usize,
    dropped: usize,
    /// Kept (reachable) demonstrations whose execution was recorded.
    executed: usize,
    /// Kept demonstrations not executed (the run was interrupted or the backend failed).
    not_executed: usize,
    /// Imitations executed, of the imitations fitted.
    imitations_executed: usize,
    imitations_fitted: usize,
    via_std_m: f64,
}

#[derive(Serialize)]
struct Dropped {
    index: usize,
    reason: String,
}

#[derive(Serialize)]
struct DemoSummary {
    index: usize,
    /// A given demonstration's take.
    #[serde(skip_serializing_if = "Option::is_none")]
    take: Option<String>,
    seed: Option<u64>,
    via: Option<Vec<ViaPoint>>,
    learned_cost: Option<f64>,
    gap_to_optimum: Option<f64>,
    termination: Option<String>,
    kept: bool,
    tracking: Option<Tracking>,
}

#[derive(Serialize)]
struct Tracking {
    max_position_error_m: f64,
    rms_position_error_m: f64,
    duration_s: f64,
    samples: usize,
    backend_steps: usize,
    unconverged_samples: usize,
}

impl Tracking {
    fn of(r: &Recording) -> Self {
        Self {
            max_position_error_m: r.max_position_error(),
            rms_position_error_m: r.rms_position_error(),
            duration_s: r.time.last().copied().unwrap_or(0.0),
            samples: r.time.len(),
            backend_steps: r.steps,
            unconverged_samples: r.unconverged,
        }
    }
}

#[derive(Serialize)]
struct FitSummary {
    method: &'static str,
    basis_functions: usize,
    tau_s: f64,
    lambda: Vec<f64>,
    rmse_to_mean_m: f64,
    rmse_per_dimension_m: Vec<f64>,
    max_error_per_dimension_m: Vec<f64>,
    integrated_squared_jerk_m2_s5: f64,
    condition_number: f64,
    /// With `[clearance]`: how the imitation was bent on the model to keep it (its
    /// errors above are the bent imitation's).
    #[serde(skip_serializing_if = "Option::is_none")]
    kept_clear: Option<KeptClearSummary>,
    tracking: Option<Tracking>,
    /// Every limit of the robot on the executed movement (its recorded joint positions)
    /// at the controller's 1 kHz: `cps-cli limits check`'s JSON.
    limit_usage: Option<serde_json::Value>,
    /// `[export] retime`: the executed movement retimed (`cps-cli retime`'s JSON).
    #[serde(skip_serializing_if = "Option::is_none")]
    retiming: Option<serde_json::Value>,
    /// `[export] formats`: the files written from it.
    #[serde(skip_serializing_if = "Option::is_none")]
    export: Option<serde_json::Value>,
    model: String,
}

/// Runs the pipeline on the experiment's backend and declares the outcome.
pub(crate) fn run(ctx: &Ctx<'_>) -> Result<Outcome, ExperimentError> {
    let run = pipeline(ctx)?;
    declare(ctx, &run)
}

/// What the pipeline left: its configuration, its outcome and the open backend (for a
/// kind that executes more on it).
pub(crate) struct Pipeline {
    pub config: ImitationConfig,
    pub outcome: ImitationOutcome,
    pub backend: Box<dyn cps_robot::Robot>,
}

/// Runs the imitation pipeline on the experiment's backend.
pub(crate) fn pipeline(ctx: &Ctx<'_>) -> Result<Pipeline, ExperimentError> {
    let exp = ctx.exp;
    let robot = exp
        .robot
        .as_ref()
        .ok_or_else(|| ExperimentError::Message("an imitation experiment has a robot".into()))?;
    let plan = exp.imitation().ok_or_else(|| {
        ExperimentError::Message("an imitation experiment has its settings".into())
    })?;
    let mut config = ImitationConfig::thesis(exp.config.clone(), robot.setup.clone());
    config.demonstrations = plan.demonstrations;
    config.via_std = plan.via_std;
    config.imitation = plan.dmp;
    config.ridge_lambda = plan.ridge_lambda;
    config.jerk_lambda = plan.jerk_lambda;
    config.given = plan.takes.clone();
    config.clearance.clone_from(&exp.clearance);

    let mut backend = robot.open()?;
    let progress = |s: ImitationStage, done: usize, total: usize| {
        ctx.observer
            .event(Event::Stage(&format!("{} {done}/{total}", s.name())))
    };
    // The backend stays on this thread; learning and checks fan out in the pool.
    let outcome = ctx
        .pool
        .install(|| cps_learn::run_imitation(&config, backend.as_mut(), &progress, ctx.stop))
        .map_err(|e| learn_error(e, "imitation run"))?;
    ctx.observer.finished();
    Ok(Pipeline {
        config,
        outcome,
        backend,
    })
}

/// The pipeline's outcome as files, figures and words.
pub(crate) fn declare(ctx: &Ctx<'_>, run: &Pipeline) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let robot = exp
        .robot
        .as_ref()
        .ok_or_else(|| ExperimentError::Message("an imitation experiment has a robot".into()))?;
    let (config, outcome) = (&run.config, &run.outcome);
    let mut header = ctx.header(outcome.complete);
    if let Some(f) = &outcome.failure {
        header.complete = false;
        header.failure = Some(f.clone());
    }
    let o = outcome;
    let mut documents = Vec::new();
    let mut fits = Vec::new();
    let mut usage_lines = Vec::new();
    let mut tables = vec![recordings(o)];
    for f in &o.fits {
        let name = format!("model_{}.json", f.method);
        let axes = vec!["x".to_string(), "y".to_string(), "z".to_string()];
        documents.push(Document::text(
            name.clone(),
            DmpModel::new(&f.imitation.dmp, &f.imitation.weights, axes).to_json(),
        ));
        let r = &f.imitation.report;
        // The executed movement against every limit, retimed and exported as `[export]`
        // asks, its files named after the method.
        let movement = match &f.recording {
            Some(rec) => Some(movement_files(
                exp,
                robot,
                &format!("{}_", f.method),
                &rec.time,
                rec.q.clone(),
            )?),
            None => None,
        };
        let (mut usage, mut retiming, mut export) = (None, None, None);
        if let Some(mut m) = movement {
            usage_lines.push(format!(
                "  imitation by {}, executed: {}",
                f.method.replace('_', " "),
                usage_line(&m.usage)
            ));
            usage_lines.extend(m.lines.drain(1..));
            retiming = m.summary.remove("retiming");
            export = m.summary.remove("export");
            tables.extend(m.tables);
            documents.extend(m.documents);
            usage = Some(m.usage);
        }
        // [clearance] bends the movement; the bend is judged at the control rate like any
        // plan, whatever `[robot] limits` says: a bend that breaks a limit made a jump.
        if f.kept_clear.is_some()
            && header.failure.is_none()
            && let Some(u) = &usage
            && let Some(why) = bent_beyond_limits(u, &robot.setup.initial_q, &robot.model)
        {
            header.failure = Some(format!(
                "[clearance] bent the imitation by {} into a movement that {why}: the clearance asks more than a smooth bend can give; lower `[clearance] distance` or move the obstacle",
                f.method.replace('_', " ")
            ));
        }
        fits.push(FitSummary {
            method: f.method,
            basis_functions: f.imitation.dmp.n_basis(),
            tau_s: f.imitation.dmp.config().tau,
            lambda: r.lambda.clone(),
            rmse_to_mean_m: f.rmse(),
            rmse_per_dimension_m: r.rmse.clone(),
            max_error_per_dimension_m: r.max_error.clone(),
            integrated_squared_jerk_m2_s5: f.integrated_squared_jerk(),
            condition_number: r.condition_number,
            kept_clear: f.kept_clear.as_ref().map(KeptClearSummary::new),
            tracking: f.recording.as_ref().map(Tracking::of),
            limit_usage: usage.as_ref().map(cps_movement::limits::LimitsReport::json),
            retiming,
            export,
            model: name,
        });
    }
    let demos = &o.demonstrations;
    let summary = Summary {
        backend: robot.describe_opened(run.backend.as_ref()),
        scene: &robot.scene,
        learner: exp.config.solver.name(),
        demonstrations: DemoCounts {
            requested: config.demonstrations,
            kept: demos.iter().filter(|d| d.dropped.is_none()).count(),
            dropped: demos.iter().filter(|d| d.dropped.is_some()).count(),
            executed: o.kept().count(),
            not_executed: demos
                .iter()
                .filter(|d| d.dropped.is_none() && d.recording.is_none())
                .count(),
            imitations_executed: o.fits.iter().filter(|f| f.recording.is_some()).count(),
            imitations_fitted: o.fits.len(),
            via_std_m: config.via_std,
        },
        dropped: demos
            .iter()
            .filter_map(|d| {
                d.dropped.as_ref().map(|r| Dropped {
                    index: d.index,
                    reason: r.clone(),
                })
            })
            .collect(),
        runs: demos
            .iter()
            .map(|d| DemoSummary {
                index: d.index,
                take: d.name.clone(),
                seed: d.learned.as_ref().map(|l| l.seed),
                via: d.task.as_ref().map(|t| t.via.clone()),
                learned_cost: d.learned.as_ref().map(|l| l.cost),
                gap_to_optimum: d.learned.as_ref().map(|l| l.gap_to_optimum),
                termination: d.learned.as_ref().map(|l| l.termination.clone()),
                kept: d.dropped.is_none(),
                tracking: d.recording.as_ref().map(Tracking::of),
            })
            .collect(),
        mean_integrated_squared_jerk_m2_s5: o
            .fits
            .first()
            .map(|f| f.imitation.report.demo_integrated_squared_jerk.iter().sum()),
        imitations: fits,
        stage_seconds: o.stage_seconds.clone(),
    };
    Ok(Outcome {
        header,
        report: report(ctx, &summary),
        summary: fields(&summary),
        tables,
        figures: figures(o, &exp.config.task),
        documents,
        lines: lines(ctx, o, &robot.describe_opened(run.backend.as_ref()))
            .into_iter()
            .chain(usage_lines)
            .collect(),
    })
}

fn lines(ctx: &Ctx<'_>, o: &ImitationOutcome, backend: &str) -> Vec<String> {
    let mut lines = vec![format!(
        "{}: {} of {} demonstrations kept and executed in {:.2} s ({backend})",
        ctx.exp.name,
        o.kept().count(),
        o.demonstrations.len(),
        ctx.wall(),
    )];
    for d in o.demonstrations.iter().filter(|d| d.dropped.is_some()) {
        lines.push(format!(
            "  dropped demonstration {}: {}",
            d.index,
            d.dropped.as_deref().unwrap_or("")
        ));
    }
    for f in &o.fits {
        lines.push(format!(
            "  imitation by {}: RMSE to the mean {:.3} mm, integrated squared jerk {:.4e} m²/s⁵, executed within {:.3} mm",
            f.method.replace('_', " "),
            f.rmse() * 1e3,
            f.integrated_squared_jerk(),
            f.recording
                .as_ref()
                .map_or(f64::NAN, |r| r.max_position_error())
                * 1e3
        ));
        if let Some(k) = &f.kept_clear {
            lines.push(
                KeptClearSummary::new(k)
                    .line(&format!("the {} imitation", f.method.replace('_', " "))),
            );
        }
    }
    lines
}

/// `recordings.csv`, one row per sample: the thesis's (type, time, state) with the index
/// of the demonstration and the tracking error where there is one.
fn recordings(outcome: &ImitationOutcome) -> Table {
    #[derive(Default)]
    struct Rows {
        kind: Vec<String>,
        index: Vec<u64>,
        t: Vec<f64>,
        p: [Vec<f64>; 3],
        e: Vec<f64>,
    }
    let mut rows = Rows::default();
    let mut row = |kind: &str, index: usize, t: f64, p: [f64; 3], e: Option<f64>| {
        rows.kind.push(kind.to_string());
        rows.index.push(index as u64);
        rows.t.push(t);
        for (column, v) in rows.p.iter_mut().zip(p) {
            column.push(v);
        }
        rows.e.push(e.unwrap_or(f64::NAN));
    };
    let at = |tr: &cps_dmp::Trajectory, k: usize| {
        [tr.position(0)[k], tr.position(1)[k], tr.position(2)[k]]
    };
    for d in &outcome.demonstrations {
        let tr = &d.trajectory;
        for (k, &t) in tr.times().iter().enumerate() {
            row("learned", d.index, t, at(tr, k), None);
        }
        if let Some(r) = &d.recording {
            for k in 0..r.time.len() {
                let e = Some(r.position_error[k]);
                row("executed", d.index, r.time[k], r.position[k], e);
            }
        }
    }
    if let Some(f) = outcome.fits.first() {
        let mean = &f.imitation.reference;
        for (k, &t) in f.trajectory.times().iter().enumerate() {
            row("mean", 0, t, [mean[0][k], mean[1][k], mean[2][k]], None);
        }
    }
    for (i, f) in outcome.fits.iter().enumerate() {
        let tr = &f.trajectory;
        let kind = format!("imitation_{}", f.method);
        for (k, &t) in tr.times().iter().enumerate() {
            row(&kind, i, t, at(tr, k), None);
        }
        if let Some(r) = &f.recording {
            let kind = format!("executed_{}", f.method);
            for k in 0..r.time.len() {
                let e = Some(r.position_error[k]);
                row(&kind, i, r.time[k], r.position[k], e);
            }
        }
    }
    let [x, y, z] = rows.p;
    Table::new("recordings")
        .with(Column::texts("type", rows.kind))
        .with(Column::integers("index", rows.index))
        .with(Column::numbers("t", rows.t, Format::Fixed(6)))
        .with(Column::numbers("x", x, Format::Fixed(9)))
        .with(Column::numbers("y", y, Format::Fixed(9)))
        .with(Column::numbers("z", z, Format::Fixed(9)))
        .with(Column::numbers("tracking_error_m", rows.e, Format::Sci(3)).nan_as_empty())
}

/// Every executed demonstration (faint, time-normalised onto the imitation's τ), the mean
/// and the imitations, per coordinate and in 3-D.
fn figures(outcome: &ImitationOutcome, task: &cps_learn::ViaPointTask) -> Vec<Figure> {
    let Some(first) = outcome.fits.first() else {
        return Vec::new();
    };
    let tau = first.imitation.dmp.config().tau;
    let mut series: Vec<Series> = outcome
        .kept()
        .filter_map(|d| d.recording.as_ref())
        .map(|r| {
            let (t0, t1) = (r.time[0], *r.time.last().unwrap_or(&r.time[0]));
            let span = (t1 - t0).max(1e-12);
            let times = r.time.iter().map(|t| (t - t0) / span * tau).collect();
            let coord = |d: usize| r.position.iter().map(|p| p[d]).collect();
            Series::new(
                "executed demonstrations (time-normalised)",
                times,
                vec![coord(0), coord(1), coord(2)],
            )
            .faint()
        })
        .collect();
    series.push(Series::new(
        "mean",
        first.trajectory.times().to_vec(),
        first.imitation.reference.clone(),
    ));
    for f in &outcome.fits {
        series.push(cps_movement::movement::trajectory_series(
            format!("imitation ({})", f.method.replace('_', " ")),
            &f.trajectory,
        ));
    }
    // The unperturbed way points, at their times scaled to the imitation's τ.
    let positions = std::iter::once(task.start.clone())
        .chain(task.via.iter().map(|v| v.position.clone()))
        .chain(std::iter::once(task.goal.clone()));
    position_figures(
        series,
        marks(task, tau / task.dmp.tau, positions),
        "Each coordinate over (normalised) time: the executed demonstrations (grey), their mean and the two imitations (dashed), with the unperturbed start, via points p1… and goal.",
        "The same in 3-D, world frame.",
    )
}

fn report(ctx: &Ctx<'_>, s: &Summary<'_>) -> Report {
    let mm = |v: f64| format!("{:.3} mm", v * 1e3);
    let mut overview = vec![
        ("backend", s.backend.clone()),
        ("scene", s.scene.to_string()),
        (
            "demonstrations",
            format!(
                "{} requested, {} kept, {} dropped (via points moved by N(0, {}²) m per axis)",
                s.demonstrations.requested,
                s.demonstrations.kept,
                s.demonstrations.dropped,
                s.demonstrations.via_std_m
            ),
        ),
        ("learner", s.learner.to_string()),
    ];
    let worst = s
        .runs
        .iter()
        .filter_map(|r| r.tracking.as_ref())
        .map(|t| t.max_position_error_m)
        .fold(None, |a: Option<f64>, e| Some(a.map_or(e, |a| a.max(e))));
    if let Some(w) = worst {
        overview.push(("worst tracking error (demonstrations)", mm(w)));
    }
    if let Some(j) = s.mean_integrated_squared_jerk_m2_s5 {
        overview.push((
            "integrated squared jerk of the mean",
            format!("{j:.4e} m²/s⁵"),
        ));
    }
    let fits = ReportTable {
        title: "Imitations of the mean recording".into(),
        header: [
            "method",
            "λ (x, y, z)",
            "RMSE to the mean",
            "integrated squared jerk",
            "tracking error (max)",
        ]
        .map(String::from)
        .to_vec(),
        rows: s
            .imitations
            .iter()
            .map(|f| {
                vec![
                    f.method.replace('_', " "),
                    f.lambda
                        .iter()
                        .map(|l| format!("{l:.2e}"))
                        .collect::<Vec<_>>()
                        .join(", "),
                    mm(f.rmse_to_mean_m),
                    format!("{:.4e} m²/s⁵", f.integrated_squared_jerk_m2_s5),
                    f.tracking
                        .as_ref()
                        .map_or("not executed".into(), |t| mm(t.max_position_error_m)),
                ]
            })
            .collect(),
    };
    let dropped = ReportTable {
        title: "Dropped demonstrations".into(),
        header: vec!["demonstration".into(), "reason".into()],
        rows: s
            .dropped
            .iter()
            .map(|d| vec![d.index.to_string(), d.reason.clone()])
            .collect(),
    };
    let mut tables = vec![ReportTable::pairs("Overview", overview), fits];
    if !dropped.rows.is_empty() {
        tables.push(dropped);
    }
    Report {
        title: format!("{}: imitation of executed demonstrations", ctx.exp.name),
        context: "Demonstrations learned by the via-point learner from perturbed via points, executed on the robot with the inverse controller, time-normalised, averaged and imitated (thesis §5.2).".into(),
        tables,
    }
}

/// What limit a bent movement breaks, in words: any violation but of a joint's position
/// range when the joint starts beyond it (the thesis's Panda starts with joint 4 at 0 rad,
/// beyond its range, a fact of the scene and not of the bend).
fn bent_beyond_limits(
    usage: &cps_movement::limits::LimitsReport,
    start: &[f64],
    model: &cps_movement::robot_file::RobotModel,
) -> Option<String> {
    use cps_kinematics::Quantity;
    let starts_beyond = |j: usize| {
        model
            .chain
            .limits()
            .is_some_and(|(lo, hi)| start.get(j).is_some_and(|q| *q < lo[j] || *q > hi[j]))
    };
    let v = usage
        .check
        .joints
        .violations
        .iter()
        .find(|v| !(v.quantity == Quantity::Position && starts_beyond(v.joint - 1)))?;
    Some(format!(
        "breaks joint {}'s {} limit at {} s ({} against {})",
        v.joint,
        v.quantity.name().replace('_', " "),
        cps_files::number(v.time, 4),
        cps_files::number(v.value, 4),
        cps_files::number(v.limit, 4)
    ))
}
