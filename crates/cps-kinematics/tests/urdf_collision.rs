//! A URDF's `<collision>` elements placed on the chain's frames (`UrdfChain::collisions`),
//! the links joined by a joint (`adjacent`) and those the chain cannot place, and shapes
//! with a bad size refused with their line; and the frames themselves as a collision
//! model takes them (`SerialChain::frames_into`).

use cps_kinematics::{CollisionGeometry, chain_from_urdf};
use nalgebra::Vector3;

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
    assert!((by("hand").origin.translation.vector - Vector3::new(0.1, 0.0, 0.0)).norm() < 1e-15);
    let f = by("finger");
    assert_eq!(f.frame, 2);
    assert!((f.origin.translation.vector - Vector3::new(0.1, 0.04, 0.02)).norm() < 1e-15);
    assert_eq!(f.line, 6);
    // The camera turns on a joint of its own: the chain cannot place it.
    assert_eq!(c.unplaced, ["camera"]);
    // Joined by a joint: base–a, a–hand (through b, which has no shape), hand–finger,
    // base–camera.
    let mut adjacent = c.adjacent.clone();
    adjacent.sort();
    assert_eq!(
        adjacent,
        [
            ("a", "hand"),
            ("base", "a"),
            ("base", "camera"),
            ("hand", "finger")
        ]
        .map(|(x, y)| (x.to_string(), y.to_string()))
    );
    // The placed frames agree with forward kinematics: the hand's centre at q.
    let q = [0.4, -0.7];
    let frames = c.chain.fk_frames(&q).unwrap();
    let hand = frames.link_frames[1] * nalgebra::Point3::from(by("hand").origin.translation.vector);
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

#[test]
fn frames_into_gives_the_base_then_every_link_frame_as_fk_frames_does() {
    use cps_kinematics::robots::{PandaTool, fr3};
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    let base = Isometry3::from_parts(
        Translation3::new(0.4, 0.02, 0.74),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
    );
    let chain = fr3(PandaTool::HandTcp).with_base(base);
    let q = [0.3, -0.5, 0.7, -2.0, 0.4, 1.9, -0.6];
    let mut out = Vec::new();
    chain.frames_into(&q, &mut out).unwrap();
    assert_eq!(out.len(), 8);
    assert!((out[0].to_homogeneous() - base.to_homogeneous()).norm() < 1e-15);
    let reference = chain.fk_frames(&q).unwrap();
    for (k, f) in reference.link_frames.iter().enumerate() {
        let d = (out[k + 1].to_homogeneous() - f.to_homogeneous()).norm();
        assert!(d < 1e-12, "frame {}: {d}", k + 1);
    }
    // The world pose of link 1 is the base's times joint 1's: the base is in the frames.
    assert!(
        (out[1].translation.vector
            - (base * Translation3::new(0.0, 0.0, 0.333))
                .translation
                .vector)
            .norm()
            < 1e-12
    );
    // Refused like fk: a wrong joint count.
    assert!(chain.frames_into(&q[..6], &mut out).is_err());
    // With the axes: the same frames, and joint k's axis is what turning joint k turns
    // every later frame's origin about (a small turn ε moves it by ε z × (p − o), to
    // second order; checked by finite differences, on the FR3 and on a URDF chain whose
    // second axis is the link's y).
    let urdf = chain_from_urdf(ARM, Some("hand")).unwrap().chain;
    for (chain, q) in [(chain, q.to_vec()), (urdf, vec![0.3, -0.7])] {
        let (mut with, mut axes) = (Vec::new(), Vec::new());
        chain.frames_axes_into(&q, &mut with, &mut axes).unwrap();
        chain.frames_into(&q, &mut out).unwrap();
        assert_eq!(with, out);
        assert_eq!(axes.len(), q.len());
        let eps = 1e-6;
        for (k, (point, axis)) in axes.iter().enumerate() {
            assert!((axis.norm() - 1.0).abs() < 1e-12);
            let mut turned = q.clone();
            turned[k] += eps;
            let mut after = Vec::new();
            chain.frames_into(&turned, &mut after).unwrap();
            for m in k + 1..out.len() {
                let p = out[m].translation.vector;
                let moved = after[m].translation.vector - p;
                let predicted = eps * axis.cross(&(p - point));
                assert!(
                    (moved - predicted).norm() < 1e-10,
                    "joint {}, frame {m}: {moved:?} against {predicted:?}",
                    k + 1
                );
            }
        }
    }
}
