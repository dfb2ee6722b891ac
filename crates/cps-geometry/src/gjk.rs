//! The distance between two convex sets given by their support functions: GJK (Gilbert,
//! Johnson & Keerthi, IEEE J. Robotics and Automation 4(2), 1988) with the signed-volume
//! sub-algorithm of Montanari, Petrinic & Barbieri (ACM TOG 36(3), 2017) for the point of a
//! simplex closest to the origin; and, when the sets overlap, the depth by the expanding
//! polytope algorithm (EPA, van den Bergen, "Proximity queries and penetration depth
//! computation on 3D game objects", GDC 2001).
//!
//! Everything works on the Minkowski difference `A − B`: the sets are apart by the
//! distance from the origin to it, and overlap by the distance from the origin to its
//! boundary when the origin is inside.

use nalgebra::Vector3;

type V = Vector3<f64>;

/// A point of `A − B` with the two points it is the difference of.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Vert {
    w: V,
    a: V,
    b: V,
}

/// What GJK found. (Returned by value on the stack: boxing the simplex would allocate
/// on every query of a path's check.)
#[derive(Debug, Clone, Copy)]
#[allow(clippy::large_enum_variant)]
pub(crate) enum Gjk {
    /// Apart (or touching): the closest points of A and B (within the tolerance), a lower
    /// bound of their distance, and the last direction `a − b` looked along.
    Apart { a: V, b: V, lower: f64, v: V },
    /// The origin is inside `A − B`, in the simplex of `n` points found so far.
    Overlap { simplex: [Vert; 4], n: usize },
}

/// The simplex's point closest to the origin: which of its points are kept (the first `n`
/// of `keep`) and their weights.
#[derive(Debug, Clone, Copy)]
struct Closest {
    keep: [usize; 4],
    lambda: [f64; 4],
    n: usize,
    v: V,
}

impl Closest {
    fn vertex(i: usize, p: &V) -> Closest {
        Closest {
            keep: [i, 0, 0, 0],
            lambda: [1.0, 0.0, 0.0, 0.0],
            n: 1,
            v: *p,
        }
    }
}

fn s1d(p: &[V; 4], i: [usize; 2]) -> Closest {
    let (p0, p1) = (p[i[0]], p[i[1]]);
    let t = p1 - p0;
    let tt = t.norm_squared();
    if tt <= 0.0 {
        return Closest::vertex(i[0], &p0);
    }
    let u = -p0.dot(&t) / tt;
    if u <= 0.0 {
        Closest::vertex(i[0], &p0)
    } else if u >= 1.0 {
        Closest::vertex(i[1], &p1)
    } else {
        Closest {
            keep: [i[0], i[1], 0, 0],
            lambda: [1.0 - u, u, 0.0, 0.0],
            n: 2,
            v: p0 + t * u,
        }
    }
}

fn best(a: Option<Closest>, b: Closest) -> Option<Closest> {
    match a {
        Some(a) if a.v.norm_squared() <= b.v.norm_squared() => Some(a),
        _ => Some(b),
    }
}

fn s2d(p: &[V; 4], i: [usize; 3]) -> Closest {
    let (p0, p1, p2) = (p[i[0]], p[i[1]], p[i[2]]);
    let n = (p1 - p0).cross(&(p2 - p0));
    let nn = n.norm_squared();
    let scale = (p1 - p0).norm_squared().max((p2 - p0).norm_squared());
    // The closest of the edges, or only the edge across vertex `only`.
    let edges = |only: Option<usize>| {
        let mut out = None;
        for (k, e) in [[i[1], i[2]], [i[2], i[0]], [i[0], i[1]]]
            .into_iter()
            .enumerate()
        {
            if only.is_none_or(|o| o == k) {
                out = best(out, s1d(p, e));
            }
        }
        out
    };
    if nn <= 1e-20 * scale * scale {
        // A sliver: its closest point is on an edge.
        return edges(None).unwrap_or_else(|| Closest::vertex(i[0], &p0));
    }
    let q = n * (n.dot(&p0) / nn);
    let l0 = (p1 - q).cross(&(p2 - q)).dot(&n) / nn;
    let l1 = (p2 - q).cross(&(p0 - q)).dot(&n) / nn;
    let l2 = 1.0 - l0 - l1;
    if l0 > 0.0 && l1 > 0.0 && l2 > 0.0 {
        return Closest {
            keep: [i[0], i[1], i[2], 0],
            lambda: [l0, l1, l2, 0.0],
            n: 3,
            v: q,
        };
    }
    // Outside: on an edge across from a vertex whose weight is not positive.
    let mut out = None;
    for (k, l) in [l0, l1, l2].into_iter().enumerate() {
        if l <= 0.0 {
            out = best(
                out,
                edges(Some(k)).unwrap_or_else(|| Closest::vertex(i[0], &p0)),
            );
        }
    }
    out.unwrap_or_else(|| Closest::vertex(i[0], &p0))
}

fn volume(a: &V, b: &V, c: &V, d: &V) -> f64 {
    (b - a).dot(&(c - a).cross(&(d - a)))
}

/// The closest point of a tetrahedron; `None` when the origin is inside it.
fn s3d(p: &[V; 4]) -> Option<Closest> {
    let o = V::zeros();
    let det = volume(&p[0], &p[1], &p[2], &p[3]);
    let c = [
        volume(&o, &p[1], &p[2], &p[3]),
        volume(&p[0], &o, &p[2], &p[3]),
        volume(&p[0], &p[1], &o, &p[3]),
        volume(&p[0], &p[1], &p[2], &o),
    ];
    let faces = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    let scale = (1..4).map(|k| (p[k] - p[0]).norm()).fold(0.0, f64::max);
    if det.abs() <= 1e-15 * scale.powi(3) {
        // Flat: the closest point is on a face.
        let mut out = None;
        for f in faces {
            out = best(out, s2d(p, f));
        }
        return out;
    }
    let lambda = c.map(|ci| ci / det);
    if lambda.iter().all(|&l| l > 0.0) {
        return None;
    }
    let mut out = None;
    for (k, l) in lambda.into_iter().enumerate() {
        if l <= 0.0 {
            out = best(out, s2d(p, faces[k]));
        }
    }
    out
}

fn support<A: FnMut(&V) -> V, B: FnMut(&V) -> V>(sa: &mut A, sb: &mut B, d: &V) -> Vert {
    let a = sa(d);
    let b = sb(&-d);
    Vert { w: a - b, a, b }
}

/// GJK on `A − B`: `sa`/`sb` give each set's farthest point along a direction, `start` is
/// a first direction to look in (the centres' difference is a good one, the last answer's
/// `v` a better one), `tol` (m) plus `rel` times the distance the gap within which the
/// answer is exact.
pub(crate) fn gjk<A: FnMut(&V) -> V, B: FnMut(&V) -> V>(
    sa: &mut A,
    sb: &mut B,
    start: V,
    tol: f64,
    rel: f64,
) -> Gjk {
    let d0 = if start.norm_squared() > 0.0 {
        start
    } else {
        V::x()
    };
    let mut s = [Vert::default(); 4];
    s[0] = support(sa, sb, &-d0);
    let mut n = 1;
    let mut lambda = [1.0, 0.0, 0.0, 0.0];
    let mut v = s[0].w;
    // The best lower bound v·w/|v| on the distance so far.
    let mut lower: f64 = 0.0;
    let witness = |s: &[Vert; 4], lambda: &[f64; 4], n: usize, lower: f64, v: V| {
        let mut a = V::zeros();
        let mut b = V::zeros();
        for k in 0..n {
            a += s[k].a * lambda[k];
            b += s[k].b * lambda[k];
        }
        Gjk::Apart { a, b, lower, v }
    };
    for _ in 0..96 {
        let vv = v.norm_squared();
        if vv <= (tol * 1e-3).powi(2) {
            return Gjk::Overlap { simplex: s, n };
        }
        let w = support(sa, sb, &-v);
        let norm = vv.sqrt();
        lower = lower.max(v.dot(&w.w) / norm);
        // The gap between the upper bound |v| and the lower bound v·w/|v| on the distance.
        if vv - v.dot(&w.w) <= (tol + rel * norm) * norm {
            return witness(&s, &lambda, n, lower, v);
        }
        if s[..n].iter().any(|x| x.w == w.w) {
            return witness(&s, &lambda, n, lower, v);
        }
        s[n] = w;
        n += 1;
        let mut p = [V::zeros(); 4];
        for k in 0..n {
            p[k] = s[k].w;
        }
        let c = match n {
            2 => s1d(&p, [0, 1]),
            3 => s2d(&p, [0, 1, 2]),
            _ => match s3d(&p) {
                Some(c) => c,
                None => return Gjk::Overlap { simplex: s, n: 4 },
            },
        };
        if c.v.norm_squared() >= vv {
            // No progress (rounding): the last simplex's answer stands.
            return witness(&s, &lambda, n - 1, lower, v);
        }
        let old = s;
        for k in 0..c.n {
            s[k] = old[c.keep[k]];
        }
        n = c.n;
        lambda = c.lambda;
        v = c.v;
    }
    witness(&s, &lambda, n, lower, v)
}

/// A face of the expanding polytope: outward unit normal and distance from the origin.
#[derive(Debug, Clone, Copy)]
struct Face {
    v: [usize; 3],
    normal: V,
    dist: f64,
}

fn face(points: &[Vert], v: [usize; 3], inside: &V) -> Option<Face> {
    let (a, b, c) = (points[v[0]].w, points[v[1]].w, points[v[2]].w);
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    if len <= 1e-300 {
        return None;
    }
    let mut n = n / len;
    let mut v = v;
    if n.dot(&(inside - a)) > 0.0 {
        n = -n;
        v.swap(1, 2);
    }
    Some(Face {
        v,
        normal: n,
        dist: n.dot(&a),
    })
}

/// How deep `A` and `B` overlap, from GJK's simplex around the origin: the depth, the unit
/// direction along which moving `B` by the depth separates them, and the deepest points
/// of A and B.
pub(crate) fn epa<A: FnMut(&V) -> V, B: FnMut(&V) -> V>(
    sa: &mut A,
    sb: &mut B,
    simplex: [Vert; 4],
    n: usize,
    tol: f64,
) -> (f64, V, V, V) {
    let mut points: Vec<Vert> = simplex[..n].to_vec();
    // Grow a lower-dimensional simplex into a tetrahedron with points of A − B.
    let axes = [V::x(), V::y(), V::z(), -V::x(), -V::y(), -V::z()];
    while points.len() < 4 {
        let mut best_new: Option<(f64, Vert)> = None;
        let candidates: Vec<V> = match points.len() {
            1 => axes.to_vec(),
            2 => {
                let t = (points[1].w - points[0].w).normalize();
                let u = if t.x.abs() < 0.6 { V::x() } else { V::y() };
                let p = t.cross(&u).normalize();
                let q = t.cross(&p);
                vec![p, -p, q, -q, (p + q).normalize(), -(p + q).normalize()]
            }
            _ => {
                let nrm = (points[1].w - points[0].w).cross(&(points[2].w - points[0].w));
                let nrm = if nrm.norm() > 0.0 {
                    nrm.normalize()
                } else {
                    V::z()
                };
                vec![nrm, -nrm]
            }
        };
        for d in candidates {
            let w = support(sa, sb, &d);
            let gain = match points.len() {
                1 => (w.w - points[0].w).norm(),
                2 => {
                    let t = points[1].w - points[0].w;
                    (w.w - points[0].w).cross(&t).norm() / t.norm().max(1e-300)
                }
                _ => {
                    let nrm = (points[1].w - points[0].w)
                        .cross(&(points[2].w - points[0].w))
                        .normalize();
                    (w.w - points[0].w).dot(&nrm).abs()
                }
            };
            if best_new.is_none_or(|(g, _)| gain > g) {
                best_new = Some((gain, w));
            }
        }
        match best_new {
            Some((g, w)) if g > tol * 1e-3 => points.push(w),
            // A − B is flat here: the sets only touch.
            _ => {
                let a = points[0].a;
                let b = points[0].b;
                return (0.0, V::x(), a, b);
            }
        }
    }
    let inside = points.iter().map(|p| p.w).sum::<V>() / 4.0;
    let mut faces: Vec<Face> = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]
        .iter()
        .filter_map(|&v| face(&points, v, &inside))
        .collect();
    let mut horizon: Vec<(usize, usize)> = Vec::new();
    for _ in 0..128 {
        let Some(f) = faces
            .iter()
            .copied()
            .min_by(|a, b| a.dist.total_cmp(&b.dist))
        else {
            break;
        };
        let w = support(sa, sb, &f.normal);
        let reach = f.normal.dot(&w.w);
        if reach - f.dist <= tol {
            return finish(&points, &f);
        }
        points.push(w);
        let new = points.len() - 1;
        // Faces the new point sees go; their horizon is closed with a cone to it.
        horizon.clear();
        let mut kept = Vec::with_capacity(faces.len() + 4);
        for g in faces.drain(..) {
            if g.normal.dot(&w.w) - g.dist > 0.0 {
                for k in 0..3 {
                    let e = (g.v[k], g.v[(k + 1) % 3]);
                    if let Some(pos) = horizon.iter().position(|&h| h == (e.1, e.0)) {
                        horizon.swap_remove(pos);
                    } else {
                        horizon.push(e);
                    }
                }
            } else {
                kept.push(g);
            }
        }
        faces = kept;
        if horizon.is_empty() {
            // Rounding: nothing is seen though the point is beyond the closest face.
            return finish(&points, &f);
        }
        for &(a, b) in &horizon {
            if let Some(g) = face(&points, [a, b, new], &inside) {
                faces.push(g);
            }
        }
    }
    let f = faces
        .iter()
        .min_by(|a, b| a.dist.total_cmp(&b.dist))
        .copied();
    match f {
        Some(f) => finish(&points, &f),
        None => (0.0, V::x(), points[0].a, points[0].b),
    }
}

/// The depth, normal and deepest points of a final face: the origin's projection on it,
/// in the face's barycentric weights.
fn finish(points: &[Vert], f: &Face) -> (f64, V, V, V) {
    let (p0, p1, p2) = (points[f.v[0]], points[f.v[1]], points[f.v[2]]);
    let q = f.normal * f.dist;
    let n = (p1.w - p0.w).cross(&(p2.w - p0.w));
    let nn = n.norm_squared().max(1e-300);
    let l0 = (p1.w - q).cross(&(p2.w - q)).dot(&n) / nn;
    let l1 = (p2.w - q).cross(&(p0.w - q)).dot(&n) / nn;
    let l2 = 1.0 - l0 - l1;
    let a = p0.a * l0 + p1.a * l1 + p2.a * l2;
    let b = p0.b * l0 + p1.b * l1 + p2.b * l2;
    (f.dist.max(0.0), f.normal, a, b)
}
