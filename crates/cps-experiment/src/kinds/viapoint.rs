//! `kind = "viapoint"`: the thesis's via-point learning (repetitions of CMA-ES, or the
//! exact solver), compared with the exact least-squares optimum.

use cps_learn::{CostBreakdown, ViaPointOutcome};
use serde::Serialize;

use super::Ctx;
use super::{cost_figure, derivative_figure, position_figures, search_figure, way_points, worst};
use crate::{ExperimentError, InputError};
use cps_outcome::outcome::{
    Column, Format, Mark, MarkKind, Outcome, Plot, Report, ReportTable, Table, fields,
};

#[derive(Serialize)]
struct Summary<'a> {
    solver: &'static str,
    parametrisation: &'static str,
    warm_start: bool,
    evaluation: &'static str,
    repetitions: usize,
    best_repetition: usize,
    generations: u64,
    evaluations: u64,
    non_finite_evaluations: u64,
    termination: &'a str,
    best_cost: f64,
    cost_terms: &'a CostBreakdown,
    goal_error_m: f64,
    via_errors_m: &'a [f64],
    max_position_error_m: f64,
    final_speed_m_s: f64,
    optimum_cost: f64,
    optimum_cost_terms: &'a CostBreakdown,
    gap_to_optimum: f64,
    hessian_condition: f64,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    obstacle_clearances_m: Vec<f64>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    obstacle_distances_m: Vec<f64>,
    runs: Vec<RunSummary<'a>>,
}

#[derive(Serialize)]
struct RunSummary<'a> {
    seed: u64,
    cost: f64,
    gap_to_optimum: f64,
    max_position_error_m: f64,
    final_speed_m_s: f64,
    generations: u64,
    evaluations: u64,
    termination: &'a str,
    seconds: f64,
}

/// Learns the via points and declares the outcome.
pub(crate) fn run(ctx: &Ctx<'_>) -> Result<Outcome, ExperimentError> {
    let (exp, config) = (ctx.exp, &ctx.exp.config);
    let progress = |_rep: usize, r: &cps_cmaes::GenerationReport<'_>| ctx.generation(r);
    let outcome = ctx
        .pool
        .install(|| cps_learn::learn_via_points(config, &progress))
        .map_err(|e| match e {
            cps_learn::LearnError::InvalidTask { .. } | cps_learn::LearnError::Dmp(_) => {
                InputError(format!("{}: {e}", exp.source.display())).into()
            }
            other => ExperimentError::Failed {
                context: "the learning run failed".into(),
                source: Box::new(other),
            },
        })?;
    ctx.observer.finished();
    let best = outcome.best();
    let traj = outcome.best_trajectory();
    let task = &config.task;
    let distances = task.obstacle_distances(&traj);
    let summary = Summary {
        solver: config.solver.name(),
        parametrisation: config.parametrisation.name(),
        warm_start: config.warm_start,
        evaluation: outcome.evaluation.name(),
        repetitions: outcome.runs.len(),
        best_repetition: outcome.best_run,
        generations: best.generations,
        evaluations: outcome.runs.iter().map(|r| r.evaluations).sum(),
        non_finite_evaluations: outcome.runs.iter().map(|r| r.non_finite_evaluations).sum(),
        termination: &best.termination,
        best_cost: best.cost,
        cost_terms: &best.breakdown,
        goal_error_m: best.errors.goal,
        via_errors_m: &best.errors.via,
        max_position_error_m: best.errors.max_position_error(),
        final_speed_m_s: best.errors.final_speed,
        optimum_cost: outcome.optimum.cost,
        optimum_cost_terms: &outcome.optimum.breakdown,
        gap_to_optimum: best.gap_to_optimum,
        hessian_condition: outcome.optimum.hessian_condition,
        obstacle_clearances_m: task.obstacles.iter().map(|o| o.clearance).collect(),
        obstacle_distances_m: distances.clone(),
        runs: outcome
            .runs
            .iter()
            .map(|r| RunSummary {
                seed: r.seed,
                cost: r.cost,
                gap_to_optimum: r.gap_to_optimum,
                max_position_error_m: r.errors.max_position_error(),
                final_speed_m_s: r.errors.final_speed,
                generations: r.generations,
                evaluations: r.evaluations,
                termination: &r.termination,
                seconds: r.seconds,
            })
            .collect(),
    };
    let histories: Vec<&[cps_learn::GenerationRecord]> =
        outcome.runs.iter().map(|r| r.history.as_slice()).collect();
    let mut figures = position_figures(
        vec![cps_movement::movement::trajectory_series(
            "learned trajectory",
            &traj,
        )],
        way_points(&config.task),
        "Each coordinate over time with the start, the via points p1… and the goal.",
        "The path in 3-D, world frame.",
    );
    // Obstacles are points in space: marked in the 3-D path only.
    for f in &mut figures {
        if let Plot::Path3d { marks, .. } = &mut f.plot {
            marks.extend(task.obstacles.iter().enumerate().map(|(i, o)| Mark {
                time: 0.0,
                values: o.position.clone(),
                kind: MarkKind::Obstacle,
                label: format!("o{}", i + 1),
            }));
        }
    }
    figures.push(derivative_figure(&traj, false));
    figures.push(derivative_figure(&traj, true));
    figures.extend(cost_figure(
        "Best cost so far per generation (log scale): the mean over the repetitions with its 95 % band, and the exact optimum.",
        vec![super::cost_arm("CMA-ES", &histories)],
        Some(outcome.optimum.cost),
    ));
    figures.extend(search_figure(&[("CMA-ES", histories[0])]));
    let lines = vec![
        format!("{}: {} in {:.2} s", exp.name, best.termination, ctx.wall()),
        format!(
            "  best cost {:.6e} (exact optimum {:.6e}, gap {:.2e}) after {} generations, {} evaluations",
            best.cost,
            outcome.optimum.cost,
            best.gap_to_optimum,
            best.generations,
            best.evaluations
        ),
        format!(
            "  goal error {:.3} mm, worst via-point error {:.3} mm, final speed {:.3} mm/s",
            best.errors.goal * 1e3,
            worst(&best.errors.via) * 1e3,
            best.errors.final_speed * 1e3
        ),
    ];
    let mut lines = lines;
    for (i, (o, d)) in task.obstacles.iter().zip(&distances).enumerate() {
        lines.push(format!(
            "  obstacle o{}: closest {:.1} mm (clearance {:.1} mm){}",
            i + 1,
            d * 1e3,
            o.clearance * 1e3,
            if *d < 0.99 * o.clearance {
                " — inside the clearance: raise [cost] obstacle"
            } else {
                ""
            }
        ));
    }
    Ok(Outcome {
        header: ctx.header(!outcome.interrupted()),
        summary: fields(&summary),
        tables: vec![history(&outcome), weights(ctx, &outcome), trajectory(&traj)],
        figures,
        documents: Vec::new(),
        report: report(ctx, &outcome),
        lines,
    })
}

/// `cost_history.csv`: one row per generation and repetition.
fn history(outcome: &ViaPointOutcome) -> Table {
    let (mut rep, mut generation, mut best, mut median, mut so_far, mut sigma) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for (r, run) in outcome.runs.iter().enumerate() {
        for h in &run.history {
            rep.push(r as u64);
            generation.push(h.generation);
            best.push(h.best);
            median.push(h.median);
            so_far.push(h.best_so_far);
            sigma.push(h.sigma);
        }
    }
    Table::new("cost_history")
        .with(Column::integers("repetition", rep))
        .with(Column::integers("generation", generation))
        .with(Column::numbers("best", best, Format::ShortestSci))
        .with(Column::numbers("median", median, Format::ShortestSci))
        .with(Column::numbers("best_so_far", so_far, Format::ShortestSci))
        .with(Column::numbers("sigma", sigma, Format::ShortestSci))
}

/// `weights.csv`: the thesis's columns, one row per repetition.
fn weights(ctx: &Ctx<'_>, outcome: &ViaPointOutcome) -> Table {
    let config = &ctx.exp.config;
    let task = &config.task;
    let dims = task.start.len();
    let sci = |v: f64| format!("{v:e}");
    let list = |v: &[f64]| {
        format!(
            "[{}]",
            v.iter().map(|x| sci(*x)).collect::<Vec<_>>().join(", ")
        )
    };
    // The way points as rows per coordinate, then their times.
    let mut way: Vec<Vec<f64>> = vec![Vec::new(); dims + 1];
    let mut push = |p: &[f64], t: f64| {
        for d in 0..dims {
            way[d].push(p[d]);
        }
        way[dims].push(t);
    };
    push(&task.start, 0.0);
    for v in &task.via {
        push(&v.position, v.time);
    }
    push(&task.goal, task.dmp.tau);
    let points: Vec<String> = way.iter().map(|r| list(r)).collect();
    let points = format!("[{}]", points.join(", "));
    let now = humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string();
    let n = outcome.runs.len();
    let runs = &outcome.runs;
    Table::new("weights")
        .with(Column::texts("Time", vec![now; n]))
        .with(Column::integers("NrDmps", vec![dims as u64; n]))
        .with(Column::integers("NrBfs", vec![task.dmp.n_basis as u64; n]))
        .with(Column::texts(
            "Scaling",
            vec![config.parametrisation.name().to_string(); n],
        ))
        .with(Column::numbers("Tau", vec![task.dmp.tau; n], Format::Plain))
        .with(Column::integers(
            "NrIterations",
            runs.iter().map(|r| r.generations).collect(),
        ))
        .with(Column::texts(
            "Weights",
            runs.iter()
                .map(|r| {
                    let w: Vec<String> = r.weights.chunks(task.dmp.n_basis).map(list).collect();
                    format!("[{}]", w.join(", "))
                })
                .collect(),
        ))
        .with(Column::texts(
            "Rewards",
            runs.iter()
                .map(|r| list(&r.history.iter().map(|h| h.best_so_far).collect::<Vec<_>>()))
                .collect(),
        ))
        .with(Column::numbers(
            "ComputeTime",
            runs.iter().map(|r| r.seconds).collect(),
            Format::Fixed(6),
        ))
        .with(Column::integers(
            "NrWayPoints",
            vec![(task.via.len() + 2) as u64; n],
        ))
        .with(Column::texts("WayPoints", vec![points; n]))
}

/// `trajectory.csv`: `t`, positions `x, y, z` (`y0, y1, …` for other dimensions), then
/// `<name>_vel`, `<name>_acc` (SI units).
pub(crate) fn trajectory(traj: &cps_dmp::Trajectory) -> Table {
    let dims = traj.dims();
    let axis = |d: usize| super::axis_name(dims, d);
    let mut table = Table::new("trajectory").with(Column::numbers(
        "t",
        traj.times().to_vec(),
        Format::Fixed(6),
    ));
    for (suffix, q) in [
        (
            "",
            cps_dmp::Trajectory::position as fn(&cps_dmp::Trajectory, usize) -> &[f64],
        ),
        ("_vel", cps_dmp::Trajectory::velocity),
        ("_acc", cps_dmp::Trajectory::acceleration),
    ] {
        for d in 0..dims {
            table.push(Column::numbers(
                format!("{}{suffix}", axis(d)),
                q(traj, d).to_vec(),
                Format::Sci(12),
            ));
        }
    }
    table
}

fn report(ctx: &Ctx<'_>, outcome: &ViaPointOutcome) -> Report {
    let config = &ctx.exp.config;
    let best = outcome.best();
    let mm = |v: f64| format!("{:.3} mm", v * 1e3);
    let task = &config.task;
    let mut rows = vec![
        (
            "solver",
            format!(
                "{} in the {} search space{}{}",
                match config.solver {
                    cps_learn::Solver::Cmaes => "CMA-ES",
                    cps_learn::Solver::Exact => "exact least squares",
                    cps_learn::Solver::LeastSquares => "Levenberg–Marquardt on the residuals",
                },
                config.parametrisation.name(),
                if config.warm_start {
                    ", warm-started at the exact optimum"
                } else {
                    ""
                },
                match (config.solver, outcome.evaluation) {
                    (cps_learn::Solver::Cmaes, cps_learn::Evaluation::Quadratic) => {
                        "; candidates evaluated by the cost's exact quadratic form, the result by a rollout"
                    }
                    _ => "",
                }
            ),
        ),
        (
            "DMPs",
            format!(
                "{} × {} basis functions, τ = {} s, dt = {} s",
                task.start.len(),
                task.dmp.n_basis,
                task.dmp.tau,
                task.dmp.dt
            ),
        ),
        ("best cost", format!("{:.6e}", best.cost)),
        (
            "exact optimum",
            format!(
                "{:.6e} (gap {:.2e})",
                outcome.optimum.cost, best.gap_to_optimum
            ),
        ),
        ("termination", best.termination.clone()),
        (
            "generations / evaluations",
            format!("{} / {}", best.generations, best.evaluations),
        ),
        ("goal error", mm(best.errors.goal)),
    ];
    for (i, e) in best.errors.via.iter().enumerate() {
        rows.push(("via-point error", format!("p{}: {}", i + 1, mm(*e))));
    }
    rows.push((
        "final speed",
        format!("{:.3} mm/s", best.errors.final_speed * 1e3),
    ));
    Report {
        title: format!("{}: via-point learning", ctx.exp.name),
        context: format!(
            "DMPs learned to pass {} via points and stop at the goal ({} repetition(s)); every cost is compared with the exact least-squares optimum.",
            task.via.len(),
            outcome.runs.len()
        ),
        tables: vec![ReportTable::pairs("Result", rows)],
    }
}
