//! Recording a robot: `sensor_msgs/JointState` messages taken as they come and put in the
//! robot model's joint order, whatever order (or extra joints) the messages carry, with
//! every lost, malformed or incomplete message counted.
//!
//! A recording holds what was **published while it ran**. A publisher may hand a reader
//! that joins late the samples it still keeps (a transient-local writer must; Fast DDS's
//! reliable writers answer a late reader's requests for them too): seconds of the past,
//! arriving in a burst. Each sample's publication time is its DATA's source timestamp
//! (the writer's clock) moved onto this machine's clock by that writer's offset, the
//! smallest arrival-minus-source difference seen from it (a sample that came straight
//! from the writer, latency only; this holds across machines whose clocks disagree).
//! Samples published before the recording began are dropped and counted (`older`); the
//! header stamps, which may run on a robot's own clock, are not used for this.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::Ros2Error;
use crate::node::{Counts, Node, Qos};
use cps_ros2_msg::msg::JointState;

/// What to record.
#[derive(Debug, Clone)]
pub struct RecordOptions {
    /// The topic (`/joint_states`).
    pub topic: String,
    /// The joints to keep, in the order of the columns.
    pub joints: Vec<String>,
    /// How long to record, from the first message published after the recording began.
    pub duration: Duration,
    /// How long to wait for the first message.
    pub wait: Duration,
    /// Best effort (hears every publisher, may lose samples) or reliable (hears reliable
    /// publishers only, loses none they keep).
    pub qos: Qos,
}

/// A recording of joint states.
#[derive(Debug, Clone, Default)]
pub struct JointRecording {
    /// The joints, in column order.
    pub joints: Vec<String>,
    /// Each kept message's header stamp (ns; 0 where the publisher sent none).
    pub stamps_ns: Vec<u64>,
    /// When each kept message arrived (ns since the Unix epoch).
    pub received_ns: Vec<u64>,
    /// Positions, one row per kept message, in `joints`' order.
    pub positions: Vec<Vec<f64>>,
    /// Velocities likewise, where every message carried them (else empty).
    pub velocities: Vec<Vec<f64>>,
    /// Seconds from the start until the first message.
    pub first_message_s: f64,
    /// Messages read whole.
    pub messages: u64,
    /// Messages without one of `joints` (or with a NaN position), not kept.
    pub incomplete: u64,
    /// Messages a publisher sent that never arrived (gaps in its sequence numbers).
    pub lost: u64,
    /// Messages published before the recording began (a publisher's history handed to
    /// a reader that joined late), not kept.
    pub older: u64,
    /// Samples dropped unread (malformed, oversized, undecodable).
    pub dropped: Counts,
    /// Whether the recording was stopped early.
    pub stopped: bool,
}

impl JointRecording {
    /// Times in seconds from the first kept message: the header stamps when every
    /// message has one and they increase, else the arrival times. The second value says
    /// which ("stamp" or "arrival").
    pub fn times(&self) -> (Vec<f64>, &'static str) {
        let stamped =
            self.stamps_ns.iter().all(|&s| s > 0) && self.stamps_ns.windows(2).all(|w| w[1] > w[0]);
        let src = if stamped {
            &self.stamps_ns
        } else {
            &self.received_ns
        };
        let t0 = src.first().copied().unwrap_or(0);
        (
            src.iter()
                .map(|&s| s.saturating_sub(t0) as f64 * 1e-9)
                .collect(),
            if stamped { "stamp" } else { "arrival" },
        )
    }
}

/// A kept message's place in time: which writer, when it was published (the writer's
/// clock) and when it arrived (this machine's).
#[derive(Debug, Clone, Copy)]
struct When {
    writer: usize,
    source_ns: Option<u64>,
    received_ns: u64,
}

/// Per writer, the smallest arrival-minus-source difference seen: its clock's offset from
/// this machine's plus the shortest latency.
#[derive(Debug, Default)]
struct Offsets {
    writers: Vec<[u8; 16]>,
    offset: Vec<Option<i128>>,
}

impl Offsets {
    fn index(&mut self, writer: [u8; 16]) -> usize {
        match self.writers.iter().position(|w| *w == writer) {
            Some(i) => i,
            None => {
                self.writers.push(writer);
                self.offset.push(None);
                self.writers.len() - 1
            }
        }
    }

    /// Takes a sample's times in; whether its writer's offset became smaller.
    fn see(&mut self, w: When) -> bool {
        let Some(src) = w.source_ns else { return false };
        let d = w.received_ns as i128 - src as i128;
        let o = &mut self.offset[w.writer];
        if o.is_none_or(|o| d < o) {
            *o = Some(d);
            true
        } else {
            false
        }
    }

    /// When the sample was published, on this machine's clock (its arrival when its
    /// writer sent no source timestamps).
    fn published(&self, w: When) -> i128 {
        match (w.source_ns, self.offset[w.writer]) {
            (Some(src), Some(o)) => src as i128 + o,
            _ => w.received_ns as i128,
        }
    }
}

/// The first publication time at or after `start` among `whens`.
fn first_published(offsets: &Offsets, whens: &[When], start: i128) -> Option<i128> {
    whens
        .iter()
        .map(|&w| offsets.published(w))
        .filter(|&p| p >= start)
        .min()
}

fn now_ns() -> i128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i128)
}

/// Records `options.topic` until `options.duration` after the first message published
/// since the recording began, `stop`, or no such message within `options.wait` (an error
/// naming the topic). `progress` sees the seconds recorded, about ten times a second.
pub fn record_joint_states(
    node: &Node,
    options: &RecordOptions,
    stop: &AtomicBool,
    mut progress: impl FnMut(f64),
) -> Result<JointRecording, Ros2Error> {
    if options.joints.is_empty() {
        return Err(Ros2Error::Input("no joints to record".into()));
    }
    let mut reader = node.subscription::<JointState>(&options.topic, options.qos)?;
    let start = Instant::now();
    let start_ns = now_ns();
    let mut offsets = Offsets::default();
    let mut whens: Vec<When> = Vec::new();
    // The first publication since the start (this machine's clock), as known so far.
    let mut first_ns: Option<i128> = None;
    let mut rec = JointRecording {
        joints: options.joints.clone(),
        ..JointRecording::default()
    };
    let mut last_seq: HashMap<[u8; 16], i64> = HashMap::new();
    let mut order: Vec<String> = Vec::new();
    let mut columns: Option<Vec<usize>> = None;
    let mut with_velocity = true;
    let mut shown = Instant::now();
    loop {
        let mut moved = false;
        while let Some(r) = reader.take::<JointState>() {
            rec.messages += 1;
            if let Some(prev) = last_seq.insert(r.writer, r.sequence)
                && r.sequence > prev + 1
            {
                rec.lost += (r.sequence - prev - 1) as u64;
            }
            let m = r.message;
            if m.name != order {
                order = m.name.clone();
                columns = options
                    .joints
                    .iter()
                    .map(|j| order.iter().position(|n| n == j))
                    .collect();
            }
            let Some(cols) = &columns else {
                rec.incomplete += 1;
                continue;
            };
            if m.position.len() != m.name.len() || cols.iter().any(|&c| !m.position[c].is_finite())
            {
                rec.incomplete += 1;
                continue;
            }
            rec.positions
                .push(cols.iter().map(|&c| m.position[c]).collect());
            if with_velocity && m.velocity.len() == m.name.len() {
                rec.velocities
                    .push(cols.iter().map(|&c| m.velocity[c]).collect());
            } else {
                with_velocity = false;
            }
            let s = m.header.stamp;
            rec.stamps_ns.push(if s.sec < 0 {
                0
            } else {
                s.sec as u64 * 1_000_000_000 + s.nanosec as u64
            });
            rec.received_ns.push(r.received_ns);
            let when = When {
                writer: offsets.index(r.writer),
                source_ns: r.source_ns,
                received_ns: r.received_ns,
            };
            moved |= offsets.see(when);
            whens.push(when);
            let p = offsets.published(when);
            if p >= start_ns && first_ns.is_none_or(|f| p < f) {
                first_ns = Some(p);
            }
        }
        if moved {
            // A writer's offset shrank: samples thought recent may be older.
            first_ns = first_published(&offsets, &whens, start_ns);
        }
        let now = Instant::now();
        let first = first_ns.map(|f| {
            let since = Duration::from_nanos((now_ns() - f).max(0) as u64);
            now.checked_sub(since).unwrap_or(start)
        });
        match first {
            None if now - start >= options.wait => {
                let unreadable = reader.counts().malformed + reader.counts().undecodable;
                return Err(nothing_published(
                    options,
                    reader.matched(),
                    &rec,
                    unreadable,
                ));
            }
            Some(f) if now - f >= options.duration => break,
            _ => {}
        }
        if stop.load(Ordering::Relaxed) {
            rec.stopped = true;
            break;
        }
        if now - shown >= Duration::from_millis(100) {
            shown = now;
            progress(first.map_or(0.0, |f| (now - f).as_secs_f64()));
        }
        std::thread::sleep(Duration::from_micros(500));
    }
    if !with_velocity {
        rec.velocities.clear();
    }
    rec.dropped = reader.counts();
    keep_window(&mut rec, &offsets, &whens, start_ns, options.duration);
    if rec.positions.is_empty() {
        return Err(no_joints_asked(options, &rec, &order));
    }
    Ok(rec)
}

/// No JointState published on the topic since the recording began, within its wait:
/// what came instead (`matched` publishers, `unreadable` samples).
fn nothing_published(
    options: &RecordOptions,
    matched: i32,
    rec: &JointRecording,
    unreadable: u64,
) -> Ros2Error {
    Ros2Error::NoPeer(format!(
        "no JointState published on {} within {:.1} s of the recording's start ({matched} publisher(s) matched{}{})",
        options.topic,
        options.wait.as_secs_f64(),
        if rec.messages > 0 {
            format!(
                "; {} message(s) came, all published before the recording began (a publisher's history)",
                rec.messages
            )
        } else {
            String::new()
        },
        if unreadable > 0 {
            format!("; {unreadable} sample(s) could not be read as sensor_msgs/JointState")
        } else {
            String::new()
        }
    ))
}

/// Messages came, none naming every joint asked for: which are missing, and what the
/// messages name (`order`).
fn no_joints_asked(options: &RecordOptions, rec: &JointRecording, order: &[String]) -> Ros2Error {
    let missing: Vec<&str> = options
        .joints
        .iter()
        .filter(|j| !order.contains(j))
        .map(String::as_str)
        .collect();
    Ros2Error::Input(format!(
        "{} message(s) on {}, none with every joint asked for: {} missing (the messages name {})",
        rec.messages,
        options.topic,
        missing.join(", "),
        if order.is_empty() {
            "no joints".to_string()
        } else {
            order.join(", ")
        }
    ))
}

/// Keeps the messages published from the first one since `start_ns` for `duration`;
/// counts those published before as `older`.
fn keep_window(
    rec: &mut JointRecording,
    offsets: &Offsets,
    whens: &[When],
    start_ns: i128,
    duration: Duration,
) {
    let Some(first) = first_published(offsets, whens, start_ns) else {
        rec.older = whens.len() as u64;
        rec.positions.clear();
        rec.velocities.clear();
        rec.stamps_ns.clear();
        rec.received_ns.clear();
        return;
    };
    let end = first + duration.as_nanos() as i128;
    let keep: Vec<bool> = whens
        .iter()
        .map(|&w| {
            let p = offsets.published(w);
            p >= first && p <= end
        })
        .collect();
    rec.older = whens
        .iter()
        .filter(|&&w| offsets.published(w) < start_ns)
        .count() as u64;
    let first_kept = whens
        .iter()
        .zip(&keep)
        .find(|(_, k)| **k)
        .map(|(w, _)| w.received_ns);
    if let Some(f) = first_kept {
        rec.first_message_s = ((f as i128 - start_ns).max(0) as f64) * 1e-9;
    }
    fn filter<T>(v: &mut Vec<T>, keep: &[bool]) {
        if v.len() == keep.len() {
            let mut k = keep.iter();
            v.retain(|_| *k.next().expect("one flag per row"));
        }
    }
    filter(&mut rec.positions, &keep);
    filter(&mut rec.velocities, &keep);
    filter(&mut rec.stamps_ns, &keep);
    filter(&mut rec.received_ns, &keep);
}
