//! Box bounds by a boundary transformation (Hansen's "BoundTransform", as in pycma).
//!
//! CMA-ES keeps searching the unbounded space; every candidate `x` is mapped into the box
//! `[lb, ub]` before it is evaluated, coordinate by coordinate:
//!
//! 1. with `a_l = min((ub − lb)/2, (1 + |lb|)/20)` and `a_u = min((ub − lb)/2, (1 + |ub|)/20)`,
//!    `x` is shifted by a multiple of the period `2 (ub − lb + a_l + a_u)` and mirrored at
//!    `lb − a_l` and `ub + a_u` into `[lb − a_l, ub + a_u]`;
//! 2. there it is mapped to `lb + (x − lb + a_l)² / (4 a_l)` below `lb + a_l`, to itself in
//!    the interior `[lb + a_l, ub − a_u]`, and to `ub − (x − ub − a_u)² / (4 a_u)` above
//!    `ub − a_u`.
//!
//! The map is the identity inside the box's interior, continuous and once differentiable,
//! and reaches the bounds themselves, so an optimum on a bound is found exactly. A side
//! with an infinite bound is left open (no shifting; only the finite side is bent).

use crate::CmaesError;

/// Lower and upper bounds per coordinate, with the transformation's margins. With the
/// `serde` feature it (de)serialises as `{ lower, upper }`, checked on reading.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(try_from = "BoundsRecord", into = "BoundsRecord")
)]
pub struct Bounds {
    lower: Vec<f64>,
    upper: Vec<f64>,
    al: Vec<f64>,
    au: Vec<f64>,
}

impl Bounds {
    /// Bounds `lower[i] < upper[i]` (either may be infinite, none NaN).
    pub fn new(lower: Vec<f64>, upper: Vec<f64>) -> Result<Self, CmaesError> {
        if lower.len() != upper.len() {
            return Err(CmaesError::DimensionMismatch {
                what: "upper bounds",
                got: upper.len(),
                expected: lower.len(),
            });
        }
        for (&l, &u) in lower.iter().zip(&upper) {
            if l.is_nan() || u.is_nan() || l >= u || l == f64::INFINITY || u == f64::NEG_INFINITY {
                return Err(CmaesError::InvalidConfig {
                    field: "bounds",
                    rule: "need lower < upper in every coordinate (no NaN)",
                    value: if l.is_nan() { l } else { u - l },
                });
            }
        }
        let margin = |b: f64, l: f64, u: f64| {
            let half = (u - l) / 2.0;
            if b.is_finite() {
                half.min((1.0 + b.abs()) / 20.0)
            } else {
                1.0
            }
        };
        let al = lower
            .iter()
            .zip(&upper)
            .map(|(&l, &u)| margin(l, l, u))
            .collect();
        let au = lower
            .iter()
            .zip(&upper)
            .map(|(&l, &u)| margin(u, l, u))
            .collect();
        Ok(Self {
            lower,
            upper,
            al,
            au,
        })
    }

    /// Number of coordinates.
    pub fn len(&self) -> usize {
        self.lower.len()
    }

    /// True if there are no coordinates.
    pub fn is_empty(&self) -> bool {
        self.lower.is_empty()
    }

    /// The lower bounds.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }

    /// The upper bounds.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }

    /// True if `y` lies in the box.
    pub fn contains(&self, y: &[f64]) -> bool {
        y.len() == self.len()
            && y.iter()
                .zip(self.lower.iter().zip(&self.upper))
                .all(|(&v, (&l, &u))| v >= l && v <= u)
    }

    fn one(&self, i: usize, x: f64) -> f64 {
        let (lb, ub, al, au) = (self.lower[i], self.upper[i], self.al[i], self.au[i]);
        let mut x = x;
        if lb.is_finite() && ub.is_finite() {
            let width = ub - lb;
            let (low, high) = (lb - 2.0 * al - width / 2.0, ub + 2.0 * au + width / 2.0);
            if x < low || x > high {
                let period = 2.0 * (width + al + au);
                x -= period * ((x - low) / period).floor();
            }
        }
        if ub.is_finite() && x > ub + au {
            x -= 2.0 * (x - ub - au);
        }
        if lb.is_finite() && x < lb - al {
            x += 2.0 * (lb - al - x);
        }
        // Mirroring at one bound may cross the other only for an open side, which the
        // checks above leave alone; the result is within [lb − al, ub + au].
        if lb.is_finite() && x < lb + al {
            lb + (x - (lb - al)).powi(2) / (4.0 * al)
        } else if ub.is_finite() && x > ub - au {
            ub - (x - (ub + au)).powi(2) / (4.0 * au)
        } else {
            x
        }
    }

    /// Maps a candidate into the box (see the module documentation).
    ///
    /// # Panics
    /// If the lengths differ from [`Bounds::len`].
    pub fn transform(&self, x: &[f64], out: &mut [f64]) {
        assert!(x.len() == self.len() && out.len() == self.len());
        for (i, (o, &v)) in out.iter_mut().zip(x).enumerate() {
            *o = self.one(i, v);
        }
    }

    /// A point of the unbounded space that [`Bounds::transform`] maps to `y` (inside the
    /// box), for starting the search at `y`.
    ///
    /// # Panics
    /// If the lengths differ from [`Bounds::len`].
    pub fn inverse(&self, y: &[f64], out: &mut [f64]) -> Result<(), CmaesError> {
        assert!(y.len() == self.len() && out.len() == self.len());
        if !self.contains(y) {
            return Err(CmaesError::InvalidConfig {
                field: "x0",
                rule: "must lie within the bounds",
                value: y
                    .iter()
                    .zip(self.lower.iter().zip(&self.upper))
                    .find(|(v, (l, u))| !(**v >= **l && **v <= **u))
                    .map_or(f64::NAN, |(v, _)| *v),
            });
        }
        for i in 0..self.len() {
            let (lb, ub, al, au, v) = (self.lower[i], self.upper[i], self.al[i], self.au[i], y[i]);
            out[i] = if lb.is_finite() && v < lb + al {
                (lb - al) + 2.0 * (al * (v - lb)).sqrt()
            } else if ub.is_finite() && v > ub - au {
                (ub + au) - 2.0 * (au * (ub - v)).sqrt()
            } else {
                v
            };
        }
        Ok(())
    }
}

/// The serialised form of [`Bounds`].
#[cfg(feature = "serde")]
#[derive(serde::Serialize, serde::Deserialize)]
struct BoundsRecord {
    lower: Vec<f64>,
    upper: Vec<f64>,
}

#[cfg(feature = "serde")]
impl From<Bounds> for BoundsRecord {
    fn from(b: Bounds) -> Self {
        Self {
            lower: b.lower,
            upper: b.upper,
        }
    }
}

#[cfg(feature = "serde")]
impl TryFrom<BoundsRecord> for Bounds {
    type Error = CmaesError;

    fn try_from(r: BoundsRecord) -> Result<Self, CmaesError> {
        Bounds::new(r.lower, r.upper)
    }
}
