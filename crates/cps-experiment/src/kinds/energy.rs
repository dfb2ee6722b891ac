//! `kind = "viapoint_energy"`: via-point learning through a simulated plant with the
//! control-effort term (thesis eq. 53/54): the exact optimum through the linear plant, or
//! CMA-ES judged against it.

use cps_learn::{EffortConfig, EffortCostBreakdown, EffortOutcome, learn_with_effort};
use serde::Serialize;

use super::{Ctx, learn_error};
use super::{
    axis_names, cost_figure, history_table, position_figures, search_figure, search_row,
    way_points, worst,
};
use crate::ExperimentError;
use cps_outcome::outcome::{
    Column, Figure, Format, Outcome, Panels, Plot, Report, ReportTable, Series, Table, fields,
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
    solver: &'static str,
    evaluation: Option<&'static str>,
    optimum_cost: f64,
    optimum_cost_terms: EffortCostBreakdown,
    gap_to_optimum: f64,
    hessian_condition: f64,
    search: &'a cps_learn::SearchStats,
    learning_seconds: f64,
}

/// Learns with the plant and declares the outcome.
pub(crate) fn run(
    ctx: &Ctx<'_>,
    plan: &crate::plan::EnergyPlan,
) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
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
    let complete = !outcome.search.interrupted();
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
        solver: config.learner.solver.name(),
        evaluation: (config.learner.solver == cps_learn::Solver::Cmaes)
            .then(|| o.evaluation.name()),
        optimum_cost: o.optimum.total(),
        optimum_cost_terms: o.optimum,
        gap_to_optimum: (o.breakdown.total() - o.optimum.total()) / o.optimum.total(),
        hessian_condition: o.hessian_condition,
        search: &o.search,
        learning_seconds: o.seconds,
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
    if config.learner.solver == cps_learn::Solver::Cmaes {
        lines.push(format!(
            "  the exact optimum through the plant costs {:.6e}: CMA-ES is {:.3} % above it",
            summary.optimum_cost,
            summary.gap_to_optimum * 100.0
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
        vec![super::cost_arm("CMA-ES", &[&o.search.history])],
        None,
    ));
    figures.extend(search_figure(&[("CMA-ES", &o.search.history)]));
    figures
}

fn report(ctx: &Ctx<'_>, s: &Summary<'_>) -> Report {
    let mm = |v: f64| format!("{:.4} mm", v * 1e3);
    let mut rows = vec![
        (
            "solver",
            match s.solver {
                "exact" => "the exact least-squares optimum through the plant (no search)".into(),
                _ => format!(
                    "CMA-ES, candidates evaluated by {}",
                    match s.evaluation {
                        Some("quadratic") =>
                            "the cost's exact quadratic form (the result by a simulation)",
                        _ => "simulating the plant",
                    }
                ),
            },
        ),
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
    if s.solver == "cmaes" {
        rows.push((
            "exact optimum",
            format!(
                "{:.6e} (the cost is quadratic in the weights: the plant is linear); CMA-ES {:.3} % above it",
                s.optimum_cost,
                s.gap_to_optimum * 100.0
            ),
        ));
    }
    Report {
        title: format!("{}: via points with a control-effort cost", ctx.exp.name),
        context: "The DMP is the reference of a PD controller driving a point mass per axis; the via points, the goal and the final velocity are judged on what the plant did, and the controller's squared force is penalised (thesis eq. 53/54).".into(),
        tables: vec![ReportTable::pairs("Result", rows)],
    }
}
