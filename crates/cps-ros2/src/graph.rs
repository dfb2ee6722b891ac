//! What cps sees of a ROS 2 graph: the participants and their middleware (vendor), the
//! nodes they announce, and, from DDS discovery, every topic, service and action with
//! its types, QoS and the nodes at each end — what `ros2 node list`, `ros2 topic list -t`,
//! `ros2 service list` and `ros2 action list` show, built the way rmw builds them
//! (endpoints from discovery, tied to nodes by the GIDs in `ros_discovery_info`).

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use crate::Ros2Error;
use crate::discovery::{Gid, GidLayout, ParticipantEntities};
use crate::node::{Node, Vendor};

/// One end of a topic or service.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct End {
    /// The node it belongs to (`/ns/name`), if its participant announced it.
    pub node: Option<String>,
    /// The middleware of its participant.
    pub vendor: Vendor,
    /// Reliable (else best effort).
    pub reliable: bool,
    /// Transient-local (else volatile).
    pub transient_local: bool,
    /// The DDS type name (`sensor_msgs::msg::dds_::JointState_`).
    pub dds_type: String,
}

/// A topic with its writers and readers.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Topic {
    /// Its ROS types (`sensor_msgs/msg/JointState`), more than one if ends disagree.
    pub types: Vec<String>,
    /// Its publishers.
    pub publishers: Vec<End>,
    /// Its subscriptions.
    pub subscriptions: Vec<End>,
}

/// A service with its servers and clients.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Service {
    /// Its ROS types (`rcl_interfaces/srv/GetParameters`).
    pub types: Vec<String>,
    /// The ends that take requests.
    pub servers: Vec<End>,
    /// The ends that send them.
    pub clients: Vec<End>,
}

/// A participant: one process (or more nodes of one).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Participant {
    /// Its GUID prefix, hex.
    pub guid_prefix: String,
    /// Its middleware.
    pub vendor: Vendor,
    /// The nodes it announces (none: a DDS program that is not ROS 2, or a ROS 2 one
    /// whose announcement has not come).
    pub nodes: Vec<String>,
}

/// The graph as seen from one node.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Graph {
    /// The DDS domain.
    pub domain: u16,
    /// Every participant heard of but this node's own.
    pub participants: Vec<Participant>,
    /// Topics by ROS name.
    pub topics: BTreeMap<String, Topic>,
    /// Services by ROS name (an action's five parts among them).
    pub services: BTreeMap<String, Service>,
    /// Actions by ROS name, as services (send_goal's ends).
    pub actions: BTreeMap<String, Service>,
}

impl Graph {
    /// The nodes on the graph, `/ns/name`, sorted.
    pub fn nodes(&self) -> Vec<String> {
        let mut n: Vec<String> = self
            .participants
            .iter()
            .flat_map(|p| p.nodes.iter().cloned())
            .collect();
        n.sort();
        n
    }
}

/// A ROS name of a DDS topic: `rt/x` is topic `/x`, `rq/xRequest` and `rr/xReply` the
/// service `/x`'s two halves; anything else is not ROS's.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RosName {
    /// A topic.
    Topic(String),
    /// A service's requests.
    Request(String),
    /// A service's replies.
    Reply(String),
}

/// The ROS name of the DDS topic `dds`, if it is one.
pub fn ros_name(dds: &str) -> Option<RosName> {
    if let Some(t) = dds.strip_prefix("rt/") {
        return Some(RosName::Topic(format!("/{t}")));
    }
    if let Some(s) = dds
        .strip_prefix("rq/")
        .and_then(|s| s.strip_suffix("Request"))
    {
        return Some(RosName::Request(format!("/{s}")));
    }
    if let Some(s) = dds
        .strip_prefix("rr/")
        .and_then(|s| s.strip_suffix("Reply"))
    {
        return Some(RosName::Reply(format!("/{s}")));
    }
    None
}

/// The ROS type of a DDS type name: `pkg::msg::dds_::Name_` is `pkg/msg/Name`;
/// `pkg::srv::dds_::Name_Request_` is `pkg/srv/Name`; an action's
/// `pkg::action::dds_::Name_SendGoal_Request_` is `pkg/action/Name_SendGoal`. Names that
/// do not follow rmw's pattern are returned as they are.
pub fn ros_type(dds: &str) -> String {
    let parts: Vec<&str> = dds.split("::").collect();
    if let [pkg, kind, "dds_", name] = parts[..] {
        let name = name.strip_suffix('_').unwrap_or(name);
        let name = name
            .strip_suffix("_Request")
            .or_else(|| name.strip_suffix("_Response"))
            .unwrap_or(name);
        return format!("{pkg}/{kind}/{name}");
    }
    dds.to_string()
}

/// A node's full name, `/ns/name`.
fn node_path(n: &crate::discovery::NodeEntities) -> String {
    if n.namespace.ends_with('/') {
        format!("{}{}", n.namespace, n.name)
    } else {
        format!("{}/{}", n.namespace, n.name)
    }
}

/// What one announcement says of each endpoint: its node.
fn node_of_endpoints(announced: &BTreeMap<[u8; 12], ParticipantEntities>) -> BTreeMap<Gid, String> {
    let mut m = BTreeMap::new();
    for p in announced.values() {
        for n in &p.nodes {
            let name = node_path(n);
            for g in n.readers.iter().chain(&n.writers) {
                m.insert(*g, name.clone());
            }
        }
    }
    m
}

fn prefix(g: &Gid) -> [u8; 12] {
    g[..12].try_into().expect("12 bytes")
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// Watches the graph from `node` for `watch` (discovery and announcements arrive over the
/// first second or so; a longer watch sees slower peers), then describes it.
pub fn observe(node: &Node, watch: Duration) -> Result<Graph, Ros2Error> {
    let mut reader = node.graph_reader()?;
    let mut announced: BTreeMap<[u8; 12], ParticipantEntities> = BTreeMap::new();
    let end = Instant::now() + watch;
    loop {
        while let Some(r) = reader.take_with(|r| {
            let mut iron = r.clone();
            ParticipantEntities::decode_as(&mut iron, GidLayout::Iron)
                .or_else(|e| ParticipantEntities::decode_as(r, GidLayout::Humble).map_err(|_| e))
        }) {
            let p = r.message;
            announced.insert(prefix(&p.gid), p);
        }
        if Instant::now() >= end {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let own = prefix(&node.gid());
    announced.remove(&own);
    let vendors = node.vendors();
    let nodes_of = node_of_endpoints(&announced);
    let mut graph = Graph {
        domain: node.name().domain,
        ..Graph::default()
    };
    let mut seen: BTreeMap<[u8; 12], Vendor> = vendors
        .participants()
        .into_iter()
        .filter(|(p, _)| *p != own)
        .collect();
    for found in node.discovered_ends() {
        let p = prefix(&found.gid);
        if p == own {
            continue;
        }
        let vendor = *seen.entry(p).or_insert_with(|| vendors.of(&found.gid));
        let end = End {
            node: nodes_of.get(&found.gid).cloned(),
            vendor,
            reliable: found.reliable,
            transient_local: found.transient_local,
            dds_type: found.dds_type.clone(),
        };
        let (dds_topic, dds_type, writer) = (found.topic, found.dds_type, found.writer);
        let ty = ros_type(&dds_type);
        // (types, the writers' list, the readers' list). A server reads requests and
        // writes replies, a client the reverse: each end is counted once, by its request
        // half.
        let (entry, writers, readers) = match ros_name(&dds_topic) {
            Some(RosName::Topic(t)) => {
                let e = graph.topics.entry(t).or_default();
                (&mut e.types, &mut e.publishers, &mut e.subscriptions)
            }
            Some(RosName::Request(s)) => {
                let e = graph.services.entry(s).or_default();
                (&mut e.types, &mut e.clients, &mut e.servers)
            }
            Some(RosName::Reply(_)) | None => continue,
        };
        let list = if writer { writers } else { readers };
        if !entry.contains(&ty) {
            entry.push(ty);
        }
        list.push(end);
    }
    for (name, s) in &graph.services {
        if let Some(action) = name.strip_suffix("/_action/send_goal") {
            let mut a = s.clone();
            a.types = a
                .types
                .iter()
                .map(|t| t.strip_suffix("_SendGoal").unwrap_or(t).to_string())
                .collect();
            graph.actions.insert(action.to_string(), a);
        }
    }
    graph.participants = seen
        .into_iter()
        .map(|(p, vendor)| {
            let mut nodes: Vec<String> = announced
                .get(&p)
                .map(|a| a.nodes.iter().map(node_path).collect())
                .unwrap_or_default();
            nodes.sort();
            Participant {
                guid_prefix: hex(&p),
                vendor,
                nodes,
            }
        })
        .collect();
    Ok(graph)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dds_names_read_as_ros_names() {
        assert_eq!(
            ros_name("rt/joint_states"),
            Some(RosName::Topic("/joint_states".into()))
        );
        assert_eq!(
            ros_name("rq/arm/follow_joint_trajectory/_action/send_goalRequest"),
            Some(RosName::Request(
                "/arm/follow_joint_trajectory/_action/send_goal".into()
            ))
        );
        assert_eq!(
            ros_name("rr/cps/get_parametersReply"),
            Some(RosName::Reply("/cps/get_parameters".into()))
        );
        assert_eq!(ros_name("ros_discovery_info"), None);
        assert_eq!(ros_name("DCPSParticipant"), None);
    }

    #[test]
    fn dds_types_read_as_ros_types() {
        assert_eq!(
            ros_type("sensor_msgs::msg::dds_::JointState_"),
            "sensor_msgs/msg/JointState"
        );
        assert_eq!(
            ros_type("rcl_interfaces::srv::dds_::GetParameters_Request_"),
            "rcl_interfaces/srv/GetParameters"
        );
        assert_eq!(
            ros_type("control_msgs::action::dds_::FollowJointTrajectory_SendGoal_Request_"),
            "control_msgs/action/FollowJointTrajectory_SendGoal"
        );
        assert_eq!(ros_type("Plain"), "Plain");
    }
}
