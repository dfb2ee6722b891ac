//! Velocity-level inverse controllers: one step `Δq` for a task-space error `e`
//! (thesis eq. 14–20). `J` is any m × n Jacobian, tall or fat.
//!
//! - Moore-Penrose pseudo-inverse `Δq = J⁺ e` (SVD; singular values below
//!   `1e-15 · σ_max` are treated as zero, like numpy's `pinv`). Exact but unbounded near
//!   singularities — why the thesis abandoned its own controller.
//! - Damped least squares `Δq = Jᵀ (J Jᵀ + λ² I)⁻¹ e`: bounded near singularities
//!   (‖Δq‖ ≤ ‖e‖ / (2λ)), at the price of a small tracking error.
//! - Jacobian transpose `Δq = Jᵀ e` (eq. 20): no inversion, always bounded, slow.

use nalgebra::{DMatrix, DVector, Dyn, OMatrix, U6};

/// `J⁺ e` with the Moore-Penrose pseudo-inverse.
///
/// # Panics
/// If `e.len()` differs from the number of rows of `j`.
pub fn pinv_step(j: &DMatrix<f64>, e: &[f64]) -> DVector<f64> {
    assert_eq!(e.len(), j.nrows(), "error vector length");
    let svd = j.clone().svd(true, true);
    let smax = svd.singular_values.iter().fold(0.0f64, |a, &s| a.max(s));
    let cutoff = 1e-15 * smax;
    let (u, vt) = (svd.u.expect("u requested"), svd.v_t.expect("v_t requested"));
    let e = DVector::from_column_slice(e);
    let mut dq = DVector::zeros(j.ncols());
    for (k, &s) in svd.singular_values.iter().enumerate() {
        if s > cutoff {
            let c = u.column(k).dot(&e) / s;
            dq += vt.row(k).transpose() * c;
        }
    }
    dq
}

/// Damped least squares `Jᵀ (J Jᵀ + λ² I)⁻¹ e`, solved by Cholesky (the matrix is
/// symmetric positive definite for λ > 0).
///
/// # Panics
/// If `e.len()` differs from the number of rows of `j`, or `lambda` is not > 0.
pub fn dls_step(j: &DMatrix<f64>, e: &[f64], lambda: f64) -> DVector<f64> {
    assert_eq!(e.len(), j.nrows(), "error vector length");
    assert!(lambda > 0.0, "damping must be > 0");
    let m = j.nrows();
    let a = j * j.transpose() + DMatrix::identity(m, m) * (lambda * lambda);
    let y = a
        .cholesky()
        .expect("J Jᵀ + λ² I is positive definite")
        .solve(&DVector::from_column_slice(e));
    j.transpose() * y
}

/// Jacobian transpose `Jᵀ e`.
///
/// # Panics
/// If `e.len()` differs from the number of rows of `j`.
pub fn transpose_step(j: &DMatrix<f64>, e: &[f64]) -> DVector<f64> {
    assert_eq!(e.len(), j.nrows(), "error vector length");
    j.transpose() * DVector::from_column_slice(e)
}

/// The 6 × n geometric Jacobian as a dynamic matrix, for the controllers.
pub fn to_dmatrix(j: &OMatrix<f64, U6, Dyn>) -> DMatrix<f64> {
    DMatrix::from_column_slice(6, j.ncols(), j.as_slice())
}
