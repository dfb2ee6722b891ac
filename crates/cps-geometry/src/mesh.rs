//! Triangle meshes from files: STL (binary and ASCII) and Wavefront OBJ. Vertices with the
//! same coordinates are merged, so a mesh's edges can be counted: an edge three or more
//! triangles share is not the surface of a solid, and the mesh is refused with the place
//! of the first such edge. Holes (edges of one triangle) are counted and allowed: what cps
//! collides is a mesh's convex hull ([`Mesh::hull`]), which closes them — franka_description's
//! own collision meshes of link0 and link6 have small ones, and MuJoCo collides their hulls
//! too.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::Vector3;

use crate::GeometryError;
use crate::hull::Hull;

type V = Vector3<f64>;

/// Files larger than this are refused before they are read (a collision mesh is kilobytes).
pub const MAX_MESH_BYTES: u64 = 64 << 20;

/// A triangle mesh with merged vertices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// The corners (m, in the file's frame times its scale).
    pub vertices: Vec<V>,
    /// Triangles as indices into `vertices`, with where each came from in its file
    /// (`line 12` or `triangle 4`).
    pub triangles: Vec<[u32; 3]>,
    places: Vec<String>,
}

impl Mesh {
    /// Reads an STL or OBJ file (by its extension, case-insensitive), each coordinate
    /// multiplied by `scale` (URDF's `<mesh scale>`), and checks it
    /// ([`Mesh::check_manifold`]): the mesh and how many edges of holes it has.
    pub fn read(path: &Path, scale: [f64; 3]) -> Result<(Mesh, usize), GeometryError> {
        let name = path.display().to_string();
        let fail = |why: String| GeometryError::Mesh {
            file: name.clone(),
            why,
        };
        let bytes = cps_files::read::read_bytes(path, MAX_MESH_BYTES, "collision mesh")
            .map_err(|e| fail(e.reason()))?;
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let mesh = match ext.as_str() {
            "stl" => Mesh::from_stl(&bytes, &name)?,
            "obj" => Mesh::from_obj(&bytes, &name)?,
            other => {
                return Err(fail(format!(
                    "a mesh of type `{other}`: cps reads STL and OBJ here (COLLADA's DAE where robot files are read)"
                )));
            }
        };
        mesh.scaled(scale, &name)
    }

    /// An STL file's triangles (binary, or ASCII when it starts with `solid` and is not
    /// the size a binary file of its triangle count would be).
    pub fn from_stl(bytes: &[u8], name: &str) -> Result<Mesh, GeometryError> {
        let fail = |why: String| GeometryError::Mesh {
            file: name.to_string(),
            why,
        };
        let binary_size = |b: &[u8]| {
            (b.len() >= 84)
                .then(|| 84 + 50 * u32::from_le_bytes([b[80], b[81], b[82], b[83]]) as usize)
        };
        let ascii = bytes.starts_with(b"solid") && binary_size(bytes) != Some(bytes.len());
        let mut builder = Builder::default();
        if ascii {
            let text = std::str::from_utf8(bytes)
                .map_err(|_| fail("an ASCII STL with bytes that are not text".into()))?;
            let mut corners: Vec<(V, usize)> = Vec::new();
            for (n, line) in text.lines().enumerate() {
                let mut words = line.split_whitespace();
                if words.next() != Some("vertex") {
                    continue;
                }
                let mut v = V::zeros();
                for (k, c) in v.iter_mut().enumerate() {
                    let w = words.next().ok_or_else(|| {
                        fail(format!(
                            "line {}: a vertex with {k} coordinates, not 3",
                            n + 1
                        ))
                    })?;
                    *c = number(w)
                        .ok_or_else(|| fail(format!("line {}: `{w}` is not a number", n + 1)))?;
                }
                corners.push((v, n + 1));
                if corners.len() == 3 {
                    let place = format!("line {}", corners[0].1);
                    builder.triangle([corners[0].0, corners[1].0, corners[2].0], place);
                    corners.clear();
                }
            }
            if !corners.is_empty() {
                return Err(fail(format!(
                    "line {}: a facet with {} vertices, not 3",
                    corners[0].1,
                    corners.len()
                )));
            }
        } else {
            let Some(expected) = binary_size(bytes) else {
                return Err(fail(format!(
                    "{} bytes: too short for a binary STL (84 at least) and not an ASCII one",
                    bytes.len()
                )));
            };
            if expected != bytes.len() {
                return Err(fail(format!(
                    "a binary STL of {} triangles is {expected} bytes, this file {}: it is cut short or not an STL",
                    (expected - 84) / 50,
                    bytes.len()
                )));
            }
            for (t, chunk) in bytes[84..].chunks_exact(50).enumerate() {
                let f = |k: usize| {
                    let o = 12 + 4 * k;
                    f32::from_le_bytes([chunk[o], chunk[o + 1], chunk[o + 2], chunk[o + 3]]) as f64
                };
                let corner = |c: usize| V::new(f(3 * c), f(3 * c + 1), f(3 * c + 2));
                builder.triangle(
                    [corner(0), corner(1), corner(2)],
                    format!("triangle {}", t + 1),
                );
            }
        }
        builder.finish(name)
    }

    /// A mesh of `triangles` (three corners each, and where each came from in its file,
    /// for messages) as another format's reader gives them: corners with identical
    /// coordinates merged, triangles without area left out. Errors: no triangles, a corner
    /// that is not finite.
    pub fn from_triangles(
        triangles: impl IntoIterator<Item = ([V; 3], String)>,
        name: &str,
    ) -> Result<Mesh, GeometryError> {
        let mut builder = Builder::default();
        for (corners, place) in triangles {
            builder.triangle(corners, place);
        }
        builder.finish(name)
    }

    /// Scales every corner by `scale` (URDF's `<mesh scale>`), then checks the mesh
    /// ([`Mesh::check_manifold`]): the mesh and how many edges of holes it has.
    pub fn scaled(mut self, scale: [f64; 3], name: &str) -> Result<(Mesh, usize), GeometryError> {
        for v in &mut self.vertices {
            for k in 0..3 {
                v[k] *= scale[k];
            }
        }
        let holes = self.check_manifold(name)?;
        Ok((self, holes))
    }

    /// A Wavefront OBJ file's faces (`v x y z` and `f a b c …`, polygons fanned into
    /// triangles; `a/b/c` and negative indices as the format allows).
    pub fn from_obj(bytes: &[u8], name: &str) -> Result<Mesh, GeometryError> {
        let fail = |line: usize, why: String| GeometryError::Mesh {
            file: format!("{name}, line {line}"),
            why,
        };
        let text = std::str::from_utf8(bytes).map_err(|_| GeometryError::Mesh {
            file: name.to_string(),
            why: "bytes that are not text: not an OBJ file".into(),
        })?;
        let mut points: Vec<V> = Vec::new();
        let mut builder = Builder::default();
        for (n, line) in text.lines().enumerate() {
            let line_no = n + 1;
            let mut words = line.split_whitespace();
            match words.next() {
                Some("v") => {
                    let mut v = V::zeros();
                    for (k, c) in v.iter_mut().enumerate() {
                        let w = words.next().ok_or_else(|| {
                            fail(line_no, format!("a vertex with {k} coordinates, not 3"))
                        })?;
                        *c = number(w)
                            .ok_or_else(|| fail(line_no, format!("`{w}` is not a number")))?;
                    }
                    points.push(v);
                }
                Some("f") => {
                    let mut corners = Vec::new();
                    for (col, w) in words.enumerate() {
                        let first = w.split('/').next().unwrap_or("");
                        let i: i64 = first.parse().map_err(|_| {
                            fail(
                                line_no,
                                format!("corner {}: `{w}` is not a vertex number", col + 1),
                            )
                        })?;
                        let index = if i > 0 {
                            i - 1
                        } else {
                            points.len() as i64 + i
                        };
                        if i == 0 || index < 0 || index >= points.len() as i64 {
                            return Err(fail(
                                line_no,
                                format!(
                                    "corner {}: vertex {i} does not exist ({} vertices so far)",
                                    col + 1,
                                    points.len()
                                ),
                            ));
                        }
                        corners.push(points[index as usize]);
                    }
                    if corners.len() < 3 {
                        return Err(fail(
                            line_no,
                            format!("a face with {} corners", corners.len()),
                        ));
                    }
                    for k in 1..corners.len() - 1 {
                        builder.triangle(
                            [corners[0], corners[k], corners[k + 1]],
                            format!("line {line_no}"),
                        );
                    }
                }
                _ => {}
            }
        }
        builder.finish(name)
    }

    /// Refuses a surface with an edge that three or more triangles share, and returns how
    /// many edges belong to one triangle only (the edges of holes).
    pub fn check_manifold(&self, name: &str) -> Result<usize, GeometryError> {
        // Each edge's count of triangles, and the first triangle (and its side) with it.
        let mut uses: HashMap<(u32, u32), (u32, (usize, usize))> = HashMap::new();
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let e = uses.entry((a.min(b), a.max(b))).or_insert((0, (t, k)));
                e.0 += 1;
            }
        }
        let holes = uses.values().filter(|(n, _)| *n == 1).count();
        let mut bad: Vec<_> = uses.into_iter().filter(|(_, (n, _))| *n > 2).collect();
        bad.sort_by_key(|(_, (_, first))| *first);
        if let Some((_, (n, (t, k)))) = bad.first() {
            let (a, b) = (self.triangles[*t][*k], self.triangles[*t][(*k + 1) % 3]);
            let (pa, pb) = (self.vertices[a as usize], self.vertices[b as usize]);
            return Err(GeometryError::Mesh {
                file: format!("{name}, {}", self.places[*t]),
                why: format!(
                    "the edge from ({:.4}, {:.4}, {:.4}) to ({:.4}, {:.4}, {:.4}) belongs to {n} triangles: the mesh is not the surface of a solid (non-manifold; {} such edges in all)",
                    pa.x,
                    pa.y,
                    pa.z,
                    pb.x,
                    pb.y,
                    pb.z,
                    bad.len()
                ),
            });
        }
        Ok(holes)
    }

    /// The mesh's convex hull.
    pub fn hull(&self, name: &str) -> Result<Hull, GeometryError> {
        Hull::new(&self.vertices, name)
    }
}

fn number(w: &str) -> Option<f64> {
    w.parse::<f64>().ok().filter(|x| x.is_finite())
}

/// Collects triangles, merging corners with identical coordinates.
#[derive(Default)]
struct Builder {
    index: HashMap<[u64; 3], u32>,
    mesh: Mesh,
}

impl Builder {
    fn triangle(&mut self, corners: [V; 3], place: String) {
        let mut t = [0u32; 3];
        for (k, c) in corners.iter().enumerate() {
            // +0.0 and -0.0 are one coordinate.
            let key = [c.x + 0.0, c.y + 0.0, c.z + 0.0].map(f64::to_bits);
            t[k] = *self.index.entry(key).or_insert_with(|| {
                self.mesh.vertices.push(*c);
                (self.mesh.vertices.len() - 1) as u32
            });
        }
        // A triangle with two equal corners has no area and no edges of its own.
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            self.mesh.triangles.push(t);
            self.mesh.places.push(place);
        }
    }

    fn finish(self, name: &str) -> Result<Mesh, GeometryError> {
        if self.mesh.triangles.is_empty() {
            return Err(GeometryError::Mesh {
                file: name.to_string(),
                why: "no triangles: the mesh is empty".into(),
            });
        }
        if let Some(i) = self
            .mesh
            .vertices
            .iter()
            .position(|v| !v.iter().all(|x| x.is_finite()))
        {
            return Err(GeometryError::NotFinite {
                what: name.to_string(),
                index: i,
            });
        }
        Ok(self.mesh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tetrahedron as ASCII STL, with one facet's lines given.
    fn tetra_ascii(drop_last_facet: bool) -> String {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let mut s = String::from("solid t\n");
        let n = if drop_last_facet { 3 } else { 4 };
        for f in &faces[..n] {
            s += "facet normal 0 0 0\n outer loop\n";
            for &i in f {
                s += &format!("  vertex {} {} {}\n", p[i][0], p[i][1], p[i][2]);
            }
            s += " endloop\nendfacet\n";
        }
        s + "endsolid t\n"
    }

    fn binary(tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
        for t in tris {
            b.extend_from_slice(&[0u8; 12]);
            for c in t {
                for x in c {
                    b.extend_from_slice(&x.to_le_bytes());
                }
            }
            b.extend_from_slice(&[0u8; 2]);
        }
        b
    }

    #[test]
    fn an_ascii_tetrahedron_reads_as_four_corners_holes_are_counted_and_a_fin_is_named_by_its_line()
    {
        let m = Mesh::from_stl(tetra_ascii(false).as_bytes(), "t.stl").unwrap();
        assert_eq!((m.vertices.len(), m.triangles.len()), (4, 4));
        assert_eq!(m.check_manifold("t.stl").unwrap(), 0);
        let open = Mesh::from_stl(tetra_ascii(true).as_bytes(), "t.stl").unwrap();
        assert_eq!(open.check_manifold("t.stl").unwrap(), 3);
        assert_eq!(
            open.hull("t.stl").unwrap().faces().len(),
            4,
            "the hull closes the hole"
        );
        // A fourth triangle on the edge from corner 0 to corner 1: three share it.
        let fin = tetra_ascii(false).replace(
            "endsolid t",
            "facet normal 0 0 0\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0.5 -1 0.5\n endloop\nendfacet\nendsolid t",
        );
        let m = Mesh::from_stl(fin.as_bytes(), "fin.stl").unwrap();
        assert_eq!(
            m.check_manifold("fin.stl").unwrap_err().to_string(),
            "fin.stl, line 4: the edge from (1.0000, 0.0000, 0.0000) to (0.0000, 0.0000, 0.0000) belongs to 3 triangles: the mesh is not the surface of a solid (non-manifold; 1 such edges in all)"
        );
    }

    #[test]
    fn a_binary_stl_cut_short_or_empty_is_refused() {
        let t = [[[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]];
        let full = binary(&t);
        assert_eq!(Mesh::from_stl(&full, "b.stl").unwrap().triangles.len(), 1);
        let cut = &full[..full.len() - 3];
        assert_eq!(
            Mesh::from_stl(cut, "b.stl").unwrap_err().to_string(),
            "b.stl: a binary STL of 1 triangles is 134 bytes, this file 131: it is cut short or not an STL"
        );
        assert_eq!(
            Mesh::from_stl(&binary(&[]), "e.stl")
                .unwrap_err()
                .to_string(),
            "e.stl: no triangles: the mesh is empty"
        );
        assert!(
            Mesh::from_stl(b"12", "x.stl")
                .unwrap_err()
                .to_string()
                .contains("too short")
        );
    }

    #[test]
    fn obj_faces_fan_into_triangles_and_bad_indices_name_line_and_corner() {
        let cube = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                    f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
        let m = Mesh::from_obj(cube.as_bytes(), "c.obj").unwrap();
        assert_eq!((m.vertices.len(), m.triangles.len()), (8, 12));
        assert_eq!(m.check_manifold("c.obj").unwrap(), 0);
        let h = m.hull("c.obj").unwrap();
        assert_eq!(h.vertices().len(), 8);
        let bad = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n";
        assert_eq!(
            Mesh::from_obj(bad.as_bytes(), "b.obj")
                .unwrap_err()
                .to_string(),
            "b.obj, line 4: corner 3: vertex 9 does not exist (3 vertices so far)"
        );
        assert_eq!(
            Mesh::from_obj(b"v 0 0 zero\n", "n.obj")
                .unwrap_err()
                .to_string(),
            "n.obj, line 1: `zero` is not a number"
        );
    }
}
