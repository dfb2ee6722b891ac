//! A robot's collision geometry from its URDF: each `<collision>` element made a shape
//! of cps-geometry — boxes, cylinders, spheres and capsules as they are, meshes (STL, OBJ,
//! COLLADA) read from their files as convex hulls — carried by the chain frame the element
//! rides on.
//!
//! Mesh file names are found as ROS tools find them, without a ROS installation:
//! `package://PKG/path` is looked for as `PKG/path` or `path` in the URDF's folder and the
//! folders above it, `file:///abs/path` is that path, anything else is relative to the
//! URDF's folder. A mesh read once is shared by every element that names it at the same
//! scale.

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
    /// Further pairs the robot's description leaves out (an SRDF's disabled collisions),
    /// each with the closest approach a search of the joint ranges found
    /// ([`crate::left_out`]): left out only while farther apart than the margin.
    pub disabled: Vec<cps_robot::LeftOut>,
    /// What the user should know: links with shapes the chain cannot place, meshes with
    /// holes (their hulls close them).
    pub notes: Vec<String>,
}

impl RobotGeometry {
    /// The shapes the guard checks: these bodies at [`cps_robot::DEFAULT_MARGIN`], the
    /// adjacent pairs never checked, the disabled ones while they keep the margin.
    pub fn shapes(self) -> cps_robot::Shapes {
        let mut left_out = cps_robot::LeftOut::each(self.adjacent, cps_robot::Why::Joined);
        left_out.extend(self.disabled);
        cps_robot::Shapes::leaving_out(self.bodies, left_out)
    }
}

/// Reads a mesh file — STL, OBJ ([`Mesh::read`]) or COLLADA ([`crate::dae::read_dae`]),
/// by its extension — each coordinate multiplied by `scale`: the mesh and how many edges
/// of holes it has.
pub fn read_mesh(path: &Path, scale: [f64; 3]) -> Result<(Mesh, usize), String> {
    let dae = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("dae"));
    if dae {
        crate::dae::read_dae(path, scale)
    } else {
        Mesh::read(path, scale).map_err(|e| e.to_string())
    }
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

/// The bodies of the chain read from the URDF at `urdf` (its meshes read from beside it),
/// and the pairs `ROBOT.srdf` beside `ROBOT.urdf` disables, when there is one, verified
/// over the joint ranges ([`crate::left_out`]: searched once, cached beside the URDF as
/// `ROBOT.pairs.json`). Errors name the file, the line of the element and the mesh.
pub fn urdf_geometry(chain: &UrdfChain, urdf: &Path) -> Result<RobotGeometry, InputError> {
    let mut meshes: HashMap<(PathBuf, [u64; 3]), Arc<cps_geometry::Hull>> = HashMap::new();
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
                // One hull per file and scale.
                let key = (path, scale.map(f64::to_bits));
                let hull = match meshes.get(&key) {
                    Some(h) => h.clone(),
                    None => {
                        let name = key.0.display().to_string();
                        let (mesh, holes) = read_mesh(&key.0, *scale).map_err(|m| at(e.line, m))?;
                        let hull =
                            Arc::new(mesh.hull(&name).map_err(|m| at(e.line, m.to_string()))?);
                        if holes > 0 {
                            notes.push(format!(
                                "{name} has {holes} edges of holes; its convex hull closes them"
                            ));
                        }
                        meshes.insert(key, hull.clone());
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
    // The pairs its SRDF disables, from `ROBOT.srdf` beside `ROBOT.urdf`.
    let srdf = urdf.with_extension("srdf");
    let disabled = if srdf.is_file() {
        let text = cps_outcome::source::read_text(
            &srdf,
            cps_outcome::source::MAX_FILE_BYTES,
            "SRDF file",
        )?;
        let declared = cps_kinematics::disabled_collisions(&text)
            .map_err(|m| InputError(format!("{}: {m}", srdf.display())))?;
        // Those a joint joins need no search.
        let joined = |a: &String, b: &String| {
            chain
                .adjacent
                .iter()
                .any(|(x, y)| (x == a && y == b) || (x == b && y == a))
        };
        let declared = declared
            .into_iter()
            .filter(|(a, b)| !joined(a, b))
            .collect();
        let urdf_text = cps_outcome::source::read_text(
            urdf,
            cps_outcome::source::MAX_FILE_BYTES,
            "robot file",
        )?;
        crate::left_out::verified(
            &chain.chain,
            &bodies,
            declared,
            (urdf, &urdf_text),
            &text,
            &mut notes,
        )
    } else {
        Vec::new()
    };
    Ok(RobotGeometry {
        bodies,
        adjacent: chain.adjacent.clone(),
        disabled,
        notes,
    })
}

/// Which Franka arm's collision meshes ([`franka_geometry`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrankaArm {
    /// Franka Research 3.
    Fr3,
    /// Franka Emika Panda (franka_description's `fer`).
    Panda,
}

/// franka_description's collision meshes (configs/robots/franka, Apache-2.0, its NOTICE
/// beside them), built in: link0 … link7 of each arm and the Franka Hand.
const FR3_MESHES: [&[u8]; 8] = [
    include_bytes!("../../../configs/robots/franka/fr3/link0.stl"),
    include_bytes!("../../../configs/robots/franka/fr3/link1.stl"),
    include_bytes!("../../../configs/robots/franka/fr3/link2.stl"),
    include_bytes!("../../../configs/robots/franka/fr3/link3.stl"),
    include_bytes!("../../../configs/robots/franka/fr3/link4.stl"),
    include_bytes!("../../../configs/robots/franka/fr3/link5.stl"),
    include_bytes!("../../../configs/robots/franka/fr3/link6.stl"),
    include_bytes!("../../../configs/robots/franka/fr3/link7.stl"),
];
const PANDA_MESHES: [&[u8]; 8] = [
    include_bytes!("../../../configs/robots/franka/fer/link0.stl"),
    include_bytes!("../../../configs/robots/franka/fer/link1.stl"),
    include_bytes!("../../../configs/robots/franka/fer/link2.stl"),
    include_bytes!("../../../configs/robots/franka/fer/link3.stl"),
    include_bytes!("../../../configs/robots/franka/fer/link4.stl"),
    include_bytes!("../../../configs/robots/franka/fer/link5.stl"),
    include_bytes!("../../../configs/robots/franka/fer/link6.stl"),
    include_bytes!("../../../configs/robots/franka/fer/link7.stl"),
];
const HAND_MESH: &[u8] = include_bytes!("../../../configs/robots/franka/hand.stl");

/// How far each finger of the hand is open in the built-in model (m): fully, the most room
/// the hand can take.
pub const FINGER_OPENING: f64 = 0.04;

fn built_in_hull(bytes: &[u8], name: &str) -> Arc<cps_geometry::Hull> {
    let mesh = Mesh::from_stl(bytes, name).expect("a built-in mesh reads");
    Arc::new(mesh.hull(name).expect("a built-in mesh has a hull"))
}

/// A Franka arm's collision bodies on its built-in chain's frames (the modified DH frames
/// of `cps_kinematics::robots`, which are franka_description's link frames), with the hand
/// and its fingers (open, [`FINGER_OPENING`]) when `hand`. The same as franka_description's
/// URDF read by [`urdf_geometry`] (tested against franky-sim's).
pub fn franka_geometry(arm: FrankaArm, hand: bool) -> RobotGeometry {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    let (prefix, meshes) = match arm {
        FrankaArm::Fr3 => ("fr3", &FR3_MESHES),
        FrankaArm::Panda => ("panda", &PANDA_MESHES),
    };
    let name = |part: &str| format!("{prefix}_{part}");
    let mut bodies: Vec<Body> = meshes
        .iter()
        .enumerate()
        .map(|(k, bytes)| Body {
            link: name(&format!("link{k}")),
            frame: k,
            origin: Isometry3::identity(),
            shape: Shape::Convex(built_in_hull(bytes, &format!("{prefix} link{k}"))),
        })
        .collect();
    let mut adjacent: Vec<(String, String)> = (0..7)
        .map(|k| (name(&format!("link{k}")), name(&format!("link{}", k + 1))))
        .collect();
    if hand {
        // The flange 0.107 m along link 7's z, the hand turned −45° about it.
        let at_hand = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.107),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -std::f64::consts::FRAC_PI_4),
        );
        bodies.push(Body {
            link: name("hand"),
            frame: 7,
            origin: at_hand,
            shape: Shape::Convex(built_in_hull(HAND_MESH, "Franka Hand")),
        });
        adjacent.push((name("link7"), name("hand")));
        // Each finger: four boxes (centre, rpy, size), 0.0584 m along the hand's z, slid open
        // along its y; the right finger turned half a turn about z, its tilted box mirrored.
        let boxes = |tilt: [f64; 3]| {
            [
                ([0.0, 0.0185, 0.011], [0.0; 3], [0.022, 0.015, 0.020]),
                ([0.0, 0.0068, 0.0022], [0.0; 3], [0.022, 0.0088, 0.0038]),
                ([0.0, 0.0159, 0.02835], tilt, [0.0175, 0.007, 0.0235]),
                ([0.0, 0.00758, 0.04525], [0.0; 3], [0.0175, 0.0152, 0.0185]),
            ]
        };
        let (pi, pi_6) = (std::f64::consts::PI, std::f64::consts::FRAC_PI_6);
        for (finger, turn, tilt) in [
            ("leftfinger", 0.0, [pi_6, 0.0, 0.0]),
            ("rightfinger", pi, [-pi_6, 0.0, pi]),
        ] {
            let at_finger = at_hand
                * Isometry3::from_parts(
                    Translation3::new(0.0, 0.0, 0.0584),
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn),
                )
                * Isometry3::translation(0.0, FINGER_OPENING, 0.0);
            for (xyz, rpy, size) in boxes(tilt) {
                bodies.push(Body {
                    link: name(finger),
                    frame: 7,
                    origin: at_finger
                        * Isometry3::from_parts(
                            Translation3::new(xyz[0], xyz[1], xyz[2]),
                            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
                        ),
                    shape: Shape::cuboid(size, "a finger's box").expect("a built-in box"),
                });
            }
            adjacent.push((name("hand"), name(finger)));
        }
    }
    // franka_description's SRDF's pairs, with what the search found of each.
    let disabled = crate::left_out::franka_left_out(prefix, arm == FrankaArm::Fr3, hand);
    RobotGeometry {
        bodies,
        adjacent,
        disabled,
        notes: Vec::new(),
    }
}
