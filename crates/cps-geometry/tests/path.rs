//! A path's check skips pairs that cannot have come close, and must never skip one that
//! did: on random smooth paths of a three-link arm among obstacles, [`PathCheck`] finds at
//! every configuration the same closest pair within its watch distance as computing every
//! pair does, with far fewer distances computed.

use std::f64::consts::PI;

use cps_geometry::{Body, CollisionModel, Obstacle, PathCheck, Shape};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A planar-ish arm: three links of 0.3 m turning about z, y and y.
fn frames(q: &[f64; 3]) -> Vec<Isometry3<f64>> {
    let base = Isometry3::identity();
    let f1 = base
        * Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.1),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q[0]),
        );
    let f2 = f1
        * Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.1),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), q[1]),
        );
    let f3 = f2
        * Isometry3::from_parts(
            Translation3::new(0.3, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), q[2]),
        );
    vec![base, f1, f2, f3]
}

fn model() -> CollisionModel {
    let link = |name: &str, frame: usize, shape: Shape, x: f64| Body {
        link: name.into(),
        frame,
        origin: Isometry3::translation(x, 0.0, 0.0),
        shape,
    };
    let bar = |l: f64| Shape::cuboid([l, 0.05, 0.05], "bar").unwrap();
    let bodies = vec![
        link("base", 0, Shape::cylinder(0.1, 0.1, "base").unwrap(), 0.0),
        link("turret", 1, Shape::sphere(0.06, "turret").unwrap(), 0.0),
        link("upper", 2, bar(0.3), 0.15),
        link("fore", 3, bar(0.3), 0.15),
        link("hand", 3, Shape::capsule(0.03, 0.08, "hand").unwrap(), 0.32),
    ];
    let obstacles = vec![
        Obstacle {
            name: "table".into(),
            pose: Isometry3::translation(0.4, 0.0, -0.05),
            shape: Shape::cuboid([0.6, 1.0, 0.1], "table").unwrap(),
        },
        Obstacle {
            name: "post".into(),
            pose: Isometry3::translation(0.0, 0.45, 0.3),
            shape: Shape::cylinder(0.05, 0.6, "post").unwrap(),
        },
        Obstacle {
            name: "ball".into(),
            pose: Isometry3::translation(-0.3, -0.2, 0.4),
            shape: Shape::sphere(0.1, "ball").unwrap(),
        },
    ];
    // The base stands on the table: that pair always touches.
    let skip = [
        ("base", "turret"),
        ("turret", "upper"),
        ("upper", "fore"),
        ("base", "table"),
    ]
    .map(|(a, b)| (a.to_string(), b.to_string()));
    CollisionModel::new(bodies, obstacles, &skip)
}

#[test]
fn the_lazy_check_finds_what_checking_every_pair_finds() {
    let m = std::sync::Arc::new(model());
    // base–upper, base–fore, base–hand, turret–fore, turret–hand, upper–hand; five
    // bodies × three obstacles, less the base on the table.
    assert_eq!(m.pair_count(), 6 + 14);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut steps, mut queries, mut hits, mut collisions) = (0, 0, 0, 0);
    for _ in 0..20 {
        let watch = 0.05;
        let mut check = PathCheck::new(m.clone(), watch);
        // A smooth random path: sums of sines, 2 000 configurations 1 ms apart.
        let amp: Vec<[f64; 3]> = (0..3)
            .map(|_| {
                [
                    rng.random_range(0.2..1.5),
                    rng.random_range(0.2..1.5),
                    rng.random_range(0.2..2.0),
                ]
            })
            .collect();
        let freq: Vec<f64> = (0..3).map(|_| rng.random_range(0.2..1.0)).collect();
        for k in 0..2000 {
            let t = k as f64 * 1e-3;
            let mut q = [0.0; 3];
            for (h, a) in amp.iter().enumerate() {
                for j in 0..3 {
                    q[j] += a[j] / (h + 1) as f64
                        * (2.0 * PI * freq[h] * (h + 1) as f64 * t + j as f64).sin();
                }
            }
            let f = frames(&q);
            let lazy = check.step(&f);
            let all = m.within(&f, watch);
            match (lazy, all.first()) {
                (None, None) => {}
                (Some(a), Some(b)) => {
                    assert_eq!(a.pair, b.pair, "step {k}");
                    assert!((a.separation.distance - b.separation.distance).abs() < 1e-9);
                    hits += 1;
                }
                (a, b) => panic!("step {k}: lazy {a:?}, every pair {b:?}"),
            }
            // Not only the closest: every pair within the watch distance.
            let mut near: Vec<usize> = check.near().iter().map(|c| c.pair).collect();
            let mut every: Vec<usize> = all.iter().map(|c| c.pair).collect();
            near.sort();
            every.sort();
            assert_eq!(near, every, "step {k}");
            collisions += all.iter().filter(|c| c.separation.distance < 0.0).count();
            steps += 1;
        }
        queries += check.queries();
    }
    let every = steps * m.pair_count();
    eprintln!(
        "{queries} distances of {every} ({:.1} %), {hits} configurations with a pair within 5 cm, {collisions} overlaps",
        100.0 * queries as f64 / every as f64
    );
    assert!(
        hits > 1000 && hits < steps,
        "the paths must come close, not always: {hits}"
    );
    assert!(collisions > 100, "and collide: {collisions}");
    assert!(queries * 3 < every, "{queries} of {every}");
}
