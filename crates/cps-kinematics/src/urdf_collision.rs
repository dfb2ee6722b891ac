//! A URDF's `<collision>` elements, placed on the chain: each element's shape as the file
//! gives it (a box, cylinder, sphere, capsule or mesh file — reading meshes is
//! cps-geometry's) and its pose in the frame of the chain link that carries it.
//!
//! Links on the chain carry their own elements. Links off it are carried by the nearest
//! link on it when every joint between is fixed or prismatic: a gripper's hand and
//! fingers. A prismatic joint is taken at its upper limit (a gripper open: the most room
//! it can take). Links behind a moving joint off the chain (a second arm, a wheel) cannot
//! be placed by the chain's angles and are listed in [`UrdfChain::unplaced`] instead.

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

/// Places every link's collision elements. `on_chain` gives each link on the chain its
/// frame and its pose in that frame; `joints` every joint of the tree; `collisions` each
/// link's elements. Returns the placed elements (in the order of `links`) and the links
/// with elements that cannot be placed.
pub(crate) fn place(
    links: &[(&str, &[UrdfCollision])],
    on_chain: &HashMap<String, (usize, Isometry3<f64>)>,
    joints: &[PlaceJoint<'_>],
) -> (Vec<CollisionElement>, Vec<String>) {
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
    (out, unplaced)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain_from_urdf;

    const ARM: &str = r#"<robot name="r">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="a"><collision><origin xyz="0 0 0.05"/><geometry><cylinder radius="0.04" length="0.1"/></geometry></collision></link>
  <link name="b"/>
  <link name="hand"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <link name="finger"><collision><geometry><capsule radius="0.01" length="0.02"/></geometry></collision></link>
  <link name="camera"><collision><geometry><mesh filename="package://r/cam.stl" scale="0.001 0.001 0.001"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="2" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0.2 0 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
  <joint name="fix" type="fixed"><parent link="b"/><child link="hand"/><origin xyz="0.1 0 0"/></joint>
  <joint name="slide" type="prismatic"><parent link="hand"/><child link="finger"/>
    <origin xyz="0 0 0.02"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" velocity="0.2" effort="10"/></joint>
  <joint name="pan" type="revolute"><parent link="base"/><child link="camera"/>
    <origin xyz="0 0.3 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>"#;

    #[test]
    fn collision_elements_are_placed_on_the_frames_that_carry_them() {
        let c = chain_from_urdf(ARM, Some("hand")).unwrap();
        let by = |link: &str| c.collisions.iter().find(|e| e.link == link).unwrap();
        assert_eq!(c.collisions.len(), 4);
        assert_eq!(
            (by("base").frame, by("a").frame, by("hand").frame),
            (0, 1, 2)
        );
        assert_eq!(
            by("base").geometry,
            CollisionGeometry::Box {
                size: [0.2, 0.2, 0.1]
            }
        );
        assert!((by("a").origin.translation.vector - Vector3::new(0.0, 0.0, 0.05)).norm() < 1e-15);
        // The hand is fixed 0.1 m along b's x; the finger slides 0.04 m (its upper limit)
        // along y, 0.02 m above the hand.
        assert!(
            (by("hand").origin.translation.vector - Vector3::new(0.1, 0.0, 0.0)).norm() < 1e-15
        );
        let f = by("finger");
        assert_eq!(f.frame, 2);
        assert!((f.origin.translation.vector - Vector3::new(0.1, 0.04, 0.02)).norm() < 1e-15);
        assert_eq!(f.line, 6);
        // The camera turns on a joint of its own: the chain cannot place it.
        assert_eq!(c.unplaced, ["camera"]);
        // The placed frames agree with forward kinematics: the hand's centre at q.
        let q = [0.4, -0.7];
        let frames = c.chain.fk_frames(&q).unwrap();
        let hand =
            frames.link_frames[1] * nalgebra::Point3::from(by("hand").origin.translation.vector);
        let tip = c.chain.fk(&q).unwrap();
        assert!((hand.coords - tip.translation.vector).norm() < 1e-12);
    }

    #[test]
    fn shapes_without_a_size_or_with_a_negative_one_are_refused_with_their_line() {
        let bad = ARM.replace(r#"radius="0.04""#, r#"radius="-0.04""#);
        let e = chain_from_urdf(&bad, None).unwrap_err().to_string();
        assert!(
            e.contains("line 3: link `a` collision: `<cylinder>`'s `radius` is -0.04, not a positive number of metres"),
            "{e}"
        );
        let bad = ARM.replace(r#"<box size="0.2 0.2 0.1"/>"#, r#"<box size="0.2 0 0.1"/>"#);
        let e = chain_from_urdf(&bad, None).unwrap_err().to_string();
        assert!(
            e.contains("line 2: link `base` collision: `<box>`'s `size` has 0"),
            "{e}"
        );
        let bad = ARM.replace(r#"<sphere radius="0.03"/>"#, r#"<cone radius="0.03"/>"#);
        let e = chain_from_urdf(&bad, None).unwrap_err().to_string();
        assert!(e.contains("`<cone>` is not a URDF shape"), "{e}");
        let bad = ARM.replace(r#"filename="package://r/cam.stl" "#, "");
        let e = chain_from_urdf(&bad, None).unwrap_err().to_string();
        assert!(
            e.contains("line 7: link `camera` collision: `<mesh>` has no `filename`"),
            "{e}"
        );
    }
}
