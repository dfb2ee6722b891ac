//! A joint path through sampled positions: one C² cubic spline per joint (continuous
//! position, slope and curvature), with one of two end conditions:
//!
//! - [`Ends::Clamped`], zero slope at both ends: on a time axis, a trajectory that starts
//!   and ends at rest (how trajectory files are resampled at the control rate); it
//!   reproduces any cubic with zero end slopes exactly.
//! - [`Ends::Natural`], zero curvature at both ends: on an arc-length axis, a geometric
//!   path whose tangent never vanishes (what retiming needs); it reproduces straight lines
//!   exactly.

use crate::KinematicsError;

/// The condition at both ends of a [`JointSpline`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ends {
    /// Zero first derivative.
    Clamped,
    /// Zero second derivative.
    Natural,
}

/// Cubic splines through `(knots[k], points[k][j])`, one per joint `j`.
#[derive(Debug, Clone)]
pub struct JointSpline {
    knots: Vec<f64>,
    /// Per joint: the positions at the knots.
    y: Vec<Vec<f64>>,
    /// Per joint: the second derivatives at the knots.
    m: Vec<Vec<f64>>,
}

/// Position and its first three derivatives of every joint at one parameter value.
#[derive(Debug, Clone, PartialEq)]
pub struct PathPoint {
    /// q(s).
    pub q: Vec<f64>,
    /// dq/ds.
    pub d1: Vec<f64>,
    /// d²q/ds².
    pub d2: Vec<f64>,
    /// d³q/ds³ (piecewise constant).
    pub d3: Vec<f64>,
}

impl JointSpline {
    /// The clamped splines through `points` (one row of joint values per knot) at the
    /// strictly increasing, finite `knots` (at least two).
    pub fn new(knots: &[f64], points: &[Vec<f64>]) -> Result<Self, KinematicsError> {
        Self::with_ends(knots, points, Ends::Clamped)
    }

    /// The splines through `points` at `knots` with the given end condition.
    pub fn with_ends(
        knots: &[f64],
        points: &[Vec<f64>],
        ends: Ends,
    ) -> Result<Self, KinematicsError> {
        if knots.len() < 2 || knots.len() != points.len() {
            return Err(KinematicsError::InvalidModel(format!(
                "a joint path needs at least two knots with one row of positions each (got {} knots, {} rows)",
                knots.len(),
                points.len()
            )));
        }
        if let Some(k) = knots.windows(2).position(|w| {
            w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater)
                || !w[0].is_finite()
                || !w[1].is_finite()
        }) {
            return Err(KinematicsError::InvalidModel(format!(
                "the path's knots must be finite and strictly increasing (knot {} is {}, knot {} is {})",
                k + 1,
                knots[k],
                k + 2,
                knots[k + 1]
            )));
        }
        let dof = points[0].len();
        if let Some(k) = points.iter().position(|r| r.len() != dof) {
            return Err(KinematicsError::JointCount {
                expected: dof,
                got: points[k].len(),
            });
        }
        let y: Vec<Vec<f64>> = (0..dof)
            .map(|j| points.iter().map(|r| r[j]).collect())
            .collect();
        let m = y
            .iter()
            .map(|col| match ends {
                Ends::Clamped => clamped_second_derivatives(knots, col),
                Ends::Natural => natural_second_derivatives(knots, col),
            })
            .collect();
        Ok(JointSpline {
            knots: knots.to_vec(),
            y,
            m,
        })
    }

    /// The first and last knot.
    pub fn span(&self) -> (f64, f64) {
        (self.knots[0], self.knots[self.knots.len() - 1])
    }

    /// Joints.
    pub fn dof(&self) -> usize {
        self.y.len()
    }

    /// The segment holding `s` (clamped to the span) and the local coordinates.
    fn locate(&self, s: f64) -> (usize, f64, f64, f64) {
        let t = &self.knots;
        let s = s.clamp(t[0], t[t.len() - 1]);
        let i = match t.partition_point(|&ti| ti <= s) {
            0 => 0,
            k => (k - 1).min(t.len() - 2),
        };
        let h = t[i + 1] - t[i];
        (i, h, (t[i + 1] - s) / h, (s - t[i]) / h)
    }

    /// Positions at `s` (clamped to the span) into `q`.
    pub fn positions_into(&self, s: f64, q: &mut [f64]) {
        let (i, h, a, b) = self.locate(s);
        for ((out, y), m) in q.iter_mut().zip(&self.y).zip(&self.m) {
            *out = a * y[i]
                + b * y[i + 1]
                + ((a * a * a - a) * m[i] + (b * b * b - b) * m[i + 1]) * h * h / 6.0;
        }
    }

    /// Positions at `s` (clamped to the span).
    pub fn positions(&self, s: f64) -> Vec<f64> {
        let mut q = vec![0.0; self.dof()];
        self.positions_into(s, &mut q);
        q
    }

    /// Positions and their first three derivatives at `s` (clamped to the span; the
    /// derivatives are those of the end segment there).
    pub fn point(&self, s: f64) -> PathPoint {
        let n = self.dof();
        let mut p = PathPoint {
            q: vec![0.0; n],
            d1: vec![0.0; n],
            d2: vec![0.0; n],
            d3: vec![0.0; n],
        };
        self.point_into(s, &mut p);
        p
    }

    /// [`Self::point`] into `p`, whose vectors have one entry per joint.
    pub fn point_into(&self, s: f64, p: &mut PathPoint) {
        let located = self.locate(s);
        self.eval(located, p);
    }

    /// [`Self::point_into`] for parameters visited in increasing order: the segment is
    /// searched from `hint` (the previous call's) onwards.
    pub(crate) fn point_after(&self, s: f64, p: &mut PathPoint, hint: &mut usize) {
        let t = &self.knots;
        let s = s.clamp(t[0], t[t.len() - 1]);
        let last = t.len() - 2;
        if *hint > last || t[*hint] > s {
            *hint = self.locate(s).0;
        }
        while *hint < last && t[*hint + 1] <= s {
            *hint += 1;
        }
        let i = *hint;
        let h = t[i + 1] - t[i];
        self.eval((i, h, (t[i + 1] - s) / h, (s - t[i]) / h), p);
    }

    fn eval(&self, (i, h, a, b): (usize, f64, f64, f64), p: &mut PathPoint) {
        for (j, (y, m)) in self.y.iter().zip(&self.m).enumerate() {
            let (m0, m1) = (m[i], m[i + 1]);
            p.q[j] = a * y[i]
                + b * y[i + 1]
                + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
            p.d1[j] = (y[i + 1] - y[i]) / h
                + ((1.0 - 3.0 * a * a) * m0 + (3.0 * b * b - 1.0) * m1) * h / 6.0;
            p.d2[j] = a * m0 + b * m1;
            p.d3[j] = (m1 - m0) / h;
        }
    }
}

/// Second derivatives at the knots of the cubic spline through `(t, y)` with zero slope at
/// both ends.
fn clamped_second_derivatives(t: &[f64], y: &[f64]) -> Vec<f64> {
    let n = t.len();
    let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let (mut lower, mut diag, mut upper, mut rhs) = interior_rows(t, y);
    diag[0] = 2.0 * h[0];
    upper[0] = h[0];
    rhs[0] = 6.0 * ((y[1] - y[0]) / h[0]);
    lower[n - 1] = h[n - 2];
    diag[n - 1] = 2.0 * h[n - 2];
    rhs[n - 1] = -6.0 * ((y[n - 1] - y[n - 2]) / h[n - 2]);
    thomas(lower, diag, upper, rhs)
}

/// Second derivatives at the knots of the cubic spline through `(t, y)` with zero second
/// derivative at both ends.
fn natural_second_derivatives(t: &[f64], y: &[f64]) -> Vec<f64> {
    let n = t.len();
    let (lower, mut diag, upper, rhs) = interior_rows(t, y);
    diag[0] = 1.0;
    diag[n - 1] = 1.0;
    thomas(lower, diag, upper, rhs)
}

/// The continuity equations of the interior knots (rows 1 … n−2 of the tridiagonal
/// system for the second derivatives; the end rows are left zero).
#[allow(clippy::type_complexity)]
fn interior_rows(t: &[f64], y: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = t.len();
    let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let (mut lower, mut diag, mut upper, mut rhs) =
        (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for i in 1..n - 1 {
        lower[i] = h[i - 1];
        diag[i] = 2.0 * (h[i - 1] + h[i]);
        upper[i] = h[i];
        rhs[i] = 6.0 * ((y[i + 1] - y[i]) / h[i] - (y[i] - y[i - 1]) / h[i - 1]);
    }
    (lower, diag, upper, rhs)
}

/// Solves a tridiagonal system (the Thomas algorithm; the spline systems are diagonally
/// dominant, so no pivoting is needed).
fn thomas(lower: Vec<f64>, mut diag: Vec<f64>, upper: Vec<f64>, mut rhs: Vec<f64>) -> Vec<f64> {
    let n = diag.len();
    for i in 1..n {
        let w = lower[i] / diag[i - 1];
        diag[i] -= w * upper[i - 1];
        rhs[i] -= w * rhs[i - 1];
    }
    let mut m = vec![0.0; n];
    m[n - 1] = rhs[n - 1] / diag[n - 1];
    for i in (0..n - 1).rev() {
        m[i] = (rhs[i] - upper[i] * m[i + 1]) / diag[i];
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_starts_and_ends_at_rest_and_reproduces_clamped_cubics() {
        let t: Vec<f64> = (0..11).map(|k| k as f64 * 0.1).collect();
        let rows: Vec<Vec<f64>> = t
            .iter()
            .map(|x| vec![(3.0 * x).sin(), 3.0 * x * x - 2.0 * x * x * x])
            .collect();
        let s = JointSpline::new(&t, &rows).unwrap();
        for (ti, r) in t.iter().zip(&rows) {
            let q = s.positions(*ti);
            assert!((q[0] - r[0]).abs() < 1e-12 && (q[1] - r[1]).abs() < 1e-12);
        }
        assert!(s.point(0.0).d1.iter().all(|v| v.abs() < 1e-12));
        assert!(s.point(1.0).d1.iter().all(|v| v.abs() < 1e-12));
        // y = 3x² − 2x³ has zero end slopes: reproduced with its derivatives.
        for k in 0..100 {
            let x = k as f64 * 0.0101;
            let p = s.point(x);
            assert!((p.q[1] - (3.0 * x * x - 2.0 * x * x * x)).abs() < 1e-12);
            assert!((p.d1[1] - (6.0 * x - 6.0 * x * x)).abs() < 1e-10);
            assert!((p.d2[1] - (6.0 - 12.0 * x)).abs() < 1e-9);
            assert!((p.d3[1] + 12.0).abs() < 1e-8);
        }
    }

    #[test]
    fn natural_ends_have_no_curvature_and_keep_straight_lines() {
        let t = [0.0, 0.5, 1.7, 2.0, 3.1];
        let rows: Vec<Vec<f64>> = t.iter().map(|x| vec![1.0 - 2.0 * x, x * x]).collect();
        let s = JointSpline::with_ends(&t, &rows, Ends::Natural).unwrap();
        for x in [0.0, 0.3, 1.1, 2.5, 3.1] {
            let p = s.point(x);
            assert!((p.q[0] - (1.0 - 2.0 * x)).abs() < 1e-12 && (p.d1[0] + 2.0).abs() < 1e-12);
        }
        assert!(s.point(0.0).d2[1].abs() < 1e-12 && s.point(3.1).d2[1].abs() < 1e-12);
        for (x, r) in t.iter().zip(&rows) {
            assert!((s.positions(*x)[1] - r[1]).abs() < 1e-12);
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let t = [0.0, 0.3, 0.5, 1.2, 1.3, 2.0];
        let rows: Vec<Vec<f64>> = t.iter().map(|x: &f64| vec![x.cos() * 2.0]).collect();
        let s = JointSpline::new(&t, &rows).unwrap();
        let h = 1e-6;
        for k in 1..40 {
            let x = k as f64 * 0.049;
            let (p, lo, hi) = (s.point(x), s.point(x - h), s.point(x + h));
            assert!(((hi.q[0] - lo.q[0]) / (2.0 * h) - p.d1[0]).abs() < 1e-6);
            assert!(((hi.d1[0] - lo.d1[0]) / (2.0 * h) - p.d2[0]).abs() < 1e-5);
        }
    }

    #[test]
    fn bad_knots_are_named() {
        let rows = vec![vec![0.0]; 3];
        let e = JointSpline::new(&[0.0, 0.2, 0.2], &rows).unwrap_err();
        assert!(
            e.to_string().contains("knot 2 is 0.2, knot 3 is 0.2"),
            "{e}"
        );
        assert!(JointSpline::new(&[0.0], &rows[..1]).is_err());
    }
}
