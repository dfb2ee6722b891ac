//! `kind = "scaling"`: the thesis's comparison of search spaces (weights scaled by eq. 55
//! vs not scaled), each learned over the same repetitions, with bands and a verdict.

use cps_learn::{Parametrisation, ViaPointOutcome, learn_via_points};
use serde::Serialize;

use super::Ctx;
use super::{cost_figure, learn_error, position_figures_with, way_points, worst};
use crate::ExperimentError;
use crate::observer::Event;
use cps_outcome::outcome::{
    Band, Column, Figure, Format, Outcome, Report, ReportTable, Series, Table, fields,
};

/// One arm of the comparison.
struct Arm {
    /// The search space.
    parametrisation: Parametrisation,
    /// Its repetitions.
    outcome: ViaPointOutcome,
}

impl Arm {
    fn final_costs(&self) -> Vec<f64> {
        self.outcome.runs.iter().map(|r| r.cost).collect()
    }
}

/// Mean and 95 % band (1.96 · std / √n) of values.
fn band(values: &[f64]) -> (f64, f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = if values.len() > 1 {
        values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    let half = 1.96 * var.sqrt() / n.sqrt();
    (mean, mean - half, mean + half)
}

#[derive(Serialize)]
struct Summary<'a> {
    repetitions: usize,
    generations: u64,
    evaluation: &'static str,
    optimum_cost: f64,
    verdict: &'a str,
    arms: Vec<ArmSummary>,
}

#[derive(Serialize)]
struct ArmSummary {
    parametrisation: &'static str,
    final_cost_mean: f64,
    final_cost_band_95: (f64, f64),
    final_costs: Vec<f64>,
    mean_gap_to_optimum: f64,
    max_position_error_m: Vec<f64>,
    seconds: Vec<f64>,
}

/// Runs every arm (the same seeds for each) and declares the outcome.
pub(crate) fn run(
    ctx: &Ctx<'_>,
    plan: &crate::plan::ScalingPlan,
) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let mut arms = Vec::new();
    for (i, &p) in plan.compare.iter().enumerate() {
        let mut config = exp.config.clone();
        config.parametrisation = p;
        let stage = format!("{} ({}/{})", p.name(), i + 1, plan.compare.len());
        // Stopping is decided by the generations that follow.
        let _ = ctx.observer.event(Event::Stage(&stage));
        let progress = |_rep: usize, r: &cps_cmaes::GenerationReport<'_>| ctx.generation(r);
        let outcome = ctx
            .pool
            .install(|| learn_via_points(&config, &progress))
            .map_err(|e| learn_error(e, "scaling run"))?;
        let stop = outcome.interrupted();
        arms.push(Arm {
            parametrisation: p,
            outcome,
        });
        if stop {
            break;
        }
    }
    ctx.observer.finished();
    let verdict = verdict(&arms);
    let complete =
        !arms.iter().any(|a| a.outcome.interrupted()) && arms.len() == plan.compare.len();
    let summary = Summary {
        repetitions: exp.config.repetitions,
        generations: exp.config.generations,
        evaluation: arms
            .first()
            .map_or("rollout", |a| a.outcome.evaluation.name()),
        optimum_cost: arms.first().map_or(f64::NAN, |a| a.outcome.optimum.cost),
        verdict: &verdict,
        arms: arms.iter().map(arm_summary).collect(),
    };
    let bands: Vec<TrajectoryBand> = arms.iter().map(TrajectoryBand::of).collect();
    let lines = vec![
        format!(
            "{}: {} search spaces compared in {:.2} s",
            exp.name,
            arms.len(),
            ctx.wall()
        ),
        format!("  {verdict}"),
    ];
    Ok(Outcome {
        header: ctx.header(complete),
        report: report(ctx, &summary),
        summary: fields(&summary),
        tables: vec![history(&arms), bands_table(ctx, &bands)],
        figures: figures(ctx, &arms, &bands),
        documents: Vec::new(),
        lines,
    })
}

fn arm_summary(a: &Arm) -> ArmSummary {
    let c = a.final_costs();
    let (m, lo, hi) = band(&c);
    let runs = &a.outcome.runs;
    ArmSummary {
        parametrisation: a.parametrisation.name(),
        final_cost_mean: m,
        final_cost_band_95: (lo, hi),
        mean_gap_to_optimum: runs.iter().map(|r| r.gap_to_optimum).sum::<f64>() / runs.len() as f64,
        max_position_error_m: runs.iter().map(|r| r.errors.max_position_error()).collect(),
        seconds: runs.iter().map(|r| r.seconds).collect(),
        final_costs: c,
    }
}

/// Mean and 95 % band of an arm's trajectories over its repetitions.
struct TrajectoryBand {
    name: &'static str,
    times: Vec<f64>,
    /// `[mean, lower, upper][dimension][sample]`.
    curves: [Vec<Vec<f64>>; 3],
}

impl TrajectoryBand {
    fn of(arm: &Arm) -> Self {
        let o = &arm.outcome;
        let trajs: Vec<cps_dmp::Trajectory> =
            o.runs.iter().map(|r| o.dmp.rollout(&r.weights)).collect();
        let first = &trajs[0];
        let mut curves: [Vec<Vec<f64>>; 3] = Default::default();
        for d in 0..first.dims() {
            let mut per = [Vec::new(), Vec::new(), Vec::new()];
            for k in 0..first.n_samples() {
                let v: Vec<f64> = trajs.iter().map(|t| t.position(d)[k]).collect();
                let (m, lo, hi) = band(&v);
                per[0].push(m);
                per[1].push(lo);
                per[2].push(hi);
            }
            for (c, p) in curves.iter_mut().zip(per) {
                c.push(p);
            }
        }
        Self {
            name: arm.parametrisation.name(),
            times: first.times().to_vec(),
            curves,
        }
    }
}

/// A plain-words verdict for every pair of arms, in the order of the file: which ended
/// lower, by what factor, and whether the 95 % bands of the final costs separate them.
fn verdict(arms: &[Arm]) -> String {
    if arms.len() < 2 {
        return "only one search space was run: nothing to compare".into();
    }
    let stats: Vec<(f64, f64, f64)> = arms.iter().map(|a| band(&a.final_costs())).collect();
    let mut parts = Vec::new();
    for i in 0..arms.len() {
        for j in i + 1..arms.len() {
            let (a, b) = (
                arms[i].parametrisation.name(),
                arms[j].parametrisation.name(),
            );
            let (sa, sb) = (stats[i], stats[j]);
            let (win, lose, sw, sl) = if sa.0 <= sb.0 {
                (a, b, sa, sb)
            } else {
                (b, a, sb, sa)
            };
            let separated = sw.2 < sl.1;
            parts.push(format!(
                "{a} vs {b}: {win} ended lower, mean final cost {:.4} (95 % band {:.4} to {:.4}) against {lose}'s {:.4} ({:.4} to {:.4}), {:.2}x lower; {}",
                sw.0,
                sw.1,
                sw.2,
                sl.0,
                sl.1,
                sl.2,
                sl.0 / sw.0,
                if separated {
                    format!("the bands do not overlap, so {win} helped")
                } else {
                    format!(
                        "the bands overlap, so with {} repetitions the difference is not significant",
                        arms[i].outcome.runs.len()
                    )
                }
            ));
        }
    }
    parts.join(". ") + "."
}

/// `cost_history.csv`: one row per generation of each repetition of each arm.
fn history(arms: &[Arm]) -> Table {
    let (mut name, mut rep, mut generation, mut best, mut so_far, mut sigma) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for a in arms {
        for (r, run) in a.outcome.runs.iter().enumerate() {
            for h in &run.history {
                name.push(a.parametrisation.name().to_string());
                rep.push(r as u64);
                generation.push(h.generation);
                best.push(h.best);
                so_far.push(h.best_so_far);
                sigma.push(h.sigma);
            }
        }
    }
    Table::new("cost_history")
        .with(Column::texts("parametrisation", name))
        .with(Column::integers("repetition", rep))
        .with(Column::integers("generation", generation))
        .with(Column::numbers("best", best, Format::ShortestSci))
        .with(Column::numbers("best_so_far", so_far, Format::ShortestSci))
        .with(Column::numbers("sigma", sigma, Format::ShortestSci))
}

/// `trajectory_bands.csv`: per arm and sample, the mean and 95 % band of each coordinate.
fn bands_table(ctx: &Ctx<'_>, bands: &[TrajectoryBand]) -> Table {
    let dims = ctx.exp.config.task.start.len();
    let axis = |d: usize| {
        if dims == 3 {
            ["x", "y", "z"][d].to_string()
        } else {
            format!("y{d}")
        }
    };
    let rows = |b: &TrajectoryBand| b.times.len();
    let mut t = Table::new("trajectory_bands")
        .with(Column::texts(
            "parametrisation",
            bands
                .iter()
                .flat_map(|b| vec![b.name.to_string(); rows(b)])
                .collect(),
        ))
        .with(Column::numbers(
            "t",
            bands.iter().flat_map(|b| b.times.clone()).collect(),
            Format::Fixed(6),
        ));
    for (p, part) in ["mean", "lo", "hi"].iter().enumerate() {
        for d in 0..dims {
            t.push(Column::numbers(
                format!("{}_{part}", axis(d)),
                bands
                    .iter()
                    .flat_map(|b| b.curves[p][d].iter().copied())
                    .collect(),
                Format::Fixed(9),
            ));
        }
    }
    t
}

fn figures(ctx: &Ctx<'_>, arms: &[Arm], bands: &[TrajectoryBand]) -> Vec<Figure> {
    let task = &ctx.exp.config.task;
    let named = arms
        .iter()
        .map(|a| {
            let h: Vec<&[cps_learn::GenerationRecord]> = a
                .outcome
                .runs
                .iter()
                .map(|r| r.history.as_slice())
                .collect();
            super::cost_arm(a.parametrisation.name(), &h)
        })
        .collect();
    let mut figures: Vec<Figure> = cost_figure(
        "Best cost so far per generation: mean and 95 % band over the repetitions, per search space.",
        named,
        arms.first().map(|a| a.outcome.optimum.cost),
    )
    .into_iter()
    .collect();
    if task.start.len() == 3 {
        let mut series = Vec::new();
        let mut shaded = Vec::new();
        for b in bands {
            series.push(Series::new(
                format!("{}: mean", b.name),
                b.times.clone(),
                b.curves[0].clone(),
            ));
            shaded.push(Band {
                label: format!("{}: 95 % band", b.name),
                times: b.times.clone(),
                lower: b.curves[1].clone(),
                upper: b.curves[2].clone(),
            });
        }
        let mut position = position_figures_with(
            series,
            shaded,
            way_points(task),
            "Mean trajectory and its 95 % band (shaded) per search space, with the start, the via points p1… and the goal.",
            "Mean paths in 3-D.",
        );
        // The movement first, then the search.
        position.append(&mut figures);
        figures = position;
    }
    figures
}

fn report(ctx: &Ctx<'_>, summary: &Summary<'_>) -> Report {
    let exp = ctx.exp;
    let rows = summary
        .arms
        .iter()
        .map(|a| {
            vec![
                a.parametrisation.to_string(),
                format!("{:.4}", a.final_cost_mean),
                format!(
                    "{:.4} – {:.4}",
                    a.final_cost_band_95.0, a.final_cost_band_95.1
                ),
                format!("{:.2} %", a.mean_gap_to_optimum * 100.0),
                format!("{:.3} mm", worst(&a.max_position_error_m) * 1e3),
            ]
        })
        .collect();
    Report {
        title: format!("{}: does weight scaling help?", exp.name),
        context: format!(
            "Each search space learns the same via-point task {} times ({} generations, the same seeds); costs are compared with the exact optimum ({:.4}).",
            exp.config.repetitions, exp.config.generations, summary.optimum_cost
        ),
        tables: vec![
            ReportTable::pairs(
                "Verdict",
                summary
                    .verdict
                    .split(". ")
                    .map(|part| ("", part.trim_end_matches('.').to_string() + "."))
                    .collect(),
            ),
            ReportTable {
                title: "Final cost per search space".into(),
                header: [
                    "search space",
                    "mean final cost",
                    "95 % band",
                    "mean gap to optimum",
                    "worst way-point error",
                ]
                .map(String::from)
                .to_vec(),
                rows,
            },
        ],
    }
}
