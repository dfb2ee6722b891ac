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

impl LinkInertia {
    /// The rigid union of `parts`, each an inertia given in its own frame with that
    /// frame's pose in this link's frame: total mass, the mass-weighted centre, and every
    /// part's inertia turned into the link's axes and moved to the common centre (the
    /// parallel-axis theorem). Massless parts contribute nothing.
    pub fn combine(parts: &[(LinkInertia, nalgebra::Isometry3<f64>)]) -> LinkInertia {
        let mass: f64 = parts.iter().map(|(p, _)| p.mass).sum();
        if mass <= 0.0 {
            return LinkInertia {
                mass: 0.0,
                com: Vector3::zeros(),
                inertia: Matrix3::zeros(),
            };
        }
        let centre = |(p, pose): &(LinkInertia, nalgebra::Isometry3<f64>)| {
            pose * nalgebra::Point3::from(p.com)
        };
        let com = parts
            .iter()
            .map(|part| centre(part).coords * part.0.mass)
            .sum::<Vector3<f64>>()
            / mass;
        let mut inertia = Matrix3::zeros();
        for part in parts {
            let (p, pose) = part;
            let r = pose.rotation.to_rotation_matrix().into_inner();
            let d = centre(part).coords - com;
            inertia += r * p.inertia * r.transpose()
                + p.mass * (Matrix3::identity() * d.norm_squared() - d * d.transpose());
        }
        LinkInertia { mass, com, inertia }
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
