//! `[[obstacle]]` in scene files: points as before, and shapes (box, sphere, cylinder,
//! capsule, mesh) placed in the world; every wrong key, size or file refused with its place.

use std::path::Path;

use cps_geometry::{Shape, distance};
use cps_movement::scene::parse_scene;
use nalgebra::Isometry3;

const HEAD: &str = r#"[robot]
model = "panda"
tool = "hand"
initial_q = [0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0]
"#;

fn scene(obstacles: &str, dir: &Path) -> Result<cps_movement::scene::Scene, String> {
    let text = format!("{HEAD}{obstacles}");
    parse_scene(&dir.join("s.toml"), &text).map_err(|e| e.to_string())
}

#[test]
fn shaped_obstacles_are_placed_in_the_world_beside_point_ones() {
    let dir = tempfile::tempdir().unwrap();
    // A unit tetrahedron as an ASCII STL.
    let stl = "solid t\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 0 1 0\nvertex 1 0 0\nendloop\nendfacet\n\
               facet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\n\
               facet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 0 0 1\nvertex 0 1 0\nendloop\nendfacet\n\
               facet normal 0 0 0\nouter loop\nvertex 1 0 0\nvertex 0 1 0\nvertex 0 0 1\nendloop\nendfacet\nendsolid t\n";
    std::fs::write(dir.path().join("t.stl"), stl).unwrap();
    let s = scene(
        r#"
[[obstacle]]
name = "pin"
position = [0.5, 0.0, 0.5]
clearance = 0.05

[[obstacle]]
name = "table"
shape = "box"
xyz = [0.5, 0.0, -0.025]
size = [1.0, 0.8, 0.05]
touch = ["panda_link0"]

[[obstacle]]
name = "post"
shape = "cylinder"
xyz = [0.0, 0.6, 0.5]
rpy = [1.5707963267948966, 0.0, 0.0]
radius = 0.05
length = 1.0

[[obstacle]]
name = "ball"
shape = "sphere"
xyz = [0.3, -0.4, 0.8]
radius = 0.1

[[obstacle]]
name = "rail"
shape = "capsule"
xyz = [0.0, 0.0, 1.5]
radius = 0.02
length = 0.4

[[obstacle]]
name = "wedge"
shape = "mesh"
file = "t.stl"
xyz = [2.0, 0.0, 0.0]
"#,
        dir.path(),
    )
    .unwrap();
    assert_eq!(s.obstacles.len(), 1);
    let names: Vec<&str> = s.shapes.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["table", "post", "ball", "rail", "wedge"]);
    // A probe ball of 1 cm radius 0.1 m above the table's top.
    let probe = Shape::sphere(0.01, "probe").unwrap();
    let above = Isometry3::translation(0.5, 0.0, 0.1);
    let d = distance(&probe, &above, &s.shapes[0].shape, &s.shapes[0].pose).distance;
    assert!((d - 0.09).abs() < 1e-9, "{d}");
    // The post turned about x lies along y: a probe at y = 0.2 beyond its end (y 0.1..1.1).
    let end = Isometry3::translation(0.0, 0.0, 0.5);
    let d = distance(&probe, &end, &s.shapes[1].shape, &s.shapes[1].pose).distance;
    assert!((d - (0.1 - 0.01)).abs() < 1e-7, "{d}");
    // The wedge's corner at the origin is moved to x = 2.
    let d = distance(
        &probe,
        &Isometry3::translation(1.5, 0.0, 0.0),
        &s.shapes[4].shape,
        &s.shapes[4].pose,
    )
    .distance;
    assert!((d - 0.49).abs() < 1e-7, "{d}");
}

#[test]
fn the_robots_shapes_meet_the_scene_and_a_start_inside_an_obstacle_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    // The table the robot stands on, allowed to touch its base: the robot is checked
    // against it with every other link, at the margin the scene sets.
    let table = "\n[[obstacle]]\nname = \"table\"\nshape = \"box\"\nxyz = [0.0, 0.0, -0.1]\nsize = [1.0, 1.0, 0.2]\n";
    let s = scene(&format!("{table}touch = [\"panda_link0\"]\n"), dir.path()).unwrap();
    let shapes = s.robot.shapes.as_ref().expect("the Panda has shapes");
    assert_eq!(shapes.obstacles().len(), 1);
    assert_eq!(shapes.margin(), cps_robot::DEFAULT_MARGIN);
    let model = shapes.model();
    let pairs: Vec<(&str, &str)> = (0..model.pair_count())
        .map(|p| model.pair_names(p))
        .collect();
    assert!(pairs.contains(&("panda_link7", "table")), "{pairs:?}");
    assert!(!pairs.contains(&("panda_link0", "table")), "{pairs:?}");
    // Without `touch`, the base stands in the table at the start: refused, with its place.
    let e = scene(table, dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("s.toml:4:13: at the robot's `initial_q`, `panda_link0` and `table` are")
            && e.contains("mm deep in each other"),
        "{e}"
    );
    // A box 3 cm from the hand's fingers at the start, with a 5 cm margin: refused.
    let q = [0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0];
    let tcp = s.robot.chain.fk(&q).unwrap().translation.vector;
    let near = format!(
        "\n[[obstacle]]\nname = \"cup\"\nshape = \"sphere\"\nxyz = [{}, {}, {}]\nradius = 0.02\n",
        tcp.x,
        tcp.y,
        tcp.z - 0.05
    );
    let text = format!("{HEAD}margin = 0.05\n{near}");
    let e = parse_scene(&dir.path().join("s.toml"), &text)
        .unwrap_err()
        .to_string();
    assert!(e.contains("within the clearance margin of 50.0 mm"), "{e}");
    // `touch` names a link the robot has, and only a shaped obstacle can be touched.
    let e = scene(&format!("{table}touch = [\"panda_link9\"]\n"), dir.path()).unwrap_err();
    assert!(
        e.contains("`panda_link9`, which is neither one of the robot's links (panda_link0, "),
        "{e}"
    );
    let e = scene(
        "\n[[obstacle]]\nname = \"p\"\nposition = [0, 0, 0]\nclearance = 0.1\ntouch = [\"panda_link0\"]\n",
        dir.path(),
    )
    .unwrap_err();
    assert!(
        e.contains(
            "s.toml:6:1: obstacle `p` is a point: only an obstacle with a `shape` can be touched"
        ),
        "{e}"
    );
    // A negative margin is named at its place.
    let e = parse_scene(
        &dir.path().join("s.toml"),
        &format!("{HEAD}margin = -0.01\n"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("s.toml:5:10: the clearance margin must be a finite distance ≥ 0 m, not -0.01"),
        "{e}"
    );
}

#[test]
fn wrong_obstacles_are_refused_with_their_place() {
    let dir = tempfile::tempdir().unwrap();
    let refused = |obstacle: &str, needle: &str| {
        let e = scene(obstacle, dir.path()).unwrap_err();
        assert!(e.contains(needle), "{e}");
        assert!(e.contains("s.toml:6:"), "placed: {e}");
    };
    refused(
        "\n[[obstacle]]\nname = \"b\"\nshape = \"box\"\nxyz = [0, 0, 0]\n",
        "obstacle `b`: a box needs `size`",
    );
    refused(
        "\n[[obstacle]]\nname = \"b\"\nshape = \"box\"\nxyz = [0, 0, 0]\nsize = [0.1, -0.2, 0.3]\n",
        "the size -0.2 is not a positive number of metres",
    );
    refused(
        "\n[[obstacle]]\nname = \"c\"\nshape = \"cone\"\nxyz = [0, 0, 0]\n",
        "shape `cone` is not one of box, sphere, cylinder, capsule, mesh",
    );
    refused(
        "\n[[obstacle]]\nname = \"s\"\nshape = \"sphere\"\nxyz = [0, 0, 0]\nradius = 0.1\nlength = 2\n",
        "a sphere has no `length`",
    );
    refused(
        "\n[[obstacle]]\nname = \"s\"\nshape = \"sphere\"\nradius = 0.1\n",
        "obstacle `s` needs `xyz`",
    );
    refused(
        "\n[[obstacle]]\nname = \"p\"\nposition = [0, 0, 0]\nclearance = 0.1\nradius = 0.2\n",
        "is a point (`position`): `radius` belongs to an obstacle with a `shape`",
    );
    refused(
        "\n[[obstacle]]\nname = \"m\"\nshape = \"mesh\"\nxyz = [0, 0, 0]\nfile = \"missing.stl\"\n",
        "missing.stl: cannot read the collision mesh",
    );
    // The sweep's: /dev/zero read 4 GB and ran out of memory; a FIFO hung for ever.
    refused(
        "\n[[obstacle]]\nname = \"z\"\nshape = \"mesh\"\nxyz = [0, 0, 0]\nfile = \"/dev/zero\"\n",
        "/dev/zero: the collision mesh must be a regular file, and this is a device",
    );
    let fifo = dir.path().join("pipe.stl");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    refused(
        "\n[[obstacle]]\nname = \"f\"\nshape = \"mesh\"\nxyz = [0, 0, 0]\nfile = \"pipe.stl\"\n",
        "pipe.stl: the collision mesh must be a regular file, and this is a FIFO",
    );
    refused(
        "\n[[obstacle]]\nname = \"p\"\n",
        "needs a `position` and a `clearance` (a point), or a `shape`",
    );
}
