//! A URDF's SRDF is not trusted: each pair it leaves out is searched over the joint ranges
//! on the shapes cps checks, a pair that meets is checked, and the search is kept beside
//! the robot (`ROBOT.pairs.json`) for the next load — read again only for the same robot,
//! never written over a file cps did not write.

use std::path::Path;

use cps_movement::robot_file::load_robot;
use cps_robot::{RobotModel, Why};

/// A three-joint arm on a 20 × 20 × 10 cm base: `upper` turns about z on it, `fore` and
/// `hand` (a 20 cm cylinder) about y, each joint within ±2.5 rad (the first ±3).
const ARM: &str = r#"<?xml version="1.0"?>
<robot name="folding">
  <link name="base">
    <collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision>
  </link>
  <link name="upper">
    <collision><origin xyz="0 0 0.15"/><geometry><box size="0.05 0.05 0.3"/></geometry></collision>
  </link>
  <link name="fore">
    <collision><origin xyz="0 0 0.15"/><geometry><box size="0.05 0.05 0.3"/></geometry></collision>
  </link>
  <link name="hand">
    <collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.03" length="0.2"/></geometry></collision>
  </link>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.05"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="2" effort="50"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="upper"/><child link="fore"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-2.5" upper="2.5" velocity="2" effort="50"/>
  </joint>
  <joint name="j3" type="revolute">
    <parent link="fore"/><child link="hand"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-2.5" upper="2.5" velocity="2" effort="50"/>
  </joint>
</robot>
"#;

/// Says `fore` and `hand` never meet the base.
const SRDF: &str = r#"<?xml version="1.0"?>
<robot name="folding">
  <disable_collisions link1="base" link2="fore" reason="Never"/>
  <disable_collisions link1="base" link2="hand" reason="Never"/>
  <disable_collisions link1="upper" link2="fore" reason="Adjacent"/>
</robot>
"#;

fn load(urdf: &Path) -> RobotModel {
    load_robot(urdf.to_str().unwrap(), None, None).unwrap()
}

/// The closest approach the loaded robot carries for `first`–`second`.
fn why(robot: &RobotModel, first: &str, second: &str) -> Why {
    let shapes = robot.shapes.as_ref().unwrap();
    shapes
        .left_out()
        .iter()
        .find(|l| l.first == first && l.second == second)
        .unwrap_or_else(|| panic!("{first}–{second} not among {:?}", shapes.left_out()))
        .why
}

/// Whether the guard's model checks the pair of links `a`, `b`.
fn checks(robot: &RobotModel, a: &str, b: &str) -> bool {
    let model = robot.shapes.as_ref().unwrap().model();
    (0..model.pair_count()).any(|p| {
        let (x, y) = model.pair_names(p);
        (x == a && y == b) || (x == b && y == a)
    })
}

/// Geometry alone decides: `fore` turned down by joint 2's 2.5 rad ends 16 cm above the
/// joint-1 axis, its box never nearer the base than a few centimetres; `hand`, 20 cm
/// further, folds into the base. The search finds both; the guard checks the one that
/// meets, at the configuration where the search found it, and leaves the other out.
#[test]
fn an_srdfs_never_pair_that_meets_is_checked_and_one_that_keeps_apart_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("arm.urdf");
    std::fs::write(&urdf, ARM).unwrap();
    std::fs::write(dir.path().join("arm.srdf"), SRDF).unwrap();
    let robot = load(&urdf);
    let Why::Searched(fore) = why(&robot, "base", "fore") else {
        panic!("base–fore not searched");
    };
    let Why::Searched(hand) = why(&robot, "base", "hand") else {
        panic!("base–hand not searched");
    };
    // fore's box bottom corner at joint 2's limit: 0.35 m up, 0.3 m along a line 2.5 rad
    // from up, its half-width 25 mm across: never below the base's top (5 cm) by less
    // than about 4 cm.
    assert!(fore > 0.03 && fore < 0.08, "base–fore {fore}");
    assert!(hand < -0.05, "base–hand {hand}");
    assert!(!checks(&robot, "base", "fore"));
    assert!(checks(&robot, "base", "hand"));
    // The adjacent pair the SRDF repeats is joined, not searched.
    assert_eq!(why(&robot, "upper", "fore"), Why::Joined);
    // At the search's witness the guard's model finds the two inside each other.
    let cache: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("arm.pairs.json")).unwrap())
            .unwrap();
    let witness: Vec<f64> = serde_json::from_value(cache["pairs"][1]["witness"].clone()).unwrap();
    assert_eq!(cache["pairs"][1]["second"], "hand");
    let mut frames = Vec::new();
    robot.chain.frames_into(&witness, &mut frames).unwrap();
    let model = robot.shapes.as_ref().unwrap().model();
    let near = model.within(&frames, 0.005);
    let deepest = near
        .iter()
        .filter(|c| model.pair_names(c.pair) == ("base", "hand"))
        .map(|c| c.separation.distance)
        .fold(f64::INFINITY, f64::min);
    assert!((deepest - hand).abs() < 1e-9, "{deepest} against {hand}");
    // `robot show`'s words.
    let words = cps_movement::robot_file::Describe::describe(&robot).join("\n");
    assert!(
        words.contains("base – fore: no closer than")
            && words.contains("base – hand: the description leaves them out, but they meet"),
        "{words}"
    );
}

/// The search is kept beside the URDF and read back for the same robot: a cache that says
/// otherwise is believed (the proof it is read), a changed robot is searched again, and a
/// file there that cps did not write is left alone.
#[test]
fn the_search_is_kept_beside_the_robot_and_redone_when_the_robot_changes() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("arm.urdf");
    let cache = dir.path().join("arm.pairs.json");
    std::fs::write(&urdf, ARM).unwrap();
    std::fs::write(dir.path().join("arm.srdf"), SRDF).unwrap();
    let Why::Searched(searched) = why(&load(&urdf), "base", "fore") else {
        panic!("not searched");
    };
    let written = std::fs::read_to_string(&cache).unwrap();
    assert!(written.contains("\"written_by\": \"cps:"), "{written}");
    // The cache read, not the search redone: a closest approach it alone says.
    let text = written.replacen(&format!("\"closest\": {searched}"), "\"closest\": -0.25", 1);
    assert_ne!(text, written);
    std::fs::write(&cache, &text).unwrap();
    let robot = load(&urdf);
    assert_eq!(why(&robot, "base", "fore"), Why::Searched(-0.25));
    assert!(checks(&robot, "base", "fore"));
    // Another robot (joint 2's range narrowed) is searched again, and the cache rewritten.
    std::fs::write(
        &urdf,
        ARM.replace(
            "lower=\"-2.5\" upper=\"2.5\"",
            "lower=\"-1.5\" upper=\"1.5\"",
        ),
    )
    .unwrap();
    let Why::Searched(narrow) = why(&load(&urdf), "base", "fore") else {
        panic!("not searched");
    };
    assert!(narrow > searched, "{narrow} against {searched}");
    assert!(!std::fs::read_to_string(&cache).unwrap().contains("-0.25"));
    // A file of the user's at the cache's place is never replaced.
    std::fs::write(&cache, "my notes\n").unwrap();
    let Why::Searched(again) = why(&load(&urdf), "base", "fore") else {
        panic!("not searched");
    };
    assert_eq!(again, narrow);
    assert_eq!(std::fs::read_to_string(&cache).unwrap(), "my notes\n");
}
