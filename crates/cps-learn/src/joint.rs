//! Joint-space via-point learning: the thesis's second variant.
//!
//! The way points are converted to joint configurations by inverse kinematics within the
//! joint limits, each solve seeded by the previous one so that they stay on one branch.
//! One DMP per joint (goal-robust formulation: a joint whose start equals its goal still
//! has a forcing term) carries the movement. The cost is judged where the task lives:
//!
//! ```text
//! C = w_goal ‖FK(q_T) − g‖² + w_via Σ_i ‖FK(q(t_i)) − p_i‖²        (task space, metres)
//!   + w_vel ‖q̇_T‖² + w_acc Σ_k ‖q̈_k‖² + w_jerk Σ_k ‖(q̈_{k+1} − q̈_k)/h‖²   (joint space)
//!   + w_limit Σ_k Σ_j excess_j(q_k)² + w_speed Σ_k Σ_j excess_j(|q̇_k|)²
//! ```
//!
//! with `excess` the amount by which a joint leaves its position range (narrowed by
//! [`LIMIT_MARGIN`] at each end) or exceeds its speed limit (radians, rad/s). The cost is
//! not quadratic in the weights (forward kinematics is in it). Its warm start is the exact
//! optimum of the joint-space surrogate (the via-point cost on the IK configurations),
//! which is quadratic; from there Levenberg–Marquardt on the residuals
//! ([`Solver::LeastSquares`]) or CMA-ES learns the rest (the arm is redundant: other
//! configurations at the via points need less joint acceleration).

use std::ops::ControlFlow;
use std::time::Instant;

use cps_cmaes::GenerationReport;
use cps_dmp::{DiscreteDmp, Formulation, Trajectory};
use cps_kinematics::KinematicsError;
use cps_robot::{Plan, Recording, Robot, StopToken, move_to};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::viapoint::{Buffered, BufferedCost, run_cmaes};
use crate::{
    LearnError, RobotSetup, SearchSpace, SearchStats, Solver, TaskErrors, ViaPoint, ViaPointConfig,
    ViaPointTask, check_way_points, exact_optimum,
};

/// How far inside each position limit the limit penalty starts, radians. A penalty lets
/// its optimum lie a hair beyond where it starts (where the penalty's pull balances the
/// rest of the cost); starting it 1e-4 rad inside keeps that hair within the limits.
pub const LIMIT_MARGIN: f64 = 1e-4;

/// Judged on an execution, the final-velocity weight is the robot's, and the command must
/// end at rest as a limit (weighted as the position limits): a plan's spline stops at its
/// last point, so a command still moving there ends in a jump of acceleration — and of
/// torque, beyond a real arm's torque-rate limit. Its final acceleration counts as the
/// velocity it would build in this many seconds.
pub const END_AT_REST: f64 = 0.1;

/// Settings of [`learn_joint_space`].
#[derive(Debug, Clone)]
pub struct JointSpaceConfig {
    /// The task in task space (way points in metres, DMP settings, cost weights) and the
    /// CMA-ES settings (σ₀ in radians of anchor offset for the default search space).
    pub learner: ViaPointConfig,
    /// The robot: its model converts and judges, its limits are penalised.
    pub robot: RobotSetup,
    /// Weight of the squared joint-position-limit excess (rad²), summed over samples.
    pub limit_weight: f64,
    /// Weight of the squared joint-speed-limit excess ((rad/s)²), summed over samples.
    pub speed_limit_weight: f64,
    /// The clearance the movement keeps from the robot's own shapes and its scene's
    /// (None: not part of the cost).
    pub clearance: Option<crate::Clearance>,
}

impl JointSpaceConfig {
    /// Defaults around a learner and a robot: limit weights 1e6 and 1e3.
    pub fn new(learner: ViaPointConfig, robot: RobotSetup) -> Self {
        Self {
            learner,
            robot,
            limit_weight: 1e6,
            speed_limit_weight: 1e3,
            clearance: None,
        }
    }
}

/// The joint-space cost term by term.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct JointCostBreakdown {
    /// Goal term (task space).
    pub goal: f64,
    /// Via-point term (task space).
    pub via: f64,
    /// Final joint velocity term.
    pub final_velocity: f64,
    /// Joint acceleration term.
    pub acceleration: f64,
    /// Joint jerk term.
    pub jerk: f64,
    /// Position-limit penalty.
    pub joint_limits: f64,
    /// Speed-limit penalty.
    pub speed_limits: f64,
    /// Position-limit penalty on the executed joints (0 when judged on the model).
    #[serde(default)]
    pub executed_joint_limits: f64,
    /// Clearance penalty: the squared shortfall of every pair closer than the clearance
    /// (0 without one).
    #[serde(default)]
    pub clearance: f64,
}

impl JointCostBreakdown {
    /// The sum of the terms.
    pub fn total(&self) -> f64 {
        self.goal
            + self.via
            + self.final_velocity
            + self.acceleration
            + self.jerk
            + self.joint_limits
            + self.speed_limits
            + self.executed_joint_limits
            + self.clearance
    }
}

/// How close a joint trajectory comes to the robot's limits.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct LimitReport {
    /// Largest excess beyond a position limit over samples and joints (rad; 0 = within).
    pub max_position_excess: f64,
    /// Smallest distance to a position limit over samples and joints (rad; negative when
    /// outside).
    pub min_position_margin: f64,
    /// Largest `|q̇_j| / v_max_j` over samples and joints (≤ 1 = within the speed limits).
    pub max_speed_ratio: f64,
}

impl LimitReport {
    /// True if no limit is exceeded.
    pub fn within(&self) -> bool {
        self.max_position_excess == 0.0 && self.max_speed_ratio <= 1.0
    }
}

/// The joint-space cost of a task on a robot, over the joint DMP's trajectories.
#[derive(Debug, Clone)]
pub struct JointSpaceCost<'a> {
    task: &'a ViaPointTask,
    robot: &'a RobotSetup,
    limit_weight: f64,
    speed_limit_weight: f64,
    clearance: Option<&'a crate::Clearance>,
}

impl<'a> JointSpaceCost<'a> {
    /// The cost `config` describes: its task, robot and limit weights.
    pub fn new(config: &'a JointSpaceConfig) -> Self {
        JointSpaceCost {
            task: &config.learner.task,
            robot: &config.robot,
            limit_weight: config.limit_weight,
            speed_limit_weight: config.speed_limit_weight,
            clearance: config.clearance.as_ref(),
        }
    }

    /// The cost of a joint trajectory, term by term.
    pub fn breakdown(&self, traj: &Trajectory) -> Result<JointCostBreakdown, KinematicsError> {
        self.breakdown_of(traj, None)
    }

    /// The cost of a commanded joint trajectory, term by term, with the goal, via-point
    /// and final-velocity terms judged on what a robot did with it when `executed` is
    /// given (and its executed positions' limit excess in `executed_joint_limits`).
    pub fn breakdown_of(
        &self,
        traj: &Trajectory,
        executed: Option<&ExecutedJoints>,
    ) -> Result<JointCostBreakdown, KinematicsError> {
        let w = &self.task.weights;
        let dof = traj.dims();
        let reached = Reached::new(traj, executed);
        let chain = &self.robot.chain;
        let mut b = JointCostBreakdown::default();
        let mut q = vec![0.0; dof];
        let mut dist2 = |t: Option<f64>, p: &[f64]| -> Result<f64, KinematicsError> {
            reached.q_at(t, &mut q);
            let x = chain.fk(&q)?.translation.vector;
            Ok((x - Vector3::new(p[0], p[1], p[2])).norm_squared())
        };
        b.goal = w.goal * dist2(None, &self.task.goal)?;
        for v in &self.task.via {
            b.via += w.via * dist2(Some(v.time), &v.position)?;
        }
        let h = traj.times()[1] - traj.times()[0];
        let limits = chain.limits();
        let speeds = chain.velocity_limits();
        for j in 0..dof {
            let (q, v, a) = (traj.position(j), traj.velocity(j), traj.acceleration(j));
            let (v_end, a_end) = (v[v.len() - 1], a[a.len() - 1]);
            match executed {
                None => b.final_velocity += w.final_velocity * v_end * v_end,
                // The robot ends at rest, and the command must end at rest (see
                // [`END_AT_REST`]).
                Some(e) => {
                    b.final_velocity += w.final_velocity * e.final_velocity(j).powi(2);
                    b.joint_limits +=
                        self.limit_weight * (v_end.powi(2) + (END_AT_REST * a_end).powi(2));
                }
            }
            if w.acceleration > 0.0 {
                b.acceleration += w.acceleration * a.iter().map(|a| a * a).sum::<f64>();
            }
            if w.jerk > 0.0 {
                b.jerk += w.jerk
                    * a.windows(2)
                        .map(|p| ((p[1] - p[0]) / h).powi(2))
                        .sum::<f64>();
            }
            if let Some((lo, hi)) = limits {
                let excess = |x: f64| limit_excess(x, lo[j], hi[j]).powi(2);
                b.joint_limits += self.limit_weight * q.iter().map(|&x| excess(x)).sum::<f64>();
                if let Some(e) = executed {
                    b.executed_joint_limits +=
                        self.limit_weight * e.q.iter().map(|q| excess(q[j])).sum::<f64>();
                }
            }
            if let Some(vmax) = speeds {
                let excess: f64 = v
                    .iter()
                    .map(|&x| (x.abs() - vmax[j]).max(0.0).powi(2))
                    .sum();
                b.speed_limits += self.speed_limit_weight * excess;
            }
        }
        if let Some(c) = self.clearance {
            let mut buffers = crate::clearance::ClearanceBuffers::default();
            b.clearance = c.cost(
                chain,
                traj.times().len(),
                |j| traj.position(j),
                &mut buffers,
            )?;
        }
        Ok(b)
    }

    /// Writes the cost's weighted residuals into `out` (cleared first): their squares sum
    /// to [`Self::breakdown`]'s total. The limit terms are hinges (zero within the limits),
    /// so the count does not depend on the trajectory.
    pub fn residuals(&self, traj: &Trajectory, out: &mut Vec<f64>) -> Result<(), KinematicsError> {
        self.residuals_of(traj, None, out)
    }

    /// [`Self::residuals`] with the task terms judged on `executed` when it is given
    /// (their squares sum to [`Self::breakdown_of`]'s total): the executed positions'
    /// limit hinges come last, one per point and joint.
    pub fn residuals_of(
        &self,
        traj: &Trajectory,
        executed: Option<&ExecutedJoints>,
        out: &mut Vec<f64>,
    ) -> Result<(), KinematicsError> {
        let w = &self.task.weights;
        let dof = traj.dims();
        let reached = Reached::new(traj, executed);
        let chain = &self.robot.chain;
        out.clear();
        let mut q = vec![0.0; dof];
        let mut tool_error = |t: Option<f64>, p: &[f64], s: f64, out: &mut Vec<f64>| {
            reached.q_at(t, &mut q);
            let x = chain.fk(&q)?.translation.vector;
            out.extend((0..3).map(|i| s * (x[i] - p[i])));
            Ok::<(), KinematicsError>(())
        };
        tool_error(None, &self.task.goal, w.goal.sqrt(), out)?;
        for v in &self.task.via {
            tool_error(Some(v.time), &v.position, w.via.sqrt(), out)?;
        }
        let h = traj.times()[1] - traj.times()[0];
        let limits = chain.limits();
        let speeds = chain.velocity_limits();
        let (sv, sa, sj) = (
            w.final_velocity.sqrt(),
            w.acceleration.sqrt(),
            w.jerk.sqrt() / h,
        );
        let (sl, ss) = (self.limit_weight.sqrt(), self.speed_limit_weight.sqrt());
        for j in 0..dof {
            let (q, v, a) = (traj.position(j), traj.velocity(j), traj.acceleration(j));
            let (v_end, a_end) = (v[v.len() - 1], a[a.len() - 1]);
            match executed {
                None => out.push(sv * v_end),
                Some(e) => out.extend([
                    sv * e.final_velocity(j),
                    sl * v_end,
                    sl * END_AT_REST * a_end,
                ]),
            }
            if w.acceleration > 0.0 {
                out.extend(a.iter().map(|a| sa * a));
            }
            if w.jerk > 0.0 {
                out.extend(a.windows(2).map(|p| sj * (p[1] - p[0])));
            }
            if let Some((lo, hi)) = limits {
                out.extend(q.iter().map(|&x| sl * limit_excess(x, lo[j], hi[j])));
            }
            if let Some(vmax) = speeds {
                out.extend(v.iter().map(|&x| ss * (x.abs() - vmax[j]).max(0.0)));
            }
        }
        if let (Some(e), Some((lo, hi))) = (executed, limits) {
            for j in 0..dof {
                out.extend(e.q.iter().map(|q| sl * limit_excess(q[j], lo[j], hi[j])));
            }
        }
        if let Some(c) = self.clearance {
            let mut buffers = crate::clearance::ClearanceBuffers::default();
            c.residuals(
                chain,
                traj.times().len(),
                |j| traj.position(j),
                &mut buffers,
                out,
            )?;
        }
        Ok(())
    }

    /// Task-space errors through forward kinematics: goal and via-point distances, and
    /// the tool's speed at the end (finite difference of the last two samples).
    pub fn task_errors(&self, traj: &Trajectory) -> Result<TaskErrors, KinematicsError> {
        self.task_errors_of(traj, None)
    }

    /// [`Self::task_errors`] of what a robot did with `traj` when `executed` is given.
    pub fn task_errors_of(
        &self,
        traj: &Trajectory,
        executed: Option<&ExecutedJoints>,
    ) -> Result<TaskErrors, KinematicsError> {
        let reached = Reached::new(traj, executed);
        let chain = &self.robot.chain;
        let mut q = vec![0.0; traj.dims()];
        let mut tool = |t: Option<f64>| -> Result<Vector3<f64>, KinematicsError> {
            reached.q_at(t, &mut q);
            Ok(chain.fk(&q)?.translation.vector)
        };
        let p = |v: &[f64]| Vector3::new(v[0], v[1], v[2]);
        let h = reached.period();
        let end = tool(None)?;
        let before = tool(Some(reached.end_time() - h))?;
        Ok(TaskErrors {
            goal: (end - p(&self.task.goal)).norm(),
            via: self
                .task
                .via
                .iter()
                .map(|v| Ok((tool(Some(v.time))? - p(&v.position)).norm()))
                .collect::<Result<_, KinematicsError>>()?,
            final_speed: (end - before).norm() / h,
        })
    }

    /// The limit report of a joint trajectory.
    pub fn limits(&self, traj: &Trajectory) -> LimitReport {
        let chain = &self.robot.chain;
        let mut r = LimitReport {
            max_position_excess: 0.0,
            min_position_margin: f64::INFINITY,
            max_speed_ratio: 0.0,
        };
        for j in 0..traj.dims() {
            if let Some((lo, hi)) = chain.limits() {
                for &x in traj.position(j) {
                    let margin = (hi[j] - x).min(x - lo[j]);
                    r.min_position_margin = r.min_position_margin.min(margin);
                    r.max_position_excess = r.max_position_excess.max(-margin);
                }
            }
            if let Some(v) = chain.velocity_limits() {
                for &x in traj.velocity(j) {
                    r.max_speed_ratio = r.max_speed_ratio.max(x.abs() / v[j]);
                }
            }
        }
        r
    }
}

/// How far `x` lies beyond the range `[lo, hi]` narrowed by [`LIMIT_MARGIN`] (0 inside).
fn limit_excess(x: f64, lo: f64, hi: f64) -> f64 {
    (x - (hi - LIMIT_MARGIN))
        .max(lo + LIMIT_MARGIN - x)
        .max(0.0)
}

/// The joints as a robot executed a commanded joint trajectory: their positions at the
/// plan's points, every `dt` from the start (point 0 at t = 0).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExecutedJoints {
    /// The plan's period (s).
    pub dt: f64,
    /// Measured joint positions at each point (rad).
    pub q: Vec<Vec<f64>>,
}

impl ExecutedJoints {
    /// Joint `j`'s velocity at the end: the last interval's mean.
    fn final_velocity(&self, j: usize) -> f64 {
        let n = self.q.len();
        (self.q[n - 1][j] - self.q[n - 2][j]) / self.dt
    }
}

/// Where the task terms read the joints: the commanded trajectory or its execution.
enum Reached<'a> {
    Commanded(&'a Trajectory),
    Executed(&'a ExecutedJoints),
}

impl<'a> Reached<'a> {
    fn new(traj: &'a Trajectory, executed: Option<&'a ExecutedJoints>) -> Self {
        executed.map_or(Reached::Commanded(traj), Reached::Executed)
    }

    /// The joints at `t` (linear between points, clamped), or at the end for `None`.
    fn q_at(&self, t: Option<f64>, q: &mut [f64]) {
        match self {
            Reached::Commanded(traj) => {
                let last = traj.n_samples() - 1;
                for (j, q) in q.iter_mut().enumerate() {
                    *q = t.map_or(traj.position(j)[last], |t| traj.position_at(j, t));
                }
            }
            Reached::Executed(e) => {
                let last = e.q.len() - 1;
                let s = t.map_or(last as f64, |t| (t / e.dt).clamp(0.0, last as f64));
                let (k, frac) = if (s - s.round()).abs() < 1e-9 {
                    (s.round() as usize, 0.0)
                } else {
                    (s.floor() as usize, s - s.floor())
                };
                for (j, q) in q.iter_mut().enumerate() {
                    *q = if frac == 0.0 {
                        e.q[k][j]
                    } else {
                        e.q[k][j] + frac * (e.q[k + 1][j] - e.q[k][j])
                    };
                }
            }
        }
    }

    /// The sampling period.
    fn period(&self) -> f64 {
        match self {
            Reached::Commanded(traj) => traj.times()[1] - traj.times()[0],
            Reached::Executed(e) => e.dt,
        }
    }

    /// The time of the last sample.
    fn end_time(&self) -> f64 {
        match self {
            Reached::Commanded(traj) => *traj.times().last().unwrap_or(&0.0),
            Reached::Executed(e) => (e.q.len() - 1) as f64 * e.dt,
        }
    }
}

/// The joint-space cost as a CMA-ES objective over the search-space parameters.
struct JointObjective<'a> {
    cost: JointSpaceCost<'a>,
    dmp: &'a DiscreteDmp,
    space: &'a SearchSpace,
}

impl BufferedCost for JointObjective<'_> {
    type Buffers = (Vec<f64>, Trajectory);

    fn buffers(&self) -> Self::Buffers {
        (vec![0.0; self.space.len()], self.dmp.new_trajectory())
    }

    fn cost(&self, x: &[f64], (w, traj): &mut Self::Buffers) -> f64 {
        self.space.to_weights(x, w);
        self.dmp.rollout_into(w, traj);
        // A configuration forward kinematics refuses (NaN) ranks last.
        self.cost
            .breakdown(traj)
            .map_or(f64::INFINITY, |b| b.total())
    }
}

impl crate::lsq::Residuals for JointObjective<'_> {
    type Buffers = (Vec<f64>, Trajectory);

    fn buffers(&self) -> Self::Buffers {
        (vec![0.0; self.space.len()], self.dmp.new_trajectory())
    }

    fn residuals(&self, x: &[f64], (w, traj): &mut Self::Buffers, out: &mut Vec<f64>) -> bool {
        self.space.to_weights(x, w);
        self.dmp.rollout_into(w, traj);
        self.cost.residuals(traj, out).is_ok()
    }
}

/// The result of [`learn_joint_space`].
#[derive(Debug, Clone)]
pub struct JointSpaceOutcome {
    /// The way points in joint space: start, via points, goal (radians).
    pub way_configurations: Vec<Vec<f64>>,
    /// The joint DMPs (goal-robust, start and goal from the IK configurations).
    pub dmp: DiscreteDmp,
    /// The learned weights (joint-major).
    pub weights: Vec<f64>,
    /// Its joint trajectory.
    pub trajectory: Trajectory,
    /// Its cost, term by term.
    pub breakdown: JointCostBreakdown,
    /// The cost of the warm start (the surrogate's exact optimum), term by term.
    pub warm_start: JointCostBreakdown,
    /// The warm start's movement (blind to everything but the way points' configurations).
    pub warm_start_trajectory: Trajectory,
    /// Task-space errors through forward kinematics.
    pub errors: TaskErrors,
    /// How close the trajectory comes to the limits.
    pub limits: LimitReport,
    /// The CMA-ES search (`exact` for the surrogate optimum alone).
    pub search: SearchStats,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// Learns the task in joint space (see the module documentation). `progress` is called
/// after every CMA-ES generation and may stop the run.
pub fn learn_joint_space(
    config: &JointSpaceConfig,
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<JointSpaceOutcome, LearnError> {
    let started = Instant::now();
    let task = &config.learner.task;
    task.validate()?;
    for (name, v) in [
        ("limit_weight", config.limit_weight),
        ("speed_limit_weight", config.speed_limit_weight),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(LearnError::task(
                name,
                format!("must be finite and ≥ 0 (got {v})"),
            ));
        }
    }
    let mut configs = check_way_points(task, &config.robot)?;
    if let Some(c) = &config.clearance {
        configs = crate::robot::clear_way_points(task, &config.robot, c, configs)?;
    }
    let n = configs.len();
    let dof = config.robot.chain.dof();
    let mut dmp_config = task.dmp;
    dmp_config.formulation = Formulation::GoalRobust;
    let surrogate = ViaPointTask {
        obstacles: Vec::new(),
        start: configs[0].clone(),
        goal: configs[n - 1].clone(),
        goal_velocity: vec![0.0; dof],
        via: task
            .via
            .iter()
            .zip(&configs[1..n - 1])
            .map(|(v, q)| ViaPoint {
                time: v.time,
                position: q.clone(),
            })
            .collect(),
        dmp: dmp_config,
        weights: task.weights,
    };
    let dmp = surrogate.build_dmp()?;
    let space = SearchSpace::new(config.learner.parametrisation, &dmp);
    let optimum = exact_optimum(&surrogate, &dmp, &space)?;
    let cost = JointSpaceCost::new(config);
    let joint_objective = JointObjective {
        cost: cost.clone(),
        dmp: &dmp,
        space: &space,
    };
    let warm_trajectory = dmp.rollout(&space.weights(&optimum.params));
    let warm = cost.breakdown(&warm_trajectory)?;
    let x0 = if config.learner.warm_start || config.learner.solver == Solver::Exact {
        optimum.params.clone()
    } else {
        vec![0.0; space.len()]
    };
    let (params, search) = match config.learner.solver {
        Solver::LeastSquares => {
            let settings = crate::lsq::settings(config.learner.generations);
            crate::lsq::levenberg_marquardt(&joint_objective, x0, settings, progress)?
        }
        _ => run_cmaes(
            &Buffered::new(joint_objective),
            x0,
            None,
            &config.learner,
            config.learner.seed,
            progress,
        )?,
    };
    let weights = space.weights(&params);
    let trajectory = dmp.rollout(&weights);
    Ok(JointSpaceOutcome {
        way_configurations: configs,
        breakdown: cost.breakdown(&trajectory)?,
        warm_start: warm,
        warm_start_trajectory: warm_trajectory,
        errors: cost.task_errors(&trajectory)?,
        limits: cost.limits(&trajectory),
        dmp,
        weights,
        trajectory,
        search,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Plays a joint trajectory on `backend`: the robot put at (or moved to) its first
/// configuration, then one commanded configuration per control period (linear
/// interpolation between grid samples) as one plan, recording the tool and the joints.
/// `position_error` is the distance of the measured tool from the model's tool at the
/// commanded configuration. `stop` brakes a robot that moves.
pub fn execute_joint_trajectory(
    backend: &mut dyn Robot,
    robot: &RobotSetup,
    traj: &Trajectory,
    stop: &StopToken,
) -> Result<Recording, LearnError> {
    let dof = traj.dims();
    let start: Vec<f64> = (0..dof).map(|j| traj.position(j)[0]).collect();
    move_to(backend, &start, stop)?;
    let dt = backend.dt();
    let commands = joint_commands(traj, dt);
    let samples = commands.len();
    // One plan: one call on a simulator with cps's scene script, one goal on a ROS 2
    // controller, one stream on a Franka.
    let run = run_whole(backend, commands.clone(), dt, stop)?;
    let mut rec = Recording {
        steps: samples,
        ..Recording::default()
    };
    for (k, q) in commands.iter().enumerate() {
        let (pose, measured, time) = (&run.tool[k], &run.q[k], run.time[k]);
        let want = robot.chain.fk(q)?.translation.vector;
        let p = pose.translation.vector;
        let o = nalgebra::UnitQuaternion::from_rotation_matrix(&pose.rotation);
        rec.time.push(time);
        rec.q.push(measured.clone());
        rec.position.push([p.x, p.y, p.z]);
        rec.orientation.push([o.i, o.j, o.k, o.w]);
        rec.position_error.push((p - want).norm());
        rec.rotation_error.push(0.0);
    }
    Ok(rec)
}

/// A joint trajectory sampled every `dt` from its start to its end: a plan's points.
pub(crate) fn joint_commands(traj: &Trajectory, dt: f64) -> Vec<Vec<f64>> {
    let end = *traj.times().last().unwrap_or(&0.0);
    let samples = (end / dt + 1e-9).floor() as usize + 1;
    (0..samples)
        .map(|k| {
            (0..traj.dims())
                .map(|j| traj.position_at(j, k as f64 * dt))
                .collect()
        })
        .collect()
}

/// Runs `commands` every `dt` as one plan on `robot`; a run that ends early (stopped,
/// failed, a reflex) is the robot's error, with its sentence.
pub(crate) fn run_whole(
    robot: &mut dyn Robot,
    commands: Vec<Vec<f64>>,
    dt: f64,
    stop: &StopToken,
) -> Result<cps_robot::Run, cps_robot::RobotError> {
    let samples = commands.len();
    let run = robot.run(&Plan::new(dt, commands)?, stop)?;
    if !run.ending.complete() || run.len() != samples {
        return Err(cps_robot::RobotError::Robot {
            robot: robot.name(),
            message: format!(
                "asked to run {samples} points, it recorded {}: {}",
                run.len(),
                run.ending.sentence()
            ),
        });
    }
    Ok(run)
}
