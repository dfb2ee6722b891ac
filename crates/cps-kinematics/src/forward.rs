//! Forward dynamics of an [`ArmModel`]: the joint accelerations that joint torques give
//! at a state, `q̈ = M(q)⁻¹ (τ − τ_f(q̇) − C(q, q̇) q̇ − g(q))`, with the joints' rotor
//! inertia (the model's armature, on `M`'s diagonal) and friction `τ_f`
//! ([`JointFriction`]: viscous and smooth Coulomb) — what a simulated arm integrates.
//!
//! Two algorithms, equal to rounding (tested) and both free of allocation:
//!
//! - [`ArmModel::forward_dynamics`]: Featherstone's articulated-body algorithm (*Rigid
//!   Body Dynamics Algorithms*, 2008, ch. 7) in world coordinates — every spatial quantity
//!   is expressed at the world origin, so no transform is carried from link to link;
//!   O(N).
//! - [`ArmModel::forward_dynamics_crba`]: the bias torques by Newton–Euler
//!   ([`ArmModel::inverse_dynamics`]), the mass matrix by the composite-rigid-body
//!   algorithm ([`ArmModel::mass_matrix_crba`], ch. 6) and a Cholesky solve; O(N²) + O(N³),
//!   small for seven joints. `BENCHMARKS.md` › Dynamics has both per call.
//!
//! Spatial vectors are `[angular; linear]` Plücker coordinates at the world origin: a
//! motion `(ω, v_O)`, `v_O` the velocity of the body-fixed point at the origin; a force
//! `(n_O, f)`, `n_O` its moment about the origin.
#![allow(clippy::needless_range_loop)] // joint-indexed loops over parallel fixed-size arrays

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use crate::contact::JointFriction;
use crate::{ArmFrames, ArmModel};

type Motion = SVector<f64, 6>;
type Inertia6 = SMatrix<f64, 6, 6>;

fn angular(m: &Motion) -> Vector3<f64> {
    m.fixed_rows::<3>(0).into_owned()
}

fn linear(m: &Motion) -> Vector3<f64> {
    m.fixed_rows::<3>(3).into_owned()
}

fn spatial(top: Vector3<f64>, bottom: Vector3<f64>) -> Motion {
    Motion::new(top.x, top.y, top.z, bottom.x, bottom.y, bottom.z)
}

/// `v × m`, the spatial cross product of motions.
fn cross_motion(v: &Motion, m: &Motion) -> Motion {
    let (w, vo) = (angular(v), linear(v));
    let (a, b) = (angular(m), linear(m));
    spatial(w.cross(&a), w.cross(&b) + vo.cross(&a))
}

/// `v ×* f`, the spatial cross product of a motion and a force.
fn cross_force(v: &Motion, f: &Motion) -> Motion {
    let (w, vo) = (angular(v), linear(v));
    let (n, fl) = (angular(f), linear(f));
    spatial(w.cross(&n) + vo.cross(&fl), w.cross(&fl))
}

/// The skew matrix `[c]×` (`[c]× x = c × x`).
fn skew(c: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -c.z, c.y, c.z, 0.0, -c.x, -c.y, c.x, 0.0)
}

/// A body's spatial inertia at the world origin from its mass, centre of mass and
/// rotational inertia about the centre of mass (world axes).
fn body_inertia(mass: f64, com: &Vector3<f64>, inertia: &Matrix3<f64>) -> Inertia6 {
    let c = skew(com);
    let mut out = Inertia6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(inertia + mass * c * c.transpose()));
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(mass * c));
    out.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(mass * c.transpose()));
    out.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(Matrix3::identity() * mass));
    out
}

/// The torques left to accelerate the joints: `τ` less the friction at `dq`.
fn driving<const N: usize>(
    tau: &[f64; N],
    dq: &[f64; N],
    friction: Option<&JointFriction<N>>,
) -> [f64; N] {
    let mut out = *tau;
    if let Some(fr) = friction {
        for i in 0..N {
            out[i] -= fr.torque(i, dq[i]);
        }
    }
    out
}

impl<const N: usize> ArmModel<N> {
    /// The joint accelerations (rad/s²) that torques `tau` (N m) give at the frames'
    /// positions and velocities `dq`, less the joints' `friction` — the articulated-body
    /// algorithm. Gravity and armature are the model's.
    pub fn forward_dynamics(
        &self,
        f: &ArmFrames<N>,
        dq: &[f64; N],
        tau: &[f64; N],
        friction: Option<&JointFriction<N>>,
    ) -> [f64; N] {
        let tau = driving(tau, dq, friction);
        let mut s = [Motion::zeros(); N];
        let mut c = [Motion::zeros(); N];
        let mut ia = [Inertia6::zeros(); N];
        let mut pa = [Motion::zeros(); N];
        let mut v = Motion::zeros();
        for i in 0..N {
            let z = f.axis[i];
            s[i] = spatial(z, f.point[i].cross(&z));
            let joint = s[i] * dq[i];
            v += joint;
            c[i] = cross_motion(&v, &joint);
            ia[i] = body_inertia(self.bodies[i].mass, &f.com[i], &f.inertia[i]);
            pa[i] = cross_force(&v, &(ia[i] * v));
        }
        let mut u_vec = [Motion::zeros(); N];
        let mut d = [0.0; N];
        let mut u = [0.0; N];
        for i in (0..N).rev() {
            u_vec[i] = ia[i] * s[i];
            d[i] = s[i].dot(&u_vec[i]) + self.armature[i];
            u[i] = tau[i] - s[i].dot(&pa[i]);
            if i > 0 {
                let articulated = ia[i] - u_vec[i] * u_vec[i].transpose() / d[i];
                let bias = pa[i] + articulated * c[i] + u_vec[i] * (u[i] / d[i]);
                ia[i - 1] += articulated;
                pa[i - 1] += bias;
            }
        }
        let mut a = spatial(Vector3::zeros(), -self.gravity);
        let mut ddq = [0.0; N];
        for i in 0..N {
            let before = a + c[i];
            ddq[i] = (u[i] - u_vec[i].dot(&before)) / d[i];
            a = before + s[i] * ddq[i];
        }
        ddq
    }

    /// The links' potential energy in the model's gravity (J, zero with every centre of
    /// mass at the world origin): with the kinetic energy `½ q̇ᵀ M q̇`, what an arm without
    /// friction or torque keeps.
    pub fn potential_energy(&self, f: &ArmFrames<N>) -> f64 {
        (0..N)
            .map(|i| -self.bodies[i].mass * self.gravity.dot(&f.com[i]))
            .sum()
    }

    /// `M(q)` by the composite-rigid-body algorithm, the armature on its diagonal: equal
    /// to [`ArmModel::mass_matrix`] to rounding, at a fraction of its cost.
    pub fn mass_matrix_crba(&self, f: &ArmFrames<N>) -> SMatrix<f64, N, N> {
        let mut m = SMatrix::<f64, N, N>::zeros();
        // The composite body of links j..N−1: mass, centre of mass, inertia about it.
        let (mut mass, mut centre, mut inertia) = (0.0, Vector3::zeros(), Matrix3::zeros());
        for j in (0..N).rev() {
            let b = &self.bodies[j];
            let total = mass + b.mass;
            let merged = if total > 0.0 {
                (centre * mass + f.com[j] * b.mass) / total
            } else {
                f.com[j]
            };
            let shift = |m: f64, at: &Vector3<f64>| {
                let r = at - merged;
                m * (Matrix3::identity() * r.norm_squared() - r * r.transpose())
            };
            inertia = inertia + shift(mass, &centre) + f.inertia[j] + shift(b.mass, &f.com[j]);
            mass = total;
            centre = merged;
            // Joint j accelerated alone: the force and moment (about the centre) the
            // composite needs, carried to each joint i ≤ j.
            let z = f.axis[j];
            let force = mass * z.cross(&(centre - f.point[j]));
            let moment = inertia * z;
            for i in 0..=j {
                let about = moment + (centre - f.point[i]).cross(&force);
                let x = f.axis[i].dot(&about);
                m[(i, j)] = x;
                m[(j, i)] = x;
            }
            m[(j, j)] += self.armature[j];
        }
        m
    }

    /// [`ArmModel::forward_dynamics`] by the mass matrix ([`ArmModel::mass_matrix_crba`]),
    /// the bias torques (Newton–Euler) and a Cholesky solve. None when `M` is not positive
    /// definite (a chain with massless links and no armature).
    pub fn forward_dynamics_crba(
        &self,
        f: &ArmFrames<N>,
        dq: &[f64; N],
        tau: &[f64; N],
        friction: Option<&JointFriction<N>>,
    ) -> Option<[f64; N]> {
        let tau = SVector::from(driving(tau, dq, friction));
        let bias = self.inverse_dynamics(f, dq, &[0.0; N], true);
        let m = self.mass_matrix_crba(f);
        let ddq = m.cholesky()?.solve(&(tau - bias));
        Some(ddq.into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robots::{PandaTool, panda, panda_inertia};
    use nalgebra::Isometry3;
    use rand::{Rng, SeedableRng};

    fn model() -> ArmModel<7> {
        let chain = panda(PandaTool::HandTcp).with_base(
            Isometry3::translation(0.1, -0.2, 0.7) * Isometry3::rotation(Vector3::z() * 0.4),
        );
        ArmModel::<7>::new(&chain, &panda_inertia())
            .unwrap()
            .with_armature([0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074])
            .unwrap()
    }

    fn random(rng: &mut impl Rng, scale: f64) -> [f64; 7] {
        std::array::from_fn(|_| rng.random_range(-1.0..1.0) * scale)
    }

    #[test]
    fn both_algorithms_invert_newton_euler_on_a_thousand_states() {
        // Newton–Euler equals pinocchio's RNEA (python/tests/test_dynamics.py); τ from it
        // for a random q̈ must give that q̈ back.
        let model = model();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(44);
        let mut worst: f64 = 0.0;
        for _ in 0..1000 {
            let (q, dq, ddq) = (
                random(&mut rng, 2.5),
                random(&mut rng, 2.0),
                random(&mut rng, 12.0),
            );
            let f = model.frames(&q);
            let tau: [f64; 7] = model.inverse_dynamics(&f, &dq, &ddq, true).into();
            let aba = model.forward_dynamics(&f, &dq, &tau, None);
            let crba = model.forward_dynamics_crba(&f, &dq, &tau, None).unwrap();
            for i in 0..7 {
                worst = worst.max((aba[i] - ddq[i]).abs());
                worst = worst.max((crba[i] - ddq[i]).abs());
            }
        }
        assert!(worst < 1e-9, "{worst}");
    }

    #[test]
    fn the_composite_mass_matrix_equals_newton_euler_s() {
        let model = model();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(45);
        for _ in 0..100 {
            let f = model.frames(&random(&mut rng, 2.5));
            let a = model.mass_matrix_crba(&f);
            assert_eq!(a, a.transpose());
            assert!((a - model.mass_matrix(&f)).amax() < 1e-12);
        }
    }

    #[test]
    fn friction_takes_its_torque_from_the_drive() {
        let model = model();
        let friction = JointFriction {
            viscous: [0.21; 7],
            coulomb: [1.137, 1.137, 1.137, 1.137, 0.763, 0.44, 0.248],
            speed: 0.01,
        };
        let q = [0.3, -0.5, 0.2, -2.0, 0.1, 1.8, 0.7];
        let dq = [0.5, -0.4, 0.3, 0.2, -1.0, 0.6, 2.0];
        let tau = [5.0, -3.0, 2.0, 1.0, 0.5, -0.2, 0.1];
        let f = model.frames(&q);
        let with = model.forward_dynamics(&f, &dq, &tau, Some(&friction));
        let less: [f64; 7] = std::array::from_fn(|i| tau[i] - friction.torque(i, dq[i]));
        let without = model.forward_dynamics(&f, &dq, &less, None);
        assert_eq!(with, without);
        // At rest under gravity alone the arm falls: the torques that hold it give zero.
        let hold: [f64; 7] = model.gravity(&f).into();
        let still = model.forward_dynamics(&f, &[0.0; 7], &hold, None);
        assert!(still.iter().all(|a| a.abs() < 1e-10), "{still:?}");
    }
}
