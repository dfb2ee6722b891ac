//! Results on disk: summary.json, CSV files and plots, written atomically.

use anyhow::Result;
use cps_learn::{ViaPointConfig, ViaPointOutcome};
use serde::Serialize;

pub use crate::results_dir::Staging;

#[derive(Serialize)]
struct Summary<'a> {
    experiment: &'a str,
    kind: &'static str,
    complete: bool,
    seed: u64,
    versions: Versions,
    threads: usize,
    wall_time_s: f64,
    solver: &'static str,
    parametrisation: &'static str,
    warm_start: bool,
    repetitions: usize,
    best_repetition: usize,
    generations: u64,
    evaluations: u64,
    non_finite_evaluations: u64,
    termination: &'a str,
    best_cost: f64,
    cost_terms: &'a cps_learn::CostBreakdown,
    goal_error_m: f64,
    via_errors_m: &'a [f64],
    max_position_error_m: f64,
    final_speed_m_s: f64,
    optimum_cost: f64,
    optimum_cost_terms: &'a cps_learn::CostBreakdown,
    gap_to_optimum: f64,
    hessian_condition: f64,
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

/// The versions that produced a result.
#[derive(Serialize)]
pub struct Versions {
    cps: &'static str,
}

impl Versions {
    /// This build's versions.
    pub fn now() -> Self {
        Self {
            cps: env!("CARGO_PKG_VERSION"),
        }
    }
}

fn sci(v: f64) -> String {
    format!("{v:e}")
}

/// Writes every result file of a via-point run into `stage`.
pub fn write_viapoint(
    stage: &Staging,
    name: &str,
    config: &ViaPointConfig,
    outcome: &ViaPointOutcome,
    wall_time_s: f64,
    threads: usize,
) -> Result<()> {
    let best = outcome.best();
    let summary = Summary {
        experiment: name,
        kind: "viapoint",
        complete: !outcome.interrupted(),
        seed: config.seed,
        versions: Versions::now(),
        threads,
        wall_time_s,
        solver: match config.solver {
            cps_learn::Solver::Cmaes => "cmaes",
            cps_learn::Solver::Exact => "exact",
        },
        parametrisation: config.parametrisation.name(),
        warm_start: config.warm_start,
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
    stage.write("summary.json", &serde_json::to_vec_pretty(&summary)?)?;

    // cost_history.csv: one row per generation and repetition.
    let mut w = csv::Writer::from_path(stage.path("cost_history.csv"))?;
    w.write_record([
        "repetition",
        "generation",
        "best",
        "median",
        "best_so_far",
        "sigma",
    ])?;
    for (rep, run) in outcome.runs.iter().enumerate() {
        for h in &run.history {
            w.write_record([
                rep.to_string(),
                h.generation.to_string(),
                sci(h.best),
                sci(h.median),
                sci(h.best_so_far),
                sci(h.sigma),
            ])?;
        }
    }
    w.flush()?;

    // weights.csv: the thesis's columns, one row per repetition.
    let task = &config.task;
    let dims = task.start.len();
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
    let list = |v: &[f64]| {
        format!(
            "[{}]",
            v.iter().map(|x| sci(*x)).collect::<Vec<_>>().join(", ")
        )
    };
    let now = humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string();
    let mut w = csv::Writer::from_path(stage.path("weights.csv"))?;
    w.write_record([
        "Time",
        "NrDmps",
        "NrBfs",
        "Scaling",
        "Tau",
        "NrIterations",
        "Weights",
        "Rewards",
        "ComputeTime",
        "NrWayPoints",
        "WayPoints",
    ])?;
    for run in &outcome.runs {
        let weights: Vec<String> = run.weights.chunks(task.dmp.n_basis).map(list).collect();
        let rewards: Vec<f64> = run.history.iter().map(|h| h.best_so_far).collect();
        let points: Vec<String> = way.iter().map(|r| list(r)).collect();
        w.write_record([
            now.clone(),
            dims.to_string(),
            task.dmp.n_basis.to_string(),
            config.parametrisation.name().to_string(),
            task.dmp.tau.to_string(),
            run.generations.to_string(),
            format!("[{}]", weights.join(", ")),
            list(&rewards),
            format!("{:.6}", run.seconds),
            (task.via.len() + 2).to_string(),
            format!("[{}]", points.join(", ")),
        ])?;
    }
    w.flush()?;

    // trajectory.csv: t, positions, velocities, accelerations (SI units).
    let traj = outcome.best_trajectory();
    let axis = |d: usize| {
        if dims == 3 {
            ["x", "y", "z"][d].to_string()
        } else {
            d.to_string()
        }
    };
    let mut header = vec!["t".to_string()];
    for prefix in ["", "v", "a"] {
        for d in 0..dims {
            header.push(format!("{prefix}{}", axis(d)));
        }
    }
    let mut w = csv::Writer::from_path(stage.path("trajectory.csv"))?;
    w.write_record(&header)?;
    for (k, t) in traj.times().iter().enumerate() {
        let mut row = vec![format!("{t:.6}")];
        for q in [
            cps_dmp::Trajectory::position,
            cps_dmp::Trajectory::velocity,
            cps_dmp::Trajectory::acceleration,
        ] {
            for d in 0..dims {
                row.push(format!("{:.12e}", q(&traj, d)[k]));
            }
        }
        w.write_record(&row)?;
    }
    w.flush()?;
    Ok(())
}

/// `report.html` of a via-point run (after its figures are drawn).
pub fn viapoint_report(
    stage: &Staging,
    exp: &crate::experiment::Experiment,
    outcome: &ViaPointOutcome,
    wall_time_s: f64,
    threads: usize,
) -> Result<()> {
    use crate::report::{Table, write};
    let (name, config) = (&exp.name, &exp.config);
    let header = crate::runner::RunHeader::new(exp, !outcome.interrupted(), threads, wall_time_s);
    let best = outcome.best();
    let mm = |v: f64| format!("{:.3} mm", v * 1e3);
    let task = &config.task;
    let mut rows = vec![
        (
            "solver",
            format!(
                "{} in the {} search space{}",
                match config.solver {
                    cps_learn::Solver::Cmaes => "CMA-ES",
                    cps_learn::Solver::Exact => "exact least squares",
                },
                config.parametrisation.name(),
                if config.warm_start {
                    ", warm-started at the exact optimum"
                } else {
                    ""
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
    write(
        stage,
        &header,
        &format!("{name}: via-point learning"),
        &format!(
            "DMPs learned to pass {} via points and stop at the goal ({} repetition(s)); every cost is compared with the exact least-squares optimum.",
            task.via.len(),
            outcome.runs.len()
        ),
        &[Table::pairs("Result", rows)],
        &[
            ("cost", "Best cost so far per generation (log scale)."),
            (
                "coordinates",
                "Each coordinate over time; dots are the way points.",
            ),
            ("path3d", "The path in 3-D, world frame."),
        ],
    )
}
