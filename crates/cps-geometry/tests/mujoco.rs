//! cps-geometry's signed distances between franka_description's collision meshes (as their
//! convex hulls) against MuJoCo's (`mj_geomDistance`, native GJK/EPA on the same hulls) at
//! random poses, half of them overlapping: within 1 mm, as the collision check promises.
//! MuJoCo comes with franky-sim's environment (`bash .ci/peers`), and so do the meshes.

use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;

use cps_geometry::{Mesh, Shape, distance};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

fn pose(v: &serde_json::Value) -> Isometry3<f64> {
    let x: Vec<f64> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    Isometry3::from_parts(
        Translation3::new(x[0], x[1], x[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(x[3], x[4], x[5], x[6])),
    )
}

#[test]
fn distances_between_franka_link_hulls_agree_with_mujoco_within_a_millimetre() {
    let Some((python, assets)) = cps_testkit::franky_sim::assets() else {
        return;
    };
    let meshes = assets.join("meshes");
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/mujoco_pairs.py");
    let mut errors: Vec<f64> = Vec::new();
    let mut overlapping = 0;
    for (i, (a, b)) in [
        ("link3", "link5"),
        ("link0", "link6"),
        ("link1", "hand"),
        ("link7", "link4"),
    ]
    .into_iter()
    .enumerate()
    {
        let (fa, fb) = (
            meshes.join(format!("{a}_coll.stl")),
            meshes.join(format!("{b}_coll.stl")),
        );
        let shape = |f: &PathBuf| {
            let name = f.display().to_string();
            Shape::Convex(Arc::new(
                Mesh::read(f, [1.0; 3]).unwrap().0.hull(&name).unwrap(),
            ))
        };
        let (sa, sb) = (shape(&fa), shape(&fb));
        let out = Command::new(&python)
            .arg(&script)
            .arg(&fa)
            .arg(&fb)
            .args(["300", &i.to_string()])
            .output()
            .expect("run MuJoCo");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        for line in String::from_utf8_lossy(&out.stdout).lines() {
            let v: serde_json::Value = serde_json::from_str(line).unwrap();
            let reference = v["distance"].as_f64().unwrap();
            let s = distance(&sa, &pose(&v["a"]), &sb, &pose(&v["b"]));
            if reference < 0.0 {
                overlapping += 1;
            }
            let e = (s.distance - reference).abs();
            assert!(
                e < 1e-3,
                "{a}–{b}: cps {} against MuJoCo {reference}",
                s.distance
            );
            errors.push(e);
        }
    }
    errors.sort_by(f64::total_cmp);
    eprintln!(
        "{} pairs ({overlapping} overlapping): median error {:.2e} m, worst {:.2e} m",
        errors.len(),
        errors[errors.len() / 2],
        errors[errors.len() - 1]
    );
    assert_eq!(errors.len(), 1200);
    assert!(
        overlapping > 200 && overlapping < 1100,
        "{overlapping} of 1200 overlap"
    );
}
