//! Joint-space via-point learning on what the robot does: the command learned on the
//! model ([`learn_joint_space`](crate::learn_joint_space)) is refined until the robot,
//! executing it, passes the via points at their times and ends at the goal at rest.
//!
//! Every evaluation executes the candidate command on a robot — in practice the robot
//! with dynamics of `cps-dynamics`, whose joint controller lags its command — put at the
//! start first, and judges its recording ([`JointSpaceCost::residuals_of`]): the goal,
//! via-point and final-velocity terms on the executed joints, the acceleration, jerk and
//! limit terms on the command (what the controller is sent), and the executed joints'
//! position-limit hinges. Levenberg–Marquardt searches the command's DMP weights, its
//! Jacobian by forward differences (one execution a column, columns in parallel, one
//! robot per worker), from the model-learned command.
//!
//! Executions must be repeatable: the same command from the same start gives the same
//! recording (a simulated robot; noise, if any, drawn from a seed every run). The robots
//! run candidates unguarded by the caller's choice: the cost keeps the command within
//! the joints' range and speeds, and the result goes through the guard when executed.

use std::ops::ControlFlow;
use std::time::Instant;

use cps_cmaes::GenerationReport;
use cps_dmp::{DiscreteDmp, Trajectory};
use cps_robot::{Robot, RobotError, StopToken};

use crate::joint::{ExecutedJoints, joint_commands, run_whole};
use crate::{
    JointCostBreakdown, JointSpaceConfig, JointSpaceCost, JointSpaceOutcome, LearnError,
    LimitReport, SearchSpace, SearchStats, TaskErrors,
};

/// Opens one robot to execute candidates on (called once per worker).
pub type OpenRobot<'a> = dyn Fn() -> Result<Box<dyn Robot>, RobotError> + Sync + 'a;

/// Where and how [`learn_joint_executed`] executes its candidates.
pub struct ExecutedSearch<'a> {
    /// Opens a robot that can be put at the start ([`Robot::teleport`]) and repeats an
    /// execution exactly.
    pub open: &'a OpenRobot<'a>,
    /// The plans' period (s): the command is the trajectory sampled at it.
    pub dt: f64,
    /// Levenberg–Marquardt's iteration budget.
    pub iterations: u64,
    /// Stops the search (the executions under way are cut short; the best so far is kept).
    pub stop: &'a StopToken,
}

/// The result of [`learn_joint_executed`].
#[derive(Debug, Clone)]
pub struct ExecutedJointOutcome {
    /// The learned command's DMP weights (joint-major; the DMP is the model-learned one's).
    pub weights: Vec<f64>,
    /// The learned command.
    pub trajectory: Trajectory,
    /// What the robot did with it.
    pub executed: ExecutedJoints,
    /// Its cost as executed, term by term.
    pub breakdown: JointCostBreakdown,
    /// The model-learned command's cost as executed (the search's start).
    pub warm_start: JointCostBreakdown,
    /// Task-space errors as executed.
    pub errors: TaskErrors,
    /// The model-learned command's task-space errors as executed.
    pub warm_start_errors: TaskErrors,
    /// What the robot did with the model-learned command.
    pub warm_start_executed: ExecutedJoints,
    /// The learned command's task-space errors on the model (what it commands).
    pub commanded_errors: TaskErrors,
    /// How close the command comes to the limits.
    pub limits: LimitReport,
    /// The search.
    pub search: SearchStats,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// Executes `traj` sampled every `dt` on `robot`, put at the trajectory's start first.
fn execute(
    robot: &mut dyn Robot,
    traj: &Trajectory,
    dt: f64,
    stop: &StopToken,
    into: &mut ExecutedJoints,
) -> Result<(), RobotError> {
    let commands = joint_commands(traj, dt);
    if commands.len() < 2 {
        return Err(RobotError::Robot {
            robot: robot.name(),
            message: format!(
                "a movement of {} s is shorter than one plan period ({dt} s)",
                traj.times().last().unwrap_or(&0.0)
            ),
        });
    }
    if !robot.teleport(&commands[0])? {
        return Err(RobotError::Robot {
            robot: robot.name(),
            message: "cannot be put at the start: learning on executions needs a simulated robot (backend = \"dynamics\")".into(),
        });
    }
    let run = run_whole(robot, commands, dt, stop)?;
    into.dt = dt;
    into.q = run.q;
    Ok(())
}

/// The executed cost as residuals of the search-space parameters.
struct ExecutedObjective<'a> {
    cost: JointSpaceCost<'a>,
    dmp: &'a DiscreteDmp,
    space: &'a SearchSpace,
    search: &'a ExecutedSearch<'a>,
}

impl crate::lsq::Residuals for ExecutedObjective<'_> {
    type Buffers = (Vec<f64>, Trajectory, Option<Box<dyn Robot>>, ExecutedJoints);

    fn buffers(&self) -> Self::Buffers {
        (
            vec![0.0; self.space.len()],
            self.dmp.new_trajectory(),
            (self.search.open)().ok(),
            ExecutedJoints::default(),
        )
    }

    fn residuals(
        &self,
        x: &[f64],
        (w, traj, robot, executed): &mut Self::Buffers,
        out: &mut Vec<f64>,
    ) -> bool {
        let Some(robot) = robot else { return false };
        self.space.to_weights(x, w);
        self.dmp.rollout_into(w, traj);
        execute(
            robot.as_mut(),
            traj,
            self.search.dt,
            self.search.stop,
            executed,
        )
        .is_ok()
            && self.cost.residuals_of(traj, Some(executed), out).is_ok()
    }
}

/// Refines `learned` (the command [`learn_joint_space`](crate::learn_joint_space) found on
/// the model for `config`) until the robot executing it passes the via points and ends
/// at the goal (see the module documentation). `progress` is called after every
/// iteration and may stop the search.
///
/// Errors: a robot that cannot be opened, put at the start or run the model-learned
/// command (its sentence), a cost forward kinematics cannot evaluate.
pub fn learn_joint_executed(
    config: &JointSpaceConfig,
    learned: &JointSpaceOutcome,
    search: &ExecutedSearch<'_>,
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<ExecutedJointOutcome, LearnError> {
    let started = Instant::now();
    if !(search.dt.is_finite() && search.dt > 0.0) {
        return Err(LearnError::task(
            "dt",
            format!("must be finite and > 0 (got {})", search.dt),
        ));
    }
    let cost = JointSpaceCost::new(config);
    let dmp = &learned.dmp;
    let space = SearchSpace::new(config.learner.parametrisation, dmp);
    // The start, executed once here so that a robot that cannot run it says why.
    let mut robot = (search.open)()?;
    let mut warm = ExecutedJoints::default();
    execute(
        robot.as_mut(),
        &learned.trajectory,
        search.dt,
        search.stop,
        &mut warm,
    )?;
    drop(robot);
    let warm_start = cost.breakdown_of(&learned.trajectory, Some(&warm))?;
    let warm_start_errors = cost.task_errors_of(&learned.trajectory, Some(&warm))?;
    let objective = ExecutedObjective {
        cost: cost.clone(),
        dmp,
        space: &space,
        search,
    };
    let x0 = space.to_params(&learned.weights);
    // Executions are costly and the executed via points nearly linear in the command
    // (the controller is): the Jacobian is kept while its steps gain.
    let settings = crate::lsq::LmSettings {
        reuse_jacobian: true,
        ..crate::lsq::settings(search.iterations)
    };
    let (params, mut stats) = crate::lsq::levenberg_marquardt(&objective, x0, settings, progress)?;
    if search.stop.is_stopped() {
        stats.termination = "interrupted".into();
    }
    let weights = space.weights(&params);
    let trajectory = dmp.rollout(&weights);
    let mut robot = (search.open)()?;
    let mut executed = ExecutedJoints::default();
    // The best command, executed once more for its recording (a stop cuts it short: the
    // start's recording stands in).
    let (trajectory, weights) = match execute(
        robot.as_mut(),
        &trajectory,
        search.dt,
        search.stop,
        &mut executed,
    ) {
        Ok(()) => (trajectory, weights),
        Err(_) if search.stop.is_stopped() => {
            executed.clone_from(&warm);
            (learned.trajectory.clone(), learned.weights.clone())
        }
        Err(e) => return Err(e.into()),
    };
    Ok(ExecutedJointOutcome {
        breakdown: cost.breakdown_of(&trajectory, Some(&executed))?,
        errors: cost.task_errors_of(&trajectory, Some(&executed))?,
        commanded_errors: cost.task_errors(&trajectory)?,
        limits: cost.limits(&trajectory),
        warm_start,
        warm_start_errors,
        warm_start_executed: warm,
        weights,
        trajectory,
        executed,
        search: stats,
        seconds: started.elapsed().as_secs_f64(),
    })
}
