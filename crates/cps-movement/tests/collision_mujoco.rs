//! The FR3's collision model — franky-sim's fr3.urdf read by cps, its franka_description
//! meshes as convex hulls — against MuJoCo on franky-sim's fr3.xml (the same meshes, which
//! MuJoCo collides as hulls too): at random configurations within the joint ranges, every
//! pair of links cps checks and the links against a 0.3 × 0.3 × 0.4 m box in front of the
//! arm, signed distances within 1 mm; and cps checks the same pairs MuJoCo's contact filter
//! does (not parent and child, not excluded). The fingers are left out: MuJoCo's model
//! gives them other shapes than the URDF.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

use cps_geometry::{CollisionModel, Obstacle, Other, Shape};
use cps_kinematics::chain_from_urdf;
use cps_movement::collision::urdf_geometry;
use nalgebra::{Isometry3, UnitQuaternion};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const CONFIGURATIONS: usize = 400;

/// franky-sim's interpreter, its model folder, its fr3.urdf read by cps (to the hand's tool
/// centre point) and that robot's collision geometry; None when franky-sim is missing.
fn franky_fr3() -> Option<(
    PathBuf,
    PathBuf,
    cps_kinematics::UrdfChain,
    cps_movement::collision::RobotGeometry,
)> {
    let (python, assets) = cps_testkit::franky_sim::assets()?;
    let urdf = assets.join("fr3.urdf");
    let text = std::fs::read_to_string(&urdf).unwrap();
    let chain = chain_from_urdf(&text, Some("fr3_hand_tcp")).unwrap();
    let geometry = urdf_geometry(&chain, &urdf).unwrap();
    Some((python, assets, chain, geometry))
}

/// `tests/mujoco_robot.py`'s reply to `job` (its input: the box, the pairs, the
/// configurations) on franky-sim's fr3.xml in `assets`, run by `python`.
fn mujoco(
    python: &std::path::Path,
    assets: &std::path::Path,
    job: &serde_json::Value,
) -> serde_json::Value {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/mujoco_robot.py");
    let mut child = Command::new(python)
        .arg(&script)
        .arg(assets.join("fr3.xml"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(job.to_string().as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// What a comparison found: errors of self and box pairs, how many configurations
/// collide, and (when timed) MuJoCo's and coal's replies.
struct Compared {
    self_errors: Vec<f64>,
    box_errors: Vec<f64>,
    /// Of either kind, where one of the two says the shapes overlap (EPA's depth).
    deep_errors: Vec<f64>,
    /// cps's distances, per configuration and pair.
    ours: Vec<Vec<f64>>,
    self_hits: usize,
    box_hits: usize,
    reply: serde_json::Value,
    /// Per configuration: every pair's exact distance by cps (s).
    ours_s: f64,
    configurations: usize,
}

/// cps's distances for every pair against MuJoCo's at `configurations` random
/// configurations (seeded), each within 1 mm; `time` asks the script for timings too.
fn compare(configurations: usize, time: bool) -> Option<Compared> {
    let (python, assets, chain, geometry) = franky_fr3()?;
    // link0 and link6's meshes have holes: said, and closed by their hulls.
    assert_eq!(geometry.notes.len(), 2, "{:?}", geometry.notes);
    let bodies: Vec<_> = geometry
        .bodies
        .into_iter()
        .filter(|b| !b.link.contains("finger"))
        .collect();
    assert_eq!(bodies.len(), 9, "link0 … link7 and the hand");
    let box_centre = [0.5, 0.0, 0.2];
    let box_half = [0.15, 0.15, 0.2];
    let obstacle = Obstacle {
        name: "box".into(),
        pose: Isometry3::translation(box_centre[0], box_centre[1], box_centre[2]),
        shape: Shape::cuboid(box_half.map(|h| 2.0 * h), "box").unwrap(),
    };
    let model = CollisionModel::new(bodies, vec![obstacle], &geometry.adjacent);
    let pairs: Vec<(String, String)> = (0..model.pair_count())
        .map(|p| {
            let (a, b) = model.pair_names(p);
            (a.to_string(), b.to_string())
        })
        .collect();

    let mut rng = ChaCha8Rng::seed_from_u64(51);
    let configurations: Vec<Vec<f64>> = (0..configurations)
        .map(|_| chain.chain.random_configuration(&mut rng))
        .collect();
    let job = serde_json::json!({
        "box": [box_centre[0], box_centre[1], box_centre[2], box_half[0], box_half[1], box_half[2]],
        "pairs": pairs.iter().map(|(a, b)| [a, b]).collect::<Vec<_>>(),
        "q": configurations,
        "time": time,
    });
    let reply = mujoco(&python, &assets, &job);

    // The same self pairs as MuJoCo's filter.
    let ours: BTreeSet<(String, String)> = pairs
        .iter()
        .filter(|(_, b)| b != "box")
        .map(|(a, b)| (a.min(b).clone(), a.max(b).clone()))
        .collect();
    let theirs: BTreeSet<(String, String)> = reply["checked"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let (a, b) = (
                p[0].as_str().unwrap().to_string(),
                p[1].as_str().unwrap().to_string(),
            );
            (a.clone().min(b.clone()), a.max(b))
        })
        .collect();
    assert_eq!(ours, theirs);

    let mut c = Compared {
        self_errors: Vec::new(),
        box_errors: Vec::new(),
        deep_errors: Vec::new(),
        ours: Vec::new(),
        self_hits: 0,
        box_hits: 0,
        reply: serde_json::Value::Null,
        ours_s: 0.0,
        configurations: configurations.len(),
    };
    let mut frames = Vec::with_capacity(8);
    for (q, reference) in configurations
        .iter()
        .zip(reply["distances"].as_array().unwrap())
    {
        chain.chain.frames_into(q, &mut frames).unwrap();
        let (mut self_hit, mut box_hit) = (false, false);
        let mut row = Vec::with_capacity(model.pair_count());
        for p in 0..model.pair_count() {
            let r = reference[p].as_f64().unwrap();
            let d = model.distance(p, &frames).distance;
            row.push(d);
            assert!(
                (d - r).abs() < 1e-3,
                "{:?} at {q:?}: cps {d}, MuJoCo {r}",
                model.pair_names(p)
            );
            let scene = matches!(model.pair(p).1, Other::Obstacle(_));
            if scene {
                c.box_errors.push((d - r).abs());
            } else {
                c.self_errors.push((d - r).abs());
            }
            if d.min(r) < 0.0 {
                c.deep_errors.push((d - r).abs());
            }
            if d < 0.0 {
                if scene {
                    box_hit = true;
                } else {
                    self_hit = true;
                }
            }
        }
        c.self_hits += self_hit as usize;
        c.box_hits += box_hit as usize;
        c.ours.push(row);
    }
    if time {
        let started = std::time::Instant::now();
        for q in &configurations {
            chain.chain.frames_into(q, &mut frames).unwrap();
            for p in 0..model.pair_count() {
                std::hint::black_box(model.distance(p, &frames));
            }
        }
        c.ours_s = started.elapsed().as_secs_f64() / configurations.len() as f64;
    }
    for e in [&mut c.self_errors, &mut c.box_errors, &mut c.deep_errors] {
        e.sort_by(f64::total_cmp);
    }
    c.reply = reply;
    Some(c)
}

#[test]
fn the_fr3_collision_model_agrees_with_mujoco_within_a_millimetre() {
    let Some(c) = compare(CONFIGURATIONS, false) else {
        return;
    };
    let (n, s, b) = (c.configurations, &c.self_errors, &c.box_errors);
    eprintln!(
        "{n} configurations: self pairs median error {:.1e} m, worst {:.1e} m; box pairs median {:.1e} m, worst {:.1e} m; {} collide with the arm itself, {} with the box",
        s[s.len() / 2],
        s[s.len() - 1],
        b[b.len() / 2],
        b[b.len() - 1],
        c.self_hits,
        c.box_hits
    );
    // About 4 % and 10 % (8 and 19 of 200 in MuJoCo on this model).
    assert!(
        (4..=40).contains(&c.self_hits),
        "{} self collisions",
        c.self_hits
    );
    assert!(
        (15..=80).contains(&c.box_hits),
        "{} box collisions",
        c.box_hits
    );
}

/// Measurement (`bash test.sh -- --ignored`): the comparison at 10 000 configurations, and
/// the time per configuration of every pair's exact distance by cps, by MuJoCo
/// (`mj_geomDistance` over the pairs; `mj_collision`, contacts only) and by coal (FCL's
/// successor, when installed beside franky-sim: `pip install coal`), with coal's
/// distances as a second opinion.
#[test]
#[ignore]
fn measure_ten_thousand_configurations_against_mujoco_and_coal() {
    let Some(c) = compare(10_000, true) else {
        return;
    };
    let (n, s, b) = (c.configurations, &c.self_errors, &c.box_errors);
    let r = &c.reply;
    let us = |key: &str| {
        r[key]
            .as_f64()
            .map_or("—".into(), |v| format!("{:.1} µs", v * 1e6))
    };
    eprintln!(
        "{n} configurations, {} self and {} box distances: self median error {:.1e} m, worst {:.1e} m; box median {:.1e} m, worst {:.1e} m; {} collide with the arm itself, {} with the box",
        s.len(),
        b.len(),
        s[s.len() / 2],
        s[s.len() - 1],
        b[b.len() / 2],
        b[b.len() - 1],
        c.self_hits,
        c.box_hits
    );
    eprintln!(
        "per configuration, every pair: cps {:.1} µs; MuJoCo mj_geomDistance {} (kinematics {} of it; a Python call {}), mj_collision {} (contacts only, with kinematics); coal {}",
        c.ours_s * 1e6,
        us("distance_s"),
        us("kinematics_s"),
        us("call_s"),
        us("collision_s"),
        us("coal_s")
    );
    let d = &c.deep_errors;
    eprintln!(
        "of them {} overlapping (a depth by EPA): median error {:.1e} m, worst {:.1e} m",
        d.len(),
        d[d.len() / 2],
        d[d.len() - 1]
    );
    if let Some(coal) = r["coal"].as_array() {
        let mut worst: f64 = 0.0;
        let mut diffs = Vec::new();
        for (row, mj) in coal.iter().zip(r["distances"].as_array().unwrap()) {
            for (a, b) in row.as_array().unwrap().iter().zip(mj.as_array().unwrap()) {
                let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
                if a > 0.0 && b > 0.0 {
                    diffs.push((a - b).abs());
                    worst = worst.max((a - b).abs());
                }
            }
        }
        diffs.sort_by(f64::total_cmp);
        eprintln!(
            "coal against MuJoCo on separated pairs: median {:.1e} m, worst {worst:.1e} m",
            diffs[diffs.len() / 2]
        );
        // cps against coal, separated and overlapping.
        let (mut apart, mut deep) = (Vec::new(), Vec::new());
        for (row, ours) in coal.iter().zip(&c.ours) {
            for (a, d) in row.as_array().unwrap().iter().zip(ours) {
                let a = a.as_f64().unwrap();
                if a.min(*d) < 0.0 {
                    deep.push((a - d).abs());
                } else {
                    apart.push((a - d).abs());
                }
            }
        }
        for v in [&mut apart, &mut deep] {
            v.sort_by(f64::total_cmp);
        }
        eprintln!(
            "cps against coal: separated median {:.1e} m, worst {:.1e} m; overlapping ({}) median {:.1e} m, worst {:.1e} m",
            apart[apart.len() / 2],
            apart[apart.len() - 1],
            deep.len(),
            deep[deep.len() / 2],
            deep[deep.len() - 1]
        );
    }
}

/// Measurement (`bash test.sh -- --ignored`): a 10 s plan at 1 kHz (10 001 configurations,
/// a smooth swing of every joint) of the FR3 with its hand and fingers, against its own
/// links and a scene of 10 boxes, checked with a 5 mm margin; and every pair computed at
/// every configuration, for comparison.
#[test]
#[ignore]
fn time_a_ten_second_plan_of_the_fr3_among_ten_shapes() {
    let Some((_, _, chain, geometry)) = franky_fr3() else {
        return;
    };
    let obstacles: Vec<Obstacle> = (0..10)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 10.0;
            Obstacle {
                name: format!("box{k}"),
                pose: Isometry3::translation(0.75 * a.cos(), 0.75 * a.sin(), 0.1 + 0.05 * k as f64),
                shape: Shape::cuboid([0.1, 0.1, 0.2], "box").unwrap(),
            }
        })
        .collect();
    let model = CollisionModel::new(geometry.bodies, obstacles, &geometry.adjacent);
    let (lo, hi) = chain.chain.limits().unwrap();
    let mid: Vec<f64> = lo.iter().zip(hi).map(|(l, h)| 0.5 * (l + h)).collect();
    let plan: Vec<Vec<f64>> = (0..=10_000)
        .map(|k| {
            let s = (std::f64::consts::PI * k as f64 / 10_000.0).sin();
            mid.iter()
                .zip(lo.iter().zip(hi))
                .map(|(m, (l, h))| m + 0.4 * (h - l) * 0.5 * s)
                .collect()
        })
        .collect();
    let mut frames = Vec::with_capacity(8);
    let all_frames: Vec<Vec<Isometry3<f64>>> = plan
        .iter()
        .map(|q| {
            chain.chain.frames_into(q, &mut frames).unwrap();
            frames.clone()
        })
        .collect();
    let t = std::time::Instant::now();
    for q in &plan {
        chain.chain.frames_into(q, &mut frames).unwrap();
        std::hint::black_box(&frames);
    }
    let fk = t.elapsed();
    let t = std::time::Instant::now();
    let model = std::sync::Arc::new(model);
    let mut check = cps_geometry::PathCheck::new(model.clone(), 0.005);
    let mut closest = f64::INFINITY;
    for f in &all_frames {
        if let Some(c) = check.step(f) {
            closest = closest.min(c.separation.distance);
        }
    }
    let lazy = t.elapsed();
    let t = std::time::Instant::now();
    for f in all_frames.iter().step_by(10) {
        for p in 0..model.pair_count() {
            std::hint::black_box(model.distance(p, f));
        }
    }
    let every = t.elapsed() * 10;
    eprintln!(
        "{} bodies, {} pairs; 10 001 configurations: forward kinematics (frames_into) {:.1} ms, the path check {:.1} ms ({} distances), every pair at every configuration {:.0} ms ({:.2} µs a configuration); closest within the margin {closest}",
        model.bodies().len(),
        model.pair_count(),
        fk.as_secs_f64() * 1e3,
        lazy.as_secs_f64() * 1e3,
        check.queries(),
        every.as_secs_f64() * 1e3,
        every.as_secs_f64() * 1e6 / 10_001.0
    );
}

/// The built-in FR3 (its modified DH chain, franka_description's meshes shipped in
/// configs/robots/franka, the hand and open fingers written in code) is the same model as
/// franky-sim's fr3.urdf read by cps: at random configurations, every pair of links (the
/// closest of their shapes) and every link against a box the same distance apart.
#[test]
fn the_built_in_fr3_is_its_urdf() {
    use cps_kinematics::robots::{PandaTool, fr3};
    use cps_movement::collision::{FrankaArm, franka_geometry};
    use std::collections::BTreeMap;
    let Some((_, _, chain, from_file)) = franky_fr3() else {
        return;
    };
    let built_in = franka_geometry(FrankaArm::Fr3, true);
    assert_eq!(built_in.bodies.len(), from_file.bodies.len());
    let scene = || {
        vec![Obstacle {
            name: "box".into(),
            pose: Isometry3::translation(0.45, 0.1, 0.3),
            shape: Shape::cuboid([0.2, 0.3, 0.4], "box").unwrap(),
        }]
    };
    let a = CollisionModel::new(from_file.bodies, scene(), &from_file.adjacent);
    let b = CollisionModel::new(built_in.bodies, scene(), &built_in.adjacent);
    assert_eq!(a.pair_count(), b.pair_count());
    let dh = fr3(PandaTool::HandTcp);
    let frames = |c: &cps_kinematics::SerialChain, q: &[f64]| {
        let poses = c.fk_frames(q).unwrap();
        let mut f = vec![Isometry3::identity()];
        f.extend(poses.link_frames.iter().map(|m| {
            Isometry3::from_parts(
                m.translation,
                UnitQuaternion::from_rotation_matrix(&m.rotation),
            )
        }));
        f
    };
    let by_links = |m: &CollisionModel, f: &[Isometry3<f64>]| {
        let mut out: BTreeMap<(String, String), f64> = BTreeMap::new();
        for c in m.within(f, 100.0) {
            let (x, y) = m.pair_names(c.pair);
            let key = (x.min(y).to_string(), x.max(y).to_string());
            let d = out.entry(key).or_insert(f64::INFINITY);
            *d = d.min(c.separation.distance);
        }
        out
    };
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..100 {
        let q = chain.chain.random_configuration(&mut rng);
        let (da, db) = (
            by_links(&a, &frames(&chain.chain, &q)),
            by_links(&b, &frames(&dh, &q)),
        );
        assert_eq!(da.len(), db.len());
        for (k, x) in &da {
            assert!(
                (x - db[k]).abs() < 1e-9,
                "{k:?} at {q:?}: URDF {x}, built in {}",
                db[k]
            );
        }
    }
}

/// The pairs a built-in Franka model leaves out beyond the joined ones (franka_description's
/// SRDF's), searched afresh on its hulls over its joint ranges: each closest approach is the
/// one the model carries (`FRANKA_LEFT_OUT`, to 0.1 mm), and those that meet are the two
/// the model checks.
fn searched_as_built_in(
    arm: cps_movement::collision::FrankaArm,
    chain: &cps_kinematics::SerialChain,
) -> Vec<cps_robot::PairApproach> {
    use cps_movement::collision::franka_geometry;
    use cps_robot::{NeverSearch, Why, closest_approaches};
    let geometry = franka_geometry(arm, true);
    assert_eq!(geometry.disabled.len(), 25);
    let pairs: Vec<(String, String)> = geometry
        .disabled
        .iter()
        .map(|l| (l.first.clone(), l.second.clone()))
        .collect();
    let started = std::time::Instant::now();
    let found =
        closest_approaches(chain, &geometry.bodies, &pairs, &NeverSearch::default()).unwrap();
    eprintln!("searched in {:.1} s", started.elapsed().as_secs_f64());
    for f in &found {
        eprintln!(
            "(\"{}\", \"{}\", {:.4}) at {:?}",
            f.first, f.second, f.closest, f.witness
        );
    }
    for (f, l) in found.iter().zip(&geometry.disabled) {
        match l.why {
            Why::Searched(carried) => {
                assert!(
                    (f.closest - carried).abs() < 6e-5,
                    "{f:?}: carried {carried}"
                )
            }
            // The search finds no pair of shapes to measure: they share a frame.
            Why::Fixed => assert_eq!(f.closest, f64::INFINITY, "{f:?}"),
            _ => panic!("{l:?} is not searched"),
        }
    }
    // Exactly link2–link6 and link5–link7 come within the guard's margin: they are the
    // pairs the model checks.
    let shapes = geometry.shapes();
    let searched = shapes.left_out().iter().filter(|l| l.why != Why::Joined);
    for (f, l) in found.iter().zip(searched) {
        let meets = f.first.ends_with("link2") && f.second.ends_with("link6")
            || f.first.ends_with("link5") && f.second.ends_with("link7");
        assert_eq!(meets, f.closest < cps_robot::DEFAULT_MARGIN, "{f:?}");
        assert_eq!(meets, !l.skipped_at(shapes.margin()), "{l:?}");
    }
    found
}

/// franka_description's SRDF leaves 13 pairs of the arm's links (and 12 of the hand's and
/// fingers') out as "Never". Searched on the hulls cps checks (`closest_approaches`:
/// 20 000 seeded samples over the FR3's joint ranges, then pattern searches from each
/// pair's closest), link2 and link6 come more than 10 mm into each other and link5 and
/// link7 more than 4 mm (47.4 and 9.7 mm found; MuJoCo's random samples had found 14.6 and
/// 5.9 mm, collision-notes.md), at configurations inside the ranges where MuJoCo, on
/// franky-sim's model, measures the same depths within a millimetre.
#[test]
fn the_srdfs_never_pairs_searched_on_the_fr3s_hulls_meet_where_mujoco_says() {
    use cps_kinematics::robots::{PandaTool, fr3};
    use cps_movement::collision::FrankaArm;
    let found = searched_as_built_in(FrankaArm::Fr3, &fr3(PandaTool::HandTcp));
    let depth = |a: &str, b: &str| {
        found
            .iter()
            .find(|f| f.first == a && f.second == b)
            .unwrap()
    };
    assert!(depth("fr3_link2", "fr3_link6").closest < -0.010);
    assert!(depth("fr3_link5", "fr3_link7").closest < -0.004);
    let Some((python, assets, _, _)) = franky_fr3() else {
        return;
    };
    let meet: Vec<_> = found.iter().filter(|f| f.closest < 0.005).collect();
    let job = serde_json::json!({
        "box": [3.0, 3.0, 3.0, 0.1, 0.1, 0.1],
        "pairs": meet.iter().map(|f| [&f.first, &f.second]).collect::<Vec<_>>(),
        "q": meet.iter().map(|f| &f.witness).collect::<Vec<_>>(),
        "time": false,
    });
    let reply = mujoco(&python, &assets, &job);
    for (k, f) in meet.iter().enumerate() {
        let theirs = reply["distances"][k][k].as_f64().unwrap();
        eprintln!(
            "{} – {}: cps {:+.2} mm, MuJoCo {:+.2} mm",
            f.first,
            f.second,
            f.closest * 1e3,
            theirs * 1e3
        );
        assert!((f.closest - theirs).abs() < 1e-3, "{f:?}: MuJoCo {theirs}");
    }
}

/// The Panda shares the FR3's SRDF pairs: searched the same way on its own hulls and joint
/// ranges, every pair it leaves out keeps farther apart than the guard's margin but for
/// link2–link6 and link5–link7, as on the FR3, and the model carries what the search found.
#[test]
fn the_pandas_left_out_pairs_keep_apart_over_its_joint_ranges() {
    use cps_kinematics::robots::{PandaTool, panda};
    use cps_movement::collision::FrankaArm;
    searched_as_built_in(FrankaArm::Panda, &panda(PandaTool::HandTcp));
}

/// A URDF's SRDF is not trusted: each pair it leaves out is searched over the joint ranges
/// on the shapes cps checks, a pair that meets is checked, and the search is kept beside
/// the robot (`ROBOT.pairs.json`) for the next load — read again only for the same robot,
/// never written over a file cps did not write.
mod srdf_pairs {
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
        let cache: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("arm.pairs.json")).unwrap(),
        )
        .unwrap();
        let witness: Vec<f64> =
            serde_json::from_value(cache["pairs"][1]["witness"].clone()).unwrap();
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
}
