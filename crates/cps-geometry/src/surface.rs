//! A shape's surface as triangles, for drawing it: what a viewer shows is what the
//! distances are computed on (a mesh as its hull, a round shape as a fine polygon).

use crate::shape::Shape;

/// Segments around a round shape's axis (and half as many rings from pole to pole): at
/// 24, a drawn cylinder lies within 0.9 % of its radius inside the true one.
pub const ROUND_SEGMENTS: usize = 24;

/// A closed triangle mesh in a shape's own frame: every triangle counter-clockwise seen
/// from outside (its normal, by the right-hand rule, points out).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Surface {
    /// Corner positions (m).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

impl Surface {
    fn vertex(&mut self, p: [f64; 3]) -> u32 {
        self.vertices.push(p);
        (self.vertices.len() - 1) as u32
    }

    /// A quad `a b c d` (counter-clockwise from outside) as two triangles.
    fn quad(&mut self, a: u32, b: u32, c: u32, d: u32) {
        self.triangles.push([a, b, c]);
        self.triangles.push([a, c, d]);
    }

    /// The volume it encloses (m³; by the divergence theorem, so positive when it faces
    /// out).
    pub fn volume(&self) -> f64 {
        let v = |i: u32| nalgebra::Vector3::from(self.vertices[i as usize]);
        self.triangles
            .iter()
            .map(|t| v(t[0]).dot(&v(t[1]).cross(&v(t[2]))) / 6.0)
            .sum()
    }
}

impl Shape {
    /// Its surface as triangles in its own frame ([`ROUND_SEGMENTS`] around round shapes).
    pub fn surface(&self) -> Surface {
        let mut s = Surface::default();
        match self {
            Shape::Cuboid { half } => {
                let corner = |i: usize| {
                    let sign = |bit: usize| if i & bit != 0 { 1.0 } else { -1.0 };
                    [sign(1) * half.x, sign(2) * half.y, sign(4) * half.z]
                };
                for i in 0..8 {
                    s.vertex(corner(i));
                }
                // Corner i has x set by bit 1, y by bit 2, z by bit 4.
                for q in [
                    [0, 2, 3, 1], // −z
                    [4, 5, 7, 6], // +z
                    [0, 1, 5, 4], // −y
                    [2, 6, 7, 3], // +y
                    [0, 4, 6, 2], // −x
                    [1, 3, 7, 5], // +x
                ] {
                    s.quad(q[0], q[1], q[2], q[3]);
                }
            }
            Shape::Cylinder {
                radius,
                half_length,
            } => round(&mut s, *radius, *half_length, 0),
            Shape::Sphere { radius } => round(&mut s, *radius, 0.0, ROUND_SEGMENTS / 2),
            Shape::Capsule {
                radius,
                half_length,
            } => round(&mut s, *radius, *half_length, ROUND_SEGMENTS / 2),
            Shape::Convex(h) => {
                s.vertices = h.vertices().iter().map(|v| [v.x, v.y, v.z]).collect();
                s.triangles = h.faces().to_vec();
            }
        }
        s
    }
}

/// A solid of revolution about z: a cylinder of `radius` from −`half` to +`half` capped by
/// two hemispheres of `rings` rings each (flat caps with none).
fn round(s: &mut Surface, radius: f64, half: f64, rings: usize) {
    let n = ROUND_SEGMENTS;
    // Circles from the bottom to the top: the lower hemisphere's rings, the cylinder's two
    // ends, the upper hemisphere's rings; each circle is `n` vertices.
    let mut circles: Vec<(f64, f64)> = Vec::new(); // (z, radius)
    let ring = |k: usize| {
        let a = std::f64::consts::FRAC_PI_2 * k as f64 / rings as f64;
        (radius * a.sin(), radius * a.cos())
    };
    for k in (1..rings).rev() {
        let (dz, r) = ring(k);
        circles.push((-half - dz, r));
    }
    circles.push((-half, radius));
    if half > 0.0 {
        circles.push((half, radius));
    }
    for k in 1..rings {
        let (dz, r) = ring(k);
        circles.push((half + dz, r));
    }
    let first = s.vertices.len() as u32;
    for &(z, r) in &circles {
        for j in 0..n {
            let a = std::f64::consts::TAU * j as f64 / n as f64;
            s.vertex([r * a.cos(), r * a.sin(), z]);
        }
    }
    let at = |c: usize, j: usize| first + (c * n + j % n) as u32;
    for c in 0..circles.len() - 1 {
        for j in 0..n {
            s.quad(at(c, j), at(c, j + 1), at(c + 1, j + 1), at(c + 1, j));
        }
    }
    // The ends: a pole (rounded) or a centre (flat), fanned to the outermost circles.
    let (bottom, top) = if rings > 0 {
        (-half - radius, half + radius)
    } else {
        (-half, half)
    };
    let low = s.vertex([0.0, 0.0, bottom]);
    let high = s.vertex([0.0, 0.0, top]);
    let last = circles.len() - 1;
    for j in 0..n {
        s.triangles.push([low, at(0, j + 1), at(0, j)]);
        s.triangles.push([high, at(last, j), at(last, j + 1)]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance;
    use nalgebra::{Isometry3, Vector3};
    use std::collections::HashMap;

    fn shapes() -> Vec<(Shape, f64)> {
        let pi = std::f64::consts::PI;
        let hull = crate::Hull::new(
            &[
                Vector3::new(0.0, 0.0, 0.0),
                Vector3::new(0.1, 0.0, 0.0),
                Vector3::new(0.0, 0.2, 0.0),
                Vector3::new(0.0, 0.0, 0.3),
                Vector3::new(0.01, 0.01, 0.01), // inside: not a corner
            ],
            "tetrahedron",
        )
        .unwrap();
        vec![
            (Shape::cuboid([0.3, 0.2, 0.1], "box").unwrap(), 0.006),
            (Shape::sphere(0.1, "ball").unwrap(), 4.0 / 3.0 * pi * 1e-3),
            (
                Shape::cylinder(0.05, 0.4, "rod").unwrap(),
                pi * 0.0025 * 0.4,
            ),
            (
                Shape::capsule(0.05, 0.2, "pill").unwrap(),
                pi * 0.0025 * 0.2 + 4.0 / 3.0 * pi * 0.05f64.powi(3),
            ),
            (
                Shape::capsule(0.05, 0.0, "pill of no length").unwrap(),
                4.0 / 3.0 * pi * 0.05f64.powi(3),
            ),
            (
                Shape::Convex(std::sync::Arc::new(hull)),
                0.1 * 0.2 * 0.3 / 6.0,
            ),
        ]
    }

    #[test]
    fn every_surface_is_closed_faces_out_and_lies_on_its_shape() {
        let dot = Shape::sphere(1e-12, "dot").unwrap();
        for (shape, volume) in shapes() {
            let s = shape.surface();
            // Closed and consistently wound: every directed edge once, its reverse once.
            let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
            for t in &s.triangles {
                for k in 0..3 {
                    *edges.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
                }
            }
            for (&(a, b), &n) in &edges {
                assert_eq!(n, 1, "{shape:?}: edge {a}-{b} used {n} times");
                assert_eq!(edges.get(&(b, a)), Some(&1), "{shape:?}: {a}-{b} open");
            }
            // Facing out, enclosing nearly the shape's volume (a polygon inside a circle
            // holds sin(2π/n)·n/2π of it).
            let v = s.volume();
            assert!(v > 0.0, "{shape:?} faces in");
            assert!(v <= volume * (1.0 + 1e-9), "{shape:?}: {v} > {volume}");
            assert!(v > 0.96 * volume, "{shape:?}: {v} against {volume}");
            // Every corner on the shape's surface.
            for p in &s.vertices {
                let at = Isometry3::translation(p[0], p[1], p[2]);
                let d = distance(&dot, &at, &shape, &Isometry3::identity()).distance;
                assert!(d.abs() < 1e-6, "{shape:?}: corner {p:?} {d} m off");
            }
        }
    }
}
