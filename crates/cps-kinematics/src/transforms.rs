//! Elementary transforms for teaching and for reading other tools' conventions (thesis
//! ch. 2): homogeneous rotations and translations in space (4 × 4) and in the plane
//! (3 × 3), and Euler angles.
//!
//! Two Euler conventions are named explicitly, because mixing them up is the classic bug:
//! - [`EulerZyx`]: `R = Rz(φ) · Ry(θ) · Rx(ψ)` (yaw φ, pitch θ, roll ψ about the fixed
//!   world axes x, then y, then z), the convention of Lynch & Park that the thesis uses, and
//!   URDF's `rpy = [ψ, θ, φ]`.
//! - [`EulerXyz`]: `R = Rx(α) · Ry(β) · Rz(γ)`, CoppeliaSim's `alpha, beta, gamma` (as
//!   returned by `sim.getObjectOrientation`).
//!
//! For quaternions use nalgebra's `UnitQuaternion` (its `from_rotation_matrix` and
//! `to_rotation_matrix` convert); cps writes them as `[x, y, z, w]` in files and JSON.

use nalgebra::{Matrix3, Matrix4, Rotation3, Vector3};

/// Homogeneous rotation by `angle` (radians) about x.
pub fn rot_x(angle: f64) -> Matrix4<f64> {
    Rotation3::from_axis_angle(&Vector3::x_axis(), angle).to_homogeneous()
}

/// Homogeneous rotation by `angle` (radians) about y.
pub fn rot_y(angle: f64) -> Matrix4<f64> {
    Rotation3::from_axis_angle(&Vector3::y_axis(), angle).to_homogeneous()
}

/// Homogeneous rotation by `angle` (radians) about z.
pub fn rot_z(angle: f64) -> Matrix4<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), angle).to_homogeneous()
}

/// Homogeneous translation by `(a, b, c)` metres.
pub fn trans(a: f64, b: f64, c: f64) -> Matrix4<f64> {
    Matrix4::new_translation(&Vector3::new(a, b, c))
}

/// Planar homogeneous rotation by `angle` (radians) about the origin.
pub fn planar_rot(angle: f64) -> Matrix3<f64> {
    let (s, c) = angle.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Planar homogeneous translation by `(x, y)` metres.
pub fn planar_trans(x: f64, y: f64) -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, x, 0.0, 1.0, y, 0.0, 0.0, 1.0)
}

/// Z-Y-X Euler angles (radians): `R = Rz(yaw) · Ry(pitch) · Rx(roll)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EulerZyx {
    /// φ, about z (applied last).
    pub yaw: f64,
    /// θ, about y.
    pub pitch: f64,
    /// ψ, about x (applied first).
    pub roll: f64,
}

impl EulerZyx {
    /// The rotation matrix.
    pub fn to_rotation(self) -> Rotation3<f64> {
        Rotation3::from_euler_angles(self.roll, self.pitch, self.yaw)
    }

    /// The angles of a rotation, pitch in [−π/2, π/2]. At pitch = ±π/2 (gimbal lock) only
    /// yaw ∓ roll is defined; roll is then reported as 0.
    pub fn from_rotation(r: &Rotation3<f64>) -> Self {
        let (roll, pitch, yaw) = r.euler_angles();
        Self { yaw, pitch, roll }
    }
}

/// X-Y-Z Euler angles (radians) as CoppeliaSim uses them: `R = Rx(α) · Ry(β) · Rz(γ)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EulerXyz {
    /// α, about x (outermost).
    pub alpha: f64,
    /// β, about y.
    pub beta: f64,
    /// γ, about z (innermost).
    pub gamma: f64,
}

impl EulerXyz {
    /// The rotation matrix.
    pub fn to_rotation(self) -> Rotation3<f64> {
        let axis = |a: nalgebra::Unit<Vector3<f64>>, t: f64| Rotation3::from_axis_angle(&a, t);
        axis(Vector3::x_axis(), self.alpha)
            * axis(Vector3::y_axis(), self.beta)
            * axis(Vector3::z_axis(), self.gamma)
    }

    /// The angles of a rotation, β in [−π/2, π/2]. At β = ±π/2 only α ± γ is defined; γ
    /// is then reported as 0.
    pub fn from_rotation(r: &Rotation3<f64>) -> Self {
        let m = r.matrix();
        // m = Rx(α) Ry(β) Rz(γ): m[0][2] = sin β, m[1][2] = −sin α cos β,
        // m[2][2] = cos α cos β, m[0][0] = cos β cos γ, m[0][1] = −cos β sin γ.
        let beta = m[(0, 2)].clamp(-1.0, 1.0).asin();
        if (1.0 - m[(0, 2)].abs()) > 1e-12 {
            Self {
                alpha: (-m[(1, 2)]).atan2(m[(2, 2)]),
                beta,
                gamma: (-m[(0, 1)]).atan2(m[(0, 0)]),
            }
        } else {
            // Gimbal lock: m[1][1] = cos(α ± γ) and m[2][1] = sin(α ± γ); with γ = 0 they
            // give α.
            Self {
                alpha: m[(2, 1)].atan2(m[(1, 1)]),
                beta,
                gamma: 0.0,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn elementary_transforms_compose_as_written() {
        // Trans then Rot: a point at the origin of the rotated frame lands at (1, 2, 3).
        let t = trans(1.0, 2.0, 3.0) * rot_z(FRAC_PI_2);
        let p = t * nalgebra::Vector4::new(1.0, 0.0, 0.0, 1.0);
        assert!((p - nalgebra::Vector4::new(1.0, 3.0, 3.0, 1.0)).norm() < 1e-15);
        assert!((rot_x(0.3) * rot_x(-0.3) - Matrix4::identity()).norm() < 1e-15);
        let y = rot_y(FRAC_PI_2) * nalgebra::Vector4::new(0.0, 0.0, 1.0, 0.0);
        assert!((y - nalgebra::Vector4::new(1.0, 0.0, 0.0, 0.0)).norm() < 1e-15);
        let q = planar_trans(1.0, 0.0) * planar_rot(FRAC_PI_2) * Vector3::new(1.0, 0.0, 1.0);
        assert!((q - Vector3::new(1.0, 1.0, 1.0)).norm() < 1e-15);
    }

    #[test]
    fn euler_angles_round_trip_and_differ_between_conventions() {
        for &(a, b, c) in &[(0.3, -0.7, 1.1), (-2.5, 0.2, 3.0), (0.1, 1.4, -0.4)] {
            let zyx = EulerZyx {
                yaw: a,
                pitch: b,
                roll: c,
            };
            let r = zyx.to_rotation();
            let manual = rot_z(a) * rot_y(b) * rot_x(c);
            assert!((r.to_homogeneous() - manual).norm() < 1e-14);
            let back = EulerZyx::from_rotation(&r);
            assert!((back.to_rotation().matrix() - r.matrix()).norm() < 1e-14);
            let xyz = EulerXyz {
                alpha: a,
                beta: b,
                gamma: c,
            };
            let r2 = xyz.to_rotation();
            assert!((r2.to_homogeneous() - rot_x(a) * rot_y(b) * rot_z(c)).norm() < 1e-14);
            let back = EulerXyz::from_rotation(&r2);
            assert!((back.alpha - a).abs() < 1e-12 && (back.beta - b).abs() < 1e-12);
            assert!((back.gamma - c).abs() < 1e-12);
            assert!(
                (r.matrix() - r2.matrix()).norm() > 1e-3,
                "conventions coincide"
            );
        }
        // Gimbal lock: the rotation is still reproduced.
        let locked = EulerXyz {
            alpha: 0.4,
            beta: FRAC_PI_2,
            gamma: 0.9,
        }
        .to_rotation();
        let back = EulerXyz::from_rotation(&locked);
        assert!((back.to_rotation().matrix() - locked.matrix()).norm() < 1e-12);
    }
}
