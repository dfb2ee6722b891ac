//! A build without DDS (the crate's `dds` feature off): the participant's types exist so
//! that everything above them compiles unchanged, and [`Node::new`] says in words that
//! this build cannot join a ROS 2 graph. No value of these types can be made, so none of
//! their methods can run.

use std::convert::Infallible;
use std::time::{Duration, Instant};

use super::{Counts, DiscoveredEnd, Qos, Received, SampleId, Vendor};
use crate::Ros2Error;
use crate::discovery::Gid;
use crate::names::NodeName;
use cps_ros2_msg::cdr::{CdrError, CdrReader};
use cps_ros2_msg::msg::Message;

/// A ROS 2 node; this build has none ([`Node::new`] says why).
#[derive(Debug)]
pub struct Node(Infallible);

/// What discovery told of the participants' vendors (none in this build).
#[derive(Debug, Clone)]
pub struct Vendors(Infallible);

/// Writes samples of one topic (none in this build).
#[derive(Debug)]
pub struct Writer(Infallible);

/// Reads samples of one topic (none in this build).
#[derive(Debug)]
pub struct Reader(Infallible);

impl Node {
    /// Refuses: this build of cps has no DDS transport.
    pub fn new(name: NodeName) -> Result<Self, Ros2Error> {
        Err(Ros2Error::Dds(format!(
            "node {}: this build of cps has no DDS transport (crate cps-ros2 without its `dds` feature, as the README's first command builds it); `cargo install --path crates/cps-cli` and the tests build it",
            name.name
        )))
    }

    /// The node's participant GID.
    pub fn gid(&self) -> Gid {
        match self.0 {}
    }

    /// The node's name.
    pub fn name(&self) -> &NodeName {
        match self.0 {}
    }

    /// What discovery told of the peers' vendors.
    pub fn vendors(&self) -> Vendors {
        match self.0 {}
    }

    /// A writer on a DDS topic.
    pub fn writer(
        &self,
        _dds_name: &str,
        _type_name: &str,
        _qos: Qos,
    ) -> Result<Writer, Ros2Error> {
        match self.0 {}
    }

    /// A reader of a DDS topic.
    pub fn reader(
        &self,
        _dds_name: &str,
        _type_name: &str,
        _qos: Qos,
    ) -> Result<Reader, Ros2Error> {
        match self.0 {}
    }

    /// A writer of `M` on a ROS 2 topic.
    pub fn publisher<M: Message>(&self, _ros_name: &str, _qos: Qos) -> Result<Writer, Ros2Error> {
        match self.0 {}
    }

    /// A reader of the graph's announcements.
    pub fn graph_reader(&self) -> Result<Reader, Ros2Error> {
        match self.0 {}
    }

    /// The readers and writers discovery has seen on the graph.
    pub(crate) fn discovered_ends(&self) -> Vec<DiscoveredEnd> {
        match self.0 {}
    }

    /// A reader of `M` on a ROS 2 topic.
    pub fn subscription<M: Message>(
        &self,
        _ros_name: &str,
        _qos: Qos,
    ) -> Result<Reader, Ros2Error> {
        match self.0 {}
    }
}

impl Vendors {
    /// The DDS vendor of the participant that holds `gid`.
    pub fn of(&self, _gid: &Gid) -> Vendor {
        match self.0 {}
    }

    /// The participants discovered so far and their vendors.
    pub fn participants(&self) -> Vec<([u8; 12], Vendor)> {
        match self.0 {}
    }
}

impl Writer {
    /// The DDS topic's name.
    pub fn topic(&self) -> &str {
        match self.0 {}
    }

    /// The writer's GID.
    pub fn gid(&self) -> Gid {
        match self.0 {}
    }

    /// Readers matched now.
    pub fn matched(&mut self) -> i32 {
        match self.0 {}
    }

    /// The readers matched now, by GID.
    pub fn matched_readers(&mut self) -> Vec<Gid> {
        match self.0 {}
    }

    /// Readers ever matched.
    pub fn matched_ever(&mut self) -> i32 {
        match self.0 {}
    }

    /// Waits until a reader is matched, or `deadline`.
    pub fn wait_matched(&mut self, _deadline: Instant) -> bool {
        match self.0 {}
    }

    /// Writes a CDR sample.
    pub fn write_cdr(&self, _sample: &[u8]) -> Result<(), Ros2Error> {
        match self.0 {}
    }

    /// Writes a body that answers `related`; its sequence number.
    pub fn write_body_related(&self, _body: &[u8], _related: SampleId) -> Result<i64, Ros2Error> {
        match self.0 {}
    }

    /// Writes a message.
    pub fn write<M: Message>(&self, _m: &M) -> Result<(), Ros2Error> {
        match self.0 {}
    }

    /// Waits until every reader acknowledged, at most `max_wait`.
    pub fn wait_acknowledged(&self, _max_wait: Duration) -> bool {
        match self.0 {}
    }
}

impl Reader {
    /// The DDS topic's name.
    pub fn topic(&self) -> &str {
        match self.0 {}
    }

    /// Writers matched now.
    pub fn matched(&mut self) -> i32 {
        match self.0 {}
    }

    /// Waits until a writer is matched, or `deadline`.
    pub fn wait_matched(&mut self, _deadline: Instant) -> bool {
        match self.0 {}
    }

    /// The reader's GID.
    pub fn gid(&self) -> Gid {
        match self.0 {}
    }

    /// An id of this reader unique on the graph.
    pub fn id(&self) -> u64 {
        match self.0 {}
    }

    /// What was read and dropped so far.
    pub fn counts(&self) -> Counts {
        match self.0 {}
    }

    /// The next sample that `decode` reads whole.
    pub fn take_with<M>(
        &mut self,
        _decode: impl FnMut(&mut CdrReader) -> Result<M, CdrError>,
    ) -> Option<Received<M>> {
        match self.0 {}
    }

    /// The next `M` that arrived whole.
    pub fn take<M: Message>(&mut self) -> Option<Received<M>> {
        match self.0 {}
    }
}
