//! `kind = "viapoint_executed"`: via-point learning with the simulator in the loop. Every
//! CMA-ES candidate is executed on the robot backend — reset, run, record — by a free
//! simulator of the pool (`[robot] endpoints`), and judged by what the robot did
//! ([`cps_learn::executed_cost`]): via-point, goal and final-velocity errors as executed,
//! the tracking error, the commanded movement's effort, and with `[clearance]` how far the
//! executed joints bring the robot's shapes within the clearance of each other and of its
//! world's ([`cps_learn::ExecutedCost::add_clearance`]). The analytic cost's exact
//! optimum is the warm start.
//!
//! Each candidate's cost depends on the candidate alone (the backend is reset before
//! each), and the costs come back in candidate order, so the result is the same for any
//! pool size and whichever simulator ran what. A simulator that fails is dropped and its
//! candidate run by another; when none is left the run stops, keeping the best so far
//! (`"complete": false`).

use cps_cmaes::Parameters;
use cps_learn::pool::{Dropped, SimulatorPool};
use cps_learn::{Judge, Judged, Kept, SearchSpace, exact_optimum, pool_failure, targets_at};
use cps_robot::{Recording, StopToken};
use serde::Serialize;

use super::clearance::{ClearanceSummary, Joints, KeptClearSummary};
use super::movement_files::movement_files;
use super::{Ctx, history_table, learn_error, position_figures, search_figure, way_points, worst};
use crate::ExperimentError;
use crate::observer::Event;
use crate::robots::RobotChoice;
use cps_outcome::outcome::{Column, Format, Outcome, Report, ReportTable, Series, Table, fields};

#[derive(Serialize)]
struct Summary<'a> {
    backend: String,
    /// The pool: which simulators ran, which were dropped (the only part of the summary,
    /// with the times, that depends on the pool).
    simulators: Simulators<'a>,
    parametrisation: &'static str,
    sigma0: f64,
    population: usize,
    generations: u64,
    /// Candidates executed and judged: the warm start and every generation's population.
    evaluations: u64,
    /// Candidates the guard refused a command of (a limit, a collision): not executed to
    /// the end, costing +∞.
    refused_candidates: u64,
    /// With `[clearance]`: the stage that kept the warm start clear on the model.
    warm_start_kept_clear: Option<KeptClearSummary>,
    termination: String,
    tracking_weight: f64,
    speed_usage_weight: f64,
    warm_start_analytic_cost: f64,
    warm_start_executed_cost: f64,
    best_cost: f64,
    cost_terms: cps_learn::CostBreakdown,
    tracking_cost: f64,
    speed_usage_cost: f64,
    /// The clearance term of the best execution (`[clearance]`; 0 without).
    clearance_cost: f64,
    /// How close the best execution and the warm start's come to the robot's shapes.
    clearance: Option<ClearanceSummary>,
    analytic_cost: f64,
    goal_error_m: f64,
    via_errors_m: &'a [f64],
    max_tracking_error_m: f64,
    unconverged_samples: usize,
    /// The executed joints' peak speeds as fractions of their limits.
    peak_speed_usage: &'a [f64],
    /// The executed movement against every limit at the control rate.
    limit_usage: serde_json::Value,
}

#[derive(Serialize)]
struct Simulators<'a> {
    endpoints: Vec<String>,
    evaluations: Vec<u64>,
    dropped: &'a [Dropped],
}

/// Learns on the executed cost and declares the outcome.
pub(crate) fn run(
    ctx: &Ctx<'_>,
    plan: &crate::plan::ExecutedPlan,
) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let config = &exp.config;
    let task = &config.task;
    let robot = exp.robot.as_ref().ok_or_else(|| {
        ExperimentError::Message("an executed-cost experiment has a robot".into())
    })?;
    let weights = plan.weights;
    let dmp = task.build_dmp().map_err(|e| learn_error(e, "DMP"))?;
    let space = SearchSpace::new(config.parametrisation, &dmp);
    let optimum = ctx
        .pool
        .install(|| exact_optimum(task, &dmp, &space))
        .map_err(|e| learn_error(e, "exact optimum (the warm start)"))?;
    let judge = Judge {
        dmp: &dmp,
        space: &space,
        task,
        setup: &robot.setup,
        weights,
        clearance: exp.clearance.as_ref().map(|c| &c.clearance),
        stop: ctx.stop,
    };
    // The in-process robot runs one copy per worker thread: the results are the same
    // for any pool size.
    let copies = ctx.pool.current_num_threads();
    let endpoints = robot.backend.pool_names(copies);
    let mut opened = robot.open_pool(copies)?;
    robot.check_runs_plans(&mut opened)?;
    let dt = opened
        .first()
        .map_or(exp.config.task.dmp.dt, |(_, b)| b.dt());
    let mut pool = SimulatorPool::new(opened);
    let mut x0 = optimum.params.clone();
    let kept = keep_warm_start_clear(ctx, &judge, dt, &mut x0)?;
    let n = x0.len();
    let warm = execute_warm_start(ctx, robot, &judge, &mut pool, &x0, kept.is_some())?;
    let warm_cost = warm.cost.total();
    let warm_recording = robot.model.shapes.as_ref().map(|_| warm.recording.clone());
    // cps-learn's one CMA-ES loop over the pool, the warm start judged already (its
    // execution is the best so far until a candidate beats it).
    let working = || ctx.observer.event(Event::Working);
    let (kept_search, stats, pool) = cps_learn::learn_on_executions(
        &judge,
        pool,
        warm,
        x0,
        config,
        &|r| ctx.generation(r),
        &working,
    )
    .map_err(|e| learn_error(e, "CMA-ES on the executed cost"))?;
    let Kept {
        best,
        best_cost,
        refused,
        ended,
    } = kept_search;
    let (termination, failure) = match ended {
        Some(cps_learn::Ended::Stopped) => ("interrupted".to_string(), None),
        Some(cps_learn::Ended::Failed(f)) => ("the simulators failed".to_string(), Some(f)),
        None => (stats.termination.clone(), None),
    };
    let interrupted = termination == "interrupted";
    let history = stats.history;
    ctx.observer.finished();
    // The executed movement against every limit; retimed and exported as `[export]` asks.
    let movement = movement_files(
        exp,
        robot,
        "",
        &best.recording.time,
        best.recording.q.clone(),
    )?;
    let summary = Summary {
        backend: robot
            .backend
            .pool_description()
            .unwrap_or_else(|| robot.describe()),
        simulators: Simulators {
            endpoints,
            evaluations: pool.evaluations(),
            dropped: pool.dropped(),
        },
        parametrisation: config.parametrisation.name(),
        sigma0: config.sigma0,
        population: config
            .population
            .unwrap_or_else(|| Parameters::default_lambda(n)),
        generations: history.len() as u64,
        evaluations: 1 + stats.evaluations,
        refused_candidates: refused,
        warm_start_kept_clear: kept,
        termination,
        tracking_weight: weights.tracking,
        speed_usage_weight: weights.speed_usage,
        warm_start_analytic_cost: optimum.cost,
        warm_start_executed_cost: warm_cost,
        best_cost,
        cost_terms: best.cost.terms,
        tracking_cost: best.cost.tracking,
        speed_usage_cost: best.cost.speed_usage,
        clearance_cost: best.cost.clearance,
        clearance: clearance_summary(ctx, robot, &best.recording, warm_recording.as_ref())?,
        analytic_cost: task.cost(&best.trajectory),
        goal_error_m: best.errors.goal,
        via_errors_m: &best.errors.via,
        max_tracking_error_m: best.errors.max_tracking,
        unconverged_samples: best.errors.unconverged,
        peak_speed_usage: &best.errors.speed_usage,
        limit_usage: movement.usage.json(),
    };
    let mut header = ctx.header(!interrupted && failure.is_none());
    header.failure = failure.clone();
    let lines = lines(ctx, &summary, failure.as_deref());
    let figures = figures(task, &best, &history);
    let report = report(ctx, &summary);
    let tables = vec![
        history_table(&[("CMA-ES", &history)]),
        executed_table(&best),
    ];
    Ok(movement.outcome(header, report, fields(&summary), tables, figures, lines))
}

/// How close the best and the warm start's executions came to the robot's world, when
/// the robot has collision shapes.
fn clearance_summary(
    ctx: &Ctx<'_>,
    robot: &RobotChoice,
    best: &Recording,
    warm: Option<&Recording>,
) -> Result<Option<ClearanceSummary>, ExperimentError> {
    let (Some(shapes), Some(warm)) = (&robot.model.shapes, warm) else {
        return Ok(None);
    };
    ClearanceSummary::new(
        shapes,
        &robot.setup.chain,
        ctx.exp.clearance.as_ref().map(|c| &c.clearance),
        &Joints::of_recording(best),
        &Joints::of_recording(warm),
    )
    .map(Some)
    .map_err(|e| ExperimentError::Message(format!("the executed joints' shapes: {e}")))
}

/// With [clearance], the warm start `x0` is first kept clear on the model (the guard would
/// refuse every candidate near one that is not): what that did.
fn keep_warm_start_clear(
    ctx: &Ctx<'_>,
    judge: &Judge<'_>,
    dt: f64,
    x0: &mut Vec<f64>,
) -> Result<Option<KeptClearSummary>, ExperimentError> {
    let Some(k) = &ctx.exp.clearance else {
        return Ok(None);
    };
    let (dmp, space) = (judge.dmp, judge.space);
    let anchor = cps_learn::task_anchor(judge.task, dmp, space);
    let targets = |theta: &[f64]| targets_at(&dmp.rollout(&space.weights(theta)), dt).1;
    let keep = cps_learn::KeepClear {
        clearance: &k.clearance,
        robot: judge.setup,
        dt,
        iterations: k.iterations,
    };
    let kept = ctx
        .pool
        .install(|| {
            cps_learn::keep_clear(&keep, x0.clone(), &anchor, &targets, &|r| ctx.generation(r))
        })
        .map_err(|e| learn_error(e, "keeping the warm start clear on the model"))?;
    x0.clone_from(&kept.theta);
    Ok(Some(KeptClearSummary::new(&kept)))
}

/// The warm start `x0` executed and judged (`kept`: kept clear on the model first). A
/// simulator executes it whole even once a stop is asked (seconds of simulated motion), so
/// an interrupted run keeps one judged execution; a real robot stops at once as always.
fn execute_warm_start(
    ctx: &Ctx<'_>,
    robot: &RobotChoice,
    judge: &Judge<'_>,
    pool: &mut SimulatorPool,
    x0: &[f64],
    kept: bool,
) -> Result<Judged, ExperimentError> {
    let never = StopToken::new();
    let warm_judge = Judge {
        stop: if robot.backend.is_simulator() {
            &never
        } else {
            ctx.stop
        },
        ..*judge
    };
    let warm = match pool.run(1, &|_, b| warm_judge.judge(x0, b)) {
        Ok(mut w) => w.remove(0),
        Err(e) => {
            return Err(ExperimentError::Message(pool_failure(
                e,
                pool,
                "executing the warm start",
            )));
        }
    };
    match &warm.refused {
        None => Ok(warm),
        Some(reason) => Err(ExperimentError::Message(format!(
            "executing the warm start (the analytic cost's exact optimum{}): the guard refused it: {reason}{}",
            if kept {
                ", kept clear on the model"
            } else {
                ""
            },
            if kept || robot.model.shapes.is_none() {
                ""
            } else {
                "; [clearance] (a distance) learns a movement that keeps clear of the robot's shapes and its world"
            }
        ))),
    }
}

/// The best candidate commanded and executed, and the search's history.
fn figures(
    task: &cps_learn::ViaPointTask,
    best: &Judged,
    history: &[cps_learn::GenerationRecord],
) -> Vec<cps_outcome::outcome::Figure> {
    position_figures(
        vec![
            cps_movement::movement::trajectory_series("commanded", &best.trajectory),
            Series::new(
                "executed",
                best.times.clone(),
                (0..3)
                    .map(|d| best.recording.position.iter().map(|p| p[d]).collect())
                    .collect(),
            ),
        ],
        way_points(task),
        "The best candidate commanded and as the robot executed it, each coordinate over time.",
        "The best candidate's path in 3-D, commanded and executed, world frame.",
    )
    .into_iter()
    .chain(search_figure(&[("CMA-ES on the executed cost", history)]))
    .collect()
}

/// `executed.csv`: the best candidate at the control period, target and executed.
fn executed_table(best: &Judged) -> Table {
    let r = &best.recording;
    let k = best.times.len().min(r.position.len());
    let target = |d: usize| -> Vec<f64> {
        best.times[..k]
            .iter()
            .map(|&t| best.trajectory.position_at(d, t))
            .collect()
    };
    let executed = |d: usize| -> Vec<f64> { r.position[..k].iter().map(|p| p[d]).collect() };
    let mut table = Table::new("executed").with(Column::numbers(
        "t",
        best.times[..k].to_vec(),
        Format::Fixed(4),
    ));
    for (d, axis) in ["x", "y", "z"].iter().enumerate() {
        table = table.with(Column::numbers(
            format!("target_{axis}"),
            target(d),
            Format::Fixed(6),
        ));
    }
    for (d, axis) in ["x", "y", "z"].iter().enumerate() {
        table = table.with(Column::numbers(
            format!("executed_{axis}"),
            executed(d),
            Format::Fixed(6),
        ));
    }
    table.with(Column::numbers(
        "tracking_error_m",
        r.position_error[..k].to_vec(),
        Format::ShortestSci,
    ))
}

fn lines(ctx: &Ctx<'_>, s: &Summary<'_>, failure: Option<&str>) -> Vec<String> {
    let mut lines = vec![
        format!(
            "{}: {} in {:.2} s ({} generations, {} executions on {} {})",
            ctx.exp.name,
            s.termination,
            ctx.wall(),
            s.generations,
            s.evaluations,
            s.simulators.endpoints.len(),
            ctx.exp
                .robot
                .as_ref()
                .map_or("simulator(s)", |r| r.backend.executed_on())
        ),
        format!(
            "  executed cost {:.6e} (warm start {:.6e}; its analytic cost {:.6e}); tracking {:.3e}",
            s.best_cost, s.warm_start_executed_cost, s.warm_start_analytic_cost, s.tracking_cost
        ),
        format!(
            "  as executed: goal error {:.3} mm, worst via-point error {:.3} mm, worst tracking error {:.3} mm",
            s.goal_error_m * 1e3,
            worst(s.via_errors_m) * 1e3,
            s.max_tracking_error_m * 1e3
        ),
    ];
    if let Some(k) = &s.warm_start_kept_clear {
        lines.push(k.line("the warm start"));
    }
    if let Some(c) = &s.clearance {
        lines.push(c.line());
    }
    if s.refused_candidates > 0 {
        lines.push(format!(
            "  {} candidate(s) refused by the guard (a limit or a collision): not executed to the end, costing +∞",
            s.refused_candidates
        ));
    }
    for d in s.simulators.dropped {
        lines.push(format!(
            "  dropped {} after {} executions: {}",
            d.endpoint, d.evaluations, d.reason
        ));
    }
    if let Some(f) = failure {
        lines.push(format!("  stopped early: {f}"));
    }
    lines
}

fn report(ctx: &Ctx<'_>, s: &Summary<'_>) -> Report {
    let mm = |v: f64| format!("{:.4} mm", v * 1e3);
    let mut rows = vec![
        ("backend", s.backend.clone()),
        ("simulators", s.simulators.endpoints.join(", ")),
        ("executed cost", format!("{:.6e}", s.best_cost)),
        (
            "warm start (the analytic optimum), executed",
            format!("{:.6e}", s.warm_start_executed_cost),
        ),
        ("goal error, executed", mm(s.goal_error_m)),
        ("worst tracking error", mm(s.max_tracking_error_m)),
        (
            "CMA-ES",
            format!(
                "{} generations, {} executions, {}",
                s.generations, s.evaluations, s.termination
            ),
        ),
    ];
    for (i, e) in s.via_errors_m.iter().enumerate() {
        rows.push((
            "via-point error, executed",
            format!("p{}: {}", i + 1, mm(*e)),
        ));
    }
    for d in s.simulators.dropped {
        rows.push((
            "dropped simulator",
            format!(
                "{} after {} executions: {}",
                d.endpoint, d.evaluations, d.reason
            ),
        ));
    }
    let mut tables = super::shared_report_tables(ctx.exp, &fields(s));
    tables.insert(0, ReportTable::pairs("Result", rows));
    Report {
        title: format!("{}: learning on the executed movement", ctx.exp.name),
        context: "Every CMA-ES candidate was executed on the robot backend, reset to the initial configuration, and judged by its recording: the via points, goal and final velocity as executed, the tracking error and the commanded movement's effort. The exact optimum of the analytic cost was the warm start.".into(),
        tables,
    }
}
