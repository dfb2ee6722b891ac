//! Velocity-level inverse controllers: one step `Δq` for a task-space error `e`
//! (thesis eq. 14–20). `J` is any m × n Jacobian, tall or fat.
//!
//! - Moore-Penrose pseudo-inverse `Δq = J⁺ e` (SVD; singular values below
//!   `1e-15 · σ_max` are treated as zero, like numpy's `pinv`). Exact but unbounded near
//!   singularities — why the thesis abandoned its own controller.
//! - Damped least squares `Δq = Jᵀ (J Jᵀ + λ² I)⁻¹ e`: bounded near singularities
//!   (‖Δq‖ ≤ ‖e‖ / (2λ)), at the price of a small tracking error.
//! - Jacobian transpose `Δq = Jᵀ e` (eq. 20): no inversion, always bounded, slow.
//!
//! [`control_step`] combines them into the controller used to execute trajectories:
//! damping that grows near singularities, a secondary task in the null space of a
//! redundant arm ([`NullSpace`]) and joint position and speed limits at every step.

use nalgebra::{DMatrix, DVector, Dyn, IsometryMatrix3, OMatrix, U6, Vector3};

use crate::{KinematicsError, SerialChain};

/// What the tool should reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IkTarget {
    /// A position in the world frame (metres); orientation free.
    Position(Vector3<f64>),
    /// A full pose in the world frame.
    Pose(IsometryMatrix3<f64>),
}

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

/// How a Jacobian is inverted for one control step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InverseMethod {
    /// Moore-Penrose pseudo-inverse: exact tracking, unbounded near singularities.
    PseudoInverse,
    /// Damped least squares with damping that grows near singularities (Nakamura &
    /// Hanafusa 1986; Chiaverini 1997): with σ_min the smallest singular value of J,
    /// `λ² = 0` while `σ_min ≥ threshold`, else `λ² = lambda_max² (1 − (σ_min/threshold)²)`.
    /// Away from singularities it is the pseudo-inverse; at one, ‖Δq‖ ≤ ‖e‖/(2 λ_max).
    Damped {
        /// Damping at an exact singularity (rad/m scale; 0.05 is a common choice).
        lambda_max: f64,
        /// Smallest singular value below which damping starts.
        threshold: f64,
    },
    /// Jacobian transpose `Δq = gain · Jᵀ e`: no inversion, always bounded, slow.
    Transpose {
        /// Step gain (rad per metre·metre): small enough for stability, e.g. 1.
        gain: f64,
    },
}

/// Secondary task projected into the null space of the primary task, for redundant arms
/// (the Panda has one spare degree of freedom for a position-and-orientation task, four
/// for a position-only task). It never disturbs the tool.
#[derive(Debug, Clone, PartialEq)]
pub enum NullSpace {
    /// No secondary task.
    None,
    /// Move away from joint limits along the gradient of Liégeois' (1977) criterion
    /// `H = −½ Σ ((q_i − mid_i)/(hi_i − lo_i))²`: `z_i = −gain (q_i − mid_i)/(hi_i − lo_i)²`
    /// per step (joints without finite limits are left alone).
    JointLimits {
        /// Scale of the gradient step (rad²); 1 moves a Panda joint at a limit by ≈ 0.1 rad
        /// per step before projection.
        gain: f64,
    },
    /// Pull towards a preferred posture: `gain · (q_pref − q)` per step.
    Posture {
        /// The preferred joint angles.
        q: Vec<f64>,
        /// Fraction of the posture error corrected per step.
        gain: f64,
    },
}

/// Settings of the inverse controller (thesis eq. 14–20 plus what makes it usable on a
/// redundant arm: damping, null space and limits).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerConfig {
    /// How the Jacobian is inverted. Default: damped, λ_max = 0.05, threshold 0.05.
    pub method: InverseMethod,
    /// Fraction η of the task error corrected per step (thesis eq. 19), in (0, 1].
    /// Default 1.
    pub gain: f64,
    /// Secondary task. Default: none.
    pub null_space: NullSpace,
    /// Keep joints inside their position limits and below their speed limits (when the
    /// chain has them). A joint already outside a limit may only move back. Default true.
    pub respect_limits: bool,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            method: InverseMethod::Damped {
                lambda_max: 0.05,
                threshold: 0.05,
            },
            gain: 1.0,
            null_space: NullSpace::None,
            respect_limits: true,
        }
    }
}

impl ControllerConfig {
    /// Checks every field; the error names the field and the rule.
    pub fn validate(&self, chain: &SerialChain) -> Result<(), KinematicsError> {
        let bad = |m: String| Err(KinematicsError::InvalidConfig(m));
        if !(self.gain > 0.0 && self.gain <= 1.0) {
            return bad(format!(
                "controller gain must be in (0, 1] (got {})",
                self.gain
            ));
        }
        match self.method {
            InverseMethod::Damped {
                lambda_max,
                threshold,
            } if !(lambda_max > 0.0
                && lambda_max.is_finite()
                && threshold > 0.0
                && threshold.is_finite()) =>
            {
                return bad(format!(
                    "damping needs finite lambda_max > 0 and threshold > 0 (got {lambda_max}, {threshold})"
                ));
            }
            InverseMethod::Transpose { gain } if !(gain > 0.0 && gain.is_finite()) => {
                return bad(format!(
                    "transpose gain must be finite and > 0 (got {gain})"
                ));
            }
            _ => {}
        }
        match &self.null_space {
            NullSpace::None => {}
            NullSpace::JointLimits { gain } => {
                if !(gain.is_finite() && *gain >= 0.0) {
                    return bad(format!(
                        "null-space gain must be finite and ≥ 0 (got {gain})"
                    ));
                }
                if chain.limits().is_none() {
                    return bad("joint-limit avoidance needs a chain with limits".into());
                }
            }
            NullSpace::Posture { q, gain } => {
                if !(gain.is_finite() && *gain >= 0.0) {
                    return bad(format!("posture gain must be finite and ≥ 0 (got {gain})"));
                }
                chain.check(q)?;
            }
        }
        Ok(())
    }
}

/// One step of the inverse controller.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlStep {
    /// Joint displacement for this step (radians), limits applied.
    pub dq: Vec<f64>,
    /// Norm of the position error before the step (metres).
    pub position_error: f64,
    /// Rotation error before the step (radians; 0 for position targets).
    pub rotation_error: f64,
    /// Damping used (0 unless damped near a singularity).
    pub damping: f64,
    /// Fraction of the step kept by the speed limits (1 = not limited).
    pub speed_scale: f64,
}

/// The world-frame task error (position, rotation vector) from the tool pose to `target`.
pub fn task_error(
    pose: &nalgebra::IsometryMatrix3<f64>,
    target: &IkTarget,
) -> (nalgebra::Vector3<f64>, nalgebra::Vector3<f64>) {
    match target {
        IkTarget::Position(p) => (p - pose.translation.vector, nalgebra::Vector3::zeros()),
        IkTarget::Pose(t) => {
            let r = t.rotation * pose.rotation.inverse();
            let w = nalgebra::UnitQuaternion::from_rotation_matrix(&r).scaled_axis();
            (t.translation.vector - pose.translation.vector, w)
        }
    }
}

/// One control step from `q` towards `target`, for a control period of `dt` seconds (used
/// only by the speed limits): `Δq = η J^# e + (I − J⁺J) z`, then limits.
///
/// The step is scaled as a whole so that no joint exceeds its speed limit (the direction is
/// kept), then each joint is kept inside its position limits (a joint outside may only
/// move back).
pub fn control_step(
    chain: &SerialChain,
    q: &[f64],
    target: &IkTarget,
    dt: f64,
    config: &ControllerConfig,
) -> Result<ControlStep, KinematicsError> {
    chain.check(q)?;
    let n = chain.dof();
    let pose = chain.fk(q)?;
    let (ep, er) = task_error(&pose, target);
    let rows = if matches!(target, IkTarget::Position(_)) {
        3
    } else {
        6
    };
    let mut e = [0.0; 6];
    for (r, e) in e.iter_mut().enumerate().take(rows) {
        *e = config.gain * if r < 3 { ep[r] } else { er[r - 3] };
    }
    let e = &e[..rows];
    let mut dq = vec![0.0; n];
    let mut damping = 0.0;
    match config.method {
        InverseMethod::Transpose { gain } => {
            let j6 = chain.jacobian(q)?;
            let j = DMatrix::from_fn(rows, n, |r, c| j6[(r, c)]);
            let t = transpose_step(&j, e) * gain;
            dq.copy_from_slice(t.as_slice());
        }
        InverseMethod::PseudoInverse | InverseMethod::Damped { .. } if n == 7 => {
            // A seven-joint arm (every control step of an execution): the Jacobian and its
            // SVD on the stack, the same arithmetic as below.
            let mut cols = [0.0; 42];
            chain.pose_and_jacobian(q, &mut cols);
            let mut z = [0.0; 7];
            macro_rules! seven {
                ($r:literal) => {{
                    let j = nalgebra::SMatrix::<f64, $r, 7>::from_fn(|r, c| cols[6 * c + r]);
                    let svd = j.svd(true, true);
                    let (u, vt) = (svd.u.expect("u requested"), svd.v_t.expect("v_t requested"));
                    let svd = ThinSvd {
                        rows: $r,
                        sv: svd.singular_values.as_slice(),
                        u: u.as_slice(),
                        vt: vt.as_slice(),
                    };
                    svd.step(e, q, chain, config, &mut dq, &mut z)
                }};
            }
            damping = if rows == 3 { seven!(3) } else { seven!(6) };
        }
        InverseMethod::PseudoInverse | InverseMethod::Damped { .. } => {
            let j6 = chain.jacobian(q)?;
            let j = DMatrix::from_fn(rows, n, |r, c| j6[(r, c)]);
            let (u, sv, vt) = svd_parts(&j);
            let mut z = vec![0.0; n];
            let svd = ThinSvd {
                rows,
                sv: sv.as_slice(),
                u: u.as_slice(),
                vt: vt.as_slice(),
            };
            damping = svd.step(e, q, chain, config, &mut dq, &mut z);
        }
    }
    let mut speed_scale = 1.0;
    if config.respect_limits {
        if let Some(vmax) = chain.velocity_limits() {
            for (d, v) in dq.iter().zip(vmax) {
                let allowed = v * dt;
                if d.abs() * speed_scale > allowed {
                    speed_scale = allowed / d.abs();
                }
            }
            for d in &mut dq {
                *d *= speed_scale;
            }
        }
        if let Some((lo, hi)) = chain.limits() {
            for i in 0..n {
                let down = (lo[i] - q[i]).min(0.0);
                let up = (hi[i] - q[i]).max(0.0);
                dq[i] = dq[i].clamp(down, up);
            }
        }
    }
    Ok(ControlStep {
        dq,
        position_error: ep.norm(),
        rotation_error: er.norm(),
        damping,
        speed_scale,
    })
}

/// A thin SVD `J = U Σ Vᵀ` of a `rows` × n Jacobian as column-major slices: `U` is
/// `rows` × p, `Vᵀ` is p × n, `σ` has p = min(rows, n) values.
struct ThinSvd<'a> {
    rows: usize,
    sv: &'a [f64],
    u: &'a [f64],
    vt: &'a [f64],
}

impl ThinSvd<'_> {
    /// The damped pseudo-inverse step `Σ_k v_k (u_kᵀ e) σ_k / (σ_k² + λ²)` (λ from the
    /// smallest singular value when damped), plus the null-space task projected by
    /// `I − Σ_{σ_k > tol} v_k v_kᵀ`, into `dq` (zeros on entry); `z` is scratch of n.
    /// Returns the damping λ.
    fn step(
        &self,
        e: &[f64],
        q: &[f64],
        chain: &SerialChain,
        config: &ControllerConfig,
        dq: &mut [f64],
        z: &mut [f64],
    ) -> f64 {
        let (m, p, n) = (self.rows, self.sv.len(), dq.len());
        let sv = self.sv;
        let u = |r: usize, k: usize| self.u[k * m + r];
        let v = |k: usize, i: usize| self.vt[i * p + k];
        let smax = sv.iter().fold(0.0f64, |a, &s| a.max(s));
        let smin = if m <= n {
            sv.iter().fold(f64::INFINITY, |a, &s| a.min(s))
        } else {
            0.0
        };
        let lambda2 = match config.method {
            InverseMethod::Damped {
                lambda_max,
                threshold,
            } if smin < threshold => lambda_max * lambda_max * (1.0 - (smin / threshold).powi(2)),
            _ => 0.0,
        };
        for (k, &s) in sv.iter().enumerate() {
            if lambda2 > 0.0 || s > 1e-15 * smax {
                // A dot product summed in order from zero, as nalgebra's for < 8 rows.
                let mut d = 0.0;
                for (r, e) in e.iter().enumerate() {
                    d += u(r, k) * e;
                }
                let c = d * s / (s * s + lambda2);
                for (i, dq) in dq.iter_mut().enumerate() {
                    *dq += v(k, i) * c;
                }
            }
        }
        // Null space of the primary task: I − Σ_{σ_k > tol} v_k v_kᵀ.
        let have = match &config.null_space {
            NullSpace::None => false,
            NullSpace::JointLimits { gain } => match chain.limits() {
                Some((lo, hi)) => {
                    for (i, z) in z.iter_mut().enumerate() {
                        let range = hi[i] - lo[i];
                        *z = if range.is_finite() {
                            -gain * (q[i] - 0.5 * (lo[i] + hi[i])) / (range * range)
                        } else {
                            0.0
                        };
                    }
                    true
                }
                None => false,
            },
            NullSpace::Posture { q: pref, gain } => {
                for (i, z) in z.iter_mut().enumerate() {
                    *z = gain * (pref[i] - q[i]);
                }
                true
            }
        };
        if have {
            let mut proj = [0.0; 16];
            let mut heap = Vec::new();
            let proj: &mut [f64] = if n <= 16 {
                &mut proj[..n]
            } else {
                heap.resize(n, 0.0);
                &mut heap
            };
            proj.copy_from_slice(z);
            for (k, &s) in sv.iter().enumerate() {
                if s > 1e-10 * smax.max(1e-300) {
                    let mut d = 0.0;
                    for (i, z) in z.iter().enumerate() {
                        d += v(k, i) * z;
                    }
                    for (i, p) in proj.iter_mut().enumerate() {
                        *p -= v(k, i) * d;
                    }
                }
            }
            for (dq, p) in dq.iter_mut().zip(proj.iter()) {
                *dq += p;
            }
        }
        lambda2.sqrt()
    }
}

/// The thin SVD `J = U Σ Vᵀ` of a Jacobian: `(U, σ, Vᵀ)`. (A seven-joint arm's is taken
/// on the stack in [`control_step`], to the same bits: `svd_tests`.)
fn svd_parts(j: &DMatrix<f64>) -> (DMatrix<f64>, DVector<f64>, DMatrix<f64>) {
    let svd = j.clone().svd(true, true);
    (
        svd.u.expect("u requested"),
        svd.singular_values,
        svd.v_t.expect("v_t requested"),
    )
}

#[cfg(test)]
mod svd_tests {
    use super::*;

    #[test]
    fn the_fixed_size_svd_is_the_dynamic_one_to_the_bit() {
        // Jacobians of a seven-joint arm, well and badly conditioned, full and position rows.
        let mut seed = 0x1234_5678_9abc_def0u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for rows in [6, 3] {
            for case in 0..50 {
                let mut j = DMatrix::from_fn(rows, 7, |_, _| next());
                if case % 5 == 0 {
                    // Nearly singular: a row almost a multiple of another.
                    let r0 = j.row(0).clone_owned();
                    j.row_mut(1).copy_from(&(r0 * 2.0));
                    j[(1, 3)] += 1e-9;
                }
                // As control_step takes it for a seven-joint arm.
                macro_rules! fixed {
                    ($r:literal) => {{
                        let svd = nalgebra::SMatrix::<f64, $r, 7>::from_fn(|r, c| j[(r, c)])
                            .svd(true, true);
                        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
                        (
                            svd.singular_values.as_slice().to_vec(),
                            u.as_slice().to_vec(),
                            vt.as_slice().to_vec(),
                        )
                    }};
                }
                let (sv, u, vt) = if rows == 3 { fixed!(3) } else { fixed!(6) };
                let (du, dsv, dvt) = svd_parts(&j);
                assert_eq!(sv, dsv.as_slice(), "{rows} rows, case {case}");
                assert_eq!(u, du.as_slice());
                assert_eq!(vt, dvt.as_slice());
            }
        }
    }
}
