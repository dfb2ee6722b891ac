//! The Franka Hand (gripper) interface, protocol version 3: TCP port 1338 for commands,
//! a 23-byte UDP state (`u32 message_id, f64 width, f64 max_width, bool is_grasped, u16
//! temperature`, packed). TCP messages start with `u16 command, u32 command_id, u32 size`
//! (10 bytes, size counting them); replies carry a `u16` status and come when the fingers
//! settle. Commands: Connect 0, Homing 1, Grasp 2 (`width, epsilon_inner, epsilon_outer,
//! speed, force`), Move 3 (`width, speed`), Stop 4.

use std::io::Write;
use std::net::{TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use crate::error::FrankaError;

/// The gripper protocol's version.
pub const GRIPPER_VERSION: u16 = 3;
/// The gripper's TCP port.
pub const GRIPPER_PORT: u16 = 1338;
/// Bytes of a gripper state datagram.
pub const GRIPPER_STATE_SIZE: usize = 23;
/// The Franka Hand's largest grasp force (N).
pub const MAX_FORCE: f64 = 140.0;
/// The Franka Hand's largest finger speed (m/s).
pub const MAX_SPEED: f64 = 0.1;
/// How long a gripper motion may take before cps gives up waiting (s).
const MOTION_TIMEOUT: Duration = Duration::from_secs(30);

/// One gripper state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperState {
    /// The gripper's tick counter.
    pub message_id: u32,
    /// Opening between the fingers (m).
    pub width: f64,
    /// Opening after homing (m).
    pub max_width: f64,
    /// Whether an object is held.
    pub is_grasped: bool,
    /// Temperature (°C).
    pub temperature: u16,
}

impl GripperState {
    /// Decodes a 23-byte datagram.
    pub fn decode(b: &[u8]) -> Result<Self, crate::wire::WireError> {
        if b.len() != GRIPPER_STATE_SIZE {
            return Err(crate::wire::WireError::Size {
                what: "the gripper state datagram",
                got: b.len(),
                expected: GRIPPER_STATE_SIZE,
            });
        }
        let f = |i: usize| f64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
        Ok(GripperState {
            message_id: u32::from_le_bytes(b[..4].try_into().expect("4 bytes")),
            width: f(4),
            max_width: f(12),
            is_grasped: b[20] != 0,
            temperature: u16::from_le_bytes([b[21], b[22]]),
        })
    }
}

/// A gripper command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GripperCommand {
    /// Open fully, close until contact, learn the maximum width.
    Homing,
    /// Close to `width` at `speed` with `force`; grasped when the fingers stop within
    /// `width − epsilon_inner … width + epsilon_outer`.
    Grasp {
        /// m.
        width: f64,
        /// m.
        epsilon_inner: f64,
        /// m.
        epsilon_outer: f64,
        /// m/s.
        speed: f64,
        /// N.
        force: f64,
    },
    /// Move the fingers to `width` at `speed`.
    Move {
        /// m.
        width: f64,
        /// m/s.
        speed: f64,
    },
    /// Stop a running gripper motion.
    Stop,
}

impl GripperCommand {
    fn number(&self) -> u16 {
        match self {
            GripperCommand::Homing => 1,
            GripperCommand::Grasp { .. } => 2,
            GripperCommand::Move { .. } => 3,
            GripperCommand::Stop => 4,
        }
    }

    fn name(&self) -> &'static str {
        match self {
            GripperCommand::Homing => "Homing",
            GripperCommand::Grasp { .. } => "Grasp",
            GripperCommand::Move { .. } => "Move",
            GripperCommand::Stop => "Stop",
        }
    }

    /// Checks the arguments: widths within `[0, max_width]`, speed in (0, 0.1] m/s, force
    /// in (0, 140] N, tolerances ≥ 0; a sentence naming the argument otherwise.
    pub fn check(&self, max_width: f64) -> Result<(), FrankaError> {
        let bad = |s: String| Err(FrankaError::Input(s));
        let (width, speed) = match *self {
            GripperCommand::Homing | GripperCommand::Stop => return Ok(()),
            GripperCommand::Move { width, speed } => (width, speed),
            GripperCommand::Grasp {
                width,
                epsilon_inner,
                epsilon_outer,
                speed,
                force,
            } => {
                if !(force.is_finite() && force > 0.0 && force <= MAX_FORCE) {
                    return bad(format!("--force: {force} N is not in (0, {MAX_FORCE}] N"));
                }
                if !(epsilon_inner.is_finite()
                    && epsilon_inner >= 0.0
                    && epsilon_outer.is_finite()
                    && epsilon_outer >= 0.0)
                {
                    return bad(format!(
                        "--epsilon: the tolerances ({epsilon_inner}, {epsilon_outer}) m must be finite and >= 0"
                    ));
                }
                (width, speed)
            }
        };
        if !(width.is_finite() && (0.0..=max_width).contains(&width)) {
            return bad(format!(
                "width {width} m is not in [0, {max_width}] m (the hand's opening)"
            ));
        }
        if !(speed.is_finite() && speed > 0.0 && speed <= MAX_SPEED) {
            return bad(format!(
                "--speed: {speed} m/s is not in (0, {MAX_SPEED}] m/s"
            ));
        }
        Ok(())
    }

    fn encode(&self, id: u32) -> Vec<u8> {
        let mut payload = Vec::new();
        let mut put = |x: f64| payload.extend_from_slice(&x.to_le_bytes());
        match *self {
            GripperCommand::Grasp {
                width,
                epsilon_inner,
                epsilon_outer,
                speed,
                force,
            } => {
                for x in [width, epsilon_inner, epsilon_outer, speed, force] {
                    put(x);
                }
            }
            GripperCommand::Move { width, speed } => {
                put(width);
                put(speed);
            }
            GripperCommand::Homing | GripperCommand::Stop => {}
        }
        header(self.number(), id, &payload)
    }
}

fn header(command: u16, id: u32, payload: &[u8]) -> Vec<u8> {
    let mut m = Vec::with_capacity(10 + payload.len());
    m.extend_from_slice(&command.to_le_bytes());
    m.extend_from_slice(&id.to_le_bytes());
    m.extend_from_slice(&((10 + payload.len()) as u32).to_le_bytes());
    m.extend_from_slice(payload);
    m
}

/// A connected Franka Hand.
#[derive(Debug)]
pub struct Gripper {
    host: String,
    tcp: TcpStream,
    udp: UdpSocket,
    next_id: u32,
}

impl Gripper {
    /// Connects to the hand of the robot at `host` (`address`, or `address:port` for
    /// port 1338 elsewhere) and checks its protocol version.
    pub fn connect(host: &str, timeout: Duration) -> Result<Self, FrankaError> {
        let (tcp, udp, port) = crate::session::open(host, GRIPPER_PORT, timeout)?;
        let mut g = Gripper {
            host: host.to_string(),
            tcp,
            udp,
            next_id: 1,
        };
        let mut payload = GRIPPER_VERSION.to_le_bytes().to_vec();
        payload.extend_from_slice(&port.to_le_bytes());
        let reply = g
            .exchange(&header(0, 0, &payload), timeout, "Connect")
            .map_err(|e| match e {
                FrankaError::Timeout { host, .. } => FrankaError::NotARobot {
                    host,
                    reason: "its gripper port accepted the connection but did not answer Connect"
                        .into(),
                },
                other => other,
            })?;
        let (status, version) = match reply.len() {
            3 => (
                u16::from(reply[0]),
                u16::from_le_bytes([reply[1], reply[2]]),
            ),
            n if n >= 4 => (
                u16::from_le_bytes([reply[0], reply[1]]),
                u16::from_le_bytes([reply[2], reply[3]]),
            ),
            n => {
                return Err(FrankaError::NotARobot {
                    host: host.into(),
                    reason: format!("a {n}-byte gripper Connect reply"),
                });
            }
        };
        if status != 0 || version != GRIPPER_VERSION {
            return Err(FrankaError::VersionMismatch {
                host: host.into(),
                robot: version,
                ours: GRIPPER_VERSION,
            });
        }
        Ok(g)
    }

    /// Sends a message and waits for the reply's payload (after the 10-byte header).
    fn exchange(
        &mut self,
        message: &[u8],
        timeout: Duration,
        what: &'static str,
    ) -> Result<Vec<u8>, FrankaError> {
        let host = self.host.clone();
        let lost = |r: String| FrankaError::ConnectionLost {
            host: host.clone(),
            reason: r,
        };
        self.tcp
            .write_all(message)
            .map_err(|e| lost(e.to_string()))?;
        let deadline = Instant::now() + timeout;
        let read = |buf: &mut [u8], tcp: &mut TcpStream| {
            crate::session::read_until(tcp, buf, deadline, &host, what, timeout)
        };
        let mut h = [0u8; 10];
        read(&mut h, &mut self.tcp)?;
        let size = u32::from_le_bytes(h[6..10].try_into().expect("4 bytes")) as usize;
        if !(10..=1024).contains(&size) {
            return Err(FrankaError::NotARobot {
                host: self.host.clone(),
                reason: format!("a gripper reply declares {size} bytes"),
            });
        }
        let mut payload = vec![0u8; size - 10];
        read(&mut payload, &mut self.tcp)?;
        Ok(payload)
    }

    /// The newest gripper state (bounded by `timeout`).
    pub fn state(&mut self, timeout: Duration) -> Result<GripperState, FrankaError> {
        let mut buf = [0u8; 64];
        self.udp.set_read_timeout(Some(timeout)).ok();
        let n = match self.udp.recv(&mut buf) {
            Ok(n) => n,
            Err(_) => {
                return Err(FrankaError::Timeout {
                    host: self.host.clone(),
                    what: "gripper state",
                    after: timeout,
                });
            }
        };
        let mut state = GripperState::decode(&buf[..n]).map_err(|source| FrankaError::Wire {
            host: self.host.clone(),
            source,
        })?;
        self.udp.set_nonblocking(true).ok();
        while let Ok(n) = self.udp.recv(&mut buf) {
            if let Ok(s) = GripperState::decode(&buf[..n]) {
                state = s;
            }
        }
        self.udp.set_nonblocking(false).ok();
        Ok(state)
    }

    /// Runs a command and waits until the fingers settle (at most 30 s). A grasp returns
    /// whether the object is held; the others return true.
    pub fn run(&mut self, command: GripperCommand) -> Result<bool, FrankaError> {
        let max_width = self.state(Duration::from_secs(1))?.max_width;
        command.check(if max_width > 0.0 { max_width } else { 0.08 })?;
        let id = self.next_id;
        self.next_id += 1;
        let reply = self.exchange(&command.encode(id), MOTION_TIMEOUT, "gripper reply")?;
        let status = match reply.len() {
            0 => 255,
            1 => u16::from(reply[0]),
            _ => u16::from_le_bytes([reply[0], reply[1]]),
        };
        let sentence = match status {
            0 => return Ok(true),
            2 if matches!(command, GripperCommand::Grasp { .. }) => return Ok(false),
            1 => "the gripper failed",
            2 => "the gripper could not complete it",
            3 => "it was aborted (a Stop)",
            _ => "an unknown status",
        };
        Err(FrankaError::Rejected {
            host: self.host.clone(),
            command: command.name(),
            sentence: sentence.into(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_encode_and_check() {
        let g = GripperCommand::Grasp {
            width: 0.02,
            epsilon_inner: 0.005,
            epsilon_outer: 0.006,
            speed: 0.05,
            force: 30.0,
        };
        let m = g.encode(7);
        assert_eq!(m.len(), 10 + 40);
        assert_eq!(&m[..2], &2u16.to_le_bytes());
        assert_eq!(&m[2..6], &7u32.to_le_bytes());
        assert_eq!(&m[6..10], &50u32.to_le_bytes());
        // width, epsilon_inner, epsilon_outer, speed, force
        assert_eq!(&m[18..26], &0.005f64.to_le_bytes());
        assert_eq!(&m[42..50], &30.0f64.to_le_bytes());
        assert!(g.check(0.08).is_ok());
        let too_hard = GripperCommand::Grasp {
            width: 0.02,
            epsilon_inner: 0.005,
            epsilon_outer: 0.005,
            speed: 0.05,
            force: 500.0,
        };
        assert!(
            too_hard
                .check(0.08)
                .unwrap_err()
                .to_string()
                .contains("--force: 500 N")
        );
        let wide = GripperCommand::Move {
            width: 0.2,
            speed: 0.05,
        };
        assert!(
            wide.check(0.08)
                .unwrap_err()
                .to_string()
                .contains("width 0.2 m is not in [0, 0.08]")
        );
        let nan = GripperCommand::Move {
            width: 0.04,
            speed: f64::NAN,
        };
        assert!(nan.check(0.08).unwrap_err().to_string().contains("--speed"));
    }

    #[test]
    fn state_decodes_its_23_bytes() {
        let mut b = Vec::new();
        b.extend_from_slice(&9u32.to_le_bytes());
        b.extend_from_slice(&0.031f64.to_le_bytes());
        b.extend_from_slice(&0.079f64.to_le_bytes());
        b.push(1);
        b.extend_from_slice(&27u16.to_le_bytes());
        let s = GripperState::decode(&b).unwrap();
        assert_eq!(
            (
                s.message_id,
                s.width,
                s.max_width,
                s.is_grasped,
                s.temperature
            ),
            (9, 0.031, 0.079, true, 27)
        );
        assert!(GripperState::decode(&b[..22]).is_err());
    }
}
