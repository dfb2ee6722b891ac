//! Workspace sampling, path reachability and mobility.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::{IkConfig, IkTarget, KinematicsError, SerialChain, solve_ik};

/// `count` tool positions reachable within the joint limits: forward kinematics of
/// uniformly random in-limit configurations drawn from `seed` (joints without limits are
/// drawn as [`SerialChain::random_configuration`] says). The same seed gives the same samples.
pub fn sample_workspace(chain: &SerialChain, count: usize, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let q = chain.random_configuration(&mut rng);
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

/// Checks that a whole Cartesian path can be followed within the joint limits, and returns
/// a joint configuration per sample.
///
/// Each sample is solved by [`solve_ik`] seeded with the previous sample's solution (the
/// first with `seed_q`), without restarts, so the solutions stay on one branch; a sample
/// that fails from there is retried with the configured restarts. With `max_joint_step`
/// (radians per sample, e.g. speed limit × dt), a jump larger than that between
/// consecutive samples (a branch change) also fails. `times` only labels the error.
///
/// # Panics
/// If `times` and `path` differ in length.
pub fn check_path(
    chain: &SerialChain,
    path: &[IkTarget],
    times: &[f64],
    seed_q: &[f64],
    config: &IkConfig,
    max_joint_step: Option<&[f64]>,
) -> Result<Vec<Vec<f64>>, KinematicsError> {
    assert_eq!(path.len(), times.len(), "one time per path sample");
    if let Some(m) = max_joint_step
        && m.len() != chain.dof()
    {
        return Err(KinematicsError::JointCount {
            expected: chain.dof(),
            got: m.len(),
        });
    }
    let tracking = IkConfig {
        restarts: 0,
        ..config.clone()
    };
    let mut prev = seed_q.to_vec();
    let mut out = Vec::with_capacity(path.len());
    for (k, (target, &t)) in path.iter().zip(times).enumerate() {
        let fail = |reason: String| KinematicsError::PathUnreachable {
            sample: k,
            time: t,
            reason,
        };
        let sol = solve_ik(chain, target, &prev, &tracking)
            .or_else(|_| solve_ik(chain, target, &prev, config))
            .map_err(|e| match e {
                KinematicsError::Unreachable {
                    position_error,
                    rotation_error,
                    ..
                } => fail(format!(
                    "no configuration within the joint limits (best position error {position_error:.3e} m, rotation error {rotation_error:.3e} rad)"
                )),
                other => other,
            })?;
        if let Some(m) = max_joint_step
            && k > 0
            && let Some(j) = (0..chain.dof()).find(|&j| (sol.q[j] - prev[j]).abs() > m[j])
        {
            return Err(fail(format!(
                "joint {} would move {:.3} rad in one sample (at most {:.3} rad): faster than its speed limit allows, or a branch change",
                j + 1,
                (sol.q[j] - prev[j]).abs(),
                m[j]
            )));
        }
        prev.clone_from(&sol.q);
        out.push(sol.q);
    }
    Ok(out)
}
