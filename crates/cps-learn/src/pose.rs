//! Via-point learning of a whole tool pose: three position DMPs and one orientation DMP
//! on unit quaternions ([`QuaternionDmp`]), with orientation targets at the via points.
//!
//! The cost separates: the position terms depend only on the position DMPs' weights, the
//! orientation terms only on the orientation DMP's, so each part is learned on its own.
//! Position: the via-point learner ([`learn_via_points`]). Orientation: CMA-ES on
//!
//! ```text
//! C_rot = w_goal ∠(q_T, g)² + w_via Σ_i ∠(q(t_i), q_i)² + w_vel ‖ω_T‖² + w_acc Σ_k ‖ω̇_k‖²
//! ```
//!
//! with angles in radians (`∠` the rotation angle between two orientations), the weights
//! of the position cost, and ω̇ by finite differences. The search space is the
//! orientation analogue of the anchor offset: `w_i = θ_i α_z β_z / c_i`, θ in radians.

use std::ops::ControlFlow;
use std::time::Instant;

use cps_cmaes::{GenerationReport, Objective, ObjectiveError};
use cps_dmp::{OrientationTrajectory, QuaternionDmp};
use nalgebra::UnitQuaternion;
use serde::{Deserialize, Serialize};

use crate::viapoint::run_cmaes;
use crate::{LearnError, SearchStats, Solver, ViaPointConfig, ViaPointOutcome, learn_via_points};

/// Settings of [`learn_pose`].
#[derive(Debug, Clone)]
pub struct PoseConfig {
    /// The position task and the CMA-ES settings of both parts.
    pub learner: ViaPointConfig,
    /// Orientation at the start.
    pub start_orientation: UnitQuaternion<f64>,
    /// Orientation at the goal.
    pub goal_orientation: UnitQuaternion<f64>,
    /// Orientation targets, one per via point of the position task (`None`: free).
    pub via_orientations: Vec<Option<UnitQuaternion<f64>>>,
    /// Initial CMA-ES step of the orientation part, radians.
    pub orientation_sigma0: f64,
    /// How the orientation part is learned: [`Solver::Cmaes`] (from zero weights, with
    /// the learner's population, generations and tolfun) or [`Solver::LeastSquares`]
    /// (Levenberg–Marquardt from zero weights, the learner's generations as its
    /// iteration budget). The orientation cost is not quadratic: `Exact` is refused.
    pub orientation_solver: Solver,
}

/// The orientation cost term by term.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct OrientationCostBreakdown {
    /// Goal term.
    pub goal: f64,
    /// Via-point term.
    pub via: f64,
    /// Final angular-velocity term.
    pub final_velocity: f64,
    /// Angular-acceleration term.
    pub acceleration: f64,
}

impl OrientationCostBreakdown {
    /// The sum of the terms.
    pub fn total(&self) -> f64 {
        self.goal + self.via + self.final_velocity + self.acceleration
    }
}

/// Orientation errors of a trajectory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OrientationErrors {
    /// Angle to the goal orientation at `t = tau`, radians.
    pub goal: f64,
    /// Angle to each via orientation at its time (`None` where free), radians.
    pub via: Vec<Option<f64>>,
    /// Angular speed at `t = tau`, rad/s.
    pub final_angular_speed: f64,
}

impl OrientationErrors {
    /// The largest of the goal and via angles.
    pub fn max_angle(&self) -> f64 {
        self.via.iter().flatten().fold(self.goal, |a, &b| a.max(b))
    }
}

/// The orientation at time `t` (spherical interpolation between grid samples).
fn orientation_at(traj: &OrientationTrajectory, t: f64) -> UnitQuaternion<f64> {
    let (k, frac) = cps_dmp::locate_on_grid(&traj.times, t);
    if frac == 0.0 || k + 1 >= traj.orientation.len() {
        traj.orientation[k]
    } else {
        traj.orientation[k]
            .try_slerp(&traj.orientation[k + 1], frac, 1e-12)
            .unwrap_or(traj.orientation[k])
    }
}

impl PoseConfig {
    fn breakdown(&self, traj: &OrientationTrajectory) -> OrientationCostBreakdown {
        let w = &self.learner.task.weights;
        let last = traj.orientation.len() - 1;
        let h = traj.times[1] - traj.times[0];
        let mut b = OrientationCostBreakdown {
            goal: w.goal
                * traj.orientation[last]
                    .angle_to(&self.goal_orientation)
                    .powi(2),
            final_velocity: w.final_velocity * traj.angular_velocity[last].norm_squared(),
            ..Default::default()
        };
        for (v, target) in self.learner.task.via.iter().zip(&self.via_orientations) {
            if let Some(q) = target {
                b.via += w.via * orientation_at(traj, v.time).angle_to(q).powi(2);
            }
        }
        if w.acceleration > 0.0 {
            b.acceleration = w.acceleration
                * traj
                    .angular_velocity
                    .windows(2)
                    .map(|p| ((p[1] - p[0]) / h).norm_squared())
                    .sum::<f64>();
        }
        b
    }

    /// The orientation errors of a trajectory.
    pub fn errors(&self, traj: &OrientationTrajectory) -> OrientationErrors {
        let last = traj.orientation.len() - 1;
        OrientationErrors {
            goal: traj.orientation[last].angle_to(&self.goal_orientation),
            via: self
                .learner
                .task
                .via
                .iter()
                .zip(&self.via_orientations)
                .map(|(v, q)| q.map(|q| orientation_at(traj, v.time).angle_to(&q)))
                .collect(),
            final_angular_speed: traj.angular_velocity[last].norm(),
        }
    }
}

struct OrientationObjective<'a> {
    config: &'a PoseConfig,
    dmp: &'a QuaternionDmp,
    scale: &'a [f64],
}

impl OrientationObjective<'_> {
    fn weights(&self, theta: &[f64]) -> Vec<f64> {
        theta.iter().zip(self.scale).map(|(t, s)| t * s).collect()
    }
}

impl crate::lsq::Residuals for OrientationObjective<'_> {
    type Buffers = ();

    fn buffers(&self) -> Self::Buffers {}

    /// The residuals whose squares sum to the cost: the rotation vectors (angle × axis)
    /// from the goal and each via target, the final angular velocity, the angular
    /// accelerations, each times the square root of its weight.
    fn residuals(&self, theta: &[f64], _: &mut (), out: &mut Vec<f64>) -> bool {
        let traj = self.dmp.rollout(&self.weights(theta));
        let c = self.config;
        let w = &c.learner.task.weights;
        let last = traj.orientation.len() - 1;
        let h = traj.times[1] - traj.times[0];
        out.clear();
        let mut push = |s: f64, v: nalgebra::Vector3<f64>| out.extend(v.iter().map(|x| s * x));
        let error = |q: &UnitQuaternion<f64>, target: &UnitQuaternion<f64>| {
            (target.inverse() * q).scaled_axis()
        };
        push(
            w.goal.sqrt(),
            error(&traj.orientation[last], &c.goal_orientation),
        );
        for (v, target) in c.learner.task.via.iter().zip(&c.via_orientations) {
            if let Some(target) = target {
                push(w.via.sqrt(), error(&orientation_at(&traj, v.time), target));
            }
        }
        push(w.final_velocity.sqrt(), traj.angular_velocity[last]);
        if w.acceleration > 0.0 {
            let s = w.acceleration.sqrt() / h;
            for p in traj.angular_velocity.windows(2) {
                push(s, p[1] - p[0]);
            }
        }
        true
    }
}

impl Objective for OrientationObjective<'_> {
    fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
        let traj = self.dmp.rollout(&self.weights(x));
        Ok(self.config.breakdown(&traj).total())
    }
}

/// The learned orientation part.
#[derive(Debug, Clone)]
pub struct OrientationResult {
    /// The orientation DMP.
    pub dmp: QuaternionDmp,
    /// Its learned weights (axis-major).
    pub weights: Vec<f64>,
    /// Its trajectory.
    pub trajectory: OrientationTrajectory,
    /// The cost term by term.
    pub breakdown: OrientationCostBreakdown,
    /// The cost of zero weights (the plain goal-directed rotation), term by term.
    pub start: OrientationCostBreakdown,
    /// The errors.
    pub errors: OrientationErrors,
    /// The CMA-ES search.
    pub search: SearchStats,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// The result of [`learn_pose`].
#[derive(Debug, Clone)]
pub struct PoseOutcome {
    /// The position part (the via-point learner's outcome).
    pub position: ViaPointOutcome,
    /// The orientation part.
    pub orientation: OrientationResult,
}

/// Learns position and orientation (see the module documentation). `progress(part,
/// report)` is called after every generation, `part` 0 for position and 1 for
/// orientation, and may stop the run.
pub fn learn_pose(
    config: &PoseConfig,
    progress: &(dyn Fn(usize, &GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<PoseOutcome, LearnError> {
    let task = &config.learner.task;
    if config.via_orientations.len() != task.via.len() {
        return Err(LearnError::task(
            "orientation.via",
            format!(
                "has {} orientations for {} via points: give one per via point",
                config.via_orientations.len(),
                task.via.len()
            ),
        ));
    }
    if !(config.orientation_sigma0.is_finite() && config.orientation_sigma0 > 0.0) {
        return Err(LearnError::task(
            "orientation.sigma0",
            format!("must be finite and > 0 (got {})", config.orientation_sigma0),
        ));
    }
    let position = learn_via_points(&config.learner, &|_, r| progress(0, r))?;
    let started = Instant::now();
    let dmp = QuaternionDmp::new(task.dmp, config.start_orientation, config.goal_orientation)?;
    let template = task.build_dmp()?;
    let cfg = template.config();
    let scale: Vec<f64> = (0..3)
        .flat_map(|_| {
            template
                .basis()
                .centers()
                .iter()
                .map(|c| cfg.alpha_z * cfg.beta_z / c)
        })
        .collect();
    let objective = OrientationObjective {
        config,
        dmp: &dmp,
        scale: &scale,
    };
    let zero = vec![0.0; scale.len()];
    let start = config.breakdown(&dmp.rollout(&zero));
    let mut learner = config.learner.clone();
    learner.sigma0 = config.orientation_sigma0;
    let (best_x, search) = match config.orientation_solver {
        Solver::LeastSquares => crate::lsq::levenberg_marquardt(
            &objective,
            zero,
            crate::lsq::settings(learner.generations),
            &|r| progress(1, r),
        )?,
        Solver::Cmaes => {
            learner.solver = Solver::Cmaes;
            run_cmaes(
                &objective,
                zero,
                &learner,
                learner.seed ^ 0x6f72_6965_6e74,
                &|r| progress(1, r),
            )?
        }
        Solver::Exact => {
            return Err(LearnError::task(
                "orientation.method",
                "the orientation cost is not quadratic in the weights: use \"least_squares\" or \"cmaes\"",
            ));
        }
    };
    let weights = objective.weights(&best_x);
    let trajectory = dmp.rollout(&weights);
    let orientation = OrientationResult {
        breakdown: config.breakdown(&trajectory),
        errors: config.errors(&trajectory),
        start,
        dmp,
        weights,
        trajectory,
        search,
        seconds: started.elapsed().as_secs_f64(),
    };
    Ok(PoseOutcome {
        position,
        orientation,
    })
}
