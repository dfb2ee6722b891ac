//! `kind = "viapoint_joint"`: via-point learning with one DMP per joint, judged in task
//! space, executed on the robot backend.

use cps_learn::{
    JointCostBreakdown, JointSpaceConfig, JointSpaceOutcome, LimitReport, execute_joint_trajectory,
    learn_joint_space,
};
use cps_robot::Recording;
use serde::Serialize;

use super::movement_files::movement_files;
use super::{Ctx, learn_error};
use super::{
    cost_figure, history_table, marks, position_figures, search_figure, search_row, way_points,
    worst,
};
use crate::outcome::{
    Column, Figure, Format, Outcome, Panels, Plot, Report, ReportTable, Series, Table, fields,
};
use crate::{Context, ExperimentError};

#[derive(Serialize)]
struct Summary<'a> {
    backend: String,
    scene: &'a str,
    way_configurations_rad: &'a [Vec<f64>],
    cost: f64,
    cost_terms: JointCostBreakdown,
    warm_start_cost: f64,
    warm_start_cost_terms: JointCostBreakdown,
    goal_error_m: f64,
    via_errors_m: &'a [f64],
    max_position_error_m: f64,
    final_tool_speed_m_s: f64,
    limits: LimitSummary,
    /// Every limit of the robot at the controller's rate (`cps-cli limits check`'s JSON).
    limit_usage: serde_json::Value,
    search: &'a cps_learn::SearchStats,
    learning_seconds: f64,
    execution: Option<ExecutionSummary>,
}

#[derive(Serialize)]
struct LimitSummary {
    within: bool,
    max_position_excess_rad: f64,
    min_position_margin_rad: f64,
    max_speed_ratio: f64,
}

impl From<LimitReport> for LimitSummary {
    fn from(l: LimitReport) -> Self {
        Self {
            within: l.within(),
            max_position_excess_rad: l.max_position_excess,
            min_position_margin_rad: l.min_position_margin,
            max_speed_ratio: l.max_speed_ratio,
        }
    }
}

#[derive(Serialize)]
struct ExecutionSummary {
    samples: usize,
    duration_s: f64,
    max_tool_deviation_m: f64,
    within_position_limits: bool,
    max_speed_ratio: f64,
}

/// Checks a recording against the robot's limits: positions within range and speeds
/// (differences of consecutive samples over the control period) within the speed limits.
fn execution_summary(rec: &Recording, chain: &cps_kinematics::SerialChain) -> ExecutionSummary {
    let within = match chain.limits() {
        Some((lo, hi)) => rec.q.iter().all(|q| {
            q.iter()
                .enumerate()
                .all(|(j, &x)| x >= lo[j] - 1e-12 && x <= hi[j] + 1e-12)
        }),
        None => true,
    };
    let mut ratio: f64 = 0.0;
    if let Some(v) = chain.velocity_limits() {
        for k in 1..rec.q.len() {
            let dt = rec.time[k] - rec.time[k - 1];
            for ((a, b), vmax) in rec.q[k].iter().zip(&rec.q[k - 1]).zip(v) {
                ratio = ratio.max((a - b).abs() / dt / vmax);
            }
        }
    }
    ExecutionSummary {
        samples: rec.time.len(),
        duration_s: rec.time.last().copied().unwrap_or(0.0),
        max_tool_deviation_m: rec.max_position_error(),
        within_position_limits: within,
        max_speed_ratio: ratio,
    }
}

/// Learns in joint space, executes the result and declares the outcome.
pub(crate) fn run(ctx: &Ctx<'_>) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let robot = exp
        .robot
        .as_ref()
        .ok_or_else(|| ExperimentError::Message("a joint-space experiment has a robot".into()))?;
    let plan = exp.joint.ok_or_else(|| {
        ExperimentError::Message("a joint-space experiment has its limit weights".into())
    })?;
    let mut config = JointSpaceConfig::new(exp.config.clone(), robot.setup.clone());
    config.limit_weight = plan.limit_weight;
    config.speed_limit_weight = plan.speed_limit_weight;
    let mut backend = robot.open()?;
    let outcome = ctx
        .pool
        .install(|| learn_joint_space(&config, &|r| ctx.generation(r)))
        .map_err(|e| learn_error(e, "joint-space run"))?;
    ctx.observer.finished();
    let interrupted = outcome.search.interrupted();
    // A backend that fails here (a simulator that died) costs the execution, not the
    // learned result: it is kept, marked incomplete, with the reason.
    let mut failure = None;
    let recording = if interrupted {
        None
    } else {
        match execute_joint_trajectory(
            backend.as_mut(),
            &robot.setup,
            &outcome.trajectory,
            ctx.stop,
        ) {
            Ok(r) => Some(r),
            Err(e) => {
                failure = Some(format!("executing the learned movement: {e}"));
                None
            }
        }
    };
    let execution = recording
        .as_ref()
        .map(|r| execution_summary(r, &robot.setup.chain));
    let mut header = ctx.header(!interrupted);
    if let Some(f) = &failure {
        header.complete = false;
        header.failure = Some(f.clone());
    }
    // The learned movement as its controller will see it, against every limit; retimed
    // and exported as `[export]` asks.
    let traj = &outcome.trajectory;
    let movement = movement_files(
        exp,
        robot,
        "",
        traj.times(),
        (0..traj.n_samples())
            .map(|k| (0..traj.dims()).map(|j| traj.position(j)[k]).collect())
            .collect(),
    )?;
    let summary = Summary {
        backend: robot.describe_opened(backend.as_ref()),
        scene: &robot.scene,
        way_configurations_rad: &outcome.way_configurations,
        cost: outcome.breakdown.total(),
        cost_terms: outcome.breakdown,
        warm_start_cost: outcome.warm_start.total(),
        warm_start_cost_terms: outcome.warm_start,
        goal_error_m: outcome.errors.goal,
        via_errors_m: &outcome.errors.via,
        max_position_error_m: outcome.errors.max_position_error(),
        final_tool_speed_m_s: outcome.errors.final_speed,
        limits: outcome.limits.into(),
        limit_usage: movement.usage.json(),
        search: &outcome.search,
        learning_seconds: outcome.seconds,
        execution,
    };
    // The tool in task space, through forward kinematics.
    let traj = &outcome.trajectory;
    let dof = traj.dims();
    let mut tool: [Vec<f64>; 3] = Default::default();
    for k in 0..traj.n_samples() {
        let q: Vec<f64> = (0..dof).map(|j| traj.position(j)[k]).collect();
        let p = config
            .robot
            .chain
            .fk(&q)
            .context_with(|| "forward kinematics of the learned movement".into())?
            .translation
            .vector;
        for d in 0..3 {
            tool[d].push(p[d]);
        }
    }
    let mut tables = vec![trajectory(&outcome, &tool)];
    tables.extend(recording.as_ref().map(|r| recording_table(r, dof)));
    tables.push(history_table(&[("joints", &outcome.search.history)]));
    let mut figures = vec![joints_figure(ctx, &outcome, &config)];
    // Joint speeds with the speed limits (the trajectory's `q1_vel…` columns).
    let speed_limits = config
        .robot
        .chain
        .velocity_limits()
        .map_or(Vec::new(), |v| v.iter().map(|&m| Some((-m, m))).collect());
    figures.push(Figure {
        name: "joint_speeds".into(),
        caption: "Joint speeds with their limits (shaded beyond them).".into(),
        plot: Plot::Panels(
            Panels::new(
                (1..=dof).map(|j| format!("q{j} speed [rad/s]")).collect(),
                vec![Series::new(
                    "joint speed",
                    traj.times().to_vec(),
                    (0..dof).map(|j| traj.velocity(j).to_vec()).collect(),
                )],
            )
            .limits(speed_limits),
        ),
    });
    figures.extend(position_figures(
        vec![Series::new("tool (forward kinematics)", traj.times().to_vec(), tool.to_vec())],
        way_points(&exp.config.task),
        "The tool in task space (forward kinematics), with the start, the via points p1… and the goal.",
        "The tool's path in 3-D.",
    ));
    figures.extend(cost_figure(
        "Best cost so far per generation.",
        vec![super::cost_arm("CMA-ES", &[&outcome.search.history])],
        None,
    ));
    figures.extend(search_figure(&[("CMA-ES", &outcome.search.history)]));
    let mut lines = vec![
        format!(
            "{}: {} in {:.2} s ({} generations, {})",
            exp.name,
            outcome.search.termination,
            ctx.wall(),
            outcome.search.generations,
            robot.describe()
        ),
        format!(
            "  cost {:.6e} (warm start {:.6e}); goal error {:.3} mm, worst via-point error {:.3} mm (task space, through forward kinematics)",
            summary.cost,
            summary.warm_start_cost,
            summary.goal_error_m * 1e3,
            worst(&outcome.errors.via) * 1e3
        ),
        format!(
            "  limits: {} (smallest margin {:.4} rad, speeds up to {:.0} % of their limits)",
            if outcome.limits.within() {
                "none exceeded"
            } else {
                "EXCEEDED"
            },
            outcome.limits.min_position_margin,
            outcome.limits.max_speed_ratio * 100.0
        ),
    ];
    if let Some(e) = &summary.execution {
        lines.push(format!(
            "  executed: {} samples, tool within {:.3e} m of the model, {}",
            e.samples,
            e.max_tool_deviation_m,
            if e.within_position_limits && e.max_speed_ratio <= 1.0 + 1e-9 {
                "within the joint limits"
            } else {
                "LIMITS EXCEEDED"
            }
        ));
    }
    let report = report(ctx, &summary);
    Ok(movement.outcome(header, report, fields(&summary), tables, figures, lines))
}

/// `trajectory.csv`: `t`, joint angles `q1…`, their speeds `q1_vel…`, the tool position
/// `tool_x, tool_y, tool_z` (forward kinematics).
fn trajectory(outcome: &JointSpaceOutcome, tool: &[Vec<f64>; 3]) -> Table {
    let traj = &outcome.trajectory;
    let dof = traj.dims();
    let mut t = Table::new("trajectory").with(Column::numbers(
        "t",
        traj.times().to_vec(),
        Format::Fixed(6),
    ));
    for j in 0..dof {
        t.push(Column::numbers(
            format!("q{}", j + 1),
            traj.position(j).to_vec(),
            Format::Sci(12),
        ));
    }
    for j in 0..dof {
        t.push(Column::numbers(
            format!("q{}_vel", j + 1),
            traj.velocity(j).to_vec(),
            Format::Sci(12),
        ));
    }
    for (name, v) in ["tool_x", "tool_y", "tool_z"].iter().zip(tool) {
        t.push(Column::numbers(*name, v.clone(), Format::Fixed(9)));
    }
    t
}

/// `recording.csv`: what the backend did, with the tool's deviation from the model.
fn recording_table(rec: &Recording, dof: usize) -> Table {
    let mut t =
        Table::new("recording").with(Column::numbers("t", rec.time.clone(), Format::Fixed(6)));
    for j in 0..dof {
        t.push(Column::numbers(
            format!("q{}", j + 1),
            rec.q.iter().map(|q| q[j]).collect(),
            Format::Sci(12),
        ));
    }
    for (d, name) in ["tool_x", "tool_y", "tool_z"].iter().enumerate() {
        t.push(Column::numbers(
            *name,
            rec.position.iter().map(|p| p[d]).collect(),
            Format::Fixed(9),
        ));
    }
    t.with(Column::numbers(
        "deviation_m",
        rec.position_error.clone(),
        Format::Sci(3),
    ))
}

/// The joints with their limits and the way points' IK configurations.
fn joints_figure(ctx: &Ctx<'_>, outcome: &JointSpaceOutcome, config: &JointSpaceConfig) -> Figure {
    let traj = &outcome.trajectory;
    let dof = traj.dims();
    let task = &ctx.exp.config.task;
    let series = vec![Series::new(
        "joint angle",
        traj.times().to_vec(),
        (0..dof).map(|j| traj.position(j).to_vec()).collect(),
    )];
    let limits = match config.robot.chain.limits() {
        Some((lo, hi)) => (0..dof).map(|j| Some((lo[j], hi[j]))).collect(),
        None => Vec::new(),
    };
    let marks = marks(task, 1.0, outcome.way_configurations.iter().cloned());
    Figure {
        name: "joints".into(),
        caption: "Joint angles over time with their limits (shaded beyond them), and the way points' IK configurations.".into(),
        plot: Plot::Panels(
            Panels::new((1..=dof).map(|j| format!("q{j} [rad]")).collect(), series)
                .limits(limits)
                .marks(marks),
        ),
    }
}

fn report(ctx: &Ctx<'_>, s: &Summary<'_>) -> Report {
    let mm = |v: f64| format!("{:.4} mm", v * 1e3);
    let mut rows = vec![
        ("backend", s.backend.clone()),
        ("cost", format!("{:.6e}", s.cost)),
        (
            "warm start (joint-space exact optimum)",
            format!("{:.6e}", s.warm_start_cost),
        ),
        ("goal error (task space)", mm(s.goal_error_m)),
    ];
    for (i, e) in s.via_errors_m.iter().enumerate() {
        rows.push((
            "via-point error (task space)",
            format!("p{}: {}", i + 1, mm(*e)),
        ));
    }
    rows.push((
        "joint limits",
        format!(
            "{} (smallest margin {:.4} rad, speeds up to {:.0} % of the limits)",
            if s.limits.within {
                "within"
            } else {
                "EXCEEDED"
            },
            s.limits.min_position_margin_rad,
            s.limits.max_speed_ratio * 100.0
        ),
    ));
    if let Some(e) = &s.execution {
        rows.push((
            "execution",
            format!(
                "{} samples; tool within {:.2e} m of the model; {}",
                e.samples,
                e.max_tool_deviation_m,
                if e.within_position_limits {
                    "joints within their limits"
                } else {
                    "joints OUTSIDE their limits"
                }
            ),
        ));
    }
    rows.push(search_row(s.search));
    rows.push(("learning time", format!("{:.2} s", s.learning_seconds)));
    Report {
        title: format!("{}: via points learned in joint space", ctx.exp.name),
        context: "The way points are converted to joint configurations by inverse kinematics (one branch), one DMP per joint carries the movement, and the via-point and goal errors are judged in task space through forward kinematics, with joint-limit and speed-limit penalties.".into(),
        tables: vec![ReportTable::pairs("Result", rows)],
    }
}
