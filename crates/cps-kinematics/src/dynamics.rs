//! Inverse dynamics of a serial chain: the recursive Newton–Euler algorithm (Luh, Walker &
//! Paul 1980; Siciliano et al., *Robotics*, §7.5), written in the world frame.
//!
//! Each link carries a [`LinkInertia`]: its mass, the centre of mass in the link's frame
//! (the frame [`SerialChain::fk_frames`] returns) and the inertia tensor about the centre of
//! mass in that frame's axes. Forward, every link's angular velocity and acceleration and
//! the linear acceleration of its joint's axis point are propagated from the base (whose
//! acceleration is −g, so gravity needs no separate term); backward, the forces and moments
//! about the joint points are summed from the tool to the base, and each joint torque is
//! the moment's component along the joint axis. Units: SI (kg, m, kg m², N m).

use nalgebra::{Matrix3, Vector3};

use crate::{KinematicsError, SerialChain};

/// Standard gravity pointing down the world's z axis (m/s²).
pub const GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// The inertial parameters of one link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkInertia {
    /// Mass in kg (≥ 0).
    pub mass: f64,
    /// Centre of mass in the link frame (m).
    pub com: Vector3<f64>,
    /// Inertia tensor about the centre of mass, in the link frame's axes (kg m²).
    pub inertia: Matrix3<f64>,
}

impl LinkInertia {
    /// A link from its mass, centre of mass and the inertia's six entries `[xx, xy, xz, yy,
    /// yz, zz]` (about the centre of mass). Checks that the values are finite, the mass is
    /// not negative and the tensor is physically possible (positive semi-definite with the
    /// triangle inequalities of its principal moments, within 1e-9 kg m²).
    pub fn new(mass: f64, com: [f64; 3], inertia: [f64; 6]) -> Result<Self, KinematicsError> {
        let bad = |why: String| KinematicsError::InvalidModel(why);
        if !(mass.is_finite() && mass >= 0.0) {
            return Err(bad(format!("link mass {mass} must be finite and ≥ 0")));
        }
        if com.iter().chain(&inertia).any(|v| !v.is_finite()) {
            return Err(bad("link centre of mass and inertia must be finite".into()));
        }
        let [xx, xy, xz, yy, yz, zz] = inertia;
        let tensor = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
        let mut p = tensor.symmetric_eigenvalues();
        p.as_mut_slice().sort_by(f64::total_cmp);
        let tol = 1e-9;
        if p[0] < -tol || p[0] + p[1] < p[2] - tol {
            return Err(bad(format!(
                "link inertia has principal moments {:.3e}, {:.3e}, {:.3e}: not a rigid body's (each must be ≥ 0 and at most the sum of the other two)",
                p[0], p[1], p[2]
            )));
        }
        Ok(Self {
            mass,
            com: Vector3::from(com),
            inertia: tensor,
        })
    }
}

impl SerialChain {
    /// Joint torques (N m) that give joint accelerations `qdd` at positions `q` and
    /// velocities `qd`, with `links[i]` the inertia of the link moved by joint i and
    /// `gravity` in the world frame (e.g. [`GRAVITY`]). Loads beyond the last link (a
    /// payload) belong in its inertia.
    pub fn inverse_dynamics(
        &self,
        links: &[LinkInertia],
        gravity: Vector3<f64>,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
    ) -> Result<Vec<f64>, KinematicsError> {
        let n = self.dof();
        for (what, v) in [("links", links.len()), ("qd", qd.len()), ("qdd", qdd.len())] {
            if v != n {
                return Err(KinematicsError::InvalidModel(format!(
                    "inverse dynamics: {what} has {v} entries for {n} joints"
                )));
            }
        }
        if let Some(v) = qd.iter().chain(qdd).find(|v| !v.is_finite()) {
            return Err(KinematicsError::InvalidModel(format!(
                "inverse dynamics: velocities and accelerations must be finite (got {v})"
            )));
        }
        let joints = self.joint_axes(q)?;
        // Forward: angular velocity and acceleration of each link, acceleration of each
        // joint point, and the link's inertial force and moment about its centre of mass.
        let (mut w, mut dw) = (Vector3::zeros(), Vector3::zeros());
        let mut acc = -gravity;
        let mut prev = joints[0].point;
        let mut force = Vec::with_capacity(n);
        let mut moment = Vec::with_capacity(n);
        let mut com = Vec::with_capacity(n);
        for (i, joint) in joints.iter().enumerate() {
            let (point, axis, link) = (&joint.point, &joint.axis, &joint.link);
            let r = point - prev;
            acc += dw.cross(&r) + w.cross(&w.cross(&r));
            let w_next = w + axis * qd[i];
            dw += axis * qdd[i] + w.cross(&(axis * qd[i]));
            w = w_next;
            let rot = link.rotation.matrix();
            let c = link.translation.vector + rot * links[i].com;
            let rc = c - point;
            let a_c = acc + dw.cross(&rc) + w.cross(&w.cross(&rc));
            let inertia = rot * links[i].inertia * rot.transpose();
            force.push(a_c * links[i].mass);
            moment.push(inertia * dw + w.cross(&(inertia * w)));
            com.push(c);
            prev = *point;
        }
        // Backward: force and moment each joint transmits, about its point.
        let mut tau = vec![0.0; n];
        let (mut f, mut m) = (Vector3::zeros(), Vector3::zeros());
        let mut next_point: Option<Vector3<f64>> = None;
        for i in (0..n).rev() {
            let (point, axis) = (&joints[i].point, &joints[i].axis);
            let carried = next_point.map_or(Vector3::zeros(), |p| (p - point).cross(&f));
            m = moment[i] + (com[i] - point).cross(&force[i]) + m + carried;
            f += force[i];
            tau[i] = axis.dot(&m);
            next_point = Some(*point);
        }
        Ok(tau)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robots::{PandaTool, panda, panda_inertia};
    use nalgebra::{DMatrix, DVector};
    use rand::{Rng, SeedableRng};

    /// Centres of mass and link rotations in the world frame, from forward kinematics only.
    fn coms(
        chain: &SerialChain,
        links: &[LinkInertia],
        q: &[f64],
    ) -> Vec<(Vector3<f64>, Matrix3<f64>)> {
        let frames = chain.fk_frames(q).unwrap().link_frames;
        frames
            .iter()
            .zip(links)
            .map(|(f, l)| {
                let r = *f.rotation.matrix();
                (f.translation.vector + r * l.com, r)
            })
            .collect()
    }

    /// The mass matrix from the kinetic energy, `M = Σ m Jvᵀ Jv + Jωᵀ I Jω`, with the
    /// Jacobians of each centre of mass and link rotation by central differences of forward
    /// kinematics: independent of the recursion.
    fn mass_matrix(chain: &SerialChain, links: &[LinkInertia], q: &[f64]) -> DMatrix<f64> {
        let n = q.len();
        let h = 1e-6;
        let base = coms(chain, links, q);
        let mut m = DMatrix::zeros(n, n);
        let mut jv = vec![DMatrix::<f64>::zeros(3, n); n];
        let mut jw = vec![DMatrix::<f64>::zeros(3, n); n];
        for j in 0..n {
            let (mut qp, mut qm) = (q.to_vec(), q.to_vec());
            qp[j] += h;
            qm[j] -= h;
            let (p, mi) = (coms(chain, links, &qp), coms(chain, links, &qm));
            for i in 0..n {
                let dv = (p[i].0 - mi[i].0) / (2.0 * h);
                // [ω]× = Ṙ Rᵀ
                let s = (p[i].1 - mi[i].1) / (2.0 * h) * base[i].1.transpose();
                let dw = Vector3::new(s[(2, 1)], s[(0, 2)], s[(1, 0)]);
                jv[i].set_column(j, &dv);
                jw[i].set_column(j, &dw);
            }
        }
        for i in 0..n {
            let inertia = base[i].1 * links[i].inertia * base[i].1.transpose();
            let iw = DMatrix::from_column_slice(3, 3, inertia.as_slice());
            m += jv[i].transpose() * &jv[i] * links[i].mass + jw[i].transpose() * iw * &jw[i];
        }
        m
    }

    fn random_state(rng: &mut impl Rng, chain: &SerialChain) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let q = chain.random_configuration(rng);
        let qd = (0..q.len()).map(|_| rng.random_range(-2.0..2.0)).collect();
        let qdd = (0..q.len()).map(|_| rng.random_range(-5.0..5.0)).collect();
        (q, qd, qdd)
    }

    #[test]
    fn gravity_torques_are_the_gradient_of_the_potential_energy() {
        let (chain, links) = (panda(PandaTool::Flange), panda_inertia());
        let g = Vector3::from(GRAVITY);
        let potential = |q: &[f64]| -> f64 {
            coms(&chain, &links, q)
                .iter()
                .zip(&links)
                .map(|((c, _), l)| -l.mass * g.dot(c))
                .sum()
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for _ in 0..20 {
            let q = chain.random_configuration(&mut rng);
            let tau = chain
                .inverse_dynamics(&links, g, &q, &[0.0; 7], &[0.0; 7])
                .unwrap();
            for j in 0..7 {
                let h = 1e-6;
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[j] += h;
                qm[j] -= h;
                let grad = (potential(&qp) - potential(&qm)) / (2.0 * h);
                assert!(
                    (tau[j] - grad).abs() < 1e-7,
                    "joint {j}: {} vs {grad}",
                    tau[j]
                );
            }
        }
    }

    #[test]
    fn the_full_equation_of_motion_matches_the_lagrangian() {
        // τ = M q̈ + C(q, q̇) q̇ + g(q), with C q̇ = Ṁ q̇ − ½ ∂(q̇ᵀ M q̇)/∂q, M from the kinetic
        // energy, every derivative by central differences of forward kinematics.
        let (chain, links) = (panda(PandaTool::Flange), panda_inertia());
        let g = Vector3::from(GRAVITY);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        for _ in 0..5 {
            let (q, qd, qdd) = random_state(&mut rng, &chain);
            let tau = chain.inverse_dynamics(&links, g, &q, &qd, &qdd).unwrap();
            let gravity = chain
                .inverse_dynamics(&links, g, &q, &[0.0; 7], &[0.0; 7])
                .unwrap();
            let m = mass_matrix(&chain, &links, &q);
            let v = DVector::from_column_slice(&qd);
            let h = 1e-4;
            let shifted =
                |s: f64| -> Vec<f64> { q.iter().zip(&qd).map(|(a, b)| a + s * b).collect() };
            let m_dot = (mass_matrix(&chain, &links, &shifted(h))
                - mass_matrix(&chain, &links, &shifted(-h)))
                / (2.0 * h);
            let mut coriolis = &m_dot * &v;
            for j in 0..7 {
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[j] += h;
                qm[j] -= h;
                let e = |q: &[f64]| (v.transpose() * mass_matrix(&chain, &links, q) * &v)[(0, 0)];
                coriolis[j] -= 0.5 * (e(&qp) - e(&qm)) / (2.0 * h);
            }
            let expected = &m * DVector::from_column_slice(&qdd)
                + coriolis
                + DVector::from_column_slice(&gravity);
            for j in 0..7 {
                assert!(
                    (tau[j] - expected[j]).abs() < 1e-4 * (1.0 + expected[j].abs()),
                    "joint {j}: {} vs {}",
                    tau[j],
                    expected[j]
                );
            }
            // And the mass matrix column by column from the recursion, without gravity.
            for j in 0..7 {
                let mut e = [0.0; 7];
                e[j] = 1.0;
                let col = chain
                    .inverse_dynamics(&links, Vector3::zeros(), &q, &[0.0; 7], &e)
                    .unwrap();
                for i in 0..7 {
                    assert!(
                        (col[i] - m[(i, j)]).abs() < 1e-7,
                        "M[{i},{j}]: {} vs {}",
                        col[i],
                        m[(i, j)]
                    );
                }
            }
        }
    }

    #[test]
    fn impossible_inertias_and_wrong_lengths_are_refused() {
        assert!(LinkInertia::new(-1.0, [0.0; 3], [1.0, 0.0, 0.0, 1.0, 0.0, 1.0]).is_err());
        let e = LinkInertia::new(1.0, [0.0; 3], [1.0, 0.0, 0.0, 1.0, 0.0, 3.0]).unwrap_err();
        assert!(e.to_string().contains("not a rigid body"), "{e}");
        let chain = panda(PandaTool::Flange);
        let e = chain
            .inverse_dynamics(
                &panda_inertia()[..6],
                Vector3::zeros(),
                &[0.0; 7],
                &[0.0; 7],
                &[0.0; 7],
            )
            .unwrap_err();
        assert!(
            e.to_string().contains("links has 6 entries for 7 joints"),
            "{e}"
        );
    }
}
