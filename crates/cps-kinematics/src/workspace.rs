//! Workspace sampling and mobility.

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::{KinematicsError, SerialChain};

/// `count` tool positions reachable within the joint limits: forward kinematics of
/// uniformly random in-limit configurations drawn from `seed` (joints without limits are
/// drawn from (−π, π)). The same seed gives the same samples.
pub fn sample_workspace(chain: &SerialChain, count: usize, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = chain.dof();
    let pi = std::f64::consts::PI;
    (0..count)
        .map(|_| {
            let q: Vec<f64> = match chain.limits() {
                Some((lo, hi)) => lo
                    .iter()
                    .zip(hi)
                    .map(|(l, h)| rng.random_range(*l..*h))
                    .collect(),
                None => (0..n).map(|_| rng.random_range(-pi..pi)).collect(),
            };
            chain
                .fk(&q)
                .expect("q has the chain's length and is finite")
                .translation
                .vector
        })
        .collect()
}

/// Grübler's formula for the degrees of freedom of a mechanism:
/// `DOF = m (N − 1) − Σ (m − f_i)`, with `m = 3` for planar and `6` for spatial mechanisms,
/// `N` links including the ground and `f_i` the freedoms of each joint (1 for revolute or
/// prismatic, 2 for universal, 3 for spherical …).
pub fn degrees_of_freedom(
    spatial: bool,
    links: usize,
    joint_freedoms: &[usize],
) -> Result<i64, KinematicsError> {
    let m: i64 = if spatial { 6 } else { 3 };
    if links == 0 {
        return Err(KinematicsError::InvalidModel(
            "a mechanism has at least the ground link".into(),
        ));
    }
    if let Some(f) = joint_freedoms.iter().find(|&&f| f == 0 || f as i64 > m) {
        return Err(KinematicsError::InvalidModel(format!(
            "a joint cannot have {f} freedoms when m = {m}"
        )));
    }
    Ok(m * (links as i64 - 1) - joint_freedoms.iter().map(|&f| m - f as i64).sum::<i64>())
}
