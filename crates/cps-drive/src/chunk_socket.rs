//! Action chunks from another process or machine over UDP: one datagram per chunk, the
//! robot's state on request. Why UDP: a chunk (50 targets × 7 joints × 8 bytes = 2.8 kB)
//! fits one datagram; a lost or late chunk is superseded by the next, so there is nothing
//! to retransmit and no head-of-line blocking; no broker, no dependency, and every
//! language a policy runs in can send one. The socket listens on loopback unless the user
//! names another address, and takes datagrams only from the senders it was opened for
//! (any port of an allowed address): anything else, and anything that does not parse, is
//! refused and counted — never a panic, never a motion.
//!
//! The messages (little-endian; `f64` IEEE 754, `u32` unsigned):
//!
//! | message | bytes |
//! |---|---|
//! | state request | `CPS?` |
//! | state (the answer) | `CPSS`, `u32` joints n, `f64` t (s on the executor's clock; NaN before the first period), n × `f64` q (rad) |
//! | chunk | `CPSC`, `u32` joints n, `u32` targets H, `f64` rate (Hz), `f64` observed_s (the executor's clock, as a state answer gave it), H × n `f64` targets, row by row |
//! | chunk taken into the queue (the answer) | `CPSA`, `u32` the chunk's index |
//! | refused (the answer) | `CPSR`, a sentence in UTF-8 |
//! | end of stream | `CPSE` (the last chunk is followed, the arm comes to rest, the run ends) |
//!
//! The executor's own verdicts (a chunk too far, late, out of range) are in the run's
//! report, as for any chunk.

use std::net::{IpAddr, SocketAddr, UdpSocket};
use std::time::Duration;

use cps_chunks::{Chunk, ChunkFeed};
use cps_robot::StopToken;

/// Largest datagram taken (bytes): 1 000 targets of 7 joints and the header.
pub const MAX_DATAGRAM: usize = 65_507;

/// What the socket saw.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SocketCounts {
    /// Chunks handed to the executor.
    pub chunks: usize,
    /// State requests answered.
    pub states: usize,
    /// Datagrams from a sender the socket was not opened for (dropped, unanswered).
    pub foreign: usize,
    /// Datagrams that did not parse or whose chunk was refused before the loop (answered
    /// with the reason).
    pub refused: usize,
    /// The first few reasons.
    pub reasons: Vec<String>,
}

/// Whether the socket takes datagrams from `peer`: an address in `allowed`, or any
/// loopback address when `allowed` is empty.
pub fn allowed(peer: &SocketAddr, allow: &[IpAddr]) -> bool {
    // A dual-stack socket hears an IPv4 sender as `::ffff:a.b.c.d`: the same sender.
    let ip = match peer.ip() {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(IpAddr::V6(v6), IpAddr::V4),
        v4 => v4,
    };
    let same = |a: &IpAddr| match a {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(*a, IpAddr::V4) == ip,
        _ => *a == ip,
    };
    if allow.is_empty() {
        ip.is_loopback()
    } else {
        allow.iter().any(same)
    }
}

/// Checks where to listen: a loopback address, or another one only with senders named
/// (`--allow`). Errors in a sentence.
pub fn check_listen(addr: &SocketAddr, allow: &[IpAddr]) -> Result<(), String> {
    if !addr.ip().is_loopback() && allow.is_empty() {
        return Err(format!(
            "--listen {addr}: not a loopback address; to take chunks from another machine, name its address with --allow"
        ));
    }
    Ok(())
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    b.get(at..at + 4)
        .map(|s| u32::from_le_bytes(s.try_into().expect("four bytes")))
}

fn f64_at(b: &[u8], at: usize) -> Option<f64> {
    b.get(at..at + 8)
        .map(|s| f64::from_le_bytes(s.try_into().expect("eight bytes")))
}

/// A chunk datagram (after `CPSC`) for a robot of `dof` joints, arriving at `now` on the
/// executor's clock; a sentence when it does not parse or is not a chunk.
pub fn parse_chunk(b: &[u8], dof: usize, now: f64) -> Result<Chunk, String> {
    let (n, h) = match (u32_at(b, 4), u32_at(b, 8)) {
        (Some(n), Some(h)) => (n as usize, h as usize),
        _ => return Err("a chunk datagram shorter than its header (28 bytes)".into()),
    };
    let (Some(rate), Some(observed)) = (f64_at(b, 12), f64_at(b, 20)) else {
        return Err("a chunk datagram shorter than its header (28 bytes)".into());
    };
    if n != dof {
        return Err(format!("a chunk for {n} joints; the robot has {dof}"));
    }
    let expected = 28 + n.saturating_mul(h).saturating_mul(8);
    if b.len() != expected {
        return Err(format!(
            "a chunk of {h} targets of {n} joints is {expected} bytes; the datagram has {}",
            b.len()
        ));
    }
    let targets = (0..h)
        .map(|k| {
            (0..n)
                .map(|j| f64_at(b, 28 + 8 * (k * n + j)).expect("length checked"))
                .collect()
        })
        .collect();
    // A stamp ahead of the robot's clock is refused here, before it reaches the stream
    // (one such chunk taken would make every honest chunk after it "go back").
    if observed > now + cps_chunks::CLOCK_TOLERANCE_S {
        return Err(cps_chunks::Refused::Ahead {
            observed_s: observed,
            now,
        }
        .to_string());
    }
    // The loop stamps the arrival; until then it is at least now.
    Chunk::new(observed, now.max(observed), rate, targets, None, dof).map_err(|e| e.to_string())
}

/// Serves the socket until the stream ends (`CPSE`), the run ends or `stop` is asked:
/// chunks from allowed senders to `feed`, state requests answered. Returns what it saw.
pub fn serve(
    socket: &UdpSocket,
    allow: &[IpAddr],
    feed: &mut ChunkFeed,
    stop: &StopToken,
) -> std::io::Result<SocketCounts> {
    socket.set_read_timeout(Some(Duration::from_millis(20)))?;
    let dof = feed.dof();
    let mut counts = SocketCounts::default();
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut q = vec![0.0; dof];
    let refuse = |counts: &mut SocketCounts, peer: &SocketAddr, why: String| {
        counts.refused += 1;
        if counts.reasons.len() < 5 {
            counts.reasons.push(format!("{peer}: {why}"));
        }
        let mut out = b"CPSR".to_vec();
        out.extend_from_slice(why.as_bytes());
        let _ = socket.send_to(&out, peer);
    };
    while feed.running() && !stop.is_stopped() {
        let (len, peer) = match socket.recv_from(&mut buf) {
            Ok(x) => x,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                continue;
            }
            // A previous answer's peer went away (ICMP): nothing to do with this stream.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
            // A signal (Ctrl-C, SIGTERM) woke the wait: the loop's condition asks the stop.
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if !allowed(&peer, allow) {
            counts.foreign += 1;
            continue;
        }
        let b = &buf[..len];
        match b.get(..4) {
            Some(b"CPS?") => {
                let t = feed.state().map_or(f64::NAN, |(t, s)| {
                    q.copy_from_slice(&s);
                    t
                });
                let mut out = b"CPSS".to_vec();
                out.extend_from_slice(&(dof as u32).to_le_bytes());
                out.extend_from_slice(&t.to_le_bytes());
                for x in &q {
                    out.extend_from_slice(&x.to_le_bytes());
                }
                counts.states += 1;
                let _ = socket.send_to(&out, peer);
            }
            Some(b"CPSC") => {
                let now = feed.state().map_or(0.0, |(t, _)| t);
                match parse_chunk(b, dof, now).and_then(|c| feed.push(c).map_err(|e| e.to_string()))
                {
                    Ok(()) => {
                        let mut out = b"CPSA".to_vec();
                        out.extend_from_slice(&(counts.chunks as u32).to_le_bytes());
                        counts.chunks += 1;
                        let _ = socket.send_to(&out, peer);
                    }
                    Err(why) => refuse(&mut counts, &peer, why),
                }
            }
            Some(b"CPSE") => {
                feed.close();
                break;
            }
            _ => refuse(
                &mut counts,
                &peer,
                "not a cps chunk message (CPS?, CPSC or CPSE)".into(),
            ),
        }
    }
    Ok(counts)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn datagram(n: u32, h: u32, rate: f64, observed: f64, values: &[f64]) -> Vec<u8> {
        let mut b = b"CPSC".to_vec();
        b.extend_from_slice(&n.to_le_bytes());
        b.extend_from_slice(&h.to_le_bytes());
        b.extend_from_slice(&rate.to_le_bytes());
        b.extend_from_slice(&observed.to_le_bytes());
        for v in values {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b
    }

    #[test]
    fn chunk_datagrams_parse_and_bad_ones_say_why() {
        let c = parse_chunk(&datagram(2, 2, 50.0, 0.1, &[1.0, 2.0, 3.0, 4.0]), 2, 0.2).unwrap();
        assert_eq!(c.targets, vec![vec![1.0, 2.0], vec![3.0, 4.0]]);
        assert_eq!((c.observed_s, c.rate_hz), (0.1, 50.0));
        let e = parse_chunk(&datagram(3, 1, 50.0, 0.1, &[1.0; 3]), 2, 0.2).unwrap_err();
        assert_eq!(e, "a chunk for 3 joints; the robot has 2");
        let e = parse_chunk(&datagram(2, 2, 50.0, 0.1, &[1.0; 3]), 2, 0.2).unwrap_err();
        assert!(e.contains("is 60 bytes; the datagram has 52"), "{e}");
        let e = parse_chunk(&datagram(2, 1, 50.0, 0.1, &[1.0, f64::NAN]), 2, 0.2).unwrap_err();
        assert!(e.contains("joint 2"), "{e}");
        let e = parse_chunk(b"CPSC\x02\0\0", 2, 0.0).unwrap_err();
        assert!(e.contains("shorter than its header"), "{e}");
        // A chunk stamped 1 000 s ahead of the robot's clock: taken, it locked out every
        // honest chunk after it ("times must not go back"); now refused alone.
        let e = parse_chunk(&datagram(2, 1, 50.0, 1000.2, &[1.0, 2.0]), 2, 0.2).unwrap_err();
        assert!(
            e.contains("later than the robot's clock now (0.2 s)"),
            "{e}"
        );
        assert!(parse_chunk(&datagram(2, 1, 50.0, 0.201, &[1.0, 2.0]), 2, 0.2).is_ok());
        // A count that would overflow is a length mismatch, not a panic.
        let e = parse_chunk(&datagram(2, u32::MAX, 50.0, 0.1, &[]), 2, 0.2).unwrap_err();
        assert!(e.contains("the datagram has 28"), "{e}");
    }

    #[test]
    fn only_loopback_unless_senders_are_named() {
        let lo: SocketAddr = "127.0.0.1:9".parse().unwrap();
        let other: SocketAddr = "10.0.0.5:9".parse().unwrap();
        assert!(allowed(&lo, &[]) && !allowed(&other, &[]));
        let ip: IpAddr = "10.0.0.5".parse().unwrap();
        assert!(allowed(&other, &[ip]) && !allowed(&lo, &[ip]));
        assert!(check_listen(&other, &[]).unwrap_err().contains("--allow"));
        // An IPv4 sender heard on a dual-stack socket, and an allowed address written
        // IPv4-mapped: the same senders (the sweep: `--allow` did not match them).
        let mapped: SocketAddr = "[::ffff:10.0.0.5]:9".parse().unwrap();
        assert!(allowed(&mapped, &[ip]));
        let mapped_ip: IpAddr = "::ffff:10.0.0.5".parse().unwrap();
        assert!(allowed(&other, &[mapped_ip]));
        let mapped_lo: SocketAddr = "[::ffff:127.0.0.1]:9".parse().unwrap();
        assert!(allowed(&mapped_lo, &[]));
        assert!(!allowed(&"[::ffff:10.0.0.6]:9".parse().unwrap(), &[ip]));
        assert!(check_listen(&lo, &[]).is_ok());
    }
}
