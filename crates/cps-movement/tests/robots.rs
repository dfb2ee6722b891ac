//! The thesis's three robots against an independent model: the UR3 (Universal Robots' DH
//! table and point masses) and the FANUC CRX-10iA (FANUC's URDF) by pinocchio
//! (tests/data/make_robot_references.py), the TOML and built-in copies against each other,
//! and the published figures the CRX's data must reproduce.

use cps_kinematics::GRAVITY;
use cps_movement::robot_file::load_robot;
use nalgebra::Vector3;
use serde_json::Value;

fn reference() -> Value {
    let text = include_str!("data/robots_pinocchio.json");
    serde_json::from_str(text).unwrap()
}

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// Forward kinematics and joint torques of `robot` at every reference state.
fn agrees_with_pinocchio(robot: &str, states: &Value) {
    let model = load_robot(robot, None, None).unwrap();
    let links = model.inertia.as_ref().expect("inertias");
    let (mut worst_tau, mut worst_pos) = (0.0_f64, 0.0_f64);
    for s in states.as_array().unwrap() {
        let q = numbers(&s["q"]);
        let tau = model
            .chain
            .inverse_dynamics(
                links,
                Vector3::from(GRAVITY),
                &q,
                &numbers(&s["qd"]),
                &numbers(&s["qdd"]),
            )
            .unwrap();
        for (a, b) in tau.iter().zip(numbers(&s["tau"])) {
            worst_tau = worst_tau.max((a - b).abs());
        }
        let pose = model.chain.fk(&q).unwrap();
        let p = numbers(&s["tip_position"]);
        worst_pos =
            worst_pos.max((pose.translation.vector - Vector3::from_column_slice(&p)).norm());
        let rows = s["tip_rotation"].as_array().unwrap();
        for (i, row) in rows.iter().enumerate() {
            for (j, r) in numbers(row).iter().enumerate() {
                assert!(
                    (pose.rotation.matrix()[(i, j)] - r).abs() < 1e-12,
                    "{robot}"
                );
            }
        }
    }
    assert!(
        worst_tau < 1e-9,
        "{robot}: torques differ by {worst_tau} N m"
    );
    assert!(
        worst_pos < 1e-12,
        "{robot}: tool positions differ by {worst_pos} m"
    );
}

#[test]
fn the_ur3_matches_pinocchio_on_universal_robots_data() {
    let r = reference();
    agrees_with_pinocchio("ur3", &r["ur3"]);
    // The robot file says the same as the built-in robot.
    agrees_with_pinocchio(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../configs/robots/ur3.toml"),
        &r["ur3"],
    );
    let ur3 = load_robot("ur3", None, None).unwrap();
    assert_eq!(
        ur3.limits.torque.as_deref(),
        Some(&[56.0, 56.0, 28.0, 12.0, 12.0, 12.0][..])
    );
}

#[test]
fn the_crx10ia_matches_pinocchio_and_fanuc_s_published_figures() {
    let r = reference();
    agrees_with_pinocchio("crx10ia", &r["crx10ia"]);
    let crx = load_robot("crx10ia", None, None).unwrap();
    // FANUC's xacro expanded by xacro and loaded in pinocchio (robot-ready notes §6): the
    // flange at (0.700, −0.150, 0.785) m and the gravity torques at q = 0.
    let flange = crx.chain.fk(&[0.0; 6]).unwrap().translation.vector;
    assert!((flange - Vector3::new(0.700, -0.150, 0.785)).norm() < 1e-12);
    let g = crx
        .chain
        .inverse_dynamics(
            crx.inertia.as_ref().unwrap(),
            Vector3::from(GRAVITY),
            &[0.0; 6],
            &[0.0; 6],
            &[0.0; 6],
        )
        .unwrap();
    for (a, b) in g.iter().zip([0.0, -38.17, 38.17, 4.90, 2.02, -0.005]) {
        assert!((a - b).abs() < 0.005, "{g:?}");
    }
    for (a, b) in g.iter().zip(numbers(&r["crx10ia_gravity_at_zero"])) {
        assert!((a - b).abs() < 1e-9);
    }
    // The URDF's limits: effort as torque limits, speeds, ranges.
    assert_eq!(
        crx.limits.torque.as_deref(),
        Some(&[400.0, 400.0, 200.0, 60.0, 60.0, 60.0][..])
    );
    let speeds = crx.chain.velocity_limits().unwrap();
    assert!((speeds[0] - 120f64.to_radians()).abs() < 1e-12);
    assert!((speeds[5] - 180f64.to_radians()).abs() < 1e-12);
    let (lo, hi) = crx.chain.limits().unwrap();
    assert!(
        (lo[2] - (-71f64).to_radians()).abs() < 1e-12
            && (hi[2] - 251f64.to_radians()).abs() < 1e-12
    );
    assert_eq!(crx.joint_names, ["J1", "J2", "J3", "J4", "J5", "J6"]);
}

/// The shipped Panda file holds every limit of the built-in Panda (Franka's Tables 5 and 6)
/// and its inertias.
#[test]
fn the_panda_file_and_the_built_in_panda_agree_on_every_limit() {
    let file = load_robot(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../configs/robots/panda.toml"
        ),
        None,
        None,
    )
    .unwrap();
    let built_in = load_robot("panda", None, None).unwrap();
    assert_eq!(file.limits, built_in.limits);
    assert_eq!(file.cartesian, built_in.cartesian);
    assert_eq!(file.chain.limits(), built_in.chain.limits());
    assert_eq!(
        file.chain.velocity_limits(),
        built_in.chain.velocity_limits()
    );
    let (a, b) = (file.inertia.unwrap(), built_in.inertia.unwrap());
    for (x, y) in a.iter().zip(&b) {
        assert!((x.mass - y.mass).abs() < 1e-12 && (x.com - y.com).norm() < 1e-12);
        assert!((x.inertia - y.inertia).norm() < 1e-12);
    }
    let c = built_in.cartesian.unwrap();
    assert_eq!(c.translation, [1.7, 13.0, 6500.0]);
    assert_eq!(c.rotation, [2.5, 25.0, 12500.0]);
    assert_eq!(c.elbow, [2.175, 10.0, 5000.0]);
}

/// A URDF's missing limits come from `ROBOT.limits.toml` beside it; the built-in CRX-10iA
/// has FANUC's MoveIt planning accelerations from its side file; bad side files are named
/// with their place.
#[test]
fn a_urdf_robot_takes_its_other_limits_from_a_side_file() {
    let crx = load_robot("crx10ia", None, None).unwrap();
    assert_eq!(
        crx.limits.acceleration.as_deref(),
        Some(&[0.4, 0.4, 0.4, 1.0, 1.0, 1.0][..])
    );
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("arm.urdf");
    std::fs::write(&urdf, cps_movement::robot_file::CRX10IA_URDF).unwrap();
    let plain = load_robot(urdf.to_str().unwrap(), None, None).unwrap();
    assert!(plain.limits.acceleration.is_none() && plain.cartesian.is_none());
    let side = dir.path().join("arm.limits.toml");
    std::fs::write(
        &side,
        "dddq_max = [1, 2, 3, 4, 5, 6]\ntau_max = [10, 10, 10, 5, 5, 5]\n[cartesian]\ntranslation = [1, 2, 3]\nrotation = [1, 2, 3]\nelbow = [1, 2, 3]\n",
    )
    .unwrap();
    let with = load_robot(urdf.to_str().unwrap(), None, None).unwrap();
    assert_eq!(
        with.limits.jerk.as_deref(),
        Some(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0][..])
    );
    assert_eq!(
        with.limits.torque.as_deref().unwrap()[0],
        10.0,
        "replaces the efforts"
    );
    assert_eq!(with.cartesian.unwrap().translation, [1.0, 2.0, 3.0]);
    for (text, wanted) in [
        (
            "ddq_max = [1, 2]\n",
            "arm.limits.toml:1:11: `ddq_max` needs 6 finite values > 0",
        ),
        ("ddq_max = [1, 2, 3, 4, 5, -6]\n", "`ddq_max` needs 6"),
        ("speed = [1]\n", "unknown field `speed`"),
        (
            "[cartesian]\ntranslation = [1, 2, 3]\nrotation = [1, 2, 3]\nelbow = [1, 0, 3]\n",
            "[cartesian] limits must be finite and > 0",
        ),
    ] {
        std::fs::write(&side, text).unwrap();
        let e = load_robot(urdf.to_str().unwrap(), None, None).unwrap_err();
        assert!(e.to_string().contains(wanted), "{e}");
    }
}
