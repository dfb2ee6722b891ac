//! Keeping a task-space movement clear, on the robot's model: the kinds that learn where
//! the tool goes (a pose, an imitation, a conditioned ProMP) and leave the joints to the
//! inverse controller judge the joints only once the robot follows the movement. This
//! stage takes such a movement's parameters θ₀ and finds the θ nearest it, by the kind's
//! own measure, whose execution keeps the clearance:
//!
//! ```text
//! C(θ) = ‖a(θ)‖² + w Σ_q Σ_p (c − d_p(q))²
//! ```
//!
//! `a(θ)` the kind's anchor residuals (its own cost, or how far the movement strays from
//! the one learned: zero at θ₀); `q` runs over every command the inverse controller
//! sends for the movement's targets on the robot's model — the same controller every
//! backend runs; a target it approaches over several control periods has each of them
//! judged, as the guard judges each command — and `p` over the pairs closer than the
//! clearance `c`, walked as the guard walks a plan. Levenberg–Marquardt searches θ from
//! θ₀, its Jacobian by forward differences (one model execution a column, columns in
//! parallel) kept for a few steps at a time. A movement whose execution already keeps
//! the clearance is left as it is. The result is executed through the guard and checked
//! against every limit like any other: a movement bent clear that the controller cannot
//! follow within the limits is refused there.

use std::ops::ControlFlow;

use cps_cmaes::GenerationReport;
use cps_kinematics::IkTarget;
use cps_robot::{KinematicRobot, Recording, StopToken};

use crate::clearance::{Clearance, Closest, by_joint, closest};
use crate::lsq::{LmSettings, Residuals, levenberg_marquardt};
use crate::search::SearchStats;
use crate::{LearnError, RobotSetup};

/// A clearance to keep and the iteration budget of the stage that keeps a task-space
/// movement clear ([`keep_clear`]): what a kind that learns a robot's movement is given.
#[derive(Debug, Clone)]
pub struct ClearanceStage {
    /// The robot's shapes, the distance and the weight.
    pub clearance: Clearance,
    /// Levenberg–Marquardt's iteration budget when a movement is bent on the model.
    pub iterations: u64,
}

/// What [`keep_clear`] keeps, on which model.
#[derive(Debug, Clone, Copy)]
pub struct KeepClear<'a> {
    /// The clearance and its weight.
    pub clearance: &'a Clearance,
    /// The robot's model, its start and its controller's settings.
    pub robot: &'a RobotSetup,
    /// The control period of the model's execution (s): the movement's targets are one
    /// per period.
    pub dt: f64,
    /// Levenberg–Marquardt's iteration budget.
    pub iterations: u64,
}

/// The result of [`keep_clear`].
#[derive(Debug, Clone)]
pub struct KeptClear {
    /// The parameters found (θ₀ when the movement was already clear).
    pub theta: Vec<f64>,
    /// The search (none when the movement was already clear: termination `clear`).
    pub search: SearchStats,
    /// The anchor's cost `‖a‖²` at θ₀ and at the result.
    pub anchor: [f64; 2],
    /// The clearance term's cost at θ₀ and at the result.
    pub clearance: [f64; 2],
    /// Where the model's execution of θ₀ and of the result comes closest (within a look
    /// of 10 cm; None farther).
    pub closest: [Option<Closest>; 2],
    /// The model's execution of the result.
    pub executed: Recording,
}

/// The movement of `targets(θ)` executed on `keep.robot`'s model from its start.
pub fn execute_on_model(
    robot: &RobotSetup,
    dt: f64,
    targets: &[IkTarget],
) -> Result<Recording, LearnError> {
    let mut model = KinematicRobot::new(robot.chain.clone(), &robot.initial_q, dt)?;
    Ok(cps_robot::execute(
        &mut model,
        &robot.chain,
        targets,
        &robot.execution,
        &StopToken::new(),
    )?)
}

/// A via-point task's own residuals over a search space's θ (goal, via points, final
/// velocity, accelerations, obstacles): the anchor that keeps a task's movement on its
/// task while [`keep_clear`] bends it.
pub fn task_anchor<'a>(
    task: &'a crate::ViaPointTask,
    dmp: &'a cps_dmp::DiscreteDmp,
    space: &'a crate::SearchSpace,
) -> impl Fn(&[f64], &mut Vec<f64>) + Sync + 'a {
    move |theta, out| {
        let r = crate::lsq::TaskResiduals { task, dmp, space };
        let mut b = r.buffers();
        r.residuals(theta, &mut b, out);
    }
}

/// The most likely movement of a Gaussian over its parameters (a ProMP's, conditioned
/// or not: weights with `mean` and covariance `cov`) whose execution on the model keeps
/// the clearance: [`keep_clear`] from the mean with the whitened distance `L⁻¹(θ − μ)` as
/// the anchor (`LLᵀ = Σ + εI`, ε a billionth of Σ's largest variance), so its cost is the
/// Mahalanobis distance `(θ − μ)ᵀ Σ⁻¹ (θ − μ)`, the negative log-likelihood up to a
/// constant. Directions the distribution pins (a conditioned ProMP's via point) stay all
/// but fixed; those the demonstrations varied in are where the movement bends.
pub fn keep_likely_clear(
    keep: &KeepClear<'_>,
    mean: &[f64],
    cov: &nalgebra::DMatrix<f64>,
    targets: &(dyn Fn(&[f64]) -> Vec<IkTarget> + Sync),
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<KeptClear, LearnError> {
    let n = mean.len();
    if cov.nrows() != n || cov.ncols() != n {
        return Err(LearnError::task(
            "clearance",
            format!(
                "a {}×{} covariance for {n} parameters",
                cov.nrows(),
                cov.ncols()
            ),
        ));
    }
    let largest = (0..n).map(|i| cov[(i, i)]).fold(0.0, f64::max);
    let jitter = 1e-9 * largest.max(f64::MIN_POSITIVE);
    let l = (cov + nalgebra::DMatrix::identity(n, n) * jitter)
        .cholesky()
        .ok_or_else(|| {
            LearnError::Exact("the distribution's covariance is not positive definite".into())
        })?
        .l();
    let anchor = |theta: &[f64], out: &mut Vec<f64>| {
        let d = nalgebra::DVector::from_iterator(n, theta.iter().zip(mean).map(|(a, b)| a - b));
        match l.solve_lower_triangular(&d) {
            Some(r) => out.extend(r.iter()),
            None => out.extend(std::iter::repeat_n(f64::NAN, n)),
        }
    };
    keep_clear(keep, mean.to_vec(), &anchor, targets, progress)
}

/// How many iterations a Jacobian is kept at the most: each costs one model execution per
/// parameter, and a step on a kept one costs one; kept longer, the steps crawl.
const REFRESH_EVERY: u64 = 4;

/// How far (m) a movement's closest approach is looked for in the report.
const LOOK: f64 = 0.10;

struct Problem<'a> {
    keep: &'a KeepClear<'a>,
    anchor: &'a (dyn Fn(&[f64], &mut Vec<f64>) + Sync),
    targets: &'a (dyn Fn(&[f64]) -> Vec<IkTarget> + Sync),
}

impl Problem<'_> {
    /// The anchor's residuals and the clearance term's on every command the controller
    /// sends for θ's movement on the model.
    fn split(&self, theta: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
        let mut anchor = Vec::new();
        (self.anchor)(theta, &mut anchor);
        let robot = self.keep.robot;
        let targets = (self.targets)(theta);
        let path = cps_robot::command_path(
            &robot.chain,
            robot.initial_q.clone(),
            &targets,
            &robot.execution,
            self.keep.dt,
        )
        .ok()?;
        Some((anchor, self.clearance_residuals(&path)?))
    }

    /// One residual per target: `√(w Σ_q Σ_p (c − d_p(q))²)` over every command `q` the
    /// controller sends for it (a target it approaches over several steps has each of
    /// them judged, as the guard judges each command; position targets take one) and the
    /// pairs `p` closer than the clearance. The commands are walked as the guard walks a
    /// plan ([`cps_geometry::PathCheck`]), from a fresh walk: the same θ, the same bits.
    fn clearance_residuals(&self, path: &cps_robot::CommandPath) -> Option<Vec<f64>> {
        let c = self.keep.clearance;
        let mut walk = cps_geometry::PathCheck::new(c.shapes.model().clone(), c.watch());
        let mut frames = Vec::with_capacity(self.keep.robot.chain.dof() + 1);
        let mut out = Vec::with_capacity(path.last_step.len());
        let mut step = 0;
        for &last in &path.last_step {
            let mut sum = 0.0;
            while step <= last {
                self.keep
                    .robot
                    .chain
                    .frames_into(&path.points[step], &mut frames)
                    .ok()?;
                walk.step(&frames);
                sum += walk
                    .near()
                    .iter()
                    .map(|n| c.shortfall_squared(n))
                    .sum::<f64>();
                step += 1;
            }
            out.push((c.weight * sum).sqrt());
        }
        Some(out)
    }

    fn closest(&self, rec: &Recording) -> Option<Closest> {
        let joints = by_joint(&rec.q);
        closest(
            &self.keep.clearance.shapes,
            &self.keep.robot.chain,
            &rec.time,
            |j| &joints[j],
            LOOK,
        )
        .ok()
        .flatten()
    }
}

impl Residuals for Problem<'_> {
    type Buffers = ();

    fn buffers(&self) -> Self::Buffers {}

    fn residuals(&self, theta: &[f64], _: &mut (), out: &mut Vec<f64>) -> bool {
        out.clear();
        match self.split(theta) {
            Some((anchor, clear)) => {
                out.extend(anchor);
                out.extend(clear);
                true
            }
            None => false,
        }
    }
}

fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum()
}

/// Finds the parameters nearest `theta0` (by `anchor`, the kind's residuals) whose
/// movement (`targets`, one per control period) the robot's model executes keeping the
/// clearance (see the module documentation). `progress` is called after every iteration
/// and may stop the search (the best so far is kept).
pub fn keep_clear(
    keep: &KeepClear<'_>,
    theta0: Vec<f64>,
    anchor: &(dyn Fn(&[f64], &mut Vec<f64>) + Sync),
    targets: &(dyn Fn(&[f64]) -> Vec<IkTarget> + Sync),
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<KeptClear, LearnError> {
    if !(keep.dt.is_finite() && keep.dt > 0.0) {
        return Err(LearnError::task(
            "clearance",
            format!("the model's control period must be > 0 (got {})", keep.dt),
        ));
    }
    let problem = Problem {
        keep,
        anchor,
        targets,
    };
    let (a0, c0) = problem.split(&theta0).ok_or_else(|| {
        LearnError::Exact("the model cannot execute the learned movement (a configuration inverse kinematics refuses)".into())
    })?;
    let rec0 = execute_on_model(keep.robot, keep.dt, &targets(&theta0))?;
    let closest0 = problem.closest(&rec0);
    let before = [sum_sq(&a0), sum_sq(&c0)];
    if before[1] == 0.0 {
        return Ok(KeptClear {
            theta: theta0,
            search: SearchStats {
                generations: 0,
                evaluations: 1,
                non_finite_evaluations: 0,
                termination: "clear".into(),
                history: Vec::new(),
            },
            anchor: [before[0]; 2],
            clearance: [0.0; 2],
            closest: [closest0.clone(), closest0],
            executed: rec0,
        });
    }
    let settings = LmSettings {
        max_iterations: keep.iterations,
        tol: 1e-10,
        reuse_jacobian: true,
        refresh_every: REFRESH_EVERY,
        patient: true,
    };
    let (theta, search) = levenberg_marquardt(&problem, theta0, settings, progress)?;
    let (a1, c1) = problem.split(&theta).ok_or_else(|| {
        LearnError::Exact("the model cannot execute the movement kept clear".into())
    })?;
    let rec1 = execute_on_model(keep.robot, keep.dt, &targets(&theta))?;
    Ok(KeptClear {
        theta,
        search,
        anchor: [before[0], sum_sq(&a1)],
        clearance: [before[1], sum_sq(&c1)],
        closest: [closest0, problem.closest(&rec1)],
        executed: rec1,
    })
}
