//! The exact optimum of a via-point cost without a simulator in the loop.
//!
//! The rollout is affine in the DMP weights and every cost residual is affine in the
//! rollout, so the cost is `‖r₀ + J θ‖²`: a linear least-squares problem. Its columns are
//! found by rolling out unit parameter vectors (no separate derivation that could drift
//! from the rollout), and it is solved with a Householder QR (faer), which works on J
//! directly instead of squaring its condition number in normal equations.

use cps_dmp::DiscreteDmp;
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

/// Residual vector of the cost at parameters `theta`.
fn residual_vector(
    task: &ViaPointTask,
    dmp: &DiscreteDmp,
    space: &SearchSpace,
    theta: &[f64],
    out: &mut Vec<f64>,
) {
    let traj = dmp.rollout(&space.weights(theta));
    out.clear();
    task.residuals(&traj, |term, r| {
        if term != Term::Obstacle {
            out.push(r);
        }
    });
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

/// The exact optimum of `task` in the search space `space`.
pub fn exact_optimum(
    task: &ViaPointTask,
    dmp: &DiscreteDmp,
    space: &SearchSpace,
) -> Result<ExactOptimum, LearnError> {
    let n = space.len();
    let mut r0 = Vec::new();
    residual_vector(task, dmp, space, &vec![0.0; n], &mut r0);
    let m = r0.len();
    if m < n {
        return Err(LearnError::Exact(format!(
            "{m} residuals cannot determine {n} parameters: add cost terms (acceleration or jerk) or via points"
        )));
    }
    // Column j of J: the residuals at the unit vector e_j minus those at 0, by batch
    // rollouts of eight unit vectors at a time in reused trajectories.
    let mut jac = Mat::<f64>::zeros(m, n);
    let nw = dmp.n_weights();
    const BATCH: usize = 8;
    let mut trajs: Vec<_> = (0..BATCH.min(n)).map(|_| dmp.new_trajectory()).collect();
    let mut weights = vec![0.0; BATCH * nw];
    let mut e = vec![0.0; n];
    for j0 in (0..n).step_by(BATCH) {
        let cols = BATCH.min(n - j0);
        for (c, w) in weights.chunks_exact_mut(nw).take(cols).enumerate() {
            e[j0 + c] = 1.0;
            space.to_weights(&e, w);
            e[j0 + c] = 0.0;
        }
        dmp.rollout_batch(&weights[..cols * nw], &mut trajs[..cols]);
        for (c, traj) in trajs[..cols].iter().enumerate() {
            let mut i = 0;
            let mut col = jac.col_mut(j0 + c);
            task.residuals(traj, |term, r| {
                if term != Term::Obstacle {
                    col[i] = r - r0[i];
                    i += 1;
                }
            });
        }
    }
    // Solve block by block when no residual couples the DMP's dimensions (J is then block
    // diagonal up to a row permutation, and each block is a small independent problem);
    // otherwise one QR of the whole J.
    let blocks = decoupled_blocks(&jac, dmp.dims(), dmp.n_basis());
    let mut params = vec![0.0; n];
    let (mut smax, mut smin) = (0.0f64, f64::INFINITY);
    for (cols, rows) in &blocks {
        let sub = Mat::from_fn(rows.len(), cols.len(), |i, j| jac[(rows[i], cols[j])]);
        let rhs = Mat::from_fn(rows.len(), 1, |i, _| -r0[rows[i]]);
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
    let mut weights = vec![0.0; n];
    space.to_weights(&params, &mut weights);
    let traj = dmp.rollout(&weights);
    let breakdown = task.breakdown(&traj);
    Ok(ExactOptimum {
        params,
        weights,
        cost: breakdown.total() - breakdown.obstacle,
        breakdown,
        hessian_condition: (smax / smin).powi(2),
    })
}
