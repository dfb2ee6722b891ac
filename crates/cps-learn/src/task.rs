//! The via-point task and its cost (Rueckert & d'Avella 2013; thesis eq. 54).

use cps_dmp::{
    BATCH_LANES, DiscreteDmp, DmpConfig, Lanes, StreamVisitor, Trajectory, locate_on_grid,
};
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

/// Weights of the cost terms; a weight of 0 switches its term off. All must be ≥ 0.
///
/// ```text
/// C = w_goal ‖y_T − g‖² + w_via Σ_i ‖y(t_i) − p_i‖² + w_vel ‖ẏ_T − ġ‖²
///   + w_acc Σ_k ‖ÿ_k‖² + w_jerk Σ_k ‖(ÿ_{k+1} − ÿ_k)/h‖²
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
}

impl CostBreakdown {
    /// The sum of the terms.
    pub fn total(&self) -> f64 {
        self.goal + self.via + self.final_velocity + self.acceleration + self.jerk
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
}

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
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(LearnError::task(
                    format!("cost.{name}"),
                    format!("must be a finite weight ≥ 0, got {value}"),
                ));
            }
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
    }

    /// The cost of a trajectory.
    pub fn cost(&self, traj: &Trajectory) -> f64 {
        let mut total = 0.0;
        self.residuals(traj, |_, r| total += r * r);
        total
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
            };
            *slot += r * r;
        });
        b
    }

    /// The costs of up to [`BATCH_LANES`] weight vectors (back to back in `weights`) from
    /// one streaming batch rollout, without storing trajectories: the fast path of
    /// population evaluation. Agrees with [`Self::cost`] of each rollout to rounding.
    ///
    /// # Panics
    /// If `out.len()` is not the number of weight vectors or it exceeds `BATCH_LANES`.
    pub fn costs_streamed(&self, dmp: &DiscreteDmp, weights: &[f64], out: &mut [f64]) {
        let m = out.len();
        assert!((1..=BATCH_LANES).contains(&m) && weights.len() == m * dmp.n_weights());
        let w = &self.weights;
        let dims = dmp.dims();
        let last = dmp.n_samples() - 1;
        let times = dmp.times();
        let h = times[1] - times[0];
        // Where each via point falls on the grid: sample k and fraction towards k + 1.
        let via_at: Vec<(usize, f64)> = self
            .via
            .iter()
            .map(|v| locate_on_grid(times, v.time))
            .collect();
        let zero = [0.0; BATCH_LANES];
        let mut marked = vec![false; last + 1];
        marked[last] = true;
        for &(k, frac) in &via_at {
            marked[k] = true;
            if frac > 0.0 {
                marked[(k + 1).min(last)] = true;
            }
        }
        let mut sink = CostSink {
            task: self,
            via_at,
            marked,
            use_acc: w.acceleration > 0.0,
            use_jerk: w.jerk > 0.0,
            last,
            inv_h: 1.0 / h,
            via_pos: vec![zero; self.via.len() * dims],
            prev_a: vec![zero; dims],
            acc: vec![zero; dims],
            jerk: vec![zero; dims],
            end: zero,
        };
        dmp.rollout_stream(weights, &mut sink);
        let CostSink {
            via_pos,
            acc,
            jerk,
            end,
            ..
        } = sink;
        for (l, o) in out.iter_mut().enumerate() {
            let mut via = 0.0;
            for (i, p) in self.via.iter().enumerate() {
                for d in 0..dims {
                    let e = via_pos[i * dims + d][l] - p.position[d];
                    via += e * e;
                }
            }
            let acc: f64 = acc.iter().map(|a| a[l]).sum();
            let jerk: f64 = jerk.iter().map(|j| j[l]).sum();
            *o = end[l] + w.via * via + w.acceleration * acc + w.jerk * jerk;
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

/// Accumulates a via-point cost from a streaming batch rollout, lane by lane.
struct CostSink<'a> {
    task: &'a ViaPointTask,
    /// Grid sample and fraction towards the next sample of each via point.
    via_at: Vec<(usize, f64)>,
    /// Samples where a via point or the goal is read.
    marked: Vec<bool>,
    use_acc: bool,
    use_jerk: bool,
    last: usize,
    inv_h: f64,
    via_pos: Vec<Lanes>,
    prev_a: Vec<Lanes>,
    acc: Vec<Lanes>,
    jerk: Vec<Lanes>,
    end: Lanes,
}

impl StreamVisitor for CostSink<'_> {
    #[inline(always)]
    fn visit(&mut self, k: usize, d: usize, y: &Lanes, v: &Lanes, a: &Lanes) {
        if self.use_acc {
            let acc = &mut self.acc[d];
            for l in 0..BATCH_LANES {
                acc[l] += a[l] * a[l];
            }
        }
        if self.use_jerk {
            if k > 0 {
                let (jerk, prev) = (&mut self.jerk[d], &self.prev_a[d]);
                for l in 0..BATCH_LANES {
                    let j = (a[l] - prev[l]) * self.inv_h;
                    jerk[l] += j * j;
                }
            }
            self.prev_a[d] = *a;
        }
        if self.marked[k] {
            self.sample(k, d, y, v);
        }
    }
}

impl CostSink<'_> {
    /// The rare samples that carry a via point or the goal.
    #[inline(never)]
    fn sample(&mut self, k: usize, d: usize, y: &Lanes, v: &Lanes) {
        let dims = self.prev_a.len();
        for (i, &(kv, frac)) in self.via_at.iter().enumerate() {
            let c = if k == kv {
                1.0 - frac
            } else if frac > 0.0 && k == kv + 1 {
                frac
            } else {
                continue;
            };
            let slot = &mut self.via_pos[i * dims + d];
            for l in 0..BATCH_LANES {
                slot[l] += c * y[l];
            }
        }
        if k == self.last {
            let w = &self.task.weights;
            let (g, gv) = (self.task.goal[d], self.task.goal_velocity[d]);
            for l in 0..BATCH_LANES {
                let (eg, ev) = (y[l] - g, v[l] - gv);
                self.end[l] += w.goal * eg * eg + w.final_velocity * ev * ev;
            }
        }
    }
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
