//! A client of a ROS 2 service, on either of the two ways rmw implementations tie a reply
//! to its request:
//!
//! - **CycloneDDS's** (`rmw_cyclonedds_cpp`): every request and reply begins with a 16-byte
//!   header, the client's 64-bit id and the request's 64-bit sequence number, which the
//!   server copies into its reply.
//! - **Fast DDS's** (`rmw_fastrtps_cpp`, ROS 2's default): the payload is the bare request;
//!   the request carries, as inline QoS (`PID_RELATED_SAMPLE_IDENTITY`, 0x0083 and the
//!   legacy 0x800f), the GUID of the client's reply reader; the server's reply carries the
//!   identity of the request: that GUID (or the request writer's) and the sequence number
//!   of the DATA that brought the request.
//!
//! A client must speak its server's: [`MappingChoice::Auto`] picks it from the vendor of
//! the participant whose request reader was matched (eProsima: Fast DDS's, anything else:
//! Cyclone's); [`MappingChoice::Force`] overrides it. The header is always 16 bytes, a
//! multiple of CDR's largest alignment, so a message's body is encoded once and carried
//! either way unchanged.

use std::time::{Duration, Instant};

use crate::Ros2Error;
use crate::names::dds_service;
use crate::node::{Counts, Node, Qos, Reader, SampleId, Vendor, Vendors, Writer, wait_until};
use cps_ros2_msg::cdr::{CdrError, CdrReader, CdrWriter};

/// How a service's replies are tied to their requests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mapping {
    /// A 16-byte header in the payload (rmw_cyclonedds).
    Cyclone,
    /// The request's identity as inline QoS (rmw_fastrtps).
    FastDds,
}

impl Mapping {
    /// The word for it (`cyclone`, `fastdds`).
    pub fn word(self) -> &'static str {
        match self {
            Mapping::Cyclone => "cyclone",
            Mapping::FastDds => "fastdds",
        }
    }

    /// The mapping a server of `vendor` speaks.
    pub fn of(vendor: Vendor) -> Self {
        if vendor == Vendor::FAST_DDS {
            Mapping::FastDds
        } else {
            Mapping::Cyclone
        }
    }
}

/// Which mapping a client speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MappingChoice {
    /// The server's, told by its participant's vendor.
    #[default]
    Auto,
    /// This one, whatever the server.
    Force(Mapping),
}

impl std::str::FromStr for MappingChoice {
    type Err = Ros2Error;

    fn from_str(s: &str) -> Result<Self, Ros2Error> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(MappingChoice::Auto),
            "cyclone" | "cyclonedds" => Ok(MappingChoice::Force(Mapping::Cyclone)),
            "fastdds" | "fastrtps" | "fast-dds" => Ok(MappingChoice::Force(Mapping::FastDds)),
            other => Err(Ros2Error::Input(format!(
                "service mapping `{other}`: give auto, cyclone or fastdds"
            ))),
        }
    }
}

/// rmw_cyclonedds's header before every service request and reply.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RequestHeader {
    /// The client (the last 8 bytes of its reply reader's GUID).
    pub client: u64,
    /// The request's number, from 1.
    pub sequence: i64,
}

/// The header's size on the wire.
pub const HEADER_BYTES: usize = 16;

/// A request on its way: how to know its reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pending {
    /// The header the reply must carry.
    Cyclone(RequestHeader),
    /// The sequence number of the DATA that carried the request.
    FastDds(i64),
}

/// A request's sample as Cyclone's mapping sends it: `header`, then the body `encode`
/// writes (Fast DDS's mapping sends the same bytes without the header).
pub fn request_sample(header: RequestHeader, encode: impl FnOnce(&mut CdrWriter)) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.u64(header.client).u64(header.sequence as u64);
    encode(&mut w);
    w.finish()
}

/// A client of one service.
pub struct ServiceClient {
    name: String,
    request: Writer,
    reply: Reader,
    choice: MappingChoice,
    vendors: Vendors,
    client: u64,
    sequence: i64,
}

impl ServiceClient {
    /// A client of the service `name` whose request and reply have the DDS types
    /// `request_type` and `reply_type` (`example_interfaces::srv::dds_::AddTwoInts_Request_`).
    pub fn new(
        node: &Node,
        name: &str,
        request_type: &str,
        reply_type: &str,
        choice: MappingChoice,
    ) -> Result<Self, Ros2Error> {
        let (rq, rr) = dds_service(node.name(), name)?;
        let qos = Qos::Reliable { depth: 100 };
        let request = node.writer(&rq, request_type, qos)?;
        let reply = node.reader(&rr, reply_type, qos)?;
        let client = reply.id();
        Ok(ServiceClient {
            name: name.to_string(),
            request,
            reply,
            choice,
            vendors: node.vendors(),
            client,
            sequence: 0,
        })
    }

    /// The service's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether a server's request reader and reply writer are both matched.
    pub fn ready(&mut self) -> bool {
        self.request.matched() > 0 && self.reply.matched() > 0
    }

    /// What of a server was found (`requests`, `replies`), for a sentence when only part
    /// of it was.
    pub fn found(&mut self) -> Vec<&'static str> {
        let mut f = Vec::new();
        if self.request.matched() > 0 {
            f.push("requests");
        }
        if self.reply.matched() > 0 {
            f.push("replies");
        }
        f
    }

    /// The mapping this client speaks now: forced, or the matched server's (Cyclone's
    /// while none is matched).
    pub fn mapping(&mut self) -> Mapping {
        match self.choice {
            MappingChoice::Force(m) => m,
            MappingChoice::Auto => self
                .request
                .matched_readers()
                .first()
                .map_or(Mapping::Cyclone, |g| Mapping::of(self.vendors.of(g))),
        }
    }

    /// Sends a request whose body (CDR, no encapsulation header) `encode` writes.
    pub fn send(&mut self, encode: impl FnOnce(&mut CdrWriter)) -> Result<Pending, Ros2Error> {
        let mapping = self.mapping();
        self.sequence += 1;
        let header = RequestHeader {
            client: self.client,
            sequence: self.sequence,
        };
        let sample = request_sample(header, encode);
        match mapping {
            Mapping::Cyclone => {
                self.request.write_cdr(&sample)?;
                Ok(Pending::Cyclone(header))
            }
            Mapping::FastDds => {
                let related = SampleId {
                    writer: self.reply.gid(),
                    sequence: SampleId::UNKNOWN_SEQUENCE,
                };
                let seq = self
                    .request
                    .write_body_related(&sample[4 + HEADER_BYTES..], related)?;
                Ok(Pending::FastDds(seq))
            }
        }
    }

    /// The reply to `pending`, if it has come, read by `decode` (the body after any
    /// header); replies to other requests and other clients are skipped, a reply that
    /// does not read is counted as malformed.
    pub fn take_reply<M>(
        &mut self,
        pending: Pending,
        mut decode: impl FnMut(&mut CdrReader) -> Result<M, CdrError>,
    ) -> Option<M> {
        let mine = [self.reply.gid(), self.request.gid()];
        match pending {
            Pending::Cyclone(header) => {
                // The header is read first; another request's reply is dropped before its
                // body is read.
                let mut matched = None;
                while let Some(r) = self.reply.take_with(|r| {
                    let h = RequestHeader {
                        client: r.u64("request header")?,
                        sequence: r.i64("request header")?,
                    };
                    if h != header {
                        return Ok(None);
                    }
                    decode(r).map(Some)
                }) {
                    if let Some(m) = r.message {
                        matched = Some(m);
                        break;
                    }
                }
                matched
            }
            Pending::FastDds(seq) => {
                let mut matched = None;
                while let Some(r) = self.reply.take_with(|r| decode(r).map(Some)) {
                    let ours = r
                        .related
                        .is_some_and(|id| id.sequence == seq && mine.contains(&id.writer));
                    if ours {
                        matched = r.message;
                        break;
                    }
                }
                matched
            }
        }
    }

    /// Waits for the reply to `pending` until `deadline`.
    pub fn wait_reply<M>(
        &mut self,
        pending: Pending,
        deadline: Instant,
        mut decode: impl FnMut(&mut CdrReader) -> Result<M, CdrError>,
    ) -> Option<M> {
        loop {
            if let Some(m) = self.take_reply(pending, &mut decode) {
                return Some(m);
            }
            if Instant::now() >= deadline {
                return None;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Waits until a server is matched, or `deadline`; whether one is.
    pub fn wait_for_server(&mut self, deadline: Instant) -> bool {
        wait_until(deadline, || self.ready())
    }

    /// What the reply reader dropped.
    pub fn counts(&self) -> Counts {
        self.reply.counts()
    }
}
