//! `kind = "viapoint_pose"`: via-point learning of the tool's position and orientation.
//! With `[robot]` and `[clearance]`, the learned pose is then bent, position and
//! orientation together, on the robot's model following it, until every pair of shapes
//! keeps the clearance ([`cps_learn::keep_pose_clear`], the pose's own costs as its
//! anchor).

use cps_learn::{OrientationCostBreakdown, PoseConfig, PoseOutcome, learn_pose};
use serde::Serialize;

use super::clearance::KeptClearSummary;
use super::movement_files::movement_files;
use super::{Ctx, learn_error};
use super::{
    cost_figure, derivative_figure, history_table, position_figures, search_figure, search_row,
    way_points, worst,
};
use crate::ExperimentError;
use cps_outcome::outcome::{
    Column, Figure, Format, Mark, MarkKind, Outcome, Panels, Plot, Report, ReportTable, Series,
    Table, fields,
};

#[derive(Serialize)]
struct Summary<'a> {
    position_cost: f64,
    position_gap_to_optimum: f64,
    goal_error_m: f64,
    via_errors_m: &'a [f64],
    /// The closest the learned tool path comes to each obstacle (the task's, then the
    /// scene's).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    obstacle_distances_m: Vec<f64>,
    orientation_cost: f64,
    orientation_cost_terms: OrientationCostBreakdown,
    orientation_start_cost: f64,
    goal_angle_deg: f64,
    via_angles_deg: Vec<Option<f64>>,
    final_angular_speed_rad_s: f64,
    orientation_search: &'a cps_learn::SearchStats,
    orientation_seconds: f64,
    /// With `[clearance]`: the stage that bent the learned position until the robot's
    /// model, following the pose, kept the clearance.
    #[serde(skip_serializing_if = "Option::is_none")]
    kept_clear: Option<KeptClearSummary>,
    /// With `[robot]`: the backend the pose was executed on.
    #[serde(skip_serializing_if = "Option::is_none")]
    backend: Option<String>,
    /// With `[robot]`: how the tool followed the pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    execution: Option<PoseExecution>,
    /// With `[robot]`: every limit on the executed joint movement at the controller's
    /// rate (`cps-cli limits check`'s JSON).
    #[serde(skip_serializing_if = "Option::is_none")]
    limit_usage: Option<serde_json::Value>,
}

#[derive(Serialize)]
struct PoseExecution {
    samples: usize,
    duration_s: f64,
    max_position_error_m: f64,
    max_rotation_error_deg: f64,
}

/// Bends the learned pose until the robot's model, following it, keeps the clearance;
/// the outcome becomes the bent pose.
fn keep_pose_clear(
    ctx: &Ctx<'_>,
    config: &PoseConfig,
    k: &crate::sections::clearance::ClearancePlan,
    robot: &crate::robots::RobotChoice,
    outcome: &mut PoseOutcome,
) -> Result<KeptClearSummary, ExperimentError> {
    let keep = cps_learn::KeepClear {
        clearance: &k.clearance,
        robot: &robot.setup,
        dt: robot.planned_every(ctx.exp.config.task.dmp.dt),
        iterations: k.iterations,
    };
    let kept = ctx
        .pool
        .install(|| cps_learn::keep_pose_clear(config, outcome, &keep, &|r| ctx.generation(r)))
        .map_err(|e| learn_error(e, "keeping the pose clear on the model"))?;
    Ok(KeptClearSummary::new(&kept))
}

/// Executes the learned pose on the experiment's robot: the recording, or why not.
fn execute_pose(
    robot: &crate::robots::RobotChoice,
    outcome: &PoseOutcome,
    stop: &cps_robot::StopToken,
) -> Result<cps_robot::Recording, String> {
    let mut backend = robot.open().map_err(|e| e.to_string())?;
    cps_robot::move_to(backend.as_mut(), &robot.setup.initial_q, stop)
        .map_err(|e| e.to_string())?;
    let targets = cps_learn::pose_targets(
        &outcome.position.best_trajectory(),
        &outcome.orientation.trajectory,
        backend.dt(),
    );
    cps_robot::execute(
        backend.as_mut(),
        &robot.setup.chain,
        &targets,
        &robot.setup.execution,
        stop,
    )
    .map_err(|e| e.to_string())
}

/// Learns position and orientation and declares the outcome.
pub(crate) fn run(ctx: &Ctx<'_>, plan: &crate::plan::PosePlan) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let config = PoseConfig {
        learner: exp.config.clone(),
        start_orientation: plan.start,
        goal_orientation: plan.goal,
        via_orientations: plan.via.clone(),
        orientation_sigma0: plan.sigma0,
        orientation_solver: plan.method,
    };
    let progress = |_: usize, r: &cps_cmaes::GenerationReport<'_>| ctx.generation(r);
    let mut outcome = ctx
        .pool
        .install(|| learn_pose(&config, &progress))
        .map_err(|e| learn_error(e, "pose run"))?;
    let complete = !outcome.position.interrupted() && !outcome.orientation.search.interrupted();
    let kept_clear = match (&exp.clearance, &exp.robot) {
        (Some(k), Some(robot)) if complete => {
            Some(keep_pose_clear(ctx, &config, k, robot, &mut outcome)?)
        }
        _ => None,
    };
    ctx.observer.finished();
    let o = &outcome.orientation;
    let best = outcome.position.best();
    let summary = Summary {
        position_cost: best.cost,
        position_gap_to_optimum: best.gap_to_optimum,
        goal_error_m: best.errors.goal,
        via_errors_m: &best.errors.via,
        obstacle_distances_m: exp
            .config
            .task
            .obstacle_distances(&outcome.position.best_trajectory()),
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
        kept_clear,
        backend: None,
        execution: None,
        limit_usage: None,
    };
    // With a robot: the pose executed (IK per control period), and the joint movement
    // checked, retimed and exported as for the other robot kinds.
    let mut summary = summary;
    let mut movement = None;
    let mut failure = None;
    if let (Some(robot), true) = (&exp.robot, complete) {
        summary.backend = Some(robot.describe());
        match execute_pose(robot, &outcome, ctx.stop) {
            Ok(rec) => {
                summary.execution = Some(PoseExecution {
                    samples: rec.time.len(),
                    duration_s: rec.time.last().copied().unwrap_or(0.0),
                    max_position_error_m: rec.max_position_error(),
                    max_rotation_error_deg: rec
                        .rotation_error
                        .iter()
                        .fold(0.0_f64, |a, &b| a.max(b))
                        .to_degrees(),
                });
                let m = movement_files(exp, robot, "", &rec.time, rec.q.clone())?;
                summary.limit_usage = Some(m.usage.json());
                movement = Some(m);
            }
            Err(e) => failure = Some(format!("executing the learned pose: {e}")),
        }
    }
    let worst_angle = |v: &[Option<f64>]| v.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
    let lines = vec![
        format!(
            "{}: position and orientation learned in {:.2} s",
            exp.name,
            ctx.wall()
        ),
        format!(
            "  position: cost {:.6e} (gap to the exact optimum {:.2e}), goal error {:.3} mm, worst via-point error {:.3} mm",
            best.cost,
            best.gap_to_optimum,
            best.errors.goal * 1e3,
            worst(&best.errors.via) * 1e3
        ),
        format!(
            "  orientation: cost {:.6e} (from {:.6e}), goal off by {:.3}°, worst via orientation off by {:.3}° ({} generations, {})",
            summary.orientation_cost,
            summary.orientation_start_cost,
            summary.goal_angle_deg,
            worst_angle(&summary.via_angles_deg),
            o.search.generations,
            o.search.termination
        ),
    ];
    let mut lines = lines;
    let mut header = ctx.header(complete);
    if let Some(f) = failure {
        lines.push(format!("  {f}"));
        header.complete = false;
        header.failure = Some(f);
    }
    if let Some(k) = &summary.kept_clear {
        lines.push(k.line("the pose"));
    }
    if let Some(e) = &summary.execution {
        lines.push(format!(
            "  executed on {}: {} samples, tool within {:.3e} m and {:.3}° of the learned pose",
            summary.backend.as_deref().unwrap_or("the robot"),
            e.samples,
            e.max_position_error_m,
            e.max_rotation_error_deg
        ));
    }
    let report = report(ctx, &summary);
    let mut summary = fields(&summary);
    let mut tables = vec![
        trajectory(&outcome),
        history_table(&[
            ("position", &best.history),
            ("orientation", &o.search.history),
        ]),
    ];
    let mut documents = Vec::new();
    if let Some(m) = movement {
        m.into_parts(&mut summary, &mut tables, &mut documents, &mut lines);
    }
    Ok(Outcome {
        header,
        report,
        summary,
        tables,
        figures: figures(ctx, &outcome, &config),
        documents,
        lines,
    })
}

/// `trajectory.csv`: `t`, position `x, y, z` and its velocity `x_vel…`, the unit
/// quaternion `qx, qy, qz, qw`, the angular velocity `omega_x…` (world frame, rad/s).
fn trajectory(outcome: &PoseOutcome) -> Table {
    let p = outcome.position.best_trajectory();
    let o = &outcome.orientation.trajectory;
    let mut t =
        Table::new("trajectory").with(Column::numbers("t", p.times().to_vec(), Format::Fixed(6)));
    for (suffix, q) in [
        (
            "",
            cps_dmp::Trajectory::position as fn(&cps_dmp::Trajectory, usize) -> &[f64],
        ),
        ("_vel", cps_dmp::Trajectory::velocity),
    ] {
        for (d, name) in ["x", "y", "z"].iter().enumerate() {
            t.push(Column::numbers(
                format!("{name}{suffix}"),
                q(&p, d).to_vec(),
                Format::Fixed(9),
            ));
        }
    }
    let n = p.n_samples();
    type Part = fn(&nalgebra::UnitQuaternion<f64>) -> f64;
    let quaternion: [(&str, Part); 4] = [
        ("qx", |q| q.i),
        ("qy", |q| q.j),
        ("qz", |q| q.k),
        ("qw", |q| q.w),
    ];
    for (name, part) in quaternion {
        t.push(Column::numbers(
            name,
            o.orientation.iter().take(n).map(part).collect(),
            Format::Fixed(12),
        ));
    }
    for (d, name) in ["omega_x", "omega_y", "omega_z"].iter().enumerate() {
        t.push(Column::numbers(
            *name,
            o.angular_velocity.iter().take(n).map(|w| w[d]).collect(),
            Format::Fixed(9),
        ));
    }
    t
}

fn figures(ctx: &Ctx<'_>, outcome: &PoseOutcome, config: &PoseConfig) -> Vec<Figure> {
    let task = &ctx.exp.config.task;
    let p = outcome.position.best_trajectory();
    let mut figures = position_figures(
        vec![cps_movement::movement::trajectory_series(
            "learned path",
            &p,
        )],
        way_points(task),
        "Position per coordinate, with the start, the via points p1… and the goal.",
        "The path in 3-D.",
    );
    // The orientation relative to the start as a rotation vector (axis × angle, degrees,
    // world frame): three angles a reader can judge, where quaternion components are not.
    // Of the vectors that name one rotation, each sample takes the one nearest the
    // previous sample's, so the curves do not jump at 180°.
    let o = &outcome.orientation.trajectory;
    let q0 = config.start_orientation;
    let degrees = |q: &nalgebra::UnitQuaternion<f64>| (q * q0.inverse()).scaled_axis();
    let mut angles: Vec<nalgebra::Vector3<f64>> = Vec::with_capacity(o.orientation.len());
    for q in &o.orientation {
        let r = degrees(q);
        let angle = r.norm();
        let next = match angles.last() {
            Some(prev) if angle > 1e-12 => {
                let axis = r / angle;
                [-1.0, 0.0, 1.0]
                    .map(|k| axis * (angle + k * std::f64::consts::TAU))
                    .into_iter()
                    .min_by(|a, b| (a - prev).norm().total_cmp(&(b - prev).norm()))
                    .unwrap_or(r)
            }
            _ => r,
        };
        angles.push(next);
    }
    let comps = (0..3)
        .map(|d| angles.iter().map(|v| v[d].to_degrees()).collect())
        .collect();
    let degrees = |q: &nalgebra::UnitQuaternion<f64>| degrees(q).map(f64::to_degrees);
    let mut marks = vec![Mark {
        time: 0.0,
        values: degrees(&config.start_orientation).iter().copied().collect(),
        kind: MarkKind::Start,
        label: "start".into(),
    }];
    for (i, (v, q)) in task.via.iter().zip(&config.via_orientations).enumerate() {
        if let Some(q) = q {
            marks.push(Mark {
                time: v.time,
                values: degrees(q).iter().copied().collect(),
                kind: MarkKind::Via,
                label: format!("p{}", i + 1),
            });
        }
    }
    marks.push(Mark {
        time: task.dmp.tau,
        values: degrees(&config.goal_orientation).iter().copied().collect(),
        kind: MarkKind::Goal,
        label: "goal".into(),
    });
    figures.push(derivative_figure(&p, false));
    figures.insert(
        1,
        Figure {
            name: "orientation".into(),
            caption: "Orientation relative to the start, as a rotation vector (axis × angle in degrees, world frame), with the orientation targets; free via orientations have no mark.".into(),
            plot: Plot::Panels(
                Panels::new(
                    ["rotation x [°]", "rotation y [°]", "rotation z [°]"]
                        .map(String::from)
                        .to_vec(),
                    vec![Series::new("learned orientation", o.times.clone(), comps)],
                )
                .marks(marks),
            ),
        },
    );
    let arms = [
        ("position", &outcome.position.best().history),
        ("orientation", &outcome.orientation.search.history),
    ]
    .into_iter()
    .filter(|(_, h)| !h.is_empty())
    .map(|(label, h)| super::cost_arm(label, &[h.as_slice()]))
    .collect();
    figures.extend(cost_figure("Best cost so far per generation.", arms, None));
    figures.extend(search_figure(&[
        ("position", &outcome.position.best().history),
        ("orientation", &outcome.orientation.search.history),
    ]));
    figures
}

fn report(ctx: &Ctx<'_>, s: &Summary<'_>) -> Report {
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
    Report {
        title: format!("{}: position and orientation through via points", ctx.exp.name),
        context: "Three DMPs carry the tool's position and one orientation DMP on unit quaternions its orientation; each part is learned against its via-point targets.".into(),
        tables: vec![ReportTable::pairs("Result", rows)],
    }
}
