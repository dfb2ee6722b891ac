//! cps against a real ROS 2 node: rclpy (ROS 2 Jazzy from PyPI's wheels) on Fast DDS,
//! `rmw_fastrtps_cpp`, ROS 2's default middleware (tests/rclpy_peer.py). Each test runs
//! in a network namespace of its own (tests/common).

mod common;

use std::time::{Duration, Instant};

use common::{Peer, inside_rclpy};
use cps_ros2::action::FollowJointTrajectoryClient;
use cps_ros2::msg::{JointState, MarkerArray};
use cps_ros2::names::NodeName;
use cps_ros2::node::{Node, Qos};
use serde_json::Value;

const FAST_DDS: &str = "rmw_fastrtps_cpp";

fn names(v: &Value) -> Vec<String> {
    v.as_array()
        .unwrap_or(&Vec::new())
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect()
}

fn snapshot(peer: &mut Peer, command: &str) -> Value {
    peer.send(command);
    let line = peer.line();
    serde_json::from_str(&line).unwrap_or_else(|e| panic!("the peer's snapshot {line:?}: {e}"))
}

/// Asks for snapshots until `done` holds of one (at most 10 s); the last one.
fn snapshot_until(peer: &mut Peer, done: impl Fn(&Value) -> bool) -> Value {
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        let s = snapshot(peer, "snapshot");
        if done(&s) || Instant::now() > end {
            return s;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn rclpy_on_fast_dds_lists_cps_its_topics_and_its_action_client() {
    if !inside_rclpy("rclpy_on_fast_dds_lists_cps_its_topics_and_its_action_client") {
        return;
    }
    let node = Node::new(NodeName::new("cps_test", "/", 0).unwrap()).unwrap();
    let markers = node
        .publisher::<MarkerArray>("/cps/markers", Qos::Latched { depth: 1 })
        .unwrap();
    let states = node
        .subscription::<JointState>("/joint_states", Qos::Reliable { depth: 10 })
        .unwrap();
    let client = FollowJointTrajectoryClient::new(&node, "/arm/follow_joint_trajectory").unwrap();

    let mut peer = Peer::rclpy(FAST_DDS, &["graph", "cps_test"]);
    let s = snapshot(&mut peer, "wait 15");
    println!("{s}");
    assert_eq!(s["rmw"], FAST_DDS);
    let nodes = names(&s["nodes"]);
    assert!(nodes.contains(&"/cps_test".to_string()), "{nodes:?}");
    assert!(nodes.contains(&"/rclpy_peer".to_string()), "{nodes:?}");
    assert_eq!(
        names(&s["publishers"]["/cps/markers"]),
        ["visualization_msgs/msg/MarkerArray"]
    );
    assert_eq!(
        names(&s["subscribers"]["/joint_states"]),
        ["sensor_msgs/msg/JointState"]
    );
    assert_eq!(
        names(&s["clients"]["/arm/follow_joint_trajectory/_action/send_goal"]),
        ["control_msgs/action/FollowJointTrajectory_SendGoal"]
    );
    assert_eq!(
        names(&s["action_clients"]["/arm/follow_joint_trajectory"]),
        ["control_msgs/action/FollowJointTrajectory"]
    );
    // Each endpoint is the node's, by its GID: rclpy names the node, not
    // `_NODE_NAME_UNKNOWN_`.
    assert_eq!(names(&s["endpoint_nodes"]["/cps/markers"]), ["/cps_test"]);
    assert!(names(&s["endpoint_nodes"]["/joint_states"]).contains(&"/cps_test".to_string()));

    // Every change is announced: a publisher dropped leaves the node's list.
    drop(markers);
    let s = snapshot_until(&mut peer, |s| s["publishers"].get("/cps/markers").is_none());
    assert!(s["publishers"].get("/cps/markers").is_none(), "{s}");
    assert!(s["subscribers"].get("/joint_states").is_some(), "{s}");

    // And the node leaves the graph with its participant.
    drop((states, client, node));
    let s = snapshot(&mut peer, "gone 15");
    assert!(
        !names(&s["nodes"]).contains(&"/cps_test".to_string()),
        "{s}"
    );
    peer.send("quit");
    peer.finish(Duration::from_secs(10));
}
