//! `cps-cli ros2 graph`: what cps sees of a ROS 2 graph, in words and JSON — the nodes
//! and their middleware, topics with types and QoS, services and actions with the nodes
//! at each end — and what it says when the graph lacks what a command looks for.

use std::time::Duration;

use cps_robot::StopToken;
use cps_ros2::graph::{End, Graph, Service, observe};
use serde_json::{Value, json};

use cps_outcome::InputError;

use crate::error::DriveError;
use cps_ros2::names::NodeName;
use cps_ros2::node::Node;
use cps_ros2::robot::NODE_NAME;

/// The node, on `domain` or `ROS_DOMAIN_ID`'s.
pub fn node(domain: Option<u16>) -> Result<Node, DriveError> {
    let name = NodeName::from_env(NODE_NAME, domain).map_err(|e| InputError(e.to_string()))?;
    Ok(Node::new(name)?)
}

/// What to look at.
#[derive(Debug, Clone)]
pub struct GraphLook {
    /// The DDS domain (None: `ROS_DOMAIN_ID`, else 0).
    pub domain: Option<u16>,
    /// Seconds to watch before describing (discovery takes about a second).
    pub seconds: f64,
}

fn end_json(e: &End) -> Value {
    json!({
        "node": e.node,
        "middleware": e.vendor.name(),
        "reliability": if e.reliable { "reliable" } else { "best_effort" },
        "durability": if e.transient_local { "transient_local" } else { "volatile" },
    })
}

fn ends_json(ends: &[End]) -> Value {
    Value::Array(ends.iter().map(end_json).collect())
}

fn service_json(s: &Service) -> Value {
    json!({"types": s.types, "servers": ends_json(&s.servers), "clients": ends_json(&s.clients)})
}

/// The graph as JSON: `domain`, `participants` (guid_prefix, middleware, nodes), `nodes`,
/// `topics`, `services` and `actions` by name.
pub fn graph_json(g: &Graph) -> Value {
    json!({
        "domain": g.domain,
        "participants": g.participants.iter().map(|p| json!({
            "guid_prefix": p.guid_prefix,
            "middleware": p.vendor.name(),
            "nodes": p.nodes,
        })).collect::<Vec<_>>(),
        "nodes": g.nodes(),
        "topics": g.topics.iter().map(|(n, t)| (n.clone(), json!({
            "types": t.types,
            "publishers": ends_json(&t.publishers),
            "subscriptions": ends_json(&t.subscriptions),
        }))).collect::<serde_json::Map<_, _>>(),
        "services": g.services.iter()
            .filter(|(n, _)| !n.contains("/_action/"))
            .map(|(n, s)| (n.clone(), service_json(s)))
            .collect::<serde_json::Map<_, _>>(),
        "actions": g.actions.iter()
            .map(|(n, s)| (n.clone(), service_json(s)))
            .collect::<serde_json::Map<_, _>>(),
    })
}

fn who(ends: &[End]) -> String {
    let mut names: Vec<String> = ends
        .iter()
        .map(|e| match &e.node {
            Some(n) => n.clone(),
            None => format!("an unnamed {} endpoint", e.vendor.name()),
        })
        .collect();
    names.sort();
    names.dedup();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

fn qos_word(ends: &[End]) -> String {
    let mut w: Vec<String> = ends
        .iter()
        .map(|e| {
            format!(
                "{}{}",
                if e.reliable {
                    "reliable"
                } else {
                    "best effort"
                },
                if e.transient_local {
                    ", transient-local"
                } else {
                    ""
                }
            )
        })
        .collect();
    w.sort();
    w.dedup();
    w.join(" | ")
}

/// The graph in words, a line each.
pub fn graph_lines(g: &Graph) -> Vec<String> {
    let mut lines = Vec::new();
    if g.participants.is_empty() {
        lines.push(format!(
            "nothing on DDS domain {}: no participant answered (is ROS_DOMAIN_ID the same on the robot's side, and is the network the same?)",
            g.domain
        ));
        return lines;
    }
    lines.push(format!(
        "DDS domain {}: {} participant(s), {} node(s)",
        g.domain,
        g.participants.len(),
        g.nodes().len()
    ));
    for p in &g.participants {
        lines.push(format!(
            "  {} ({}): {}",
            p.guid_prefix,
            p.vendor.name(),
            if p.nodes.is_empty() {
                "no ROS 2 node announced".to_string()
            } else {
                p.nodes.join(", ")
            }
        ));
    }
    lines.push(format!("topics ({}):", g.topics.len()));
    for (n, t) in &g.topics {
        let side = |ends: &[End]| {
            if ends.is_empty() {
                "none".to_string()
            } else {
                format!("{} ({})", who(ends), qos_word(ends))
            }
        };
        lines.push(format!(
            "  {n} [{}] published by {}; subscribed by {}",
            t.types.join(", "),
            side(&t.publishers),
            side(&t.subscriptions)
        ));
    }
    let services: Vec<(&String, &Service)> = g
        .services
        .iter()
        .filter(|(n, _)| !n.contains("/_action/"))
        .collect();
    lines.push(format!("services ({}):", services.len()));
    for (n, s) in services {
        lines.push(format!(
            "  {n} [{}] served by {}; clients {}",
            s.types.join(", "),
            who(&s.servers),
            who(&s.clients)
        ));
    }
    lines.push(format!("actions ({}):", g.actions.len()));
    for (n, s) in &g.actions {
        lines.push(format!(
            "  {n} [{}] served by {}; clients {}",
            s.types.join(", "),
            who(&s.servers),
            who(&s.clients)
        ));
    }
    lines
}

/// `ros2 graph`: watches the graph for `look.seconds` and describes it.
pub fn graph(look: &GraphLook, stop: &StopToken) -> Result<Seen, DriveError> {
    if !(look.seconds.is_finite() && look.seconds > 0.0 && look.seconds <= 600.0) {
        return Err(InputError(format!(
            "--seconds {}: give a time above 0 and at most 600 s to watch the graph",
            look.seconds
        ))
        .into());
    }
    let n = node(look.domain)?;
    // Watched in slices, so Ctrl-C ends the watch at once.
    let slices = (look.seconds / 0.1).ceil() as u32;
    for _ in 0..slices {
        if stop.is_stopped() {
            break;
        }
        std::thread::sleep(Duration::from_secs_f64(look.seconds / slices as f64));
    }
    Ok(Seen(observe(&n, Duration::from_millis(200))?))
}

/// What `ros2 graph` saw: JSON as [`graph_json`], words as [`graph_lines`].
#[derive(Debug, Clone)]
pub struct Seen(pub Graph);

impl serde::Serialize for Seen {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        serde::Serialize::serialize(&graph_json(&self.0), s)
    }
}

impl std::fmt::Display for Seen {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&graph_lines(&self.0).join("\n"))
    }
}

/// What the graph on `node`'s domain offers in place of the action `missing`: a sentence
/// naming the actions there are (and their nodes), or that there are none.
pub fn action_hint(node: &Node, missing: &str) -> String {
    let Ok(g) = observe(node, Duration::from_millis(800)) else {
        return String::new();
    };
    if g.participants.is_empty() {
        return format!(
            "; nothing answered on DDS domain {} (is ROS_DOMAIN_ID the same on the robot's side?)",
            g.domain
        );
    }
    let last = missing.rsplit('/').next().unwrap_or(missing);
    let offered: Vec<String> = g
        .actions
        .iter()
        .map(|(n, s)| format!("{n} ({})", who(&s.servers)))
        .collect();
    if offered.is_empty() {
        format!(
            "; no node on domain {} offers an action ({} node(s) there: {})",
            g.domain,
            g.nodes().len(),
            g.nodes().join(", ")
        )
    } else {
        let similar: Vec<&String> = offered.iter().filter(|o| o.contains(last)).collect();
        format!(
            "; actions on domain {}: {}{}",
            g.domain,
            offered.join(", "),
            if similar.is_empty() {
                format!(" — no node offers {last}")
            } else {
                String::new()
            }
        )
    }
}

/// What [`publish_latched`] did: the domain it published in, and how many subscribers
/// matched while it stayed on the graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Published {
    /// The DDS domain.
    pub domain: u16,
    /// The most subscribers matched at once.
    pub subscribers: usize,
}

/// Publishes `markers` latched on `topic` (a viewer that joins later still gets them) and
/// stays on the graph for `seconds` (in (0, 86 400]) or until `stop`.
pub fn publish_latched(
    markers: &cps_ros2_msg::msg::MarkerArray,
    topic: &str,
    seconds: f64,
    domain: Option<u16>,
    stop: &StopToken,
) -> Result<Published, DriveError> {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 86_400.0) {
        return Err(InputError(format!("--seconds {seconds}: give seconds in (0, 86400]")).into());
    }
    let node = node(domain)?;
    let mut writer = node.publisher::<cps_ros2_msg::msg::MarkerArray>(
        topic,
        cps_ros2::node::Qos::Latched { depth: 1 },
    )?;
    writer.write(markers)?;
    let end = std::time::Instant::now() + Duration::from_secs_f64(seconds);
    while std::time::Instant::now() < end && !stop.is_stopped() {
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok(Published {
        domain: node.name().domain,
        subscribers: usize::try_from(writer.matched_ever()).unwrap_or(0),
    })
}
