//! The participant on a real DDS (RTPS, through `rustdds`): [`Node`], its [`Writer`]s and
//! [`Reader`]s, and what discovery says of the peers ([`Vendors`]). Built with the crate's
//! `dds` feature; without it, `absent.rs` stands in.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bytes::Bytes;
use rustdds::no_key::{Decode, DefaultDecoder, DeserializerAdapter, SerializerAdapter};
use rustdds::{
    DataReaderStatus, DataWriterStatus, DomainParticipant, DomainParticipantBuilder,
    DomainParticipantStatusEvent, DomainParticipantStatusListener, GUID, Publisher, QosPolicies,
    QosPolicyBuilder, RTPSEntity, RepresentationIdentifier, SampleIdentity, SequenceNumber,
    StatusEvented, Subscriber, TopicKind, WriteOptionsBuilder, policy,
};

use super::{Counts, DiscoveredEnd, MAX_SAMPLE_BYTES, Qos, Received, SampleId, Vendor, wait_until};
use crate::Ros2Error;
use crate::discovery::{Gid, GidLayout, NodeEntities, ParticipantEntities};
use crate::names::{NodeName, dds_topic};
use cps_ros2_msg::cdr::{CdrError, CdrReader};
use cps_ros2_msg::msg::Message;

/// A sample's body as it came (after the encapsulation header) and its byte order.
#[derive(Debug, Clone)]
struct Raw {
    little: bool,
    /// Over [`MAX_SAMPLE_BYTES`]: the body was not copied.
    oversized: bool,
    body: Vec<u8>,
}

impl Raw {
    /// The body of a little-endian sample as [`cps_ros2_msg::cdr::CdrWriter::finish`] gives it
    /// (encapsulation header first).
    fn of_sample(sample: &[u8]) -> Self {
        debug_assert_eq!(&sample[..2], &[0, 1], "a little-endian CDR sample");
        Raw {
            little: true,
            oversized: false,
            body: sample[4..].to_vec(),
        }
    }
}

/// rustdds's bridge to cps's bytes: nothing is interpreted here.
struct RawAdapter;

/// Never produced: copying bytes cannot fail.
#[derive(Debug)]
struct NoError;

impl std::fmt::Display for NoError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("no error")
    }
}

impl std::error::Error for NoError {}

impl SerializerAdapter<Raw> for RawAdapter {
    type Error = NoError;

    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }

    fn to_bytes(value: &Raw) -> Result<Bytes, NoError> {
        Ok(Bytes::copy_from_slice(&value.body))
    }
}

static ENCODINGS: [RepresentationIdentifier; 2] = [
    RepresentationIdentifier::CDR_LE,
    RepresentationIdentifier::CDR_BE,
];

impl DeserializerAdapter<Raw> for RawAdapter {
    type Error = NoError;
    type Decoded = Raw;

    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &ENCODINGS
    }

    fn transform_decoded(decoded: Raw) -> Raw {
        decoded
    }
}

#[derive(Clone)]
struct RawDecoder;

impl<'de> Decode<'de, Raw> for RawDecoder {
    type Error = NoError;

    fn decode_bytes(
        self,
        bytes: &'de [u8],
        encoding: RepresentationIdentifier,
    ) -> Result<Raw, NoError> {
        let oversized = bytes.len() > MAX_SAMPLE_BYTES;
        Ok(Raw {
            little: encoding != RepresentationIdentifier::CDR_BE,
            oversized,
            body: if oversized {
                Vec::new()
            } else {
                bytes.to_vec()
            },
        })
    }
}

impl DefaultDecoder<Raw> for RawAdapter {
    type Decoder = RawDecoder;
    const DECODER: RawDecoder = RawDecoder;
}

impl Qos {
    fn policies(self) -> QosPolicies {
        let (reliable, durability, depth) = match self {
            Qos::Reliable { depth } => (true, policy::Durability::Volatile, depth),
            Qos::Latched { depth } => (true, policy::Durability::TransientLocal, depth),
            Qos::BestEffort { depth } => (false, policy::Durability::Volatile, depth),
        };
        QosPolicyBuilder::new()
            .reliability(if reliable {
                policy::Reliability::Reliable {
                    max_blocking_time: rustdds::Duration::from_millis(100),
                }
            } else {
                policy::Reliability::BestEffort
            })
            .durability(durability)
            .history(policy::History::KeepLast { depth })
            .build()
    }
}

/// A ROS 2 node: one DDS participant in the node's domain, announced on
/// `ros_discovery_info` with every reader and writer it makes, so ROS 2's graph tools list
/// it as they list any node.
pub struct Node {
    name: NodeName,
    announcer: Arc<Announcer>,
    vendors: Vendors,
    publisher: Publisher,
    subscriber: Subscriber,
    participant: DomainParticipant,
}

/// The node's entry in `ros_discovery_info` ([`crate::discovery`]), written again whole
/// on every change (a reader or writer made or dropped).
struct Announcer {
    writer: rustdds::no_key::DataWriter<Raw, RawAdapter>,
    layout: GidLayout,
    entities: Mutex<ParticipantEntities>,
}

impl Announcer {
    fn publish(&self, entities: &ParticipantEntities) -> Result<(), Ros2Error> {
        self.writer
            .write(Raw::of_sample(&entities.to_cdr_as(self.layout)), None)
            .map_err(|e| Ros2Error::Dds(format!("announcing the node on the graph: {e:?}")))
    }

    fn change(&self, f: impl FnOnce(&mut NodeEntities)) -> Result<(), Ros2Error> {
        // A poisoned lock only means another thread panicked while editing the list; the
        // list itself is still whole.
        let mut e = self.entities.lock().unwrap_or_else(|p| p.into_inner());
        match e.nodes.first_mut() {
            Some(node) => f(node),
            // The node has left the graph: nothing more is announced.
            None => return Ok(()),
        }
        self.publish(&e)
    }

    /// Announces that the node has left (an empty list, as rmw writes when a process's last
    /// node goes), and waits a moment for the graph's readers to take it, so ROS 2's tools
    /// drop the node at once rather than when the participant's lease runs out.
    fn leave(&self) {
        let mut e = self.entities.lock().unwrap_or_else(|p| p.into_inner());
        e.nodes.clear();
        if self.publish(&e).is_ok() {
            let _ = self.writer.wait_for_acknowledgments(LEAVE_WAIT);
        }
    }
}

/// The participants discovery has told of, by GUID prefix, with their vendor ids.
struct Peers {
    status: DomainParticipantStatusListener,
    vendors: BTreeMap<[u8; 12], [u8; 2]>,
}

impl Peers {
    /// Takes discovery's news (at most a bounded number per call).
    fn drain(&mut self) {
        for _ in 0..10_000 {
            match self.status.try_recv_status() {
                Some(DomainParticipantStatusEvent::ParticipantDiscovered { dpd }) => {
                    let prefix: [u8; 12] = dpd.guid.to_bytes()[..12].try_into().expect("12 bytes");
                    self.vendors.insert(prefix, dpd.vendor_id.vendor_id);
                }
                Some(DomainParticipantStatusEvent::ParticipantLost { id, .. }) => {
                    let prefix: [u8; 12] = id.as_ref().try_into().expect("12 bytes");
                    self.vendors.remove(&prefix);
                }
                Some(_) => {}
                None => break,
            }
        }
    }
}

/// What discovery told of the participants' vendors; cloned handles share it.
#[derive(Clone)]
pub struct Vendors(Arc<Mutex<Peers>>);

impl Vendors {
    /// The DDS vendor of the participant that holds the entity `gid` (a reader, a writer
    /// or the participant itself): what its discovery said, else what its GUID's first two
    /// bytes say (Fast DDS, CycloneDDS and RustDDS put their vendor id there).
    pub fn of(&self, gid: &Gid) -> Vendor {
        let mut peers = self.0.lock().unwrap_or_else(|p| p.into_inner());
        peers.drain();
        let prefix: [u8; 12] = gid[..12].try_into().expect("12 bytes");
        match peers.vendors.get(&prefix) {
            Some(v) => Vendor(*v),
            None => Vendor([gid[0], gid[1]]),
        }
    }

    /// The participants discovered so far (their GUID prefixes) and their vendors.
    pub fn participants(&self) -> Vec<([u8; 12], Vendor)> {
        let mut peers = self.0.lock().unwrap_or_else(|p| p.into_inner());
        peers.drain();
        peers
            .vendors
            .iter()
            .map(|(k, v)| (*k, Vendor(*v)))
            .collect()
    }
}

impl SampleId {
    fn to_dds(self) -> SampleIdentity {
        SampleIdentity {
            writer_guid: GUID::from_bytes(self.writer),
            sequence_number: SequenceNumber::from(self.sequence),
        }
    }

    fn from_dds(s: SampleIdentity) -> Self {
        SampleId {
            writer: s.writer_guid.to_bytes(),
            sequence: i64::from(s.sequence_number),
        }
    }
}

/// How long a node that is dropped waits for the graph to take its leaving.
const LEAVE_WAIT: std::time::Duration = std::time::Duration::from_millis(300);

impl Drop for Node {
    fn drop(&mut self) {
        self.announcer.leave();
    }
}

/// A reader's or writer's place in the node's announcement, taken out when it is dropped.
struct Entry {
    announcer: Arc<Announcer>,
    gid: Gid,
}

impl Entry {
    fn new(announcer: &Arc<Announcer>, gid: Gid, reader: bool) -> Result<Self, Ros2Error> {
        announcer.change(|n| {
            if reader {
                n.readers.push(gid)
            } else {
                n.writers.push(gid)
            }
        })?;
        Ok(Entry {
            announcer: announcer.clone(),
            gid,
        })
    }
}

impl Drop for Entry {
    fn drop(&mut self) {
        let gid = self.gid;
        // Best effort: a participant going away takes its announcement with it anyway.
        let _ = self.announcer.change(|n| {
            n.readers.retain(|g| *g != gid);
            n.writers.retain(|g| *g != gid);
        });
    }
}

impl std::fmt::Debug for Node {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Node").field("name", &self.name).finish()
    }
}

impl Node {
    /// Joins the node's DDS domain (discovery starts at once, in rustdds's threads).
    pub fn new(name: NodeName) -> Result<Self, Ros2Error> {
        let dds = |what: &str, e: String| Ros2Error::Dds(format!("{what}: {e}"));
        let participant = DomainParticipantBuilder::new(name.domain)
            .build()
            .map_err(|e| {
                dds(
                    &format!("joining DDS domain {}", name.domain),
                    format!("{e:?}"),
                )
            })?;
        let qos = QosPolicies::qos_none();
        let publisher = participant
            .create_publisher(&qos)
            .map_err(|e| dds("a publisher", format!("{e:?}")))?;
        let subscriber = participant
            .create_subscriber(&qos)
            .map_err(|e| dds("a subscriber", format!("{e:?}")))?;
        let announce_qos = Qos::Latched { depth: 1 }.policies();
        let topic = participant
            .create_topic(
                crate::discovery::TOPIC.to_string(),
                <ParticipantEntities as Message>::TYPE.to_string(),
                &announce_qos,
                TopicKind::NoKey,
            )
            .map_err(|e| dds("the graph's topic", format!("{e:?}")))?;
        let writer = publisher
            .create_datawriter_no_key::<Raw, RawAdapter>(&topic, Some(announce_qos))
            .map_err(|e| dds("the graph's writer", format!("{e:?}")))?;
        let announcer = Arc::new(Announcer {
            writer,
            layout: GidLayout::from_distro(std::env::var("ROS_DISTRO").ok().as_deref()),
            entities: Mutex::new(ParticipantEntities {
                gid: participant.guid().to_bytes(),
                nodes: vec![NodeEntities {
                    namespace: name.namespace.clone(),
                    name: name.name.clone(),
                    readers: Vec::new(),
                    writers: Vec::new(),
                }],
            }),
        });
        announcer.change(|_| ())?;
        let vendors = Vendors(Arc::new(Mutex::new(Peers {
            status: participant.status_listener(),
            vendors: BTreeMap::new(),
        })));
        Ok(Node {
            name,
            announcer,
            vendors,
            publisher,
            subscriber,
            participant,
        })
    }

    /// The participant's GID (its GUID), as the graph names it.
    pub fn gid(&self) -> Gid {
        self.participant.guid().to_bytes()
    }

    /// The node's name, namespace and domain.
    pub fn name(&self) -> &NodeName {
        &self.name
    }

    /// The participants' vendors, as discovery tells them (shared: a handle that stays
    /// current).
    pub fn vendors(&self) -> Vendors {
        self.vendors.clone()
    }

    fn topic(
        &self,
        dds_name: &str,
        type_name: &str,
        qos: Qos,
    ) -> Result<rustdds::Topic, Ros2Error> {
        self.participant
            .create_topic(
                dds_name.to_string(),
                type_name.to_string(),
                &qos.policies(),
                TopicKind::NoKey,
            )
            .map_err(|e| Ros2Error::Dds(format!("topic {dds_name}: {e:?}")))
    }

    /// A writer of `type_name` samples on the DDS topic `dds_name` (`rt/…`, `rq/…`).
    pub fn writer(&self, dds_name: &str, type_name: &str, qos: Qos) -> Result<Writer, Ros2Error> {
        let topic = self.topic(dds_name, type_name, qos)?;
        let inner = self
            .publisher
            .create_datawriter_no_key::<Raw, RawAdapter>(&topic, Some(qos.policies()))
            .map_err(|e| Ros2Error::Dds(format!("a writer on {dds_name}: {e:?}")))?;
        let entry = Entry::new(&self.announcer, inner.guid().to_bytes(), false)?;
        Ok(Writer {
            inner,
            _entry: entry,
            topic: dds_name.to_string(),
            matched: 0,
            ever: 0,
            readers: BTreeSet::new(),
        })
    }

    /// A reader of `type_name` samples on the DDS topic `dds_name`.
    pub fn reader(&self, dds_name: &str, type_name: &str, qos: Qos) -> Result<Reader, Ros2Error> {
        let topic = self.topic(dds_name, type_name, qos)?;
        let inner = self
            .subscriber
            .create_simple_datareader_no_key::<Raw, RawAdapter>(&topic, Some(qos.policies()))
            .map_err(|e| Ros2Error::Dds(format!("a reader on {dds_name}: {e:?}")))?;
        let entry = Entry::new(&self.announcer, inner.guid().to_bytes(), true)?;
        Ok(Reader {
            inner,
            _entry: Some(entry),
            topic: dds_name.to_string(),
            matched: 0,
            counts: Counts::default(),
        })
    }

    /// A publisher of `M` on the ROS topic `ros_name` (resolved in the node's namespace).
    pub fn publisher<M: Message>(&self, ros_name: &str, qos: Qos) -> Result<Writer, Ros2Error> {
        let t = dds_topic(&self.name, ros_name)?;
        self.writer(&t, M::TYPE, qos)
    }

    /// A reader of the graph's announcements (`ros_discovery_info`), which, as rmw's own,
    /// is no node's and is not announced.
    pub fn graph_reader(&self) -> Result<Reader, Ros2Error> {
        let qos = Qos::Latched { depth: 1000 };
        let topic = self.topic(crate::discovery::TOPIC, ParticipantEntities::TYPE, qos)?;
        let inner = self
            .subscriber
            .create_simple_datareader_no_key::<Raw, RawAdapter>(&topic, Some(qos.policies()))
            .map_err(|e| Ros2Error::Dds(format!("a reader of the graph: {e:?}")))?;
        Ok(Reader {
            inner,
            _entry: None,
            topic: crate::discovery::TOPIC.to_string(),
            matched: 0,
            counts: Counts::default(),
        })
    }

    /// The readers and writers discovery has seen on the graph.
    pub(crate) fn discovered_ends(&self) -> Vec<DiscoveredEnd> {
        let end = |gid: GUID, topic: &str, dds_type: &str, q: QosPolicies, writer| DiscoveredEnd {
            gid: gid.to_bytes(),
            topic: topic.to_string(),
            dds_type: dds_type.to_string(),
            reliable: q.is_reliable(),
            transient_local: !q.is_volatile(),
            writer,
        };
        let dp = &self.participant;
        let writers = dp.discovered_writers().into_iter().map(|w| {
            let d = &w.publication_topic_data;
            end(d.key, &d.topic_name, &d.type_name, d.qos(), true)
        });
        let readers = dp.discovered_readers().into_iter().map(|r| {
            let d = &r.subscription_topic_data;
            end(d.key(), d.topic_name(), d.type_name(), d.qos(), false)
        });
        writers.chain(readers).collect()
    }

    /// A subscription to `M` on the ROS topic `ros_name`.
    pub fn subscription<M: Message>(&self, ros_name: &str, qos: Qos) -> Result<Reader, Ros2Error> {
        let t = dds_topic(&self.name, ros_name)?;
        self.reader(&t, M::TYPE, qos)
    }
}

/// Writes samples of one topic.
pub struct Writer {
    inner: rustdds::no_key::DataWriter<Raw, RawAdapter>,
    _entry: Entry,
    topic: String,
    matched: i32,
    ever: i32,
    readers: BTreeSet<Gid>,
}

impl Writer {
    /// The DDS topic's name.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// The writer's GID (its DDS GUID).
    pub fn gid(&self) -> Gid {
        self.inner.guid().to_bytes()
    }

    /// Readers matched now (discovery's news taken first).
    pub fn matched(&mut self) -> i32 {
        while let Some(s) = self.inner.try_recv_status() {
            if let DataWriterStatus::PublicationMatched {
                current,
                total,
                reader,
            } = s
            {
                self.matched = current.count();
                self.ever = total.count();
                if current.count_change() > 0 {
                    self.readers.insert(reader.to_bytes());
                } else if current.count_change() < 0 {
                    self.readers.remove(&reader.to_bytes());
                }
            }
        }
        self.matched
    }

    /// The readers matched now, by GID.
    pub fn matched_readers(&mut self) -> Vec<Gid> {
        self.matched();
        self.readers.iter().copied().collect()
    }

    /// Readers matched at any time so far (those gone included).
    pub fn matched_ever(&mut self) -> i32 {
        self.matched();
        self.ever
    }

    /// Waits until a reader is matched, or `deadline`; whether one is.
    pub fn wait_matched(&mut self, deadline: Instant) -> bool {
        wait_until(deadline, || self.matched() > 0)
    }

    /// Sends one sample (its bytes as [`cps_ros2_msg::cdr::CdrWriter::finish`] gives them,
    /// little-endian encapsulation header first).
    pub fn write_cdr(&self, sample: &[u8]) -> Result<(), Ros2Error> {
        self.inner
            .write(Raw::of_sample(sample), None)
            .map_err(|e| Ros2Error::Dds(format!("writing on {}: {e:?}", self.topic)))
    }

    /// Sends one sample's body (CDR, little-endian, without the encapsulation header) with
    /// `related` as its related sample identity (inline QoS `PID_RELATED_SAMPLE_IDENTITY`,
    /// both 0x0083 and Fast DDS's older 0x800f); the sample's own sequence number.
    pub fn write_body_related(&self, body: &[u8], related: SampleId) -> Result<i64, Ros2Error> {
        let options = WriteOptionsBuilder::new()
            .related_sample_identity(related.to_dds())
            .build();
        let id = self
            .inner
            .write_with_options(
                Raw {
                    little: true,
                    oversized: false,
                    body: body.to_vec(),
                },
                options,
            )
            .map_err(|e| Ros2Error::Dds(format!("writing on {}: {e:?}", self.topic)))?;
        Ok(i64::from(id.sequence_number))
    }

    /// Sends one message.
    pub fn write<M: Message>(&self, m: &M) -> Result<(), Ros2Error> {
        self.write_cdr(&m.to_cdr())
    }

    /// Waits until every matched reliable reader has acknowledged what was written, or
    /// `max_wait`; whether they did.
    pub fn wait_acknowledged(&self, max_wait: Duration) -> bool {
        self.inner
            .wait_for_acknowledgments(max_wait)
            .unwrap_or(false)
    }
}

/// Reads samples of one topic.
pub struct Reader {
    inner: rustdds::no_key::SimpleDataReader<Raw, RawAdapter>,
    _entry: Option<Entry>,
    topic: String,
    matched: i32,
    counts: Counts,
}

impl Reader {
    /// The DDS topic's name.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// Writers matched now.
    pub fn matched(&mut self) -> i32 {
        while let Some(s) = self.inner.try_recv_status() {
            if let DataReaderStatus::SubscriptionMatched { current, .. } = s {
                self.matched = current.count();
            }
        }
        self.matched
    }

    /// Waits until a writer is matched, or `deadline`; whether one is.
    pub fn wait_matched(&mut self, deadline: Instant) -> bool {
        wait_until(deadline, || self.matched() > 0)
    }

    /// The reader's GID (its DDS GUID).
    pub fn gid(&self) -> Gid {
        self.inner.guid().to_bytes()
    }

    /// An id of this reader unique on the graph: the low 8 bytes of its DDS GUID.
    pub fn id(&self) -> u64 {
        let g = self.inner.guid().to_bytes();
        u64::from_le_bytes(g[8..16].try_into().expect("8 bytes"))
    }

    /// What was read and dropped so far.
    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// The next sample that `decode` reads whole, if one has arrived; those it cannot
    /// read are counted and skipped.
    pub fn take_with<M>(
        &mut self,
        mut decode: impl FnMut(&mut CdrReader) -> Result<M, CdrError>,
    ) -> Option<Received<M>> {
        self.inner.drain_read_notifications();
        // At most this many dropped samples per call, so a flood cannot hold the caller.
        for _ in 0..10_000 {
            let change = match self.inner.try_take_one() {
                Ok(Some(c)) => c,
                Ok(None) => return None,
                Err(_) => {
                    self.counts.undecodable += 1;
                    continue;
                }
            };
            let received_ns = ticks_to_nanos(change.receive_instant.to_ticks());
            let writer = change.writer_guid.to_bytes();
            let sequence = i64::from(change.sequence_number);
            let source_ns = change
                .source_timestamp()
                .map(|t| ticks_to_nanos(t.to_ticks()));
            let related = change.related_sample_identity().map(SampleId::from_dds);
            let raw = change.into_value();
            if raw.oversized {
                self.counts.oversized += 1;
                continue;
            }
            match decode(&mut CdrReader::new(&raw.body, raw.little)) {
                Ok(message) => {
                    self.counts.read += 1;
                    return Some(Received {
                        message,
                        received_ns,
                        writer,
                        sequence,
                        source_ns,
                        related,
                    });
                }
                Err(_) => self.counts.malformed += 1,
            }
        }
        None
    }

    /// The next `M` that arrived whole, if any.
    pub fn take<M: Message>(&mut self) -> Option<Received<M>> {
        self.take_with(M::decode)
    }
}

/// RTPS time (seconds in the high 32 bits, 2^-32 s in the low ones) in nanoseconds.
fn ticks_to_nanos(ticks: u64) -> u64 {
    (ticks >> 32) * 1_000_000_000 + (((ticks & 0xffff_ffff) * 1_000_000_000) >> 32)
}
