//! Levenberg–Marquardt on a cost that is a sum of squared residuals, `C(θ) = ‖r(θ)‖²`.
//!
//! Every cost cps learns is one (the via points, the goal, the accelerations, the
//! obstacle and limit hinges, the orientation angles), and a search that knows it
//! converges in tens of steps where CMA-ES, which sees only the costs' ranks, needs
//! thousands of generations. Each step:
//!
//! 1. the Jacobian `J` by forward differences, one column per parameter, columns in
//!    parallel (a column is a rollout: the cost's own code, no derivation that could
//!    drift from it; rows that do not move are exactly zero, as the DMP's dimensions are
//!    rolled out independently);
//! 2. the normal equations `(JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr`, `JᵀJ` summed row by row over
//!    each row's non-zero columns (a DMP's acceleration rows touch one dimension's
//!    weights only: the sum costs a few per cent of the dense product), solved by
//!    Cholesky;
//! 3. the step is taken if it lowers the cost (then λ shrinks), else λ grows and the step
//!    is solved again (Marquardt's scaling by `diag(JᵀJ)` makes λ unit-free).
//!
//! It stops when a step lowers the cost by less than `tol` relative, when no λ gives a
//! lower cost, at the iteration budget, or when the caller says so. Deterministic: the
//! same start gives the same bits on any number of threads.

use std::ops::ControlFlow;

use cps_cmaes::GenerationReport;
use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use rayon::prelude::*;

use cps_dmp::{DiscreteDmp, Trajectory};

use crate::exact::dot;
use crate::search::{BufferPool, GenerationRecord, SearchStats};
use crate::{LearnError, SearchSpace, ViaPointTask};

/// The settings of a learner's search as Levenberg–Marquardt's: its generation budget as
/// the iteration budget, and a relative tolerance of 1e-10 (a step that gains less has
/// reached the minimum to the precision of the forward differences).
pub(crate) fn settings(generations: u64) -> LmSettings {
    LmSettings {
        max_iterations: generations,
        tol: 1e-10,
        reuse_jacobian: false,
        refresh_every: 0,
        patient: false,
    }
}

/// Levenberg–Marquardt from a search's result `x` (up to 1000 iterations, until
/// converged), its iterations and evaluations added to the search's statistics and its
/// history appended (numbered on); the termination becomes `<search's>+polished`.
pub(crate) fn polish<R: Residuals>(
    problem: &R,
    x: Vec<f64>,
    mut stats: SearchStats,
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<(Vec<f64>, SearchStats), LearnError> {
    let settings = LmSettings {
        max_iterations: 1000,
        tol: 1e-10,
        reuse_jacobian: false,
        refresh_every: 0,
        patient: false,
    };
    let (x, lm) = levenberg_marquardt(problem, x, settings, progress)?;
    let offset = stats.generations;
    stats.history.extend(lm.history.into_iter().map(|mut h| {
        h.generation += offset;
        h
    }));
    stats.generations += lm.generations;
    stats.evaluations += lm.evaluations;
    stats.termination = if lm.termination == "interrupted" {
        lm.termination
    } else {
        format!("{}+polished", stats.termination)
    };
    Ok((x, stats))
}

/// The via-point cost's residuals (obstacles included) over a search space's θ.
pub(crate) struct TaskResiduals<'a> {
    pub(crate) task: &'a ViaPointTask,
    pub(crate) dmp: &'a DiscreteDmp,
    pub(crate) space: &'a SearchSpace,
}

impl Residuals for TaskResiduals<'_> {
    type Buffers = (Vec<f64>, Trajectory);

    fn buffers(&self) -> Self::Buffers {
        (vec![0.0; self.dmp.n_weights()], self.dmp.new_trajectory())
    }

    fn residuals(&self, theta: &[f64], (w, traj): &mut Self::Buffers, out: &mut Vec<f64>) -> bool {
        self.space.to_weights(theta, w);
        self.dmp.rollout_into(w, traj);
        out.clear();
        self.task.residuals(traj, |_, r| out.push(r));
        true
    }
}

/// A cost as residuals of the parameters θ.
pub(crate) trait Residuals: Sync {
    /// Buffers one evaluation needs (a trajectory, weights).
    type Buffers: Send;
    /// Fresh buffers.
    fn buffers(&self) -> Self::Buffers;
    /// Writes the residuals at `theta` into `out` (cleared first; the same count for every
    /// θ). Returns false if the cost cannot be evaluated there (forward kinematics refused
    /// a configuration): the step is then rejected.
    fn residuals(&self, theta: &[f64], buffers: &mut Self::Buffers, out: &mut Vec<f64>) -> bool;
}

/// Settings of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct LmSettings {
    /// Iteration budget.
    pub(crate) max_iterations: u64,
    /// Stop once a step lowers the cost by less than this fraction of it.
    pub(crate) tol: f64,
    /// Keep the Jacobian across iterations while its steps lower the cost, computing it
    /// afresh only when they stop doing so (a chord method): for residuals that are
    /// expensive (an execution each) and nearly linear in θ, an iteration then costs
    /// one evaluation instead of one per parameter.
    pub(crate) reuse_jacobian: bool,
    /// With `reuse_jacobian`: a kept Jacobian is computed afresh after this many
    /// iterations at the most (0: only when its steps stop gaining).
    pub(crate) refresh_every: u64,
    /// Grow λ until a step gains or λ passes 1e12, instead of for 12 tries, before calling
    /// the search converged: for costs with hinges (a clearance), where a Jacobian by
    /// forward differences can lead a short step only.
    pub(crate) patient: bool,
}

/// Minimises `‖r(θ)‖²` from `x0` (see the module documentation). `progress` is called
/// after every iteration with the cost as the "best" and "best so far", λ as the "step
/// size", and may stop the search (termination `interrupted`).
pub(crate) fn levenberg_marquardt<R: Residuals>(
    problem: &R,
    x0: Vec<f64>,
    settings: LmSettings,
    progress: &(dyn Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<(Vec<f64>, SearchStats), LearnError> {
    let n = x0.len();
    let pool = BufferPool::default();
    let eval = |theta: &[f64], out: &mut Vec<f64>| {
        pool.with(
            || problem.buffers(),
            |b| problem.residuals(theta, b, out) && out.iter().all(|r| r.is_finite()),
        )
    };
    let mut x = x0;
    let mut r = Vec::new();
    if !eval(&x, &mut r) {
        return Err(LearnError::Exact(
            "the cost cannot be evaluated at the search's start (a configuration forward kinematics refuses, or a value that is not finite)".into(),
        ));
    }
    let m = r.len();
    let mut cost = sum_sq(&r);
    let mut evaluations = 1u64;
    let mut lambda = 1e-3;
    let mut history = Vec::new();
    let mut termination = "max_iterations";
    let mut jac = vec![0.0; m * n]; // column-major: column j at j m
    let mut trial = Vec::with_capacity(m);
    // Whether `jac` is the Jacobian at `x` (else at an earlier point, kept), and whether
    // there is one yet.
    let (mut at_x, mut have) = (false, false);
    let mut since_exact = 0u64;
    let mut iteration = 0;
    while iteration < settings.max_iterations {
        // 1. Forward differences, columns in parallel.
        if !at_x && (!settings.reuse_jacobian || !have) {
            evaluations += n as u64;
            if !forward_differences(&mut jac, &x, &r, &eval) {
                termination = "evaluation_failed";
                break;
            }
            (at_x, have) = (true, true);
        }
        // 2. JᵀJ and Jᵀr over each row's non-zero columns.
        let (h, g) = normal_equations(&jac, &r, m, n);
        // 3. Damped steps until one lowers the cost.
        let mut accepted = None;
        let tries = if settings.patient { 60 } else { 12 };
        for _ in 0..tries {
            if settings.patient && lambda > 1e12 {
                break;
            }
            let Some(delta) = damped_step(&h, &g, lambda) else {
                lambda *= 10.0;
                continue;
            };
            let xt: Vec<f64> = x.iter().zip(&delta).map(|(a, d)| a + d).collect();
            evaluations += 1;
            if eval(&xt, &mut trial) && sum_sq(&trial) < cost {
                // The reduction the linear model predicted: −(2 gᵀδ + δᵀHδ).
                let hd: f64 = (0..n)
                    .map(|i| delta[i] * dot(&h[i * n..(i + 1) * n], &delta))
                    .sum();
                accepted = Some((xt, -(2.0 * dot(&g, &delta) + hd)));
                break;
            }
            lambda *= 4.0;
        }
        let Some((xt, predicted)) = accepted else {
            if !at_x {
                // The kept Jacobian no longer leads downhill: compute it where we are.
                have = false;
                lambda = 1e-3;
                continue;
            }
            termination = "converged";
            break;
        };
        let exact_jacobian = at_x;
        at_x = false;
        iteration += 1;
        let new_cost = sum_sq(&trial);
        let gain = (cost - new_cost) / cost.max(f64::MIN_POSITIVE);
        let cost_before = cost;
        x = xt;
        std::mem::swap(&mut r, &mut trial);
        cost = new_cost;
        lambda = (lambda / 3.0).max(1e-12);
        history.push(GenerationRecord {
            generation: iteration,
            best: cost,
            median: cost,
            best_so_far: cost,
            sigma: lambda,
        });
        let report = GenerationReport {
            generation: iteration,
            evaluations,
            best_cost: cost,
            median_cost: cost,
            best_so_far: cost,
            sigma: lambda,
            condition: f64::NAN,
            mean: &x,
        };
        if progress(&report).is_break() {
            termination = "interrupted";
            break;
        }
        if gain < settings.tol && exact_jacobian {
            termination = "converged";
            break;
        }
        // A kept Jacobian whose step gained less than half what it predicted (or next to
        // nothing), or that is `refresh_every` iterations old, is computed afresh for the
        // next one.
        since_exact = if exact_jacobian { 1 } else { since_exact + 1 };
        if !exact_jacobian && (gain < settings.tol || cost_before - cost < 0.5 * predicted)
            || (settings.refresh_every > 0 && since_exact >= settings.refresh_every)
        {
            have = false;
        }
    }
    Ok((
        x,
        SearchStats {
            generations: history.len() as u64,
            evaluations,
            non_finite_evaluations: 0,
            termination: termination.into(),
            history,
        },
    ))
}

/// The Jacobian of the residuals `r` at `x` by forward differences into `jac`
/// (column-major), its columns in parallel; false when a residual cannot be evaluated.
fn forward_differences(
    jac: &mut [f64],
    x: &[f64],
    r: &[f64],
    eval: &(dyn Fn(&[f64], &mut Vec<f64>) -> bool + Sync),
) -> bool {
    let m = r.len();
    jac.par_chunks_mut(m).enumerate().all(|(j, col)| {
        let h = 1e-6 * x[j].abs().max(1.0);
        let mut xp = x.to_vec();
        xp[j] += h;
        let h = xp[j] - x[j]; // the step actually represented
        let mut rp = Vec::with_capacity(m);
        if !eval(&xp, &mut rp) {
            return false;
        }
        for ((c, &a), &b) in col.iter_mut().zip(&rp).zip(r) {
            *c = (a - b) / h;
        }
        true
    })
}

fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// `JᵀJ` (row-major `n × n`) and `Jᵀr` of a column-major `m × n` Jacobian. Each column
/// is read once to find its runs of non-zero rows; a product of two columns is then summed
/// over the overlaps of their runs only, in memory order (a DMP's acceleration rows touch
/// one dimension's weights, so most pairs of columns share only a few rows).
fn normal_equations(jac: &[f64], r: &[f64], m: usize, n: usize) -> (Vec<f64>, Vec<f64>) {
    let runs: Vec<Vec<(usize, usize)>> = jac
        .chunks_exact(m)
        .map(|col| {
            let mut runs = Vec::new();
            let mut i = 0;
            while i < m {
                if col[i] == 0.0 {
                    i += 1;
                    continue;
                }
                let start = i;
                while i < m && col[i] != 0.0 {
                    i += 1;
                }
                runs.push((start, i));
            }
            runs
        })
        .collect();
    let col = |j: usize| &jac[j * m..(j + 1) * m];
    let mut h = vec![0.0; n * n];
    let g: Vec<f64> = (0..n)
        .map(|j| {
            runs[j]
                .iter()
                .map(|&(a, b)| dot(&col(j)[a..b], &r[a..b]))
                .sum()
        })
        .collect();
    for a in 0..n {
        for b in a..n {
            let mut sum = 0.0;
            let (ra, rb) = (&runs[a], &runs[b]);
            let (mut p, mut q) = (0, 0);
            while p < ra.len() && q < rb.len() {
                let lo = ra[p].0.max(rb[q].0);
                let hi = ra[p].1.min(rb[q].1);
                if lo < hi {
                    sum += dot(&col(a)[lo..hi], &col(b)[lo..hi]);
                }
                if ra[p].1 < rb[q].1 {
                    p += 1;
                } else {
                    q += 1;
                }
            }
            h[a * n + b] = sum;
            h[b * n + a] = sum;
        }
    }
    (h, g)
}

/// Solves `(H + λ diag(H)) δ = −g` by Cholesky; `None` if the damped matrix is not
/// positive definite (λ too small for a singular `H`).
fn damped_step(h: &[f64], g: &[f64], lambda: f64) -> Option<Vec<f64>> {
    let n = g.len();
    let a = Mat::from_fn(n, n, |i, j| {
        let v = h[i * n + j];
        if i == j { v + lambda * v.max(1e-12) } else { v }
    });
    let llt = a.llt(Side::Lower).ok()?;
    let rhs = Mat::from_fn(n, 1, |i, _| -g[i]);
    let x = llt.solve(&rhs);
    let delta: Vec<f64> = (0..n).map(|i| x[(i, 0)]).collect();
    delta.iter().all(|d| d.is_finite()).then_some(delta)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock's function as residuals, `r = (10 (x₂ − x₁²), 1 − x₁)`: a curved valley
    /// with the minimum 0 at (1, 1), from the classic start (−1.2, 1).
    struct Rosenbrock;

    impl Residuals for Rosenbrock {
        type Buffers = ();
        fn buffers(&self) {}
        fn residuals(&self, x: &[f64], _: &mut (), out: &mut Vec<f64>) -> bool {
            out.clear();
            out.extend([10.0 * (x[1] - x[0] * x[0]), 1.0 - x[0]]);
            true
        }
    }

    fn quiet() -> impl Fn(&GenerationReport<'_>) -> ControlFlow<()> + Sync {
        |_| ControlFlow::Continue(())
    }

    #[test]
    fn it_finds_the_minimum_of_rosenbrocks_valley() {
        let settings = LmSettings {
            max_iterations: 200,
            tol: 1e-14,
            reuse_jacobian: false,
            refresh_every: 0,
            patient: false,
        };
        let (x, stats) =
            levenberg_marquardt(&Rosenbrock, vec![-1.2, 1.0], settings, &quiet()).unwrap();
        assert!(
            (x[0] - 1.0).abs() < 1e-6 && (x[1] - 1.0).abs() < 1e-6,
            "{x:?}"
        );
        assert!(stats.generations < 100, "{} iterations", stats.generations);
        // Every accepted step lowered the cost.
        assert!(stats.history.windows(2).all(|w| w[1].best < w[0].best));
    }

    #[test]
    fn a_kept_jacobian_still_finds_the_minimum_and_computes_fewer_columns() {
        let exact = LmSettings {
            max_iterations: 500,
            tol: 1e-14,
            reuse_jacobian: false,
            refresh_every: 0,
            patient: false,
        };
        let kept = LmSettings {
            reuse_jacobian: true,
            ..exact
        };
        let (x, stats) = levenberg_marquardt(&Rosenbrock, vec![-1.2, 1.0], kept, &quiet()).unwrap();
        assert!(
            (x[0] - 1.0).abs() < 1e-6 && (x[1] - 1.0).abs() < 1e-6,
            "{x:?}"
        );
        assert!(stats.history.windows(2).all(|w| w[1].best < w[0].best));
        // On a nearly linear problem (Rosenbrock near its minimum) the kept Jacobian
        // saves evaluations: from (0.9, 0.8), fewer columns than iterations × n.
        let (_, e) = levenberg_marquardt(&Rosenbrock, vec![0.9, 0.8], exact, &quiet()).unwrap();
        let (x, k) = levenberg_marquardt(&Rosenbrock, vec![0.9, 0.8], kept, &quiet()).unwrap();
        assert!((x[0] - 1.0).abs() < 1e-6 && (x[1] - 1.0).abs() < 1e-6);
        assert!(
            k.evaluations - k.generations < e.evaluations - e.generations,
            "kept {k:?} exact {e:?}"
        );
    }

    #[test]
    fn the_normal_equations_equal_the_dense_products() {
        // A column-major 5 × 3 Jacobian with zero runs in different places.
        let (m, n) = (5, 3);
        let jac = [
            1.0, 0.0, 2.0, 0.0, 3.0, // column 0
            0.0, 4.0, 5.0, 0.0, 0.0, // column 1
            6.0, 0.0, 0.0, 7.0, 8.0, // column 2
        ];
        let r = [1.0, -2.0, 0.5, 3.0, -1.0];
        let (h, g) = normal_equations(&jac, &r, m, n);
        for a in 0..n {
            let ga: f64 = (0..m).map(|i| jac[a * m + i] * r[i]).sum();
            assert_eq!(g[a], ga);
            for b in 0..n {
                let hab: f64 = (0..m).map(|i| jac[a * m + i] * jac[b * m + i]).sum();
                assert_eq!(h[a * n + b], hab, "({a}, {b})");
            }
        }
    }

    #[test]
    fn an_interrupted_search_says_so_and_keeps_its_best() {
        let settings = LmSettings {
            max_iterations: 200,
            tol: 1e-14,
            reuse_jacobian: false,
            refresh_every: 0,
            patient: false,
        };
        let stop = |r: &GenerationReport<'_>| {
            if r.generation >= 3 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        };
        let (x, stats) =
            levenberg_marquardt(&Rosenbrock, vec![-1.2, 1.0], settings, &stop).unwrap();
        assert_eq!(stats.termination, "interrupted");
        assert_eq!(stats.generations, 3);
        let mut r = Vec::new();
        Rosenbrock.residuals(&x, &mut (), &mut r);
        assert_eq!(sum_sq(&r), stats.history[2].best);
    }
}
