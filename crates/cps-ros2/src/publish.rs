//! One message to a topic, delivered: the writer waits until a subscriber is matched and
//! [`DISCOVERY_SETTLE`](crate::node::DISCOVERY_SETTLE) more (a message written before the subscriber has matched the
//! writer in turn is lost on a volatile topic), writes, and waits until the reliable
//! subscribers have acknowledged it.

use std::time::{Duration, Instant};

use crate::Ros2Error;
use crate::node::{Node, Qos, settle};
use cps_ros2_msg::msg::Message;

/// How a message went out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Published {
    /// Seconds until a subscriber was matched.
    pub matched_after_s: f64,
    /// Subscribers matched when it was written.
    pub subscribers: i32,
    /// Whether every reliable subscriber acknowledged it in time.
    pub acknowledged: bool,
    /// Its size on the wire (bytes, the CDR header included).
    pub bytes: usize,
}

/// Publishes `message` on `topic` with `qos` once a subscriber is matched (within
/// `wait`, else an error naming the topic) and [`DISCOVERY_SETTLE`](crate::node::DISCOVERY_SETTLE) has passed, then waits up to `wait` again for its
/// acknowledgement. [`Qos::Reliable`] for a command (a controller's `joint_trajectory`),
/// [`Qos::Latched`] for what late subscribers should see too (markers).
pub fn publish<M: Message>(
    node: &Node,
    topic: &str,
    message: &M,
    qos: Qos,
    wait: Duration,
) -> Result<Published, Ros2Error> {
    let mut writer = node.publisher::<M>(topic, qos)?;
    let start = Instant::now();
    if !writer.wait_matched(start + wait) {
        return Err(Ros2Error::NoPeer(format!(
            "no subscriber to {topic} ({}) appeared within {:.1} s (is the controller active, on this ROS_DOMAIN_ID?)",
            M::TYPE,
            wait.as_secs_f64()
        )));
    }
    let matched_after_s = start.elapsed().as_secs_f64();
    std::thread::sleep(settle(matched_after_s));
    let bytes = message.to_cdr();
    writer.write_cdr(&bytes)?;
    let acknowledged = writer.wait_acknowledged(wait);
    Ok(Published {
        matched_after_s,
        subscribers: writer.matched(),
        acknowledged,
        bytes: bytes.len(),
    })
}
