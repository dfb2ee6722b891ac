//! Serial chains of revolute joints: forward kinematics and geometric Jacobians.
//!
//! A chain is described either by a Denavit-Hartenberg table (standard or modified, named
//! explicitly) or by URDF-style joints (a fixed origin, then a rotation about an axis).
//! Both compile to one internal form: per joint a constant rigid transform followed by a
//! rotation about the local z axis, `T = base · Π_i (F_i · Rz(q_i + offset_i)) · tail`,
//! so forward kinematics costs one 3×4 product and one z-rotation per joint whatever the
//! description.

use nalgebra::{
    Isometry3, IsometryMatrix3, Matrix3, Matrix4, OMatrix, Rotation3, Translation3, U6, Unit,
    UnitQuaternion, Vector3,
};

use crate::KinematicsError;
use crate::fastmath::sin_cos_batch;
use pulp::{Arch, Simd, WithSimd};

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

/// A rigid transform `[R | t]` stored as four columns of four lanes (the fourth lane is
/// padding, always 0): the three columns of `R`, then `t`. Column arithmetic on `[f64; 4]`
/// vectorises, which is what makes forward kinematics fast.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Affine {
    c: [[f64; 4]; 4],
}

/// `a·x + y` lane-wise; fused when the dispatched instruction set has FMA.
#[inline(always)]
fn axpy<const FMA: bool>(a: [f64; 4], x: f64, y: [f64; 4]) -> [f64; 4] {
    let mut out = y;
    for i in 0..4 {
        out[i] = if FMA {
            a[i].mul_add(x, y[i])
        } else {
            a[i] * x + y[i]
        };
    }
    out
}

/// `c0·v0 + c1·v1 + c2·v2 + base`: one column of an affine product.
#[inline(always)]
fn column<const FMA: bool>(c: &[[f64; 4]; 4], v: [f64; 4], base: [f64; 4]) -> [f64; 4] {
    axpy::<FMA>(
        c[2],
        v[2],
        axpy::<FMA>(c[1], v[1], axpy::<FMA>(c[0], v[0], base)),
    )
}

#[inline(always)]
fn scale(a: [f64; 4], x: f64) -> [f64; 4] {
    [a[0] * x, a[1] * x, a[2] * x, a[3] * x]
}

impl Affine {
    const IDENTITY: Affine = Affine::from_rows(
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        [0.0; 3],
    );

    const fn from_rows(r: [[f64; 3]; 3], t: [f64; 3]) -> Affine {
        Affine {
            c: [
                [r[0][0], r[1][0], r[2][0], 0.0],
                [r[0][1], r[1][1], r[2][1], 0.0],
                [r[0][2], r[1][2], r[2][2], 0.0],
                [t[0], t[1], t[2], 0.0],
            ],
        }
    }

    /// Entry `(i, j)` of the rotation.
    #[inline(always)]
    fn r(&self, i: usize, j: usize) -> f64 {
        self.c[j][i]
    }

    /// The translation.
    #[inline(always)]
    fn t(&self) -> [f64; 3] {
        [self.c[3][0], self.c[3][1], self.c[3][2]]
    }

    /// `self · o`: column j of the product is `R · o_j` (plus `t` for the translation).
    fn mul(&self, o: &Affine) -> Affine {
        self.mul_f::<false>(o)
    }

    #[inline(always)]
    fn mul_f<const FMA: bool>(&self, o: &Affine) -> Affine {
        let c = &self.c;
        Affine {
            c: [
                column::<FMA>(c, o.c[0], [0.0; 4]),
                column::<FMA>(c, o.c[1], [0.0; 4]),
                column::<FMA>(c, o.c[2], [0.0; 4]),
                column::<FMA>(c, o.c[3], c[3]),
            ],
        }
    }

    /// `self · Rz(θ)` given `(sin θ, cos θ)`: only the first two columns change.
    #[inline(always)]
    fn rot_z<const FMA: bool>(&self, (s, c): (f64, f64)) -> Affine {
        let [x, y, z, t] = self.c;
        Affine {
            c: [
                axpy::<FMA>(y, s, scale(x, c)),
                axpy::<FMA>(x, -s, scale(y, c)),
                z,
                t,
            ],
        }
    }

    fn from_isometry(iso: &Isometry3<f64>) -> Affine {
        let m = iso.rotation.to_rotation_matrix();
        let m = m.matrix();
        Affine::from_rows(
            std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
            [iso.translation.x, iso.translation.y, iso.translation.z],
        )
    }

    fn to_matrix4(self) -> Matrix4<f64> {
        Matrix4::from_fn(|i, j| match (i, j) {
            (3, 3) => 1.0,
            (3, _) => 0.0,
            _ => self.c[j][i],
        })
    }

    fn to_isometry3(self) -> Isometry3<f64> {
        let m = self.to_isometry();
        Isometry3::from_parts(
            m.translation,
            UnitQuaternion::from_rotation_matrix(&m.rotation),
        )
    }

    fn to_isometry(self) -> IsometryMatrix3<f64> {
        let m = Matrix3::from_fn(|i, j| self.c[j][i]);
        let t = self.t();
        IsometryMatrix3::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            Rotation3::from_matrix_unchecked(m),
        )
    }

    fn rot_x(alpha: f64) -> Affine {
        let (s, c) = alpha.sin_cos();
        Affine::from_rows([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]], [0.0; 3])
    }

    fn translation(x: f64, y: f64, z: f64) -> Affine {
        Affine::from_rows(
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [x, y, z],
        )
    }

    /// The inverse of a rigid transform: `[Rᵀ | −Rᵀ t]`.
    fn inverse(&self) -> Affine {
        let t = self.t();
        Affine::from_rows(
            std::array::from_fn(|i| std::array::from_fn(|j| self.r(j, i))),
            std::array::from_fn(|i| {
                -(self.r(0, i) * t[0] + self.r(1, i) * t[1] + self.r(2, i) * t[2])
            }),
        )
    }
}

/// Joints handled with stack buffers; longer chains use the heap.
const STACK_JOINTS: usize = 16;

/// Three scratch slices of length `n`: on the stack when `n` fits, else in `heap`.
#[inline(always)]
fn scratch<'a>(
    n: usize,
    stack: &'a mut [[f64; STACK_JOINTS]; 3],
    heap: &'a mut Vec<f64>,
) -> [&'a mut [f64]; 3] {
    if n <= STACK_JOINTS {
        let [a, s, c] = stack;
        [&mut a[..n], &mut s[..n], &mut c[..n]]
    } else {
        heap.resize(3 * n, 0.0);
        let (a, rest) = heap.split_at_mut(n);
        let (s, c) = rest.split_at_mut(n);
        [a, s, c]
    }
}

/// One revolute joint in URDF form: the joint frame sits at `origin` relative to the
/// previous joint's child frame (the base frame for the first joint), and the joint turns
/// by `q + offset` about `axis`, given in the joint frame. The child frame is the joint
/// frame turned by that angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RevoluteJoint {
    /// Fixed transform from the parent frame to the joint frame (metres, radians).
    pub origin: Isometry3<f64>,
    /// Rotation axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Angle offset added to `q`.
    pub offset: f64,
}

/// How a chain was described; kept for display and for saving the model again.
#[derive(Debug, Clone, PartialEq)]
pub enum ChainGeometry {
    /// A Denavit-Hartenberg table in the named convention.
    Dh {
        /// Standard or modified.
        convention: DhConvention,
        /// One row per joint.
        links: Vec<DhLink>,
    },
    /// URDF-style joints.
    Joints(Vec<RevoluteJoint>),
}

/// Joint position limits in radians.
#[derive(Debug, Clone, PartialEq)]
struct Limits {
    lower: Vec<f64>,
    upper: Vec<f64>,
}

/// A serial chain of revolute joints with a fixed base transform (world → robot base) and
/// a fixed tool transform (last joint's frame → tool point), optional joint position
/// limits and optional joint speed limits.
#[derive(Debug, Clone, PartialEq)]
pub struct SerialChain {
    geometry: ChainGeometry,
    /// Constant factor before each joint's z-rotation, the previous joint's trailing factor
    /// and (for the first joint) the base folded in.
    fixed: Vec<Affine>,
    /// Constant factor after each joint's z-rotation (rotation frame → link frame).
    post: Vec<Affine>,
    offsets: Vec<f64>,
    /// The first joint's own leading factor (before the base is folded in).
    pre0: Affine,
    base: Affine,
    tool: Affine,
    /// `post[n−1] · tool`.
    tail: Affine,
    limits: Option<Limits>,
    velocity_limits: Option<Vec<f64>>,
}

/// A joint's axis and the link it moves, in the world frame ([`SerialChain::joint_axes`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct JointAxis {
    /// A point on the axis (the joint frame's origin).
    pub point: Vector3<f64>,
    /// The axis direction (unit).
    pub axis: Vector3<f64>,
    /// The pose of the link the joint moves.
    pub link: IsometryMatrix3<f64>,
}

/// Forward kinematics with every link frame, for teaching and drawing.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainPose {
    /// World pose of the frame attached after each joint: DH frame i for either DH
    /// convention, the child link frame for URDF joints. `link_frames[0]` follows joint 1.
    pub link_frames: Vec<IsometryMatrix3<f64>>,
    /// World pose of the tool point.
    pub tool: IsometryMatrix3<f64>,
}

/// A rotation taking the z axis onto `axis`.
fn z_onto(axis: &Unit<Vector3<f64>>) -> Affine {
    let q = UnitQuaternion::rotation_between(&Vector3::z(), axis).unwrap_or_else(|| {
        // axis = −z: any half turn about an axis perpendicular to z
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    });
    Affine::from_isometry(&Isometry3::from_parts(Translation3::identity(), q))
}

fn finite_isometry(iso: &Isometry3<f64>) -> bool {
    iso.translation.vector.iter().all(|v| v.is_finite())
        && iso.rotation.coords.iter().all(|v| v.is_finite())
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
        let (pre, post) = links
            .iter()
            .map(|l| match convention {
                // Rz(θ) · Tz(d) Tx(a) Rx(α)
                DhConvention::Standard => (
                    Affine::IDENTITY,
                    Affine::translation(l.a, 0.0, l.d).mul(&Affine::rot_x(l.alpha)),
                ),
                // Rx(α) Tx(a) · Rz(θ) · Tz(d)
                DhConvention::Modified => (
                    Affine::rot_x(l.alpha).mul(&Affine::translation(l.a, 0.0, 0.0)),
                    Affine::translation(0.0, 0.0, l.d),
                ),
            })
            .unzip();
        let offsets = links.iter().map(|l| l.offset).collect();
        Ok(Self::compile(
            ChainGeometry::Dh { convention, links },
            pre,
            post,
            offsets,
        ))
    }

    /// A chain from URDF-style revolute joints (see [`RevoluteJoint`]). The base and tool
    /// transforms start as identities.
    pub fn from_joints(joints: Vec<RevoluteJoint>) -> Result<Self, KinematicsError> {
        if joints.is_empty() {
            return Err(KinematicsError::InvalidModel(
                "a serial chain needs at least one joint".into(),
            ));
        }
        for (i, j) in joints.iter().enumerate() {
            if !(finite_isometry(&j.origin)
                && j.axis.iter().all(|v| v.is_finite())
                && j.offset.is_finite())
            {
                return Err(KinematicsError::InvalidModel(format!(
                    "joint {} has a non-finite origin, axis or offset",
                    i + 1
                )));
            }
        }
        // origin · Rot(axis, θ) = (origin · A) · Rz(θ) · Aᵀ with A taking z onto the axis
        let (pre, post) = joints
            .iter()
            .map(|j| {
                let a = z_onto(&j.axis);
                (Affine::from_isometry(&j.origin).mul(&a), a.inverse())
            })
            .unzip();
        let offsets = joints.iter().map(|j| j.offset).collect();
        Ok(Self::compile(
            ChainGeometry::Joints(joints),
            pre,
            post,
            offsets,
        ))
    }

    fn compile(
        geometry: ChainGeometry,
        pre: Vec<Affine>,
        post: Vec<Affine>,
        offsets: Vec<f64>,
    ) -> Self {
        // F_0 = pre_0 (base folded in later), F_i = post_{i−1} · pre_i
        let fixed = std::iter::once(pre[0])
            .chain(post.iter().zip(&pre[1..]).map(|(a, b)| a.mul(b)))
            .collect();
        let mut chain = Self {
            geometry,
            fixed,
            post,
            offsets,
            pre0: pre[0],
            base: Affine::IDENTITY,
            tool: Affine::IDENTITY,
            tail: Affine::IDENTITY,
            limits: None,
            velocity_limits: None,
        };
        chain.refold();
        chain
    }

    /// Folds the base into the first factor and the tool into the tail.
    fn refold(&mut self) {
        self.fixed[0] = self.base.mul(&self.pre0);
        self.tail = self.post[self.post.len() - 1].mul(&self.tool);
    }

    /// The same chain placed at `base` (world → robot base frame).
    pub fn with_base(mut self, base: Isometry3<f64>) -> Self {
        self.base = Affine::from_isometry(&base);
        self.refold();
        self
    }

    /// The same chain with the tool point at `tool` relative to the last link frame.
    pub fn with_tool(mut self, tool: Isometry3<f64>) -> Self {
        self.tool = Affine::from_isometry(&tool);
        self.refold();
        self
    }

    /// The same chain with joint position limits (radians), `lower < upper` per joint.
    /// A joint without a limit (a continuous joint) takes `−∞ .. ∞`.
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
            if lower[i].is_nan() || upper[i].is_nan() || lower[i] >= upper[i] {
                return Err(KinematicsError::InvalidModel(format!(
                    "joint {}: limits need lower < upper (got {} .. {})",
                    i + 1,
                    lower[i],
                    upper[i]
                )));
            }
        }
        self.limits = Some(Limits {
            lower: lower.to_vec(),
            upper: upper.to_vec(),
        });
        Ok(self)
    }

    /// The same chain with joint speed limits (rad/s, each finite and > 0).
    pub fn with_velocity_limits(mut self, max: &[f64]) -> Result<Self, KinematicsError> {
        if max.len() != self.dof() {
            return Err(KinematicsError::InvalidModel(format!(
                "speed limits have {} values for {} joints",
                max.len(),
                self.dof()
            )));
        }
        if let Some(i) = max.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(KinematicsError::InvalidModel(format!(
                "joint {}: the speed limit must be finite and > 0 (got {})",
                i + 1,
                max[i]
            )));
        }
        self.velocity_limits = Some(max.to_vec());
        Ok(self)
    }

    /// Joint position limits `(lower, upper)`, if the model has them.
    pub fn limits(&self) -> Option<(&[f64], &[f64])> {
        self.limits
            .as_ref()
            .map(|l| (l.lower.as_slice(), l.upper.as_slice()))
    }

    /// Joint speed limits in rad/s, if the model has them.
    pub fn velocity_limits(&self) -> Option<&[f64]> {
        self.velocity_limits.as_deref()
    }

    /// How the chain was described.
    pub fn geometry(&self) -> &ChainGeometry {
        &self.geometry
    }

    /// The base transform (world → robot base).
    pub fn base(&self) -> Isometry3<f64> {
        self.base.to_isometry3()
    }

    /// The tool transform (last link frame → tool point).
    pub fn tool(&self) -> Isometry3<f64> {
        self.tool.to_isometry3()
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.offsets.len()
    }

    /// Checks a joint vector's length and finiteness.
    pub fn check(&self, q: &[f64]) -> Result<(), KinematicsError> {
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

    /// Checks `q` like [`SerialChain::check`] and that it lies within the position limits;
    /// the error names the first joint outside.
    pub fn check_within_limits(&self, q: &[f64]) -> Result<(), KinematicsError> {
        self.check(q)?;
        if let Some((lo, hi)) = self.limits()
            && let Some(i) = (0..q.len()).find(|&i| q[i] < lo[i] || q[i] > hi[i])
        {
            return Err(KinematicsError::OutsideLimits {
                joint: i + 1,
                value: q[i],
                lower: lo[i],
                upper: hi[i],
            });
        }
        Ok(())
    }

    /// Whether `q` lies within the position limits (always true without limits).
    pub fn within_limits(&self, q: &[f64]) -> bool {
        self.limits.as_ref().is_none_or(|l| {
            q.iter()
                .zip(l.lower.iter().zip(&l.upper))
                .all(|(v, (lo, hi))| lo <= v && v <= hi)
        })
    }

    /// A uniformly random configuration within the limits; joints without limits (or
    /// with an infinite side) draw from the finite part of `(−π, π)` ∪ their limits.
    pub fn random_configuration(&self, rng: &mut impl rand::Rng) -> Vec<f64> {
        let pi = std::f64::consts::PI;
        (0..self.dof())
            .map(|i| {
                let (lo, hi) = self
                    .limits
                    .as_ref()
                    .map_or((-pi, pi), |l| (l.lower[i], l.upper[i]));
                let (lo, hi) = match (lo.is_finite(), hi.is_finite()) {
                    (true, true) => (lo, hi),
                    (true, false) => (lo, lo + 2.0 * pi),
                    (false, true) => (hi - 2.0 * pi, hi),
                    (false, false) => (-pi, pi),
                };
                rng.random_range(lo..hi)
            })
            .collect()
    }

    /// Walks the chain, calling `frame(i, axis_frame)` with the world frame whose z axis is
    /// joint i's axis (after the joint's rotation), and returns the tool transform.
    /// Walks the chain joint by joint, calling `frame(i, axis_frame)` with the world frame
    /// whose z axis is joint i's axis (after the joint's rotation), and returns the tool
    /// transform. Runtime dispatch: compiled for AVX2+FMA and AVX-512 too, the best the
    /// processor has runs.
    #[inline(always)]
    fn walk(&self, q: &[f64], frame: impl FnMut(usize, &Affine)) -> Affine {
        struct Walk<'a, F> {
            chain: &'a SerialChain,
            q: &'a [f64],
            frame: F,
        }
        impl<F: FnMut(usize, &Affine)> WithSimd for Walk<'_, F> {
            type Output = Affine;
            #[inline(always)]
            fn with_simd<S: Simd>(self, _simd: S) -> Affine {
                if S::IS_SCALAR {
                    self.chain.walk_with::<false>(self.q, self.frame)
                } else {
                    self.chain.walk_with::<true>(self.q, self.frame)
                }
            }
        }
        Arch::new().dispatch(Walk {
            chain: self,
            q,
            frame,
        })
    }

    /// The tool transform alone: every joint's factor `F_i · Rz(q_i)` is independent, so
    /// they are multiplied as a balanced tree (depth ⌈log₂ n⌉ instead of n dependent
    /// products), which is what makes forward kinematics latency-cheap.
    #[inline(always)]
    fn tool_transform(&self, q: &[f64]) -> Affine {
        struct Tool<'a> {
            chain: &'a SerialChain,
            q: &'a [f64],
        }
        impl WithSimd for Tool<'_> {
            type Output = Affine;
            #[inline(always)]
            fn with_simd<S: Simd>(self, _simd: S) -> Affine {
                if S::IS_SCALAR {
                    self.chain.tree_with::<false>(self.q)
                } else {
                    self.chain.tree_with::<true>(self.q)
                }
            }
        }
        Arch::new().dispatch(Tool { chain: self, q })
    }

    /// Sines and cosines of `q + offset`, into `s` and `c` (`a` is scratch), all of the
    /// chain's length.
    #[inline(always)]
    fn angles<const FMA: bool>(&self, q: &[f64], a: &mut [f64], s: &mut [f64], c: &mut [f64]) {
        for ((a, &qi), &off) in a.iter_mut().zip(q).zip(&self.offsets) {
            *a = qi + off;
        }
        sin_cos_batch::<FMA>(a, s, c);
    }

    #[inline(always)]
    fn walk_with<const FMA: bool>(
        &self,
        q: &[f64],
        mut frame: impl FnMut(usize, &Affine),
    ) -> Affine {
        let n = self.dof();
        let mut stack = [[0.0; STACK_JOINTS]; 3];
        let mut heap = Vec::new();
        let [a, s, c] = scratch(n, &mut stack, &mut heap);
        self.angles::<FMA>(q, a, s, c);
        let mut t = self.fixed[0].rot_z::<FMA>((s[0], c[0]));
        frame(0, &t);
        for i in 1..n {
            t = t.mul_f::<FMA>(&self.fixed[i]).rot_z::<FMA>((s[i], c[i]));
            frame(i, &t);
        }
        t.mul_f::<FMA>(&self.tail)
    }

    #[inline(always)]
    fn tree_with<const FMA: bool>(&self, q: &[f64]) -> Affine {
        let n = self.dof();
        let mut stack = [[0.0; STACK_JOINTS]; 3];
        let mut heap = Vec::new();
        let [a, s, c] = scratch(n, &mut stack, &mut heap);
        self.angles::<FMA>(q, a, s, c);
        // Arms up to 7 joints (with the tail, 8 factors) stay on the stack.
        let mut stack_m = [Affine::IDENTITY; 8];
        let mut heap_m = Vec::new();
        let m: &mut [Affine] = if n < 8 {
            &mut stack_m[..n + 1]
        } else {
            heap_m.resize(n + 1, Affine::IDENTITY);
            &mut heap_m
        };
        for i in 0..n {
            m[i] = self.fixed[i].rot_z::<FMA>((s[i], c[i]));
        }
        m[n] = self.tail;
        let mut len = n + 1;
        while len > 1 {
            let half = len / 2;
            for j in 0..half {
                m[j] = m[2 * j].mul_f::<FMA>(&m[2 * j + 1]);
            }
            if len % 2 == 1 {
                m[half] = m[len - 1];
            }
            len = len.div_ceil(2);
        }
        m[0]
    }

    /// The tool pose and the 6 × n Jacobian, column-major in `cols` (column i is
    /// `cols[6 i .. 6 i + 6]`, rows as in [`SerialChain::jacobian`]), from one walk without
    /// allocating. `q` must be checked by the caller.
    pub(crate) fn pose_and_jacobian(&self, q: &[f64], cols: &mut [f64]) -> IsometryMatrix3<f64> {
        let mut origins = [[0.0; 3]; STACK_JOINTS];
        let mut heap = Vec::new();
        let store: &mut [[f64; 3]] = if q.len() <= STACK_JOINTS {
            &mut origins[..q.len()]
        } else {
            heap.resize(q.len(), [0.0; 3]);
            &mut heap
        };
        let tool = self.walk(q, |i, f| {
            for k in 0..3 {
                cols[6 * i + k + 3] = f.r(k, 2);
            }
            store[i] = f.t();
        });
        let tt = tool.t();
        for (col, o) in cols.chunks_exact_mut(6).zip(store.iter()) {
            let r = [tt[0] - o[0], tt[1] - o[1], tt[2] - o[2]];
            let z = [col[3], col[4], col[5]];
            col[0] = z[1] * r[2] - z[2] * r[1];
            col[1] = z[2] * r[0] - z[0] * r[2];
            col[2] = z[0] * r[1] - z[1] * r[0];
        }
        tool.to_isometry()
    }

    /// The tool pose for a checked `q`.
    pub(crate) fn fk_unchecked(&self, q: &[f64]) -> IsometryMatrix3<f64> {
        self.tool_transform(q).to_isometry()
    }

    /// The world pose of the tool point at joint angles `q` (radians), with its rotation
    /// as a matrix (`IsometryMatrix3`; convert with `UnitQuaternion::from_rotation_matrix`
    /// when a quaternion is wanted).
    pub fn fk(&self, q: &[f64]) -> Result<IsometryMatrix3<f64>, KinematicsError> {
        self.check(q)?;
        Ok(self.tool_transform(q).to_isometry())
    }

    /// The tool pose as a 4×4 homogeneous matrix (row-major as printed, metres).
    pub fn fk_matrix(&self, q: &[f64]) -> Result<Matrix4<f64>, KinematicsError> {
        self.check(q)?;
        Ok(self.tool_transform(q).to_matrix4())
    }

    /// The tool pose and every link frame.
    pub fn fk_frames(&self, q: &[f64]) -> Result<ChainPose, KinematicsError> {
        self.check(q)?;
        let mut frames = Vec::with_capacity(self.dof());
        let tool = self.walk(q, |i, f| frames.push(f.mul(&self.post[i]).to_isometry()));
        Ok(ChainPose {
            link_frames: frames,
            tool: tool.to_isometry(),
        })
    }

    /// The base and every link frame as world poses, written into `out`: `out[0]` the base
    /// (a collision model's frame 0), `out[k]` the link joint `k` moves ([`Self::fk_frames`]'s
    /// `link_frames[k − 1]`). Nothing is allocated once `out` has room for `dof + 1`: what a
    /// collision check takes at every sample of a plan.
    pub fn frames_into(
        &self,
        q: &[f64],
        out: &mut Vec<Isometry3<f64>>,
    ) -> Result<(), KinematicsError> {
        self.check(q)?;
        out.clear();
        out.push(self.base());
        self.walk(q, |i, f| {
            let m = f.mul(&self.post[i]).to_isometry();
            out.push(Isometry3::from_parts(
                m.translation,
                UnitQuaternion::from_rotation_matrix(&m.rotation),
            ));
        });
        Ok(())
    }

    /// [`Self::frames_into`], and each joint's axis in the world into `axes` (`axes[k]` joint
    /// `k + 1`'s: a point on it and its unit direction), from one walk along the chain:
    /// what bounds how far a body can move when the joints turn (a point `D` from an axis
    /// moves at most `D |δ|` when it turns by `δ`). Nothing is allocated once both have room.
    pub fn frames_axes_into(
        &self,
        q: &[f64],
        out: &mut Vec<Isometry3<f64>>,
        axes: &mut Vec<(Vector3<f64>, Vector3<f64>)>,
    ) -> Result<(), KinematicsError> {
        self.check(q)?;
        out.clear();
        axes.clear();
        out.push(self.base());
        self.walk(q, |i, f| {
            let joint = f.to_isometry();
            axes.push((
                joint.translation.vector,
                joint.rotation.matrix().column(2).into_owned(),
            ));
            let m = f.mul(&self.post[i]).to_isometry();
            out.push(Isometry3::from_parts(
                m.translation,
                UnitQuaternion::from_rotation_matrix(&m.rotation),
            ));
        });
        Ok(())
    }

    /// The chain as URDF-style joints that all turn about their own z axis, for writing
    /// it out (viewers, ROS 2): `(base, joints, tail)` with `base` the world → robot-base
    /// transform, joint i's `origin` the fixed transform from joint i−1's rotating frame
    /// (the robot base for the first) to joint i's, its angle offset folded in (so the
    /// joint turns by `q_i` itself: `offset` is 0), and `tail` from the last joint's
    /// rotating frame to the tool point. `base · Π(origin_i · Rz(q_i)) · tail` is [`Self::fk`].
    pub fn axis_joints(&self) -> (Isometry3<f64>, Vec<RevoluteJoint>, Isometry3<f64>) {
        let joints = self
            .fixed
            .iter()
            .zip(&self.offsets)
            .enumerate()
            .map(|(i, (f, off))| {
                let f = if i == 0 { self.pre0 } else { *f };
                let (s, c) = off.sin_cos();
                RevoluteJoint {
                    origin: f.rot_z::<false>((s, c)).to_isometry3(),
                    axis: Vector3::z_axis(),
                    offset: 0.0,
                }
            })
            .collect();
        (self.base.to_isometry3(), joints, self.tail.to_isometry3())
    }

    /// Per joint, in the world frame: the point its axis passes through, the axis, and the
    /// pose of the link it moves (the frame of [`Self::fk_frames`]), for inverse dynamics.
    pub(crate) fn joint_axes(&self, q: &[f64]) -> Result<Vec<JointAxis>, KinematicsError> {
        self.check(q)?;
        let mut out = Vec::with_capacity(self.dof());
        self.walk(q, |i, f| {
            let rotation = f.to_isometry();
            out.push(JointAxis {
                point: rotation.translation.vector,
                axis: rotation.rotation.matrix().column(2).into_owned(),
                link: f.mul(&self.post[i]).to_isometry(),
            });
        });
        Ok(out)
    }

    /// The geometric Jacobian of the tool point in the world frame, 6 × n: rows
    /// `[vx, vy, vz, ωx, ωy, ωz]` (linear velocity of the tool point, angular velocity),
    /// column i for joint i: `(z_i × (p_tool − p_i), z_i)` with `z_i` the joint's axis and
    /// `p_i` a point on it.
    pub fn jacobian(&self, q: &[f64]) -> Result<OMatrix<f64, U6, nalgebra::Dyn>, KinematicsError> {
        self.check(q)?;
        let mut j = OMatrix::<f64, U6, nalgebra::Dyn>::zeros(self.dof());
        self.pose_and_jacobian(q, j.as_mut_slice());
        Ok(j)
    }

    /// The position part of the geometric Jacobian, 3 × n (the rows the thesis used).
    pub fn jacobian_position(
        &self,
        q: &[f64],
    ) -> Result<OMatrix<f64, nalgebra::U3, nalgebra::Dyn>, KinematicsError> {
        Ok(self.jacobian(q)?.fixed_rows::<3>(0).into_owned())
    }

    /// Yoshikawa's manipulability `√det(J Jᵀ)` of the full 6 × n Jacobian (0 at a
    /// singularity and for chains with fewer than 6 joints).
    pub fn manipulability(&self, q: &[f64]) -> Result<f64, KinematicsError> {
        let j = self.jacobian(q)?;
        Ok((j.clone() * j.transpose()).determinant().max(0.0).sqrt())
    }
}
