//! A session with one robot: the TCP command connection and the UDP state stream,
//! connecting with the version check, the command/reply exchanges with bounded waits, and
//! errors as typed values naming the host.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use crate::error::FrankaError;
use crate::wire::{
    COMMAND_PORT, COMMAND_SIZE, CollisionBehavior, Command, CommandKind, ControllerMode,
    HEADER_SIZE, Header, MotionGeneratorMode, MoveStatus, PROTOCOL_VERSION, Request, RobotMode,
    RobotState, STATE_SIZE, WireError, decode_connect_reply,
};

/// Largest reply payload accepted (the FR3's URDF is ≈ 11 kB).
const MAX_REPLY: usize = 1 << 20;

/// How long the session waits for each kind of answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timeouts {
    /// TCP connection and the Connect reply.
    pub connect: Duration,
    /// A reply to a command.
    pub reply: Duration,
    /// A robot state outside a motion.
    pub state: Duration,
}

impl Default for Timeouts {
    fn default() -> Self {
        Timeouts {
            connect: Duration::from_secs(3),
            reply: Duration::from_secs(3),
            state: Duration::from_secs(1),
        }
    }
}

/// A connected robot.
#[derive(Debug)]
pub struct Connection {
    host: String,
    tcp: TcpStream,
    udp: UdpSocket,
    robot_udp: Option<SocketAddr>,
    next_id: u32,
    timeouts: Timeouts,
    /// Replies that arrived while another was awaited (a Move's final status).
    parked: Vec<(Header, Vec<u8>)>,
    state_buf: Box<[u8; STATE_SIZE + 1]>,
    command_buf: [u8; COMMAND_SIZE],
    /// A lossy link, on purpose ([`Connection::lose_commands`]).
    loss: Option<cps_robot::CycleLoss>,
}

fn io_reason(e: &std::io::Error) -> String {
    match e.kind() {
        ErrorKind::ConnectionRefused => "connection refused".into(),
        ErrorKind::TimedOut | ErrorKind::WouldBlock => "no answer".into(),
        _ => e.to_string(),
    }
}

/// Refuses an address that is not one: an IP address (with a port or not) or a host name
/// of letters, digits, `-` and `.` (RFC 1123), optionally `:port`.
fn check_host(host: &str) -> Result<(), FrankaError> {
    if host.parse::<std::net::IpAddr>().is_ok() || host.parse::<SocketAddr>().is_ok() {
        return Ok(());
    }
    let (name, port) = match host.rsplit_once(':') {
        Some((h, p)) => (h, Some(p)),
        None => (host, None),
    };
    let name_ok = !name.is_empty()
        && name.len() <= 253
        && name.split('.').all(|label| {
            !label.is_empty()
                && label.len() <= 63
                && !label.starts_with('-')
                && !label.ends_with('-')
                && label
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'-')
        });
    let port_ok = port.is_none_or(|p| p.parse::<u16>().is_ok_and(|p| p > 0));
    if name_ok && port_ok {
        Ok(())
    } else {
        Err(FrankaError::Input(format!(
            "--host `{host}`: not an address; give the robot's IP address or host name (optionally with :port), e.g. 172.16.0.2"
        )))
    }
}

/// Opens the TCP connection to `host` (`address` or `address:port`, else `default_port`)
/// within `timeout`, and a UDP socket on the same local address for the state; returns
/// them with the UDP port to announce. Errors name the host.
pub(crate) fn open(
    host: &str,
    default_port: u16,
    timeout: Duration,
) -> Result<(TcpStream, UdpSocket, u16), FrankaError> {
    let unreachable = |reason: String| FrankaError::Unreachable {
        host: host.to_string(),
        reason,
    };
    check_host(host)?;
    let has_port = host.parse::<SocketAddr>().is_ok()
        || host
            .rsplit_once(':')
            .is_some_and(|(h, p)| !h.contains(':') && p.parse::<u16>().is_ok());
    let with_port = if has_port {
        host.to_string()
    } else {
        format!("{host}:{default_port}")
    };
    let addr = with_port
        .to_socket_addrs()
        .map_err(|e| unreachable(format!("the address does not resolve: {e}")))?
        .next()
        .ok_or_else(|| unreachable("the address does not resolve".into()))?;
    let tcp = TcpStream::connect_timeout(&addr, timeout).map_err(|e| unreachable(io_reason(&e)))?;
    tcp.set_nodelay(true).ok();
    let local_ip = tcp
        .local_addr()
        .map_err(|e| unreachable(e.to_string()))?
        .ip();
    let udp = UdpSocket::bind((local_ip, 0))
        .map_err(|e| unreachable(format!("cannot open a UDP port: {e}")))?;
    let udp_port = udp
        .local_addr()
        .map_err(|e| unreachable(e.to_string()))?
        .port();
    Ok((tcp, udp, udp_port))
}

/// Reads exactly `buf` from `tcp` before `deadline`; a timeout names `what` and `after`,
/// a closed or broken connection is lost. Shared by the robot's and the hand's sessions.
pub(crate) fn read_until(
    tcp: &mut TcpStream,
    buf: &mut [u8],
    deadline: Instant,
    host: &str,
    what: &'static str,
    after: Duration,
) -> Result<(), FrankaError> {
    let lost = |reason: String| FrankaError::ConnectionLost {
        host: host.to_string(),
        reason,
    };
    let mut got = 0;
    while got < buf.len() {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(FrankaError::Timeout {
                host: host.to_string(),
                what,
                after,
            });
        }
        tcp.set_read_timeout(Some(left)).ok();
        match tcp.read(&mut buf[got..]) {
            Ok(0) => return Err(lost("the peer closed the connection".into())),
            Ok(n) => got += n,
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(lost(e.to_string())),
        }
    }
    Ok(())
}

impl Connection {
    /// Connects to the robot at `host` (`address` or `address:port`; the port defaults to
    /// 1337), opens a UDP port for its state and checks that it speaks protocol 10.
    pub fn connect(host: &str, timeouts: Timeouts) -> Result<Self, FrankaError> {
        let (tcp, udp, udp_port) = open(host, COMMAND_PORT, timeouts.connect)?;
        let mut c = Connection {
            host: host.to_string(),
            tcp,
            udp,
            robot_udp: None,
            next_id: 1,
            timeouts,
            parked: Vec::new(),
            state_buf: Box::new([0; STATE_SIZE + 1]),
            command_buf: [0; COMMAND_SIZE],
            loss: None,
        };
        let id = c.send(&Request::Connect {
            version: PROTOCOL_VERSION,
            udp_port,
        })?;
        let payload = c
            .await_reply(CommandKind::Connect, id, timeouts.connect)
            .map_err(|e| match e {
                FrankaError::Timeout { host, .. } => FrankaError::NotARobot {
                    host,
                    reason: "it accepted the connection but did not answer Connect".into(),
                },
                FrankaError::Wire { host, source } => FrankaError::NotARobot {
                    host,
                    reason: source.to_string(),
                },
                other => other,
            })?;
        let (status, version) =
            decode_connect_reply(&payload).map_err(|e| FrankaError::NotARobot {
                host: host.to_string(),
                reason: e.to_string(),
            })?;
        // libfranka's statuses: 0 success, 1 incompatible library version.
        match status {
            0 => {}
            1 => {
                return Err(FrankaError::VersionMismatch {
                    host: host.to_string(),
                    robot: version,
                    ours: PROTOCOL_VERSION,
                });
            }
            other => {
                return Err(FrankaError::Rejected {
                    host: host.to_string(),
                    command: "Connect",
                    sentence: format!("status {other}"),
                });
            }
        }
        // franky-sim sends the version as a u16 after a u16 status; a real robot after a
        // u8 status. A version that is present and differs is refused.
        if version != PROTOCOL_VERSION && version != 0 {
            return Err(FrankaError::VersionMismatch {
                host: host.to_string(),
                robot: version,
                ours: PROTOCOL_VERSION,
            });
        }
        Ok(c)
    }

    /// The host as given.
    pub fn host(&self) -> &str {
        &self.host
    }

    fn lost(&self, reason: impl Into<String>) -> FrankaError {
        FrankaError::ConnectionLost {
            host: self.host.clone(),
            reason: reason.into(),
        }
    }

    fn timeout(&self, what: &'static str, after: Duration) -> FrankaError {
        FrankaError::Timeout {
            host: self.host.clone(),
            what,
            after,
        }
    }

    /// Sends a request; returns its command id.
    pub fn send(&mut self, request: &Request) -> Result<u32, FrankaError> {
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1).max(1);
        self.tcp
            .write_all(&request.encode(id))
            .map_err(|e| self.lost(format!("sending {}: {e}", request.kind().name())))?;
        Ok(id)
    }

    /// Reads one whole reply (header and payload) before `deadline`.
    fn read_reply(
        &mut self,
        deadline: Instant,
        what: &'static str,
    ) -> Result<(Header, Vec<u8>), FrankaError> {
        let mut header = [0u8; HEADER_SIZE];
        self.read_exact_by(&mut header, deadline, what)?;
        let h = Header::decode(&header).map_err(|source| FrankaError::Wire {
            host: self.host.clone(),
            source,
        })?;
        if h.payload_len > MAX_REPLY {
            return Err(FrankaError::Wire {
                host: self.host.clone(),
                source: WireError::Malformed(format!(
                    "a {} reply declares {} bytes, more than the {MAX_REPLY} cps accepts",
                    h.command.name(),
                    h.payload_len
                )),
            });
        }
        let mut payload = vec![0u8; h.payload_len];
        self.read_exact_by(&mut payload, deadline, what)?;
        Ok((h, payload))
    }

    fn read_exact_by(
        &mut self,
        buf: &mut [u8],
        deadline: Instant,
        what: &'static str,
    ) -> Result<(), FrankaError> {
        let after = deadline.saturating_duration_since(Instant::now());
        read_until(&mut self.tcp, buf, deadline, &self.host, what, after)
    }

    /// Waits for the reply to command `id` of `kind`, parking any other reply.
    pub fn await_reply(
        &mut self,
        kind: CommandKind,
        id: u32,
        timeout: Duration,
    ) -> Result<Vec<u8>, FrankaError> {
        if let Some(i) = self
            .parked
            .iter()
            .position(|(h, _)| h.command == kind && h.command_id == id)
        {
            return Ok(self.parked.remove(i).1);
        }
        let deadline = Instant::now() + timeout;
        loop {
            let (h, payload) = self.read_reply(deadline, kind.name_reply())?;
            if h.command == kind && h.command_id == id {
                return Ok(payload);
            }
            if self.parked.len() < 64 {
                self.parked.push((h, payload));
            }
        }
    }

    /// Sends a request and returns the status byte of its reply and the rest.
    pub fn request(&mut self, request: &Request) -> Result<(u8, Vec<u8>), FrankaError> {
        let id = self.send(request)?;
        let mut payload = self.await_reply(request.kind(), id, self.timeouts.reply)?;
        if payload.is_empty() {
            return Err(FrankaError::Wire {
                host: self.host.clone(),
                source: WireError::Malformed(format!(
                    "the {} reply has no status",
                    request.kind().name()
                )),
            });
        }
        let status = payload.remove(0);
        Ok((status, payload))
    }

    /// A setter: succeeds on status 0, else names the status.
    fn set(&mut self, request: &Request) -> Result<(), FrankaError> {
        let (status, _) = self.request(request)?;
        // Setters answer 0 success, 1 command not possible, 2 invalid argument.
        let sentence = match status {
            0 => return Ok(()),
            1 => "the robot cannot take it now (a motion is running?)".to_string(),
            2 => "an argument is invalid".to_string(),
            s => format!("status {s}"),
        };
        Err(FrankaError::Rejected {
            host: self.host.clone(),
            command: request.kind().name(),
            sentence,
        })
    }

    /// Sets the contact and collision thresholds.
    pub fn set_collision_behavior(&mut self, c: CollisionBehavior) -> Result<(), FrankaError> {
        self.set(&Request::SetCollisionBehavior(c))
    }

    /// Sets the internal joint impedance's stiffness (N m/rad).
    pub fn set_joint_impedance(&mut self, k: [f64; 7]) -> Result<(), FrankaError> {
        self.set(&Request::SetJointImpedance(k))
    }

    /// Sets the internal Cartesian impedance's stiffness.
    pub fn set_cartesian_impedance(&mut self, k: [f64; 6]) -> Result<(), FrankaError> {
        self.set(&Request::SetCartesianImpedance(k))
    }

    /// Sets the stiffness frame in the end-effector frame (column-major 4 × 4).
    pub fn set_ee_to_k(&mut self, m: [f64; 16]) -> Result<(), FrankaError> {
        self.set(&Request::SetEEToK(m))
    }

    /// Sets the end effector in the nominal end-effector frame.
    pub fn set_ne_to_ee(&mut self, m: [f64; 16]) -> Result<(), FrankaError> {
        self.set(&Request::SetNEToEE(m))
    }

    /// Sets the payload.
    pub fn set_load(
        &mut self,
        mass: f64,
        center_of_mass: [f64; 3],
        inertia: [f64; 9],
    ) -> Result<(), FrankaError> {
        self.set(&Request::SetLoad {
            mass,
            center_of_mass,
            inertia,
        })
    }

    /// Leaves a reflex.
    pub fn automatic_error_recovery(&mut self) -> Result<(), FrankaError> {
        let (status, _) = self.request(&Request::AutomaticErrorRecovery)?;
        let sentence = match status {
            0 => return Ok(()),
            1 => "the robot cannot recover now",
            2 => "a safety function is active",
            3 => "manual error recovery is required (Desk)",
            4 => "a reflex aborted the recovery",
            5 => "the emergency stop aborted the recovery",
            _ => "the recovery was aborted",
        };
        Err(FrankaError::Rejected {
            host: self.host.clone(),
            command: "AutomaticErrorRecovery",
            sentence: sentence.into(),
        })
    }

    /// The robot's own URDF (with `<inertial>` elements on a FR3).
    pub fn robot_model(&mut self) -> Result<String, FrankaError> {
        let (status, payload) = self.request(&Request::GetRobotModel)?;
        if status != 0 {
            return Err(FrankaError::Rejected {
                host: self.host.clone(),
                command: "GetRobotModel",
                sentence: format!("status {status}"),
            });
        }
        String::from_utf8(payload).map_err(|_| FrankaError::Wire {
            host: self.host.clone(),
            source: WireError::Malformed("the robot model is not UTF-8 text".into()),
        })
    }

    /// Starts a motion; returns its motion id once the robot answers `MotionStarted`.
    /// States that arrive meanwhile are not consumed.
    pub fn start_move(
        &mut self,
        controller: ControllerMode,
        generator: MotionGeneratorMode,
    ) -> Result<u32, FrankaError> {
        // libfranka's default deviations (translation m, rotation rad, elbow rad).
        let deviation = [10.0, 3.12, 2.0 * std::f64::consts::PI];
        let id = self.send(&Request::Move {
            controller,
            generator,
            maximum_path_deviation: deviation,
            maximum_goal_pose_deviation: deviation,
        })?;
        let payload = self.await_reply(CommandKind::Move, id, self.timeouts.reply)?;
        match payload.first().map(|&b| MoveStatus::from_u8(b)) {
            Some(MoveStatus::MotionStarted) => Ok(id),
            Some(s) => Err(FrankaError::Rejected {
                host: self.host.clone(),
                command: "Move",
                sentence: s.sentence(),
            }),
            None => Err(FrankaError::Wire {
                host: self.host.clone(),
                source: WireError::Malformed("the Move reply has no status".into()),
            }),
        }
    }

    /// Waits for a motion's final status.
    pub fn await_move_end(
        &mut self,
        motion_id: u32,
        timeout: Duration,
    ) -> Result<MoveStatus, FrankaError> {
        let payload = self.await_reply(CommandKind::Move, motion_id, timeout)?;
        Ok(MoveStatus::from_u8(payload.first().copied().unwrap_or(255)))
    }

    /// Polls, without blocking, whether the robot sent a motion's final status.
    pub fn poll_move_end(&mut self, motion_id: u32) -> Result<Option<MoveStatus>, FrankaError> {
        if let Some(i) = self
            .parked
            .iter()
            .position(|(h, _)| h.command == CommandKind::Move && h.command_id == motion_id)
        {
            let (_, p) = self.parked.remove(i);
            return Ok(Some(MoveStatus::from_u8(p.first().copied().unwrap_or(255))));
        }
        let mut probe = [0u8; 1];
        self.tcp.set_nonblocking(true).ok();
        let ready = self.tcp.peek(&mut probe);
        self.tcp.set_nonblocking(false).ok();
        match ready {
            Ok(0) => Err(self.lost("the robot closed the connection")),
            Ok(_) => self
                .await_move_end(motion_id, self.timeouts.reply)
                .map(Some),
            Err(e) if e.kind() == ErrorKind::WouldBlock => Ok(None),
            Err(e) => Err(self.lost(e.to_string())),
        }
    }

    /// Receives the next state datagram, waiting at most `timeout`; returns its decoded
    /// state. Learns the robot's UDP address from the first datagram.
    pub fn recv_state(&mut self, timeout: Duration) -> Result<RobotState, FrankaError> {
        self.udp
            .set_read_timeout(Some(timeout.max(Duration::from_micros(1))))
            .ok();
        loop {
            match self.udp.recv_from(&mut self.state_buf[..]) {
                Ok((n, from)) => {
                    if self.robot_udp.is_none() {
                        self.robot_udp = Some(from);
                    }
                    return RobotState::decode(&self.state_buf[..n]).map_err(|source| {
                        FrankaError::Wire {
                            host: self.host.clone(),
                            source,
                        }
                    });
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    return Err(self.timeout("robot state", timeout));
                }
                Err(e) => return Err(self.lost(e.to_string())),
            }
        }
    }

    /// The newest state: waits for one, then takes every further one already queued.
    /// Returns it and how many older states were skipped.
    pub fn newest_state(&mut self, timeout: Duration) -> Result<(RobotState, u32), FrankaError> {
        let mut state = self.recv_state(timeout)?;
        let mut skipped = 0;
        self.udp.set_nonblocking(true).ok();
        while let Ok((n, _)) = self.udp.recv_from(&mut self.state_buf[..]) {
            match RobotState::decode(&self.state_buf[..n]) {
                Ok(s) => {
                    state = s;
                    skipped += 1;
                }
                Err(source) => {
                    self.udp.set_nonblocking(false).ok();
                    return Err(FrankaError::Wire {
                        host: self.host.clone(),
                        source,
                    });
                }
            }
        }
        self.udp.set_nonblocking(false).ok();
        Ok((state, skipped))
    }

    /// Whether a state is already waiting to be read: a newer one than the state being
    /// answered, so that the robot has closed that state's cycle, and an answer sent now
    /// would come late (a real robot drops it; a simulator may apply it late).
    pub fn state_waiting(&mut self) -> bool {
        self.udp.set_nonblocking(true).ok();
        let mut probe = [0u8; 1];
        let waiting = self.udp.peek_from(&mut probe).is_ok();
        self.udp.set_nonblocking(false).ok();
        waiting
    }

    /// One state, outside a motion (bounded by the state timeout).
    pub fn read_state(&mut self) -> Result<RobotState, FrankaError> {
        let t = self.timeouts.state;
        self.newest_state(t).map(|(s, _)| s)
    }

    /// Makes the link lossy on purpose: from now on `share` (0 to
    /// [`cps_robot::MAX_LOSS`]) of the commands are not sent, chosen by a generator seeded
    /// with `seed` ([`cps_robot::CycleLoss`]) — as a congested network drops them — except
    /// a motion's last, so that it still ends. For trying a loop's handling of lost cycles
    /// against a simulator with the robot's rules (franka-sim): the robot extrapolates
    /// every cycle it gets no command for, and the next state shows it.
    pub fn lose_commands(&mut self, share: f64, seed: u64) -> Result<(), FrankaError> {
        let loss = cps_robot::CycleLoss::new(share, seed)?;
        self.loss = (share > 0.0).then_some(loss);
        Ok(())
    }

    /// Commands dropped on purpose so far ([`Connection::lose_commands`]).
    pub fn commands_lost(&self) -> u64 {
        self.loss.map_or(0, |l| l.lost())
    }

    /// Sends one command datagram (no allocation).
    pub fn send_command(&mut self, command: &Command) -> Result<(), FrankaError> {
        if let Some(loss) = &mut self.loss
            && !(command.motion_generation_finished || command.torque_command_finished)
            && loss.loses()
        {
            return Ok(());
        }
        let Some(to) = self.robot_udp else {
            return Err(
                self.lost("no state has been received, so the robot's UDP address is unknown")
            );
        };
        command.encode(&mut self.command_buf);
        match self.udp.send_to(&self.command_buf, to) {
            Ok(n) if n == COMMAND_SIZE => Ok(()),
            Ok(n) => Err(self.lost(format!(
                "only {n} of {COMMAND_SIZE} command bytes were sent"
            ))),
            Err(e) => Err(self.lost(e.to_string())),
        }
    }

    /// Refuses to move a robot that is in a reflex, has errors or is not idle.
    pub fn ensure_ready(&mut self, state: &RobotState) -> Result<(), FrankaError> {
        if state.errors.any() || state.robot_mode == RobotMode::Reflex {
            return Err(FrankaError::Reflex {
                host: self.host.clone(),
                mode: state.robot_mode.sentence(),
                errors: state.errors.describe(),
            });
        }
        if state.robot_mode != RobotMode::Idle {
            return Err(FrankaError::Rejected {
                host: self.host.clone(),
                command: "Move",
                sentence: format!("the robot is not idle: {}", state.robot_mode.sentence()),
            });
        }
        Ok(())
    }
}

trait ReplyName {
    fn name_reply(self) -> &'static str;
}

impl ReplyName for CommandKind {
    fn name_reply(self) -> &'static str {
        match self {
            CommandKind::Connect => "reply to Connect",
            CommandKind::Move => "reply to Move",
            CommandKind::StopMove => "reply to StopMove",
            CommandKind::GetRobotModel => "reply to GetRobotModel",
            CommandKind::AutomaticErrorRecovery => "reply to AutomaticErrorRecovery",
            _ => "reply to a setter",
        }
    }
}
