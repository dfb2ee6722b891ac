//! Via-point learning with a control-effort term (thesis eq. 53/54): the DMP is the
//! desired movement of a simulated plant that a PD controller makes follow it, and the
//! cost judges what the plant did and what the controller spent.
//!
//! Plant: a point mass `m` per axis, `m ÿ = u`, with
//! `u = K_p (y* − y) + K_v (ẏ* − ẏ)` tracking the DMP's position `y*` and velocity `ẏ*`
//! (linearly interpolated between DMP samples), integrated by semi-implicit Euler with
//! `substeps` steps per DMP sample, starting at rest at the DMP's start.
//!
//! ```text
//! C = w_goal ‖y_T − g‖² + w_via Σ_i ‖y(t_i) − p_i‖² + w_vel ‖ẏ_T − ġ‖²     (the plant)
//!   + w_acc Σ_k ‖ÿ*_k‖² + w_jerk …                                           (the DMP)
//!   + w_effort Σ_k ‖u_k‖²                                                    (the controller)
//! ```
//!
//! with sums over the DMP samples. Each rollout is a small simulation, so the population
//! is evaluated in parallel; the results do not depend on the number of threads.

use std::ops::ControlFlow;
use std::time::Instant;

use cps_cmaes::GenerationReport;
use cps_dmp::{DiscreteDmp, Trajectory};
use serde::{Deserialize, Serialize};

use crate::exact::AffineResiduals;
use crate::task::Term;
use crate::viapoint::{Buffered, BufferedCost, QuadraticObjective, run_cmaes};
use crate::{
    Evaluation, LearnError, QuadraticCost, SearchSpace, SearchStats, Solver, TaskErrors,
    ViaPointConfig, exact_optimum,
};

/// The simulated plant and its PD controller, the same on every axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PointMassPlant {
    /// Mass in kg. Default 1.
    pub mass: f64,
    /// Position gain `K_p` in N/m. Default 400 (ω = 20 rad/s with 1 kg).
    pub kp: f64,
    /// Velocity gain `K_v` in N·s/m. Default 40 (critically damped with 1 kg).
    pub kv: f64,
    /// Integration steps per DMP sample. Default 10 (1 ms for dt = 0.01 s).
    pub substeps: usize,
}

impl Default for PointMassPlant {
    fn default() -> Self {
        Self {
            mass: 1.0,
            kp: 400.0,
            kv: 40.0,
            substeps: 10,
        }
    }
}

impl PointMassPlant {
    /// Checks the plant; errors name the field.
    pub fn validate(&self, dt: f64) -> Result<(), LearnError> {
        for (name, v) in [("mass", self.mass), ("kp", self.kp), ("kv", self.kv)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(LearnError::task(
                    format!("plant.{name}"),
                    format!("must be finite and > 0 (got {v})"),
                ));
            }
        }
        if self.substeps == 0 || self.substeps > 10_000 {
            return Err(LearnError::task(
                "plant.substeps",
                format!("must be between 1 and 10000 (got {})", self.substeps),
            ));
        }
        // Semi-implicit Euler on the closed loop is stable for h·ω well below 2.
        let h = dt / self.substeps as f64;
        let omega = (self.kp / self.mass).sqrt();
        let zeta_term = self.kv / self.mass * h;
        if omega * h > 0.5 || zeta_term > 1.0 {
            return Err(LearnError::task(
                "plant.substeps",
                format!(
                    "{} substeps of {h:.2e} s are too coarse for these gains (ω·h = {:.2}, K_v·h/m = {:.2}; both must stay below 0.5 and 1): use more substeps",
                    self.substeps,
                    omega * h,
                    zeta_term
                ),
            ));
        }
        Ok(())
    }

    /// Simulates the plant following `traj`: per DMP sample and axis, the plant's position
    /// and velocity and the control force (at the sample's time). `out` is reused.
    pub fn simulate(&self, traj: &Trajectory, out: &mut PlantTrajectory) {
        let dims = traj.dims();
        let n = traj.n_samples();
        out.resize(dims, n);
        let h = if n > 1 {
            (traj.times()[1] - traj.times()[0]) / self.substeps as f64
        } else {
            0.0
        };
        let inv_m = 1.0 / self.mass;
        let frac = 1.0 / self.substeps as f64;
        // The axes are independent: stepping them side by side gives the processor
        // independent dependency chains to overlap.
        let mut y: Vec<f64> = (0..dims).map(|d| traj.position(d)[0]).collect();
        let mut v = vec![0.0; dims];
        for k in 0..n {
            for d in 0..dims {
                let u =
                    self.kp * (traj.position(d)[k] - y[d]) + self.kv * (traj.velocity(d)[k] - v[d]);
                out.position[d][k] = y[d];
                out.velocity[d][k] = v[d];
                out.force[d][k] = u;
            }
            if k + 1 == n {
                break;
            }
            for s in 0..self.substeps {
                let a = s as f64 * frac;
                for d in 0..dims {
                    let (yd, vd) = (traj.position(d), traj.velocity(d));
                    let target = yd[k] + a * (yd[k + 1] - yd[k]);
                    let target_v = vd[k] + a * (vd[k + 1] - vd[k]);
                    let u = self.kp * (target - y[d]) + self.kv * (target_v - v[d]);
                    v[d] += h * u * inv_m;
                    y[d] += h * v[d];
                }
            }
        }
    }
}

/// What the plant did: `[axis][sample]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlantTrajectory {
    /// Positions (m).
    pub position: Vec<Vec<f64>>,
    /// Velocities (m/s).
    pub velocity: Vec<Vec<f64>>,
    /// Control forces (N).
    pub force: Vec<Vec<f64>>,
}

impl PlantTrajectory {
    fn resize(&mut self, dims: usize, n: usize) {
        for v in [&mut self.position, &mut self.velocity, &mut self.force] {
            v.resize(dims, Vec::new());
            for a in v.iter_mut() {
                a.resize(n, 0.0);
            }
        }
    }
}

/// The effort cost term by term.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct EffortCostBreakdown {
    /// Goal term (the plant).
    pub goal: f64,
    /// Via-point term (the plant).
    pub via: f64,
    /// Final-velocity term (the plant).
    pub final_velocity: f64,
    /// Acceleration term (the DMP).
    pub acceleration: f64,
    /// Jerk term (the DMP).
    pub jerk: f64,
    /// Control-effort term.
    pub effort: f64,
}

impl EffortCostBreakdown {
    /// The sum of the terms.
    pub fn total(&self) -> f64 {
        self.goal + self.via + self.final_velocity + self.acceleration + self.jerk + self.effort
    }
}

/// Settings of [`learn_with_effort`].
#[derive(Debug, Clone)]
pub struct EffortConfig {
    /// The via-point task, its cost weights and the CMA-ES settings.
    pub learner: ViaPointConfig,
    /// The plant and controller.
    pub plant: PointMassPlant,
    /// Weight of the control effort `Σ_k ‖u_k‖²` (N²). Thesis symbol `H_E`.
    pub effort_weight: f64,
}

/// The effort cost's weighted residuals (their squares sum to [`effort_cost`]'s total):
/// the DMP's acceleration and jerk, the plant's goal, via-point and final-velocity
/// errors, the control forces. The plant is linear and starts at the DMP's start, so every
/// residual is affine in the DMP's weights.
fn residuals(
    config: &EffortConfig,
    traj: &Trajectory,
    plant: &mut PlantTrajectory,
    out: &mut Vec<f64>,
) {
    let task = &config.learner.task;
    config.plant.simulate(traj, plant);
    out.clear();
    task.residuals(traj, |term, r| {
        if matches!(term, Term::Acceleration | Term::Jerk) {
            out.push(r)
        }
    });
    let w = &task.weights;
    let (sg, sv, sf, se) = (
        w.goal.sqrt(),
        w.via.sqrt(),
        w.final_velocity.sqrt(),
        config.effort_weight.sqrt(),
    );
    let last = traj.n_samples() - 1;
    for d in 0..traj.dims() {
        let (y, v, u) = (&plant.position[d], &plant.velocity[d], &plant.force[d]);
        out.push(sg * (y[last] - task.goal[d]));
        out.push(sf * (v[last] - task.goal_velocity[d]));
        for p in &task.via {
            out.push(sv * (at_time(traj, y, p.time) - p.position[d]));
        }
        out.extend(u.iter().map(|u| se * u));
    }
}

/// A plant signal `y` (one value per DMP sample) at time `t`, linearly interpolated.
fn at_time(traj: &Trajectory, y: &[f64], t: f64) -> f64 {
    let (k, frac) = traj.locate(t);
    if frac == 0.0 {
        y[k]
    } else {
        y[k] + frac * (y[k + 1] - y[k])
    }
}

/// The effort cost of a DMP trajectory `traj` through the plant, term by term (`plant`
/// is reused for the simulation).
pub fn effort_cost(
    config: &EffortConfig,
    traj: &Trajectory,
    plant: &mut PlantTrajectory,
) -> EffortCostBreakdown {
    let task = &config.learner.task;
    config.plant.simulate(traj, plant);
    let mut b = EffortCostBreakdown::default();
    // The DMP-side terms (acceleration, jerk) come from the task's own residuals.
    task.residuals(traj, |term, r| match term {
        Term::Acceleration => b.acceleration += r * r,
        Term::Jerk => b.jerk += r * r,
        _ => {}
    });
    let w = &task.weights;
    let last = traj.n_samples() - 1;
    for d in 0..traj.dims() {
        let (y, v, u) = (&plant.position[d], &plant.velocity[d], &plant.force[d]);
        b.goal += w.goal * (y[last] - task.goal[d]).powi(2);
        b.final_velocity += w.final_velocity * (v[last] - task.goal_velocity[d]).powi(2);
        for p in &task.via {
            b.via += w.via * (at_time(traj, y, p.time) - p.position[d]).powi(2);
        }
        b.effort += config.effort_weight * u.iter().map(|u| u * u).sum::<f64>();
    }
    b
}

struct EffortObjective<'a> {
    config: &'a EffortConfig,
    dmp: &'a DiscreteDmp,
    space: &'a SearchSpace,
}

impl BufferedCost for EffortObjective<'_> {
    type Buffers = (Vec<f64>, Trajectory, PlantTrajectory);

    fn buffers(&self) -> Self::Buffers {
        (
            vec![0.0; self.space.len()],
            self.dmp.new_trajectory(),
            PlantTrajectory::default(),
        )
    }

    fn cost(&self, x: &[f64], (w, traj, plant): &mut Self::Buffers) -> f64 {
        self.space.to_weights(x, w);
        self.dmp.rollout_into(w, traj);
        effort_cost(self.config, traj, plant).total()
    }
}

/// The result of [`learn_with_effort`].
#[derive(Debug, Clone)]
pub struct EffortOutcome {
    /// The DMP.
    pub dmp: DiscreteDmp,
    /// The learned weights.
    pub weights: Vec<f64>,
    /// The DMP's trajectory (the controller's reference).
    pub reference: Trajectory,
    /// What the plant did.
    pub plant: PlantTrajectory,
    /// The cost term by term.
    pub breakdown: EffortCostBreakdown,
    /// The exact optimum's cost term by term (the cost is quadratic in the weights: the
    /// plant is linear). With [`Solver::Exact`] it is the result.
    pub optimum: EffortCostBreakdown,
    /// Condition number of the cost's Hessian in the search space used.
    pub hessian_condition: f64,
    /// How CMA-ES evaluated candidates ([`Evaluation::Rollout`] for the exact solver,
    /// which evaluates none).
    pub evaluation: Evaluation,
    /// The cost of the start point (zero weights, or the warm start), term by term.
    pub start: EffortCostBreakdown,
    /// The plant's errors: goal, via points, final speed.
    pub errors: TaskErrors,
    /// The CMA-ES search.
    pub search: SearchStats,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// Learns the via-point task through the plant with the effort term (see the module
/// documentation).
///
/// The plant is linear, so the cost is quadratic in the weights: its exact optimum is
/// found first (rollouts of unit vectors through the plant, then least squares).
/// [`Solver::Exact`] returns it; CMA-ES learns from zero weights or, with the warm start,
/// from the exact optimum of the plain via-point cost (the DMP alone, without the
/// plant), and is judged against it. `progress` is called after every generation and may
/// stop the run.
pub fn learn_with_effort(
    config: &EffortConfig,
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<EffortOutcome, LearnError> {
    let started = Instant::now();
    let task = &config.learner.task;
    let dmp = task.build_dmp()?;
    config.plant.validate(dmp.config().step())?;
    if !(config.effort_weight.is_finite() && config.effort_weight >= 0.0) {
        return Err(LearnError::task(
            "plant.effort_weight",
            format!("must be finite and ≥ 0 (got {})", config.effort_weight),
        ));
    }
    let space = SearchSpace::new(config.learner.parametrisation, &dmp);
    // The cost is a sum of squared residuals affine in the weights: its exact optimum.
    let mut plant = PlantTrajectory::default();
    let affine = AffineResiduals::of(&dmp, &space, |traj, out| {
        residuals(config, traj, &mut plant, out)
    })?;
    let (optimum_params, hessian_condition) = affine.solve()?;
    let optimum = effort_cost(
        config,
        &dmp.rollout(&space.weights(&optimum_params)),
        &mut plant,
    );
    let learner = &config.learner;
    // Least squares on a quadratic cost is the exact solve.
    let (start, params, search, evaluation) = if learner.solver != Solver::Cmaes {
        (
            optimum,
            optimum_params,
            SearchStats::exact(),
            Evaluation::Rollout,
        )
    } else {
        // CMA-ES from zero weights, or from the exact optimum of the plain via-point
        // cost (the DMP alone), which the plant lags behind.
        let x0 = if learner.warm_start {
            exact_optimum(task, &dmp, &space)?.params
        } else {
            vec![0.0; space.len()]
        };
        let start = effort_cost(config, &dmp.rollout(&space.weights(&x0)), &mut plant);
        let quadratic;
        let rollouts;
        let (objective, evaluation): (&dyn cps_cmaes::Objective, _) = match learner.evaluation {
            Evaluation::Auto | Evaluation::Quadratic => {
                quadratic = QuadraticCost::from_affine(&affine)?;
                (&QuadraticObjective(&quadratic), Evaluation::Quadratic)
            }
            Evaluation::Rollout => {
                rollouts = Buffered::new(EffortObjective {
                    config,
                    dmp: &dmp,
                    space: &space,
                });
                (&rollouts, Evaluation::Rollout)
            }
        };
        let (params, search) = run_cmaes(objective, x0, None, learner, learner.seed, progress)?;
        (start, params, search, evaluation)
    };
    let weights = space.weights(&params);
    let reference = dmp.rollout(&weights);
    let breakdown = effort_cost(config, &reference, &mut plant);
    let last = reference.n_samples() - 1;
    let dims = reference.dims();
    let dist = |f: &dyn Fn(usize) -> f64| (0..dims).map(|d| f(d).powi(2)).sum::<f64>().sqrt();
    let errors = TaskErrors {
        goal: dist(&|d| plant.position[d][last] - task.goal[d]),
        via: task
            .via
            .iter()
            .map(|p| {
                let (k, frac) = reference.locate(p.time);
                dist(&|d| {
                    let y = &plant.position[d];
                    let at = if frac == 0.0 {
                        y[k]
                    } else {
                        y[k] + frac * (y[k + 1] - y[k])
                    };
                    at - p.position[d]
                })
            })
            .collect(),
        final_speed: dist(&|d| plant.velocity[d][last]),
    };
    Ok(EffortOutcome {
        dmp,
        weights,
        reference,
        plant,
        breakdown,
        optimum,
        hessian_condition,
        evaluation,
        start,
        errors,
        search,
        seconds: started.elapsed().as_secs_f64(),
    })
}
