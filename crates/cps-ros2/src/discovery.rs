//! ROS 2's graph over DDS: `ros_discovery_info`, the topic on which every participant
//! says which nodes it holds and which of its DDS readers and writers belong to which node
//! (rmw_dds_common's `ParticipantEntitiesInfo`). `ros2 node list`, `ros2 node info`,
//! rqt_graph and rclpy's graph API are built from it alone: a participant that does not
//! publish it has endpoints but no node.
//!
//! On the wire: topic `rt/ros_discovery_info`, type
//! `rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_`, reliable, transient-local,
//! keep-last 1, the whole list written again on every change. An entity's GID is its DDS
//! GUID (12-byte prefix, 4-byte entity id): 16 bytes since Iron (rmw_dds_common 2), 24 on
//! Humble (the GUID and 8 zero bytes). cps writes 16 unless told Humble and reads both.

use cps_ros2_msg::cdr::{CdrError, CdrReader, CdrWriter};
use cps_ros2_msg::msg::Message;

/// The DDS topic of the graph's announcements.
pub const TOPIC: &str = "ros_discovery_info";

/// An entity's global id: its DDS GUID.
pub type Gid = [u8; 16];

/// The most nodes cps keeps of one participant's announcement; more are refused as
/// malformed (a real process holds a handful; rclcpp's component containers, tens).
pub const MAX_NODES: usize = 10_000;

/// How GIDs are spelled on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GidLayout {
    /// `char[16]`: Iron, Jazzy, Kilted and later.
    #[default]
    Iron,
    /// `char[24]` (the GUID, then zeros): Humble.
    Humble,
}

impl GidLayout {
    /// The layout of the ROS 2 release `ROS_DISTRO` names (`humble`: Humble's; anything
    /// else, or unset: Iron's).
    pub fn from_distro(distro: Option<&str>) -> Self {
        match distro.map(|d| d.trim().to_ascii_lowercase()) {
            Some(d) if d == "humble" => GidLayout::Humble,
            _ => GidLayout::Iron,
        }
    }

    fn bytes(self) -> usize {
        match self {
            GidLayout::Iron => 16,
            GidLayout::Humble => 24,
        }
    }
}

/// One node's entities (`rmw_dds_common/NodeEntitiesInfo`).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct NodeEntities {
    /// The node's namespace (`/`, `/arm`).
    pub namespace: String,
    /// The node's name.
    pub name: String,
    /// Its subscriptions' and services' DDS readers.
    pub readers: Vec<Gid>,
    /// Its publishers' and services' DDS writers.
    pub writers: Vec<Gid>,
}

/// What a participant announces (`rmw_dds_common/ParticipantEntitiesInfo`).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ParticipantEntities {
    /// The participant's GID (its GUID prefix and the participant's entity id).
    pub gid: Gid,
    /// Its nodes.
    pub nodes: Vec<NodeEntities>,
}

impl ParticipantEntities {
    /// The sample's bytes with GIDs spelled as `layout` says.
    pub fn to_cdr_as(&self, layout: GidLayout) -> Vec<u8> {
        let mut w = CdrWriter::new();
        let gid = |w: &mut CdrWriter, g: &Gid| {
            w.raw(g);
            w.raw(&[0; 8][..layout.bytes() - 16]);
        };
        gid(&mut w, &self.gid);
        w.u32(self.nodes.len() as u32);
        for n in &self.nodes {
            w.string(&n.namespace).string(&n.name);
            for list in [&n.readers, &n.writers] {
                w.u32(list.len() as u32);
                for g in list {
                    gid(&mut w, g);
                }
            }
        }
        w.finish()
    }

    /// Reads a sample whose GIDs are spelled as `layout` says; the whole body must be
    /// used (a Humble sample read as Iron's, or the reverse, fails).
    pub fn decode_as(r: &mut CdrReader, layout: GidLayout) -> Result<Self, CdrError> {
        let n = layout.bytes();
        let gid = |r: &mut CdrReader, field: &'static str| -> Result<Gid, CdrError> {
            let g: Gid = r.array(field)?;
            for _ in 16..n {
                r.u8(field)?;
            }
            Ok(g)
        };
        let participant = gid(r, "gid")?;
        // A node takes at least two empty strings (4 + 1 bytes each, aligned) and two
        // counts.
        let count = r.count("node_entities_info_seq", 16)?;
        if count > MAX_NODES {
            return Err(CdrError {
                field: "node_entities_info_seq",
                offset: 0,
                problem: format!("{count} nodes, more than the {MAX_NODES} cps keeps"),
            });
        }
        let mut nodes = Vec::with_capacity(count);
        for _ in 0..count {
            let namespace = r.string("node_namespace")?;
            let name = r.string("node_name")?;
            let mut lists = [Vec::new(), Vec::new()];
            for (list, field) in lists.iter_mut().zip(["reader_gid_seq", "writer_gid_seq"]) {
                let k = r.count(field, n)?;
                list.reserve(k);
                for _ in 0..k {
                    list.push(gid(r, field)?);
                }
            }
            let [readers, writers] = lists;
            nodes.push(NodeEntities {
                namespace,
                name,
                readers,
                writers,
            });
        }
        if r.remaining() > 3 {
            return Err(CdrError {
                field: "end",
                offset: 0,
                problem: format!("{} bytes after the last node", r.remaining()),
            });
        }
        Ok(ParticipantEntities {
            gid: participant,
            nodes,
        })
    }

    /// Reads a sample of either layout: Iron's first, then Humble's.
    pub fn decode_any(body: &[u8], little: bool) -> Result<(Self, GidLayout), CdrError> {
        match Self::decode_as(&mut CdrReader::new(body, little), GidLayout::Iron) {
            Ok(p) => Ok((p, GidLayout::Iron)),
            Err(iron) => Self::decode_as(&mut CdrReader::new(body, little), GidLayout::Humble)
                .map(|p| (p, GidLayout::Humble))
                .map_err(|_| iron),
        }
    }
}

impl Message for ParticipantEntities {
    const TYPE: &'static str = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";

    fn encode(&self, w: &mut CdrWriter) {
        // Message::to_cdr is overridden below; encode is Iron's layout without the header.
        let bytes = self.to_cdr_as(GidLayout::Iron);
        w.raw(&bytes[4..]);
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Self::decode_as(r, GidLayout::Iron)
    }

    fn to_cdr(&self) -> Vec<u8> {
        self.to_cdr_as(GidLayout::Iron)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gid(k: u8) -> Gid {
        std::array::from_fn(|i| k.wrapping_mul(31).wrapping_add(i as u8))
    }

    fn sample() -> ParticipantEntities {
        ParticipantEntities {
            gid: gid(1),
            nodes: vec![
                NodeEntities {
                    namespace: "/".into(),
                    name: "cps".into(),
                    readers: vec![gid(2), gid(3)],
                    writers: vec![gid(4)],
                },
                NodeEntities {
                    namespace: "/arm".into(),
                    name: "x".into(),
                    readers: vec![],
                    writers: vec![],
                },
            ],
        }
    }

    #[test]
    fn both_layouts_round_trip_and_are_told_apart() {
        for layout in [GidLayout::Iron, GidLayout::Humble] {
            let bytes = sample().to_cdr_as(layout);
            let (back, seen) = ParticipantEntities::decode_any(&bytes[4..], true).unwrap();
            assert_eq!(back, sample());
            assert_eq!(seen, layout);
        }
    }

    #[test]
    fn the_iron_layout_is_rmw_dds_commons() {
        // gid (16) | count 1 | "/" (4 + 2, padded to 4) | "n" (4 + 2, padded) | 1 reader
        // gid | 0 writers.
        let p = ParticipantEntities {
            gid: [7; 16],
            nodes: vec![NodeEntities {
                namespace: "/".into(),
                name: "n".into(),
                readers: vec![[9; 16]],
                writers: vec![],
            }],
        };
        let b = p.to_cdr();
        let mut want = vec![0, 1, 0, 0];
        want.extend([7; 16]);
        want.extend(1u32.to_le_bytes());
        want.extend(2u32.to_le_bytes());
        want.extend(b"/\0\0\0");
        want.extend(2u32.to_le_bytes());
        want.extend(b"n\0\0\0");
        want.extend(1u32.to_le_bytes());
        want.extend([9; 16]);
        want.extend(0u32.to_le_bytes());
        assert_eq!(b, want);
    }

    #[test]
    fn a_thousand_nodes_are_read_and_more_than_the_bound_refused() {
        let node = |k: usize| NodeEntities {
            namespace: "/fleet".into(),
            name: format!("arm_{k}"),
            readers: vec![gid(k as u8)],
            writers: vec![
                gid((k as u8).wrapping_add(1)),
                gid((k as u8).wrapping_add(2)),
            ],
        };
        let many = ParticipantEntities {
            gid: gid(9),
            nodes: (0..1000).map(node).collect(),
        };
        let bytes = many.to_cdr();
        let (back, _) = ParticipantEntities::decode_any(&bytes[4..], true).unwrap();
        assert_eq!(back, many);
        let too_many = ParticipantEntities {
            gid: gid(9),
            nodes: (0..MAX_NODES + 1)
                .map(|_| NodeEntities::default())
                .collect(),
        };
        let bytes = too_many.to_cdr();
        let e = ParticipantEntities::decode_any(&bytes[4..], true).unwrap_err();
        assert!(
            e.to_string().contains("more than the 10000 cps keeps"),
            "{e}"
        );
    }

    #[test]
    fn malformed_samples_are_errors() {
        let bytes = sample().to_cdr();
        for cut in [0, 10, 20, bytes.len() - 8] {
            assert!(ParticipantEntities::decode_any(&bytes[4..cut.max(4)], true).is_err());
        }
        // A count of a billion nodes in a short sample.
        let mut lie = bytes[4..24].to_vec();
        lie.extend(1_000_000_000u32.to_le_bytes());
        let e = ParticipantEntities::decode_any(&lie, true).unwrap_err();
        assert!(e.to_string().contains("more than"), "{e}");
    }
}
