//! `cps-cli ros2 follow` against a CycloneDDS subscriber on the controller's topic (cps-ros2's
//! tests/peer.py), in a network namespace of the test's own: one replacement trajectory per
//! chunk, each starting where the one it replaces has the arm at that instant, moving as it
//! moves — continuous for the controller — and within the Panda's limits.

mod common;
use cps_testkit::ros2_graph as graph;

use cps_chunks::StandIn;

use common::cli;

/// The Panda's ready pose and velocity limits (rad, rad/s).
const READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
const PANDA_DQ_MAX: [f64; 7] = [2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61];

/// Message `m`'s positions and velocities at `t` s from its start (cubic Hermite between
/// its points, from their positions and velocities).
fn at(m: &serde_json::Value, t: f64) -> (Vec<f64>, Vec<f64>) {
    let points = m["points"].as_array().unwrap();
    let time = |p: &serde_json::Value| {
        let s = &p["time_from_start"];
        s[0].as_f64().unwrap() + s[1].as_f64().unwrap() * 1e-9
    };
    let v = |p: &serde_json::Value, k: &str| -> Vec<f64> {
        p[k].as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let i = points
        .iter()
        .rposition(|p| time(p) <= t)
        .unwrap()
        .min(points.len() - 2);
    let (a, b) = (&points[i], &points[i + 1]);
    let h = time(b) - time(a);
    let u = (t - time(a)) / h;
    let (qa, qb, va, vb) = (
        v(a, "positions"),
        v(b, "positions"),
        v(a, "velocities"),
        v(b, "velocities"),
    );
    let (u2, u3) = (u * u, u * u * u);
    let q = (0..7)
        .map(|j| {
            (2.0 * u3 - 3.0 * u2 + 1.0) * qa[j]
                + (u3 - 2.0 * u2 + u) * h * va[j]
                + (-2.0 * u3 + 3.0 * u2) * qb[j]
                + (u3 - u2) * h * vb[j]
        })
        .collect();
    let d = (0..7)
        .map(|j| {
            ((6.0 * u2 - 6.0 * u) * qa[j]
                + (3.0 * u2 - 4.0 * u + 1.0) * h * va[j]
                + (-6.0 * u2 + 6.0 * u) * qb[j]
                + (3.0 * u2 - 2.0 * u) * h * vb[j])
                / h
        })
        .collect();
    (q, d)
}

fn stamp(m: &serde_json::Value) -> f64 {
    m["stamp"][0].as_f64().unwrap() + m["stamp"][1].as_f64().unwrap() * 1e-9
}

#[test]
fn chunks_reach_a_controller_as_replacements_continuous_across_each() {
    if !graph::inside("chunks_reach_a_controller_as_replacements_continuous_across_each") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let demo = |t: f64| -> Vec<f64> {
        let s = 0.5 - 0.5 * (std::f64::consts::FRAC_PI_2 * t.max(0.0)).cos();
        READY
            .iter()
            .enumerate()
            .map(|(j, q)| q + 0.2 * s * if j % 2 == 0 { 1.0 } else { -0.5 })
            .collect()
    };
    let chunks = StandIn {
        horizon: 50,
        target_hz: 50.0,
        chunk_hz: 10.0,
        delay_s: (0.05, 0.15),
        noise_rad: 0.002,
        seed: 9,
    }
    .chunks(&demo, 0.0, 2.0);
    let file = dir.path().join("chunks.csv");
    std::fs::write(&file, cps_movement::chunks::write_chunks(&chunks, 7)).unwrap();
    let got = dir.path().join("messages.json");
    let count = chunks.len().to_string();
    let listener = graph::Peer::start(&[
        "listen",
        "/panda_arm_controller/joint_trajectory",
        got.to_str().unwrap(),
        "--count",
        &count,
    ]);
    let o = cli(&[
        "ros2",
        "follow",
        file.to_str().unwrap(),
        "--controller",
        "/panda_arm_controller",
        "--rate",
        "50",
        "--wait",
        "30",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let answer: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(answer["published"], chunks.len(), "{answer}");
    assert_eq!(answer["replacements"], chunks.len());
    listener.finish(std::time::Duration::from_secs(30));
    let seen = common::json(&got);
    let messages = seen["messages"].as_array().unwrap();
    assert_eq!(messages.len(), chunks.len());
    let mut worst = (0.0_f64, 0.0_f64);
    for w in messages.windows(2) {
        let (old, new) = (&w[0], &w[1]);
        let gap = stamp(new) - stamp(old);
        assert!((0.09..0.11).contains(&gap), "{gap} s between replacements");
        // Where the old message has the arm when the new one starts is where the new one
        // starts, moving as the old one moves.
        let (q_old, v_old) = at(old, gap);
        let (q_new, v_new) = at(new, 0.0);
        for j in 0..7 {
            worst.0 = worst.0.max((q_old[j] - q_new[j]).abs());
            worst.1 = worst.1.max((v_old[j] - v_new[j]).abs());
        }
    }
    eprintln!(
        "across the replacements: position within {:.2e} rad, velocity within {:.2e} rad/s",
        worst.0, worst.1
    );
    // (The new chunk changes the motion from its first millisecond, within the jerk
    // limit: J·dt² ≈ 2e-3 rad/s at most on the wrist's 1 645 rad/s³.)
    assert!(worst.0 < 1e-5 && worst.1 < 5e-3, "{worst:?}");
    // Within the Panda's velocity limits everywhere, and the last message ends at rest.
    let vmax = PANDA_DQ_MAX;
    for m in messages {
        for p in m["points"].as_array().unwrap() {
            for (j, v) in p["velocities"].as_array().unwrap().iter().enumerate() {
                assert!(v.as_f64().unwrap().abs() <= vmax[j], "{v}");
            }
        }
    }
    let last = messages.last().unwrap()["points"].as_array().unwrap();
    let end = last.last().unwrap()["velocities"].as_array().unwrap();
    assert!(end.iter().all(|v| v.as_f64().unwrap() == 0.0));
}

#[test]
fn a_chunk_file_for_another_robot_is_refused_before_the_graph() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("six.csv");
    std::fs::write(
        &file,
        "chunk,arrived_s,observed_s,k,q1,q2,q3,q4,q5,q6\n0,0.1,0,0,0,0,0,0,0,0\n",
    )
    .unwrap();
    let o = cli(&[
        "ros2",
        "follow",
        file.to_str().unwrap(),
        "--controller",
        "/arm",
        "--rate",
        "50",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("six.csv"), "{e}");
}

/// `--scene`: chunks whose motion runs the hand into a post of the scene are refused
/// before anything joins the graph, the hand and the post named.
#[test]
fn chunks_into_a_scene_s_obstacle_are_refused_before_the_graph() {
    let dir = tempfile::tempdir().unwrap();
    let reach = [0.2, -0.1, 0.2, -0.1, 0.2, -0.1, 0.2];
    let demo = |t: f64| -> Vec<f64> {
        let s = 0.5 - 0.5 * (std::f64::consts::FRAC_PI_2 * t.clamp(0.0, 2.0)).cos();
        READY.iter().zip(reach).map(|(q, d)| q + d * s).collect()
    };
    let chunks = StandIn {
        horizon: 50,
        target_hz: 50.0,
        chunk_hz: 10.0,
        delay_s: (0.05, 0.15),
        noise_rad: 0.0,
        seed: 9,
    }
    .chunks(&demo, 0.0, 2.5);
    let file = dir.path().join("chunks.csv");
    std::fs::write(&file, cps_movement::chunks::write_chunks(&chunks, 7)).unwrap();
    // The post where the hand ends.
    let at = common::hand_at("panda", &demo(2.0));
    let scene = common::post_scene(dir.path(), "scene", "panda", &READY, at, [0.04, 0.04, 0.3]);
    let o = cli(&[
        "ros2",
        "follow",
        file.to_str().unwrap(),
        "--controller",
        "/arm",
        "--rate",
        "50",
        "--scene",
        scene.to_str().unwrap(),
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("refused before sending anything: the executor's motion for these chunks comes too close")
            && e.contains("`panda_hand` and `post`"),
        "{e}"
    );
}
