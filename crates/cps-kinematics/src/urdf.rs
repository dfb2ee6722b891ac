//! Serial chains from URDF (Unified Robot Description Format) text, so users can bring any
//! arm whose description they have. The XML is read here (the part robot descriptions use:
//! elements and attributes; text, comments and unknown elements such as visuals and
//! transmissions are passed over), every number checked, and the tree walked.
//!
//! The chain runs from the root link (the one link that is no joint's child) to a tip link.
//! Fixed joints fold into the neighbouring transforms; revolute joints keep their limits
//! (position, and speed when every joint gives one); continuous joints are unlimited.
//! Prismatic, floating, planar, spherical and mimic joints on the path are refused with
//! the joint's name: cps chains are revolute.

use std::collections::HashMap;

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};

use crate::urdf_collision::{
    Carry, CollisionElement, CollisionGeometry, PlaceJoint, UrdfCollision, place,
};
use crate::xml::{Element, parse_xml};
use crate::{KinematicsError, LinkInertia, RevoluteJoint, SerialChain};

/// A joint's `type`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum JointType {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
    Floating,
    Planar,
}

/// `<origin xyz rpy>` (zero when absent).
#[derive(Debug, Clone, Copy, Default)]
struct Pose {
    xyz: [f64; 3],
    rpy: [f64; 3],
}

/// A link's `<inertial>` (zero when absent): its origin, mass and inertia tensor about the
/// centre of mass (`ixx ixy ixz iyy iyz izz`).
#[derive(Debug, Clone, Copy, Default)]
struct Inertial {
    origin: Pose,
    mass: f64,
    inertia: [f64; 6],
}

#[derive(Debug)]
struct Link {
    name: String,
    inertial: Inertial,
    collisions: Vec<UrdfCollision>,
}

/// A joint's `<limit>` (zero when absent or not given).
#[derive(Debug, Clone, Copy, Default)]
struct Limit {
    lower: f64,
    upper: f64,
    effort: f64,
    velocity: f64,
}

#[derive(Debug)]
struct Joint {
    name: String,
    joint_type: JointType,
    parent: String,
    child: String,
    origin: Pose,
    axis: [f64; 3],
    limit: Limit,
    mimic: bool,
}

#[derive(Debug)]
struct Robot {
    name: String,
    links: Vec<Link>,
    joints: Vec<Joint>,
}

/// A chain read from a URDF description.
#[derive(Debug, Clone)]
pub struct UrdfChain {
    /// The robot's `name` attribute.
    pub name: String,
    /// The chain, with limits, and the fixed joints after the last revolute one as its tool.
    pub chain: SerialChain,
    /// Names of the revolute joints in chain order.
    pub joint_names: Vec<String>,
    /// The root link.
    pub base_link: String,
    /// The tip link.
    pub tip_link: String,
    /// Torque limits from the joints' `<limit effort>`, when every joint gives one > 0.
    pub effort: Option<Vec<f64>>,
    /// Each moving link's `<inertial>` (with the links fixed to it merged in), when any
    /// moving link has a mass.
    pub inertia: Option<Vec<LinkInertia>>,
    /// Every `<collision>` element the chain carries, placed on its frames (empty when the
    /// description has none: nothing can then be checked for collisions).
    pub collisions: Vec<CollisionElement>,
    /// Links with collision elements behind a moving joint off the chain, which the
    /// chain's angles cannot place.
    pub unplaced: Vec<String>,
    /// Pairs of links with collision elements that a joint joins (looking through links
    /// without any): their shapes touch at the joint, so they are not checked against
    /// each other.
    pub adjacent: Vec<(String, String)>,
}

/// A link's `<inertial>` in the link's frame (its origin's rotation applied).
fn inertial(link: &Link) -> Result<LinkInertia, KinematicsError> {
    let i = &link.inertial;
    let own = LinkInertia::new(i.mass, [0.0; 3], i.inertia)
        .map_err(|e| invalid(format!("link `{}`: {e}", link.name)))?;
    let origin =
        pose(&i.origin).map_err(|m| invalid(format!("link `{}` inertial: {m}", link.name)))?;
    Ok(LinkInertia::combine(&[(own, origin)]))
}

fn invalid(msg: String) -> KinematicsError {
    KinematicsError::InvalidModel(format!("URDF: {msg}"))
}

fn pose(p: &Pose) -> Result<Isometry3<f64>, String> {
    if !p.xyz.iter().chain(p.rpy.iter()).all(|v| v.is_finite()) {
        return Err("origin has a non-finite value".into());
    }
    Ok(Isometry3::from_parts(
        Translation3::new(p.xyz[0], p.xyz[1], p.xyz[2]),
        UnitQuaternion::from_euler_angles(p.rpy[0], p.rpy[1], p.rpy[2]),
    ))
}

/// The largest URDF text [`chain_from_urdf`] reads: 16 MiB.
pub const MAX_URDF_BYTES: usize = 16 << 20;
/// The deepest element nesting [`chain_from_urdf`] accepts (checked before parsing, so a
/// hostile file cannot exhaust the parser's stack).
pub const MAX_URDF_DEPTH: usize = crate::xml::MAX_DEPTH;

/// A `<collision>`'s `<geometry>`: one shape, every size a positive number.
fn collision_geometry(c: &Element, what: &str) -> Result<CollisionGeometry, String> {
    let g = c
        .child("geometry")
        .ok_or_else(|| format!("line {}: {what} has no `<geometry>`", c.line))?;
    let Some(shape) = g.children.first() else {
        return Err(format!(
            "line {}: {what}: `<geometry>` holds no shape",
            g.line
        ));
    };
    let size = |key: &str| -> Result<f64, String> {
        if shape.attr(key).is_none() {
            return Err(format!(
                "line {}: {what}: `<{}>` has no `{key}`",
                shape.line, shape.name
            ));
        }
        let v = one(shape, key, what)?;
        if v > 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(format!(
                "line {}: {what}: `<{}>`'s `{key}` is {v}, not a positive number of metres",
                shape.line, shape.name
            ))
        }
    };
    Ok(match shape.name.as_str() {
        "box" => {
            if shape.attr("size").is_none() {
                return Err(format!(
                    "line {}: {what}: `<box>` has no `size`",
                    shape.line
                ));
            }
            let v = three(shape, "size", what, [0.0; 3])?;
            if let Some(bad) = v.iter().find(|x| !(**x > 0.0 && x.is_finite())) {
                return Err(format!(
                    "line {}: {what}: `<box>`'s `size` has {bad}, not a positive number of metres",
                    shape.line
                ));
            }
            CollisionGeometry::Box { size: v }
        }
        "cylinder" => CollisionGeometry::Cylinder {
            radius: size("radius")?,
            length: size("length")?,
        },
        "capsule" => CollisionGeometry::Capsule {
            radius: size("radius")?,
            length: size("length")?,
        },
        "sphere" => CollisionGeometry::Sphere {
            radius: size("radius")?,
        },
        "mesh" => {
            let filename = shape
                .attr("filename")
                .filter(|f| !f.trim().is_empty())
                .ok_or_else(|| format!("line {}: {what}: `<mesh>` has no `filename`", shape.line))?
                .to_string();
            let scale = three(shape, "scale", what, [1.0; 3])?;
            if let Some(bad) = scale.iter().find(|x| !(**x > 0.0 && x.is_finite())) {
                return Err(format!(
                    "line {}: {what}: `<mesh>`'s `scale` has {bad}, not a positive number",
                    shape.line
                ));
            }
            CollisionGeometry::Mesh { filename, scale }
        }
        other => {
            return Err(format!(
                "line {}: {what}: `<{other}>` is not a URDF shape (box, cylinder, sphere, capsule, mesh)",
                shape.line
            ));
        }
    })
}

/// How deeply the elements of `xml` nest, by a scan that needs no stack: comments,
/// processing instructions, declarations and quoted attribute values are skipped.
fn nesting_depth(xml: &str) -> usize {
    let b = xml.as_bytes();
    let (mut i, mut depth, mut max) = (0usize, 0usize, 0usize);
    let find = |from: usize, pat: &[u8]| {
        b[from.min(b.len())..]
            .windows(pat.len())
            .position(|w| w == pat)
            .map_or(b.len(), |p| from + p + pat.len())
    };
    while i < b.len() {
        if b[i] != b'<' {
            i += 1;
            continue;
        }
        match b.get(i + 1) {
            Some(b'!') if b[i..].starts_with(b"<!--") => i = find(i + 4, b"-->"),
            Some(b'!') if b[i..].starts_with(b"<![CDATA[") => i = find(i + 9, b"]]>"),
            Some(b'!') | Some(b'?') => i = find(i + 2, b">"),
            Some(b'/') => {
                depth = depth.saturating_sub(1);
                i = find(i + 2, b">");
            }
            _ => {
                // A start tag: to its `>`, outside quotes; `/>` closes it at once.
                let mut j = i + 1;
                let mut quote = None;
                while j < b.len() {
                    match (quote, b[j]) {
                        (None, b'"' | b'\'') => quote = Some(b[j]),
                        (Some(q), c) if c == q => quote = None,
                        (None, b'>') => break,
                        _ => {}
                    }
                    j += 1;
                }
                if j >= b.len() || b[j - 1] != b'/' {
                    depth += 1;
                    max = max.max(depth);
                }
                i = j + 1;
            }
        }
    }
    max
}

/// An attribute's numbers (none when it is absent).
fn numbers(e: &Element, key: &str, what: &str) -> Result<Vec<f64>, String> {
    match e.attr(key) {
        None => Ok(Vec::new()),
        Some(v) => v
            .split_whitespace()
            .map(|x| {
                x.parse::<f64>().map_err(|_| {
                    format!("line {}: {what}: `{key}` has `{x}`, not a number", e.line)
                })
            })
            .collect(),
    }
}

/// An attribute's three numbers (`default` when it is absent).
fn three(e: &Element, key: &str, what: &str, default: [f64; 3]) -> Result<[f64; 3], String> {
    let v = numbers(e, key, what)?;
    if e.attr(key).is_none() {
        return Ok(default);
    }
    <[f64; 3]>::try_from(v.as_slice()).map_err(|_| {
        format!(
            "line {}: {what}: `{key}` must be three numbers (got {})",
            e.line,
            v.len()
        )
    })
}

/// An attribute's one number (0 when it is absent).
fn one(e: &Element, key: &str, what: &str) -> Result<f64, String> {
    let v = numbers(e, key, what)?;
    match v.as_slice() {
        [] => Ok(0.0),
        [x] => Ok(*x),
        _ => Err(format!(
            "line {}: {what}: `{key}` must be one number",
            e.line
        )),
    }
}

/// An element's `<origin>` (none: the identity).
fn origin(parent: &Element, what: &str) -> Result<Pose, String> {
    Ok(match parent.child("origin") {
        Some(o) => Pose {
            xyz: three(o, "xyz", what, [0.0; 3])?,
            rpy: three(o, "rpy", what, [0.0; 3])?,
        },
        None => Pose::default(),
    })
}

/// An element's name, required.
fn element_name(e: &Element) -> Result<String, String> {
    e.attr("name")
        .map(str::to_string)
        .ok_or_else(|| format!("line {}: a `<{}>` without a name", e.line, e.name))
}

/// The robot of a URDF document: its links and joints with their numbers checked (`xyz`,
/// `rpy`, limits, masses, inertias), unknown elements passed over.
fn read_robot(xml: &str) -> Result<Robot, String> {
    let root = parse_xml(xml)?;
    if root.name != "robot" {
        return Err(format!(
            "line {}: the root element is `<{}>`, not `<robot>`",
            root.line, root.name
        ));
    }
    Ok(Robot {
        name: root.attr("name").unwrap_or_default().to_string(),
        links: root
            .children("link")
            .map(read_link)
            .collect::<Result<_, _>>()?,
        joints: root
            .children("joint")
            .map(read_joint)
            .collect::<Result<_, _>>()?,
    })
}

/// A `<link>`: its inertial and its collision shapes.
fn read_link(l: &Element) -> Result<Link, String> {
    let link = element_name(l)?;
    let what = format!("link `{link}`");
    let inertial = match l.child("inertial") {
        None => Inertial::default(),
        Some(i) => Inertial {
            origin: origin(i, &what)?,
            mass: match i.child("mass") {
                Some(m) => one(m, "value", &what)?,
                None => 0.0,
            },
            inertia: match i.child("inertia") {
                Some(m) => {
                    let mut t = [0.0; 6];
                    for (k, key) in ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"]
                        .iter()
                        .enumerate()
                    {
                        t[k] = one(m, key, &what)?;
                    }
                    t
                }
                None => [0.0; 6],
            },
        },
    };
    let mut collisions = Vec::new();
    for c in l.children("collision") {
        let what = format!("link `{link}` collision");
        let at = pose(&origin(c, &what)?).map_err(|m| format!("line {}: {what}: {m}", c.line))?;
        collisions.push(UrdfCollision {
            origin: at,
            geometry: collision_geometry(c, &what)?,
            line: c.line,
        });
    }
    Ok(Link {
        name: link,
        inertial,
        collisions,
    })
}

/// A `<joint>`: its type, its links, origin, axis and limits.
fn read_joint(j: &Element) -> Result<Joint, String> {
    let joint = element_name(j)?;
    let what = format!("joint `{joint}`");
    let joint_type = match j.attr("type") {
        Some("revolute") => JointType::Revolute,
        Some("continuous") => JointType::Continuous,
        Some("prismatic") => JointType::Prismatic,
        Some("fixed") => JointType::Fixed,
        Some("floating") => JointType::Floating,
        Some("planar") => JointType::Planar,
        Some(other) => {
            return Err(format!(
                "line {}: {what} has type `{other}`, not one of URDF's (revolute, continuous, prismatic, fixed, floating, planar)",
                j.line
            ));
        }
        None => return Err(format!("line {}: {what} has no type", j.line)),
    };
    let end = |role: &str| -> Result<String, String> {
        j.child(role)
            .and_then(|e| e.attr("link"))
            .map(str::to_string)
            .ok_or_else(|| format!("line {}: {what} has no `<{role} link=…>`", j.line))
    };
    let limit = match j.child("limit") {
        Some(l) => Limit {
            lower: one(l, "lower", &what)?,
            upper: one(l, "upper", &what)?,
            effort: one(l, "effort", &what)?,
            velocity: one(l, "velocity", &what)?,
        },
        None => Limit::default(),
    };
    Ok(Joint {
        joint_type,
        parent: end("parent")?,
        child: end("child")?,
        origin: origin(j, &what)?,
        axis: match j.child("axis") {
            Some(a) => three(a, "xyz", &what, [1.0, 0.0, 0.0])?,
            None => [1.0, 0.0, 0.0],
        },
        limit,
        mimic: j.child("mimic").is_some(),
        name: joint,
    })
}

/// Whole-model checks, before any walk: unique names, joints between existing links,
/// finite origins, finite non-zero axes where a joint moves, finite ordered limits.
fn validate(robot: &Robot) -> Result<(), KinematicsError> {
    let mut links = std::collections::HashSet::new();
    for l in &robot.links {
        if !links.insert(l.name.as_str()) {
            return Err(invalid(format!("two links are named `{}`", l.name)));
        }
    }
    let mut joints = std::collections::HashSet::new();
    for j in &robot.joints {
        let at = |m: String| invalid(format!("joint `{}`: {m}", j.name));
        if !joints.insert(j.name.as_str()) {
            return Err(invalid(format!("two joints are named `{}`", j.name)));
        }
        for (role, link) in [("parent", &j.parent), ("child", &j.child)] {
            if !links.contains(link.as_str()) {
                return Err(at(format!("its {role} link `{link}` does not exist")));
            }
        }
        if j.parent == j.child {
            return Err(at("its parent and child are the same link".into()));
        }
        pose(&j.origin).map_err(at)?;
        if !matches!(j.joint_type, JointType::Fixed) {
            let a = j.axis;
            let norm = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            if !(norm.is_finite() && norm > 1e-12) {
                return Err(at(format!(
                    "the axis is zero or not finite ({}, {}, {})",
                    a[0], a[1], a[2]
                )));
            }
        }
        if matches!(j.joint_type, JointType::Revolute | JointType::Prismatic) {
            let (lo, hi) = (j.limit.lower, j.limit.upper);
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(at(format!(
                    "limits must be finite with lower ≤ upper (got {lo} .. {hi})"
                )));
            }
        }
        let v = j.limit.velocity;
        if !(v.is_finite() && v >= 0.0) {
            return Err(at(format!(
                "the velocity limit must be finite and ≥ 0 (got {v})"
            )));
        }
    }
    Ok(())
}

/// The joints' tree: each link's parent joint, and the one root.
struct Tree<'a> {
    robot: &'a Robot,
    parent_joint: HashMap<&'a str, usize>,
    root: &'a str,
}

impl<'a> Tree<'a> {
    /// The tree of `robot`'s joints, refused when its links do not form one.
    fn of(robot: &'a Robot) -> Result<Self, KinematicsError> {
        let mut parent_joint: HashMap<&str, usize> = HashMap::new();
        for (i, j) in robot.joints.iter().enumerate() {
            if parent_joint.insert(j.child.as_str(), i).is_some() {
                return Err(invalid(format!(
                    "link `{}` is the child of two joints: not a tree",
                    j.child
                )));
            }
        }
        let roots: Vec<&str> = robot
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|l| !parent_joint.contains_key(l))
            .collect();
        let root = match roots.as_slice() {
            [r] => *r,
            [] => return Err(invalid("no root link (every link has a parent)".into())),
            many => {
                return Err(invalid(format!(
                    "several root links ({}): the links do not form one tree",
                    many.join(", ")
                )));
            }
        };
        Ok(Tree {
            robot,
            parent_joint,
            root,
        })
    }

    /// The path of joints from the root to a link, or None if it does not reach the root.
    fn path_to(&self, link: &str) -> Option<Vec<usize>> {
        let mut path = Vec::new();
        let mut at = link;
        while let Some(&j) = self.parent_joint.get(at) {
            if path.len() > self.robot.joints.len() {
                return None; // a cycle
            }
            path.push(j);
            at = self.robot.joints[j].parent.as_str();
        }
        path.reverse();
        (at == self.root).then_some(path)
    }

    fn revolute(&self, j: usize) -> bool {
        matches!(
            self.robot.joints[j].joint_type,
            JointType::Revolute | JointType::Continuous
        )
    }

    /// The chain's tip: the link named, or the one leaf reached through revolute,
    /// continuous and fixed joints only with the most revolute joints on its path.
    fn tip(&self, tip: Option<&str>) -> Result<String, KinematicsError> {
        let robot = self.robot;
        if let Some(t) = tip {
            if !robot.links.iter().any(|l| l.name == t) {
                return Err(invalid(format!("no link named `{t}`")));
            }
            return Ok(t.to_string());
        }
        let parents: Vec<&str> = robot.joints.iter().map(|j| j.parent.as_str()).collect();
        let mut best: Vec<(&str, usize)> = Vec::new();
        for l in robot.links.iter().map(|l| l.name.as_str()) {
            if parents.contains(&l) {
                continue; // not a leaf
            }
            let Some(path) = self.path_to(l) else {
                continue;
            };
            if !path.iter().all(|&j| {
                self.revolute(j) || matches!(robot.joints[j].joint_type, JointType::Fixed)
            }) {
                continue;
            }
            let count = path.iter().filter(|&&j| self.revolute(j)).count();
            match best.first().map(|b| b.1) {
                Some(c) if c > count => {}
                Some(c) if c == count => best.push((l, count)),
                _ => best = vec![(l, count)],
            }
        }
        match best.as_slice() {
            [(l, _)] => Ok(l.to_string()),
            // No clean path: take the deepest leaf, so that the walk names the joint that
            // is in the way.
            [] => robot
                .links
                .iter()
                .filter(|l| !parents.contains(&l.name.as_str()))
                .filter_map(|l| self.path_to(&l.name).map(|p| (l.name.clone(), p.len())))
                .max_by_key(|(_, depth)| *depth)
                .map(|(name, _)| name)
                .ok_or_else(|| invalid("no leaf link is connected to the root".into())),
            many => {
                let names: Vec<&str> = many.iter().map(|b| b.0).collect();
                Err(invalid(format!(
                    "several tip links are possible ({}): name one",
                    names.join(", ")
                )))
            }
        }
    }
}

/// What the walk from the root along a path of joints gathers: the revolute joints, their
/// names and limits, the fixed transform after the last, where each link on the chain is
/// carried, and the inertial parts rigidly attached to each moving link.
struct Walk {
    joints: Vec<RevoluteJoint>,
    names: Vec<String>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    speed: Vec<f64>,
    effort: Vec<f64>,
    pending: Isometry3<f64>,
    on_chain: HashMap<String, (usize, Isometry3<f64>)>,
    parts: Vec<Vec<(LinkInertia, Isometry3<f64>)>>,
}

/// Walks `path` (joint indices) from `root`; refuses a joint cps chains cannot have.
fn walk(robot: &Robot, path: &[usize], root: &str) -> Result<Walk, KinematicsError> {
    let mut joints = Vec::new();
    let mut names = Vec::new();
    let (mut lower, mut upper, mut speed, mut effort) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut pending = Isometry3::identity();
    // Each link on the chain: the frame that carries it and its pose there.
    let mut on_chain: HashMap<String, (usize, Isometry3<f64>)> = HashMap::new();
    on_chain.insert(root.to_string(), (0, Isometry3::identity()));
    // Per moving link: the inertial parts rigidly attached to it, in its frame.
    let mut parts: Vec<Vec<(LinkInertia, Isometry3<f64>)>> = Vec::new();
    let link = |name: &str| robot.links.iter().find(|l| l.name == name);
    for &ji in path {
        let j = &robot.joints[ji];
        let origin =
            pending * pose(&j.origin).map_err(|m| invalid(format!("joint `{}`: {m}", j.name)))?;
        if j.mimic {
            return Err(invalid(format!(
                "joint `{}` mimics another joint: not supported",
                j.name
            )));
        }
        match &j.joint_type {
            JointType::Fixed => {
                pending = origin;
                on_chain.insert(j.child.clone(), (joints.len(), pending));
                if let (Some(last), Some(l)) = (parts.last_mut(), link(&j.child)) {
                    last.push((inertial(l)?, origin));
                }
            }
            JointType::Revolute | JointType::Continuous => {
                let a = Vector3::from(j.axis);
                let axis = Unit::try_new(a, 1e-12)
                    .filter(|_| a.iter().all(|v| v.is_finite()))
                    .ok_or_else(|| {
                        invalid(format!(
                            "joint `{}`: the axis is zero or not finite",
                            j.name
                        ))
                    })?;
                joints.push(RevoluteJoint {
                    origin,
                    axis,
                    offset: 0.0,
                });
                names.push(j.name.clone());
                if matches!(j.joint_type, JointType::Revolute) {
                    let (lo, hi) = (j.limit.lower, j.limit.upper);
                    if lo.is_nan() || hi.is_nan() || lo >= hi {
                        return Err(invalid(format!(
                            "joint `{}`: a revolute joint needs limits lower < upper (got {lo} .. {hi})",
                            j.name
                        )));
                    }
                    lower.push(lo);
                    upper.push(hi);
                } else {
                    lower.push(f64::NEG_INFINITY);
                    upper.push(f64::INFINITY);
                }
                speed.push(j.limit.velocity);
                effort.push(j.limit.effort);
                let own = match link(&j.child) {
                    Some(l) => inertial(l)?,
                    None => LinkInertia::combine(&[]),
                };
                parts.push(vec![(own, Isometry3::identity())]);
                pending = Isometry3::identity();
                on_chain.insert(j.child.clone(), (joints.len(), pending));
            }
            other => {
                return Err(invalid(format!(
                    "joint `{}` is {}: cps chains have revolute joints only",
                    j.name,
                    format!("{other:?}").to_lowercase()
                )));
            }
        }
    }
    Ok(Walk {
        joints,
        names,
        lower,
        upper,
        speed,
        effort,
        pending,
        on_chain,
        parts,
    })
}

/// Every joint as it carries the collision shapes of its child link.
fn carriers(robot: &Robot) -> Result<Vec<PlaceJoint<'_>>, KinematicsError> {
    let mut carriers = Vec::new();
    for j in &robot.joints {
        carriers.push(PlaceJoint {
            parent: &j.parent,
            child: &j.child,
            origin: pose(&j.origin).map_err(|m| invalid(format!("joint `{}`: {m}", j.name)))?,
            axis: Vector3::from(j.axis)
                .try_normalize(1e-12)
                .unwrap_or_default(),
            carry: match j.joint_type {
                JointType::Fixed => Carry::Rigid(0.0),
                JointType::Prismatic if j.limit.upper.is_finite() => Carry::Rigid(j.limit.upper),
                JointType::Prismatic => Carry::Rigid(0.0),
                _ => Carry::Moving,
            },
        });
    }
    Ok(carriers)
}

/// Reads the serial chain from the root link to `tip` (a link name). Without `tip`, the
/// tip is the one leaf link reachable through revolute, continuous and fixed joints only
/// with the most revolute joints on its path; when several tie, the error lists them.
pub fn chain_from_urdf(xml: &str, tip: Option<&str>) -> Result<UrdfChain, KinematicsError> {
    if xml.len() > MAX_URDF_BYTES {
        return Err(invalid(format!(
            "the description has {} bytes, more than the {MAX_URDF_BYTES} read",
            xml.len()
        )));
    }
    let depth = nesting_depth(xml);
    if depth > MAX_URDF_DEPTH {
        return Err(invalid(format!(
            "elements are nested {depth} deep, more than the {MAX_URDF_DEPTH} a robot description needs"
        )));
    }
    let robot = read_robot(xml).map_err(invalid)?;
    validate(&robot)?;
    let tree = Tree::of(&robot)?;
    let root = tree.root;
    let tip_link = tree.tip(tip)?;
    let path = tree
        .path_to(&tip_link)
        .ok_or_else(|| invalid(format!("link `{tip_link}` is not connected to the root")))?;
    let Walk {
        joints,
        names,
        lower,
        upper,
        speed,
        effort,
        pending,
        on_chain,
        parts,
    } = walk(&robot, &path, root)?;
    if joints.is_empty() {
        return Err(invalid(format!(
            "no revolute joint between `{root}` and `{tip_link}`"
        )));
    }
    let mut chain = SerialChain::from_joints(joints)?
        .with_tool(pending)
        .with_limits(&lower, &upper)?;
    if speed.iter().all(|v| v.is_finite() && *v > 0.0) {
        chain = chain.with_velocity_limits(&speed)?;
    }
    let inertia: Vec<LinkInertia> = parts.iter().map(|p| LinkInertia::combine(p)).collect();
    let carriers = carriers(&robot)?;
    let link_collisions: Vec<(&str, &[UrdfCollision])> = robot
        .links
        .iter()
        .map(|l| (l.name.as_str(), l.collisions.as_slice()))
        .collect();
    let placed = place(&link_collisions, &on_chain, &carriers);
    Ok(UrdfChain {
        name: robot.name.clone(),
        chain,
        joint_names: names,
        base_link: root.to_string(),
        tip_link,
        effort: effort
            .iter()
            .all(|e| e.is_finite() && *e > 0.0)
            .then_some(effort),
        inertia: inertia.iter().any(|l| l.mass > 0.0).then_some(inertia),
        collisions: placed.elements,
        unplaced: placed.unplaced,
        adjacent: placed.adjacent,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWO_LINK: &str = r#"<robot name="r">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="2" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0.2 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
</robot>"#;

    fn refused(xml: &str, needle: &str) {
        match chain_from_urdf(xml, None) {
            Ok(_) => panic!("accepted, expected `{needle}`"),
            Err(e) => assert!(e.to_string().contains(needle), "{e}"),
        }
    }

    #[test]
    fn the_valid_description_reads() {
        let c = chain_from_urdf(TWO_LINK, None).unwrap();
        assert_eq!(c.joint_names, ["j1", "j2"]);
    }

    #[test]
    fn efforts_and_inertials_are_read_and_fixed_links_merged() {
        let c = chain_from_urdf(TWO_LINK, None).unwrap();
        assert_eq!(c.effort.as_deref(), Some(&[1.0, 1.0][..]));
        assert!(c.inertia.is_none(), "no link has a mass");
        // Link b: 2 kg at (0.1, 0, 0) with its tensor turned a quarter about z; a 1 kg
        // point fixed 0.4 m along b's x axis.
        let xml = TWO_LINK
            .replace(
                r#"<link name="b"/>"#,
                r#"<link name="b"><inertial><origin xyz="0.1 0 0" rpy="0 0 1.5707963267948966"/>
                   <mass value="2"/><inertia ixx="0.3" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.2"/></inertial></link>
                   <link name="tip"><inertial><mass value="1"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>"#,
            )
            .replace(
                "</robot>",
                r#"<joint name="f" type="fixed"><parent link="b"/><child link="tip"/><origin xyz="0.4 0 0" rpy="0 0 0"/></joint></robot>"#,
            );
        let c = chain_from_urdf(&xml, None).unwrap();
        let links = c.inertia.expect("b has a mass");
        assert_eq!(links[0].mass, 0.0);
        let b = &links[1];
        assert!((b.mass - 3.0).abs() < 1e-15);
        assert!((b.com - Vector3::new(0.2, 0.0, 0.0)).norm() < 1e-15);
        // xx and yy swap under the quarter turn; the parallel axis adds m·d² off the x axis:
        // 2 kg 0.1 m and 1 kg 0.2 m from the common centre.
        let extra = 2.0 * 0.01 + 1.0 * 0.04;
        assert!((b.inertia[(0, 0)] - 0.1).abs() < 1e-12);
        assert!((b.inertia[(1, 1)] - (0.3 + extra)).abs() < 1e-12);
        assert!((b.inertia[(2, 2)] - (0.2 + extra)).abs() < 1e-12);
    }

    #[test]
    fn broken_descriptions_are_named_by_element() {
        refused(
            &TWO_LINK.replace(r#"<link name="b"/>"#, r#"<link name="b"/><link name="a"/>"#),
            "two links are named `a`",
        );
        refused(
            &TWO_LINK.replace(r#"name="j2""#, r#"name="j1""#),
            "two joints are named `j1`",
        );
        refused(
            &TWO_LINK.replace(r#"xyz="0 1 0""#, r#"xyz="0 0 0""#),
            "joint `j2`: the axis",
        );
        refused(
            &TWO_LINK.replace(r#"xyz="0 1 0""#, r#"xyz="0 NaN 0""#),
            "joint `j2`: the axis",
        );
        refused(
            &TWO_LINK.replace(r#"upper="2""#, r#"upper="inf""#),
            "joint `j2`: limits",
        );
        refused(
            &TWO_LINK.replace(r#"lower="-1" upper="1""#, r#"lower="1" upper="-1""#),
            "joint `j1`: limits",
        );
        refused(
            &TWO_LINK.replace(r#"xyz="0.2 0 0""#, r#"xyz="0.2 inf 0""#),
            "joint `j2`: origin",
        );
        refused(
            &TWO_LINK.replace(r#"<child link="b"/>"#, r#"<child link="zz"/>"#),
            "child link `zz` does not exist",
        );
        refused(
            &TWO_LINK.replace(r#"<child link="b"/>"#, r#"<child link="a"/>"#),
            "same link",
        );
        // A cycle: b is the parent of base.
        refused(
            &TWO_LINK.replace(
                "</robot>",
                r#"<joint name="j3" type="fixed"><parent link="b"/><child link="base"/></joint></robot>"#,
            ),
            "root",
        );
    }

    #[test]
    fn numbers_and_joint_types_are_checked_where_they_are_read() {
        refused(
            &TWO_LINK.replace(r#"xyz="0.2 0 0""#, r#"xyz="0.2 zero 0""#),
            "joint `j2`: `xyz` has `zero`, not a number",
        );
        refused(
            &TWO_LINK.replace(r#"xyz="0.2 0 0""#, r#"xyz="0.2 0""#),
            "`xyz` must be three numbers (got 2)",
        );
        refused(
            &TWO_LINK.replace(
                r#"type="revolute"><parent link="a"/>"#,
                r#"type="hinge"><parent link="a"/>"#,
            ),
            "has type `hinge`",
        );
    }

    #[test]
    fn deep_nesting_is_refused_before_parsing() {
        let deep = format!("{}{}", "<a>".repeat(100_000), "</a>".repeat(100_000));
        refused(&deep, "nested 100000 deep");
        // Comments, quotes and self-closing tags do not count.
        assert_eq!(nesting_depth("<a x='>'><!-- <b><c> --><d/><e></e></a>"), 2);
    }
}
