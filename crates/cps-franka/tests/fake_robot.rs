//! Faults franky-sim cannot produce, from a fake robot of cps's own speaking the same
//! wire layouts: a version mismatch, a host that accepts but never answers, nothing
//! listening, a robot already in a reflex, a reflex during a motion, a truncated datagram.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use cps_franka::limits::{Arm, RateLimits};
use cps_franka::wire::{Errors, RobotState, STATE_SIZE};
use cps_franka::{
    Connection, FrankaError, LoopOptions, MotionEnd, Realtime, RobotMode, Start, Timeouts,
    approach, check_trajectory, execute_stream,
};

#[derive(Clone, Copy)]
enum Scenario {
    /// Answers Connect with "incompatible version 9".
    OldVersion,
    /// Accepts the connection, never answers.
    Silent,
    /// Serves states, in a reflex with joint_reflex set.
    InReflex,
    /// Serves states; 200 ms into a motion, a reflex: errors set, Move answered ReflexAborted.
    ReflexDuringMotion,
    /// Serves states; 200 ms into a motion, one datagram of 1000 bytes.
    Truncated,
}

fn state(id: u64, mode: RobotMode, errors: Errors) -> [u8; STATE_SIZE] {
    let mut buf = [0u8; STATE_SIZE];
    let mut s = RobotState::decode(&buf).unwrap();
    s.message_id = id;
    s.q = cps_kinematics::robots::PANDA_READY;
    s.q_d = s.q;
    s.robot_mode = mode;
    s.errors = errors;
    s.control_command_success_rate = 1.0;
    s.encode(&mut buf);
    buf
}

fn reply(tcp: &mut TcpStream, command: u32, id: u32, payload: &[u8]) {
    let mut msg = Vec::new();
    msg.extend_from_slice(&command.to_le_bytes());
    msg.extend_from_slice(&id.to_le_bytes());
    msg.extend_from_slice(&(12 + payload.len() as u32).to_le_bytes());
    msg.extend_from_slice(payload);
    let _ = tcp.write_all(&msg);
}

/// A fake robot on 127.0.0.1, an ephemeral port; returns its address.
fn fake(scenario: Scenario) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    std::thread::spawn(move || {
        let (mut tcp, peer) = listener.accept().unwrap();
        let mut header = [0u8; 12];
        if tcp.read_exact(&mut header).is_err() {
            return;
        }
        let word = |b: &[u8], i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap());
        let mut payload = vec![0u8; word(&header, 8) as usize - 12];
        tcp.read_exact(&mut payload).unwrap();
        let udp_port = u16::from_le_bytes([payload[2], payload[3]]);
        match scenario {
            Scenario::OldVersion => {
                reply(&mut tcp, 0, word(&header, 4), &[1, 9, 0]);
                std::thread::sleep(Duration::from_secs(1));
                return;
            }
            Scenario::Silent => {
                std::thread::sleep(Duration::from_secs(10));
                return;
            }
            _ => reply(&mut tcp, 0, word(&header, 4), &[0, 10, 0]),
        }
        let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
        let to = (peer.ip(), udp_port);
        tcp.set_nonblocking(true).unwrap();
        let (mut id, mut motion) = (1u64, None::<(u32, Instant)>);
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(5) {
            let in_reflex = matches!(scenario, Scenario::InReflex)
                || (matches!(scenario, Scenario::ReflexDuringMotion)
                    && motion.is_some_and(|(_, t)| t.elapsed() > Duration::from_millis(200)));
            if let Ok(()) = tcp.read_exact(&mut header) {
                tcp.set_nonblocking(false).unwrap();
                let mut p = vec![0u8; word(&header, 8) as usize - 12];
                tcp.read_exact(&mut p).unwrap();
                tcp.set_nonblocking(true).unwrap();
                if word(&header, 0) == 1 {
                    motion = Some((word(&header, 4), Instant::now()));
                    reply(&mut tcp, 1, word(&header, 4), &[1]); // MotionStarted
                }
            }
            let mut errors = Errors::default();
            if in_reflex {
                errors.0[6] = true; // joint_reflex
            }
            let mode = if in_reflex {
                RobotMode::Reflex
            } else {
                RobotMode::Idle
            };
            if in_reflex
                && matches!(scenario, Scenario::ReflexDuringMotion)
                && let Some((mid, _)) = motion.take()
            {
                reply(&mut tcp, 1, mid, &[8]); // ReflexAborted
            }
            let s = state(id, mode, errors);
            let truncate = matches!(scenario, Scenario::Truncated)
                && motion.is_some_and(|(_, t)| t.elapsed() > Duration::from_millis(200));
            let _ = udp.send_to(if truncate { &s[..1000] } else { &s[..] }, to);
            id += 1;
            std::thread::sleep(Duration::from_millis(1));
        }
    });
    addr
}

fn quick() -> Timeouts {
    Timeouts {
        connect: Duration::from_millis(500),
        reply: Duration::from_millis(500),
        state: Duration::from_millis(500),
    }
}

fn try_motion(host: &str) -> Result<cps_franka::MotionReport, FrankaError> {
    let mut robot = Connection::connect(host, quick())?;
    let limits = RateLimits::of(Arm::Fr3);
    let from = cps_franka::rt::start_position(&robot.read_state()?);
    let mut goal = from;
    goal[0] += 0.5;
    let stream = check_trajectory(
        &limits,
        from,
        &approach(&limits, from, goal, 0.3),
        Start::Refuse,
    )?;
    let options = LoopOptions {
        realtime: Realtime::Ignore,
        ..LoopOptions::default()
    };
    let stop = Arc::new(AtomicBool::new(false));
    let r = execute_stream(&mut robot, limits, &stream, &options, &stop);
    assert!(!stop.load(Ordering::Relaxed));
    r
}

#[test]
fn a_version_mismatch_is_named() {
    let host = fake(Scenario::OldVersion);
    let e = Connection::connect(&host, quick()).unwrap_err();
    assert!(
        matches!(
            e,
            FrankaError::VersionMismatch {
                robot: 9,
                ours: 10,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        e.to_string().contains("protocol version 9, cps speaks 10"),
        "{e}"
    );
}

#[test]
fn a_host_that_does_not_answer_is_named_within_the_timeout() {
    let host = fake(Scenario::Silent);
    let start = Instant::now();
    let e = Connection::connect(&host, quick()).unwrap_err();
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "{:?}",
        start.elapsed()
    );
    assert!(matches!(e, FrankaError::NotARobot { .. }), "{e:?}");
    assert!(e.to_string().contains("did not answer Connect"), "{e}");
}

#[test]
fn nothing_listening_is_unreachable() {
    // A port that was just free.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let e = Connection::connect(&format!("127.0.0.1:{port}"), quick()).unwrap_err();
    assert!(matches!(e, FrankaError::Unreachable { .. }), "{e:?}");
    assert!(e.to_string().contains("connection refused"), "{e}");
}

#[test]
fn a_robot_in_a_reflex_is_not_moved() {
    let host = fake(Scenario::InReflex);
    let e = try_motion(&host).unwrap_err();
    assert!(matches!(e, FrankaError::Reflex { .. }), "{e:?}");
    assert!(e.to_string().contains("joint_reflex"), "{e}");
}

#[test]
fn a_reflex_during_a_motion_ends_it_with_the_reason_and_the_recording() {
    let host = fake(Scenario::ReflexDuringMotion);
    let r = try_motion(&host).unwrap();
    match &r.ending {
        MotionEnd::Robot { status, .. } => {
            assert_eq!(
                *status,
                cps_franka::wire::MoveStatus::ReflexAborted,
                "{}",
                r.ending.sentence()
            );
        }
        other => panic!("expected the robot's reflex, got {other:?}"),
    }
    assert!(
        r.ending.sentence().contains("aborted by a reflex"),
        "{}",
        r.ending.sentence()
    );
    assert!(r.samples.len() > 50, "{} samples kept", r.samples.len());
}

#[test]
fn a_truncated_datagram_ends_the_motion_naming_it() {
    let host = fake(Scenario::Truncated);
    let r = try_motion(&host).unwrap();
    match &r.ending {
        MotionEnd::Lost(reason) => assert!(
            reason.contains("1000 bytes but protocol 10 has 1377"),
            "{reason}"
        ),
        other => panic!("expected a lost connection, got {other:?}"),
    }
    assert!(r.samples.len() > 50);
}
