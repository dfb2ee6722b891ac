//! Denavit-Hartenberg serial chains: forward kinematics and geometric Jacobians.

use nalgebra::{
    Isometry3, IsometryMatrix3, Matrix3, Matrix4, OMatrix, Rotation3, Translation3, U6, Vector3,
};

use crate::KinematicsError;

/// Which Denavit-Hartenberg convention a link table is written in. The two are not
/// interchangeable: the same numbers describe different robots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DhConvention {
    /// Standard (distal) DH: `T_i = RotZ(θ_i) TransZ(d_i) TransX(a_i) RotX(α_i)`; joint i
    /// turns about the z axis of frame i − 1.
    Standard,
    /// Modified (proximal, Craig) DH: `T_i = RotX(α_{i−1}) TransX(a_{i−1}) RotZ(θ_i)
    /// TransZ(d_i)`; joint i turns about the z axis of frame i. Each row holds
    /// `a_{i−1}`, `α_{i−1}`, `d_i`, `θ_i`. The Panda's published table is in this convention.
    Modified,
}

/// One revolute joint and its link, as one row of a DH table (lengths in metres, angles in
/// radians). The joint angle is `θ = q + offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhLink {
    /// Link length `a` (for modified DH: `a_{i−1}`).
    pub a: f64,
    /// Link offset `d`.
    pub d: f64,
    /// Link twist `α` (for modified DH: `α_{i−1}`).
    pub alpha: f64,
    /// Joint angle offset added to `q`.
    pub offset: f64,
}

impl DhLink {
    /// A row with no joint offset.
    pub const fn new(a: f64, d: f64, alpha: f64) -> Self {
        Self {
            a,
            d,
            alpha,
            offset: 0.0,
        }
    }
}

/// A rigid transform as a 3×4 matrix `[R | t]`, the fast internal form.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Affine {
    r: [[f64; 3]; 3],
    t: [f64; 3],
}

impl Affine {
    const IDENTITY: Affine = Affine {
        r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        t: [0.0; 3],
    };

    fn mul(&self, o: &Affine) -> Affine {
        let row = |a: &[f64; 3]| {
            let r = std::array::from_fn(|j| a[0] * o.r[0][j] + a[1] * o.r[1][j] + a[2] * o.r[2][j]);
            (r, a[0] * o.t[0] + a[1] * o.t[1] + a[2] * o.t[2])
        };
        let rows = [row(&self.r[0]), row(&self.r[1]), row(&self.r[2])];
        Affine {
            r: [rows[0].0, rows[1].0, rows[2].0],
            t: [
                self.t[0] + rows[0].1,
                self.t[1] + rows[1].1,
                self.t[2] + rows[2].1,
            ],
        }
    }

    fn from_isometry(iso: &Isometry3<f64>) -> Affine {
        let m = iso.rotation.to_rotation_matrix();
        let m = m.matrix();
        Affine {
            r: [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ],
            t: [iso.translation.x, iso.translation.y, iso.translation.z],
        }
    }

    fn to_matrix4(self) -> Matrix4<f64> {
        let r = self.r;
        let t = self.t;
        Matrix4::new(
            r[0][0], r[0][1], r[0][2], t[0], r[1][0], r[1][1], r[1][2], t[1], r[2][0], r[2][1],
            r[2][2], t[2], 0.0, 0.0, 0.0, 1.0,
        )
    }

    fn to_isometry(self) -> IsometryMatrix3<f64> {
        let r = self.r;
        let m = Matrix3::new(
            r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
        );
        IsometryMatrix3::from_parts(
            Translation3::new(self.t[0], self.t[1], self.t[2]),
            Rotation3::from_matrix_unchecked(m),
        )
    }

    /// The transform of one DH row at joint angle `theta`.
    fn link(conv: DhConvention, l: &DhLink, (sa, ca): (f64, f64), theta: f64) -> Affine {
        let (st, ct) = theta.sin_cos();
        match conv {
            DhConvention::Standard => Affine {
                r: [
                    [ct, -st * ca, st * sa],
                    [st, ct * ca, -ct * sa],
                    [0.0, sa, ca],
                ],
                t: [l.a * ct, l.a * st, l.d],
            },
            DhConvention::Modified => Affine {
                r: [
                    [ct, -st, 0.0],
                    [st * ca, ct * ca, -sa],
                    [st * sa, ct * sa, ca],
                ],
                t: [l.a, -sa * l.d, ca * l.d],
            },
        }
    }
}

/// A serial chain of revolute joints described by a DH table, with a fixed base transform
/// (world → robot base) and a fixed tool transform (last joint frame → tool point).
#[derive(Debug, Clone, PartialEq)]
pub struct SerialChain {
    convention: DhConvention,
    links: Vec<DhLink>,
    /// `(sin α, cos α)` of each row, computed once.
    twist: Vec<(f64, f64)>,
    base: Affine,
    tool: Affine,
    limits: Option<(Vec<f64>, Vec<f64>)>,
}

/// Forward kinematics with every joint frame, for Jacobians and teaching.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainPose {
    /// World pose of each joint's frame: for modified DH, frame i (whose z axis is joint
    /// i's axis); for standard DH, frame i − 1 (ditto). `frames[0]` is joint 1's.
    pub joint_frames: Vec<IsometryMatrix3<f64>>,
    /// World pose of the tool point.
    pub tool: IsometryMatrix3<f64>,
}

impl SerialChain {
    /// A chain from its DH table. The base and tool transforms start as identities.
    pub fn new(convention: DhConvention, links: Vec<DhLink>) -> Result<Self, KinematicsError> {
        if links.is_empty() {
            return Err(KinematicsError::InvalidModel(
                "a serial chain needs at least one joint".into(),
            ));
        }
        for (i, l) in links.iter().enumerate() {
            if ![l.a, l.d, l.alpha, l.offset].iter().all(|v| v.is_finite()) {
                return Err(KinematicsError::InvalidModel(format!(
                    "DH row {} has a non-finite value",
                    i + 1
                )));
            }
        }
        let twist = links.iter().map(|l| l.alpha.sin_cos()).collect();
        Ok(Self {
            convention,
            links,
            twist,
            base: Affine::IDENTITY,
            tool: Affine::IDENTITY,
            limits: None,
        })
    }

    /// The same chain placed at `base` (world → robot base frame).
    pub fn with_base(mut self, base: Isometry3<f64>) -> Self {
        self.base = Affine::from_isometry(&base);
        self
    }

    /// The same chain with the tool point at `tool` relative to the last joint frame.
    pub fn with_tool(mut self, tool: Isometry3<f64>) -> Self {
        self.tool = Affine::from_isometry(&tool);
        self
    }

    /// The same chain with joint position limits (radians); each lower < upper.
    pub fn with_limits(mut self, lower: &[f64], upper: &[f64]) -> Result<Self, KinematicsError> {
        let n = self.dof();
        for (what, v) in [("lower", lower), ("upper", upper)] {
            if v.len() != n {
                return Err(KinematicsError::InvalidModel(format!(
                    "{what} limits have {} values for {n} joints",
                    v.len()
                )));
            }
        }
        for i in 0..n {
            if !(lower[i].is_finite() && upper[i].is_finite() && lower[i] < upper[i]) {
                return Err(KinematicsError::InvalidModel(format!(
                    "joint {}: limits must be finite with lower < upper (got {} .. {})",
                    i + 1,
                    lower[i],
                    upper[i]
                )));
            }
        }
        self.limits = Some((lower.to_vec(), upper.to_vec()));
        Ok(self)
    }

    /// Joint position limits `(lower, upper)`, if the model has them.
    pub fn limits(&self) -> Option<(&[f64], &[f64])> {
        self.limits
            .as_ref()
            .map(|(l, u)| (l.as_slice(), u.as_slice()))
    }

    /// The DH convention of the table.
    pub fn convention(&self) -> DhConvention {
        self.convention
    }

    /// The DH table.
    pub fn links(&self) -> &[DhLink] {
        &self.links
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.links.len()
    }

    fn check(&self, q: &[f64]) -> Result<(), KinematicsError> {
        if q.len() != self.dof() {
            return Err(KinematicsError::JointCount {
                expected: self.dof(),
                got: q.len(),
            });
        }
        if let Some((i, &v)) = q.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(KinematicsError::NotFinite {
                joint: i + 1,
                value: v,
            });
        }
        Ok(())
    }

    /// Walks the chain, calling `frame(i, axis_frame)` with the frame whose z axis is joint
    /// i's axis, and returns the tool transform.
    fn walk(&self, q: &[f64], mut frame: impl FnMut(usize, &Affine)) -> Affine {
        let mut t = self.base;
        for (i, ((l, &tw), &qi)) in self.links.iter().zip(&self.twist).zip(q).enumerate() {
            let link = Affine::link(self.convention, l, tw, qi + l.offset);
            match self.convention {
                DhConvention::Standard => {
                    frame(i, &t);
                    t = t.mul(&link);
                }
                DhConvention::Modified => {
                    t = t.mul(&link);
                    frame(i, &t);
                }
            }
        }
        t.mul(&self.tool)
    }

    /// The world pose of the tool point at joint angles `q` (radians), with its rotation
    /// as a matrix (`IsometryMatrix3`; convert with `UnitQuaternion::from_rotation_matrix`
    /// when a quaternion is wanted).
    pub fn fk(&self, q: &[f64]) -> Result<IsometryMatrix3<f64>, KinematicsError> {
        self.check(q)?;
        Ok(self.walk(q, |_, _| {}).to_isometry())
    }

    /// The tool pose as a 4×4 homogeneous matrix (row-major as printed, metres).
    pub fn fk_matrix(&self, q: &[f64]) -> Result<Matrix4<f64>, KinematicsError> {
        self.check(q)?;
        Ok(self.walk(q, |_, _| {}).to_matrix4())
    }

    /// The tool pose and every joint frame.
    pub fn fk_frames(&self, q: &[f64]) -> Result<ChainPose, KinematicsError> {
        self.check(q)?;
        let mut frames = Vec::with_capacity(self.dof());
        let tool = self.walk(q, |_, f| frames.push(f.to_isometry()));
        Ok(ChainPose {
            joint_frames: frames,
            tool: tool.to_isometry(),
        })
    }

    /// The geometric Jacobian of the tool point in the world frame, 6 × n: rows
    /// `[vx, vy, vz, ωx, ωy, ωz]` (linear velocity of the tool point, angular velocity),
    /// column i for joint i: `(z_i × (p_tool − p_i), z_i)`.
    pub fn jacobian(&self, q: &[f64]) -> Result<OMatrix<f64, U6, nalgebra::Dyn>, KinematicsError> {
        self.check(q)?;
        let n = self.dof();
        let mut axes = Vec::with_capacity(n);
        let mut origins = Vec::with_capacity(n);
        let tool = self.walk(q, |_, f| {
            axes.push([f.r[0][2], f.r[1][2], f.r[2][2]]);
            origins.push(f.t);
        });
        let mut j = OMatrix::<f64, U6, nalgebra::Dyn>::zeros(n);
        for i in 0..n {
            let z = Vector3::from(axes[i]);
            let r = Vector3::from(tool.t) - Vector3::from(origins[i]);
            let v = z.cross(&r);
            for k in 0..3 {
                j[(k, i)] = v[k];
                j[(k + 3, i)] = z[k];
            }
        }
        Ok(j)
    }

    /// Yoshikawa's manipulability `√det(J Jᵀ)` of the full 6 × n Jacobian (0 at a
    /// singularity and for chains with fewer than 6 joints).
    pub fn manipulability(&self, q: &[f64]) -> Result<f64, KinematicsError> {
        let j = self.jacobian(q)?;
        Ok((j.clone() * j.transpose()).determinant().max(0.0).sqrt())
    }
}
