//! `kind = "promp"`: the imitation pipeline, then a ProMP of its executed demonstrations
//! (the spread the averaging throws away): its mean ± 2σ band, the ProMP conditioned on a
//! new via point (`[promp.via]`), and the conditioned mean executed on the robot.

use cps_dmp::Trajectory;
use cps_robot::Recording;
use serde::Serialize;

use super::Ctx;
use super::clearance::KeptClearSummary;
use super::imitation::{declare, pipeline};
use super::learn_error;
use crate::ExperimentError;
use cps_movement::promp::{Conditioned, NamedProMp, ViaPoints, condition, fit_demos};
use cps_outcome::outcome::{Column, Document, Format, Outcome, ReportTable, Table};

#[derive(Serialize)]
struct Summary {
    basis_functions: usize,
    demonstrations: usize,
    duration_s: f64,
    /// Mean standard deviation over the movement, per axis.
    mean_std_m: Vec<f64>,
    /// Largest standard deviation over the movement, per axis.
    max_std_m: Vec<f64>,
    notes: Vec<String>,
    via: Via,
    /// The conditioned mean (with `[clearance]`, the movement kept clear) as the robot
    /// executed it.
    executed: Option<Executed>,
    /// With `[clearance]`: the movement executed instead of the mean, the most likely of
    /// the conditioned ProMP that keeps the clearance on the model.
    #[serde(skip_serializing_if = "Option::is_none")]
    kept_clear: Option<KeptClearSummary>,
    model: &'static str,
    conditioned_model: &'static str,
}

#[derive(Serialize)]
struct Via {
    time_s: f64,
    position_m: Vec<f64>,
    std_m: f64,
    prior_mean_m: Vec<f64>,
    prior_std_m: Vec<f64>,
    /// How far outside the demonstrated spread the via point lies, in prior σ.
    prior_sigmas: f64,
    conditioned_mean_m: Vec<f64>,
    conditioned_std_m: Vec<f64>,
    /// Distance of the conditioned mean from the via point at its time.
    mean_error_m: f64,
}

#[derive(Serialize)]
struct Executed {
    max_position_error_m: f64,
    rms_position_error_m: f64,
    /// The closest the executed tool came to the via point (the controller reaches each
    /// target one control period after it is commanded).
    via_error_m: f64,
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// Runs the pipeline, then the ProMP stage, and declares both.
pub(crate) fn run(
    ctx: &Ctx<'_>,
    plan: &crate::plan::ProMpPlan,
) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let mut run = pipeline(ctx)?;
    let mut outcome = declare(ctx, &run)?;
    let raw: Vec<(Vec<f64>, Vec<Vec<f64>>)> = run
        .outcome
        .kept()
        .filter_map(|d| d.recording.as_ref())
        .map(|r| {
            (
                r.time.clone(),
                r.position.iter().map(|p| p.to_vec()).collect(),
            )
        })
        .collect();
    if raw.len() < 2 {
        outcome.lines.push(format!(
            "  no ProMP: {} demonstration(s) executed, at least 2 are needed",
            raw.len()
        ));
        return Ok(outcome);
    }
    let labels: Vec<String> = run
        .outcome
        .kept()
        .map(|d| format!("demonstration {}", d.index))
        .collect();
    let names: Vec<String> = AXES.iter().map(|s| s.to_string()).collect();
    let tau = exp.config.task.dmp.tau;
    let fitted = fit_demos(raw, names, &labels, plan.bases, Some(tau))?;
    let via = ViaPoints {
        at: vec![plan.time],
        positions: vec![plan.position.clone()],
        stds: vec![plan.std],
        ..ViaPoints::default()
    };
    let cond = condition(fitted.promp.clone(), &via)?;
    let dt = exp.config.task.dmp.dt;
    let times = cond.posterior.grid(dt, 12)?;
    let mut traj = mean_trajectory(&cond.posterior, &times);
    let going = outcome.header.complete && outcome.header.failure.is_none();
    // With [clearance]: the most likely movement of the conditioned ProMP that keeps it,
    // on the model, instead of its mean.
    let kept = match &exp.clearance {
        Some(k) if going => {
            let p = &cond.posterior.promp;
            let dt = run.backend.dt();
            let targets = |w: &[f64]| cps_learn::targets_at(&trajectory_of(p, w, &times), dt).1;
            let keep = cps_learn::KeepClear {
                clearance: &k.clearance,
                robot: &run.config.robot,
                dt,
                iterations: k.iterations,
            };
            let kept = ctx
                .pool
                .install(|| {
                    cps_learn::keep_likely_clear(
                        &keep,
                        p.weight_mean(),
                        p.weight_cov(),
                        &targets,
                        &|r| ctx.generation(r),
                    )
                })
                .map_err(|e| learn_error(e, "keeping the conditioned ProMP clear"))?;
            traj = trajectory_of(p, &kept.theta, &times);
            Some(KeptClearSummary::new(&kept))
        }
        _ => None,
    };
    // Execute the conditioned mean unless the pipeline stopped early.
    let executed = if going {
        let robot = &run.config.robot;
        match cps_learn::execute_trajectory(run.backend.as_mut(), robot, &traj, ctx.stop) {
            Ok(r) => Some(r),
            Err(e) => {
                outcome.header.complete = false;
                outcome.header.failure = Some(format!("executing the conditioned ProMP: {e}"));
                None
            }
        }
    } else {
        None
    };
    let mut summary = summarise(&fitted.promp, &cond, &fitted.notes, executed.as_ref(), plan);
    summary.kept_clear = kept;
    outcome.lines.extend(lines(&summary));
    outcome.report.tables.push(report_table(&summary));
    outcome.summary.insert(
        "promp".into(),
        serde_json::to_value(&summary).map_err(|e| ExperimentError::Message(e.to_string()))?,
    );
    outcome.figures.push(fitted.figure());
    outcome.figures.push(cond.figure());
    let grid = fitted.promp.grid(dt, 7)?;
    let mut stats = fitted.promp.stats_table(&grid);
    stats.name = "promp_stats".into();
    let mut conditioned = cond.posterior.stats_table(&grid);
    conditioned.name = "promp_conditioned".into();
    outcome.tables.push(stats);
    outcome.tables.push(conditioned);
    if let Some(r) = &executed {
        outcome.tables.push(recording_table(r));
    }
    outcome.documents.push(Document::text(
        "promp.json".to_string(),
        fitted.promp.to_json(),
    ));
    outcome.documents.push(Document::text(
        "promp_conditioned.json".to_string(),
        cond.posterior.to_json(),
    ));
    Ok(outcome)
}

/// The ProMP's mean over `times` as a trajectory: positions and velocities from the
/// basis, accelerations by central differences of the velocities.
fn mean_trajectory(p: &NamedProMp, times: &[f64]) -> Trajectory {
    trajectory_of(&p.promp, p.promp.weight_mean(), times)
}

/// The ProMP's movement of weights `w` at `times`: positions `Φ w`, velocities `Φ̇ w`,
/// accelerations by differences of the velocities.
/// (The products are cps-promp's, compiled optimised: a search calls this per candidate.)
fn trajectory_of(p: &cps_promp::ProMp, w: &[f64], times: &[f64]) -> Trajectory {
    let n = times.len();
    let (m, v) = p
        .path(w, times)
        .expect("the weights are the ProMP's own (its mean or a search over them)");
    let (mut pos, mut vel) = (vec![vec![0.0; n]; 3], vec![vec![0.0; n]; 3]);
    for k in 0..n {
        for d in 0..3 {
            pos[d][k] = m[k * 3 + d];
            vel[d][k] = v[k * 3 + d];
        }
    }
    let acc = vel
        .iter()
        .map(|v| {
            (0..n)
                .map(|k| {
                    let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                    (v[b] - v[a]) / (times[b] - times[a])
                })
                .collect()
        })
        .collect::<Vec<Vec<f64>>>();
    Trajectory::from_parts(times.to_vec(), &pos, &vel, &acc)
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

fn summarise(
    prior: &NamedProMp,
    cond: &Conditioned,
    notes: &[String],
    executed: Option<&Recording>,
    plan: &crate::plan::ProMpPlan,
) -> Summary {
    let grid: Vec<f64> = (0..=200)
        .map(|k| prior.promp.duration() * k as f64 / 200.0)
        .collect();
    let stats = prior.promp.stats(&grid);
    let per_axis = |f: &dyn Fn(usize) -> f64| (0..3).map(f).collect::<Vec<f64>>();
    let at = [plan.time];
    let (m0, s0) = prior.promp.stats(&at).remove(0);
    let (m1, s1) = cond.posterior.promp.stats(&at).remove(0);
    let prior_sigmas = (0..3)
        .map(|d| {
            (plan.position[d] - m0[d]).abs()
                / (s0[d] * s0[d] + plan.std * plan.std).sqrt().max(1e-300)
        })
        .fold(0.0, f64::max);
    let executed = executed.map(|r| Executed {
        max_position_error_m: r.max_position_error(),
        rms_position_error_m: r.rms_position_error(),
        via_error_m: r
            .position
            .iter()
            .map(|p| distance(p, &plan.position))
            .fold(f64::INFINITY, f64::min),
    });
    Summary {
        basis_functions: prior.promp.bases(),
        demonstrations: prior.demonstrations,
        duration_s: prior.promp.duration(),
        mean_std_m: per_axis(&|d| {
            stats.iter().map(|(_, s)| s[d]).sum::<f64>() / stats.len() as f64
        }),
        max_std_m: per_axis(&|d| stats.iter().map(|(_, s)| s[d]).fold(0.0, f64::max)),
        notes: notes.to_vec(),
        via: Via {
            time_s: plan.time,
            position_m: plan.position.clone(),
            std_m: plan.std,
            mean_error_m: distance(&m1, &plan.position),
            prior_mean_m: m0,
            prior_std_m: s0,
            prior_sigmas,
            conditioned_mean_m: m1,
            conditioned_std_m: s1,
        },
        executed,
        kept_clear: None,
        model: "promp.json",
        conditioned_model: "promp_conditioned.json",
    }
}

fn lines(s: &Summary) -> Vec<String> {
    let mm = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{:.1}", x * 1e3))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut out = vec![
        format!(
            "  ProMP of {} executed demonstrations ({} basis functions): mean σ ({}) mm, largest ({}) mm",
            s.demonstrations,
            s.basis_functions,
            mm(&s.mean_std_m),
            mm(&s.max_std_m)
        ),
        format!(
            "  conditioned on ({}) mm at {} s ({:.1} σ from the demonstrated mean): its mean passes within {:.3} mm",
            mm(&s.via.position_m),
            s.via.time_s,
            s.via.prior_sigmas,
            s.via.mean_error_m * 1e3
        ),
    ];
    if let Some(k) = &s.kept_clear {
        out.push(k.line("the conditioned ProMP's most likely movement"));
    }
    if let Some(e) = &s.executed {
        out.push(format!(
            "  {} executed within {:.3} mm, passing {:.3} mm from the via point",
            if s.kept_clear.is_some() {
                "the movement kept clear"
            } else {
                "conditioned mean"
            },
            e.max_position_error_m * 1e3,
            e.via_error_m * 1e3
        ));
    }
    out
}

fn report_table(s: &Summary) -> ReportTable {
    let mm = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{:.2}", x * 1e3))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut rows = vec![
        ("demonstrations", s.demonstrations.to_string()),
        ("basis functions", s.basis_functions.to_string()),
        ("mean σ (x, y, z) [mm]", mm(&s.mean_std_m)),
        ("largest σ (x, y, z) [mm]", mm(&s.max_std_m)),
        (
            "via point [mm] at [s]",
            format!("({}) at {}", mm(&s.via.position_m), s.via.time_s),
        ),
        ("prior mean there [mm]", mm(&s.via.prior_mean_m)),
        ("prior σ there [mm]", mm(&s.via.prior_std_m)),
        ("conditioned mean there [mm]", mm(&s.via.conditioned_mean_m)),
        ("conditioned σ there [mm]", mm(&s.via.conditioned_std_m)),
    ];
    if let Some(e) = &s.executed {
        rows.push((
            "executed: max tracking error / closest to the via point [mm]",
            format!(
                "{:.3} / {:.3}",
                e.max_position_error_m * 1e3,
                e.via_error_m * 1e3
            ),
        ));
    }
    ReportTable::pairs("ProMP of the executed demonstrations", rows)
}

/// `promp_executed.csv`: the robot's recording of the conditioned mean.
fn recording_table(r: &Recording) -> Table {
    let axis = |d: usize| r.position.iter().map(|p| p[d]).collect();
    Table::new("promp_executed")
        .with(Column::numbers("t", r.time.clone(), Format::Plain))
        .with(Column::numbers("x", axis(0), Format::Plain))
        .with(Column::numbers("y", axis(1), Format::Plain))
        .with(Column::numbers("z", axis(2), Format::Plain))
        .with(Column::numbers(
            "position_error",
            r.position_error.clone(),
            Format::ShortestSci,
        ))
}
