//! Forward kinematics and Jacobians against independent reference data:
//! `tests/data/panda_reference.json` (roboticstoolbox-python, cross-checked with pinocchio
//! to 1e-15): the Panda's flange and Franka Hand TCP in modified DH, the same table read as
//! standard DH, and a Puma 560 in standard DH.

use cps_kinematics::robots::{PandaTool, panda, puma560};
use cps_kinematics::{DhConvention, DhLink, SerialChain};
use nalgebra::Isometry3;
use proptest::prelude::*;
use serde_json::Value;

const TOL: f64 = 1e-12;

fn reference() -> Value {
    serde_json::from_str(include_str!("data/panda_reference.json")).unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    match v {
        Value::Array(a) => a.iter().flat_map(floats).collect(),
        Value::Number(n) => vec![n.as_f64().unwrap()],
        other => panic!("not numeric: {other}"),
    }
}

fn check(chain: &SerialChain, q: &[f64], expect: &Value, what: &str) {
    let t = chain.fk_matrix(q).unwrap();
    let t_ref = floats(&expect["T"]);
    for r in 0..4 {
        for c in 0..4 {
            let d = (t[(r, c)] - t_ref[r * 4 + c]).abs();
            assert!(d < TOL, "{what}: T[{r}][{c}] off by {d:e}");
        }
    }
    let j = chain.jacobian(q).unwrap();
    let j_ref = floats(&expect["J"]);
    let n = chain.dof();
    for r in 0..6 {
        for c in 0..n {
            let d = (j[(r, c)] - j_ref[r * n + c]).abs();
            assert!(d < TOL, "{what}: J[{r}][{c}] off by {d:e}");
        }
    }
    if let Some(m) = expect.get("manipulability").and_then(Value::as_f64) {
        let got = chain.manipulability(q).unwrap();
        assert!(
            (got - m).abs() <= 1e-9 * m.max(1e-6),
            "{what}: manipulability {got} vs {m}"
        );
    }
}

#[test]
fn panda_flange_and_hand_match_the_reference_in_all_twenty_configurations() {
    let data = reference();
    let (flange, hand) = (panda(PandaTool::Flange), panda(PandaTool::HandTcp));
    let configs = data["configs"].as_array().unwrap();
    assert_eq!(configs.len(), 20);
    for c in configs {
        let q = floats(&c["q"]);
        let name = c["name"].as_str().unwrap();
        check(&flange, &q, &c["flange"], &format!("{name} flange"));
        check(&hand, &q, &c["hand_tcp"], &format!("{name} hand"));
    }
}

#[test]
fn the_same_table_read_as_standard_dh_is_a_different_robot_and_matches_too() {
    let data = reference();
    let rows: Vec<DhLink> = data["meta"]["dh_modified"].as_array().unwrap()[..7]
        .iter()
        .map(|r| {
            DhLink::new(
                r["a"].as_f64().unwrap(),
                r["d"].as_f64().unwrap(),
                r["alpha"].as_f64().unwrap(),
            )
        })
        .collect();
    let std = SerialChain::new(DhConvention::Standard, rows)
        .unwrap()
        .with_tool(Isometry3::translation(0.0, 0.0, 0.107));
    let flange = panda(PandaTool::Flange);
    let mut differs = false;
    for c in data["configs"].as_array().unwrap() {
        let q = floats(&c["q"]);
        check(&std, &q, &c["std_dh_same_table"], "standard-DH reading");
        differs |= (std.fk(&q).unwrap().translation.vector
            - flange.fk(&q).unwrap().translation.vector)
            .norm()
            > 1e-3;
    }
    assert!(differs, "the conventions must not coincide");
}

#[test]
fn puma560_matches_the_reference() {
    let data = reference();
    let puma = puma560();
    for c in data["puma560_standard_dh"]["configs"].as_array().unwrap() {
        check(&puma, &floats(&c["q"]), c, "puma560");
    }
}

#[test]
fn controller_steps_match_the_reference() {
    use cps_kinematics::controllers::{dls_step, pinv_step, to_dmatrix, transpose_step};
    let data = reference();
    let e = floats(&data["meta"]["e_test"]);
    let lambda = data["meta"]["dls_lambda"].as_f64().unwrap();
    let arm = panda(PandaTool::Flange);
    for c in data["configs"].as_array().unwrap() {
        let name = c["name"].as_str().unwrap();
        let q = floats(&c["q"]);
        let j = to_dmatrix(&arm.jacobian(&q).unwrap());
        let f = &c["flange"];
        let sv = floats(&f["singular_values"]);
        let singular = sv.iter().cloned().fold(f64::INFINITY, f64::min) < 1e-10;
        let close = |got: &nalgebra::DVector<f64>, key: &str, tol: f64| {
            for (k, r) in floats(&f[key]).iter().enumerate() {
                assert!(
                    (got[k] - r).abs() < tol,
                    "{name} {key}[{k}]: {} vs {r}",
                    got[k]
                );
            }
        };
        close(&transpose_step(&j, &e), "JT_e", 1e-12);
        close(&dls_step(&j, &e, lambda), "dls_J_e", 1e-12);
        // At the singular configurations the pseudo-inverse depends on the rank cut-off.
        if !singular {
            close(&pinv_step(&j, &e), "pinv_J_e", 1e-10);
        }
    }
}

#[test]
fn damped_steps_stay_bounded_through_a_singularity_where_the_pseudo_inverse_explodes() {
    use cps_kinematics::controllers::{dls_step, pinv_step, to_dmatrix};
    let arm = panda(PandaTool::Flange);
    let e = [0.0, 0.0, 0.01, 0.0, 0.0, 0.0];
    let lambda = 0.1;
    let mut worst_pinv = 0.0f64;
    // Approach the stretched-out singularity (q4 → 0 straightens the elbow).
    for k in 0..50 {
        let q4 = -0.5 * (1.0 - k as f64 / 50.0) - 1e-7;
        let q = [0.0, 0.3, 0.0, q4, 0.0, 1.0, 0.0];
        let j = to_dmatrix(&arm.jacobian(&q).unwrap());
        let dls = dls_step(&j, &e, lambda).norm();
        assert!(
            dls <= 0.01 / (2.0 * lambda) + 1e-12,
            "DLS step {dls} at q4 = {q4}"
        );
        worst_pinv = worst_pinv.max(pinv_step(&j, &e).norm());
    }
    assert!(
        worst_pinv > 1.0,
        "the pseudo-inverse should blow up near the singularity: {worst_pinv}"
    );
}

#[test]
fn bad_joint_vectors_are_typed_errors() {
    let arm = panda(PandaTool::Flange);
    assert!(matches!(
        arm.fk(&[0.0; 6]),
        Err(cps_kinematics::KinematicsError::JointCount {
            expected: 7,
            got: 6
        })
    ));
    let mut q = [0.0; 7];
    q[3] = f64::NAN;
    assert!(matches!(
        arm.jacobian(&q),
        Err(cps_kinematics::KinematicsError::NotFinite { joint: 4, .. })
    ));
    assert!(SerialChain::new(DhConvention::Modified, vec![]).is_err());
}

proptest! {
    /// The analytic Jacobian equals central finite differences of forward kinematics:
    /// linear rows against the position, angular rows against the rotation's change.
    #[test]
    fn jacobian_matches_finite_differences(q in proptest::collection::vec(-2.8f64..2.8, 7)) {
        let arm = panda(PandaTool::HandTcp);
        let j = arm.jacobian(&q).unwrap();
        let h = 1e-6;
        for i in 0..7 {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[i] += h;
            qm[i] -= h;
            let (tp, tm) = (arm.fk(&qp).unwrap(), arm.fk(&qm).unwrap());
            let dv = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
            let quat = |r: &nalgebra::Rotation3<f64>| nalgebra::UnitQuaternion::from_rotation_matrix(r);
            let dw = (quat(&tp.rotation) * quat(&tm.rotation).inverse()).scaled_axis() / (2.0 * h);
            for k in 0..3 {
                prop_assert!((dv[k] - j[(k, i)]).abs() < 1e-7, "v joint {} row {}", i, k);
                prop_assert!((dw[k] - j[(k + 3, i)]).abs() < 1e-7, "w joint {} row {}", i, k);
            }
        }
    }
}

mod inverse {
    use cps_kinematics::robots::{PANDA_Q_MAX, PANDA_Q_MIN, PandaTool, panda};
    use cps_kinematics::{IkConfig, IkTarget, KinematicsError, solve_ik};
    use nalgebra::{UnitQuaternion, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];

    /// FK∘IK round trips: random in-limit configurations give reachable poses; IK from the
    /// ready pose reaches each to 1e-9 m / 1e-9 rad inside the limits.
    #[test]
    fn full_pose_round_trips_within_limits() {
        let arm = panda(PandaTool::HandTcp);
        let mut rng = ChaCha8Rng::seed_from_u64(42);
        let (mut ok, total) = (0, 200);
        for _ in 0..total {
            let q: Vec<f64> = PANDA_Q_MIN
                .iter()
                .zip(&PANDA_Q_MAX)
                .map(|(l, h)| rng.random_range(*l..*h))
                .collect();
            let target = arm.fk(&q).unwrap();
            if let Ok(sol) = solve_ik(&arm, &IkTarget::Pose(target), &READY, &IkConfig::default()) {
                let reached = arm.fk(&sol.q).unwrap();
                assert!((reached.translation.vector - target.translation.vector).norm() <= 1e-9);
                let dr = UnitQuaternion::from_rotation_matrix(
                    &(reached.rotation * target.rotation.inverse()),
                )
                .angle();
                assert!(dr <= 1e-9, "rotation error {dr}");
                for (i, v) in sol.q.iter().enumerate() {
                    assert!(
                        (PANDA_Q_MIN[i]..=PANDA_Q_MAX[i]).contains(v),
                        "joint {} at {v}",
                        i + 1
                    );
                }
                ok += 1;
            }
        }
        assert!(ok as f64 >= 0.995 * total as f64, "{ok}/{total} solved");
    }

    #[test]
    fn position_targets_and_unreachable_targets() {
        let arm = panda(PandaTool::HandTcp);
        let target = Vector3::new(0.4, 0.2, 0.5);
        let sol = solve_ik(
            &arm,
            &IkTarget::Position(target),
            &READY,
            &IkConfig::default(),
        )
        .unwrap();
        assert!((arm.fk(&sol.q).unwrap().translation.vector - target).norm() <= 1e-9);
        let far = Vector3::new(3.0, 0.0, 0.5);
        let cfg = IkConfig {
            restarts: 5,
            ..IkConfig::default()
        };
        match solve_ik(&arm, &IkTarget::Position(far), &READY, &cfg) {
            Err(KinematicsError::Unreachable {
                position_error,
                iterations,
                ..
            }) => {
                assert!(position_error > 1.5, "residual {position_error}");
                assert!(iterations > 0);
            }
            other => panic!("{other:?}"),
        }
        let nan = IkTarget::Position(Vector3::new(f64::NAN, 0.0, 0.0));
        assert!(solve_ik(&arm, &nan, &READY, &cfg).is_err());
    }
}

#[test]
fn ur3_zero_configuration_and_jacobian_consistency() {
    use cps_kinematics::robots::ur3;
    let arm = ur3();
    // Standard DH at q = 0: the arm lies along −x, offset along −y by d4 + d6, and d5 lower.
    let p = arm.fk(&[0.0; 6]).unwrap().translation.vector;
    let expect = [-0.24365 - 0.21325, -(0.11235 + 0.0819), 0.1519 - 0.08535];
    for k in 0..3 {
        assert!((p[k] - expect[k]).abs() < 1e-12, "{p:?}");
    }
    let q = [0.3, -1.1, 0.8, -0.4, 1.2, 0.5];
    let j = arm.jacobian(&q).unwrap();
    let h = 1e-6;
    for i in 0..6 {
        let (mut qp, mut qm) = (q, q);
        qp[i] += h;
        qm[i] -= h;
        let dv = (arm.fk(&qp).unwrap().translation.vector
            - arm.fk(&qm).unwrap().translation.vector)
            / (2.0 * h);
        for k in 0..3 {
            assert!((dv[k] - j[(k, i)]).abs() < 1e-7);
        }
    }
}

#[test]
fn workspace_samples_are_reachable_and_reproducible() {
    use cps_kinematics::sample_workspace;
    let arm = panda(PandaTool::HandTcp);
    let a = sample_workspace(&arm, 50, 3);
    assert_eq!(a, sample_workspace(&arm, 50, 3));
    assert_ne!(a, sample_workspace(&arm, 50, 4));
    for p in &a {
        // The Panda reaches about 0.855 m from joint 2 (0.333 m above the base) plus the hand.
        assert!((p - nalgebra::Vector3::new(0.0, 0.0, 0.333)).norm() < 0.855 + 0.11 + 0.11);
    }
}

#[test]
fn grubler_counts_classic_mechanisms() {
    use cps_kinematics::degrees_of_freedom;
    assert_eq!(degrees_of_freedom(false, 4, &[1, 1, 1, 1]).unwrap(), 1); // four-bar linkage
    assert_eq!(degrees_of_freedom(false, 5, &[1; 5]).unwrap(), 2); // five-bar linkage
    assert_eq!(degrees_of_freedom(true, 8, &[1; 7]).unwrap(), 7); // the Panda: 7 revolute joints
    assert_eq!(degrees_of_freedom(true, 7, &[1; 6]).unwrap(), 6); // UR3
    assert!(degrees_of_freedom(false, 3, &[4]).is_err());
}
