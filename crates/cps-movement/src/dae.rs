//! COLLADA (`.dae`) meshes, as robot descriptions name them: the triangles of every
//! geometry a visual scene's nodes place (their `<matrix>`, `<translate>`, `<rotate>` and
//! `<scale>` applied, nested nodes composed), in metres (`<unit meter>`) with z up
//! (`<up_axis>` `Y_UP` turned to it), read with cps's XML reader.
//!
//! A geometry's `<mesh>` gives its positions in a `<source>`'s `<float_array>`, named by
//! `<vertices>`; its `<triangles>`, `<polylist>` (polygons fanned) and `<polygons>` give
//! corners as indices into them, each corner `stride` indices long (one per `<input>`
//! offset), the `VERTEX` input's among them. A file without a visual scene is read as its
//! geometries, unplaced. Every error names the file and the line.

use std::collections::HashMap;
use std::path::Path;

use cps_geometry::Mesh;
use cps_kinematics::xml::{Element, parse_xml};
use nalgebra::{Matrix4, Point3, Rotation3, Unit, Vector3};

/// Reads the COLLADA file at `path`, each coordinate multiplied by `scale`, and checks the
/// mesh as every mesh is checked: the mesh and how many edges of holes it has.
pub fn read_dae(path: &Path, scale: [f64; 3]) -> Result<(Mesh, usize), String> {
    let name = path.display().to_string();
    let text = cps_outcome::source::read_text(path, cps_geometry::MAX_MESH_BYTES, "collision mesh")
        .map_err(|e| e.0)?;
    let triangles = dae_triangles(&text).map_err(|m| format!("{name}: {m}"))?;
    Mesh::from_triangles(triangles, &name)
        .and_then(|m| m.scaled(scale, &name))
        .map_err(|e| e.to_string())
}

type Corner = Vector3<f64>;

/// The most indices a corner may have (one per `<input>` offset; files use 1 to 4).
const MAX_INPUTS: usize = 64;

/// The most triangles a COLLADA file may place, instances counted (a robot's link mesh
/// has thousands; 2 million placed triangles with their sources are about 200 MB).
const MAX_TRIANGLES: u64 = 2_000_000;

/// The triangles of a COLLADA document, each with where it came from.
pub fn dae_triangles(text: &str) -> Result<Vec<([Corner; 3], String)>, String> {
    let root = parse_xml(text)?;
    if root.name() != "COLLADA" {
        return Err(format!(
            "line {}: the root element is <{}>, not COLLADA's",
            root.line(),
            root.name()
        ));
    }
    let asset = root.child("asset");
    let unit = match asset
        .and_then(|a| a.child("unit"))
        .and_then(|u| u.attr("meter"))
    {
        Some(m) => number(m)
            .filter(|m| *m > 0.0)
            .ok_or_else(|| format!("<unit meter=\"{m}\">: not a positive number of metres"))?,
        None => 1.0,
    };
    let up = asset
        .and_then(|a| a.child("up_axis"))
        .map_or("Z_UP", |u| u.text().trim());
    let to_z_up = match up {
        "Z_UP" => Matrix4::identity(),
        // y up, z towards the viewer: turned a quarter about x, y becomes z.
        "Y_UP" => Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2)
            .to_homogeneous(),
        other => return Err(format!("<up_axis> {other}: cps reads Z_UP and Y_UP")),
    };
    let root_transform = to_z_up * Matrix4::new_scaling(unit);
    let geometries: HashMap<&str, &Element> = root
        .children("library_geometries")
        .flat_map(|l| l.children("geometry"))
        .filter_map(|g| g.attr("id").map(|id| (id, g)))
        .collect();
    let mut placed: Vec<(&Element, Matrix4<f64>)> = Vec::new();
    let scene = root
        .children("library_visual_scenes")
        .flat_map(|l| l.children("visual_scene"))
        .next();
    match scene {
        Some(scene) => {
            // Nodes depth first, each with its parent's transform (no recursion).
            let mut stack: Vec<(&Element, Matrix4<f64>)> = scene
                .children("node")
                .map(|n| (n, root_transform))
                .collect();
            while let Some((node, parent)) = stack.pop() {
                let here = parent * node_transform(node)?;
                for g in node.children("instance_geometry") {
                    let url = g.attr("url").unwrap_or("");
                    let id = url.strip_prefix('#').unwrap_or(url);
                    let geometry = geometries.get(id).ok_or_else(|| {
                        format!("line {}: no geometry `{id}` in the file", g.line())
                    })?;
                    placed.push((geometry, here));
                }
                stack.extend(node.children("node").map(|n| (n, here)));
            }
        }
        None => placed.extend(geometries.values().map(|g| (*g, root_transform))),
    }
    let mut out = Vec::new();
    for (geometry, transform) in placed {
        if let Some(mesh) = geometry.child("mesh") {
            mesh_triangles(mesh, &transform, &mut out)?;
        }
    }
    Ok(out)
}

fn number(w: &str) -> Option<f64> {
    w.parse::<f64>().ok().filter(|x| x.is_finite())
}

/// The numbers of an element's text, or which word is not one, on its line (the text
/// starts on the start tag's line).
fn numbers(e: &Element) -> Result<Vec<f64>, String> {
    let mut out = Vec::new();
    for (n, line) in e.text().split('\n').enumerate() {
        for w in line.split_whitespace() {
            out.push(
                number(w).ok_or_else(|| format!("line {}: `{w}` is not a number", e.line() + n))?,
            );
        }
    }
    Ok(out)
}

/// A node's own transform: its `<matrix>`, `<translate>`, `<rotate>` and `<scale>` in the
/// order written.
fn node_transform(node: &Element) -> Result<Matrix4<f64>, String> {
    let mut m = Matrix4::identity();
    for e in node.elements() {
        let v = match e.name() {
            "matrix" | "translate" | "rotate" | "scale" => numbers(e)?,
            _ => continue,
        };
        let want = match e.name() {
            "matrix" => 16,
            "rotate" => 4,
            _ => 3,
        };
        if v.len() != want {
            return Err(format!(
                "line {}: <{}> needs {want} numbers, not {}",
                e.line(),
                e.name(),
                v.len()
            ));
        }
        m *= match e.name() {
            "matrix" => Matrix4::from_row_slice(&v),
            "translate" => Matrix4::new_translation(&Vector3::new(v[0], v[1], v[2])),
            "scale" => Matrix4::new_nonuniform_scaling(&Vector3::new(v[0], v[1], v[2])),
            _ => {
                let axis = Vector3::new(v[0], v[1], v[2]);
                if axis.norm() == 0.0 {
                    return Err(format!("line {}: <rotate> about a zero axis", e.line()));
                }
                Rotation3::from_axis_angle(&Unit::new_normalize(axis), v[3].to_radians())
                    .to_homogeneous()
            }
        };
    }
    Ok(m)
}

/// The triangles of one `<mesh>`, placed by `transform`.
fn mesh_triangles(
    mesh: &Element,
    transform: &Matrix4<f64>,
    out: &mut Vec<([Corner; 3], String)>,
) -> Result<(), String> {
    // Sources by id, and <vertices> naming its POSITION source.
    let mut sources: HashMap<&str, Vec<f64>> = HashMap::new();
    for s in mesh.children("source") {
        if let (Some(id), Some(a)) = (s.attr("id"), s.child("float_array")) {
            sources.insert(id, numbers(a)?);
        }
    }
    let mut vertices: HashMap<&str, &str> = HashMap::new();
    for v in mesh.children("vertices") {
        let position = v
            .children("input")
            .find(|i| i.attr("semantic") == Some("POSITION"))
            .and_then(|i| i.attr("source"));
        if let (Some(id), Some(src)) = (v.attr("id"), position) {
            vertices.insert(id, src.trim_start_matches('#'));
        }
    }
    for prim in mesh.elements() {
        let kind = prim.name();
        if !matches!(kind, "triangles" | "polylist" | "polygons") {
            continue;
        }
        let inputs: Vec<&Element> = prim.children("input").collect();
        let mut stride = 1;
        for i in &inputs {
            match i.attr("offset").map(str::parse::<usize>) {
                None => {}
                Some(Ok(o)) if o < MAX_INPUTS => stride = stride.max(o + 1),
                Some(_) => {
                    return Err(format!(
                        "line {}: an <input> offset of {}: a corner has at most {MAX_INPUTS} indices",
                        i.line(),
                        i.attr("offset").unwrap_or("")
                    ));
                }
            }
        }
        let Some(vertex) = inputs.iter().find(|i| i.attr("semantic") == Some("VERTEX")) else {
            return Err(format!(
                "line {}: <{kind}> has no VERTEX input",
                prim.line()
            ));
        };
        let offset = vertex
            .attr("offset")
            .and_then(|o| o.parse::<usize>().ok())
            .unwrap_or(0);
        let target = vertex.attr("source").unwrap_or("").trim_start_matches('#');
        let source = vertices.get(target).copied().unwrap_or(target);
        let positions = sources.get(source).ok_or_else(|| {
            format!(
                "line {}: <{kind}> reads positions from `{target}`, which the mesh does not have",
                prim.line()
            )
        })?;
        let count = positions.len() / 3;
        let corner = |p: &Element, k: usize, index: f64| -> Result<Corner, String> {
            let i = index as usize;
            if index < 0.0 || index.fract() != 0.0 || i >= count {
                return Err(format!(
                    "line {}: corner {} of <{kind}> is vertex {index}, of {count}",
                    p.line(),
                    k + 1
                ));
            }
            let local = Point3::new(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
            Ok(transform.transform_point(&local).coords)
        };
        // Polygons: (their <p>, corner counts).
        let polygons: Vec<(&Element, Vec<usize>)> = match kind {
            "triangles" => prim
                .child("p")
                .map(|p| {
                    let n = p.text().split_whitespace().count() / stride;
                    (p, vec![3; n / 3])
                })
                .into_iter()
                .collect(),
            "polylist" => {
                let counts = prim
                    .child("vcount")
                    .map(numbers)
                    .transpose()?
                    .unwrap_or_default();
                // Each count a whole number of corners the <p> could hold.
                if let Some(c) = counts
                    .iter()
                    .find(|c| !(c.fract() == 0.0 && (3.0..=1e6).contains(*c)))
                {
                    return Err(format!(
                        "line {}: <vcount> gives a polygon {c} corners; a polygon has 3 to a million",
                        prim.line()
                    ));
                }
                prim.child("p")
                    .map(|p| (p, counts.iter().map(|c| *c as usize).collect()))
                    .into_iter()
                    .collect()
            }
            _ => prim
                .children("p")
                .map(|p| {
                    let n = p.text().split_whitespace().count() / stride;
                    (p, vec![n])
                })
                .collect(),
        };
        for (p, counts) in polygons {
            let idx = numbers(p)?;
            let corners = counts.iter().fold(0usize, |a, c| a.saturating_add(*c));
            if idx.len() < corners.saturating_mul(stride) {
                return Err(format!(
                    "line {}: <{kind}> names {corners} corners of {stride} indices each, and <p> has {} indices",
                    p.line(),
                    idx.len()
                ));
            }
            let mut at = 0;
            for n in counts {
                if n < 3 {
                    return Err(format!("line {}: a polygon of {n} corners", p.line()));
                }
                let c = |k: usize| corner(p, at + k, idx[(at + k) * stride + offset]);
                // Instancing multiplies triangles: counted before they are held.
                cps_files::count::within(
                    (out.len() + n - 2) as f64,
                    MAX_TRIANGLES,
                    &format!("line {}: triangles after instancing", p.line()),
                    "a collision mesh is simplified before it is checked (a hull needs its outline, not its detail)",
                )
                .map_err(|e| e.to_string())?;
                let first = c(0)?;
                for k in 1..n - 1 {
                    out.push(([first, c(k)?, c(k + 1)?], format!("line {}", p.line())));
                }
                at += n;
            }
        }
    }
    Ok(())
}
