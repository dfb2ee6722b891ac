//! An arm's rigid-body model for control loops: the mass matrix, Coriolis and centrifugal
//! torques, gravity torques and the tool's Jacobian of an `N`-joint chain, in fixed-size
//! arrays so that a 1 kHz loop can evaluate them without allocating.
//!
//! [`ArmModel`] is built once from a [`SerialChain`] and its links' [`LinkInertia`] (the
//! frames of [`SerialChain::fk_frames`]), for instance from a robot's own URDF
//! ([`crate::chain_from_urdf`] reads `<inertial>`), plus a payload at the tool (a Franka's
//! hand and load, as its state reports them). Each tick, [`ArmModel::frames`] places every
//! joint axis and link in the world once; the quantities are then read from those
//! [`ArmFrames`]:
//!
//! - [`ArmModel::inverse_dynamics`]: the recursive Newton–Euler algorithm in the world
//!   frame, as [`SerialChain::inverse_dynamics`] (checked there against pinocchio);
//! - [`ArmModel::mass_matrix`]: `M(q)`, column j the torques that give joint j a unit
//!   acceleration from rest without gravity;
//! - [`ArmModel::coriolis`]: `C(q, q̇)·q̇`, the torques of motion alone (no acceleration, no
//!   gravity); [`ArmModel::gravity`]: `g(q)`;
//! - [`ArmFrames::jacobian`]: the tool's geometric Jacobian, rows `[v; ω]`.
//!
//! `M(q)·q̈ + C(q, q̇)·q̇ + g(q) = τ` with `τ` the joint torques (N m).
#![allow(clippy::needless_range_loop)] // joint-indexed loops over parallel fixed-size arrays

use nalgebra::{Isometry3, Matrix3, SMatrix, SVector, Translation3, UnitQuaternion, Vector3};

use crate::{GRAVITY, KinematicsError, LinkInertia, SerialChain};

/// One link's inertia in its joint's rotating frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Body {
    pub(crate) mass: f64,
    pub(crate) com: Vector3<f64>,
    pub(crate) inertia: Matrix3<f64>,
}

/// The rigid-body model of an `N`-joint serial arm: built once, evaluated per tick through
/// [`ArmModel::frames`] without allocating.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmModel<const N: usize> {
    base: Isometry3<f64>,
    /// Joint i's frame in joint i−1's rotating frame (the base for the first); every joint
    /// turns about its own z axis by `q_i`.
    origins: [Isometry3<f64>; N],
    /// The tool in the last joint's rotating frame.
    tail: Isometry3<f64>,
    pub(crate) bodies: [Body; N],
    pub(crate) gravity: Vector3<f64>,
    /// Rotor inertia reflected to each joint (kg m²), added to the mass matrix's diagonal.
    pub(crate) armature: [f64; N],
}

/// Every joint axis and link of an [`ArmModel`] placed in the world at one configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmFrames<const N: usize> {
    /// The joint positions these frames are for.
    pub q: [f64; N],
    /// A point on each joint's axis (the joint frame's origin).
    pub(crate) point: [Vector3<f64>; N],
    /// Each joint's axis (unit).
    pub(crate) axis: [Vector3<f64>; N],
    /// Each link's centre of mass.
    pub(crate) com: [Vector3<f64>; N],
    /// Each link's inertia about its centre of mass, in world axes.
    pub(crate) inertia: [Matrix3<f64>; N],
    /// The tool's pose.
    pub tool: Isometry3<f64>,
}

impl<const N: usize> ArmModel<N> {
    /// The model of `chain` with `links[i]` the inertia of the link joint i moves, in the
    /// link frame [`SerialChain::fk_frames`] reports. Gravity is [`GRAVITY`] in the world
    /// frame (the chain's base transform places the robot in it).
    pub fn new(chain: &SerialChain, links: &[LinkInertia]) -> Result<Self, KinematicsError> {
        if chain.dof() != N || links.len() != N {
            return Err(KinematicsError::InvalidModel(format!(
                "arm model: {N} joints expected, the chain has {} and {} link inertias were given",
                chain.dof(),
                links.len()
            )));
        }
        let (base, joints, tail) = chain.axis_joints();
        let mut origins = [Isometry3::identity(); N];
        for (o, j) in origins.iter_mut().zip(&joints) {
            *o = j.origin;
        }
        // The inertias are given in the link frames; the loop works in the joints' rotating
        // frames. The constant transform between them is read at q = 0.
        let zero = [0.0; N];
        let links_at_zero = chain.fk_frames(&zero)?.link_frames;
        let mut rotating = base;
        let mut bodies = [Body {
            mass: 0.0,
            com: Vector3::zeros(),
            inertia: Matrix3::zeros(),
        }; N];
        for i in 0..N {
            rotating *= origins[i];
            let link = links_at_zero[i];
            let link = Isometry3::from_parts(
                link.translation,
                UnitQuaternion::from_rotation_matrix(&link.rotation),
            );
            let post = rotating.inverse() * link;
            let r = post.rotation.to_rotation_matrix().into_inner();
            bodies[i] = Body {
                mass: links[i].mass,
                com: (post * nalgebra::Point3::from(links[i].com)).coords,
                inertia: r * links[i].inertia * r.transpose(),
            };
        }
        Ok(ArmModel {
            base,
            origins,
            tail,
            bodies,
            gravity: Vector3::from(GRAVITY),
            armature: [0.0; N],
        })
    }

    /// The same arm with gravity `g` in the world frame (m/s²).
    pub fn with_gravity(mut self, g: [f64; 3]) -> Self {
        self.gravity = Vector3::from(g);
        self
    }

    /// The same arm with each joint's rotor inertia reflected through its gear (kg m²,
    /// MuJoCo's `armature`): it adds to the mass matrix's diagonal. Refused when one is
    /// negative or not finite.
    pub fn with_armature(mut self, armature: [f64; N]) -> Result<Self, KinematicsError> {
        if let Some((i, a)) = armature
            .iter()
            .enumerate()
            .find(|(_, a)| !(a.is_finite() && **a >= 0.0))
        {
            return Err(KinematicsError::InvalidModel(format!(
                "joint {}'s armature {a} kg m² must be finite and ≥ 0",
                i + 1
            )));
        }
        self.armature = armature;
        Ok(self)
    }

    /// The same arm with the tool point moved by `tool`, given in the current tool frame
    /// (e.g. a Franka's `F_T_EE`, flange to end effector).
    pub fn with_tool(mut self, tool: Isometry3<f64>) -> Self {
        self.tail *= tool;
        self
    }

    /// The same arm carrying `payload` rigidly at the tool (its centre of mass and inertia
    /// in the tool frame): a hand, a grasped object. Refused when it is not a body's.
    pub fn with_payload(mut self, payload: LinkInertia) -> Result<Self, KinematicsError> {
        let i = payload.inertia;
        LinkInertia::new(
            payload.mass,
            payload.com.into(),
            [
                i[(0, 0)],
                i[(0, 1)],
                i[(0, 2)],
                i[(1, 1)],
                i[(1, 2)],
                i[(2, 2)],
            ],
        )
        .map_err(|e| KinematicsError::InvalidModel(format!("payload: {e}")))?;
        let last = &mut self.bodies[N - 1];
        let own = LinkInertia {
            mass: last.mass,
            com: last.com,
            inertia: last.inertia,
        };
        let merged = LinkInertia::combine(&[(own, Isometry3::identity()), (payload, self.tail)]);
        *last = Body {
            mass: merged.mass,
            com: merged.com,
            inertia: merged.inertia,
        };
        Ok(self)
    }

    /// The total mass of the links (kg).
    pub fn mass(&self) -> f64 {
        self.bodies.iter().map(|b| b.mass).sum()
    }

    /// Places every joint axis and link at `q` (radians).
    pub fn frames(&self, q: &[f64; N]) -> ArmFrames<N> {
        let mut f = ArmFrames {
            q: *q,
            point: [Vector3::zeros(); N],
            axis: [Vector3::zeros(); N],
            com: [Vector3::zeros(); N],
            inertia: [Matrix3::zeros(); N],
            tool: Isometry3::identity(),
        };
        let mut t = self.base;
        for i in 0..N {
            t *= self.origins[i];
            t.rotation *= UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q[i]);
            let r = t.rotation.to_rotation_matrix().into_inner();
            let b = &self.bodies[i];
            f.point[i] = t.translation.vector;
            f.axis[i] = r.column(2).into_owned();
            f.com[i] = t.translation.vector + r * b.com;
            f.inertia[i] = r * b.inertia * r.transpose();
        }
        f.tool = t * self.tail;
        f
    }

    /// Joint torques giving accelerations `ddq` at the frames' positions and velocities
    /// `dq`, with gravity when `with_gravity` (the recursive Newton–Euler algorithm).
    pub fn inverse_dynamics(
        &self,
        f: &ArmFrames<N>,
        dq: &[f64; N],
        ddq: &[f64; N],
        with_gravity: bool,
    ) -> SVector<f64, N> {
        let (mut w, mut dw) = (Vector3::zeros(), Vector3::<f64>::zeros());
        let mut acc = if with_gravity {
            -self.gravity
        } else {
            Vector3::zeros()
        };
        let mut prev = f.point[0];
        let mut force = [Vector3::zeros(); N];
        let mut moment = [Vector3::zeros(); N];
        for i in 0..N {
            let (point, axis) = (f.point[i], f.axis[i]);
            let r = point - prev;
            acc += dw.cross(&r) + w.cross(&w.cross(&r));
            let spin = axis * dq[i];
            dw += axis * ddq[i] + w.cross(&spin);
            w += spin;
            let rc = f.com[i] - point;
            let a_c = acc + dw.cross(&rc) + w.cross(&w.cross(&rc));
            let inertia = &f.inertia[i];
            force[i] = a_c * self.bodies[i].mass;
            moment[i] = inertia * dw + w.cross(&(inertia * w));
            prev = point;
        }
        let mut tau = SVector::<f64, N>::zeros();
        let (mut fo, mut m) = (Vector3::zeros(), Vector3::zeros());
        for i in (0..N).rev() {
            let point = f.point[i];
            let carried = if i + 1 < N {
                (f.point[i + 1] - point).cross(&fo)
            } else {
                Vector3::zeros()
            };
            m += moment[i] + (f.com[i] - point).cross(&force[i]) + carried;
            fo += force[i];
            tau[i] = f.axis[i].dot(&m) + self.armature[i] * ddq[i];
        }
        tau
    }

    /// The joint-space mass matrix `M(q)` (symmetric, positive definite for a chain
    /// whose links all have mass).
    pub fn mass_matrix(&self, f: &ArmFrames<N>) -> SMatrix<f64, N, N> {
        let mut m = SMatrix::<f64, N, N>::zeros();
        let zero = [0.0; N];
        let mut unit = [0.0; N];
        for j in 0..N {
            unit[j] = 1.0;
            m.set_column(j, &self.inverse_dynamics(f, &zero, &unit, false));
            unit[j] = 0.0;
        }
        // Exactly symmetric (the two triangles differ by rounding only).
        (m + m.transpose()) * 0.5
    }

    /// `C(q, q̇)·q̇`: Coriolis and centrifugal torques.
    pub fn coriolis(&self, f: &ArmFrames<N>, dq: &[f64; N]) -> SVector<f64, N> {
        self.inverse_dynamics(f, dq, &[0.0; N], false)
    }

    /// `g(q)`: the torques that hold the arm against gravity.
    pub fn gravity(&self, f: &ArmFrames<N>) -> SVector<f64, N> {
        self.inverse_dynamics(f, &[0.0; N], &[0.0; N], true)
    }
}

impl<const N: usize> ArmFrames<N> {
    /// The tool point's geometric Jacobian in the world frame, rows `[vx, vy, vz, ωx, ωy,
    /// ωz]`, column i `(z_i × (p_tool − p_i), z_i)`.
    pub fn jacobian(&self) -> SMatrix<f64, 6, N> {
        let p = self.tool.translation.vector;
        let mut j = SMatrix::<f64, 6, N>::zeros();
        for i in 0..N {
            let z = self.axis[i];
            let v = z.cross(&(p - self.point[i]));
            j.fixed_view_mut::<3, 1>(0, i).copy_from(&v);
            j.fixed_view_mut::<3, 1>(3, i).copy_from(&z);
        }
        j
    }

    /// The tool's position.
    pub fn tool_position(&self) -> Translation3<f64> {
        self.tool.translation
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robots::{PandaTool, panda, panda_inertia};
    use rand::{Rng, SeedableRng};

    fn random_state(rng: &mut impl Rng) -> ([f64; 7], [f64; 7], [f64; 7]) {
        let mut s = [[0.0; 7]; 3];
        for (k, v) in s.iter_mut().enumerate() {
            for x in v.iter_mut() {
                *x = rng.random_range(-1.0..1.0) * [2.5, 2.0, 12.0][k];
            }
        }
        (s[0], s[1], s[2])
    }

    #[test]
    fn agrees_with_the_chain_s_newton_euler_and_jacobian() {
        // SerialChain::inverse_dynamics is checked against pinocchio (python/tests).
        let chain = panda(PandaTool::HandTcp).with_base(
            Isometry3::translation(0.1, -0.2, 0.7) * Isometry3::rotation(Vector3::z() * 0.4),
        );
        let links = panda_inertia();
        let model = ArmModel::<7>::new(&chain, &links).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        for _ in 0..50 {
            let (q, dq, ddq) = random_state(&mut rng);
            let f = model.frames(&q);
            let mine = model.inverse_dynamics(&f, &dq, &ddq, true);
            let reference = chain
                .inverse_dynamics(&links, Vector3::from(GRAVITY), &q, &dq, &ddq)
                .unwrap();
            for i in 0..7 {
                assert!(
                    (mine[i] - reference[i]).abs() < 1e-9,
                    "joint {i}: {mine} vs {reference:?}"
                );
            }
            // τ = M q̈ + C q̇ + g.
            let sum = model.mass_matrix(&f) * SVector::from(ddq)
                + model.coriolis(&f, &dq)
                + model.gravity(&f);
            assert!((sum - mine).amax() < 1e-9);
            let j = chain.jacobian(&q).unwrap();
            assert!((f.jacobian() - j).amax() < 1e-12);
            let tool = chain.fk(&q).unwrap();
            assert!((f.tool.translation.vector - tool.translation.vector).norm() < 1e-12);
        }
    }

    #[test]
    fn mass_matrix_is_symmetric_positive_definite_and_gives_the_kinetic_energy() {
        let chain = panda(PandaTool::Flange);
        let model = ArmModel::<7>::new(&chain, &panda_inertia()).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for _ in 0..20 {
            let (q, dq, _) = random_state(&mut rng);
            let f = model.frames(&q);
            let m = model.mass_matrix(&f);
            assert_eq!(m, m.transpose());
            assert!(m.cholesky().is_some());
            // Ṁ − 2C is skew-symmetric, so q̇ᵀ(Ṁ q̇ − 2 C q̇) = 0: the power balance
            // d/dt(½ q̇ᵀMq̇) = q̇ᵀ(τ − g) holds. Ṁ along q̇ by central differences.
            let h = 1e-6;
            let shifted = |s: f64| {
                let mut x = q;
                for (v, d) in x.iter_mut().zip(dq) {
                    *v += s * h * d;
                }
                model.mass_matrix(&model.frames(&x))
            };
            let m_dot = (shifted(1.0) - shifted(-1.0)) / (2.0 * h);
            let dqv = SVector::from(dq);
            let power = dqv.dot(&(m_dot * dqv - 2.0 * model.coriolis(&f, &dq)));
            assert!(power.abs() < 1e-5 * (1.0 + dqv.norm_squared()), "{power}");
        }
    }

    #[test]
    fn a_payload_adds_its_weight_at_the_tool() {
        let chain = panda(PandaTool::Flange);
        let bare = ArmModel::<7>::new(&chain, &panda_inertia()).unwrap();
        let load =
            LinkInertia::new(2.0, [0.0, 0.0, 0.05], [1e-3, 0.0, 0.0, 1e-3, 0.0, 1e-3]).unwrap();
        let loaded = bare.clone().with_payload(load).unwrap();
        assert!((loaded.mass() - bare.mass() - 2.0).abs() < 1e-12);
        let q = [0.3, -0.5, 0.2, -2.0, 0.1, 1.8, 0.7];
        let (fb, fl) = (bare.frames(&q), loaded.frames(&q));
        // The extra gravity torques are Jᵀ of the load's weight at its centre of mass.
        let centre = fl.tool * nalgebra::Point3::new(0.0, 0.0, 0.05);
        let at_centre = bare
            .clone()
            .with_tool(Isometry3::translation(0.0, 0.0, 0.05));
        let j = at_centre.frames(&q).jacobian();
        let weight = SVector::<f64, 6>::new(0.0, 0.0, 2.0 * 9.81, 0.0, 0.0, 0.0);
        let extra = loaded.gravity(&fl) - bare.gravity(&fb);
        assert!((extra - j.transpose() * weight).amax() < 1e-9);
        assert!((at_centre.frames(&q).tool.translation.vector - centre.coords).norm() < 1e-12);
        let bad = LinkInertia { mass: -1.0, ..load };
        assert!(
            bare.with_payload(bad)
                .unwrap_err()
                .to_string()
                .contains("payload")
        );
    }
}
