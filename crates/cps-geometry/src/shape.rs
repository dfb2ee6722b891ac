//! Convex shapes and the signed distance between two of them at their poses.
//!
//! Each shape is a core and a radius: a sphere is a point grown by its radius, a capsule a
//! segment grown by its radius; boxes, cylinders and hulls have none. GJK runs on the
//! cores and the radii are taken off after, which is exact and keeps the rounded shapes'
//! answers as sharp as the flat ones'.

use std::sync::Arc;

use nalgebra::{Isometry3, Vector3};

use crate::GeometryError;
use crate::MAX_EXTENT;
use crate::gjk::{Gjk, epa, gjk};
use crate::hull::Hull;

type V = Vector3<f64>;

/// Distances are exact to this (m): GJK stops when its upper and lower bounds are this
/// close.
pub const DISTANCE_TOLERANCE: f64 = 1e-7;

/// A convex shape in its own frame.
#[derive(Debug, Clone)]
pub enum Shape {
    /// A ball about the origin.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// A box centred on the origin, its edges along the axes.
    Cuboid {
        /// Half its edge lengths (m).
        half: V,
    },
    /// A cylinder about the z axis, centred on the origin (URDF's convention).
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Half its length (m).
        half_length: f64,
    },
    /// A cylinder with hemispherical ends about the z axis, centred on the origin; its
    /// length is the cylinder's, without the caps.
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Half the length of its cylindrical part (m).
        half_length: f64,
    },
    /// A convex polytope: a mesh's convex hull.
    Convex(Arc<Hull>),
}

/// The signed distance between two shapes and where it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Separation {
    /// The distance between the shapes (m); negative when they overlap, the depth of the
    /// overlap (how far one must move to part them).
    pub distance: f64,
    /// The point of the first shape closest to the second (deepest in it when they overlap).
    pub point_a: V,
    /// The point of the second shape closest to the first.
    pub point_b: V,
    /// The unit direction from the first shape to the second: moving the second along it
    /// increases the distance fastest.
    pub normal: V,
}

impl Shape {
    /// A sphere, checked: `what` names it in the error.
    pub fn sphere(radius: f64, what: &str) -> Result<Shape, GeometryError> {
        positive(radius, "radius", what)?;
        Ok(Shape::Sphere { radius })
    }

    /// A box of full edge lengths `size` (as URDF's `<box size>` and scene files give it).
    pub fn cuboid(size: [f64; 3], what: &str) -> Result<Shape, GeometryError> {
        for s in size {
            positive(s, "size", what)?;
        }
        Ok(Shape::Cuboid {
            half: V::from(size) / 2.0,
        })
    }

    /// A cylinder of `radius` and full `length` about z.
    pub fn cylinder(radius: f64, length: f64, what: &str) -> Result<Shape, GeometryError> {
        positive(radius, "radius", what)?;
        positive(length, "length", what)?;
        Ok(Shape::Cylinder {
            radius,
            half_length: length / 2.0,
        })
    }

    /// A capsule of `radius` whose cylindrical part is `length` long, about z.
    pub fn capsule(radius: f64, length: f64, what: &str) -> Result<Shape, GeometryError> {
        positive(radius, "radius", what)?;
        if length > MAX_EXTENT {
            return Err(GeometryError::Extent {
                what: what.to_string(),
                quantity: "length",
                value: length,
            });
        }
        if !(length >= 0.0 && length.is_finite()) {
            return Err(GeometryError::Size {
                what: what.to_string(),
                quantity: "length",
                value: length,
            });
        }
        Ok(Shape::Capsule {
            radius,
            half_length: length / 2.0,
        })
    }

    /// The radius the core is grown by.
    fn margin(&self) -> f64 {
        match self {
            Shape::Sphere { radius } | Shape::Capsule { radius, .. } => *radius,
            _ => 0.0,
        }
    }

    /// The core's farthest point along `d` (own frame).
    #[inline]
    fn core_support(&self, d: &V, hint: &mut u32) -> V {
        let sign = |x: f64| if x >= 0.0 { 1.0 } else { -1.0 };
        match self {
            Shape::Sphere { .. } => V::zeros(),
            Shape::Capsule { half_length, .. } => V::new(0.0, 0.0, sign(d.z) * half_length),
            Shape::Cuboid { half } => {
                V::new(sign(d.x) * half.x, sign(d.y) * half.y, sign(d.z) * half.z)
            }
            Shape::Cylinder {
                radius,
                half_length,
            } => {
                let r = (d.x * d.x + d.y * d.y).sqrt();
                let z = sign(d.z) * half_length;
                if r > 1e-300 {
                    V::new(radius * d.x / r, radius * d.y / r, z)
                } else {
                    V::new(0.0, 0.0, z)
                }
            }
            Shape::Convex(h) => h.support(d, hint),
        }
    }

    /// A sphere about a point of the shape's frame that holds the whole shape: its centre
    /// and radius.
    pub fn bounds(&self) -> (V, f64) {
        match self {
            Shape::Sphere { radius } => (V::zeros(), *radius),
            Shape::Cuboid { half } => (V::zeros(), half.norm()),
            Shape::Cylinder {
                radius,
                half_length,
            } => (V::zeros(), radius.hypot(*half_length)),
            Shape::Capsule {
                radius,
                half_length,
            } => (V::zeros(), radius + half_length),
            Shape::Convex(h) => h.bounds(),
        }
    }
}

fn positive(x: f64, quantity: &'static str, what: &str) -> Result<(), GeometryError> {
    if x > 0.0 && x <= MAX_EXTENT {
        Ok(())
    } else if x > MAX_EXTENT {
        Err(GeometryError::Extent {
            what: what.to_string(),
            quantity,
            value: x,
        })
    } else {
        Err(GeometryError::Size {
            what: what.to_string(),
            quantity,
            value: x,
        })
    }
}

/// The signed distance between shape `a` at pose `pa` and shape `b` at pose `pb` (poses
/// map each shape's frame into a common one, where the answer is given).
pub fn distance(a: &Shape, pa: &Isometry3<f64>, b: &Shape, pb: &Isometry3<f64>) -> Separation {
    distance_hinted(a, pa, b, pb, &mut [0, 0])
}

/// Shape `s` at pose `p`: its core's farthest point along a world direction, in the world
/// (a hull climbed from `hint`, left where the climb ended).
#[inline(always)]
fn world_support<'a>(
    s: &'a Shape,
    p: &'a Isometry3<f64>,
    hint: &'a mut u32,
) -> impl FnMut(&V) -> V + 'a {
    move |d: &V| {
        (p * nalgebra::Point3::from(s.core_support(&p.rotation.inverse_transform_vector(d), hint)))
            .coords
    }
}

/// From `b`'s bounding sphere's centre to `a`'s: where GJK looks first without a better
/// direction.
fn centres(a: &Shape, pa: &Isometry3<f64>, b: &Shape, pb: &Isometry3<f64>) -> V {
    (pa * nalgebra::Point3::from(a.bounds().0)) - (pb * nalgebra::Point3::from(b.bounds().0))
}

/// A lower bound of the signed distance between `a` at `pa` and `b` at `pb`, within
/// `rel` of the distance between their cores (and [`DISTANCE_TOLERANCE`]): what a
/// conservative walk needs, for fewer GJK steps than the distance itself. `hints` as for
/// [`distance_hinted`]; `dir` is where GJK starts looking (zero: the centres' difference)
/// and is left where it ended, for the same pair's next query at a nearby pose. Where the
/// cores overlap, the margins' negated sum (the distance is at most that).
pub fn distance_bound(
    a: &Shape,
    pa: &Isometry3<f64>,
    b: &Shape,
    pb: &Isometry3<f64>,
    hints: &mut [u32; 2],
    dir: &mut V,
    rel: f64,
) -> f64 {
    let (ra, rb) = (a.margin(), b.margin());
    let [ha, hb] = hints;
    let start = if dir.norm_squared() > 0.0 {
        *dir
    } else {
        centres(a, pa, b, pb)
    };
    let (mut fa, mut fb) = (world_support(a, pa, ha), world_support(b, pb, hb));
    match gjk(&mut fa, &mut fb, start, DISTANCE_TOLERANCE, rel) {
        Gjk::Apart { lower, v, .. } => {
            *dir = v;
            lower - ra - rb
        }
        Gjk::Overlap { .. } => -ra - rb,
    }
}

/// [`distance`] with the hull vertices the last query of the same pair ended on, which
/// makes a query at a nearby pose a few steps of climbing.
pub fn distance_hinted(
    a: &Shape,
    pa: &Isometry3<f64>,
    b: &Shape,
    pb: &Isometry3<f64>,
    hints: &mut [u32; 2],
) -> Separation {
    let (ra, rb) = (a.margin(), b.margin());
    let [ha, hb] = hints;
    let (mut fa, mut fb) = (world_support(a, pa, ha), world_support(b, pb, hb));
    let between = centres(a, pa, b, pb);
    match gjk(&mut fa, &mut fb, between, DISTANCE_TOLERANCE, 0.0) {
        Gjk::Apart { a: pa_, b: pb_, .. } => {
            let gap = pb_ - pa_;
            let d = gap.norm();
            let normal = if d > 0.0 {
                gap / d
            } else {
                if between.norm() > 0.0 {
                    -between.normalize()
                } else {
                    V::z()
                }
            };
            Separation {
                distance: d - ra - rb,
                point_a: pa_ + normal * ra,
                point_b: pb_ - normal * rb,
                normal,
            }
        }
        Gjk::Overlap { simplex, n } => {
            let (depth, normal, pa_, pb_) = epa(&mut fa, &mut fb, simplex, n, DISTANCE_TOLERANCE);
            Separation {
                distance: -depth - ra - rb,
                point_a: pa_ + normal * ra,
                point_b: pb_ - normal * rb,
                normal,
            }
        }
    }
}
