//! The ROS 2 numbers of docs/ros2.md, side by side on Fast DDS (rclpy 7.1.6 on
//! `rmw_fastrtps_cpp`) and CycloneDDS (11.0.1), and rclpy doing the same work itself: a
//! benchmark, not a test — every case is `#[ignore]`d and prints what it measured:
//!
//! ```text
//! cargo test --profile checked -p cps-ros2 --test numbers -- --ignored --nocapture --test-threads=1
//! ```
//!
//! Each runs in a network namespace of its own (tests/common), against the test peers
//! (tests/rclpy_peer.py, tests/peer.py).

use cps_testkit::ros2_graph as common;
mod support;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use common::{Peer, control_msgs, inside, inside_rclpy, temp};
use cps_ros2::action::{FollowJointTrajectoryClient, FollowTimes};
use cps_ros2::names::NodeName;
use cps_ros2::node::{Node, Qos};
use cps_ros2::record::{RecordOptions, record_joint_states};
use cps_ros2_msg::msg::{FollowJointTrajectoryGoal, GoalId};
use serde_json::Value;

fn cps_node() -> Node {
    Node::new(NodeName::new("cps_numbers", "/", 0).unwrap()).unwrap()
}

fn unix_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64
}

/// Node start to a 10 s trajectory (1001 points) acknowledged: the discovery, the wait
/// after it and the delivery; `received` gives the peer's JSON of what it got and when.
fn trajectory(middleware: &str, received: impl FnOnce() -> (Value, u64)) {
    let started_ns = unix_ns();
    let start = Instant::now();
    let node = cps_node();
    let t = support::trajectory(10.0, 100.0);
    let sent = cps_ros2::publish::publish(
        &node,
        "/arm_controller/joint_trajectory",
        &t,
        Qos::Reliable { depth: 1 },
        Duration::from_secs(30),
    )
    .unwrap();
    let acknowledged = start.elapsed().as_secs_f64();
    let (got, at_ns) = received();
    support::assert_same_trajectory(&got, &t);
    println!(
        "| {middleware} | discovery (cps's writer matched) | {:.3} s |",
        sent.matched_after_s
    );
    println!(
        "| {middleware} | node start → a 10 s trajectory (1001 points, {} bytes) received, every number equal | {:.3} s (acknowledged at {acknowledged:.3} s) |",
        sent.bytes,
        (at_ns.saturating_sub(started_ns)) as f64 * 1e-9
    );
}

/// JointState at 1 kHz for 10 s from the peer, recorded until it says it is done.
fn joint_states(middleware: &str, peer: Peer) {
    let node = cps_node();
    let stop = AtomicBool::new(false);
    let (rec, said) = std::thread::scope(|s| {
        let recording = s.spawn(|| {
            record_joint_states(
                &node,
                &RecordOptions {
                    topic: "/joint_states".into(),
                    joints: support::joints(),
                    duration: Duration::from_secs(120),
                    wait: Duration::from_secs(30),
                    qos: Qos::Reliable { depth: 5000 },
                },
                &stop,
                |_| {},
            )
        });
        let mut peer = peer;
        let said = peer.line();
        std::thread::sleep(Duration::from_millis(500));
        stop.store(true, Ordering::Relaxed);
        peer.send("quit");
        (recording.join().unwrap().unwrap(), said)
    });
    println!(
        "| {middleware} | JointState at 1 kHz, 10 s (the peer: {said}) | {} recorded, {} lost, {} older |",
        rec.positions.len(),
        rec.lost,
        rec.older
    );
}

/// A goal's round trip (a one-point goal: sent → accepted → result) five times, and the
/// time from a cancel to the goal's end.
fn action(middleware: &str, name: &str) {
    let node = cps_node();
    let mut client = FollowJointTrajectoryClient::new(&node, name).unwrap();
    let times = FollowTimes {
        server: Duration::from_secs(20),
        result: Duration::from_secs(30),
        after_cancel: Duration::from_secs(10),
    };
    let never = AtomicBool::new(false);
    let goal = FollowJointTrajectoryGoal {
        trajectory: support::trajectory(0.0, 100.0),
        ..Default::default()
    };
    let mut trips = Vec::new();
    for k in 0..6 {
        let start = Instant::now();
        let o = client
            .follow(&goal, GoalId::from_bits(100 + k), times, &never, |_| {})
            .unwrap();
        assert!(o.succeeded(), "{o:?}");
        // The first includes discovery and the wait after it.
        if k > 0 {
            trips.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    trips.sort_by(f64::total_cmp);
    println!(
        "| {middleware} | goal → accepted → result, one-point goal, 5 times | median {:.1} ms (min {:.1}, max {:.1}) |",
        trips[2], trips[0], trips[4]
    );
    let long = FollowJointTrajectoryGoal {
        trajectory: support::trajectory(10.0, 100.0),
        ..Default::default()
    };
    let cancel = AtomicBool::new(false);
    let asked = std::sync::Mutex::new(None);
    let (o, ended) = std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(1500));
            *asked.lock().unwrap() = Some(Instant::now());
            cancel.store(true, Ordering::Relaxed);
        });
        let o = client
            .follow(&long, GoalId::from_bits(200), times, &cancel, |_| {})
            .unwrap();
        (o, Instant::now())
    });
    let latency = ended - asked.lock().unwrap().expect("the cancel was asked");
    println!(
        "| {middleware} | cancel of a running 10 s goal → its end reported ({}) | {:.1} ms |",
        o.status.word(),
        latency.as_secs_f64() * 1e3
    );
}

#[test]
#[ignore]
fn numbers_on_fast_dds() {
    if control_msgs().is_none() || !inside_rclpy("numbers_on_fast_dds") {
        return;
    }
    let mut listener = Peer::rclpy(
        "rmw_fastrtps_cpp",
        &["listen", "/arm_controller/joint_trajectory"],
    );
    trajectory("Fast DDS", || {
        let got: Value = serde_json::from_str(&listener.line()).unwrap();
        let at = got["received_ns"].as_u64().unwrap();
        (got, at)
    });
    let states = Peer::rclpy("rmw_fastrtps_cpp", &["states", "1000", "10", "5000"]);
    joint_states("Fast DDS", states);
    let dir = temp("goals").with_file_name("goals");
    std::fs::create_dir_all(&dir).unwrap();
    let mut server = Peer::rclpy(
        "rmw_fastrtps_cpp",
        &[
            "fjt",
            "/arm_controller/follow_joint_trajectory",
            dir.to_str().unwrap(),
        ],
    );
    action("Fast DDS", "/arm_controller/follow_joint_trajectory");
    server.send("quit");
}

#[test]
#[ignore]
fn numbers_on_cyclonedds() {
    if !inside("numbers_on_cyclonedds") {
        return;
    }
    let out = temp("trajectory.json");
    let listener = Peer::start(&[
        "listen",
        "/arm_controller/joint_trajectory",
        out.to_str().unwrap(),
    ]);
    trajectory("CycloneDDS", || {
        listener.finish(Duration::from_secs(60));
        let got: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let at = (got["received_at"].as_f64().unwrap() * 1e9) as u64;
        (got["messages"][0].clone(), at)
    });
    let names = support::joints().join(",");
    let states = Peer::start(&[
        "publish",
        "/joint_states",
        "--rate",
        "1000",
        "--seconds",
        "10",
        "--joints",
        &names,
    ]);
    joint_states("CycloneDDS", states);
    let seen = temp("server.json");
    let _server = Peer::start(&[
        "serve",
        "/arm_controller/follow_joint_trajectory",
        seen.to_str().unwrap(),
        "--linger",
        "30",
    ]);
    action("CycloneDDS", "/arm_controller/follow_joint_trajectory");
}

/// rclpy's own figures for the same work on Fast DDS (tests/rclpy_peer.py's `send`,
/// `count` and `goals`): rclpy to rclpy, measured the same way.
#[test]
#[ignore]
fn numbers_of_rclpy_on_fast_dds() {
    if control_msgs().is_none() || !inside_rclpy("numbers_of_rclpy_on_fast_dds") {
        return;
    }
    let rmw = "rmw_fastrtps_cpp";
    let mut listener = Peer::rclpy(rmw, &["listen", "/arm_controller/joint_trajectory"]);
    let mut sender = Peer::rclpy(rmw, &["send", "/arm_controller/joint_trajectory"]);
    let sent: Value = serde_json::from_str(&sender.line()).unwrap();
    let got: Value = serde_json::from_str(&listener.line()).unwrap();
    sender.send("quit");
    support::assert_same_trajectory(&got, &support::trajectory(10.0, 100.0));
    let started = sent["started_ns"].as_u64().unwrap();
    let at = got["received_ns"].as_u64().unwrap();
    println!(
        "| rclpy, Fast DDS | discovery (rclpy's publisher matched) | {:.3} s |",
        sent["matched_s"].as_f64().unwrap()
    );
    println!(
        "| rclpy, Fast DDS | rclpy.init → a 10 s trajectory received, every number equal | {:.3} s |",
        at.saturating_sub(started) as f64 * 1e-9
    );

    let mut counter = Peer::rclpy(rmw, &["count"]);
    let mut states = Peer::rclpy(rmw, &["states", "1000", "10", "5000"]);
    let said = states.line();
    std::thread::sleep(Duration::from_millis(500));
    counter.send("quit");
    states.send("quit");
    let counted = counter.line();
    println!("| rclpy, Fast DDS | JointState at 1 kHz, 10 s (the peer: {said}) | {counted} |");

    let dir = temp("goals").with_file_name("goals");
    std::fs::create_dir_all(&dir).unwrap();
    let action = "/arm_controller/follow_joint_trajectory";
    let mut server = Peer::rclpy(rmw, &["fjt", action, dir.to_str().unwrap()]);
    let mut client = Peer::rclpy(rmw, &["goals", action]);
    let said: Value = serde_json::from_str(&client.line()).unwrap();
    server.send("quit");
    let mut trips = support::floats(&said["trips_ms"])[1..].to_vec();
    trips.sort_by(f64::total_cmp);
    println!(
        "| rclpy, Fast DDS | goal → accepted → result, one-point goal, 5 times | median {:.1} ms (min {:.1}, max {:.1}) |",
        trips[2], trips[0], trips[4]
    );
    println!(
        "| rclpy, Fast DDS | cancel of a running 10 s goal → its end reported (status {}) | {:.1} ms |",
        said["cancel_status"],
        said["cancel_ms"].as_f64().unwrap()
    );
}
