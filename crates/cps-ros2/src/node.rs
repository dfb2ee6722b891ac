//! A ROS 2 participant over DDS (RTPS, through `rustdds`): a node's name, namespace and
//! domain, and typed writers and readers of raw CDR samples on ROS 2's topic names.
//!
//! The bytes are cps's own ([`cps_ros2_msg::cdr`], [`cps_ros2_msg::msg`]): rustdds carries them as they
//! are, so every sample a peer sends is read by cps's bounded reader, and one that is
//! malformed, oversized or in an encoding ROS 2 does not use is counted and dropped,
//! never a panic.
//!
//! The transport is the crate's `dds` feature (on by default; `cargo install` builds
//! cps-cli with it). Without it — a build of cps that runs experiments and plans without a
//! ROS 2 graph, as the README's first command does — the same types exist and
//! [`Node::new`] says, in words, that this build has no DDS; nothing else changes.

use std::time::{Duration, Instant};

use crate::discovery::Gid;

#[cfg(not(feature = "dds"))]
#[path = "node/absent.rs"]
mod transport;
#[cfg(feature = "dds")]
#[path = "node/dds.rs"]
mod transport;

pub use transport::{Node, Reader, Vendors, Writer};

/// A reader or writer discovery has seen on the graph (its GID, DDS topic and type, QoS).
#[derive(Debug, Clone)]
pub(crate) struct DiscoveredEnd {
    pub(crate) gid: Gid,
    pub(crate) topic: String,
    pub(crate) dds_type: String,
    pub(crate) reliable: bool,
    pub(crate) transient_local: bool,
    /// A writer (else a reader).
    pub(crate) writer: bool,
}

/// The largest sample cps reads (16 MiB: a 10 s trajectory at 1 kHz for seven joints,
/// with velocities and accelerations, is 2 MiB); bigger ones are counted and dropped.
pub const MAX_SAMPLE_BYTES: usize = 16 << 20;

/// How long cps waits after it has matched a peer before it writes to it. Discovery is
/// two-sided: cps matches a peer's reader when it hears of it, the peer matches cps's
/// writer when it hears of that, and a volatile reader (a controller's subscription, a
/// service's request reader) drops what was written before its own side matched —
/// CycloneDDS's readers do, measured here: a trajectory written at once was lost every
/// time, after 0.5 s never. No RTPS message tells a writer that the reader has matched it,
/// so cps waits this long, or [`settle`]'s longer time when discovery itself was slow.
pub const DISCOVERY_SETTLE: Duration = Duration::from_millis(500);

/// The wait after a match that took `discovery_s` seconds: [`DISCOVERY_SETTLE`], or three
/// times the discovery where that is longer (a loaded machine slows both sides alike), at
/// most 3 s.
pub fn settle(discovery_s: f64) -> Duration {
    DISCOVERY_SETTLE.max(Duration::from_secs_f64((3.0 * discovery_s).min(3.0)))
}

/// How a topic's samples travel (ROS 2's QoS profiles).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Qos {
    /// Reliable, volatile, the last `depth` samples kept: ROS 2's default for topics and
    /// services.
    Reliable {
        /// History depth.
        depth: i32,
    },
    /// Reliable and transient-local (late joiners get the last `depth`): ROS 2's
    /// "latched" topics, an action's status.
    Latched {
        /// History depth.
        depth: i32,
    },
    /// Best effort: ROS 2's sensor-data profile; such a reader also hears reliable
    /// writers.
    BestEffort {
        /// History depth.
        depth: i32,
    },
}

/// A DDS implementation, by its RTPS vendor id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Vendor(pub [u8; 2]);

impl Vendor {
    /// eProsima Fast DDS (under `rmw_fastrtps_cpp`, ROS 2's default).
    pub const FAST_DDS: Vendor = Vendor([0x01, 0x0f]);
    /// Eclipse CycloneDDS (under `rmw_cyclonedds_cpp`).
    pub const CYCLONE: Vendor = Vendor([0x01, 0x10]);
    /// RTI Connext DDS (under `rmw_connextdds`).
    pub const CONNEXT: Vendor = Vendor([0x01, 0x01]);
    /// RustDDS (cps itself).
    pub const RUSTDDS: Vendor = Vendor([0x01, 0x12]);

    /// Its name as users know it.
    pub fn name(self) -> String {
        match self {
            Vendor::FAST_DDS => "Fast DDS".into(),
            Vendor::CYCLONE => "CycloneDDS".into(),
            Vendor::CONNEXT => "RTI Connext".into(),
            Vendor::RUSTDDS => "RustDDS".into(),
            Vendor([0x01, 0x02]) => "OpenDDS (OCI)".into(),
            Vendor([0x01, 0x03]) => "OpenSplice".into(),
            Vendor([0x01, 0x06]) => "GurumDDS".into(),
            Vendor([a, b]) => format!("vendor {a:02x}{b:02x}"),
        }
    }
}

/// A sample's identity on the wire: the writer's GUID and the sample's number in its
/// sequence (what DDS-RPC and Fast DDS's services use to tie a reply to its request).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleId {
    /// The writer's GID.
    pub writer: Gid,
    /// The sample's sequence number (unknown: −1 · 2^32).
    pub sequence: i64,
}

impl SampleId {
    /// RTPS's "unknown" sequence number.
    pub const UNKNOWN_SEQUENCE: i64 = (u32::MAX as i64) << 32;
}

/// Samples a reader dropped, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Read whole.
    pub read: u64,
    /// Not a valid sample of the topic's type (cut short, a lying length, not UTF-8, …).
    pub malformed: u64,
    /// Larger than [`MAX_SAMPLE_BYTES`].
    pub oversized: u64,
    /// In an encoding ROS 2 does not use, or refused by DDS before cps saw it.
    pub undecodable: u64,
}

/// One sample read: the message, who sent it and when it arrived.
#[derive(Debug)]
pub struct Received<M> {
    /// The message.
    pub message: M,
    /// When it reached this machine (ns since the Unix epoch).
    pub received_ns: u64,
    /// The writer that sent it (its DDS GUID).
    pub writer: [u8; 16],
    /// Its number in the writer's sequence (1, 2, …: a gap is a lost sample).
    pub sequence: i64,
    /// When the writer wrote it, by the writer's clock (ns since the Unix epoch), if it
    /// said (RTPS INFO_TS; every DDS sends it).
    pub source_ns: Option<u64>,
    /// The sample it answers (Fast DDS's service replies carry their request's).
    pub related: Option<SampleId>,
}

/// Polls `done` every 2 ms until it holds or `deadline` passes; whether it held.
pub fn wait_until(deadline: Instant, mut done: impl FnMut() -> bool) -> bool {
    loop {
        if done() {
            return true;
        }
        if Instant::now() >= deadline {
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}
