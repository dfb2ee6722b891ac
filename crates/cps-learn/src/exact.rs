//! The exact optimum of a cost that is a sum of squared residuals affine in the weights.
//!
//! The rollout is affine in the DMP weights. When every cost residual is affine in the
//! rollout (the via-point cost without obstacles; the effort cost, whose plant is
//! linear), the cost is `‖r₀ + J θ‖²`: a linear least-squares problem. Its columns are
//! found by rolling out unit parameter vectors (no separate derivation that could drift
//! from the rollout), and it is solved with a Householder QR (faer), which works on J
//! directly instead of squaring its condition number in normal equations.
//!
//! The same `J` gives [`QuadraticCost`]: the cost as `c* + (θ − θ*)ᵀ H (θ − θ*)`,
//! which a search (CMA-ES) can evaluate for a whole population in a fraction of a
//! rollout's time, to the same value.

use cps_dmp::{DiscreteDmp, Trajectory};
use faer::Mat;
use faer::prelude::SolveLstsq;
use serde::{Deserialize, Serialize};

use crate::task::Term;
use crate::{CostBreakdown, LearnError, SearchSpace, ViaPointTask};

/// The least-squares optimum of a via-point task.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExactOptimum {
    /// Optimal parameters θ in the search space used.
    pub params: Vec<f64>,
    /// Optimal DMP weights.
    pub weights: Vec<f64>,
    /// The optimal cost (evaluated by a rollout of the optimal weights). With obstacles it
    /// leaves their term out (the optimum is of the quadratic terms only), and is then a
    /// lower bound of the whole cost's minimum.
    pub cost: f64,
    /// The optimal cost term by term.
    pub breakdown: CostBreakdown,
    /// Condition number of the Hessian `2 JᵀJ` in the search space used: how hard the
    /// problem is for an optimiser that must learn its shape (CMA-ES).
    pub hessian_condition: f64,
}

/// A cost's residuals as an affine map of the parameters: `r(θ) = r₀ + J θ`.
pub(crate) struct AffineResiduals {
    /// The residuals at θ = 0.
    pub(crate) r0: Vec<f64>,
    /// Their Jacobian, one column per parameter.
    pub(crate) jac: Mat<f64>,
    /// The DMP's dimensions and basis functions per dimension (for the block solve).
    dims: usize,
    n_basis: usize,
}

impl AffineResiduals {
    /// Finds `r₀` and `J` of the residuals that `residuals` writes for a trajectory (it
    /// must clear `out` and push the same number of residuals every time), by rollouts
    /// of θ = 0 and of every unit vector, eight at a time in reused trajectories.
    pub(crate) fn of(
        dmp: &DiscreteDmp,
        space: &SearchSpace,
        mut residuals: impl FnMut(&Trajectory, &mut Vec<f64>),
    ) -> Result<Self, LearnError> {
        let n = space.len();
        let mut r0 = Vec::new();
        residuals(&dmp.rollout(&space.weights(&vec![0.0; n])), &mut r0);
        let m = r0.len();
        if m < n {
            return Err(LearnError::Exact(format!(
                "{m} residuals cannot determine {n} parameters: add cost terms (acceleration or jerk) or via points"
            )));
        }
        let mut jac = Mat::<f64>::zeros(m, n);
        let nw = dmp.n_weights();
        const BATCH: usize = 8;
        let mut trajs: Vec<_> = (0..BATCH.min(n)).map(|_| dmp.new_trajectory()).collect();
        let mut weights = vec![0.0; BATCH * nw];
        let mut e = vec![0.0; n];
        let mut r = Vec::with_capacity(m);
        for j0 in (0..n).step_by(BATCH) {
            let cols = BATCH.min(n - j0);
            for (c, w) in weights.chunks_exact_mut(nw).take(cols).enumerate() {
                e[j0 + c] = 1.0;
                space.to_weights(&e, w);
                e[j0 + c] = 0.0;
            }
            dmp.rollout_batch(&weights[..cols * nw], &mut trajs[..cols]);
            for (c, traj) in trajs[..cols].iter().enumerate() {
                residuals(traj, &mut r);
                debug_assert_eq!(r.len(), m, "the residual count changed with θ");
                let mut col = jac.col_mut(j0 + c);
                for (i, (&ri, &r0i)) in r.iter().zip(&r0).enumerate() {
                    col[i] = ri - r0i;
                }
            }
        }
        Ok(Self {
            r0,
            jac,
            dims: dmp.dims(),
            n_basis: dmp.n_basis(),
        })
    }

    /// The least-squares solution θ* of `min ‖r₀ + J θ‖²` and the condition number of
    /// the Hessian `2 JᵀJ`. Solved block by block when no residual couples the DMP's
    /// dimensions (J is then block diagonal up to a row permutation, and each block is a
    /// small independent problem); otherwise one QR of the whole J.
    pub(crate) fn solve(&self) -> Result<(Vec<f64>, f64), LearnError> {
        let jac = &self.jac;
        let blocks = decoupled_blocks(jac, self.dims, self.n_basis);
        let mut params = vec![0.0; jac.ncols()];
        let (mut smax, mut smin) = (0.0f64, f64::INFINITY);
        for (cols, rows) in &blocks {
            let sub = Mat::from_fn(rows.len(), cols.len(), |i, j| jac[(rows[i], cols[j])]);
            let rhs = Mat::from_fn(rows.len(), 1, |i, _| -self.r0[rows[i]]);
            let qr = sub.qr();
            // cond(J) = cond(R): singular values of the small square factor R.
            let sv = qr
                .thin_R()
                .singular_values()
                .map_err(|_| {
                    LearnError::Exact(
                        "the singular value decomposition of the cost's Jacobian did not converge (are the settings extreme?)".into(),
                    )
                })?;
            for &v in &sv {
                smax = smax.max(v);
                smin = smin.min(v);
            }
            let sol = qr.solve_lstsq(&rhs);
            for (j, &c) in cols.iter().enumerate() {
                params[c] = sol[(j, 0)];
            }
        }
        if smin.is_nan() || smin <= smax * 1e-14 {
            return Err(LearnError::Exact(format!(
                "the problem is rank deficient (singular values from {smax:.3e} down to {smin:.3e}): \
                 some weights do not affect the cost; add an acceleration or jerk term"
            )));
        }
        Ok((params, (smax / smin).powi(2)))
    }
}

/// Column blocks (one per DMP dimension) with the rows that touch them, when no row
/// touches two blocks; otherwise a single block with everything.
fn decoupled_blocks(jac: &Mat<f64>, dims: usize, nb: usize) -> Vec<(Vec<usize>, Vec<usize>)> {
    let (m, n) = (jac.nrows(), jac.ncols());
    let mut owner = vec![usize::MAX; m];
    for d in 0..dims {
        for j in d * nb..(d + 1) * nb {
            for (i, &v) in jac.col(j).iter().enumerate() {
                if v != 0.0 {
                    if owner[i] != usize::MAX && owner[i] != d {
                        return vec![((0..n).collect(), (0..m).collect())];
                    }
                    owner[i] = d;
                }
            }
        }
    }
    (0..dims)
        .map(|d| {
            let rows = (0..m).filter(|&i| owner[i] == d).collect();
            ((d * nb..(d + 1) * nb).collect(), rows)
        })
        .collect()
}

/// The via-point cost's residuals of a trajectory, obstacles left out (they are not
/// affine).
fn quadratic_residuals(task: &ViaPointTask, traj: &Trajectory, out: &mut Vec<f64>) {
    out.clear();
    task.residuals(traj, |term, r| {
        if term != Term::Obstacle {
            out.push(r);
        }
    });
}

/// The exact optimum of `task` in the search space `space`.
pub fn exact_optimum(
    task: &ViaPointTask,
    dmp: &DiscreteDmp,
    space: &SearchSpace,
) -> Result<ExactOptimum, LearnError> {
    let affine = AffineResiduals::of(dmp, space, |traj, out| quadratic_residuals(task, traj, out))?;
    let (params, hessian_condition) = affine.solve()?;
    let weights = space.weights(&params);
    let traj = dmp.rollout(&weights);
    let breakdown = task.breakdown(&traj);
    Ok(ExactOptimum {
        params,
        weights,
        cost: breakdown.total() - breakdown.obstacle,
        breakdown,
        hessian_condition,
    })
}

/// A cost that is exactly quadratic in the parameters, in the form that is cheapest and
/// most accurate to evaluate: `c(θ) = c* + (θ − θ*)ᵀ H (θ − θ*)` about its minimum
/// (`H = JᵀJ`). Centred on the minimum, a candidate near it costs `c*` plus a small
/// positive quadratic: no cancellation of the large costs far from it.
///
/// For a via-point task without obstacles it equals the rollout's cost to rounding
/// (≈ 1e-12 relative) at `n²` multiply-adds per candidate instead of a rollout of the
/// whole movement; CMA-ES then learns the same function, with the same generations and
/// evaluations, many times faster.
#[derive(Debug, Clone)]
pub struct QuadraticCost {
    centre: Vec<f64>,
    minimum: f64,
    /// `H`, row-major `n × n`.
    hessian: Vec<f64>,
}

impl QuadraticCost {
    /// The via-point cost of `task` (without its obstacle term) in `space`.
    pub fn of_task(
        task: &ViaPointTask,
        dmp: &DiscreteDmp,
        space: &SearchSpace,
    ) -> Result<Self, LearnError> {
        let affine =
            AffineResiduals::of(dmp, space, |traj, out| quadratic_residuals(task, traj, out))?;
        Self::from_affine(&affine)
    }

    /// The quadratic `‖r₀ + J θ‖²` of affine residuals.
    pub(crate) fn from_affine(affine: &AffineResiduals) -> Result<Self, LearnError> {
        let (centre, _) = affine.solve()?;
        let jac = &affine.jac;
        let n = jac.ncols();
        let h = jac.transpose() * jac;
        let mut minimum = 0.0;
        for (i, &r0) in affine.r0.iter().enumerate() {
            let r = r0 + (0..n).map(|j| jac[(i, j)] * centre[j]).sum::<f64>();
            minimum += r * r;
        }
        Ok(Self {
            centre,
            minimum,
            hessian: (0..n * n).map(|k| h[(k / n, k % n)]).collect(),
        })
    }

    /// The number of parameters.
    pub fn len(&self) -> usize {
        self.centre.len()
    }

    /// True for a cost of no parameters.
    pub fn is_empty(&self) -> bool {
        self.centre.is_empty()
    }

    /// The minimiser θ*.
    pub fn minimiser(&self) -> &[f64] {
        &self.centre
    }

    /// The minimum `c(θ*)`.
    pub fn minimum(&self) -> f64 {
        self.minimum
    }

    /// The cost at `theta`; `scratch` (any length) is reused.
    ///
    /// # Panics
    /// If `theta.len() != self.len()`.
    pub fn cost(&self, theta: &[f64], scratch: &mut Vec<f64>) -> f64 {
        let n = self.centre.len();
        assert_eq!(theta.len(), n, "parameter vector length");
        scratch.clear();
        scratch.extend(theta.iter().zip(&self.centre).map(|(t, c)| t - c));
        let q: f64 = self
            .hessian
            .chunks_exact(n)
            .zip(scratch.iter())
            .map(|(row, &di)| di * dot(row, scratch))
            .sum();
        self.minimum + q.max(0.0)
    }
}

/// `a · b` with eight independent sums (a single running sum is a chain of dependent
/// additions that no processor can overlap, and that the compiler may not reorder).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    acc.iter().sum::<f64>() + tail
}
