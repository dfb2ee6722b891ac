//! Recording a robot: `sensor_msgs/JointState` messages taken as they come and put in the
//! robot model's joint order, whatever order (or extra joints) the messages carry, with
//! every lost, malformed or incomplete message counted.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::Ros2Error;
use crate::msg::JointState;
use crate::node::{Counts, Node, Qos};

/// What to record.
#[derive(Debug, Clone)]
pub struct RecordOptions {
    /// The topic (`/joint_states`).
    pub topic: String,
    /// The joints to keep, in the order of the columns.
    pub joints: Vec<String>,
    /// How long to record, from the first message.
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

/// Records `options.topic` until `options.duration` after the first message, `stop`, or
/// no first message within `options.wait` (an error naming the topic). `progress` sees
/// the seconds recorded, about ten times a second.
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
    let mut rec = JointRecording {
        joints: options.joints.clone(),
        ..JointRecording::default()
    };
    let mut first: Option<Instant> = None;
    let mut last_seq: HashMap<[u8; 16], i64> = HashMap::new();
    let mut order: Vec<String> = Vec::new();
    let mut columns: Option<Vec<usize>> = None;
    let mut with_velocity = true;
    let mut shown = Instant::now();
    loop {
        while let Some(r) = reader.take::<JointState>() {
            if first.is_none() {
                first = Some(Instant::now());
                rec.first_message_s = start.elapsed().as_secs_f64();
            }
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
        }
        let now = Instant::now();
        match first {
            None if now - start >= options.wait => {
                return Err(Ros2Error::NoPeer(format!(
                    "no JointState arrived on {} within {:.1} s ({} publisher(s) matched{})",
                    options.topic,
                    options.wait.as_secs_f64(),
                    reader.matched(),
                    if reader.counts().malformed + reader.counts().undecodable > 0 {
                        format!(
                            "; {} sample(s) could not be read as sensor_msgs/JointState",
                            reader.counts().malformed + reader.counts().undecodable
                        )
                    } else {
                        String::new()
                    }
                )));
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
    if rec.positions.is_empty() {
        let missing: Vec<&String> = options
            .joints
            .iter()
            .filter(|j| !order.contains(j))
            .collect();
        return Err(Ros2Error::Input(format!(
            "{} message(s) on {}, none with every joint asked for: {} missing (the messages name {})",
            rec.messages,
            options.topic,
            missing
                .iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            if order.is_empty() {
                "no joints".to_string()
            } else {
                order.join(", ")
            }
        )));
    }
    Ok(rec)
}
