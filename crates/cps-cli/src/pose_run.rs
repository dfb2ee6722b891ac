//! `kind = "viapoint_pose"`: via-point learning of the tool's position and orientation.

use anyhow::{Context, Result};
use cps_learn::{OrientationCostBreakdown, PoseConfig, PoseOutcome, learn_pose};
use serde::Serialize;

use crate::experiment::Experiment;
use crate::output::Staging;
use crate::plots::{CostArm, Series, costs, figures, panels, trajectory_series, way_points};
use crate::report::{self, Table};
use crate::runner::{Finished, RunContext, RunHeader, learn_error, search_row, write_history};

#[derive(Serialize)]
struct Summary<'a> {
    #[serde(flatten)]
    header: RunHeader<'a>,
    position_cost: f64,
    position_gap_to_optimum: f64,
    goal_error_m: f64,
    via_errors_m: &'a [f64],
    orientation_cost: f64,
    orientation_cost_terms: OrientationCostBreakdown,
    orientation_start_cost: f64,
    goal_angle_deg: f64,
    via_angles_deg: Vec<Option<f64>>,
    final_angular_speed_rad_s: f64,
    orientation_search: &'a cps_learn::SearchStats,
    orientation_seconds: f64,
}

/// Learns position and orientation and writes everything into `stage`.
pub fn run(
    exp: &Experiment,
    ctx: &RunContext<'_>,
    stage: &Staging,
    wall: &dyn Fn() -> f64,
) -> Result<Finished> {
    let plan = exp
        .pose
        .as_ref()
        .context("a pose experiment has its orientations")?;
    let config = PoseConfig {
        learner: exp.config.clone(),
        start_orientation: plan.start,
        goal_orientation: plan.goal,
        via_orientations: plan.via.clone(),
        orientation_sigma0: plan.sigma0,
    };
    let progress = |_: usize, _: &cps_cmaes::GenerationReport<'_>| ctx.generation();
    let outcome = ctx
        .pool
        .install(|| learn_pose(&config, &progress))
        .map_err(|e| learn_error(e, "pose run"))?;
    ctx.bar.finish_and_clear();
    let o = &outcome.orientation;
    let best = outcome.position.best();
    let complete = !outcome.position.interrupted() && !o.search.interrupted();
    let summary = Summary {
        header: RunHeader::new(exp, complete, ctx.pool.current_num_threads(), wall()),
        position_cost: best.cost,
        position_gap_to_optimum: best.gap_to_optimum,
        goal_error_m: best.errors.goal,
        via_errors_m: &best.errors.via,
        orientation_cost: o.breakdown.total(),
        orientation_cost_terms: o.breakdown,
        orientation_start_cost: o.start.total(),
        goal_angle_deg: o.errors.goal.to_degrees(),
        via_angles_deg: o
            .errors
            .via
            .iter()
            .map(|a| a.map(f64::to_degrees))
            .collect(),
        final_angular_speed_rad_s: o.errors.final_angular_speed,
        orientation_search: &o.search,
        orientation_seconds: o.seconds,
    };
    stage.write("summary.json", &serde_json::to_vec_pretty(&summary)?)?;
    write_trajectory(stage, &outcome)?;
    if exp.plots {
        plot(stage, exp, &outcome, &config)?;
    }
    write_report(stage, exp, &summary)?;
    let worst = |v: &[Option<f64>]| v.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
    Ok(Finished {
        failure: None,
        complete,
        lines: vec![
            format!(
                "{}: position and orientation learned in {:.2} s",
                exp.name,
                wall()
            ),
            format!(
                "  position: cost {:.6e} (gap to the exact optimum {:.2e}), goal error {:.3} mm, worst via-point error {:.3} mm",
                best.cost,
                best.gap_to_optimum,
                best.errors.goal * 1e3,
                best.errors.via.iter().fold(0.0f64, |a, &b| a.max(b)) * 1e3
            ),
            format!(
                "  orientation: cost {:.6e} (from {:.6e}), goal off by {:.3}°, worst via orientation off by {:.3}° ({} generations, {})",
                summary.orientation_cost,
                summary.orientation_start_cost,
                summary.goal_angle_deg,
                worst(&summary.via_angles_deg),
                o.search.generations,
                o.search.termination
            ),
        ],
    })
}

fn write_trajectory(stage: &Staging, outcome: &PoseOutcome) -> Result<()> {
    let p = outcome.position.best_trajectory();
    let o = &outcome.orientation.trajectory;
    let mut w = csv::Writer::from_path(stage.path("trajectory.csv"))?;
    w.write_record(["t", "x", "y", "z", "qx", "qy", "qz", "qw", "wx", "wy", "wz"])?;
    for (k, t) in p.times().iter().enumerate() {
        let q = o.orientation[k];
        let om = o.angular_velocity[k];
        let mut row = vec![format!("{t:.6}")];
        row.extend((0..3).map(|d| format!("{:.9}", p.position(d)[k])));
        row.extend([q.i, q.j, q.k, q.w].map(|v| format!("{v:.12}")));
        row.extend([om.x, om.y, om.z].map(|v| format!("{v:.9}")));
        w.write_record(&row)?;
    }
    w.flush()?;
    write_history(
        stage,
        &[
            ("position", &outcome.position.best().history),
            ("orientation", &outcome.orientation.search.history),
        ],
    )
}

fn plot(
    stage: &Staging,
    exp: &Experiment,
    outcome: &PoseOutcome,
    config: &PoseConfig,
) -> Result<()> {
    let histories: Vec<CostArm<'_>> = [
        ("position", &outcome.position.best().history),
        ("orientation", &outcome.orientation.search.history),
    ]
    .into_iter()
    .filter(|(_, h)| !h.is_empty())
    .map(|(label, h)| CostArm {
        label: label.into(),
        runs: vec![h.as_slice()],
    })
    .collect();
    if !histories.is_empty() {
        costs(stage, "cost", &histories, None)?;
    }
    let p = outcome.position.best_trajectory();
    figures(
        stage,
        "coordinates",
        "path3d",
        &[trajectory_series("", &p)],
        &way_points(&exp.config.task),
    )?;
    // The orientation as quaternion components, with the targets (sign-aligned with the
    // trajectory, since q and −q are the same orientation).
    let o = &outcome.orientation.trajectory;
    let comps: [Vec<f64>; 4] = [
        o.orientation.iter().map(|q| q.i).collect(),
        o.orientation.iter().map(|q| q.j).collect(),
        o.orientation.iter().map(|q| q.k).collect(),
        o.orientation.iter().map(|q| q.w).collect(),
    ];
    let mut marks = Vec::new();
    let mut mark = |t: f64, q: &nalgebra::UnitQuaternion<f64>| {
        let (k, _) = cps_dmp::locate_on_grid(&o.times, t);
        let sign = if o.orientation[k].coords.dot(&q.coords) < 0.0 {
            -1.0
        } else {
            1.0
        };
        marks.push((t, q.coords.iter().map(|c| sign * c).collect::<Vec<f64>>()));
    };
    mark(0.0, &config.start_orientation);
    for (v, q) in exp.config.task.via.iter().zip(&config.via_orientations) {
        if let Some(q) = q {
            mark(v.time, q);
        }
    }
    mark(exp.config.task.dmp.tau, &config.goal_orientation);
    let names: Vec<String> = ["qx", "qy", "qz", "qw"].map(String::from).to_vec();
    panels(
        stage,
        "orientation",
        &names,
        &[Series {
            label: "orientation (unit quaternion)".into(),
            times: &o.times,
            values: comps.iter().map(Vec::as_slice).collect(),
            faint: false,
        }],
        &marks,
    )
}

fn write_report(stage: &Staging, exp: &Experiment, s: &Summary<'_>) -> Result<()> {
    let mut rows = vec![(
        "position",
        format!(
            "cost {:.6e} (gap to the exact optimum {:.2e}); goal error {:.4} mm",
            s.position_cost,
            s.position_gap_to_optimum,
            s.goal_error_m * 1e3
        ),
    )];
    for (i, e) in s.via_errors_m.iter().enumerate() {
        rows.push(("via-point error", format!("p{}: {:.4} mm", i + 1, e * 1e3)));
    }
    rows.push((
        "orientation",
        format!(
            "cost {:.6e} (zero weights: {:.6e}); goal off by {:.4}°",
            s.orientation_cost, s.orientation_start_cost, s.goal_angle_deg
        ),
    ));
    for (i, a) in s.via_angles_deg.iter().enumerate() {
        rows.push((
            "via orientation",
            match a {
                Some(a) => format!("p{}: off by {a:.4}°", i + 1),
                None => format!("p{}: free", i + 1),
            },
        ));
    }
    rows.push(search_row(s.orientation_search));
    rows.push((
        "orientation learning time",
        format!("{:.2} s", s.orientation_seconds),
    ));
    report::write(
        stage,
        &s.header,
        &format!("{}: position and orientation through via points", exp.name),
        "Three DMPs carry the tool's position and one orientation DMP on unit quaternions its orientation; each part is learned against its via-point targets.",
        &[Table::pairs("Result", rows)],
        &[
            (
                "coordinates",
                "Position per coordinate; dots are the way points.",
            ),
            (
                "orientation",
                "Orientation as unit-quaternion components; dots are the orientation targets.",
            ),
            ("path3d", "The path in 3-D."),
            ("cost", "Best cost so far per generation."),
        ],
    )
}
