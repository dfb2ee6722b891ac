//! Convex hulls of point sets by quickhull (Barber, Dobkin & Huhdanpaa, "The quickhull
//! algorithm for convex hulls", ACM TOMS 22(4), 1996): a tetrahedron of extreme points,
//! then, face by face, the farthest point outside is added and the faces it sees are
//! replaced by a cone from their horizon to it. Points within a tolerance of a face count
//! as on it, so the hull of a triangulated box is its 8 corners.
//!
//! A hull keeps its vertices, its outward triangles (for drawing) and each vertex's
//! neighbours, so that the support point in a direction is found by climbing from a
//! vertex to a better neighbour (on a convex polytope a vertex no neighbour improves on is
//! the best) instead of scanning every vertex.

use std::collections::HashMap;

use nalgebra::Vector3;

use crate::GeometryError;

type V = Vector3<f64>;

/// Hulls with at most this many vertices are scanned whole for a support point (faster
/// than climbing at that size).
const SCAN_BELOW: usize = 48;

/// A convex polytope: the convex hull of a point set.
#[derive(Debug, Clone)]
pub struct Hull {
    vertices: Vec<V>,
    faces: Vec<[u32; 3]>,
    neighbours: Vec<Vec<u32>>,
    centre: V,
    radius: f64,
}

#[derive(Debug, Clone)]
struct Face {
    v: [usize; 3],
    normal: V,
    offset: f64,
    outside: Vec<usize>,
    alive: bool,
}

fn plane(points: &[V], v: [usize; 3]) -> (V, f64) {
    let (a, b, c) = (points[v[0]], points[v[1]], points[v[2]]);
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    let n = if len > 0.0 { n / len } else { n };
    (n, n.dot(&a))
}

impl Hull {
    /// The convex hull of `points` (at least four, not all in one plane). `what` names the
    /// points in errors (a file, or "a box").
    pub fn new(points: &[V], what: &str) -> Result<Hull, GeometryError> {
        let hull = Self::quickhull(points, what)?;
        // Points on a face or an edge of the final hull that were added before the corners
        // around them stay as vertices; the hull of the corners alone is the same solid.
        let corners = hull.corners();
        if corners.len() < hull.vertices.len() && corners.len() >= 4 {
            return Self::quickhull(&corners, what);
        }
        Ok(hull)
    }

    /// The vertices that are the one farthest point of the hull in some direction: each
    /// vertex is tried in the sum of its faces' normals, which lies inside its cone of
    /// normals when it is a corner, and along a face or edge it merely lies on otherwise.
    /// On a convex hull a vertex ahead of every neighbour along a direction is ahead of
    /// every vertex (the simplex method's argument), so only neighbours are compared.
    fn corners(&self) -> Vec<V> {
        let mut around = vec![V::zeros(); self.vertices.len()];
        let mut next: Vec<Vec<u32>> = vec![Vec::new(); self.vertices.len()];
        for t in &self.faces {
            for k in 0..3 {
                next[t[k] as usize].push(t[(k + 1) % 3]);
            }
        }
        for t in &self.faces {
            let (a, b, c) = (
                self.vertices[t[0] as usize],
                self.vertices[t[1] as usize],
                self.vertices[t[2] as usize],
            );
            let n = (b - a).cross(&(c - a));
            let len = n.norm();
            if len > 0.0 {
                for &k in t {
                    around[k as usize] += n / len;
                }
            }
        }
        let scale = self.radius.max(f64::MIN_POSITIVE);
        (0..self.vertices.len())
            .filter(|&i| {
                let d = around[i];
                let len = d.norm();
                if len == 0.0 {
                    return false;
                }
                let d = d / len;
                let own = self.vertices[i].dot(&d);
                next[i]
                    .iter()
                    .all(|&j| self.vertices[j as usize].dot(&d) < own - 1e-9 * scale)
            })
            .map(|i| self.vertices[i])
            .collect()
    }

    // Long on purpose (over 150 lines): the algorithm's one loop (the first simplex, then
    // each outside point's horizon and new faces) with its invariants beside it.
    fn quickhull(points: &[V], what: &str) -> Result<Hull, GeometryError> {
        if points.len() < 4 {
            return Err(GeometryError::Flat {
                what: what.to_string(),
                why: format!("it has {} points, a solid needs 4", points.len()),
            });
        }
        if let Some(i) = points
            .iter()
            .position(|p| !p.iter().all(|x| x.abs() <= crate::MAX_EXTENT))
        {
            return Err(GeometryError::NotFinite {
                what: what.to_string(),
                index: i,
            });
        }
        let mut lo = points[0];
        let mut hi = points[0];
        for p in points {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let extent = hi - lo;
        let scale = extent.amax();
        let eps = 1e-9 * scale.max(f64::MIN_POSITIVE);
        if scale == 0.0 {
            return Err(GeometryError::Flat {
                what: what.to_string(),
                why: "all its points are one point".into(),
            });
        }
        // The initial tetrahedron: the two extremes along the longest axis, the point
        // farthest from their line, the point farthest from their plane.
        let axis = extent.imax();
        let i0 = (0..points.len())
            .min_by(|&a, &b| points[a][axis].total_cmp(&points[b][axis]))
            .unwrap_or(0);
        let i1 = (0..points.len())
            .max_by(|&a, &b| points[a][axis].total_cmp(&points[b][axis]))
            .unwrap_or(0);
        let line = (points[i1] - points[i0]).normalize();
        let off_line = |p: &V| {
            let r = p - points[i0];
            (r - line * r.dot(&line)).norm()
        };
        let i2 = (0..points.len())
            .max_by(|&a, &b| off_line(&points[a]).total_cmp(&off_line(&points[b])))
            .unwrap_or(0);
        if off_line(&points[i2]) <= eps {
            return Err(GeometryError::Flat {
                what: what.to_string(),
                why: "all its points lie on one line".into(),
            });
        }
        let (n, d) = plane(points, [i0, i1, i2]);
        let i3 = (0..points.len())
            .max_by(|&a, &b| {
                (n.dot(&points[a]) - d)
                    .abs()
                    .total_cmp(&(n.dot(&points[b]) - d).abs())
            })
            .unwrap_or(0);
        if (n.dot(&points[i3]) - d).abs() <= eps {
            return Err(GeometryError::Flat {
                what: what.to_string(),
                why: "all its points lie in one plane".into(),
            });
        }
        let mut faces: Vec<Face> = Vec::new();
        let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
        let inner = (points[i0] + points[i1] + points[i2] + points[i3]) / 4.0;
        let add = |faces: &mut Vec<Face>,
                   edges: &mut HashMap<(usize, usize), usize>,
                   mut v: [usize; 3],
                   inside: &V| {
            let (mut n, mut d) = plane(points, v);
            if n.dot(inside) - d > 0.0 {
                v.swap(1, 2);
                (n, d) = (-n, -d);
            }
            let f = faces.len();
            for k in 0..3 {
                edges.insert((v[k], v[(k + 1) % 3]), f);
            }
            faces.push(Face {
                v,
                normal: n,
                offset: d,
                outside: Vec::new(),
                alive: true,
            });
        };
        for v in [[i0, i1, i2], [i0, i1, i3], [i0, i2, i3], [i1, i2, i3]] {
            add(&mut faces, &mut edges, v, &inner);
        }
        let seeds = [i0, i1, i2, i3];
        for (i, p) in points.iter().enumerate() {
            if seeds.contains(&i) {
                continue;
            }
            if let Some(f) = faces.iter().position(|f| f.normal.dot(p) - f.offset > eps) {
                faces[f].outside.push(i);
            }
        }
        let mut visible: Vec<usize> = Vec::new();
        let mut stack: Vec<usize> = Vec::new();
        let mut horizon: Vec<(usize, usize)> = Vec::new();
        let mut orphans: Vec<usize> = Vec::new();
        // Faces that may have outside points, latest on top (dead or emptied ones are
        // skipped when popped): finding the next face is not a scan of every face made.
        let mut pending: Vec<usize> = (0..faces.len())
            .filter(|&f| !faces[f].outside.is_empty())
            .collect();
        // A face is seen this round when its stamp is the round's (no clearing per round).
        let mut seen: Vec<usize> = Vec::new();
        // Each round adds one point, so the rounds are bounded by the points.
        for round in 1..=points.len() {
            let start = loop {
                match pending.pop() {
                    Some(f) if faces[f].alive && !faces[f].outside.is_empty() => break Some(f),
                    Some(_) => continue,
                    None => break None,
                }
            };
            let Some(start) = start else {
                break;
            };
            let f0 = &faces[start];
            let apex = *f0
                .outside
                .iter()
                .max_by(|&&a, &&b| {
                    (f0.normal.dot(&points[a]) - f0.offset)
                        .total_cmp(&(f0.normal.dot(&points[b]) - f0.offset))
                })
                .unwrap_or(&f0.outside[0]);
            let p = points[apex];
            // The faces the apex sees, as one connected patch grown from the start face.
            seen.resize(faces.len(), 0);
            visible.clear();
            stack.clear();
            stack.push(start);
            seen[start] = round;
            while let Some(f) = stack.pop() {
                visible.push(f);
                let v = faces[f].v;
                for k in 0..3 {
                    if let Some(&g) = edges.get(&(v[(k + 1) % 3], v[k]))
                        && seen[g] != round
                        && faces[g].alive
                        && faces[g].normal.dot(&p) - faces[g].offset > eps
                    {
                        seen[g] = round;
                        stack.push(g);
                    }
                }
            }
            horizon.clear();
            for &f in &visible {
                let v = faces[f].v;
                for k in 0..3 {
                    let (a, b) = (v[k], v[(k + 1) % 3]);
                    match edges.get(&(b, a)) {
                        Some(&g) if seen[g] == round => {}
                        _ => horizon.push((a, b)),
                    }
                }
            }
            orphans.clear();
            for &f in &visible {
                faces[f].alive = false;
                orphans.append(&mut faces[f].outside);
                let v = faces[f].v;
                for k in 0..3 {
                    edges.remove(&(v[k], v[(k + 1) % 3]));
                }
            }
            let first_new = faces.len();
            for &(a, b) in &horizon {
                let (n, d) = plane(points, [a, b, apex]);
                let f = faces.len();
                for e in [(a, b), (b, apex), (apex, a)] {
                    edges.insert(e, f);
                }
                faces.push(Face {
                    v: [a, b, apex],
                    normal: n,
                    offset: d,
                    outside: Vec::new(),
                    alive: true,
                });
            }
            for &i in &orphans {
                if i == apex {
                    continue;
                }
                let q = &points[i];
                if let Some(f) = (first_new..faces.len())
                    .find(|&f| faces[f].normal.dot(q) - faces[f].offset > eps)
                {
                    faces[f].outside.push(i);
                }
            }
            pending.extend((first_new..faces.len()).filter(|&f| !faces[f].outside.is_empty()));
        }
        // Keep the live faces, with the vertices they use renumbered from 0.
        let mut index: HashMap<usize, u32> = HashMap::new();
        let mut vertices = Vec::new();
        let mut tris = Vec::new();
        for f in faces.iter().filter(|f| f.alive) {
            let mut t = [0u32; 3];
            for k in 0..3 {
                t[k] = *index.entry(f.v[k]).or_insert_with(|| {
                    vertices.push(points[f.v[k]]);
                    (vertices.len() - 1) as u32
                });
            }
            tris.push(t);
        }
        Ok(Self::from_parts(vertices, tris))
    }

    fn from_parts(vertices: Vec<V>, faces: Vec<[u32; 3]>) -> Hull {
        let mut neighbours = vec![Vec::new(); vertices.len()];
        for t in &faces {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if !neighbours[a as usize].contains(&b) {
                    neighbours[a as usize].push(b);
                }
                if !neighbours[b as usize].contains(&a) {
                    neighbours[b as usize].push(a);
                }
            }
        }
        let centre = vertices.iter().sum::<V>() / vertices.len().max(1) as f64;
        let radius = vertices
            .iter()
            .map(|v| (v - centre).norm())
            .fold(0.0, f64::max);
        Hull {
            vertices,
            faces,
            neighbours,
            centre,
            radius,
        }
    }

    /// The hull's corners.
    pub fn vertices(&self) -> &[V] {
        &self.vertices
    }

    /// Its surface as triangles of [`Hull::vertices`] indices, counter-clockwise seen from
    /// outside.
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// A sphere that holds it: centre and radius.
    pub fn bounds(&self) -> (V, f64) {
        (self.centre, self.radius)
    }

    /// The vertex farthest along `d`. `hint` is the vertex a climb starts from (the last
    /// answer for a nearby direction makes it a step or two) and is set to the answer.
    #[inline]
    pub fn support(&self, d: &V, hint: &mut u32) -> V {
        let n = self.vertices.len();
        if n <= SCAN_BELOW {
            let mut best = 0;
            let mut best_dot = f64::NEG_INFINITY;
            for (i, v) in self.vertices.iter().enumerate() {
                let s = v.dot(d);
                if s > best_dot {
                    best_dot = s;
                    best = i;
                }
            }
            *hint = best as u32;
            return self.vertices[best];
        }
        let mut at = (*hint as usize).min(n - 1);
        let mut at_dot = self.vertices[at].dot(d);
        loop {
            let mut moved = false;
            for &j in &self.neighbours[at] {
                let s = self.vertices[j as usize].dot(d);
                if s > at_dot {
                    at_dot = s;
                    at = j as usize;
                    moved = true;
                }
            }
            if !moved {
                break;
            }
        }
        *hint = at as u32;
        self.vertices[at]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn cube_points() -> Vec<V> {
        let mut p = Vec::new();
        for x in [-1.0, 1.0] {
            for y in [-1.0, 1.0] {
                for z in [-1.0, 1.0] {
                    p.push(V::new(x, y, z));
                }
            }
        }
        // Points on the faces and inside: none of them is a corner.
        p.push(V::new(0.0, 0.0, 1.0));
        p.push(V::new(0.3, -0.2, 0.1));
        p.push(V::new(1.0, 0.5, -0.5));
        p
    }

    #[test]
    fn the_hull_of_a_cube_is_its_corners_with_twelve_outward_triangles() {
        let h = Hull::new(&cube_points(), "a cube").unwrap();
        assert_eq!(h.vertices().len(), 8);
        assert_eq!(h.faces().len(), 12);
        for t in h.faces() {
            let (a, b, c) = (
                h.vertices[t[0] as usize],
                h.vertices[t[1] as usize],
                h.vertices[t[2] as usize],
            );
            let n = (b - a).cross(&(c - a));
            // Outward: the centre is behind every face.
            assert!(n.dot(&(V::zeros() - a)) < 0.0, "{t:?}");
        }
        // Euler: V - E + F = 2 for a closed surface of triangles (E = 3F/2).
        let f = h.faces().len() as i64;
        assert_eq!(h.vertices().len() as i64 - 3 * f / 2 + f, 2);
    }

    #[test]
    fn every_point_is_inside_the_hull_and_the_support_is_the_scanned_maximum() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for round in 0..20 {
            let n = 4 + round * 40;
            let points: Vec<V> = (0..n)
                .map(|_| {
                    V::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-0.5..0.5),
                        rng.random_range(-0.2..0.2),
                    )
                })
                .collect();
            let h = Hull::new(&points, "random points").unwrap();
            for p in &points {
                for t in h.faces() {
                    let (a, b, c) = (
                        h.vertices[t[0] as usize],
                        h.vertices[t[1] as usize],
                        h.vertices[t[2] as usize],
                    );
                    let n = (b - a).cross(&(c - a)).normalize();
                    assert!(n.dot(&(p - a)) <= 1e-9, "a point outside face {t:?}");
                }
            }
            let f = h.faces().len() as i64;
            assert_eq!(h.vertices().len() as i64 - 3 * f / 2 + f, 2, "Euler");
            let mut hint = 0;
            for _ in 0..50 {
                let d = V::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let best = points.iter().map(|p| p.dot(&d)).fold(f64::MIN, f64::max);
                assert!((h.support(&d, &mut hint).dot(&d) - best).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn flat_or_broken_point_sets_are_refused_with_a_sentence() {
        let square: Vec<V> = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]]
            .iter()
            .map(|p| V::new(p[0], p[1], 2.0))
            .collect();
        assert_eq!(
            Hull::new(&square, "flat.stl").unwrap_err().to_string(),
            "flat.stl is flat: all its points lie in one plane"
        );
        let line: Vec<V> = (0..5).map(|i| V::new(i as f64, 0.0, 0.0)).collect();
        assert!(
            Hull::new(&line, "a line")
                .unwrap_err()
                .to_string()
                .contains("one line")
        );
        let mut nan = cube_points();
        nan[3].y = f64::NAN;
        assert_eq!(
            Hull::new(&nan, "bad.obj").unwrap_err().to_string(),
            "bad.obj: point 4 is not a number of metres within 100 of the origin"
        );
        // A point of a mesh in millimetres read as metres, or worse: refused, as sizes are.
        let mut far = cube_points();
        far[5].x = 1e15;
        assert!(
            Hull::new(&far, "far.obj")
                .unwrap_err()
                .to_string()
                .contains("point 6")
        );
        assert!(Hull::new(&[V::zeros(); 3], "tiny").is_err());
    }
}
