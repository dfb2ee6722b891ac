//! Rigid transforms and the best rigid fit of point sets: Horn's closed form (1987), the
//! rotation as the unit quaternion that is the leading eigenvector of a 4 × 4 symmetric
//! matrix built from the points' cross-covariance — always a proper rotation, never a
//! reflection — found by cyclic Jacobi rotations.

/// A point or vector, metres unless said otherwise.
pub type Vec3 = [f64; 3];
/// A 3 × 3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// The identity matrix.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// A rigid transform `p ↦ R·p + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    /// The rotation `R`.
    pub rotation: Mat3,
    /// The translation `t`.
    pub translation: Vec3,
}

impl Default for Rigid {
    fn default() -> Self {
        Self {
            rotation: IDENTITY,
            translation: [0.0; 3],
        }
    }
}

impl Rigid {
    /// Applies the transform to a point.
    pub fn apply(&self, p: Vec3) -> Vec3 {
        add(mul(&self.rotation, p), self.translation)
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn then_after(&self, other: &Rigid) -> Rigid {
        Rigid {
            rotation: matmul(&self.rotation, &other.rotation),
            translation: self.apply(other.translation),
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Rigid {
        let rt = transpose(&self.rotation);
        Rigid {
            rotation: rt,
            translation: scale(mul(&rt, self.translation), -1.0),
        }
    }
}

/// `a + b`.
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
/// `a − b`.
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
/// `s·a`.
pub fn scale(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
/// `a·b`.
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// `a × b`.
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
/// `|a|`.
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}
/// `M·v`.
pub fn mul(m: &Mat3, v: Vec3) -> Vec3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}
/// `A·B`.
pub fn matmul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}
/// `Mᵀ`.
pub fn transpose(m: &Mat3) -> Mat3 {
    [
        [m[0][0], m[1][0], m[2][0]],
        [m[0][1], m[1][1], m[2][1]],
        [m[0][2], m[1][2], m[2][2]],
    ]
}

/// The rotation of a unit quaternion `[x, y, z, w]`.
pub fn rotation_of(q: [f64; 4]) -> Mat3 {
    let [x, y, z, w] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// The unit quaternion `[x, y, z, w]` (w ≥ 0) of a rotation matrix (Shepperd's method:
/// the largest of the four squared components first, for accuracy).
pub fn quaternion_of(m: &Mat3) -> [f64; 4] {
    let tr = m[0][0] + m[1][1] + m[2][2];
    let q = if tr >= m[0][0].max(m[1][1]).max(m[2][2]) {
        let w = (1.0 + tr).max(0.0).sqrt() / 2.0;
        let k = 0.25 / w;
        [
            (m[2][1] - m[1][2]) * k,
            (m[0][2] - m[2][0]) * k,
            (m[1][0] - m[0][1]) * k,
            w,
        ]
    } else if m[0][0] >= m[1][1] && m[0][0] >= m[2][2] {
        let x = (1.0 + 2.0 * m[0][0] - tr).max(0.0).sqrt() / 2.0;
        let k = 0.25 / x;
        [
            x,
            (m[0][1] + m[1][0]) * k,
            (m[0][2] + m[2][0]) * k,
            (m[2][1] - m[1][2]) * k,
        ]
    } else if m[1][1] >= m[2][2] {
        let y = (1.0 + 2.0 * m[1][1] - tr).max(0.0).sqrt() / 2.0;
        let k = 0.25 / y;
        [
            (m[0][1] + m[1][0]) * k,
            y,
            (m[1][2] + m[2][1]) * k,
            (m[0][2] - m[2][0]) * k,
        ]
    } else {
        let z = (1.0 + 2.0 * m[2][2] - tr).max(0.0).sqrt() / 2.0;
        let k = 0.25 / z;
        [
            (m[0][2] + m[2][0]) * k,
            (m[1][2] + m[2][1]) * k,
            z,
            (m[1][0] - m[0][1]) * k,
        ]
    };
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let s = if q[3] < 0.0 { -1.0 / n } else { 1.0 / n };
    q.map(|v| v * s)
}

/// The angle of the rotation taking `a` to `b`, radians.
pub fn angle_between(a: &Mat3, b: &Mat3) -> f64 {
    let r = matmul(&transpose(a), b);
    let c = ((r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0).clamp(-1.0, 1.0);
    // acos loses accuracy near 0: use the skew part's size there.
    let s = norm([r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]]) / 2.0;
    s.atan2(c)
}

/// The eigenvalues and eigenvectors (columns of the second) of a symmetric matrix, by
/// cyclic Jacobi rotations.
#[allow(clippy::needless_range_loop)] // the rotations index rows and columns by p, q, k
pub fn symmetric_eigen<const N: usize>(mut a: [[f64; N]; N]) -> ([f64; N], [[f64; N]; N]) {
    let mut v = [[0.0; N]; N];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    let scale: f64 = a.iter().flatten().map(|x| x * x).sum::<f64>();
    for _sweep in 0..64 {
        let mut off = 0.0;
        for p in 0..N {
            for q in p + 1..N {
                off += a[p][q] * a[p][q];
            }
        }
        if off <= scale * 1e-32 || off == 0.0 {
            break;
        }
        for p in 0..N {
            for q in p + 1..N {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for row in a.iter_mut() {
                    let (kp, kq) = (row[p], row[q]);
                    row[p] = c * kp - s * kq;
                    row[q] = s * kp + c * kq;
                }
                for k in 0..N {
                    let (pk, qk) = (a[p][k], a[q][k]);
                    a[p][k] = c * pk - s * qk;
                    a[q][k] = s * pk + c * qk;
                }
                for row in v.iter_mut() {
                    let (kp, kq) = (row[p], row[q]);
                    row[p] = c * kp - s * kq;
                    row[q] = s * kp + c * kq;
                }
            }
        }
    }
    let mut values = [0.0; N];
    for (i, x) in values.iter_mut().enumerate() {
        *x = a[i][i];
    }
    (values, v)
}

/// The mean of points.
pub fn centroid(points: &[Vec3]) -> Vec3 {
    let n = points.len().max(1) as f64;
    let s = points.iter().fold([0.0; 3], |s, p| add(s, *p));
    scale(s, 1.0 / n)
}

/// How far points are from lying on one line: the second principal spread over the
/// first (`√(λ₂/λ₁)` of their covariance); 0 for collinear points, ≈ 1 for a round cloud.
pub fn planarity(points: &[Vec3]) -> f64 {
    let c = centroid(points);
    let mut m = [[0.0; 3]; 3];
    for p in points {
        let d = sub(*p, c);
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += d[i] * d[j];
            }
        }
    }
    let (mut l, _) = symmetric_eigen(m);
    l.sort_by(|a, b| b.total_cmp(a));
    if l[0] <= 0.0 {
        return 0.0;
    }
    (l[1].max(0.0) / l[0]).sqrt()
}

/// The rigid transform that best maps `from` onto `to` (least squares over pairs) and the
/// RMS distance left; `None` with fewer than three pairs.
pub fn fit(from: &[Vec3], to: &[Vec3]) -> Option<(Rigid, f64)> {
    if from.len() != to.len() || from.len() < 3 {
        return None;
    }
    let (ca, cb) = (centroid(from), centroid(to));
    let mut s = [[0.0; 3]; 3];
    for (a, b) in from.iter().zip(to) {
        let (a, b) = (sub(*a, ca), sub(*b, cb));
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] += a[i] * b[j];
            }
        }
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    let n = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let (values, vectors) = symmetric_eigen(n);
    let best = (0..4).max_by(|&i, &j| values[i].total_cmp(&values[j]))?;
    let (w, x, y, z) = (
        vectors[0][best],
        vectors[1][best],
        vectors[2][best],
        vectors[3][best],
    );
    let len = (w * w + x * x + y * y + z * z).sqrt();
    let rotation = rotation_of([x / len, y / len, z / len, w / len]);
    let translation = sub(cb, mul(&rotation, ca));
    let t = Rigid {
        rotation,
        translation,
    };
    let sq: f64 = from
        .iter()
        .zip(to)
        .map(|(a, b)| {
            let d = sub(t.apply(*a), *b);
            dot(d, d)
        })
        .sum();
    Some((t, (sq / from.len() as f64).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rot(axis: Vec3, angle: f64) -> Mat3 {
        let n = norm(axis);
        let (s, c) = (angle / 2.0).sin_cos();
        rotation_of([axis[0] / n * s, axis[1] / n * s, axis[2] / n * s, c])
    }

    #[test]
    fn fit_recovers_a_known_transform_to_machine_precision() {
        let r = rot([0.3, -1.0, 0.4], 2.9);
        let t = [0.4, -1.2, 2.5];
        let truth = Rigid {
            rotation: r,
            translation: t,
        };
        let from = [
            [0.0, 0.0, 0.0],
            [0.1, 0.0, 0.02],
            [0.03, 0.08, -0.01],
            [0.05, 0.02, 0.07],
        ];
        let to: Vec<Vec3> = from.iter().map(|p| truth.apply(*p)).collect();
        let (got, rms) = fit(&from, &to).unwrap();
        assert!(rms < 1e-12, "{rms}");
        assert!(angle_between(&got.rotation, &r) < 1e-12);
        assert!(norm(sub(got.translation, t)) < 1e-12);
        // Three points are enough, and a half-turn (w = 0) is found too.
        let half = rot([0.0, 0.0, 1.0], std::f64::consts::PI);
        let to: Vec<Vec3> = from[..3].iter().map(|p| mul(&half, *p)).collect();
        let (got, _) = fit(&from[..3], &to).unwrap();
        assert!(angle_between(&got.rotation, &half) < 1e-12);
    }

    #[test]
    fn a_mirror_image_is_fitted_by_a_rotation_not_a_reflection() {
        let from = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let to: Vec<Vec3> = from.iter().map(|p| [p[0], p[1], -p[2]]).collect();
        let (got, rms) = fit(&from, &to).unwrap();
        let r = got.rotation;
        let det = dot(r[0], cross(r[1], r[2]));
        assert!((det - 1.0).abs() < 1e-12, "{det}");
        assert!(rms > 0.1);
    }

    #[test]
    fn quaternions_and_matrices_round_trip() {
        for (axis, angle) in [
            ([1.0, 2.0, 3.0], 0.3),
            ([0.0, 1.0, 0.0], 3.1),
            ([1.0, 0.0, 0.0], std::f64::consts::PI - 1e-6),
            ([0.2, 0.1, -1.0], 1e-9),
        ] {
            let m = rot(axis, angle);
            let back = rotation_of(quaternion_of(&m));
            assert!(angle_between(&m, &back) < 1e-12);
        }
    }

    #[test]
    fn collinear_points_have_no_planarity() {
        let line = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]];
        assert!(planarity(&line) < 1e-7);
        let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(planarity(&tri) > 0.5);
    }
}
