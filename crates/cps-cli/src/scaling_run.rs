//! `kind = "scaling"`: the thesis's comparison of search spaces (weights scaled by eq. 55
//! vs not scaled), each learned over the same repetitions, with bands and a verdict.

use std::ops::ControlFlow;
use std::sync::atomic::Ordering;

use anyhow::Result;
use cps_learn::{Parametrisation, ViaPointOutcome, learn_via_points};
use serde::Serialize;

use crate::experiment::Experiment;
use crate::output::Staging;
use crate::plots::{CostArm, Series, costs, figures, way_points};
use crate::report::{self, Table};
use crate::runner::{Finished, RunContext, RunHeader};

/// One arm of the comparison.
struct Arm {
    /// The search space.
    parametrisation: Parametrisation,
    /// Its repetitions.
    outcome: ViaPointOutcome,
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

/// Runs every arm (the same seeds for each) and writes the results into `stage`.
pub fn run(
    exp: &Experiment,
    ctx: &RunContext<'_>,
    stage: &Staging,
    wall: &dyn Fn() -> f64,
) -> Result<Finished> {
    let plan = exp
        .scaling
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("a scaling experiment has its arms"))?;
    let mut arms = Vec::new();
    for (i, &p) in plan.compare.iter().enumerate() {
        let mut config = exp.config.clone();
        config.parametrisation = p;
        ctx.bar
            .set_message(format!("{} ({}/{})", p.name(), i + 1, plan.compare.len()));
        let progress = |_rep: usize, _r: &cps_cmaes::GenerationReport<'_>| {
            ctx.bar.inc(1);
            if ctx.interrupted.load(Ordering::Relaxed) {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        };
        let outcome = ctx.pool.install(|| learn_via_points(&config, &progress))?;
        let stop = outcome.interrupted();
        arms.push(Arm {
            parametrisation: p,
            outcome,
        });
        if stop {
            break;
        }
    }
    ctx.bar.finish_and_clear();
    let verdict = verdict(&arms);
    write(
        exp,
        &arms,
        &verdict,
        stage,
        ctx.pool.current_num_threads(),
        wall(),
    )?;
    Ok(Finished {
        failure: None,
        complete: !arms.iter().any(|a| a.outcome.interrupted()),
        lines: vec![
            format!(
                "{}: {} search spaces compared in {:.2} s",
                exp.name,
                arms.len(),
                wall()
            ),
            format!("  {verdict}"),
        ],
    })
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

fn final_costs(arm: &Arm) -> Vec<f64> {
    arm.outcome.runs.iter().map(|r| r.cost).collect()
}

/// A plain-words verdict for every pair of arms, in the order of the file: which ended
/// lower, by what factor, and whether the 95 % bands of the final costs separate them.
fn verdict(arms: &[Arm]) -> String {
    if arms.len() < 2 {
        return "only one search space was run: nothing to compare".into();
    }
    let stats: Vec<(f64, f64, f64)> = arms.iter().map(|a| band(&final_costs(a))).collect();
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

#[derive(Serialize)]
struct Summary<'a> {
    #[serde(flatten)]
    header: RunHeader<'a>,
    repetitions: usize,
    generations: u64,
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

fn write(
    exp: &Experiment,
    arms: &[Arm],
    verdict: &str,
    stage: &Staging,
    threads: usize,
    wall_time_s: f64,
) -> Result<()> {
    let complete = !arms.iter().any(|a| a.outcome.interrupted())
        && arms.len() == exp.scaling.as_ref().map_or(0, |s| s.compare.len());
    let summary = Summary {
        header: RunHeader::new(exp, complete, threads, wall_time_s),
        repetitions: exp.config.repetitions,
        generations: exp.config.generations,
        optimum_cost: arms.first().map_or(f64::NAN, |a| a.outcome.optimum.cost),
        verdict,
        arms: arms
            .iter()
            .map(|a| {
                let c = final_costs(a);
                let (m, lo, hi) = band(&c);
                ArmSummary {
                    parametrisation: a.parametrisation.name(),
                    final_cost_mean: m,
                    final_cost_band_95: (lo, hi),
                    mean_gap_to_optimum: a
                        .outcome
                        .runs
                        .iter()
                        .map(|r| r.gap_to_optimum)
                        .sum::<f64>()
                        / a.outcome.runs.len() as f64,
                    max_position_error_m: a
                        .outcome
                        .runs
                        .iter()
                        .map(|r| r.errors.max_position_error())
                        .collect(),
                    seconds: a.outcome.runs.iter().map(|r| r.seconds).collect(),
                    final_costs: c,
                }
            })
            .collect(),
    };
    stage.write("summary.json", &serde_json::to_vec_pretty(&summary)?)?;

    let mut w = csv::Writer::from_path(stage.path("cost_history.csv"))?;
    w.write_record([
        "parametrisation",
        "repetition",
        "generation",
        "best",
        "best_so_far",
        "sigma",
    ])?;
    for a in arms {
        for (rep, run) in a.outcome.runs.iter().enumerate() {
            for h in &run.history {
                w.write_record([
                    a.parametrisation.name().to_string(),
                    rep.to_string(),
                    h.generation.to_string(),
                    format!("{:e}", h.best),
                    format!("{:e}", h.best_so_far),
                    format!("{:e}", h.sigma),
                ])?;
            }
        }
    }
    w.flush()?;

    // Mean and 95 % band of the trajectories, per arm.
    let bands: Vec<TrajectoryBand> = arms.iter().map(TrajectoryBand::of).collect();
    let dims = exp.config.task.start.len();
    let axis = |d: usize| {
        if dims == 3 {
            ["x", "y", "z"][d].to_string()
        } else {
            format!("y{d}")
        }
    };
    let mut w = csv::Writer::from_path(stage.path("trajectory_bands.csv"))?;
    let mut header = vec!["parametrisation".to_string(), "t".to_string()];
    for part in ["mean", "lo", "hi"] {
        header.extend((0..dims).map(|d| format!("{}_{part}", axis(d))));
    }
    w.write_record(&header)?;
    for b in &bands {
        for (k, t) in b.times.iter().enumerate() {
            let mut row = vec![b.name.to_string(), format!("{t:.6}")];
            for part in &b.curves {
                row.extend(part.iter().map(|d| format!("{:.9}", d[k])));
            }
            w.write_record(&row)?;
        }
    }
    w.flush()?;

    if exp.plots {
        let named: Vec<CostArm<'_>> = arms
            .iter()
            .map(|a| CostArm::of(a.parametrisation.name(), &a.outcome))
            .collect();
        costs(
            stage,
            "cost",
            &named,
            arms.first().map(|a| a.outcome.optimum.cost),
        )?;
        if dims == 3 {
            let mut series = Vec::new();
            for b in &bands {
                series.push(Series {
                    label: format!("{}: mean", b.name),
                    times: &b.times,
                    values: b.curves[0].iter().map(Vec::as_slice).collect(),
                    faint: false,
                });
                for part in &b.curves[1..] {
                    series.push(Series {
                        label: "95 % bands".into(),
                        times: &b.times,
                        values: part.iter().map(Vec::as_slice).collect(),
                        faint: true,
                    });
                }
            }
            figures(
                stage,
                "coordinates",
                "path3d",
                &series,
                &way_points(&exp.config.task),
            )?;
        }
    }
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
                format!(
                    "{:.3} mm",
                    a.max_position_error_m.iter().fold(0.0f64, |x, &y| x.max(y)) * 1e3
                ),
            ]
        })
        .collect();
    report::write(
        stage,
        &summary.header,
        &format!("{}: does weight scaling help?", exp.name),
        &format!(
            "Each search space learns the same via-point task {} times ({} generations, the same seeds); costs are compared with the exact optimum ({:.4}).",
            exp.config.repetitions, exp.config.generations, summary.optimum_cost
        ),
        &[
            Table::pairs("Verdict", vec![("verdict", verdict.to_string())]),
            Table {
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
        &[
            (
                "cost",
                "Best cost so far per generation: mean and 95 % band over the repetitions, per search space.",
            ),
            (
                "coordinates",
                "Mean trajectory and its 95 % band per search space; dots are the way points.",
            ),
            ("path3d", "Mean paths in 3-D."),
        ],
    )?;
    Ok(())
}
