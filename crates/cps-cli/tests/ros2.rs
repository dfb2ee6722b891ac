//! `cps-cli ros2 send` and `ros2 record` against a CycloneDDS FollowJointTrajectory server
//! that publishes joint states (cps-ros2's tests/peer.py), in a network namespace of the
//! test's own; and the refusals that happen before anything reaches the graph.

mod common;
#[path = "../../cps-ros2/tests/common/mod.rs"]
mod graph;

use std::process::{Command, Stdio};

use common::cli;

/// A 2 s move of every joint from the Panda's ready pose (cosine blend, rest to rest).
fn trajectory(dir: &std::path::Path, amplitude: f64, seconds: f64) -> std::path::PathBuf {
    let ready = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let mut text = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
    for k in 0..=100 {
        let t = seconds * k as f64 / 100.0;
        let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 100.0).cos();
        let row: Vec<String> = ready
            .iter()
            .map(|q| format!("{}", q + amplitude * s))
            .collect();
        text.push_str(&format!("{t},{}\n", row.join(",")));
    }
    let p = dir.join("move.csv");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn send_follows_a_goal_and_record_writes_the_robots_joint_states() {
    if !graph::inside("send_follows_a_goal_and_record_writes_the_robots_joint_states") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let traj = trajectory(dir.path(), 0.2, 2.0);
    let seen = dir.path().join("server.json");
    let _server = graph::Peer::start(&[
        "serve",
        "/panda_arm_controller/follow_joint_trajectory",
        seen.to_str().unwrap(),
        "--joint-states",
        "/joint_states",
        "--rate",
        "200",
    ]);
    let rec = dir.path().join("rec.csv");
    let recorder = Command::new(env!("CARGO_BIN_EXE_cps-cli"))
        .args([
            "ros2",
            "record",
            "--duration",
            "2.5",
            "--wait",
            "30",
            "--json",
            "--out",
        ])
        .arg(&rec)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let sent = cli(&[
        "ros2",
        "send",
        traj.to_str().unwrap(),
        "--controller",
        "/panda_arm_controller",
        "--wait",
        "30",
        "--json",
    ]);
    let err = String::from_utf8_lossy(&sent.stderr);
    assert_eq!(sent.status.code(), Some(0), "{err}");
    let answer: serde_json::Value = serde_json::from_slice(&sent.stdout).unwrap();
    assert_eq!(answer["succeeded"], true, "{answer}");
    assert_eq!(answer["status"], "succeeded");
    assert_eq!(answer["points"], 201, "2 s at the default 10 ms");
    assert_eq!(answer["joint_names"][6], "panda_joint7");
    assert!(answer["feedback"].as_u64().unwrap() >= 20, "{answer}");
    let recorded = recorder.wait_with_output().unwrap();
    assert_eq!(
        recorded.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&recorded.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&recorded.stdout).unwrap();
    assert_eq!(report["lost"], 0, "{report}");
    // The recording gets the limit check every trajectory gets.
    assert!(report["limits"]["ok"].is_boolean(), "{report}");
    assert_eq!(report["limits"]["rate_hz"], 1000.0);
    assert_eq!(report["time_source"], "stamp");
    let text = std::fs::read_to_string(&rec).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,panda_joint1,panda_joint2,panda_joint3,panda_joint4,panda_joint5,panda_joint6,panda_joint7"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert!(rows.len() > 300, "200 Hz for 2.8 s: {} rows", rows.len());
    let last = rows.last().unwrap();
    let goal = [0.2, -0.585, 0.2, -2.156, 0.2, 1.771, 0.985];
    for (j, g) in goal.iter().enumerate() {
        assert!(
            (last[j + 1] - g).abs() < 1e-9,
            "joint {j}: {} vs {g}",
            last[j + 1]
        );
    }
    // The recording imitates as any demonstration does.
    let model = dir.path().join("model.json");
    let o = cli(&[
        "imitate",
        rec.to_str().unwrap(),
        "--out",
        model.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn bad_input_is_refused_before_anything_reaches_the_graph() {
    let dir = tempfile::tempdir().unwrap();
    let ok = trajectory(dir.path(), 0.2, 2.0);
    let send = |extra: &[&str], file: &std::path::Path| {
        let mut args = vec![
            "ros2",
            "send",
            file.to_str().unwrap(),
            "--controller",
            "/arm",
            "--wait",
            "1",
        ];
        args.extend_from_slice(extra);
        cli(&args)
    };
    let o = send(&["--joint-names", "a,b,c"], &ok);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("3 name(s) for the panda's 7 joints"));
    let o = send(&["--domain", "300"], &ok);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("domain 300"));
    // 1.2 rad in 0.1 s breaks the Panda's velocity limits: refused, exit 1.
    let fast = trajectory(dir.path(), 1.2, 0.1);
    let o = send(&[], &fast);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("refused, nothing was sent"), "{err}");
    let o = send(&[], &dir.path().join("missing.csv"));
    assert_eq!(o.status.code(), Some(2));
    std::fs::write(dir.path().join("taken.csv"), "x").unwrap();
    let o = cli(&[
        "ros2",
        "record",
        "--duration",
        "1",
        "--out",
        dir.path().join("taken.csv").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--force"));
    assert_eq!(
        std::fs::read_to_string(dir.path().join("taken.csv")).unwrap(),
        "x"
    );
}
