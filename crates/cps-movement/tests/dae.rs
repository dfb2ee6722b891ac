//! COLLADA meshes: franky-sim's link1_vis.dae (Blender's export of franka_description's
//! visual mesh) read by cps has the same convex hull as the same mesh as Blender's OBJ
//! (link1_vis.obj beside it); a cube written by hand in millimetres with y up, placed by a
//! node, lands where COLLADA says; broken files are named with their line.

use cps_geometry::Mesh;
use cps_movement::collision::read_mesh;
use cps_movement::dae::dae_triangles;
use nalgebra::Vector3;

/// The largest gap between two hulls' supports over a spread of directions.
fn hull_gap(a: &Mesh, b: &Mesh) -> f64 {
    let (ha, hb) = (a.hull("a").unwrap(), b.hull("b").unwrap());
    let (mut x, mut y) = (0u32, 0u32);
    (0..400)
        .map(|k| {
            // A Fibonacci sphere of directions.
            let z = 1.0 - (k as f64 + 0.5) / 200.0;
            let r = (1.0 - z * z).sqrt();
            let phi = k as f64 * 2.399_963_229_728_653;
            let d = Vector3::new(r * phi.cos(), r * phi.sin(), z);
            let (pa, pb) = (ha.support(&d, &mut x), hb.support(&d, &mut y));
            (d.dot(&pa) - d.dot(&pb)).abs()
        })
        .fold(0.0, f64::max)
}

#[test]
fn franka_descriptions_dae_has_the_hull_of_its_obj() {
    let Some((_, assets)) = cps_testkit::franky_sim::assets() else {
        return;
    };
    let meshes = assets.join("meshes");
    let (dae, _) = read_mesh(&meshes.join("link1_vis.dae"), [1.0; 3])
        .or_else(|_| {
            // A visual mesh need not be a closed surface: read it without the check.
            let text = std::fs::read_to_string(meshes.join("link1_vis.dae")).unwrap();
            Mesh::from_triangles(dae_triangles(&text).unwrap(), "dae").map(|m| (m, 0))
        })
        .unwrap();
    let obj = Mesh::from_obj(&std::fs::read(meshes.join("link1_vis.obj")).unwrap(), "obj").unwrap();
    assert!(dae.triangles.len() > 5_000, "{}", dae.triangles.len());
    let gap = hull_gap(&dae, &obj);
    assert!(gap < 1e-5, "the hulls' supports differ by {gap} m");
}

const CUBE: &str = r##"<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="millimetre" meter="0.001"/><up_axis>Y_UP</up_axis></asset>
  <library_geometries>
    <geometry id="cube-mesh"><mesh>
      <source id="cube-pos"><float_array id="cube-pos-array" count="24">
        0 0 0  10 0 0  10 10 0  0 10 0  0 0 10  10 0 10  10 10 10  0 10 10
      </float_array></source>
      <source id="cube-n"><float_array id="cube-n-array" count="3">0 0 1</float_array></source>
      <vertices id="cube-v"><input semantic="POSITION" source="#cube-pos"/></vertices>
      <polylist count="6">
        <input semantic="VERTEX" source="#cube-v" offset="0"/>
        <input semantic="NORMAL" source="#cube-n" offset="1"/>
        <vcount>4 4 4 4 4 4</vcount>
        <p>0 0 3 0 2 0 1 0  4 0 5 0 6 0 7 0  0 0 1 0 5 0 4 0  1 0 2 0 6 0 5 0  2 0 3 0 7 0 6 0  3 0 0 0 4 0 7 0</p>
      </polylist>
    </mesh></geometry>
  </library_geometries>
  <library_visual_scenes><visual_scene id="s">
    <node id="n"><translate>100 0 0</translate><instance_geometry url="#cube-mesh"/></node>
  </visual_scene></library_visual_scenes>
</COLLADA>
"##;

#[test]
fn a_cube_in_millimetres_with_y_up_lands_where_collada_puts_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.dae");
    std::fs::write(&path, CUBE).unwrap();
    let (mesh, holes) = read_mesh(&path, [2.0, 1.0, 1.0]).unwrap();
    assert_eq!(
        (mesh.vertices.len(), mesh.triangles.len(), holes),
        (8, 12, 0)
    );
    // Millimetres to metres, moved 0.1 m along x, y up turned to z up ((x, y, z) →
    // (x, −z, y)), then URDF's scale: x from 0.2 to 0.22, y from −0.01 to 0, z 0 to 0.01.
    let lo = mesh
        .vertices
        .iter()
        .fold(Vector3::repeat(f64::INFINITY), |a, v| a.inf(v));
    let hi = mesh
        .vertices
        .iter()
        .fold(Vector3::repeat(f64::NEG_INFINITY), |a, v| a.sup(v));
    for (got, want) in [(lo, [0.2, -0.01, 0.0]), (hi, [0.22, 0.0, 0.01])] {
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 1e-12, "{got:?} vs {want:?}");
        }
    }
}

#[test]
fn broken_collada_is_named_with_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let bad = |name: &str, text: &str, needle: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let e = read_mesh(&path, [1.0; 3]).unwrap_err();
        assert!(e.contains(name) && e.contains(needle), "{e}");
    };
    bad(
        "index.dae",
        &CUBE.replace("3 0 0 0 4 0 7 0</p>", "3 0 0 0 4 0 9 0</p>"),
        "line 15: corner 24 of <polylist> is vertex 9, of 8",
    );
    bad(
        "word.dae",
        &CUBE.replace("10 10 10", "10 ten 10"),
        "line 7: `ten` is not a number",
    );
    bad(
        "source.dae",
        &CUBE.replace("source=\"#cube-pos\"", "source=\"#elsewhere\""),
        "reads positions from `cube-v`, which the mesh does not have",
    );
    bad(
        "short.dae",
        &CUBE.replace(
            "<vcount>4 4 4 4 4 4</vcount>",
            "<vcount>4 4 4 4 4 4 4</vcount>",
        ),
        "names 28 corners of 2 indices each, and <p> has 48 indices",
    );
    bad("root.dae", "<robot/>", "not COLLADA's");
    bad(
        "unit.dae",
        &CUBE.replace("meter=\"0.001\"", "meter=\"-1\""),
        "not a positive number of metres",
    );
    bad("open.dae", &CUBE.replace("</COLLADA>", ""), "is not closed");
    bad(
        "empty.dae",
        &CUBE.replace("<instance_geometry url=\"#cube-mesh\"/>", ""),
        "no triangles: the mesh is empty",
    );
    // The sweep's two panics: an offset past every index (1 + usize::MAX wrapped to a
    // stride of 0, a division by zero) and a corner count past the indices (a sum that
    // wrapped, then an index out of bounds).
    bad(
        "offset.dae",
        &CUBE.replace("offset=\"1\"", "offset=\"18446744073709551615\""),
        "line 13: an <input> offset of 18446744073709551615",
    );
    bad(
        "vcount.dae",
        &CUBE.replace(
            "<vcount>4 4 4 4 4 4</vcount>",
            "<vcount>4 4 4 4 4 18446744073709551615</vcount>",
        ),
        "<vcount> gives a polygon 18446744073709552000 corners",
    );
    // One geometry placed 1 000 times in an 800 kB file held 3.2 GB: the triangles are
    // counted as they are placed, and refused past the ceiling.
    let node = "<node><instance_geometry url=\"#cube-mesh\"/></node>";
    let big = CUBE
        .replace(
            "<vcount>4 4 4 4 4 4</vcount>",
            &format!("<vcount>{}</vcount>", "4 ".repeat(6 * 400)),
        )
        .replace(
            "0 0 3 0 2 0 1 0  4 0 5 0 6 0 7 0  0 0 1 0 5 0 4 0  1 0 2 0 6 0 5 0  2 0 3 0 7 0 6 0  3 0 0 0 4 0 7 0",
            &"0 0 3 0 2 0 1 0  4 0 5 0 6 0 7 0  0 0 1 0 5 0 4 0  1 0 2 0 6 0 5 0  2 0 3 0 7 0 6 0  3 0 0 0 4 0 7 0 ".repeat(400),
        )
        .replace("<visual_scene id=\"s\">", &format!("<visual_scene id=\"s\">{}", node.repeat(1000)));
    bad(
        "instanced.dae",
        &big,
        "triangles after instancing: 2000002 would be held in memory, more than the ceiling of 2000000",
    );
}
