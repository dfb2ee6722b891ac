//! cps on a DDS graph against CycloneDDS (tests/peer.py): the trajectory a subscriber
//! receives, joint states recorded at 1 kHz, a FollowJointTrajectory server that accepts,
//! rejects, aborts and sees a cancel, markers, and no peer at all. Each test runs in a
//! network namespace of its own (tests/common).

use cps_testkit::ros2_graph as common;
mod support;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use common::{Peer, inside, temp};
use cps_ros2::Ros2Error;
use cps_ros2::action::{FollowJointTrajectoryClient, FollowTimes};
use cps_ros2::names::NodeName;
use cps_ros2::node::{Node, Qos};
use cps_ros2::record::{RecordOptions, record_joint_states};
use cps_ros2_msg::msg::{FollowJointTrajectoryGoal, GoalId, GoalStatus, JointTrajectory, Time};
use serde_json::Value;
use support::{assert_same_trajectory, floats, joints, trajectory};

fn node() -> Node {
    Node::new(NodeName::new("cps_test", "/", 0).unwrap()).unwrap()
}

#[test]
fn a_cyclonedds_subscriber_receives_a_10_s_trajectory_at_100_hz_whole() {
    if !inside("a_cyclonedds_subscriber_receives_a_10_s_trajectory_at_100_hz_whole") {
        return;
    }
    let out = temp("trajectory.json");
    let peer = Peer::start(&[
        "listen",
        "/arm_controller/joint_trajectory",
        out.to_str().unwrap(),
    ]);
    let start = Instant::now();
    let node = node();
    let t = trajectory(10.0, 100.0);
    let sent = cps_ros2::publish::publish(
        &node,
        "/arm_controller/joint_trajectory",
        &t,
        Qos::Reliable { depth: 1 },
        Duration::from_secs(20),
    )
    .unwrap();
    assert!(sent.acknowledged, "the subscriber acknowledged the message");
    peer.finish(Duration::from_secs(30));
    let got: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let messages = got["messages"].as_array().unwrap();
    assert_eq!(messages.len(), 1);
    assert_same_trajectory(&messages[0], &t);
    println!(
        "discovery {:.3} s, first message delivered {:.3} s after the node started; {} points, {} bytes",
        sent.matched_after_s,
        start.elapsed().as_secs_f64(),
        t.points.len(),
        sent.bytes
    );
}

#[test]
fn joint_states_at_1_khz_are_recorded_in_the_model_order_without_loss() {
    if !inside("joint_states_at_1_khz_are_recorded_in_the_model_order_without_loss") {
        return;
    }
    let names = joints().join(",");
    let peer = Peer::start(&[
        "publish",
        "/joint_states",
        "--rate",
        "1000",
        "--seconds",
        "10",
        "--joints",
        &names,
        "--junk",
        "5",
        "--huge",
        "1",
    ]);
    let node = node();
    let stop = AtomicBool::new(false);
    // Recorded until the peer has sent everything (however slow a loaded machine makes
    // it), then stopped.
    let (rec, said) = std::thread::scope(|s| {
        let recording = s.spawn(|| {
            record_joint_states(
                &node,
                &RecordOptions {
                    topic: "/joint_states".into(),
                    joints: joints(),
                    duration: Duration::from_secs(120),
                    wait: Duration::from_secs(30),
                    qos: Qos::Reliable { depth: 5000 },
                },
                &stop,
                |_| {},
            )
        });
        let said = peer.finish(Duration::from_secs(120));
        std::thread::sleep(Duration::from_millis(500));
        stop.store(true, Ordering::Relaxed);
        (recording.join().unwrap().unwrap(), said)
    });
    println!("peer: {said}");
    println!(
        "recorded {} of 10000 JointState at 1 kHz: {} lost, {} incomplete, dropped {:?}, first after {:.3} s",
        rec.positions.len(),
        rec.lost,
        rec.incomplete,
        rec.dropped,
        rec.first_message_s
    );
    assert_eq!(rec.positions.len(), 10_000, "every message kept");
    assert_eq!(rec.lost, 0);
    assert_eq!(rec.incomplete, 0);
    assert_eq!(rec.dropped.malformed, 5, "the junk samples are counted");
    assert_eq!(rec.dropped.oversized, 1, "the 17 MiB sample is counted");
    let (times, source) = rec.times();
    assert_eq!(source, "stamp");
    for (k, (row, t)) in rec.positions.iter().zip(&times).enumerate() {
        assert!((t - k as f64 * 1e-3).abs() < 1e-9, "time of row {k}: {t}");
        for (i, q) in row.iter().enumerate() {
            let want = 0.1 * i as f64 + (k as f64 / 1000.0 + i as f64).sin();
            assert_eq!(*q, want, "row {k}, joint {i}");
        }
    }
    assert_eq!(rec.velocities.len(), 10_000);
    assert_eq!(rec.velocities[0][3], 3f64.cos());
}

fn follow(
    args: &[&str],
    seconds: f64,
    cancel_after: Option<f64>,
) -> (
    Result<cps_ros2::action::FollowOutcome, Ros2Error>,
    Value,
    Vec<f64>,
    JointTrajectory,
) {
    let out = temp("server.json");
    let mut peer_args = vec![
        "serve",
        "/arm_controller/follow_joint_trajectory",
        out.to_str().unwrap(),
    ];
    peer_args.extend_from_slice(args);
    let peer = Peer::start(&peer_args);
    let node = node();
    let mut client =
        FollowJointTrajectoryClient::new(&node, "/arm_controller/follow_joint_trajectory").unwrap();
    let t = trajectory(seconds, 50.0);
    let cancel = AtomicBool::new(false);
    let start = Instant::now();
    let mut progress = Vec::new();
    let outcome = std::thread::scope(|s| {
        if let Some(after) = cancel_after {
            let cancel = &cancel;
            s.spawn(move || {
                std::thread::sleep(Duration::from_secs_f64(after));
                cancel.store(true, Ordering::Relaxed);
            });
        }
        client.follow(
            &FollowJointTrajectoryGoal {
                trajectory: t.clone(),
                goal_time_tolerance: Time::from_secs(0.5),
            },
            GoalId::from_bits(0x1234_5678_9abc_def0_0fed_cba9_8765_4321),
            FollowTimes {
                server: Duration::from_secs(20),
                result: Duration::from_secs_f64(seconds + 10.0),
                after_cancel: Duration::from_secs(5),
            },
            &cancel,
            |f| progress.push(f.desired.positions[0]),
        )
    });
    println!(
        "goal over after {:.2} s: {outcome:?}",
        start.elapsed().as_secs_f64()
    );
    peer.finish(Duration::from_secs(30));
    let seen: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    (outcome, seen, progress, t)
}

#[test]
fn a_follow_joint_trajectory_goal_is_accepted_followed_and_succeeds() {
    if !inside("a_follow_joint_trajectory_goal_is_accepted_followed_and_succeeds") {
        return;
    }
    let (outcome, seen, progress, t) = follow(&[], 1.0, None);
    let outcome = outcome.unwrap();
    assert!(outcome.succeeded(), "{outcome:?}");
    assert!(
        outcome.feedback >= 10,
        "feedback at 50 Hz for 1 s: {}",
        outcome.feedback
    );
    assert_eq!(outcome.feedback as usize, progress.len());
    assert!(
        progress.windows(2).any(|w| w[1] != w[0]),
        "the feedback moves"
    );
    let goals = seen["goals"].as_array().unwrap();
    assert_eq!(goals.len(), 1);
    assert_same_trajectory(&goals[0]["trajectory"], &t);
    let id: Vec<u8> = goals[0]["goal_id"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as u8)
        .collect();
    assert_eq!(id, outcome.goal_id.0);
    assert_eq!(
        goals[0]["goal_time_tolerance"],
        serde_json::json!([0, 500_000_000])
    );
    assert_eq!(seen["result_requests"], 1);
    assert!(seen["cancels"].as_array().unwrap().is_empty());
    println!(
        "discovery {:.3} s; {} feedback",
        outcome.discovery_s, outcome.feedback
    );
}

#[test]
fn a_cancelled_goal_is_cancelled_on_the_server() {
    if !inside("a_cancelled_goal_is_cancelled_on_the_server") {
        return;
    }
    let (outcome, seen, _, _) = follow(&[], 5.0, Some(1.0));
    let outcome = outcome.unwrap();
    assert!(outcome.cancel_requested);
    assert_eq!(outcome.status, GoalStatus::Canceled, "{outcome:?}");
    assert!(!outcome.succeeded());
    let cancels = seen["cancels"].as_array().unwrap();
    assert_eq!(cancels.len(), 1);
    let id: Vec<u8> = cancels[0]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as u8)
        .collect();
    assert_eq!(id, outcome.goal_id.0);
}

#[test]
fn refused_and_aborted_goals_say_so() {
    if !inside("refused_and_aborted_goals_say_so") {
        return;
    }
    let (outcome, _, _, _) = follow(&["--reject"], 1.0, None);
    let outcome = outcome.unwrap();
    assert!(!outcome.accepted && !outcome.succeeded(), "{outcome:?}");
    let (outcome, _, _, _) = follow(&["--abort"], 2.0, None);
    let outcome = outcome.unwrap();
    assert_eq!(outcome.status, GoalStatus::Aborted);
    assert_eq!(outcome.error_code, -4);
    assert!(
        outcome.error_string.contains("path tolerance"),
        "{outcome:?}"
    );
}

#[test]
fn no_controller_is_a_sentence_after_the_timeout() {
    if !inside("no_controller_is_a_sentence_after_the_timeout") {
        return;
    }
    let node = node();
    let start = Instant::now();
    let mut client =
        FollowJointTrajectoryClient::new(&node, "/nobody/follow_joint_trajectory").unwrap();
    let e = client
        .follow(
            &FollowJointTrajectoryGoal::default(),
            GoalId::from_bits(1),
            FollowTimes {
                server: Duration::from_secs(1),
                result: Duration::from_secs(1),
                after_cancel: Duration::from_secs(1),
            },
            &AtomicBool::new(false),
            |_| {},
        )
        .unwrap_err();
    assert!(matches!(e, Ros2Error::NoPeer(_)));
    assert!(
        e.to_string().contains("/nobody/follow_joint_trajectory"),
        "{e}"
    );
    let e = cps_ros2::publish::publish(
        &node,
        "/nobody/joint_trajectory",
        &trajectory(0.1, 10.0),
        Qos::Reliable { depth: 1 },
        Duration::from_secs(1),
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("no subscriber to /nobody/joint_trajectory"),
        "{e}"
    );
    assert!(start.elapsed() < Duration::from_secs(10));
}

#[test]
fn markers_reach_a_late_subscriber() {
    if !inside("markers_reach_a_late_subscriber") {
        return;
    }
    let out = temp("markers.json");
    let peer = Peer::start(&["markers", "/cps/markers", out.to_str().unwrap()]);
    let node = node();
    let path: Vec<[f64; 3]> = (0..50)
        .map(|k| [0.4 + 0.004 * k as f64, 0.0, 0.5])
        .collect();
    let m = cps_ros2::markers::path_markers("panda_link0", &path, &[[0.5, 0.0, 0.5]]);
    cps_ros2::publish::publish(
        &node,
        "/cps/markers",
        &m,
        Qos::Latched { depth: 1 },
        Duration::from_secs(20),
    )
    .unwrap();
    peer.finish(Duration::from_secs(30));
    let got: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let got = got.as_array().unwrap();
    assert_eq!(got.len(), m.markers.len());
    assert_eq!(got[0]["frame_id"], "panda_link0");
    let points: Vec<Vec<f64>> = got[0]["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(floats)
        .collect();
    assert_eq!(points, path.iter().map(|p| p.to_vec()).collect::<Vec<_>>());
    assert_eq!(got[5]["text"], "goal");
    assert_eq!(floats(&got[4]["position"]), path[49].to_vec());
}
