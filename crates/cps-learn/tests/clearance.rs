//! The clearance cost against an analytic distance: a ball on the Panda's first link at
//! 0.5 m from its axis swings past a ball standing at the same height and reach, so their
//! distance at joint 1's angle `φ` is `2 R sin(|φ − φ₀| / 2) − 2 r`, and each judged
//! sample's residual is `√w · max(0, c − d)`. A movement evaluated just after a nearby one
//! (its remembered walk) gives the same bits as on a fresh thread.

use std::sync::Arc;

use cps_geometry::{Body, Obstacle, Shape};
use cps_kinematics::robots::{PandaTool, panda};
use cps_learn::Clearance;
use cps_robot::Shapes;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

const REACH: f64 = 0.5;
const AT: f64 = 1.0;
const BALL: f64 = 0.05;
const CLEAR: f64 = 0.03;
const WEIGHT: f64 = 4.0;

fn clearance(stride: usize) -> (Clearance, cps_kinematics::SerialChain) {
    let chain = panda(PandaTool::HandTcp);
    let mut frames = Vec::new();
    chain.frames_into(&[0.0; 7], &mut frames).unwrap();
    let at = |a: f64| Vector3::new(REACH * a.cos(), REACH * a.sin(), 0.333);
    let body = Body {
        link: "panda_link1".into(),
        frame: 1,
        origin: Isometry3::from_parts(
            (frames[1].inverse() * Point3::from(at(0.0))).into(),
            UnitQuaternion::identity(),
        ),
        shape: Shape::sphere(BALL, "a ball").unwrap(),
    };
    let ball = Obstacle {
        name: "ball".into(),
        pose: Isometry3::translation(at(AT).x, at(AT).y, at(AT).z),
        shape: Shape::sphere(BALL, "the ball").unwrap(),
    };
    let shapes = Shapes::new(vec![body], vec![])
        .with_obstacles(vec![ball], vec![])
        .unwrap();
    (
        Clearance {
            shapes: Arc::new(shapes),
            distance: CLEAR,
            self_distance: CLEAR,
            weight: WEIGHT,
            stride,
        },
        chain,
    )
}

/// Joint 1 from 0 to `to` over `n` samples (cosine), the other joints at 0.
fn sweep(to: f64, n: usize) -> Vec<Vec<f64>> {
    let q1: Vec<f64> = (0..n)
        .map(|k| to * (0.5 - 0.5 * (std::f64::consts::PI * k as f64 / (n - 1) as f64).cos()))
        .collect();
    let mut joints = vec![vec![0.0; n]; 7];
    joints[0] = q1;
    joints
}

fn residuals(c: &Clearance, chain: &cps_kinematics::SerialChain, joints: &[Vec<f64>]) -> Vec<f64> {
    let mut out = Vec::new();
    let mut b = cps_learn::ClearanceBuffers::default();
    c.residuals(chain, joints[0].len(), |j| &joints[j], &mut b, &mut out)
        .unwrap();
    out
}

fn analytic(phi: f64) -> f64 {
    2.0 * REACH * ((phi - AT).abs() / 2.0).sin() - 2.0 * BALL
}

#[test]
fn each_judged_sample_costs_its_shortfall_squared() {
    for stride in [1, 4] {
        let (c, chain) = clearance(stride);
        let joints = sweep(1.6, 1001);
        let r = residuals(&c, &chain, &joints);
        let judged: Vec<usize> = (0..1001).step_by(stride).collect();
        assert_eq!(r.len(), judged.len(), "the last sample is one of every 4th");
        let mut near = 0;
        for (i, &k) in judged.iter().enumerate() {
            let want = WEIGHT.sqrt() * (CLEAR - analytic(joints[0][k])).max(0.0);
            assert!((r[i] - want).abs() < 1e-9, "sample {k}: {} vs {want}", r[i]);
            near += usize::from(want > 0.0);
        }
        assert!(near > 10, "the sweep passes through the ball");
    }
}

#[test]
fn a_nearby_movement_remembered_gives_the_same_bits_as_a_fresh_walk() {
    let (c, chain) = clearance(4);
    let joints = sweep(1.6, 1001);
    let first = residuals(&c, &chain, &joints);
    // A Jacobian column's movement: one joint a hair off.
    let mut column = joints.clone();
    for (k, q) in column[0].iter_mut().enumerate() {
        *q += 1e-7 * (k as f64 / 1000.0);
    }
    let remembered = residuals(&c, &chain, &column);
    let fresh = std::thread::spawn({
        let (c, chain, column) = (c.clone(), chain.clone(), column.clone());
        move || residuals(&c, &chain, &column)
    })
    .join()
    .unwrap();
    assert_eq!(remembered, fresh);
    assert_ne!(remembered, first);
    // A movement far from the remembered one is walked afresh, and still exact.
    let far = sweep(1.2, 1001);
    let r = residuals(&c, &chain, &far);
    let mut near = 0;
    for (i, k) in (0..1001).step_by(4).enumerate() {
        let want = WEIGHT.sqrt() * (CLEAR - analytic(far[0][k])).max(0.0);
        assert!((r[i] - want).abs() < 1e-9);
        near += usize::from(want > 0.0);
    }
    assert!(near > 10);
}

/// The bound the remembered walk skips samples by: joints turned by `δ` move no point of
/// any body further than `2 · reach · Σ|δ|` (each body's motion as the guard measures it:
/// its bounding sphere's centre plus the chord its radius sweeps).
#[test]
fn no_body_moves_further_than_twice_the_reach_times_the_joints_turn() {
    use rand::{Rng, SeedableRng};
    let chain = panda(PandaTool::HandTcp);
    let bodies: Vec<Body> = (0..=7)
        .map(|k| Body {
            link: format!("link{k}"),
            frame: k,
            origin: Isometry3::translation(0.05 * k as f64, -0.03, 0.08),
            shape: Shape::capsule(0.04, 0.1, "a link").unwrap(),
        })
        .collect();
    let model = cps_geometry::CollisionModel::new(bodies, vec![], &[]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let (mut f0, mut f1, mut moved) = (Vec::new(), Vec::new(), Vec::new());
    let mut tightest: f64 = 0.0;
    for _ in 0..2000 {
        let q: Vec<f64> = (0..7).map(|_| rng.random_range(-2.5..2.5)).collect();
        let scale = 10f64.powf(rng.random_range(-7.0..-2.0));
        let turned: Vec<f64> = q
            .iter()
            .map(|x| x + scale * rng.random_range(-1.0..1.0))
            .collect();
        chain.frames_into(&q, &mut f0).unwrap();
        chain.frames_into(&turned, &mut f1).unwrap();
        let sum: f64 = q.iter().zip(&turned).map(|(a, b)| (a - b).abs()).sum();
        let bound = 2.0 * model.reach(&f0) * sum;
        model.motions(&f0, &f1, &mut moved);
        for &m in &moved {
            assert!(
                m <= bound * (1.0 + 1e-6) + 1e-15,
                "moved {m}, bound {bound}"
            );
            tightest = tightest.max(m / bound);
        }
    }
    assert!(
        tightest > 0.1,
        "the bound is not absurdly loose: {tightest}"
    );
}

/// Inverse kinematics that prefers clear configurations: a ball where the thesis task's
/// second via configuration puts the elbow makes [`cps_learn::clear_way_points`] choose
/// another solution for that point — the tool still on it, every body keeping the
/// clearance — and leaves the configurations that were clear as they were.
#[test]
fn a_way_configuration_inside_an_obstacle_is_replaced_by_a_clear_one() {
    use cps_learn::{RobotSetup, ViaPointTask, check_way_points, clear_way_points};
    let chain = panda(PandaTool::HandTcp).with_base(Isometry3::translation(0.5396, 0.02, 0.749));
    let robot = RobotSetup {
        chain: chain.clone(),
        initial_q: cps_kinematics::robots::PANDA_THESIS_START.to_vec(),
        execution: Default::default(),
    };
    let task = ViaPointTask::thesis();
    let configs = check_way_points(&task, &robot).unwrap();
    // A crude arm: a ball at every link frame's origin (several share one: the links are
    // checked against the ball only).
    let bodies: Vec<Body> = (1..=7)
        .map(|k| Body {
            link: format!("link{k}"),
            frame: k,
            origin: Isometry3::identity(),
            shape: Shape::sphere(0.06, "a link").unwrap(),
        })
        .collect();
    let touching: Vec<(String, String)> = (1..=7)
        .flat_map(|a| ((a + 1)..=7).map(move |b| (format!("link{a}"), format!("link{b}"))))
        .collect();
    let mut frames = Vec::new();
    chain.frames_into(&configs[2], &mut frames).unwrap();
    let elbow = frames[4].translation.vector;
    let obstacle = Obstacle {
        name: "ball".into(),
        pose: Isometry3::translation(elbow.x, elbow.y, elbow.z),
        shape: Shape::sphere(0.05, "the ball").unwrap(),
    };
    let shapes = Shapes::new(bodies, touching)
        .with_obstacles(vec![obstacle], vec![])
        .unwrap();
    let clearance = Clearance {
        shapes: Arc::new(shapes),
        distance: 0.02,
        self_distance: 0.02,
        weight: 1.0,
        stride: 1,
    };
    let keeps = |q: &[f64]| {
        cps_learn::closest(&clearance.shapes, &chain, &[0.0], |j| &q[j..=j], 0.02)
            .unwrap()
            .is_none()
    };
    assert!(!keeps(&configs[2]), "the ball is where the elbow is");
    let clear = clear_way_points(&task, &robot, &clearance, configs.clone()).unwrap();
    assert_eq!(clear.len(), configs.len());
    let target = &task.via[1].position;
    let tool = chain.fk(&clear[2]).unwrap().translation.vector;
    assert!((tool - Vector3::new(target[0], target[1], target[2])).norm() < 1e-6);
    assert!(keeps(&clear[2]), "{:?}", clear[2]);
    assert!(chain.check_within_limits(&clear[2]).is_ok());
    for k in [0, 1, 3, 4, 5] {
        if keeps(&configs[k]) {
            assert_eq!(clear[k], configs[k], "way point {k} was clear and stays");
        }
    }
    // The same twice: deterministic.
    assert_eq!(
        clear,
        clear_way_points(&task, &robot, &clearance, configs).unwrap()
    );
}
