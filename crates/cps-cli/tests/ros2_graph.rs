//! `cps-cli ros2 graph` and the graph's words in `ros2 send`, against a real ROS 2 node
//! (rclpy on Fast DDS, cps-ros2's tests/rclpy_peer.py) and a CycloneDDS action server
//! (tests/peer.py) on one graph, in a network namespace of the test's own.

mod common;
use cps_testkit::ros2_graph as graph;

use common::cli;
use serde_json::Value;

fn names(v: &Value) -> Vec<String> {
    v.as_array()
        .unwrap_or(&Vec::new())
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect()
}

/// A 1 s trajectory that stays at the Panda's ready pose.
fn still(dir: &std::path::Path) -> std::path::PathBuf {
    let traj = dir.join("t.csv");
    std::fs::write(
        &traj,
        "t,q1,q2,q3,q4,q5,q6,q7\n0,0,-0.785,0,-2.356,0,1.571,0.785\n0.5,0,-0.785,0,-2.356,0,1.571,0.785\n1,0,-0.785,0,-2.356,0,1.571,0.785\n",
    )
    .unwrap();
    traj
}

/// `ros2 send` of [`still`] to `controller` with `more` arguments: its exit code and
/// what it said on stderr.
fn send_still(dir: &std::path::Path, controller: &str, more: &[&str]) -> (Option<i32>, String) {
    let traj = still(dir);
    let mut args = vec![
        "ros2",
        "send",
        traj.to_str().unwrap(),
        "--controller",
        controller,
    ];
    args.extend(more);
    let out = cli(&args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// cps-ros2's CycloneDDS FollowJointTrajectory server at
/// `/arm_controller/follow_joint_trajectory`, staying 30 s.
fn cyclone_server(dir: &std::path::Path) -> graph::Peer {
    let seen = dir.join("server.json");
    graph::Peer::start(&[
        "serve",
        "/arm_controller/follow_joint_trajectory",
        seen.to_str().unwrap(),
        "--linger",
        "30",
    ])
}

fn middlewares(ends: &Value) -> Vec<String> {
    ends.as_array()
        .unwrap()
        .iter()
        .map(|e| e["middleware"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn graph_lists_the_nodes_topics_services_and_actions_of_both_middlewares() {
    if !graph::inside_rclpy("graph_lists_the_nodes_topics_services_and_actions_of_both_middlewares")
        || graph::python().is_none()
    {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let _rclpy = graph::Peer::rclpy("rmw_fastrtps_cpp", &["serve", "0.05"]);
    let _cyclone = cyclone_server(dir.path());
    // Discovery windows long enough for a loaded machine: `bash test.sh` runs this beside
    // the franky-sim lane at a lower priority, where 1.5 s once missed rclpy's node.
    let out = cli(&["ros2", "graph", "--seconds", "3", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let g: Value = serde_json::from_slice(&out.stdout).unwrap();
    println!("{}", serde_json::to_string_pretty(&g).unwrap());
    assert_eq!(g["domain"], 0);
    assert_eq!(names(&g["nodes"]), ["/rclpy_peer"]);
    let mut vendors: Vec<String> = g["participants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["middleware"].as_str().unwrap().to_string())
        .collect();
    vendors.sort();
    assert_eq!(vendors, ["CycloneDDS", "Fast DDS"]);
    // rclpy's node: its action, its parameter services, its log topic, named by node.
    let fib = &g["actions"]["/fibonacci"];
    assert_eq!(names(&fib["types"]), ["test_msgs/action/Fibonacci"]);
    assert_eq!(fib["servers"][0]["node"], "/rclpy_peer");
    assert_eq!(middlewares(&fib["servers"]), ["Fast DDS"]);
    let params = &g["services"]["/rclpy_peer/get_parameters"];
    assert_eq!(
        names(&params["types"]),
        ["rcl_interfaces/srv/GetParameters"]
    );
    assert_eq!(params["servers"][0]["node"], "/rclpy_peer");
    let rosout = &g["topics"]["/rosout"];
    assert_eq!(names(&rosout["types"]), ["rcl_interfaces/msg/Log"]);
    assert_eq!(rosout["publishers"][0]["node"], "/rclpy_peer");
    // rosout is transient-local in rclpy (so late listeners get the last lines).
    assert_eq!(rosout["publishers"][0]["durability"], "transient_local");
    // The CycloneDDS server: an action with no node (plain DDS announces none).
    let fjt = &g["actions"]["/arm_controller/follow_joint_trajectory"];
    assert_eq!(
        names(&fjt["types"]),
        ["control_msgs/action/FollowJointTrajectory"]
    );
    assert_eq!(middlewares(&fjt["servers"]), ["CycloneDDS"]);
    assert!(fjt["servers"][0]["node"].is_null());

    // In words. (A window of 6 s: beside the other lanes on CI's two cores, a 3 s window
    // once closed before rclpy's node announcement reached the new participant.)
    let out = cli(&["ros2", "graph", "--seconds", "6"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("DDS domain 0: 2 participant(s), 1 node(s)"),
        "{text}"
    );
    assert!(
        text.contains("/fibonacci [test_msgs/action/Fibonacci] served by /rclpy_peer"),
        "{text}"
    );
    assert!(
        text.contains("served by an unnamed CycloneDDS endpoint"),
        "{text}"
    );

    // A controller that is not there: the error says what is.
    let (code, err) = send_still(dir.path(), "/panda_arm_controller", &["--wait", "2"]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("actions on domain 0: /arm_controller/follow_joint_trajectory (an unnamed CycloneDDS endpoint), /fibonacci (/rclpy_peer)"),
        "{err}"
    );
}

#[test]
fn graph_on_an_empty_domain_says_so() {
    if !graph::inside_rclpy("graph_on_an_empty_domain_says_so") {
        return;
    }
    let out = cli(&["ros2", "graph", "--seconds", "1", "--domain", "7"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("nothing on DDS domain 7: no participant answered"),
        "{text}"
    );
    let out = cli(&["ros2", "graph", "--seconds", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--seconds 0"));
}

#[test]
fn a_service_mapping_that_is_not_one_is_refused() {
    let out = cli(&[
        "ros2",
        "send",
        "t.csv",
        "--controller",
        "/arm",
        "--service-mapping",
        "zenoh",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("service mapping `zenoh`: give auto, cyclone or fastdds"),
        "{err}"
    );
}

/// Forced onto the mapping its server does not speak, a goal gets no answer, and the
/// sentence says which mapping cps spoke.
#[test]
fn a_forced_mapping_the_server_does_not_speak_gets_no_answer() {
    if !graph::inside("a_forced_mapping_the_server_does_not_speak_gets_no_answer") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let _cyclone = cyclone_server(dir.path());
    let (code, err) = send_still(
        dir.path(),
        "/arm_controller",
        &["--wait", "3", "--service-mapping", "fastdds"],
    );
    assert_eq!(code, Some(1));
    assert!(
        err.contains(
            "did not answer the goal within 3.0 s (cps spoke Fast DDS's request/reply mapping to it"
        ),
        "{err}"
    );
}
