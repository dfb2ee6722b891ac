//! A robot's collision geometry from its URDF: each `<collision>` element made a shape
//! of cps-geometry — boxes, cylinders, spheres and capsules as they are, meshes read from
//! their files as convex hulls — carried by the chain frame the element rides on.
//!
//! Mesh file names are found as ROS tools find them, without a ROS installation:
//! `package://PKG/path` is looked for as `PKG/path` or `path` in the URDF's folder and the
//! folders above it, `file:///abs/path` is that path, anything else is relative to the
//! URDF's folder. A mesh read once is shared by every element that names it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use cps_geometry::{Body, Mesh, Shape};
use cps_kinematics::{CollisionGeometry, UrdfChain};
use cps_outcome::InputError;

/// How far up from the URDF's folder a `package://` mesh is looked for.
const PACKAGE_SEARCH_DEPTH: usize = 4;

/// A robot's bodies and the pairs of links never checked against each other.
#[derive(Debug, Clone)]
pub struct RobotGeometry {
    /// One body per collision element.
    pub bodies: Vec<Body>,
    /// Links a joint joins (they touch at the joint).
    pub adjacent: Vec<(String, String)>,
    /// What the user should know: links with shapes the chain cannot place, meshes with
    /// holes (their hulls close them).
    pub notes: Vec<String>,
}

/// Where a URDF's mesh `filename` is, from the URDF at `urdf`.
pub fn find_mesh(filename: &str, urdf: &Path) -> Result<PathBuf, String> {
    let dir = urdf.parent().unwrap_or(Path::new("."));
    if let Some(abs) = filename.strip_prefix("file://") {
        let p = PathBuf::from(abs);
        return if p.is_file() {
            Ok(p)
        } else {
            Err(format!("the mesh `{filename}` does not exist"))
        };
    }
    if let Some(rest) = filename.strip_prefix("package://") {
        let (package, path) = rest.split_once('/').unwrap_or((rest, ""));
        let mut at = Some(dir);
        for _ in 0..=PACKAGE_SEARCH_DEPTH {
            let Some(d) = at else { break };
            for candidate in [d.join(package).join(path), d.join(path)] {
                if !path.is_empty() && candidate.is_file() {
                    return Ok(candidate);
                }
            }
            at = d.parent();
        }
        return Err(format!(
            "the mesh `{filename}` was looked for as `{package}/{path}` and `{path}` in {} and the {PACKAGE_SEARCH_DEPTH} folders above it, and is not there",
            dir.display()
        ));
    }
    let p = dir.join(filename);
    if p.is_file() {
        Ok(p)
    } else {
        Err(format!("the mesh `{filename}` is not at {}", p.display()))
    }
}

/// The bodies of the chain read from the URDF at `urdf` (its meshes read from beside it).
/// Errors name the URDF, the line of the element and the mesh.
pub fn urdf_geometry(chain: &UrdfChain, urdf: &Path) -> Result<RobotGeometry, InputError> {
    let mut meshes: HashMap<PathBuf, (Arc<cps_geometry::Hull>, usize)> = HashMap::new();
    let mut bodies = Vec::with_capacity(chain.collisions.len());
    let mut notes = Vec::new();
    let at = |line: usize, why: String| {
        InputError(format!("{}:{line}: link collision: {why}", urdf.display()))
    };
    for e in &chain.collisions {
        let what = format!("link `{}`", e.link);
        let shape = match &e.geometry {
            CollisionGeometry::Box { size } => Shape::cuboid(*size, &what),
            CollisionGeometry::Cylinder { radius, length } => {
                Shape::cylinder(*radius, *length, &what)
            }
            CollisionGeometry::Sphere { radius } => Shape::sphere(*radius, &what),
            CollisionGeometry::Capsule { radius, length } => {
                Shape::capsule(*radius, *length, &what)
            }
            CollisionGeometry::Mesh { filename, scale } => {
                let path = find_mesh(filename, urdf).map_err(|m| at(e.line, m))?;
                let key = path.clone();
                let hull = match meshes.get(&key) {
                    Some((h, _)) => h.clone(),
                    None => {
                        let mesh =
                            Mesh::read(&path, *scale).map_err(|m| at(e.line, m.to_string()))?;
                        let holes = mesh
                            .check_manifold(&path.display().to_string())
                            .map_err(|m| at(e.line, m.to_string()))?;
                        let hull = Arc::new(
                            mesh.hull(&path.display().to_string())
                                .map_err(|m| at(e.line, m.to_string()))?,
                        );
                        if holes > 0 {
                            notes.push(format!(
                                "{} has {holes} edges of holes; its convex hull closes them",
                                path.display()
                            ));
                        }
                        meshes.insert(key, (hull.clone(), holes));
                        hull
                    }
                };
                Ok(Shape::Convex(hull))
            }
        }
        .map_err(|m| at(e.line, m.to_string()))?;
        bodies.push(Body {
            link: e.link.clone(),
            frame: e.frame,
            origin: e.origin,
            shape,
        });
    }
    for link in &chain.unplaced {
        notes.push(format!(
            "link `{link}` has collision shapes behind a joint off the chain: they are not checked"
        ));
    }
    Ok(RobotGeometry {
        bodies,
        adjacent: chain.adjacent.clone(),
        notes,
    })
}
