//! The via-point cost of a movement as the robot executed it: where the tool really was at
//! the via-point times and at the end, how far it lagged its targets, with the effort
//! terms of the commanded movement. Learning on this cost judges what the robot does, not
//! what the DMP says (the thesis's case for learning in simulation).

use cps_dmp::Trajectory;
use cps_robot::Recording;
use serde::{Deserialize, Serialize};

use crate::task::{CostBreakdown, ViaPointTask};

/// The terms of [`executed_cost`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ExecutedCost {
    /// The task's terms: goal, via points and final velocity as executed; acceleration,
    /// jerk and obstacles of the commanded movement.
    pub terms: CostBreakdown,
    /// `w_track Σ_k ‖e_k‖²`: the executed tool's distance from its target at every control
    /// step (joint limits hit, a lagging controller, dynamics).
    pub tracking: f64,
    /// `w_speed Σ_j u_j²`, `u_j` the executed joint j's peak speed as a fraction of its
    /// limit: keeps a margin to the speed limits.
    #[serde(default)]
    pub speed_usage: f64,
    /// `w Σ_k Σ_p (c − d_p)²` over the executed joints' pairs closer than the clearance
    /// `c` ([`crate::Clearance`]; zero without one): added by the caller that keeps one
    /// ([`ExecutedCost::add_clearance`]).
    #[serde(default)]
    pub clearance: f64,
}

impl ExecutedCost {
    /// The sum of every term.
    pub fn total(&self) -> f64 {
        self.terms.total() + self.tracking + self.speed_usage + self.clearance
    }

    /// Adds the clearance term of `recording`'s joints on `chain` (an error if forward
    /// kinematics refuses a recorded configuration).
    pub fn add_clearance(
        &mut self,
        clearance: &crate::Clearance,
        chain: &cps_kinematics::SerialChain,
        recording: &Recording,
    ) -> Result<(), cps_kinematics::KinematicsError> {
        let mut r = Vec::with_capacity(recording.q.len());
        clearance.residuals_of_recording(
            chain,
            recording,
            &mut crate::ClearanceBuffers::default(),
            &mut r,
        )?;
        self.clearance = r.iter().map(|x| x * x).sum();
        Ok(())
    }
}

/// The weights [`executed_cost`] adds to the task's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ExecutedWeights {
    /// Of the squared tracking errors (m², summed over the control steps).
    pub tracking: f64,
    /// Of the squared peak speed usages of the joints (fractions of their limits).
    pub speed_usage: f64,
}

/// Plain-unit errors of an executed movement.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ExecutedErrors {
    /// Distance of the executed tool from the goal at the end (m).
    pub goal: f64,
    /// Distance of the executed tool from each via point at its time (m).
    pub via: Vec<f64>,
    /// The largest distance from a target during the execution (m).
    pub max_tracking: f64,
    /// Samples the controller did not reach within its iterations.
    pub unconverged: usize,
    /// Each joint's peak executed speed as a fraction of its limit (empty without
    /// limits).
    pub speed_usage: Vec<f64>,
}

/// Each joint's peak speed over `recording` (differences of the measured joints over the
/// recorded clock) as a fraction of `limits`.
fn speed_usage(recording: &Recording, limits: &[f64]) -> Vec<f64> {
    let mut peak = vec![0.0_f64; limits.len()];
    for k in 1..recording.q.len().min(recording.time.len()) {
        let h = recording.time[k] - recording.time[k - 1];
        if h <= 0.0 {
            continue;
        }
        for (j, p) in peak.iter_mut().enumerate() {
            let (a, b) = (recording.q[k - 1].get(j), recording.q[k].get(j));
            if let (Some(a), Some(b)) = (a, b) {
                *p = p.max((b - a).abs() / h / limits[j]);
            }
        }
    }
    peak
}

/// The tool's executed position at time `t` (seconds from the start): `recording`'s
/// sample `k` is where the tool was when target `k`, at `times[k]`, was due; linear
/// between samples, held beyond the last.
fn executed_at(times: &[f64], rec: &Recording, t: f64) -> [f64; 3] {
    let n = rec.position.len().min(times.len());
    if n == 0 {
        return [f64::NAN; 3];
    }
    let k = times[..n].partition_point(|&s| s <= t);
    if k == 0 {
        return rec.position[0];
    }
    if k >= n {
        return rec.position[n - 1];
    }
    let (a, b) = (times[k - 1], times[k]);
    let u = if b > a { (t - a) / (b - a) } else { 0.0 };
    let (p, q) = (rec.position[k - 1], rec.position[k]);
    [0, 1, 2].map(|d| p[d] + u * (q[d] - p[d]))
}

fn squared_distance(p: &[f64; 3], q: &[f64]) -> f64 {
    (0..3).map(|d| (p[d] - q[d]).powi(2)).sum()
}

/// The cost of `traj` (a 3-D task-space movement) as `recording` shows it executed, its
/// targets due at `times` (from [`crate::targets_at`]): the task's goal, via-point and
/// final-velocity terms on the executed positions (the final velocity by the last
/// difference), its acceleration, jerk and obstacle terms on the commanded movement, the
/// squared tracking errors and the joints' squared peak speed usages (of `speed_limits`,
/// if the robot has them), with `weights`. A recording shorter than the targets (an
/// execution cut short) costs +∞.
pub fn executed_cost(
    task: &ViaPointTask,
    traj: &Trajectory,
    times: &[f64],
    recording: &Recording,
    weights: &ExecutedWeights,
    speed_limits: Option<&[f64]>,
) -> (ExecutedCost, ExecutedErrors) {
    let w = &task.weights;
    let commanded = task.breakdown(traj);
    let n = times.len();
    if recording.position.len() < n || n == 0 || task.goal.len() != 3 {
        let inf = ExecutedCost {
            terms: CostBreakdown {
                goal: f64::INFINITY,
                ..commanded
            },
            tracking: f64::INFINITY,
            speed_usage: 0.0,
            clearance: 0.0,
        };
        return (inf, ExecutedErrors::default());
    }
    let last = recording.position[n - 1];
    let goal = squared_distance(&last, &task.goal);
    let via: Vec<f64> = task
        .via
        .iter()
        .map(|v| squared_distance(&executed_at(times, recording, v.time), &v.position))
        .collect();
    let final_velocity = if n >= 2 && times[n - 1] > times[n - 2] {
        let prev = recording.position[n - 2];
        let h = times[n - 1] - times[n - 2];
        (0..3)
            .map(|d| ((last[d] - prev[d]) / h - task.goal_velocity[d]).powi(2))
            .sum()
    } else {
        0.0
    };
    let tracked = &recording.position_error[..n.min(recording.position_error.len())];
    let usage = speed_limits.map_or(Vec::new(), |l| speed_usage(recording, l));
    let cost = ExecutedCost {
        terms: CostBreakdown {
            goal: w.goal * goal,
            via: w.via * via.iter().sum::<f64>(),
            final_velocity: w.final_velocity * final_velocity,
            ..commanded
        },
        tracking: weights.tracking * tracked.iter().map(|e| e * e).sum::<f64>(),
        speed_usage: weights.speed_usage * usage.iter().map(|u| u * u).sum::<f64>(),
        clearance: 0.0,
    };
    let errors = ExecutedErrors {
        goal: goal.sqrt(),
        via: via.iter().map(|v| v.sqrt()).collect(),
        max_tracking: tracked.iter().fold(0.0, |a: f64, &e| a.max(e)),
        unconverged: recording.unconverged,
        speed_usage: usage,
    };
    (cost, errors)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::targets_at;

    const W: ExecutedWeights = ExecutedWeights {
        tracking: 1e5,
        speed_usage: 0.0,
    };

    /// Peak speed usage: a joint moving 0.01 rad per 0.01 s step uses half of a 2 rad/s
    /// limit; the term is w Σ u².
    #[test]
    fn speed_usage_is_the_peak_fraction_of_each_limit() {
        let rec = Recording {
            time: vec![0.0, 0.01, 0.02],
            q: vec![vec![0.0, 0.0], vec![0.01, 0.0], vec![0.015, -0.004]],
            ..Recording::default()
        };
        let u = speed_usage(&rec, &[2.0, 1.0]);
        assert!(
            (u[0] - 0.5).abs() < 1e-12 && (u[1] - 0.4).abs() < 1e-12,
            "{u:?}"
        );
    }

    /// A robot that executes the targets exactly: the executed cost is the analytic cost
    /// up to the final velocity's difference quotient; a robot that lags by a known
    /// offset pays it in every term, exactly.
    #[test]
    fn a_perfect_robot_pays_the_analytic_cost_and_a_lagging_one_its_lag() {
        let task = ViaPointTask::thesis();
        let dmp = task.build_dmp().unwrap();
        let w = vec![0.0; dmp.n_weights()];
        let traj = dmp.rollout(&w);
        let (times, targets) = targets_at(&traj, 0.01);
        let position: Vec<[f64; 3]> = targets
            .iter()
            .map(|t| match t {
                cps_kinematics::IkTarget::Position(p) => [p.x, p.y, p.z],
                _ => unreachable!(),
            })
            .collect();
        let perfect = Recording {
            time: times.clone(),
            position_error: vec![0.0; position.len()],
            position: position.clone(),
            ..Recording::default()
        };
        let (c, e) = executed_cost(&task, &traj, &times, &perfect, &W, None);
        let analytic = task.breakdown(&traj);
        assert!((c.terms.goal - analytic.goal).abs() <= 1e-9 * analytic.goal.max(1.0));
        assert!((c.terms.via - analytic.via).abs() <= 1e-6 * analytic.via.max(1.0));
        assert_eq!(c.terms.acceleration, analytic.acceleration);
        assert_eq!(c.tracking, 0.0);
        assert!(e.max_tracking == 0.0 && e.via.len() == 4);
        // 1 mm off in z at every sample.
        let lagging = Recording {
            position: position.iter().map(|p| [p[0], p[1], p[2] - 1e-3]).collect(),
            position_error: vec![1e-3; position.len()],
            ..perfect.clone()
        };
        let (l, le) = executed_cost(&task, &traj, &times, &lagging, &W, None);
        assert!((l.tracking - 1e5 * 1e-6 * position.len() as f64).abs() < 1e-9);
        assert!((le.max_tracking - 1e-3).abs() < 1e-15);
        assert!(l.total() > c.total());
        // Cut short: +∞.
        let short = Recording {
            position: position[..10].to_vec(),
            ..perfect
        };
        assert_eq!(
            executed_cost(&task, &traj, &times, &short, &W, None)
                .0
                .total(),
            f64::INFINITY
        );
    }
}
