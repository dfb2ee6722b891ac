//! Signed distances against what is known without GJK: closed forms for spheres, boxes,
//! cylinders and capsules; for random convex pairs, a certificate (the witness points are
//! `distance` apart and a plane between them has every vertex of each shape on its side);
//! for overlapping boxes, the separating-axis theorem's depth over the 15 candidate axes.

use std::sync::Arc;

use cps_geometry::{Hull, Shape, distance, distance_bound};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

type V = Vector3<f64>;

fn at(x: f64, y: f64, z: f64) -> Isometry3<f64> {
    Isometry3::translation(x, y, z)
}

fn random_pose(rng: &mut ChaCha8Rng, spread: f64) -> Isometry3<f64> {
    let axis = V::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    Isometry3::from_parts(
        Translation3::new(
            rng.random_range(-spread..spread),
            rng.random_range(-spread..spread),
            rng.random_range(-spread..spread),
        ),
        UnitQuaternion::from_scaled_axis(axis * 2.0),
    )
}

fn box_corners(half: V) -> Vec<V> {
    let mut p = Vec::new();
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            for sz in [-1.0, 1.0] {
                p.push(V::new(sx * half.x, sy * half.y, sz * half.z));
            }
        }
    }
    p
}

#[test]
fn spheres_boxes_cylinders_and_capsules_match_their_closed_forms() {
    let ball = Shape::sphere(0.1, "ball").unwrap();
    let small = Shape::sphere(0.05, "small").unwrap();
    // Centres 0.5 apart along a diagonal.
    let c = V::new(0.3, -0.4, 0.0);
    let s = distance(
        &ball,
        &at(0.0, 0.0, 0.0),
        &small,
        &Isometry3::translation(c.x, c.y, c.z),
    );
    assert!((s.distance - 0.35).abs() < 1e-9, "{s:?}");
    assert!((s.normal - c / 0.5).norm() < 1e-9);
    assert!((s.point_a - c / 0.5 * 0.1).norm() < 1e-9);
    // Overlapping by 0.05.
    let s = distance(&ball, &at(0.0, 0.0, 0.0), &small, &at(0.0, 0.0, 0.1));
    assert!((s.distance + 0.05).abs() < 1e-9, "{s:?}");

    // A box's corner towards a ball: the distance to the corner.
    let cube = Shape::cuboid([0.2, 0.2, 0.2], "cube").unwrap();
    let s = distance(&cube, &at(0.0, 0.0, 0.0), &ball, &at(0.5, 0.5, 0.5));
    assert!(
        (s.distance - ((3.0f64 * 0.4 * 0.4).sqrt() - 0.1)).abs() < 1e-7,
        "{s:?}"
    );
    // Two boxes, corner to corner, one turned about z by 45°.
    let turned = Isometry3::from_parts(
        Translation3::new(0.5, 0.0, 0.0),
        UnitQuaternion::from_axis_angle(&V::z_axis(), std::f64::consts::FRAC_PI_4),
    );
    let s = distance(&cube, &at(0.0, 0.0, 0.0), &cube, &turned);
    assert!(
        (s.distance - (0.5 - 0.1 - 0.1 * 2f64.sqrt())).abs() < 1e-7,
        "{s:?}"
    );

    // A cylinder (radius 0.1, length 0.4 about z) and a ball: above the cap, beside the
    // side, off the rim.
    let cyl = Shape::cylinder(0.1, 0.4, "cylinder").unwrap();
    let o = at(0.0, 0.0, 0.0);
    assert!((distance(&cyl, &o, &small, &at(0.0, 0.03, 0.5)).distance - 0.25).abs() < 1e-7);
    assert!((distance(&cyl, &o, &small, &at(0.3, 0.0, 0.1)).distance - 0.15).abs() < 1e-7);
    let rim = (0.2f64 * 0.2 + 0.1 * 0.1).sqrt() - 0.05; // from (0.3, 0, 0.3) to (0.1, 0, 0.2)
    let s = distance(&cyl, &o, &small, &at(0.3, 0.0, 0.3));
    assert!((s.distance - rim).abs() < 1e-6, "{s:?} against {rim}");

    // Two capsules on skew lines: the segments' distance less both radii.
    let cap = Shape::capsule(0.02, 0.6, "capsule").unwrap();
    let across = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.25),
        UnitQuaternion::from_axis_angle(&V::x_axis(), std::f64::consts::FRAC_PI_2),
    );
    // Segment 1: x = 0.1, y = 0, z in [-0.3, 0.3]; segment 2: x = 0, z = 0.25, y in
    // [-0.3, 0.3]. Closest points (0.1, 0, 0.25) and (0, 0, 0.25).
    let s = distance(&cap, &at(0.1, 0.0, 0.0), &cap, &across);
    assert!((s.distance - (0.1 - 0.04)).abs() < 1e-9, "{s:?}");
}

/// The hull of 5 to `most` random points in a 20 × 10 × 40 cm box.
fn random_hull(rng: &mut ChaCha8Rng, most: usize) -> Arc<Hull> {
    let points: Vec<V> = (0..rng.random_range(5..most))
        .map(|_| {
            V::new(
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.05..0.05),
                rng.random_range(-0.2..0.2),
            )
        })
        .collect();
    Arc::new(Hull::new(&points, "random").unwrap())
}

#[test]
fn every_separation_of_random_convex_pairs_comes_with_its_certificate() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut separated = 0;
    for round in 0..400 {
        let (ha, hb) = (random_hull(&mut rng, 120), random_hull(&mut rng, 120));
        let (a, b) = (Shape::Convex(ha.clone()), Shape::Convex(hb.clone()));
        let (pa, pb) = (random_pose(&mut rng, 0.4), random_pose(&mut rng, 0.4));
        let s = distance(&a, &pa, &b, &pb);
        let back = distance(&b, &pb, &a, &pa);
        assert!(
            (s.distance - back.distance).abs() < 1e-6,
            "round {round}: not symmetric"
        );
        // The same pair moved together is as far apart.
        let m = random_pose(&mut rng, 1.0);
        let moved = distance(&a, &(m * pa), &b, &(m * pb));
        assert!(
            (s.distance - moved.distance).abs() < 1e-6,
            "round {round}: moved"
        );
        if s.distance > 1e-6 {
            separated += 1;
            assert!(((s.point_b - s.point_a).norm() - s.distance).abs() < 1e-6);
            // Every corner of A is behind the plane through point_a, every corner of B
            // beyond the plane through point_b: nothing is closer than the distance.
            for v in ha.vertices() {
                let w = pa * nalgebra::Point3::from(*v);
                assert!(
                    s.normal.dot(&(w.coords - s.point_a)) <= 1e-6,
                    "round {round}: A"
                );
            }
            for v in hb.vertices() {
                let w = pb * nalgebra::Point3::from(*v);
                assert!(
                    s.normal.dot(&(w.coords - s.point_b)) >= -1e-6,
                    "round {round}: B"
                );
            }
        }
    }
    assert!(
        separated > 100 && separated < 390,
        "{separated} of 400 apart"
    );
}

/// `distance_bound`, what the planner's walk steps by: never above the distance, within its
/// share of it (20 % here), from a cold start and from the direction the query before at a
/// nearby pose ended on; and where the shapes touch or overlap, at most minus their radii
/// (the distance is at most that: a walk's step is refused either way).
#[test]
fn a_distance_bound_is_below_the_distance_and_within_its_share_of_it() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let (mut apart, mut tight) = (0, 0);
    for round in 0..400 {
        let a = Shape::Convex(random_hull(&mut rng, 80));
        let b = if round % 2 == 0 {
            Shape::capsule(0.03, 0.1, "capsule").unwrap()
        } else {
            Shape::cuboid([0.2, 0.1, 0.05], "box").unwrap()
        };
        let (pa, pb) = (random_pose(&mut rng, 0.4), random_pose(&mut rng, 0.4));
        let nudge = Isometry3::from_parts(
            Translation3::new(0.003, -0.002, 0.001),
            UnitQuaternion::from_euler_angles(0.01, 0.0, -0.01),
        );
        let mut dir = V::zeros();
        let mut hints = [0, 0];
        for pb in [pb, nudge * pb] {
            let exact = distance(&a, &pa, &b, &pb).distance;
            let bound = distance_bound(&a, &pa, &b, &pb, &mut hints, &mut dir, 0.2);
            let radius = if round % 2 == 0 { 0.03 } else { 0.0 };
            if exact > 1e-6 {
                assert!(bound <= exact + 1e-9, "round {round}: {bound} > {exact}");
                apart += 1;
                let cores = exact + radius;
                assert!(
                    bound + radius >= 0.8 * cores - 1e-7,
                    "round {round}: {bound} against {exact}"
                );
                if bound > exact - 1e-6 {
                    tight += 1;
                }
            } else {
                // Touching or overlapping: below the distance, or, where the cores
                // overlap, at minus the radii.
                assert!(
                    bound <= exact.max(-radius) + 1e-9,
                    "round {round}: {bound} at {exact}"
                );
            }
        }
    }
    assert!(apart > 200 && tight > 50, "{apart} apart, {tight} exact");
}

/// The depth two boxes overlap by, by the separating-axis theorem: the least overlap of
/// their projections over the 15 candidate axes (3 + 3 face normals, 9 edge crosses).
fn sat_depth(ha: V, pa: &Isometry3<f64>, hb: V, pb: &Isometry3<f64>) -> f64 {
    let ra = pa.rotation.to_rotation_matrix();
    let rb = pb.rotation.to_rotation_matrix();
    let mut axes: Vec<V> = Vec::new();
    for i in 0..3 {
        axes.push(ra.matrix().column(i).into());
        axes.push(rb.matrix().column(i).into());
        for j in 0..3 {
            let c: V = ra.matrix().column(i).cross(&rb.matrix().column(j));
            if c.norm() > 1e-9 {
                axes.push(c.normalize());
            }
        }
    }
    let ca: Vec<V> = box_corners(ha)
        .iter()
        .map(|v| (pa * nalgebra::Point3::from(*v)).coords)
        .collect();
    let cb: Vec<V> = box_corners(hb)
        .iter()
        .map(|v| (pb * nalgebra::Point3::from(*v)).coords)
        .collect();
    axes.iter()
        .map(|n| {
            let (mut a0, mut a1, mut b0, mut b1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for v in &ca {
                a0 = a0.min(n.dot(v));
                a1 = a1.max(n.dot(v));
            }
            for v in &cb {
                b0 = b0.min(n.dot(v));
                b1 = b1.max(n.dot(v));
            }
            (a1 - b0).min(b1 - a0)
        })
        .fold(f64::MAX, f64::min)
}

#[test]
fn overlapping_boxes_are_as_deep_as_the_separating_axis_theorem_says_as_boxes_and_as_hulls() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut overlapping = 0;
    for round in 0..300 {
        let ha = V::new(0.1, 0.05, 0.2);
        let hb = V::new(0.08, 0.12, 0.03);
        let (pa, pb) = (random_pose(&mut rng, 0.12), random_pose(&mut rng, 0.12));
        let a = Shape::Cuboid { half: ha };
        let b = Shape::Cuboid { half: hb };
        let s = distance(&a, &pa, &b, &pb);
        let depth = sat_depth(ha, &pa, hb, &pb);
        if depth > 1e-4 {
            overlapping += 1;
            assert!(
                (s.distance + depth).abs() < 1e-6,
                "round {round}: {} against SAT {}",
                s.distance,
                -depth
            );
            // The same as hulls of the corners.
            let hull = |h: V| Shape::Convex(Arc::new(Hull::new(&box_corners(h), "box").unwrap()));
            let t = distance(&hull(ha), &pa, &hull(hb), &pb);
            assert!(
                (t.distance - s.distance).abs() < 1e-6,
                "round {round}: hull {} box {}",
                t.distance,
                s.distance
            );
            // Moving B along the normal by the depth leaves them touching.
            let apart = Isometry3::from_parts(
                Translation3::from(s.normal * (depth + 1e-3)),
                Default::default(),
            ) * pb;
            let after = distance(&a, &pa, &b, &apart);
            assert!(
                (after.distance - 1e-3).abs() < 1e-5,
                "round {round}: {after:?}"
            );
        }
    }
    assert!(overlapping > 50, "{overlapping} overlapping");
}

#[test]
fn sizes_that_are_not_positive_are_refused_by_name() {
    assert_eq!(
        Shape::cuboid([0.1, -0.2, 0.3], "shelf")
            .unwrap_err()
            .to_string(),
        "shelf: the size -0.2 is not a positive number of metres"
    );
    assert!(Shape::sphere(f64::NAN, "ball").is_err());
    assert!(Shape::cylinder(0.1, 0.0, "post").is_err());
    assert!(
        Shape::capsule(0.1, 0.0, "pill").is_ok(),
        "a capsule of no length is a ball"
    );
}
