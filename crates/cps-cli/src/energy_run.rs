//! `kind = "viapoint_energy"`: via-point learning through a simulated plant with the
//! control-effort term (thesis eq. 53/54), and the measured parallel speed-up.

use std::ops::ControlFlow;
use std::time::Instant;

use anyhow::{Context, Result};
use cps_learn::{EffortConfig, EffortCostBreakdown, EffortOutcome, learn_with_effort};
use serde::Serialize;

use crate::experiment::Experiment;
use crate::output::Staging;
use crate::plots::{CostArm, Series, axis_names, costs, figures, panels, way_points};
use crate::report::{self, Table};
use crate::runner::{Finished, RunContext, RunHeader, learn_error, search_row, write_history};

#[derive(Serialize)]
struct Summary<'a> {
    #[serde(flatten)]
    header: RunHeader<'a>,
    plant: cps_learn::PointMassPlant,
    effort_weight: f64,
    cost: f64,
    cost_terms: EffortCostBreakdown,
    start_cost: f64,
    start_cost_terms: EffortCostBreakdown,
    goal_error_m: f64,
    via_errors_m: &'a [f64],
    max_position_error_m: f64,
    final_speed_m_s: f64,
    peak_force_n: f64,
    search: &'a cps_learn::SearchStats,
    learning_seconds: f64,
    speedup: Option<Speedup>,
}

/// The same generations timed on one thread and on two (the faster of two runs each).
#[derive(Serialize, Clone, Copy)]
struct Speedup {
    generations: u64,
    seconds_1_thread: f64,
    seconds_2_threads: f64,
    speedup: f64,
    identical_results: bool,
}

/// Learns with the plant, measures the speed-up if asked, writes everything into `stage`.
pub fn run(
    exp: &Experiment,
    ctx: &RunContext<'_>,
    stage: &Staging,
    wall: &dyn Fn() -> f64,
) -> Result<Finished> {
    let plan = exp.energy.context("an effort experiment has its plant")?;
    let config = EffortConfig {
        learner: exp.config.clone(),
        plant: plan.plant,
        effort_weight: plan.effort_weight,
    };
    let progress = |_: &cps_cmaes::GenerationReport<'_>| ctx.generation();
    let outcome = ctx
        .pool
        .install(|| learn_with_effort(&config, &progress))
        .map_err(|e| learn_error(e, "effort run"))?;
    let mut complete = !outcome.search.interrupted();
    let speedup = if complete && plan.speedup_generations > 0 {
        let speedup = measure_speedup(&config, plan.speedup_generations, &progress)?;
        complete = speedup.is_some();
        speedup
    } else {
        None
    };
    ctx.bar.finish_and_clear();
    let peak = outcome
        .plant
        .force
        .iter()
        .flat_map(|f| f.iter())
        .fold(0.0f64, |a, &u| a.max(u.abs()));
    let summary = Summary {
        header: RunHeader::new(exp, complete, ctx.pool.current_num_threads(), wall()),
        plant: plan.plant,
        effort_weight: plan.effort_weight,
        cost: outcome.breakdown.total(),
        cost_terms: outcome.breakdown,
        start_cost: outcome.start.total(),
        start_cost_terms: outcome.start,
        goal_error_m: outcome.errors.goal,
        via_errors_m: &outcome.errors.via,
        max_position_error_m: outcome.errors.max_position_error(),
        final_speed_m_s: outcome.errors.final_speed,
        peak_force_n: peak,
        search: &outcome.search,
        learning_seconds: outcome.seconds,
        speedup,
    };
    stage.write("summary.json", &serde_json::to_vec_pretty(&summary)?)?;
    write_trajectory(stage, &outcome)?;
    if exp.plots {
        plot(stage, exp, &outcome)?;
    }
    write_report(stage, exp, &summary)?;
    let mut lines = vec![
        format!(
            "{}: {} in {:.2} s ({} generations)",
            exp.name,
            outcome.search.termination,
            wall(),
            outcome.search.generations
        ),
        format!(
            "  cost {:.6e} (start {:.6e}; control effort {:.4e}); the plant's goal error {:.3} mm, worst via-point error {:.3} mm; peak force {peak:.2} N",
            summary.cost,
            summary.start_cost,
            outcome.breakdown.effort,
            summary.goal_error_m * 1e3,
            outcome.errors.via.iter().fold(0.0f64, |a, &b| a.max(b)) * 1e3
        ),
    ];
    if let Some(s) = speedup {
        lines.push(format!(
            "  parallel speed-up: {} generations in {:.2} s on 1 thread, {:.2} s on 2 threads: {:.2}x ({})",
            s.generations,
            s.seconds_1_thread,
            s.seconds_2_threads,
            s.speedup,
            if s.identical_results {
                "identical results"
            } else {
                "RESULTS DIFFER"
            }
        ));
    }
    Ok(Finished {
        complete,
        failure: None,
        lines,
    })
}

/// Times `generations` generations of the same run on 1 and on 2 threads, three times each in
/// alternation, keeping the faster time of each (the usual guard against a busy machine),
/// and checks that every run found the same weights, bit for bit. `None` if interrupted.
fn measure_speedup(
    config: &EffortConfig,
    generations: u64,
    progress: &(dyn Fn(&cps_cmaes::GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<Option<Speedup>> {
    let mut short = config.clone();
    short.learner.generations = generations;
    short.learner.tol_fun = None;
    let pools = [1, 2].map(|threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .context("cannot start the worker threads")
    });
    let mut best = [f64::INFINITY; 2];
    let mut weights: Vec<Vec<f64>> = Vec::new();
    for _round in 0..3 {
        for (i, pool) in pools.iter().enumerate() {
            let pool = pool.as_ref().map_err(|e| anyhow::anyhow!("{e:#}"))?;
            let started = Instant::now();
            let o = pool
                .install(|| learn_with_effort(&short, progress))
                .map_err(|e| learn_error(e, "speed-up measurement"))?;
            if o.search.interrupted() {
                return Ok(None);
            }
            best[i] = best[i].min(started.elapsed().as_secs_f64());
            weights.push(o.weights);
        }
    }
    Ok(Some(Speedup {
        generations,
        seconds_1_thread: best[0],
        seconds_2_threads: best[1],
        speedup: best[0] / best[1],
        identical_results: weights.windows(2).all(|w| w[0] == w[1]),
    }))
}

fn write_trajectory(stage: &Staging, o: &EffortOutcome) -> Result<()> {
    let dims = o.reference.dims();
    let axes: Vec<String> = if dims == 3 {
        ["x", "y", "z"].map(String::from).to_vec()
    } else {
        (0..dims).map(|d| format!("y{d}")).collect()
    };
    let mut w = csv::Writer::from_path(stage.path("trajectory.csv"))?;
    let mut header = vec!["t".to_string()];
    for prefix in ["reference_", "plant_", "plant_v", "force_"] {
        header.extend(axes.iter().map(|a| format!("{prefix}{a}")));
    }
    w.write_record(&header)?;
    for (k, t) in o.reference.times().iter().enumerate() {
        let mut row = vec![format!("{t:.6}")];
        row.extend((0..dims).map(|d| format!("{:.9}", o.reference.position(d)[k])));
        for part in [&o.plant.position, &o.plant.velocity, &o.plant.force] {
            row.extend(part.iter().map(|a| format!("{:.9}", a[k])));
        }
        w.write_record(&row)?;
    }
    w.flush()?;
    write_history(stage, &[("plant", &o.search.history)])
}

fn plot(stage: &Staging, exp: &Experiment, o: &EffortOutcome) -> Result<()> {
    if !o.search.history.is_empty() {
        costs(
            stage,
            "cost",
            &[CostArm {
                label: "CMA-ES".into(),
                runs: vec![&o.search.history],
            }],
            None,
        )?;
    }
    let times = o.reference.times();
    let series = [
        Series {
            label: "DMP (the controller's reference)".into(),
            times,
            values: (0..o.reference.dims())
                .map(|d| o.reference.position(d))
                .collect(),
            faint: false,
        },
        Series {
            label: "plant".into(),
            times,
            values: o.plant.position.iter().map(Vec::as_slice).collect(),
            faint: false,
        },
    ];
    figures(
        stage,
        "coordinates",
        "path3d",
        &series,
        &way_points(&exp.config.task),
    )?;
    let names: Vec<String> = axis_names(o.reference.dims())
        .iter()
        .map(|n| n.replace("[m]", "force [N]"))
        .collect();
    panels(
        stage,
        "force",
        &names,
        &[Series {
            label: "PD control force".into(),
            times,
            values: o.plant.force.iter().map(Vec::as_slice).collect(),
            faint: false,
        }],
        &[],
    )
}

fn write_report(stage: &Staging, exp: &Experiment, s: &Summary<'_>) -> Result<()> {
    let mm = |v: f64| format!("{:.4} mm", v * 1e3);
    let mut rows = vec![
        (
            "plant",
            format!(
                "point mass {} kg per axis, PD gains K_p = {} N/m, K_v = {} N·s/m, {} substeps per sample",
                s.plant.mass, s.plant.kp, s.plant.kv, s.plant.substeps
            ),
        ),
        ("cost", format!("{:.6e}", s.cost)),
        (
            "control effort term",
            format!("{:.4e}", s.cost_terms.effort),
        ),
        ("cost at the start", format!("{:.6e}", s.start_cost)),
        ("goal error (plant)", mm(s.goal_error_m)),
        ("worst via-point error (plant)", mm(s.max_position_error_m)),
        ("peak force", format!("{:.2} N", s.peak_force_n)),
        search_row(s.search),
        ("learning time", format!("{:.2} s", s.learning_seconds)),
    ];
    if let Some(p) = &s.speedup {
        rows.push((
            "parallel speed-up",
            format!(
                "{:.2}x: {} generations in {:.2} s on 1 thread, {:.2} s on 2 ({})",
                p.speedup,
                p.generations,
                p.seconds_1_thread,
                p.seconds_2_threads,
                if p.identical_results {
                    "identical results"
                } else {
                    "results differ"
                }
            ),
        ));
    }
    report::write(
        stage,
        &s.header,
        &format!("{}: via points with a control-effort cost", exp.name),
        "The DMP is the reference of a PD controller driving a point mass per axis; the via points, the goal and the final velocity are judged on what the plant did, and the controller's squared force is penalised (thesis eq. 53/54).",
        &[Table::pairs("Result", rows)],
        &[
            (
                "coordinates",
                "The DMP (reference) and the plant per coordinate; dots are the way points.",
            ),
            ("force", "The PD controller's force per axis."),
            ("path3d", "Paths in 3-D."),
            ("cost", "Best cost so far per generation."),
        ],
    )
}
