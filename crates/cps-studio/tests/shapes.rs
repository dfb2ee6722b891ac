//! The studio draws what the guard checks: the thesis Panda's collision hulls and the
//! table it stands on, posed by the executed movement, with every near miss at its time.
//! Judged from the answer's own numbers: the drawn corners of each link, put in the world
//! by the drawn poses, against the table's top (a plane the test knows: z = 0.749 m, the
//! scene's base height).

use cps_studio::api;
use serde_json::{Value, json};

const TABLE_TOP: f64 = 0.749;

fn request(via_1: [f64; 3]) -> api::ViaPointRequest {
    serde_json::from_value(json!({
        "start": [0.75, 0.02, 1.87], "goal": [0.55, -0.57, 1.45], "tau": 10,
        "via": [{"time": 2, "position": [0.78, 0.60, 1.70]},
                {"time": 4, "position": via_1},
                {"time": 6, "position": [1.15, -0.15, 1.20]},
                {"time": 8, "position": [0.90, -0.53, 1.20]}],
        "robot": true,
    }))
    .unwrap()
}

/// The lowest drawn corner of every body at `pose` (body index → z, m).
fn lowest(shapes: &Value, pose: &Value) -> Vec<f64> {
    let pose: Vec<[f64; 12]> = serde_json::from_value(pose.clone()).unwrap();
    shapes["bodies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            let m = pose[b["frame"].as_u64().unwrap() as usize];
            let v: Vec<f64> = serde_json::from_value(b["vertices"].clone()).unwrap();
            v.chunks(3)
                .map(|p| m[8] * p[0] + m[9] * p[1] + m[10] * p[2] + m[11])
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

#[test]
fn the_robot_is_drawn_with_its_hulls_and_its_near_misses_at_their_time() {
    let studio = cps_studio::robot::StudioRobot::thesis().unwrap();
    let view = serde_json::to_value(studio.view()).unwrap();
    let shapes = &view["shapes"];
    let bodies = shapes["bodies"].as_array().unwrap();
    let names: Vec<&str> = bodies.iter().map(|b| b["name"].as_str().unwrap()).collect();
    for link in ["panda_link0", "panda_link4", "panda_link7", "panda_hand"] {
        assert!(names.contains(&link), "{names:?}");
    }
    assert!(names.iter().any(|n| n.contains("finger")), "{names:?}");
    assert_eq!(shapes["obstacles"][0]["name"], "table");
    assert!(view["shapes_note"].is_null());
    assert_eq!(
        view["pose"].as_array().unwrap().len(),
        8,
        "base and 7 links"
    );
    for b in bodies {
        let v = b["vertices"].as_array().unwrap().len();
        let t: Vec<u64> = serde_json::from_value(b["triangles"].clone()).unwrap();
        assert!(
            v.is_multiple_of(3) && t.len().is_multiple_of(3) && t.len() >= 12,
            "{}",
            b["name"]
        );
        assert!(t.iter().all(|&i| (i as usize) < v / 3), "{}", b["name"]);
    }
    // The table's drawn top is the scene's: z = 0.749 m.
    let table: Vec<f64> =
        serde_json::from_value(shapes["obstacles"][0]["vertices"].clone()).unwrap();
    let top = table
        .chunks(3)
        .map(|p| p[2])
        .fold(f64::NEG_INFINITY, f64::max);
    assert!((top - TABLE_TOP).abs() < 1e-6, "{top}");
    // At rest every link but the base, which stands on it, is above the table.
    let rest = lowest(shapes, &view["pose"]);
    for (b, z) in bodies.iter().zip(&rest) {
        if b["name"] != "panda_link0" {
            assert!(*z > TABLE_TOP + 0.1, "{}: {z}", b["name"]);
        }
    }

    // The thesis's task: clear of the table and of itself; the guard agrees.
    let answer = api::viapoint(&request([1.12, 0.37, 1.45]), Some(&studio), &|| false).unwrap();
    let r = serde_json::to_value(answer.robot.unwrap()).unwrap();
    assert!(r["collision"].is_null(), "{}", r["collision"]);
    let poses = r["poses"].as_array().unwrap();
    assert_eq!(poses.len(), r["frames"].as_array().unwrap().len());
    for near in r["near"].as_array().unwrap() {
        for n in near.as_array().unwrap() {
            assert!(n["distance"].as_f64().unwrap() >= shapes["margin"].as_f64().unwrap());
        }
    }

    // Via point p2 a centimetre above the table: the hand's fingers reach into it around
    // t = 4 s. The near misses are drawn there, on the bodies whose drawn corners go below
    // the table's top, and the guard's sentence names the table.
    let answer = api::viapoint(&request([1.0, 0.2, 0.76]), Some(&studio), &|| false).unwrap();
    let r = serde_json::to_value(answer.robot.unwrap()).unwrap();
    assert!(r["unreachable"].is_null(), "{r}");
    let sentence = r["collision"].as_str().expect("the guard refuses it");
    assert!(sentence.contains("`table`"), "{sentence}");
    let t: Vec<f64> = serde_json::from_value(r["t"].clone()).unwrap();
    let near = r["near"].as_array().unwrap();
    let deepest = |k: usize| {
        near[k]
            .as_array()
            .unwrap()
            .iter()
            .filter(|n| n["obstacle"] == 0)
            .map(|n| n["distance"].as_f64().unwrap())
            .fold(f64::INFINITY, f64::min)
    };
    let k = (0..t.len())
        .min_by(|&a, &b| deepest(a).total_cmp(&deepest(b)))
        .unwrap();
    assert!(deepest(k) < 0.0, "overlapping: {}", deepest(k));
    // The first drawn pose within the margin is the one after the guard's first sample
    // within it (poses are drawn every 40 ms and stand for the samples since the last).
    let guard_t: f64 = sentence
        .split("t = ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let margin = shapes["margin"].as_f64().unwrap();
    let first = (0..t.len()).find(|&k| deepest(k) < margin).unwrap();
    assert!(
        t[first] >= guard_t && t[first] - guard_t <= 0.04 + 1e-9,
        "{} against {sentence}",
        t[first]
    );
    assert!(
        (3.9..4.6).contains(&t[k]),
        "deepest around the via point's time: {}",
        t[k]
    );
    let low = lowest(shapes, &r["poses"][k]);
    for n in near[k].as_array().unwrap() {
        if n["obstacle"] == 0 && n["distance"].as_f64().unwrap() < 0.0 {
            let b = n["body"].as_u64().unwrap() as usize;
            assert!(low[b] < TABLE_TOP, "{}: {}", bodies[b]["name"], low[b]);
        }
    }
    // The corners below the table belong to bodies coloured as overlapping it.
    for (b, z) in low.iter().enumerate() {
        if *z < TABLE_TOP - 1e-3 && bodies[b]["name"] != "panda_link0" {
            assert!(
                near[k]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|n| n["body"] == b && n["obstacle"] == 0),
                "{}",
                bodies[b]["name"]
            );
        }
    }
}
