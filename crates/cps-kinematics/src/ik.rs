//! Numerical inverse kinematics: Levenberg-Marquardt on the pose error, joint limits by
//! projection, seeded random restarts.

use nalgebra::{DMatrix, DVector, IsometryMatrix3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::controllers::task_error;
use crate::{KinematicsError, SerialChain};

/// What the tool should reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IkTarget {
    /// A position in the world frame (metres); orientation free.
    Position(Vector3<f64>),
    /// A full pose in the world frame.
    Pose(IsometryMatrix3<f64>),
}

/// Settings of [`solve_ik`]; defaults reach 1e-9 m / 1e-9 rad.
#[derive(Debug, Clone, PartialEq)]
pub struct IkConfig {
    /// Accepted position error in metres.
    pub position_tolerance: f64,
    /// Accepted rotation error in radians (pose targets).
    pub rotation_tolerance: f64,
    /// Iteration cap per attempt.
    pub max_iterations: usize,
    /// Random restarts after the first attempt from the seed configuration.
    pub restarts: usize,
    /// Seed of the restart configurations.
    pub seed: u64,
    /// Keep every iterate inside the chain's joint limits.
    pub respect_limits: bool,
}

impl Default for IkConfig {
    fn default() -> Self {
        Self {
            position_tolerance: 1e-9,
            rotation_tolerance: 1e-9,
            max_iterations: 100,
            restarts: 50,
            seed: 0,
            respect_limits: true,
        }
    }
}

/// A configuration that reaches the target.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSolution {
    /// Joint angles in radians.
    pub q: Vec<f64>,
    /// Remaining position error in metres.
    pub position_error: f64,
    /// Remaining rotation error in radians (0 for position targets).
    pub rotation_error: f64,
    /// Iterations spent over all attempts.
    pub iterations: usize,
    /// Restarts used (0 if the seed configuration converged).
    pub restarts: usize,
}

fn pose_error(chain: &SerialChain, q: &[f64], target: &IkTarget) -> (Vector3<f64>, Vector3<f64>) {
    task_error(&chain.fk(q).expect("q checked"), target)
}

fn cost(e: &(Vector3<f64>, Vector3<f64>)) -> f64 {
    e.0.norm_squared() + e.1.norm_squared()
}

/// Solves inverse kinematics from `seed_q`, then from seeded random configurations inside
/// the limits until one converges.
///
/// Each attempt runs Levenberg-Marquardt on the stacked error: solve
/// `(JᵀJ + μ I) Δq = Jᵀ e`, accept a step that lowers the error (μ /= 10) or reject it
/// (μ × 10); with limits, every iterate is projected into them. Failure is
/// [`KinematicsError::Unreachable`] with the best residuals found.
pub fn solve_ik(
    chain: &SerialChain,
    target: &IkTarget,
    seed_q: &[f64],
    config: &IkConfig,
) -> Result<IkSolution, KinematicsError> {
    let n = chain.dof();
    if seed_q.len() != n {
        return Err(KinematicsError::JointCount {
            expected: n,
            got: seed_q.len(),
        });
    }
    let finite = match target {
        IkTarget::Position(p) => p.iter().all(|v| v.is_finite()),
        IkTarget::Pose(t) => t
            .translation
            .vector
            .iter()
            .chain(t.rotation.matrix().iter())
            .all(|v| v.is_finite()),
    };
    if !finite {
        return Err(KinematicsError::InvalidModel(
            "the IK target is not finite".into(),
        ));
    }
    let limits = if config.respect_limits {
        chain.limits()
    } else {
        None
    };
    let clamp = |q: &mut [f64]| {
        if let Some((lo, hi)) = limits {
            for ((v, l), h) in q.iter_mut().zip(lo).zip(hi) {
                *v = v.clamp(*l, *h);
            }
        }
    };
    let rows = if matches!(target, IkTarget::Position(_)) {
        3
    } else {
        6
    };
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let mut iterations = 0;
    let mut best: Option<(f64, f64, f64)> = None;
    for attempt in 0..=config.restarts {
        let mut q: Vec<f64> = if attempt == 0 {
            seed_q.to_vec()
        } else {
            chain.random_configuration(&mut rng)
        };
        if let Some(i) = q.iter().position(|v| !v.is_finite()) {
            return Err(KinematicsError::NotFinite {
                joint: i + 1,
                value: q[i],
            });
        }
        clamp(&mut q);
        let mut e = pose_error(chain, &q, target);
        let mut mu = 1e-3;
        // Converged or not, the loop ends with the attempt's residuals in `e`.
        for step in 0..=config.max_iterations {
            let (pe, re) = (e.0.norm(), e.1.norm());
            if pe <= config.position_tolerance && re <= config.rotation_tolerance {
                return Ok(IkSolution {
                    q,
                    position_error: pe,
                    rotation_error: re,
                    iterations,
                    restarts: attempt,
                });
            }
            if step == config.max_iterations {
                break;
            }
            iterations += 1;
            let j6 = chain.jacobian(&q)?;
            let j = DMatrix::from_fn(rows, n, |r, c| j6[(r, c)]);
            let ev = DVector::from_fn(rows, |r, _| if r < 3 { e.0[r] } else { e.1[r - 3] });
            let jtj = j.transpose() * &j;
            let g = j.transpose() * ev;
            let mut improved = false;
            for _ in 0..8 {
                let a = &jtj + DMatrix::identity(n, n) * mu;
                let Some(ch) = a.cholesky() else {
                    mu *= 10.0;
                    continue;
                };
                let dq = ch.solve(&g);
                let mut trial: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
                clamp(&mut trial);
                let te = pose_error(chain, &trial, target);
                if cost(&te) < cost(&e) {
                    q = trial;
                    e = te;
                    mu = (mu / 10.0).max(1e-12);
                    improved = true;
                    break;
                }
                mu *= 10.0;
            }
            if !improved {
                break; // stuck at a limit or a local minimum: restart
            }
        }
        let (pe, re) = (e.0.norm(), e.1.norm());
        if best.is_none_or(|b| pe * pe + re * re < b.0) {
            best = Some((pe * pe + re * re, pe, re));
        }
    }
    let (_, position_error, rotation_error) =
        best.unwrap_or((f64::INFINITY, f64::INFINITY, f64::INFINITY));
    Err(KinematicsError::Unreachable {
        position_error,
        rotation_error,
        iterations,
    })
}
