//! `kind = "imitation"`: the thesis's imitation pipeline run from a file, with its results
//! (recordings, summary, models, figures, report).

use std::ops::ControlFlow;
use std::sync::atomic::Ordering;

use anyhow::{Context, Result};
use cps_dmp::DmpModel;
use cps_kinematics::Recording;
use cps_learn::{ImitationConfig, ImitationOutcome, ImitationStage, ViaPoint};
use serde::Serialize;

use crate::experiment::Experiment;
use crate::output::Staging;
use crate::plots::{Series, figures, trajectory_series};
use crate::report::{self, Table};
use crate::runner::{Finished, RunContext, RunHeader};

/// Runs the pipeline and writes every result into `stage`.
pub fn run(
    exp: &Experiment,
    ctx: &RunContext<'_>,
    stage: &Staging,
    wall: &dyn Fn() -> f64,
) -> Result<Finished> {
    let robot = exp
        .robot
        .as_ref()
        .context("an imitation experiment has a robot")?;
    let plan = exp
        .imitation
        .as_ref()
        .context("an imitation experiment has its settings")?;
    let mut config = ImitationConfig::thesis(exp.config.clone(), robot.setup.clone());
    config.demonstrations = plan.demonstrations;
    config.via_std = plan.via_std;
    config.imitation = plan.dmp;
    config.ridge_lambda = plan.ridge_lambda;
    config.jerk_lambda = plan.jerk_lambda;

    let mut backend = robot.open()?;
    let progress = |s: ImitationStage, done: usize, total: usize| {
        ctx.bar.set_message(format!("{} {done}/{total}", s.name()));
        ctx.bar.tick();
        if ctx.interrupted.load(Ordering::Relaxed) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    // The backend stays on this thread; learning and checks fan out in the pool.
    let outcome = ctx
        .pool
        .install(|| cps_learn::run_imitation(&config, backend.as_mut(), &progress))
        .map_err(|e| crate::runner::learn_error(e, "imitation run"))?;
    ctx.bar.finish_and_clear();
    let header = RunHeader::new(
        exp,
        outcome.complete,
        ctx.pool.current_num_threads(),
        wall(),
    )
    .failed(outcome.failure.as_deref());
    write(exp, &config, robot, &outcome, stage, header)?;
    let o = &outcome;
    let mut lines = vec![format!(
        "{}: {} of {} demonstrations kept and executed in {:.2} s ({})",
        exp.name,
        o.kept().count(),
        o.demonstrations.len(),
        wall(),
        robot.describe()
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
    }
    Ok(Finished {
        complete: o.complete,
        failure: o.failure.clone(),
        lines,
    })
}

#[derive(Serialize)]
struct Summary<'a> {
    #[serde(flatten)]
    header: RunHeader<'a>,
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
    seed: u64,
    via: Vec<ViaPoint>,
    learned_cost: f64,
    gap_to_optimum: f64,
    termination: String,
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
    tracking: Option<Tracking>,
    model: String,
}

fn write(
    exp: &Experiment,
    config: &ImitationConfig,
    robot: &crate::pipelines::RobotChoice,
    outcome: &ImitationOutcome,
    stage: &Staging,
    header: RunHeader<'_>,
) -> Result<()> {
    let kept = outcome.kept().count();
    let mut fits = Vec::new();
    for f in &outcome.fits {
        let file = format!("model_{}.json", f.method);
        let names = vec!["x".to_string(), "y".to_string(), "z".to_string()];
        stage.write(
            &file,
            DmpModel::new(&f.imitation.dmp, &f.imitation.weights, names)
                .to_json()
                .as_bytes(),
        )?;
        let r = &f.imitation.report;
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
            tracking: f.recording.as_ref().map(Tracking::of),
            model: file,
        });
    }
    let summary = Summary {
        header,
        backend: robot.describe(),
        scene: &robot.scene,
        learner: match exp.config.solver {
            cps_learn::Solver::Cmaes => "cmaes",
            cps_learn::Solver::Exact => "exact",
        },
        demonstrations: DemoCounts {
            requested: config.demonstrations,
            kept: outcome
                .demonstrations
                .iter()
                .filter(|d| d.dropped.is_none())
                .count(),
            dropped: outcome
                .demonstrations
                .iter()
                .filter(|d| d.dropped.is_some())
                .count(),
            executed: kept,
            not_executed: outcome
                .demonstrations
                .iter()
                .filter(|d| d.dropped.is_none() && d.recording.is_none())
                .count(),
            imitations_executed: outcome
                .fits
                .iter()
                .filter(|f| f.recording.is_some())
                .count(),
            imitations_fitted: outcome.fits.len(),
            via_std_m: config.via_std,
        },
        dropped: outcome
            .demonstrations
            .iter()
            .filter_map(|d| {
                d.dropped.as_ref().map(|r| Dropped {
                    index: d.index,
                    reason: r.clone(),
                })
            })
            .collect(),
        runs: outcome
            .demonstrations
            .iter()
            .map(|d| DemoSummary {
                index: d.index,
                seed: d.learned.seed,
                via: d.task.via.clone(),
                learned_cost: d.learned.cost,
                gap_to_optimum: d.learned.gap_to_optimum,
                termination: d.learned.termination.clone(),
                kept: d.dropped.is_none(),
                tracking: d.recording.as_ref().map(Tracking::of),
            })
            .collect(),
        mean_integrated_squared_jerk_m2_s5: outcome
            .fits
            .first()
            .map(|f| f.imitation.report.demo_integrated_squared_jerk.iter().sum()),
        imitations: fits,
        stage_seconds: outcome.stage_seconds.clone(),
    };
    stage.write("summary.json", &serde_json::to_vec_pretty(&summary)?)?;
    write_recordings(stage, outcome)?;
    if exp.plots {
        plot(stage, outcome, &exp.config.task)?;
    }
    report(exp, &summary, stage)
}

/// `recordings.csv`, one row per sample: the thesis's (type, time, state) with the index
/// of the demonstration and the tracking error where there is one.
fn write_recordings(stage: &Staging, outcome: &ImitationOutcome) -> Result<()> {
    let mut w = csv::Writer::from_path(stage.path("recordings.csv"))?;
    w.write_record(["type", "index", "t", "x", "y", "z", "tracking_error_m"])?;
    let mut row = |kind: &str, index: usize, t: f64, p: [f64; 3], e: Option<f64>| {
        w.write_record([
            kind.to_string(),
            index.to_string(),
            format!("{t:.6}"),
            format!("{:.9}", p[0]),
            format!("{:.9}", p[1]),
            format!("{:.9}", p[2]),
            e.map_or(String::new(), |e| format!("{e:.3e}")),
        ])
    };
    for d in &outcome.demonstrations {
        let tr = &d.trajectory;
        for (k, &t) in tr.times().iter().enumerate() {
            row(
                "learned",
                d.index,
                t,
                [tr.position(0)[k], tr.position(1)[k], tr.position(2)[k]],
                None,
            )?;
        }
        if let Some(r) = &d.recording {
            for k in 0..r.time.len() {
                row(
                    "executed",
                    d.index,
                    r.time[k],
                    r.position[k],
                    Some(r.position_error[k]),
                )?;
            }
        }
    }
    if let Some(f) = outcome.fits.first() {
        let mean = &f.imitation.reference;
        for (k, &t) in f.trajectory.times().iter().enumerate() {
            row("mean", 0, t, [mean[0][k], mean[1][k], mean[2][k]], None)?;
        }
    }
    for (i, f) in outcome.fits.iter().enumerate() {
        let tr = &f.trajectory;
        let kind = format!("imitation_{}", f.method);
        for (k, &t) in tr.times().iter().enumerate() {
            row(
                &kind,
                i,
                t,
                [tr.position(0)[k], tr.position(1)[k], tr.position(2)[k]],
                None,
            )?;
        }
        if let Some(r) = &f.recording {
            let kind = format!("executed_{}", f.method);
            for k in 0..r.time.len() {
                row(
                    &kind,
                    i,
                    r.time[k],
                    r.position[k],
                    Some(r.position_error[k]),
                )?;
            }
        }
    }
    w.flush()?;
    Ok(())
}

/// Every executed demonstration (faint, time-normalised onto the imitation's τ), the mean
/// and the imitations, per coordinate and in 3-D.
fn plot(stage: &Staging, outcome: &ImitationOutcome, task: &cps_learn::ViaPointTask) -> Result<()> {
    let Some(first) = outcome.fits.first() else {
        return Ok(());
    };
    let tau = first.imitation.dmp.config().tau;
    let recordings: Vec<(Vec<f64>, [Vec<f64>; 3])> = outcome
        .kept()
        .filter_map(|d| d.recording.as_ref())
        .map(|r| {
            let (t0, t1) = (r.time[0], *r.time.last().unwrap_or(&r.time[0]));
            let span = (t1 - t0).max(1e-12);
            let times = r.time.iter().map(|t| (t - t0) / span * tau).collect();
            let coord = |d: usize| r.position.iter().map(|p| p[d]).collect();
            (times, [coord(0), coord(1), coord(2)])
        })
        .collect();
    let mut series: Vec<Series<'_>> = recordings
        .iter()
        .map(|(t, v)| Series {
            label: "executed demonstrations (time-normalised)".into(),
            times: t,
            values: v.iter().map(Vec::as_slice).collect(),
            faint: true,
        })
        .collect();
    series.push(Series {
        label: "mean".into(),
        times: first.trajectory.times(),
        values: first
            .imitation
            .reference
            .iter()
            .map(Vec::as_slice)
            .collect(),
        faint: false,
    });
    for f in &outcome.fits {
        series.push(trajectory_series(
            &format!("imitation ({})", f.method.replace('_', " ")),
            &f.trajectory,
        ));
    }
    // The unperturbed way points, at their times scaled to the imitation's τ.
    let scale = tau / task.dmp.tau;
    let mut points = vec![(0.0, task.start.clone())];
    points.extend(
        task.via
            .iter()
            .map(|v| (v.time * scale, v.position.clone())),
    );
    points.push((tau, task.goal.clone()));
    figures(stage, "coordinates", "path3d", &series, &points)
}

fn report(exp: &Experiment, s: &Summary<'_>, stage: &Staging) -> Result<()> {
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
    let fits = Table {
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
    let dropped = Table {
        title: "Dropped demonstrations".into(),
        header: vec!["demonstration".into(), "reason".into()],
        rows: s
            .dropped
            .iter()
            .map(|d| vec![d.index.to_string(), d.reason.clone()])
            .collect(),
    };
    let mut tables = vec![Table::pairs("Overview", overview), fits];
    if !dropped.rows.is_empty() {
        tables.push(dropped);
    }
    report::write(
        stage,
        &s.header,
        &format!("{}: imitation of executed demonstrations", exp.name),
        "Demonstrations learned by the via-point learner from perturbed via points, executed on the robot with the inverse controller, time-normalised, averaged and imitated (thesis §5.2).",
        &tables,
        &[
            (
                "coordinates",
                "Each coordinate over (normalised) time: the executed demonstrations (grey), their mean and the two imitations; dots are the unperturbed way points.",
            ),
            ("path3d", "The same in 3-D, world frame."),
        ],
    )
}
