//! Learning on executions: each CMA-ES candidate rolled out, executed on a free robot of a
//! [`SimulatorPool`] — reset, run, record — and judged by what the robot did
//! ([`executed_cost`]), through cps-learn's one CMA-ES loop ([`run_cmaes`]).
//!
//! Each candidate's cost depends on the candidate alone (the robot is reset before each),
//! and the costs come back in candidate order, so the result is the same for any pool
//! size and whichever robot ran what. A robot that fails is dropped and its candidate run
//! by another; when none is left, or a stop is asked, the search ends
//! ([`cps_cmaes::EndSearch`]) keeping the best so far.

use std::ops::ControlFlow;
use std::sync::{Mutex, PoisonError};

use cps_cmaes::{CandidateError, EndSearch, GenerationReport, Objective, ObjectiveError};
use cps_dmp::{DiscreteDmp, Trajectory};
use cps_robot::{Recording, Robot, RobotError, StopToken};

use crate::pool::{JobError, PoolError, SimulatorPool};
use crate::robot::{execute_trajectory, targets_at};
use crate::{
    Clearance, ExecutedCost, ExecutedErrors, ExecutedWeights, LearnError, RobotSetup, SearchSpace,
    SearchStats, ViaPointConfig, ViaPointTask, executed_cost, run_cmaes,
};

/// One candidate executed and judged.
pub struct Judged {
    /// Why the guard refused a command of it (then it was not executed to the end, and
    /// costs +∞).
    pub refused: Option<String>,
    /// Its executed cost, term by term.
    pub cost: ExecutedCost,
    /// Its errors as executed.
    pub errors: ExecutedErrors,
    /// What the robot did.
    pub recording: Recording,
    /// The command's times at the robot's period.
    pub times: Vec<f64>,
    /// The commanded movement.
    pub trajectory: Trajectory,
}

/// What the learner needs to judge a candidate.
#[derive(Clone, Copy)]
pub struct Judge<'a> {
    /// The DMP the candidates weight.
    pub dmp: &'a DiscreteDmp,
    /// The search space θ lives in.
    pub space: &'a SearchSpace,
    /// The task whose cost is judged as executed.
    pub task: &'a ViaPointTask,
    /// The robot's chain and initial configuration.
    pub setup: &'a RobotSetup,
    /// The executed cost's own weights.
    pub weights: ExecutedWeights,
    /// With a clearance kept, the robot's shapes and world.
    pub clearance: Option<&'a Clearance>,
    /// Stops an execution under way.
    pub stop: &'a StopToken,
}

impl Judge<'_> {
    /// Rolls θ out, executes it on `backend` from the initial configuration and costs
    /// the recording. A backend failure is the simulator's; anything else is the job's.
    pub fn judge(&self, theta: &[f64], backend: &mut dyn Robot) -> Result<Judged, JobError> {
        let trajectory = self.dmp.rollout(&self.space.weights(theta));
        let recording = match execute_trajectory(backend, self.setup, &trajectory, self.stop) {
            Ok(r) => r,
            // A run the stop ended (the scene script stopped where it was) is the stop's,
            // not a dead simulator's.
            Err(_) if self.stop.is_stopped() => return Err(JobError::Stopped),
            Err(LearnError::Robot(e @ RobotError::Robot { .. })) => {
                return Err(JobError::Simulator(e.to_string()));
            }
            // The guard refused a command (a limit, a collision): the robot holds the one
            // before and the next candidate puts it back at the start.
            Err(LearnError::Robot(RobotError::CommandRefused { reason, .. })) => {
                let (times, _) = targets_at(&trajectory, backend.dt());
                let (cost, errors) = executed_cost(
                    self.task,
                    &trajectory,
                    &times,
                    &Recording::default(),
                    &self.weights,
                    None,
                );
                return Ok(Judged {
                    refused: Some(reason.to_string()),
                    cost,
                    errors,
                    recording: Recording::default(),
                    times,
                    trajectory,
                });
            }
            Err(e) => return Err(JobError::Fatal(e.to_string())),
        };
        let (times, _) = targets_at(&trajectory, backend.dt());
        let (mut cost, errors) = executed_cost(
            self.task,
            &trajectory,
            &times,
            &recording,
            &self.weights,
            self.setup.chain.velocity_limits(),
        );
        if let Some(c) = self.clearance {
            cost.add_clearance(c, &self.setup.chain, &recording)
                .map_err(|e| JobError::Fatal(format!("the executed joints' shapes: {e}")))?;
        }
        Ok(Judged {
            refused: None,
            cost,
            errors,
            recording,
            times,
            trajectory,
        })
    }
}

/// Why the search ended before its rules said: a stop asked, or no simulator left.
pub enum Ended {
    /// A stop was asked.
    Stopped,
    /// No simulator is left (each one's reason).
    Failed(String),
}

/// What the search keeps as it goes: the best execution whole, the refusals, and why it
/// ended early.
pub struct Kept {
    /// The best execution so far (the warm start's until a candidate beats it).
    pub best: Judged,
    /// Its cost.
    pub best_cost: f64,
    /// Candidates the guard refused.
    pub refused: u64,
    /// Why the search ended early, if it did.
    pub ended: Option<Ended>,
}

/// The executed cost as CMA-ES's objective: each generation's candidates executed on a
/// free simulator of the pool, in candidate order (the same costs for any pool).
struct Executions<'a> {
    judge: &'a Judge<'a>,
    working: &'a (dyn Fn() -> ControlFlow<()> + Sync),
    pool: Mutex<SimulatorPool>,
    kept: Mutex<Kept>,
}

impl Objective for Executions<'_> {
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
        cps_cmaes::evaluate_through_batch(self, x)
    }

    /// Ctrl-C stops handing out candidates at once (a generation on slow simulators takes
    /// a while), and a pool with no simulator left ends the search: either way the
    /// generation is not counted ([`EndSearch`]).
    fn evaluate_batch(
        &self,
        xs: &[f64],
        dim: usize,
        out: &mut [f64],
    ) -> Result<(), CandidateError> {
        let mut pool = self.pool.lock().unwrap_or_else(PoisonError::into_inner);
        let run = pool.run(out.len(), &|i, b| {
            if (self.working)().is_break() {
                return Err(JobError::Stopped);
            }
            self.judge.judge(&xs[i * dim..(i + 1) * dim], b)
        });
        let mut kept = self.kept.lock().unwrap_or_else(PoisonError::into_inner);
        let judged = match run {
            Ok(j) => j,
            Err(e) => {
                kept.ended = Some(match e {
                    PoolError::Stopped => Ended::Stopped,
                    e => Ended::Failed(pool_failure(e, &pool, "evaluating candidates")),
                });
                return Err(CandidateError {
                    index: 0,
                    source: Box::new(EndSearch),
                });
            }
        };
        kept.refused += judged.iter().filter(|j| j.refused.is_some()).count() as u64;
        for (o, j) in out.iter_mut().zip(&judged) {
            *o = j.cost.total();
        }
        // The first of equal costs wins: the same choice for any pool.
        if let Some((i, c)) = out
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .filter(|(_, c)| **c < kept.best_cost)
        {
            kept.best_cost = *c;
            kept.best = judged.into_iter().nth(i).expect("a judged candidate");
        }
        Ok(())
    }
}

/// A pool that could not finish, in words: every simulator gone (with each one's reason)
/// or a candidate no simulator can execute.
pub fn pool_failure(e: PoolError, pool: &SimulatorPool, what: &str) -> String {
    match e {
        PoolError::Fatal(m) => format!("{what}: {m}"),
        PoolError::Stopped => format!("{what}: interrupted"),
        PoolError::Exhausted => {
            let why: Vec<String> = pool
                .dropped()
                .iter()
                .map(|d| format!("{} ({})", d.endpoint, d.reason))
                .collect();
            format!(
                "{what}: every simulator of the pool is gone: {}",
                why.join("; ")
            )
        }
    }
}

/// CMA-ES on the executed cost over `pool`, from `x0`, whose execution `warm` is the best
/// so far (not executed again); `progress` sees every generation, `working` is asked before
/// each execution whether to go on. What the search kept, its statistics, and the pool
/// (which robots ran, which were dropped).
pub fn learn_on_executions(
    judge: &Judge<'_>,
    pool: SimulatorPool,
    warm: Judged,
    x0: Vec<f64>,
    config: &ViaPointConfig,
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
    working: &(dyn Fn() -> ControlFlow<()> + Sync),
) -> Result<(Kept, SearchStats, SimulatorPool), LearnError> {
    let warm_cost = warm.cost.total();
    let executions = Executions {
        judge,
        working,
        pool: Mutex::new(pool),
        kept: Mutex::new(Kept {
            best: warm,
            best_cost: warm_cost,
            refused: 0,
            ended: None,
        }),
    };
    let (_, stats) = run_cmaes(
        &executions,
        x0,
        Some(warm_cost),
        config,
        config.seed,
        progress,
    )?;
    let kept = executions
        .kept
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner);
    let pool = executions
        .pool
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner);
    Ok((kept, stats, pool))
}
