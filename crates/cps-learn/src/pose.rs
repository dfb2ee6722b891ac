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

/// The orientation part's search space: `w_i = θ_i α_z β_z / c_i` (θ in radians).
fn orientation_scale(task: &crate::ViaPointTask) -> Result<Vec<f64>, LearnError> {
    let template = task.build_dmp()?;
    let cfg = template.config();
    Ok((0..3)
        .flat_map(|_| {
            template
                .basis()
                .centers()
                .iter()
                .map(|c| cfg.alpha_z * cfg.beta_z / c)
        })
        .collect())
}

/// A pose (position `p` and orientation `o` on one time grid) as one tool target per
/// control period `dt`, orientations interpolated by slerp: what a robot follows.
pub fn pose_targets(
    p: &cps_dmp::Trajectory,
    o: &OrientationTrajectory,
    dt: f64,
) -> Vec<cps_kinematics::IkTarget> {
    let end = p.times().last().copied().unwrap_or(0.0);
    let n = (end / dt + 1e-9).floor() as usize + 1;
    (0..n)
        .map(|k| {
            let t = k as f64 * dt;
            let i = o
                .times
                .partition_point(|&x| x <= t)
                .clamp(1, o.times.len().max(2) - 1);
            let rot = if o.times.len() < 2 {
                o.orientation[0]
            } else {
                let (t0, t1) = (o.times[i - 1], o.times[i]);
                let f = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
                o.orientation[i - 1].slerp(&o.orientation[i], f)
            };
            let pos = nalgebra::Translation3::new(
                p.position_at(0, t),
                p.position_at(1, t),
                p.position_at(2, t),
            );
            cps_kinematics::IkTarget::Pose(nalgebra::IsometryMatrix3::from_parts(
                pos,
                rot.to_rotation_matrix(),
            ))
        })
        .collect()
}

/// Bends a learned pose — position and orientation together, since either may fold the
/// arm into itself or its world — until the robot's model, following it, keeps the
/// clearance ([`crate::keep_clear`]), anchored by the pose's own costs: the position
/// task's residuals and the orientation cost's. `outcome` becomes the result: the best
/// position run's parameters, cost and errors, and the orientation's weights, trajectory,
/// cost and errors, are those of the bent pose.
pub fn keep_pose_clear(
    config: &PoseConfig,
    outcome: &mut PoseOutcome,
    keep: &crate::KeepClear<'_>,
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<crate::KeptClear, LearnError> {
    let task = &config.learner.task;
    let dmp = outcome.position.dmp.clone();
    let space = crate::SearchSpace::new(config.learner.parametrisation, &dmp);
    let scale = orientation_scale(task)?;
    let quaternion = outcome.orientation.dmp.clone();
    let rotation = OrientationObjective {
        config,
        dmp: &quaternion,
        scale: &scale,
    };
    let np = outcome.position.best().params.len();
    let position = crate::task_anchor(task, &dmp, &space);
    let anchor = |theta: &[f64], out: &mut Vec<f64>| {
        position(&theta[..np], out);
        let mut r = Vec::new();
        crate::lsq::Residuals::residuals(&rotation, &theta[np..], &mut (), &mut r);
        out.extend(r);
    };
    let targets = |theta: &[f64]| {
        pose_targets(
            &dmp.rollout(&space.weights(&theta[..np])),
            &quaternion.rollout(&rotation.weights(&theta[np..])),
            keep.dt,
        )
    };
    let mut theta0 = outcome.position.best().params.clone();
    theta0.extend(
        outcome
            .orientation
            .weights
            .iter()
            .zip(&scale)
            .map(|(w, s)| w / s),
    );
    let kept = crate::keep_clear(keep, theta0, &anchor, &targets, progress)?;
    // The bent pose becomes the outcome.
    let optimum = outcome.position.optimum.cost;
    let best = outcome.position.best_run;
    let run = &mut outcome.position.runs[best];
    run.weights = space.weights(&kept.theta[..np]);
    run.params = kept.theta[..np].to_vec();
    let traj = dmp.rollout(&run.weights);
    run.cost = task.cost(&traj);
    run.breakdown = task.breakdown(&traj);
    run.errors = task.errors(&traj);
    run.gap_to_optimum = (run.cost - optimum) / optimum;
    run.evaluations += kept.search.evaluations;
    let o = &mut outcome.orientation;
    o.weights = rotation.weights(&kept.theta[np..]);
    o.trajectory = o.dmp.rollout(&o.weights);
    o.breakdown = config.breakdown(&o.trajectory);
    o.errors = config.errors(&o.trajectory);
    Ok(kept)
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
    let scale = orientation_scale(task)?;
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
                None,
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
