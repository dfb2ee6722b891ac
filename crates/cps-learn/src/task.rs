//! The via-point task and its cost (Rueckert & d'Avella 2013; thesis eq. 54).

use cps_dmp::{DiscreteDmp, DmpConfig, Trajectory};
use serde::{Deserialize, Serialize};

use crate::LearnError;

/// A point the movement must pass at a given time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViaPoint {
    /// Time in seconds, strictly inside `(0, tau)`.
    pub time: f64,
    /// Position, one value per dimension (metres for task space).
    pub position: Vec<f64>,
}

/// A point obstacle the movement must keep `clearance` away from (task units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointObstacle {
    /// Its position, one value per dimension.
    pub position: Vec<f64>,
    /// The distance the movement should keep (> 0); closer samples are penalised.
    pub clearance: f64,
}

/// Weights of the cost terms; a weight of 0 switches its term off. All must be ≥ 0.
///
/// ```text
/// C = w_goal ‖y_T − g‖² + w_via Σ_i ‖y(t_i) − p_i‖² + w_vel ‖ẏ_T − ġ‖²
///   + w_acc Σ_k ‖ÿ_k‖² + w_jerk Σ_k ‖(ÿ_{k+1} − ÿ_k)/h‖²
///   + w_obs Σ_k Σ_o max(0, r_o − ‖y_k − o‖)²
/// ```
///
/// with sums over the grid samples (not integrals) and every quantity in SI units
/// (physical velocity, acceleration and jerk).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CostWeights {
    /// Goal position error at `t = tau` (thesis: 1e5).
    pub goal: f64,
    /// Via-point position errors (thesis: 1e5).
    pub via: f64,
    /// Final velocity error against the goal velocity (thesis: 1e3, target 0).
    pub final_velocity: f64,
    /// Squared physical acceleration at every sample (thesis: 1e-2).
    pub acceleration: f64,
    /// Squared physical jerk (finite difference of the acceleration) at every step.
    pub jerk: f64,
    /// Squared intrusion into an obstacle's clearance at every sample (not quadratic in
    /// the weights: the exact optimum leaves it out and is then a lower bound).
    #[serde(default)]
    pub obstacle: f64,
}

impl CostWeights {
    /// The thesis's via-point experiment: goal 1e5, via 1e5, final velocity 1e3,
    /// acceleration 1e-2, no jerk term.
    pub fn thesis() -> Self {
        Self {
            goal: 1e5,
            via: 1e5,
            final_velocity: 1e3,
            acceleration: 1e-2,
            jerk: 0.0,
            obstacle: 0.0,
        }
    }
}

/// The value of each cost term.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct CostBreakdown {
    /// Goal term.
    pub goal: f64,
    /// Via-point term.
    pub via: f64,
    /// Final-velocity term.
    pub final_velocity: f64,
    /// Acceleration term.
    pub acceleration: f64,
    /// Jerk term.
    pub jerk: f64,
    /// Obstacle term.
    #[serde(default)]
    pub obstacle: f64,
}

impl CostBreakdown {
    /// The sum of the terms.
    pub fn total(&self) -> f64 {
        self.goal + self.via + self.final_velocity + self.acceleration + self.jerk + self.obstacle
    }
}

/// Which cost term a residual belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Term {
    Goal,
    Via,
    FinalVelocity,
    Acceleration,
    Jerk,
    Obstacle,
}

/// A via-point movement: start, goal, via points, the DMP that carries it and the cost.
#[derive(Debug, Clone, PartialEq)]
pub struct ViaPointTask {
    /// Start position `y0` (the DMP's start).
    pub start: Vec<f64>,
    /// Goal position `g`, reached at `t = tau`.
    pub goal: Vec<f64>,
    /// Target velocity at the goal (usually zero).
    pub goal_velocity: Vec<f64>,
    /// Via points, with increasing times inside `(0, tau)`.
    pub via: Vec<ViaPoint>,
    /// DMP parameters (basis functions, `tau`, `dt`, gains).
    pub dmp: DmpConfig,
    /// Cost weights.
    pub weights: CostWeights,
    /// Point obstacles (penalised by `weights.obstacle`).
    pub obstacles: Vec<PointObstacle>,
}

/// Largest magnitude of a coordinate (start, goal, via points, goal velocity) that
/// [`ViaPointTask::validate`] accepts: cps-dmp's, 1e6 task units (a thousand kilometres in
/// metres).
pub use cps_dmp::MAX_COORDINATE;
/// Largest cost weight [`ViaPointTask::validate`] accepts: beyond 1e12 the cost's terms
/// differ by more than double precision can weigh against each other.
pub const MAX_WEIGHT: f64 = 1e12;

impl ViaPointTask {
    /// The thesis's Table 3 task: start (0.75, 0.02, 1.87), via points at 2, 4, 6 and 8 s,
    /// goal (0.55, −0.57, 1.45) at 10 s; 3 DMPs × 25 bases, `tau` = 10 s, dt = 0.01 s.
    pub fn thesis() -> Self {
        let via = [
            (2.0, [0.78, 0.60, 1.70]),
            (4.0, [1.12, 0.37, 1.45]),
            (6.0, [1.15, -0.15, 1.20]),
            (8.0, [0.90, -0.53, 1.20]),
        ];
        Self {
            start: vec![0.75, 0.02, 1.87],
            goal: vec![0.55, -0.57, 1.45],
            goal_velocity: vec![0.0; 3],
            via: via
                .iter()
                .map(|(t, p)| ViaPoint {
                    time: *t,
                    position: p.to_vec(),
                })
                .collect(),
            dmp: DmpConfig::new(25, 10.0, 0.01),
            weights: CostWeights::thesis(),
            obstacles: Vec::new(),
        }
    }

    /// Checks the task; errors name the field (`via[1].time`, `goal`, …) and the rule.
    pub fn validate(&self) -> Result<(), LearnError> {
        let dims = self.start.len();
        if dims == 0 {
            return Err(LearnError::task(
                "start",
                "must have at least one coordinate",
            ));
        }
        let check_vec = |name: String, v: &[f64]| -> Result<(), LearnError> {
            if v.len() != dims {
                return Err(LearnError::task(
                    name,
                    format!("has {} coordinates, expected {dims} like `start`", v.len()),
                ));
            }
            if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                return Err(LearnError::task(
                    format!("{name}[{i}]"),
                    format!("must be finite, got {x}"),
                ));
            }
            if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| x.abs() > MAX_COORDINATE) {
                return Err(LearnError::task(
                    format!("{name}[{i}]"),
                    format!("must be at most {MAX_COORDINATE:e} in magnitude, got {x:?}"),
                ));
            }
            Ok(())
        };
        check_vec("start".into(), &self.start)?;
        check_vec("goal".into(), &self.goal)?;
        check_vec("goal_velocity".into(), &self.goal_velocity)?;
        self.dmp.validate()?;
        let tau = self.dmp.tau;
        let mut previous = 0.0;
        for (i, v) in self.via.iter().enumerate() {
            check_vec(format!("via[{i}].position"), &v.position)?;
            if !(v.time.is_finite() && v.time > 0.0 && v.time < tau) {
                return Err(LearnError::task(
                    format!("via[{i}].time"),
                    format!(
                        "must lie strictly inside (0, tau = {tau}) s, got {}",
                        v.time
                    ),
                ));
            }
            if v.time <= previous {
                return Err(LearnError::task(
                    format!("via[{i}].time"),
                    format!(
                        "must be later than the previous via point ({previous} s), got {}",
                        v.time
                    ),
                ));
            }
            previous = v.time;
        }
        let w = &self.weights;
        for (name, value) in [
            ("goal", w.goal),
            ("via", w.via),
            ("final_velocity", w.final_velocity),
            ("acceleration", w.acceleration),
            ("jerk", w.jerk),
            ("obstacle", w.obstacle),
        ] {
            if !(value.is_finite() && (0.0..=MAX_WEIGHT).contains(&value)) {
                return Err(LearnError::task(
                    format!("cost.{name}"),
                    format!("must be a weight between 0 and {MAX_WEIGHT:e}, got {value:?}"),
                ));
            }
        }
        for (i, o) in self.obstacles.iter().enumerate() {
            check_vec(format!("obstacles[{i}].position"), &o.position)?;
            if !(o.clearance.is_finite() && o.clearance > 0.0 && o.clearance <= MAX_COORDINATE) {
                return Err(LearnError::task(
                    format!("obstacles[{i}].clearance"),
                    format!("must be > 0 and finite, got {:?}", o.clearance),
                ));
            }
            cps_dmp::check_endpoints(
                &self.start,
                &self.goal,
                &o.position,
                o.clearance,
                &format!("obstacles[{i}]"),
            )
            .map_err(|e| LearnError::task(format!("obstacles[{i}].position"), e.to_string()))?;
        }
        if !self.obstacles.is_empty() && w.obstacle == 0.0 {
            return Err(LearnError::task(
                "cost.obstacle",
                "is 0, so the obstacles would be ignored: give it a weight (e.g. 1e5)",
            ));
        }
        // Only the Ijspeert form scales its forcing term with goal − start.
        let scaled = self.dmp.formulation == cps_dmp::Formulation::Ijspeert2013;
        for d in (0..dims).filter(|_| scaled) {
            let amp = self.goal[d] - self.start[d];
            let scale = self.start[d].abs().max(self.goal[d].abs()).max(1.0);
            if amp.abs() <= 1e-9 * scale {
                return Err(LearnError::task(
                    format!("goal[{d}]"),
                    format!(
                        "equals start[{d}] ({}): the DMP's forcing term is proportional to goal − start, \
                         so this dimension could not move towards any via point; move the goal slightly",
                        self.start[d]
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The DMP for this task (validated).
    pub fn build_dmp(&self) -> Result<DiscreteDmp, LearnError> {
        self.validate()?;
        Ok(DiscreteDmp::new(self.dmp, &self.start, &self.goal)?)
    }

    /// Calls `visit(term, r)` for every weighted residual `r` of the cost; the cost is
    /// the sum of their squares. Every residual is affine in the trajectory.
    pub(crate) fn residuals(&self, traj: &Trajectory, mut visit: impl FnMut(Term, f64)) {
        let w = &self.weights;
        let last = traj.n_samples() - 1;
        let dims = traj.dims();
        if w.goal > 0.0 {
            let s = w.goal.sqrt();
            for d in 0..dims {
                visit(Term::Goal, s * (traj.position(d)[last] - self.goal[d]));
            }
        }
        if w.via > 0.0 {
            let s = w.via.sqrt();
            for v in &self.via {
                for d in 0..dims {
                    visit(Term::Via, s * (traj.position_at(d, v.time) - v.position[d]));
                }
            }
        }
        if w.final_velocity > 0.0 {
            let s = w.final_velocity.sqrt();
            for d in 0..dims {
                visit(
                    Term::FinalVelocity,
                    s * (traj.velocity(d)[last] - self.goal_velocity[d]),
                );
            }
        }
        if w.acceleration > 0.0 {
            let s = w.acceleration.sqrt();
            for d in 0..dims {
                for &a in traj.acceleration(d) {
                    visit(Term::Acceleration, s * a);
                }
            }
        }
        if w.jerk > 0.0 && last > 0 {
            let h = traj.times()[1] - traj.times()[0];
            let s = w.jerk.sqrt() / h;
            for d in 0..dims {
                for a in traj.acceleration(d).windows(2) {
                    visit(Term::Jerk, s * (a[1] - a[0]));
                }
            }
        }
        if w.obstacle > 0.0 {
            let s = w.obstacle.sqrt();
            self.intrusions(traj, |r| visit(Term::Obstacle, s * r));
        }
    }

    /// The obstacle residuals, `max(0, r − ‖y_k − o‖)` per sample and obstacle (unweighted).
    fn intrusions(&self, traj: &Trajectory, mut visit: impl FnMut(f64)) {
        let dims = traj.dims();
        for o in &self.obstacles {
            for k in 0..traj.n_samples() {
                let d2: f64 = (0..dims)
                    .map(|d| (traj.position(d)[k] - o.position[d]).powi(2))
                    .sum();
                if d2 < o.clearance * o.clearance {
                    visit(o.clearance - d2.sqrt());
                } else {
                    visit(0.0);
                }
            }
        }
    }

    /// The smallest distance of the trajectory's samples from each obstacle.
    pub fn obstacle_distances(&self, traj: &Trajectory) -> Vec<f64> {
        let dims = traj.dims();
        self.obstacles
            .iter()
            .map(|o| {
                (0..traj.n_samples())
                    .map(|k| {
                        (0..dims)
                            .map(|d| (traj.position(d)[k] - o.position[d]).powi(2))
                            .sum::<f64>()
                            .sqrt()
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    /// The cost of a trajectory, term by term.
    pub fn breakdown(&self, traj: &Trajectory) -> CostBreakdown {
        let mut b = CostBreakdown::default();
        self.residuals(traj, |term, r| {
            let slot = match term {
                Term::Goal => &mut b.goal,
                Term::Via => &mut b.via,
                Term::FinalVelocity => &mut b.final_velocity,
                Term::Acceleration => &mut b.acceleration,
                Term::Jerk => &mut b.jerk,
                Term::Obstacle => &mut b.obstacle,
            };
            *slot += r * r;
        });
        b
    }

    /// The cost of a trajectory: the sum of [`Self::breakdown`]'s terms (equal to rounding),
    /// with the long sums over samples taken in eight partial sums (SIMD) instead of one
    /// latency-bound chain — the hot path of population evaluation.
    pub fn cost(&self, traj: &Trajectory) -> f64 {
        let w = &self.weights;
        let last = traj.n_samples() - 1;
        let dims = traj.dims();
        let mut total = 0.0;
        for d in 0..dims {
            let (p, v) = (traj.position(d), traj.velocity(d));
            total += w.goal * (p[last] - self.goal[d]).powi(2);
            total += w.final_velocity * (v[last] - self.goal_velocity[d]).powi(2);
            for via in &self.via {
                total += w.via * (traj.position_at(d, via.time) - via.position[d]).powi(2);
            }
            let a = traj.acceleration(d);
            if w.acceleration > 0.0 {
                total += w.acceleration * sum_of_squared_differences(a, None);
            }
            if w.jerk > 0.0 && last > 0 {
                let h = traj.times()[1] - traj.times()[0];
                let steps = sum_of_squared_differences(&a[1..], Some(&a[..last]));
                total += w.jerk / (h * h) * steps;
            }
        }
        if w.obstacle > 0.0 {
            self.intrusions(traj, |r| total += w.obstacle * r * r);
        }
        total
    }

    /// The costs of a population (weight vectors back to back in `weights`) by one batch
    /// rollout into `trajs` (one per candidate, from [`DiscreteDmp::new_trajectory`]) and
    /// [`Self::cost`].
    ///
    /// # Panics
    /// If the lengths of `weights`, `trajs` and `out` do not match.
    pub fn costs_batched(
        &self,
        dmp: &DiscreteDmp,
        weights: &[f64],
        trajs: &mut [Trajectory],
        out: &mut [f64],
    ) {
        assert_eq!(trajs.len(), out.len(), "one trajectory per cost");
        dmp.rollout_batch(weights, trajs);
        for (o, t) in out.iter_mut().zip(trajs.iter()) {
            *o = self.cost(t);
        }
    }

    /// Plain-unit errors of a trajectory: goal distance, distance at each via point and
    /// final speed.
    pub fn errors(&self, traj: &Trajectory) -> TaskErrors {
        let dims = traj.dims();
        let last = traj.n_samples() - 1;
        let norm = |f: &dyn Fn(usize) -> f64| (0..dims).map(|d| f(d).powi(2)).sum::<f64>().sqrt();
        TaskErrors {
            goal: norm(&|d| traj.position(d)[last] - self.goal[d]),
            via: self
                .via
                .iter()
                .map(|v| norm(&|d| traj.position_at(d, v.time) - v.position[d]))
                .collect(),
            final_speed: norm(&|d| traj.velocity(d)[last]),
        }
    }
}

/// `Σ (a_k − b_k)²` over two equally long slices (`b` all zero for a plain sum of
/// squares), with eight independent partial sums: vectorised, and no single
/// latency-bound chain of additions.
fn sum_of_squared_differences(a: &[f64], b: Option<&[f64]>) -> f64 {
    let mut acc = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.map(|b| b.chunks_exact(8)));
    let (ra, rb) = (ca.remainder(), cb.as_ref().map(|c| c.remainder()));
    match cb {
        Some(cb) => {
            for (x, y) in ca.zip(cb) {
                for l in 0..8 {
                    let d = x[l] - y[l];
                    acc[l] += d * d;
                }
            }
        }
        None => {
            for x in ca {
                for l in 0..8 {
                    acc[l] += x[l] * x[l];
                }
            }
        }
    }
    for (l, x) in ra.iter().enumerate() {
        let d = x - rb.map_or(0.0, |r| r[l]);
        acc[l] += d * d;
    }
    acc.iter().sum()
}

/// Errors of a trajectory in the task's units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskErrors {
    /// Distance from the goal at `t = tau`.
    pub goal: f64,
    /// Distance from each via point at its time.
    pub via: Vec<f64>,
    /// Speed at `t = tau`.
    pub final_speed: f64,
}

impl TaskErrors {
    /// The largest of the goal and via-point distances.
    pub fn max_position_error(&self) -> f64 {
        self.via.iter().fold(self.goal, |a, &b| a.max(b))
    }
}
