//! A URDF's `<collision>` elements, placed on the chain: each element's shape as the file
//! gives it (a box, cylinder, sphere, capsule or mesh file — reading meshes is
//! cps-geometry's) and its pose in the frame of the chain link that carries it.
//!
//! Links on the chain carry their own elements. Links off it are carried by the nearest
//! link on it when every joint between is fixed or prismatic: a gripper's hand and
//! fingers. A prismatic joint is taken at its upper limit (a gripper open: the most room
//! it can take). Links behind a moving joint off the chain (a second arm, a wheel) cannot
//! be placed by the chain's angles and are listed in [`UrdfChain::unplaced`] instead.
//!
//! A robot's SRDF (MoveIt's semantic description) names the pairs of links never checked
//! against each other: [`disabled_collisions`] reads its `<disable_collisions>`.

use std::collections::HashMap;

use nalgebra::{Isometry3, Translation3, Vector3};

/// A collision element's shape, in the element's own frame, as URDF defines it.
#[derive(Debug, Clone, PartialEq)]
pub enum CollisionGeometry {
    /// A box centred on the frame: full edge lengths (m).
    Box {
        /// `size`: x, y, z.
        size: [f64; 3],
    },
    /// A cylinder about z, centred on the frame.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Full length (m).
        length: f64,
    },
    /// A ball centred on the frame.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// A capsule about z (ROS 2's URDF extension): a cylinder of `length` with
    /// hemispherical caps.
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Length of the cylindrical part (m).
        length: f64,
    },
    /// A mesh file, as written (`package://…`, `file://…` or a relative path), and its
    /// scale.
    Mesh {
        /// The `filename` attribute.
        filename: String,
        /// The `scale` attribute (1 1 1 when absent).
        scale: [f64; 3],
    },
}

/// One `<collision>` element of a link as read, before placing.
#[derive(Debug, Clone)]
pub(crate) struct UrdfCollision {
    pub(crate) origin: Isometry3<f64>,
    pub(crate) geometry: CollisionGeometry,
    pub(crate) line: usize,
}

/// A collision element placed on the chain.
#[derive(Debug, Clone)]
pub struct CollisionElement {
    /// The URDF link it belongs to.
    pub link: String,
    /// The chain frame that carries it: 0 for the base (the root link), `k` for the link
    /// joint `k` moves (`SerialChain::fk_frames`'s `link_frames[k − 1]`).
    pub frame: usize,
    /// Its pose in that frame.
    pub origin: Isometry3<f64>,
    /// Its shape.
    pub geometry: CollisionGeometry,
    /// The line of its `<collision>` element in the URDF.
    pub line: usize,
}

/// How a joint moves, for placing links off the chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Carry {
    /// Fixed, or prismatic at this travel along its axis.
    Rigid(f64),
    /// A joint that turns: what is behind it cannot be placed.
    Moving,
}

/// A joint as placing needs it.
pub(crate) struct PlaceJoint<'a> {
    pub(crate) parent: &'a str,
    pub(crate) child: &'a str,
    pub(crate) origin: Isometry3<f64>,
    pub(crate) axis: Vector3<f64>,
    pub(crate) carry: Carry,
}

/// What [`place`] finds.
pub(crate) struct Placed {
    pub(crate) elements: Vec<CollisionElement>,
    pub(crate) unplaced: Vec<String>,
    pub(crate) adjacent: Vec<(String, String)>,
}

/// Each link with collision elements and its nearest ancestor with some (links without
/// any in between, such as a flange frame, are looked through): the pairs a joint joins,
/// whose shapes touch at the joint whatever its angle.
fn adjacent(
    links: &[(&str, &[UrdfCollision])],
    joints: &[PlaceJoint<'_>],
) -> Vec<(String, String)> {
    let parent: HashMap<&str, &str> = joints.iter().map(|j| (j.child, j.parent)).collect();
    let solid = |l: &str| links.iter().any(|(n, c)| *n == l && !c.is_empty());
    let mut out = Vec::new();
    for (name, elements) in links {
        if elements.is_empty() {
            continue;
        }
        let mut at = *name;
        for _ in 0..=joints.len() {
            let Some(&up) = parent.get(at) else { break };
            if solid(up) {
                out.push((up.to_string(), name.to_string()));
                break;
            }
            at = up;
        }
    }
    out
}

/// Places every link's collision elements. `on_chain` gives each link on the chain its
/// frame and its pose in that frame; `joints` every joint of the tree; `collisions` each
/// link's elements. Returns the placed elements (in the order of `links`), the links
/// with elements that cannot be placed, and the adjacent pairs of links with elements.
pub(crate) fn place(
    links: &[(&str, &[UrdfCollision])],
    on_chain: &HashMap<String, (usize, Isometry3<f64>)>,
    joints: &[PlaceJoint<'_>],
) -> Placed {
    let mut placed: HashMap<String, (usize, Isometry3<f64>)> = on_chain.clone();
    // Grow outwards from the chain through fixed and prismatic joints; the tree has at
    // most as many levels as joints.
    for _ in 0..=joints.len() {
        let mut grew = false;
        for j in joints {
            if placed.contains_key(j.child) {
                continue;
            }
            let (Some(&(frame, at)), Carry::Rigid(travel)) = (placed.get(j.parent), j.carry) else {
                continue;
            };
            let slide = Translation3::from(j.axis * travel);
            placed.insert(j.child.to_string(), (frame, at * j.origin * slide));
            grew = true;
        }
        if !grew {
            break;
        }
    }
    let mut out = Vec::new();
    let mut unplaced = Vec::new();
    for (name, elements) in links {
        if elements.is_empty() {
            continue;
        }
        match placed.get(*name) {
            Some(&(frame, at)) => out.extend(elements.iter().map(|c| CollisionElement {
                link: name.to_string(),
                frame,
                origin: at * c.origin,
                geometry: c.geometry.clone(),
                line: c.line,
            })),
            None => unplaced.push(name.to_string()),
        }
    }
    Placed {
        elements: out,
        unplaced,
        adjacent: adjacent(links, joints),
    }
}

/// The `<disable_collisions link1="…" link2="…">` pairs of an SRDF document (MoveIt's
/// semantic robot description): links that touch at a joint, or that can never meet.
/// Errors name the line (a document that is not XML, an element without both links).
pub fn disabled_collisions(srdf: &str) -> Result<Vec<(String, String)>, String> {
    let root = crate::xml::parse_xml(srdf)?;
    if root.name != "robot" {
        return Err(format!(
            "line {}: the root element is <{}>, not an SRDF's <robot>",
            root.line, root.name
        ));
    }
    root.children
        .iter()
        .filter(|e| e.name == "disable_collisions")
        .map(|e| match (e.attr("link1"), e.attr("link2")) {
            (Some(a), Some(b)) if !a.is_empty() && !b.is_empty() => {
                Ok((a.to_string(), b.to_string()))
            }
            _ => Err(format!(
                "line {}: <disable_collisions> needs both `link1` and `link2`",
                e.line
            )),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_srdfs_disabled_pairs_are_read_and_a_broken_one_named_by_its_line() {
        let srdf = "<?xml version=\"1.0\"?>\n<robot name=\"fr3\">\n  <group name=\"arm\"><chain base_link=\"a\" tip_link=\"b\"/></group>\n  <disable_collisions link1=\"fr3_link0\" link2=\"fr3_link2\" reason=\"Never\"/>\n  <disable_collisions link1=\"fr3_hand\" link2=\"fr3_link6\" reason=\"Never\"/>\n</robot>\n";
        assert_eq!(
            disabled_collisions(srdf).unwrap(),
            [
                ("fr3_link0".to_string(), "fr3_link2".to_string()),
                ("fr3_hand".to_string(), "fr3_link6".to_string())
            ]
        );
        let e = disabled_collisions("<robot>\n<disable_collisions link1=\"a\"/>\n</robot>")
            .unwrap_err();
        assert_eq!(
            e,
            "line 2: <disable_collisions> needs both `link1` and `link2`"
        );
        let e = disabled_collisions("<srdf/>").unwrap_err();
        assert!(e.contains("not an SRDF's <robot>"), "{e}");
        assert!(
            disabled_collisions("<robot>")
                .unwrap_err()
                .contains("not closed")
        );
    }
}
