//! Forward kinematics, Jacobians and inverse dynamics against independent references, and
//! the limit checks. Reference data:
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

    const READY: [f64; 7] = cps_kinematics::robots::PANDA_READY;

    /// FK∘IK round trips: random in-limit configurations give reachable poses; IK from the
    /// ready pose reaches at least 99.9 % of 1000 of them to 1e-9 m / 1e-9 rad inside the
    /// limits.
    #[test]
    fn full_pose_round_trips_within_limits() {
        let arm = panda(PandaTool::HandTcp);
        let mut rng = ChaCha8Rng::seed_from_u64(42);
        let (mut ok, total) = (0, 1000);
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
        assert!(ok as f64 >= 0.999 * total as f64, "{ok}/{total} solved");
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

mod urdf {
    use super::*;
    use cps_kinematics::{KinematicsError, chain_from_urdf};

    const PANDA_URDF: &str = include_str!("../../../configs/robots/panda.urdf");

    /// The Panda written as URDF joints (origins and axes, no DH) is a different
    /// description of the same robot: it must match the reference to 1e-12 as well.
    #[test]
    fn the_panda_urdf_matches_the_reference_at_the_tcp_and_the_flange() {
        let data = reference();
        let hand = chain_from_urdf(PANDA_URDF, None).unwrap();
        assert_eq!(hand.tip_link, "panda_hand_tcp");
        assert_eq!(hand.base_link, "panda_link0");
        assert_eq!(hand.joint_names.len(), 7);
        assert_eq!(hand.chain.limits(), panda(PandaTool::HandTcp).limits());
        assert_eq!(
            hand.chain.velocity_limits(),
            Some(&cps_kinematics::robots::PANDA_DQ_MAX[..])
        );
        let flange = chain_from_urdf(PANDA_URDF, Some("panda_link8")).unwrap();
        for c in data["configs"].as_array().unwrap() {
            let q = floats(&c["q"]);
            let name = c["name"].as_str().unwrap();
            check(
                &hand.chain,
                &q,
                &c["hand_tcp"],
                &format!("{name} urdf hand"),
            );
            check(
                &flange.chain,
                &q,
                &c["flange"],
                &format!("{name} urdf flange"),
            );
        }
    }

    #[test]
    fn non_serial_or_malformed_urdf_is_refused_with_the_reason() {
        let err = |xml: &str, tip: Option<&str>| match chain_from_urdf(xml, tip) {
            Err(KinematicsError::InvalidModel(m)) => m,
            other => panic!("{other:?}"),
        };
        assert!(err("<robot name='x'><link name='a'/>", None).starts_with("URDF:"));
        let finger = err(PANDA_URDF, Some("panda_leftfinger"));
        assert!(
            finger.contains("panda_finger_joint1") && finger.contains("prismatic"),
            "{finger}"
        );
        assert!(err(PANDA_URDF, Some("nowhere")).contains("no link named `nowhere`"));
        let two_roots = "<robot name='x'><link name='a'/><link name='b'/></robot>";
        assert!(err(two_roots, None).contains("several root links"));
        let forked = r#"<robot name="y"><link name="a"/><link name="b"/><link name="c"/>
            <joint name="j1" type="continuous"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint>
            <joint name="j2" type="continuous"><parent link="a"/><child link="c"/><axis xyz="0 1 0"/></joint>
            </robot>"#;
        assert!(err(forked, None).contains("several tip links are possible (b, c)"));
        let zero_axis = forked.replace("0 1 0", "0 0 0");
        assert!(err(&zero_axis, Some("c")).contains("axis is zero"));
        // A continuous joint is unlimited, and an axis other than z works.
        let c = chain_from_urdf(forked, Some("c")).unwrap().chain;
        assert_eq!(c.limits().unwrap().0, &[f64::NEG_INFINITY]);
        let j = c.jacobian(&[0.4]).unwrap();
        let w = nalgebra::Vector3::new(j[(3, 0)], j[(4, 0)], j[(5, 0)]);
        assert!((w - nalgebra::Vector3::y()).norm() < 1e-15, "{w:?}");
    }
}

#[test]
fn a_base_transform_moves_every_frame_and_link_frames_end_at_the_tool() {
    let q = [0.1, -0.4, 0.3, -2.0, 0.2, 1.6, 0.7];
    let base = Isometry3::new(
        nalgebra::Vector3::new(0.5396, 0.02, 0.749),
        nalgebra::Vector3::new(0.0, 0.0, 0.3),
    );
    let arm = panda(PandaTool::Flange);
    let placed = panda(PandaTool::Flange).with_base(base);
    let base_m = base.to_homogeneous();
    let (t0, t1) = (arm.fk_matrix(&q).unwrap(), placed.fk_matrix(&q).unwrap());
    assert!((base_m * t0 - t1).abs().max() < 1e-14);
    let frames = placed.fk_frames(&q).unwrap();
    let last = frames.link_frames[6] * nalgebra::Translation3::new(0.0, 0.0, 0.107);
    assert!((last.to_homogeneous() - t1).abs().max() < 1e-14);
    // Modified DH: link frame 1 sits 0.333 m above the base, turned by q1.
    let f1 = frames.link_frames[0].to_homogeneous();
    let expect = base_m
        * nalgebra::Isometry3::new(
            nalgebra::Vector3::new(0.0, 0.0, 0.333),
            nalgebra::Vector3::new(0.0, 0.0, q[0]),
        )
        .to_homogeneous();
    assert!((f1 - expect).abs().max() < 1e-14);
    // Rotation parts of the Jacobian are unchanged by a base translation, turned by its rotation.
    let (j0, j1) = (arm.jacobian(&q).unwrap(), placed.jacobian(&q).unwrap());
    assert_eq!(arm.jacobian_position(&q).unwrap(), j0.fixed_rows::<3>(0));
    let r = base.rotation;
    for i in 0..7 {
        let w0 = nalgebra::Vector3::new(j0[(3, i)], j0[(4, i)], j0[(5, i)]);
        let w1 = nalgebra::Vector3::new(j1[(3, i)], j1[(4, i)], j1[(5, i)]);
        assert!((r * w0 - w1).norm() < 1e-14);
    }
}

mod control_and_execution {
    use cps_kinematics::controllers::{ControllerConfig, InverseMethod, NullSpace, control_step};
    use cps_kinematics::robots::{PANDA_DQ_MAX, PandaTool, panda};
    use cps_kinematics::{IkConfig, IkTarget, KinematicsError, check_path};
    use nalgebra::Vector3;

    const THESIS_Q0: [f64; 7] = [
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        std::f64::consts::FRAC_PI_2,
        std::f64::consts::FRAC_PI_4,
    ];
    const READY: [f64; 7] = cps_kinematics::robots::PANDA_READY;

    /// A secondary task in the null space does not move the tool (to first order), and a
    /// posture task brings the redundant joint towards the preferred posture.
    #[test]
    fn null_space_motion_leaves_the_tool_alone_and_reaches_the_posture() {
        let arm = panda(PandaTool::HandTcp);
        let q = READY;
        let hold = IkTarget::Pose(arm.fk(&q).unwrap());
        let mut pref = READY;
        pref[2] += 0.5; // elbow swivel: reachable by self-motion
        let cfg = ControllerConfig {
            null_space: NullSpace::Posture {
                q: pref.to_vec(),
                gain: 0.2,
            },
            ..ControllerConfig::default()
        };
        let st = control_step(&arm, &q, &hold, 0.01, &cfg).unwrap();
        let j = arm.jacobian(&q).unwrap();
        let dq = nalgebra::DVector::from_column_slice(&st.dq);
        let twist = j * dq;
        assert!(st.dq.iter().any(|d| d.abs() > 1e-4), "no null-space motion");
        assert!(twist.norm() < 1e-12, "tool moved: {twist}");
        // Iterate: the tool stays put while joint 3 approaches the preferred angle.
        let mut q = q.to_vec();
        for _ in 0..300 {
            let st = control_step(&arm, &q, &hold, 0.01, &cfg).unwrap();
            for (a, d) in q.iter_mut().zip(&st.dq) {
                *a += d;
            }
        }
        let moved = (arm.fk(&q).unwrap().translation.vector
            - arm.fk(&READY).unwrap().translation.vector)
            .norm();
        assert!(moved < 1e-6, "tool drifted {moved} m");
        // The self-motion manifold is one-dimensional: the posture error shrinks as far as
        // moving along it can (here from 0.5 to the closest point of the manifold).
        let dist = |q: &[f64]| {
            q.iter()
                .zip(&pref)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        assert!(
            dist(&q) < 0.9 * dist(&READY),
            "posture error {} (start 0.5)",
            dist(&q)
        );
        // Joint-limit avoidance moves joints towards mid-range without moving the tool.
        let near_limit = [2.7, 0.3, 0.0, -1.5, 0.0, 1.8, 0.0];
        let hold = IkTarget::Position(arm.fk(&near_limit).unwrap().translation.vector);
        let cfg = ControllerConfig {
            null_space: NullSpace::JointLimits { gain: 1.0 },
            ..ControllerConfig::default()
        };
        let st = control_step(&arm, &near_limit, &hold, 0.01, &cfg).unwrap();
        assert!(
            st.dq[0] < 0.0,
            "joint 1 should leave its upper limit: {:?}",
            st.dq
        );
    }

    /// Damping grows through a singularity: joint speeds stay bounded where the plain
    /// pseudo-inverse explodes, and the damping is zero far from it.
    #[test]
    fn adaptive_damping_bounds_steps_at_a_singularity() {
        let arm = panda(PandaTool::Flange);
        let free = ControllerConfig {
            respect_limits: false,
            ..ControllerConfig::default()
        };
        let pinv = ControllerConfig {
            method: InverseMethod::PseudoInverse,
            ..free.clone()
        };
        // Next to the thesis's initial configuration, which is singular (σ_min ≈ 4e-17 in
        // the reference; exactly at it the pseudo-inverse's rank cut-off hides the problem).
        let mut q = THESIS_Q0;
        q[1] = 1e-4;
        // A 1 cm / 0.01 rad error along the direction the arm can hardly move in.
        let j = cps_kinematics::controllers::to_dmatrix(&arm.jacobian(&q).unwrap());
        let svd = j.svd(true, false);
        let k = svd.singular_values.imin();
        let e = svd.u.unwrap().column(k) * 0.01;
        let pose = arm.fk(&q).unwrap();
        let rot = nalgebra::Rotation3::new(Vector3::new(e[3], e[4], e[5]));
        let target = IkTarget::Pose(nalgebra::IsometryMatrix3::from_parts(
            nalgebra::Translation3::from(pose.translation.vector + Vector3::new(e[0], e[1], e[2])),
            rot * pose.rotation,
        ));
        let damped = control_step(&arm, &q, &target, 0.01, &free).unwrap();
        let exact = control_step(&arm, &q, &target, 0.01, &pinv).unwrap();
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(damped.damping > 0.04, "damping {}", damped.damping);
        assert!(norm(&damped.dq) <= 0.01 / (2.0 * 0.05) + 1e-9);
        assert!(
            norm(&exact.dq) > 10.0 * norm(&damped.dq),
            "{} vs {}",
            norm(&exact.dq),
            norm(&damped.dq)
        );
        let easy = control_step(&arm, &READY, &target, 0.01, &free).unwrap();
        assert_eq!(easy.damping, 0.0);
    }

    #[test]
    fn path_checks_find_the_first_unreachable_sample() {
        let arm = panda(PandaTool::HandTcp);
        let p0 = arm.fk(&READY).unwrap().translation.vector;
        let mut path: Vec<IkTarget> = (0..50)
            .map(|k| IkTarget::Position(p0 + Vector3::new(0.004 * k as f64, 0.0, 0.0)))
            .collect();
        let times: Vec<f64> = (0..60).map(|k| k as f64 * 0.01).collect();
        let step: Vec<f64> = PANDA_DQ_MAX.iter().map(|v| v * 0.01 * 5.0).collect();
        let qs = check_path(
            &arm,
            &path,
            &times[..50],
            &READY,
            &IkConfig::default(),
            Some(&step),
        )
        .unwrap();
        assert_eq!(qs.len(), 50);
        for (q, t) in qs.iter().zip(&path) {
            let IkTarget::Position(p) = t else {
                unreachable!()
            };
            assert!((arm.fk(q).unwrap().translation.vector - p).norm() < 1e-9);
        }
        path.extend((0..10).map(|_| IkTarget::Position(Vector3::new(1.5, 0.0, 0.3))));
        let cfg = IkConfig {
            restarts: 3,
            ..IkConfig::default()
        };
        match check_path(&arm, &path, &times, &READY, &cfg, None) {
            Err(KinematicsError::PathUnreachable {
                sample,
                time,
                reason,
            }) => {
                assert_eq!(sample, 50);
                assert!((time - 0.5).abs() < 1e-12);
                assert!(reason.contains("best position error"), "{reason}");
            }
            other => panic!("{other:?}"),
        }
    }
}

/// Inverse dynamics of the Panda with Gaz et al.'s inertias against pinocchio's RNEA on 50
/// random states (`tests/data/panda_rnea_pinocchio.json`, made by `make_panda_rnea.py`
/// from the published tables, independently of this crate's code).
#[test]
fn panda_inverse_dynamics_matches_pinocchio() {
    let reference: serde_json::Value =
        serde_json::from_str(include_str!("data/panda_rnea_pinocchio.json")).unwrap();
    let arm = cps_kinematics::robots::panda(cps_kinematics::robots::PandaTool::HandTcp);
    let links = cps_kinematics::robots::panda_inertia();
    let gravity = nalgebra::Vector3::from(cps_kinematics::GRAVITY);
    let vec = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let states = reference["states"].as_array().unwrap();
    assert_eq!(states.len(), 50);
    let mut worst = 0.0_f64;
    for s in states {
        let tau = arm
            .inverse_dynamics(
                &links,
                gravity,
                &vec(&s["q"]),
                &vec(&s["qd"]),
                &vec(&s["qdd"]),
            )
            .unwrap();
        for (a, b) in tau.iter().zip(vec(&s["tau"])) {
            worst = worst.max((a - b).abs());
        }
    }
    assert!(worst < 1e-9, "largest torque difference {worst:e} N m");
}

/// Inverse dynamics against independent formulas (the gradient of the potential energy, the
/// Lagrangian equations of motion), every derivative by finite differences of FK.
mod dynamics {
    use cps_kinematics::robots::{PandaTool, panda, panda_inertia};
    use cps_kinematics::{GRAVITY, LinkInertia, SerialChain};
    use nalgebra::{DMatrix, DVector};
    use nalgebra::{Matrix3, Vector3};
    use rand::{Rng, SeedableRng};

    /// Centres of mass and link rotations in the world frame, from forward kinematics only.
    fn coms(
        chain: &SerialChain,
        links: &[LinkInertia],
        q: &[f64],
    ) -> Vec<(Vector3<f64>, Matrix3<f64>)> {
        let frames = chain.fk_frames(q).unwrap().link_frames;
        frames
            .iter()
            .zip(links)
            .map(|(f, l)| {
                let r = *f.rotation.matrix();
                (f.translation.vector + r * l.com, r)
            })
            .collect()
    }

    /// The mass matrix from the kinetic energy, `M = Σ m Jvᵀ Jv + Jωᵀ I Jω`, with the
    /// Jacobians of each centre of mass and link rotation by central differences of forward
    /// kinematics: independent of the recursion.
    fn mass_matrix(chain: &SerialChain, links: &[LinkInertia], q: &[f64]) -> DMatrix<f64> {
        let n = q.len();
        let h = 1e-6;
        let base = coms(chain, links, q);
        let mut m = DMatrix::zeros(n, n);
        let mut jv = vec![DMatrix::<f64>::zeros(3, n); n];
        let mut jw = vec![DMatrix::<f64>::zeros(3, n); n];
        for j in 0..n {
            let (mut qp, mut qm) = (q.to_vec(), q.to_vec());
            qp[j] += h;
            qm[j] -= h;
            let (p, mi) = (coms(chain, links, &qp), coms(chain, links, &qm));
            for i in 0..n {
                let dv = (p[i].0 - mi[i].0) / (2.0 * h);
                // [ω]× = Ṙ Rᵀ
                let s = (p[i].1 - mi[i].1) / (2.0 * h) * base[i].1.transpose();
                let dw = Vector3::new(s[(2, 1)], s[(0, 2)], s[(1, 0)]);
                jv[i].set_column(j, &dv);
                jw[i].set_column(j, &dw);
            }
        }
        for i in 0..n {
            let inertia = base[i].1 * links[i].inertia * base[i].1.transpose();
            let iw = DMatrix::from_column_slice(3, 3, inertia.as_slice());
            m += jv[i].transpose() * &jv[i] * links[i].mass + jw[i].transpose() * iw * &jw[i];
        }
        m
    }

    fn random_state(rng: &mut impl Rng, chain: &SerialChain) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let q = chain.random_configuration(rng);
        let qd = (0..q.len()).map(|_| rng.random_range(-2.0..2.0)).collect();
        let qdd = (0..q.len()).map(|_| rng.random_range(-5.0..5.0)).collect();
        (q, qd, qdd)
    }

    #[test]
    fn gravity_torques_are_the_gradient_of_the_potential_energy() {
        let (chain, links) = (panda(PandaTool::Flange), panda_inertia());
        let g = Vector3::from(GRAVITY);
        let potential = |q: &[f64]| -> f64 {
            coms(&chain, &links, q)
                .iter()
                .zip(&links)
                .map(|((c, _), l)| -l.mass * g.dot(c))
                .sum()
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for _ in 0..20 {
            let q = chain.random_configuration(&mut rng);
            let tau = chain
                .inverse_dynamics(&links, g, &q, &[0.0; 7], &[0.0; 7])
                .unwrap();
            for j in 0..7 {
                let h = 1e-6;
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[j] += h;
                qm[j] -= h;
                let grad = (potential(&qp) - potential(&qm)) / (2.0 * h);
                assert!(
                    (tau[j] - grad).abs() < 1e-7,
                    "joint {j}: {} vs {grad}",
                    tau[j]
                );
            }
        }
    }

    #[test]
    fn the_full_equation_of_motion_matches_the_lagrangian() {
        // τ = M q̈ + C(q, q̇) q̇ + g(q), with C q̇ = Ṁ q̇ − ½ ∂(q̇ᵀ M q̇)/∂q, M from the kinetic
        // energy, every derivative by central differences of forward kinematics.
        let (chain, links) = (panda(PandaTool::Flange), panda_inertia());
        let g = Vector3::from(GRAVITY);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        for _ in 0..5 {
            let (q, qd, qdd) = random_state(&mut rng, &chain);
            let tau = chain.inverse_dynamics(&links, g, &q, &qd, &qdd).unwrap();
            let gravity = chain
                .inverse_dynamics(&links, g, &q, &[0.0; 7], &[0.0; 7])
                .unwrap();
            let m = mass_matrix(&chain, &links, &q);
            let v = DVector::from_column_slice(&qd);
            let h = 1e-4;
            let shifted =
                |s: f64| -> Vec<f64> { q.iter().zip(&qd).map(|(a, b)| a + s * b).collect() };
            let m_dot = (mass_matrix(&chain, &links, &shifted(h))
                - mass_matrix(&chain, &links, &shifted(-h)))
                / (2.0 * h);
            let mut coriolis = &m_dot * &v;
            for j in 0..7 {
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[j] += h;
                qm[j] -= h;
                let e = |q: &[f64]| (v.transpose() * mass_matrix(&chain, &links, q) * &v)[(0, 0)];
                coriolis[j] -= 0.5 * (e(&qp) - e(&qm)) / (2.0 * h);
            }
            let expected = &m * DVector::from_column_slice(&qdd)
                + coriolis
                + DVector::from_column_slice(&gravity);
            for j in 0..7 {
                assert!(
                    (tau[j] - expected[j]).abs() < 1e-4 * (1.0 + expected[j].abs()),
                    "joint {j}: {} vs {}",
                    tau[j],
                    expected[j]
                );
            }
            // And the mass matrix column by column from the recursion, without gravity.
            for j in 0..7 {
                let mut e = [0.0; 7];
                e[j] = 1.0;
                let col = chain
                    .inverse_dynamics(&links, Vector3::zeros(), &q, &[0.0; 7], &e)
                    .unwrap();
                for i in 0..7 {
                    assert!(
                        (col[i] - m[(i, j)]).abs() < 1e-7,
                        "M[{i},{j}]: {} vs {}",
                        col[i],
                        m[(i, j)]
                    );
                }
            }
        }
    }

    #[test]
    fn impossible_inertias_and_wrong_lengths_are_refused() {
        assert!(LinkInertia::new(-1.0, [0.0; 3], [1.0, 0.0, 0.0, 1.0, 0.0, 1.0]).is_err());
        let e = LinkInertia::new(1.0, [0.0; 3], [1.0, 0.0, 0.0, 1.0, 0.0, 3.0]).unwrap_err();
        assert!(e.to_string().contains("not a rigid body"), "{e}");
        let chain = panda(PandaTool::Flange);
        let e = chain
            .inverse_dynamics(
                &panda_inertia()[..6],
                Vector3::zeros(),
                &[0.0; 7],
                &[0.0; 7],
                &[0.0; 7],
            )
            .unwrap_err();
        assert!(
            e.to_string().contains("links has 6 entries for 7 joints"),
            "{e}"
        );
    }
}

/// Checking joint trajectories against the Panda's limits.
mod limits {
    use cps_kinematics::robots::{PandaTool, panda, panda_inertia, panda_limits};
    use cps_kinematics::{GRAVITY, LimitCheck, Quantity, check_joint_trajectory};
    use nalgebra::Vector3;

    const DT: f64 = 0.001;

    fn check(q: &[Vec<f64>], inertia: bool) -> LimitCheck {
        let chain = panda(PandaTool::HandTcp);
        let links = panda_inertia();
        let (limits, _) = panda_limits();
        check_joint_trajectory(
            &chain,
            &limits,
            inertia.then_some(links.as_slice()),
            Vector3::from(GRAVITY),
            0.0,
            DT,
            q,
        )
        .unwrap()
    }

    fn usage(c: &LimitCheck, q: Quantity) -> &[f64] {
        &c.peak_usage.iter().find(|(k, _)| *k == q).unwrap().1
    }

    const READY: [f64; 7] = cps_kinematics::robots::PANDA_READY;

    #[test]
    fn standing_still_uses_only_the_torque_against_gravity() {
        let q = vec![READY.to_vec(); 100];
        let c = check(&q, true);
        assert!(c.ok(), "{:?}", c.violations);
        assert!(c.not_checked.is_empty());
        for quantity in [
            Quantity::Velocity,
            Quantity::Acceleration,
            Quantity::Jerk,
            Quantity::TorqueRate,
        ] {
            assert!(
                usage(&c, quantity).iter().all(|u| *u == 0.0),
                "{quantity:?}"
            );
        }
        let chain = panda(PandaTool::HandTcp);
        let g = chain
            .inverse_dynamics(
                &panda_inertia(),
                Vector3::from(GRAVITY),
                &READY,
                &[0.0; 7],
                &[0.0; 7],
            )
            .unwrap();
        let torque = usage(&c, Quantity::Torque);
        for (j, limit) in [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]
            .iter()
            .enumerate()
        {
            assert!((torque[j] - 100.0 * g[j].abs() / limit).abs() < 1e-9);
        }
    }

    #[test]
    fn a_sine_uses_its_analytic_peaks_and_a_fast_one_violates_them() {
        // Joint 1 follows A sin(w t): its peak speed A w shows as the velocity usage, and the
        // jump from rest to A w at the first command as an acceleration of A w / dt.
        let (amp, w) = (0.2, 5.0);
        let q: Vec<Vec<f64>> = (0..=2513)
            .map(|k| {
                let mut r = READY.to_vec();
                r[0] = amp * (w * k as f64 * DT).sin();
                r
            })
            .collect();
        let c = check(&q, false);
        let vel = usage(&c, Quantity::Velocity)[0];
        assert!((vel - 100.0 * amp * w / 2.175).abs() < 0.05, "{vel}");
        // Starting at A w from rest is an acceleration step of A w / dt = 1000 rad/s².
        assert!(
            c.violations
                .iter()
                .any(|v| v.joint == 1 && v.quantity == Quantity::Acceleration && v.time == 0.001)
        );
        assert_eq!(
            c.not_checked.iter().map(|(q, _)| *q).collect::<Vec<_>>(),
            vec![Quantity::Torque, Quantity::TorqueRate]
        );
        assert!(c.not_checked[0].1.contains("inertias are not known"));
    }

    #[test]
    fn a_ramp_past_the_speed_limit_is_one_violation_per_run() {
        // Joint 5 accelerates at 12 rad/s² (its limit is 15) up to 2.7 rad/s (its speed
        // limit is 2.61) and keeps going: one velocity run, reported at its worst sample.
        let mut q = Vec::new();
        let (mut x, mut v) = (0.0, 0.0);
        for _ in 0..600 {
            v = (v + 12.0 * DT).min(2.7);
            x += v * DT;
            let mut r = READY.to_vec();
            r[4] = x;
            q.push(r);
        }
        let c = check(&q, true);
        let speed: Vec<_> = c
            .violations
            .iter()
            .filter(|v| v.quantity == Quantity::Velocity)
            .collect();
        assert_eq!(speed.len(), 1, "{speed:?}");
        assert_eq!(speed[0].joint, 5);
        assert!((speed[0].value - 2.7).abs() < 1e-9 && speed[0].limit == 2.61);
        // Stopping from 2.7 rad/s within one period afterwards breaks acceleration and jerk.
        assert!(
            c.violations
                .iter()
                .any(|v| v.quantity == Quantity::Acceleration && v.joint == 5)
        );
        assert!(!c.ok());
    }

    #[test]
    fn positions_beyond_the_range_name_the_bound() {
        let mut q = vec![READY.to_vec(); 10];
        q[5][3] = -0.05; // joint 4's upper bound is -0.0698
        let c = check(&q, false);
        let v = c
            .violations
            .iter()
            .find(|v| v.quantity == Quantity::Position)
            .unwrap();
        assert_eq!((v.joint, v.value, v.limit), (4, -0.05, -0.0698));
        assert!((v.time - 0.005).abs() < 1e-12);
        assert!(usage(&c, Quantity::Position)[3] > 100.0);
    }
}

mod axis_joints {
    use cps_kinematics::robots::{PandaTool, panda, puma560, ur3};
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    use rand::{Rng, SeedableRng};

    /// `base · Π(origin_i · Rz(q_i)) · tail` is the chain's forward kinematics, for DH
    /// chains of both conventions with offsets, a placed base and a tool.
    #[test]
    fn composing_the_joints_gives_forward_kinematics() {
        let placed = Isometry3::from_parts(
            Translation3::new(0.3, -0.2, 0.5),
            UnitQuaternion::from_euler_angles(0.1, -0.4, 1.2),
        );
        let chains = [
            panda(PandaTool::HandTcp).with_base(placed),
            ur3(),
            puma560().with_base(placed),
        ];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for chain in &chains {
            let (base, joints, tail) = chain.axis_joints();
            for _ in 0..50 {
                let q: Vec<f64> = (0..chain.dof())
                    .map(|_| rng.random_range(-3.0..3.0))
                    .collect();
                let mut t = base;
                for (j, qi) in joints.iter().zip(&q) {
                    assert_eq!(j.offset, 0.0);
                    assert_eq!(j.axis.into_inner(), Vector3::z());
                    t = t * j.origin * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), *qi);
                }
                t *= tail;
                let fk = chain.fk(&q).unwrap();
                assert!((t.translation.vector - fk.translation.vector).norm() < 1e-12);
                assert!(
                    (t.rotation.to_rotation_matrix().matrix() - fk.rotation.matrix()).norm()
                        < 1e-12
                );
            }
        }
    }
}

/// The tool's Cartesian motion against closed forms.
mod cartesian {
    use cps_kinematics::check_cartesian;
    use cps_kinematics::robots::{PandaTool, panda, panda_limits};

    /// Joint 1 turning at a constant ω carries the tool on a circle about the base's z
    /// axis: speed ω·r, turn rate ω, centripetal acceleration ω²·r; the elbow (joint 3)
    /// stays still. Starting from rest, the first command's jump is a violation of the
    /// acceleration and jerk limits, named at t = 0.
    #[test]
    fn a_turn_about_the_base_is_a_circle() {
        let chain = panda(PandaTool::Flange);
        let (_, limits) = panda_limits();
        let q0 = cps_kinematics::robots::PANDA_READY;
        let r = chain.fk(&q0).unwrap().translation.vector.xy().norm();
        let omega = 1.0;
        let dt = 0.001;
        let q: Vec<Vec<f64>> = (0..2000)
            .map(|k| {
                let mut q = q0.to_vec();
                q[0] = omega * k as f64 * dt;
                q
            })
            .collect();
        let c = check_cartesian(&chain, &limits, 0.0, dt, &q).unwrap();
        let peak = |name: &str| c.peak_usage.iter().find(|(n, _)| *n == name).unwrap().1;
        // The chord over one period is 2r·sin(ω dt / 2) / dt ≈ ω r.
        let chord = 2.0 * r * (omega * dt / 2.0).sin() / dt;
        assert!((peak("translation_velocity") - 100.0 * chord / 1.7).abs() < 1e-9);
        let p = peak("rotation_velocity");
        assert!((p - 100.0 * omega / 2.5).abs() < 1e-6, "{p}");
        assert_eq!(peak("elbow_velocity"), 0.0);
        // Starting and stopping jumps: the first command's speed appears within one period.
        let first = c
            .violations
            .iter()
            .find(|v| v.quantity == "translation_acceleration")
            .unwrap();
        assert!(first.time <= dt && first.value > 13.0);
        // In the steady middle, the centripetal acceleration ω²r is well within 13 m/s²: no
        // violation between the start and the stop.
        assert!(
            c.violations.iter().all(|v| v.time < 0.01 || v.time > 1.99),
            "{:?}",
            c.violations
        );
    }
}
