//! `kind = "viapoint_joint"`: via-point learning with one DMP per joint, judged in task
//! space, executed on the robot backend.

use cps_dmp::Trajectory;
use cps_learn::{
    ExecutedJointOutcome, ExecutedJoints, ExecutedSearch, JointCostBreakdown, JointSpaceConfig,
    JointSpaceOutcome, LimitReport, TaskErrors, execute_joint_trajectory, learn_joint_executed,
    learn_joint_space,
};
use cps_robot::Recording;
use serde::Serialize;

use super::clearance::{ClearanceSummary, Joints};
use super::movement_files::movement_files;
use super::{Ctx, learn_error};
use super::{
    cost_figure, history_table, marks, position_figures, search_figure, search_row, way_points,
    worst,
};
use crate::{Context, ExperimentError};
use cps_outcome::outcome::{
    Column, Figure, Format, Outcome, Panels, Plot, Report, ReportTable, Series, Table, fields,
};

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
    /// On a robot with dynamics: the command learned on what the robot does.
    executed_learning: Option<ExecutedLearning>,
    execution: Option<ExecutionSummary>,
    /// Where the movement comes closest to the robot's own shapes and its world's (a robot
    /// with collision geometry).
    #[serde(skip_serializing_if = "Option::is_none")]
    clearance: Option<ClearanceSummary>,
}

/// The second stage on a robot with dynamics: from the model-learned command, the
/// command whose execution passes the via points.
#[derive(Serialize)]
struct ExecutedLearning {
    /// The model-learned command as the robot executed it (the search's start).
    model_learned_goal_error_m: f64,
    model_learned_via_errors_m: Vec<f64>,
    model_learned_cost: f64,
    /// The learned command as the robot executed it.
    goal_error_m: f64,
    via_errors_m: Vec<f64>,
    final_tool_speed_m_s: f64,
    cost: f64,
    cost_terms: JointCostBreakdown,
    /// The learned command itself on the model (it leads where the robot lags).
    commanded_via_errors_m: Vec<f64>,
    iterations: u64,
    executions: u64,
    termination: String,
    seconds: f64,
}

impl ExecutedLearning {
    fn new(r: &ExecutedJointOutcome) -> Self {
        ExecutedLearning {
            model_learned_goal_error_m: r.warm_start_errors.goal,
            model_learned_via_errors_m: r.warm_start_errors.via.clone(),
            model_learned_cost: r.warm_start.total(),
            goal_error_m: r.errors.goal,
            via_errors_m: r.errors.via.clone(),
            final_tool_speed_m_s: r.errors.final_speed,
            cost: r.breakdown.total(),
            cost_terms: r.breakdown,
            commanded_via_errors_m: r.commanded_errors.via.clone(),
            iterations: r.search.generations,
            executions: r.search.evaluations + 2,
            termination: r.search.termination.clone(),
            seconds: r.seconds,
        }
    }
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
    /// The tool as the robot reported it, at the via points' times and at the end.
    goal_error_m: f64,
    via_errors_m: Vec<f64>,
    final_tool_speed_m_s: f64,
    max_tool_deviation_m: f64,
    within_position_limits: bool,
    max_speed_ratio: f64,
}

/// The task's errors as the robot reported its tool: at each via point's time (between
/// the plan's points, `dt` apart, linearly) and at the last point.
fn recorded_errors(rec: &Recording, task: &cps_learn::ViaPointTask, dt: f64) -> TaskErrors {
    let n = rec.position.len();
    let at = |t: f64| -> nalgebra::Vector3<f64> {
        let s = (t / dt).clamp(0.0, (n - 1) as f64);
        let k = (s.floor() as usize).min(n.saturating_sub(2));
        let f = s - k as f64;
        let (a, b) = (rec.position[k], rec.position[(k + 1).min(n - 1)]);
        nalgebra::Vector3::from_fn(|d, _| a[d] + f * (b[d] - a[d]))
    };
    let p = |v: &[f64]| nalgebra::Vector3::new(v[0], v[1], v[2]);
    let end = at((n - 1) as f64 * dt);
    TaskErrors {
        goal: (end - p(&task.goal)).norm(),
        via: task
            .via
            .iter()
            .map(|v| (at(v.time) - p(&v.position)).norm())
            .collect(),
        final_speed: (end - at((n as f64 - 2.0).max(0.0) * dt)).norm() / dt,
    }
}

/// Checks a recording against the robot's limits: positions within range and speeds
/// (differences of consecutive samples over the control period) within the speed limits.
fn execution_summary(
    rec: &Recording,
    chain: &cps_kinematics::SerialChain,
    task: &cps_learn::ViaPointTask,
    dt: f64,
) -> ExecutionSummary {
    let errors = recorded_errors(rec, task, dt);
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
        goal_error_m: errors.goal,
        via_errors_m: errors.via,
        final_tool_speed_m_s: errors.final_speed,
        max_tool_deviation_m: rec.max_position_error(),
        within_position_limits: within,
        max_speed_ratio: ratio,
    }
}

/// Learns in joint space, executes the result and declares the outcome.
pub(crate) fn run(ctx: &Ctx<'_>, plan: crate::plan::JointPlan) -> Result<Outcome, ExperimentError> {
    let exp = ctx.exp;
    let robot = exp
        .robot
        .as_ref()
        .ok_or_else(|| ExperimentError::Message("a joint-space experiment has a robot".into()))?;
    let mut config = JointSpaceConfig::new(exp.config.clone(), robot.setup.clone());
    config.limit_weight = plan.limit_weight;
    config.speed_limit_weight = plan.speed_limit_weight;
    config.clearance = exp.clearance.as_ref().map(|c| c.clearance.clone());
    let mut backend = robot.open()?;
    let outcome = ctx
        .pool
        .install(|| learn_joint_space(&config, &|r| ctx.generation(r)))
        .map_err(|e| learn_error(e, "joint-space run"))?;
    // On a robot with dynamics, the command is then learned on what the robot does.
    let learning = robot
        .learning_robots()
        .filter(|_| plan.learn_on == crate::plan::LearnOn::Execution);
    let refined = match learning {
        Some((open, dt)) if !outcome.search.interrupted() => {
            let search = ExecutedSearch {
                open: open.as_ref(),
                dt,
                iterations: exp.config.generations,
                stop: ctx.stop,
            };
            Some(
                ctx.pool
                    .install(|| {
                        learn_joint_executed(&config, &outcome, &search, &|r| ctx.generation(r))
                    })
                    .map_err(|e| learn_error(e, "learning on the executed movement"))?,
            )
        }
        _ => None,
    };
    ctx.observer.finished();
    let interrupted =
        outcome.search.interrupted() || refined.as_ref().is_some_and(|r| r.search.interrupted());
    // What is kept, exported and executed: the command learned on the executions, else
    // on the model.
    let (trajectory, errors, limits) = match &refined {
        Some(r) => (&r.trajectory, &r.errors, r.limits),
        None => (&outcome.trajectory, &outcome.errors, outcome.limits),
    };
    // A backend that fails here (a simulator that died) costs the execution, not the
    // learned result: it is kept, marked incomplete, with the reason.
    let mut failure = None;
    let recording = if interrupted {
        None
    } else {
        match execute_joint_trajectory(backend.as_mut(), &robot.setup, trajectory, ctx.stop) {
            Ok(r) => Some(r),
            Err(e) => {
                failure = Some(format!("executing the learned movement: {e}"));
                None
            }
        }
    };
    let plan_dt = backend.dt();
    let execution = recording
        .as_ref()
        .map(|r| execution_summary(r, &robot.setup.chain, &exp.config.task, plan_dt));
    let mut header = ctx.header(!interrupted);
    if let Some(f) = &failure {
        header.complete = false;
        header.failure = Some(f.clone());
    }
    // The learned movement as its controller will see it, against every limit; retimed
    // and exported as `[export]` asks.
    let traj = trajectory;
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
        limits: limits.into(),
        limit_usage: movement.usage.json(),
        search: &outcome.search,
        learning_seconds: outcome.seconds,
        executed_learning: refined.as_ref().map(ExecutedLearning::new),
        execution,
        clearance: match &robot.model.shapes {
            Some(shapes) => Some(
                ClearanceSummary::new(
                    shapes,
                    &config.robot.chain,
                    exp.clearance.as_ref().map(|c| &c.clearance),
                    &Joints::of_trajectory(trajectory),
                    &Joints::of_trajectory(&outcome.warm_start_trajectory),
                )
                .context_with(|| "the learned movement's distances".into())?,
            ),
            None => None,
        },
    };
    let dof = traj.dims();
    let tool = tool_path(&config, traj)?;
    let mut tables = vec![trajectory_table(traj, &tool)];
    tables.extend(recording.as_ref().map(|r| recording_table(r, dof)));
    tables.push(history_table(&[("joints", &outcome.search.history)]));
    let figures = figures(ctx, &config, &outcome, refined.as_ref(), traj, tool)?;
    let lines = lines(ctx, &outcome, &summary, errors, limits);
    let report = report(ctx, &summary);
    Ok(movement.outcome(header, report, fields(&summary), tables, figures, lines))
}

/// The tool in task space along `traj`, through forward kinematics.
fn tool_path(
    config: &JointSpaceConfig,
    traj: &Trajectory,
) -> Result<[Vec<f64>; 3], ExperimentError> {
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
    Ok(tool)
}

/// The joints, their speeds against their limits, the tool commanded (and executed, when
/// learned on the executions), and the search.
fn figures(
    ctx: &Ctx<'_>,
    config: &JointSpaceConfig,
    outcome: &JointSpaceOutcome,
    refined: Option<&ExecutedJointOutcome>,
    traj: &Trajectory,
    tool: [Vec<f64>; 3],
) -> Result<Vec<Figure>, ExperimentError> {
    let dof = traj.dims();
    let mut figures = vec![joints_figure(ctx, traj, outcome, config)];
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
    let mut tools = vec![Series::new(
        if refined.is_some() {
            "tool commanded"
        } else {
            "tool (forward kinematics)"
        },
        traj.times().to_vec(),
        tool.to_vec(),
    )];
    if let Some(r) = refined {
        tools.push(executed_tool(
            "executed (robot with dynamics)",
            &r.executed,
            config,
        )?);
        tools.push(executed_tool(
            "model-learned command, executed",
            &r.warm_start_executed,
            config,
        )?);
    }
    figures.extend(position_figures(
        tools,
        way_points(&ctx.exp.config.task),
        "The tool in task space (forward kinematics), with the start, the via points p1… and the goal.",
        "The tool's path in 3-D.",
    ));
    figures.extend(cost_figure(
        "Best cost so far per generation.",
        vec![super::cost_arm("CMA-ES", &[&outcome.search.history])],
        None,
    ));
    figures.extend(search_figure(&[("CMA-ES", &outcome.search.history)]));
    Ok(figures)
}

/// The terminal's lines: the search, the errors, the limits, the clearance, the
/// execution.
fn lines(
    ctx: &Ctx<'_>,
    outcome: &JointSpaceOutcome,
    summary: &Summary<'_>,
    errors: &TaskErrors,
    limits: LimitReport,
) -> Vec<String> {
    let robot = ctx
        .exp
        .robot
        .as_ref()
        .map_or(String::new(), |r| r.describe());
    let mut lines = vec![
        format!(
            "{}: {} in {:.2} s ({} generations, {})",
            ctx.exp.name,
            outcome.search.termination,
            ctx.wall(),
            outcome.search.generations,
            robot
        ),
        format!(
            "  cost {:.6e} (warm start {:.6e}); goal error {:.3} mm, worst via-point error {:.3} mm (task space, through forward kinematics)",
            summary.cost,
            summary.warm_start_cost,
            summary.goal_error_m * 1e3,
            worst(&outcome.errors.via) * 1e3
        ),
    ];
    if let Some(r) = &summary.executed_learning {
        lines.push(format!(
            "  on the robot with dynamics: the model-learned command passes its via points up to {:.3} mm away as executed; learned on the executions ({}, {} iterations, {} executions, {:.2} s): goal {:.3} mm, worst via point {:.3} mm as executed",
            worst(&r.model_learned_via_errors_m) * 1e3,
            r.termination,
            r.iterations,
            r.executions,
            r.seconds,
            errors.goal * 1e3,
            worst(&errors.via) * 1e3,
        ));
    }
    lines.push(format!(
        "  limits: {} (smallest margin {:.4} rad, speeds up to {:.0} % of their limits)",
        if limits.within() {
            "none exceeded"
        } else {
            "EXCEEDED"
        },
        limits.min_position_margin,
        limits.max_speed_ratio * 100.0
    ));
    if let Some(c) = &summary.clearance {
        lines.push(c.line());
    }
    if let Some(e) = &summary.execution {
        lines.push(format!(
            "  executed: {} samples, goal {:.3} mm, worst via point {:.3} mm as the robot reported its tool, tool within {:.3e} m of the model, {}",
            e.samples,
            e.goal_error_m * 1e3,
            worst(&e.via_errors_m) * 1e3,
            e.max_tool_deviation_m,
            if e.within_position_limits && e.max_speed_ratio <= 1.0 + 1e-9 {
                "within the joint limits"
            } else {
                "LIMITS EXCEEDED"
            }
        ));
    }
    lines
}

/// The tool where the robot put it, through forward kinematics of its executed joints.
fn executed_tool(
    name: &str,
    executed: &ExecutedJoints,
    config: &JointSpaceConfig,
) -> Result<Series, ExperimentError> {
    let mut tool: [Vec<f64>; 3] = Default::default();
    for q in &executed.q {
        let p = config
            .robot
            .chain
            .fk(q)
            .context_with(|| "forward kinematics of the executed movement".into())?
            .translation
            .vector;
        for d in 0..3 {
            tool[d].push(p[d]);
        }
    }
    let times = (0..executed.q.len())
        .map(|k| k as f64 * executed.dt)
        .collect();
    Ok(Series::new(name, times, tool.to_vec()))
}

/// `trajectory.csv`: `t`, joint angles `q1…`, their speeds `q1_vel…`, the tool position
/// `tool_x, tool_y, tool_z` (forward kinematics).
fn trajectory_table(traj: &Trajectory, tool: &[Vec<f64>; 3]) -> Table {
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
fn joints_figure(
    ctx: &Ctx<'_>,
    traj: &Trajectory,
    outcome: &JointSpaceOutcome,
    config: &JointSpaceConfig,
) -> Figure {
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
