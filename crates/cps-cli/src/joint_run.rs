//! `kind = "viapoint_joint"`: via-point learning with one DMP per joint, judged in task
//! space, executed on the robot backend.

use anyhow::{Context, Result};
use cps_kinematics::Recording;
use cps_learn::{
    JointCostBreakdown, JointSpaceConfig, JointSpaceOutcome, LimitReport, execute_joint_trajectory,
    learn_joint_space,
};
use serde::Serialize;

use crate::experiment::Experiment;
use crate::output::Staging;
use crate::plots::{CostArm, Series, costs, figures, way_points};
use crate::report::{self, Table};
use crate::runner::{Finished, RunContext, RunHeader, learn_error, search_row, write_history};

#[derive(Serialize)]
struct Summary<'a> {
    #[serde(flatten)]
    header: RunHeader<'a>,
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

/// Learns in joint space, executes the result and writes everything into `stage`.
pub fn run(
    exp: &Experiment,
    ctx: &RunContext<'_>,
    stage: &Staging,
    wall: &dyn Fn() -> f64,
) -> Result<Finished> {
    let robot = exp
        .robot
        .as_ref()
        .context("a joint-space experiment has a robot")?;
    let plan = exp
        .joint
        .context("a joint-space experiment has its limit weights")?;
    let mut config = JointSpaceConfig::new(exp.config.clone(), robot.setup.clone());
    config.limit_weight = plan.limit_weight;
    config.speed_limit_weight = plan.speed_limit_weight;
    let mut backend = robot.open()?;
    let outcome = ctx
        .pool
        .install(|| learn_joint_space(&config, &|_| ctx.generation()))
        .map_err(|e| learn_error(e, "joint-space run"))?;
    ctx.bar.finish_and_clear();
    let interrupted = outcome.search.interrupted();
    // A backend that fails here (a simulator that died) costs the execution, not the
    // learned result: it is written, marked incomplete, with the reason.
    let mut failure = None;
    let recording = if interrupted {
        None
    } else {
        match execute_joint_trajectory(backend.as_mut(), &robot.setup, &outcome.trajectory) {
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
    let summary = Summary {
        header: RunHeader::new(exp, !interrupted, ctx.pool.current_num_threads(), wall())
            .failed(failure.as_deref()),
        backend: robot.describe(),
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
        search: &outcome.search,
        learning_seconds: outcome.seconds,
        execution,
    };
    stage.write("summary.json", &serde_json::to_vec_pretty(&summary)?)?;
    write_files(stage, &outcome, recording.as_ref(), &config)?;
    if exp.plots {
        plot(stage, exp, &outcome, &config)?;
    }
    write_report(stage, exp, &summary)?;
    let mut lines = vec![
        format!(
            "{}: {} in {:.2} s ({} generations, {})",
            exp.name,
            outcome.search.termination,
            wall(),
            outcome.search.generations,
            robot.describe()
        ),
        format!(
            "  cost {:.6e} (warm start {:.6e}); goal error {:.3} mm, worst via-point error {:.3} mm (task space, through forward kinematics)",
            summary.cost,
            summary.warm_start_cost,
            summary.goal_error_m * 1e3,
            outcome.errors.via.iter().fold(0.0f64, |a, &b| a.max(b)) * 1e3
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
    Ok(Finished {
        complete: !interrupted && failure.is_none(),
        failure,
        lines,
    })
}

fn write_files(
    stage: &Staging,
    outcome: &JointSpaceOutcome,
    recording: Option<&Recording>,
    config: &JointSpaceConfig,
) -> Result<()> {
    let traj = &outcome.trajectory;
    let dof = traj.dims();
    let chain = &config.robot.chain;
    let mut w = csv::Writer::from_path(stage.path("trajectory.csv"))?;
    let mut header = vec!["t".to_string()];
    header.extend((1..=dof).map(|j| format!("q{j}")));
    header.extend((1..=dof).map(|j| format!("dq{j}")));
    header.extend(["x", "y", "z"].map(String::from));
    w.write_record(&header)?;
    for (k, t) in traj.times().iter().enumerate() {
        let q: Vec<f64> = (0..dof).map(|j| traj.position(j)[k]).collect();
        let p = chain.fk(&q)?.translation.vector;
        let mut row = vec![format!("{t:.6}")];
        row.extend(q.iter().map(|v| format!("{v:.12e}")));
        row.extend((0..dof).map(|j| format!("{:.12e}", traj.velocity(j)[k])));
        row.extend([p.x, p.y, p.z].map(|v| format!("{v:.9}")));
        w.write_record(&row)?;
    }
    w.flush()?;
    if let Some(rec) = recording {
        let mut w = csv::Writer::from_path(stage.path("recording.csv"))?;
        let mut header = vec!["t".to_string()];
        header.extend((1..=dof).map(|j| format!("q{j}")));
        header.extend(["x", "y", "z", "deviation_m"].map(String::from));
        w.write_record(&header)?;
        for k in 0..rec.time.len() {
            let mut row = vec![format!("{:.6}", rec.time[k])];
            row.extend(rec.q[k].iter().map(|v| format!("{v:.12e}")));
            row.extend(rec.position[k].map(|v| format!("{v:.9}")));
            row.push(format!("{:.3e}", rec.position_error[k]));
            w.write_record(&row)?;
        }
        w.flush()?;
    }
    write_history(stage, &[("joints", &outcome.search.history)])
}

fn plot(
    stage: &Staging,
    exp: &Experiment,
    outcome: &JointSpaceOutcome,
    config: &JointSpaceConfig,
) -> Result<()> {
    let traj = &outcome.trajectory;
    let dof = traj.dims();
    let chain = &config.robot.chain;
    if !outcome.search.history.is_empty() {
        costs(
            stage,
            "cost",
            &[CostArm {
                label: "CMA-ES".into(),
                runs: vec![&outcome.search.history],
            }],
            None,
        )?;
    }
    // The tool in task space, through forward kinematics.
    let mut tool: [Vec<f64>; 3] = Default::default();
    for k in 0..traj.n_samples() {
        let q: Vec<f64> = (0..dof).map(|j| traj.position(j)[k]).collect();
        let p = chain.fk(&q)?.translation.vector;
        for d in 0..3 {
            tool[d].push(p[d]);
        }
    }
    figures(
        stage,
        "coordinates",
        "path3d",
        &[Series {
            label: String::new(),
            times: traj.times(),
            values: tool.iter().map(Vec::as_slice).collect(),
            faint: false,
        }],
        &way_points(&exp.config.task),
    )?;
    // The joints with their limits.
    let ends = [traj.times()[0], *traj.times().last().unwrap_or(&1.0)];
    let limits: Option<[Vec<[f64; 2]>; 2]> = chain.limits().map(|(lo, hi)| {
        [
            lo.iter().map(|&v| [v, v]).collect(),
            hi.iter().map(|&v| [v, v]).collect(),
        ]
    });
    let mut series = vec![Series {
        label: "joint angle".into(),
        times: traj.times(),
        values: (0..dof).map(|j| traj.position(j)).collect(),
        faint: false,
    }];
    if let Some(l) = &limits {
        for side in l {
            series.push(Series {
                label: "limits".into(),
                times: &ends,
                values: side.iter().map(|v| v.as_slice()).collect(),
                faint: true,
            });
        }
    }
    let names: Vec<String> = (1..=dof).map(|j| format!("q{j} [rad]")).collect();
    let marks: Vec<(f64, Vec<f64>)> = std::iter::once(0.0)
        .chain(exp.config.task.via.iter().map(|v| v.time))
        .chain(std::iter::once(exp.config.task.dmp.tau))
        .zip(&outcome.way_configurations)
        .map(|(t, q)| (t, q.clone()))
        .collect();
    crate::plots::panels(stage, "joints", &names, &series, &marks)
}

fn write_report(stage: &Staging, exp: &Experiment, s: &Summary<'_>) -> Result<()> {
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
    report::write(
        stage,
        &s.header,
        &format!("{}: via points learned in joint space", exp.name),
        "The way points are converted to joint configurations by inverse kinematics (one branch), one DMP per joint carries the movement, and the via-point and goal errors are judged in task space through forward kinematics, with joint-limit and speed-limit penalties.",
        &[Table::pairs("Result", rows)],
        &[
            (
                "joints",
                "Joint angles over time with their limits (grey); dots are the way points' IK configurations.",
            ),
            (
                "coordinates",
                "The tool in task space (forward kinematics); dots are the way points.",
            ),
            ("path3d", "The tool's path in 3-D."),
            ("cost", "Best cost so far per generation."),
        ],
    )
}
