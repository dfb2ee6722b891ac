//! `kind = "viapoint_energy"`: via-point learning through a simulated plant with the
//! control-effort term (thesis eq. 53/54), and the measured parallel speed-up.

use std::ops::ControlFlow;
use std::time::Instant;

use cps_learn::{EffortConfig, EffortCostBreakdown, EffortOutcome, learn_with_effort};
use serde::Serialize;

use super::{Ctx, learn_error};
use super::{
    axis_names, cost_figure, history_table, position_figures, search_figure, search_row,
    way_points, worst,
};
use crate::ExperimentError;
use crate::observer::Event;
use crate::outcome::{
    Column, CostArm, Figure, Format, Outcome, Panels, Plot, Report, ReportTable, Series, Table,
    fields,
};

#[derive(Serialize)]
struct Summary<'a> {
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

/// The same generations timed on one thread and on two (the faster of three runs each).
#[derive(Serialize, Clone, Copy)]
struct Speedup {
    generations: u64,
    seconds_1_thread: f64,
    seconds_2_threads: f64,
    speedup: f64,
    identical_results: bool,
}

/// Learns with the plant, measures the speed-up if asked, declares the outcome.
pub(crate) fn run(ctx: &Ctx<'_>) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let plan = exp
        .energy
        .ok_or_else(|| ExperimentError::Message("an effort experiment has its plant".into()))?;
    let config = EffortConfig {
        learner: exp.config.clone(),
        plant: plan.plant,
        effort_weight: plan.effort_weight,
    };
    let progress = |r: &cps_cmaes::GenerationReport<'_>| ctx.generation(r);
    let outcome = ctx
        .pool
        .install(|| learn_with_effort(&config, &progress))
        .map_err(|e| learn_error(e, "effort run"))?;
    let mut complete = !outcome.search.interrupted();
    let speedup = if complete && plan.speedup_generations > 0 {
        let _ = ctx
            .observer
            .event(Event::Stage("measuring the parallel speed-up"));
        let working = |_: &cps_cmaes::GenerationReport<'_>| ctx.observer.event(Event::Working);
        let speedup = measure_speedup(&config, plan.speedup_generations, &working)?;
        complete = speedup.is_some();
        speedup
    } else {
        None
    };
    ctx.observer.finished();
    let o = &outcome;
    let peak = o
        .plant
        .force
        .iter()
        .flat_map(|f| f.iter())
        .fold(0.0f64, |a, &u| a.max(u.abs()));
    let summary = Summary {
        plant: plan.plant,
        effort_weight: plan.effort_weight,
        cost: o.breakdown.total(),
        cost_terms: o.breakdown,
        start_cost: o.start.total(),
        start_cost_terms: o.start,
        goal_error_m: o.errors.goal,
        via_errors_m: &o.errors.via,
        max_position_error_m: o.errors.max_position_error(),
        final_speed_m_s: o.errors.final_speed,
        peak_force_n: peak,
        search: &o.search,
        learning_seconds: o.seconds,
        speedup,
    };
    let mut lines = vec![
        format!(
            "{}: {} in {:.2} s ({} generations)",
            exp.name,
            o.search.termination,
            ctx.wall(),
            o.search.generations
        ),
        format!(
            "  cost {:.6e} (start {:.6e}; control effort {:.4e}); the plant's goal error {:.3} mm, worst via-point error {:.3} mm; peak force {peak:.2} N",
            summary.cost,
            summary.start_cost,
            o.breakdown.effort,
            summary.goal_error_m * 1e3,
            worst(&o.errors.via) * 1e3
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
    Ok(Outcome {
        header: ctx.header(complete),
        report: report(ctx, &summary),
        summary: fields(&summary),
        tables: vec![
            trajectory(o),
            history_table(&[("plant", &o.search.history)]),
        ],
        figures: figures(ctx, o),
        documents: Vec::new(),
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
) -> Result<Option<Speedup>, ExperimentError> {
    let mut short = config.clone();
    short.learner.generations = generations;
    short.learner.tol_fun = None;
    let mut pools = Vec::new();
    for threads in [1, 2] {
        pools.push(
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| ExperimentError::Failed {
                    context: "cannot start the worker threads".into(),
                    source: Box::new(e),
                })?,
        );
    }
    let mut best = [f64::INFINITY; 2];
    let mut weights: Vec<Vec<f64>> = Vec::new();
    for _round in 0..3 {
        for (i, pool) in pools.iter().enumerate() {
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

/// `trajectory.csv`: `t`, the reference `reference_x…`, the plant's position `plant_x…`
/// and velocity `plant_x_vel…`, the force `force_x…`.
fn trajectory(o: &EffortOutcome) -> Table {
    let dims = o.reference.dims();
    let axes: Vec<String> = (0..dims).map(|d| super::axis_name(dims, d)).collect();
    let mut t = Table::new("trajectory").with(Column::numbers(
        "t",
        o.reference.times().to_vec(),
        Format::Fixed(6),
    ));
    for (d, a) in axes.iter().enumerate() {
        t.push(Column::numbers(
            format!("reference_{a}"),
            o.reference.position(d).to_vec(),
            Format::Fixed(9),
        ));
    }
    for (prefix, suffix, part) in [
        ("plant_", "", &o.plant.position),
        ("plant_", "_vel", &o.plant.velocity),
        ("force_", "", &o.plant.force),
    ] {
        for (a, v) in axes.iter().zip(part) {
            t.push(Column::numbers(
                format!("{prefix}{a}{suffix}"),
                v.clone(),
                Format::Fixed(9),
            ));
        }
    }
    t
}

fn figures(ctx: &Ctx<'_>, o: &EffortOutcome) -> Vec<Figure> {
    let times = o.reference.times().to_vec();
    let dims = o.reference.dims();
    let series = vec![
        Series::new(
            "DMP (the controller's reference)",
            times.clone(),
            (0..dims)
                .map(|d| o.reference.position(d).to_vec())
                .collect(),
        ),
        Series::new("plant", times.clone(), o.plant.position.clone()),
    ];
    let mut figures = position_figures(
        series,
        way_points(&ctx.exp.config.task),
        "The DMP (reference) and the plant per coordinate, with the start, the via points p1… and the goal.",
        "Paths in 3-D.",
    );
    figures.insert(
        1,
        Figure {
            name: "force".into(),
            caption: "The PD controller's force per axis.".into(),
            plot: Plot::Panels(Panels::new(
                axis_names(dims)
                    .iter()
                    .map(|n| n.replace("[m]", "force [N]"))
                    .collect(),
                vec![Series::new(
                    "PD control force",
                    times,
                    o.plant.force.clone(),
                )],
            )),
        },
    );
    figures.extend(cost_figure(
        "Best cost so far per generation.",
        vec![CostArm::new("CMA-ES", &[&o.search.history])],
        None,
    ));
    figures.extend(search_figure(&[("CMA-ES", &o.search.history)]));
    figures
}

fn report(ctx: &Ctx<'_>, s: &Summary<'_>) -> Report {
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
    Report {
        title: format!("{}: via points with a control-effort cost", ctx.exp.name),
        context: "The DMP is the reference of a PD controller driving a point mass per axis; the via points, the goal and the final velocity are judged on what the plant did, and the controller's squared force is penalised (thesis eq. 53/54).".into(),
        tables: vec![ReportTable::pairs("Result", rows)],
    }
}
