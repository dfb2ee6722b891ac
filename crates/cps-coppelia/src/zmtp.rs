//! The part of ZMTP 3 (ZeroMQ's wire protocol, RFC 23/ZMTP and 37/ZMTP) the remote API
//! needs: the NULL security mechanism, REQ/REP and SUB/PUB peers, one connection each.
//!
//! Written here rather than taken from the `zeromq` crate because a peer on the network is
//! untrusted: every frame's declared size is checked against a ceiling **before** anything
//! is allocated for it (the crate reserved whatever a header declared, so a 64 GiB header
//! aborted the process), a body is read as its bytes arrive, and the number of frames in a
//! message is bounded. Commands other than `READY` (ZMTP 3.1's `PING`, …) are skipped.
//!
//! Interoperability is tested against libzmq (through the official Python client in the
//! CLI's tests) and against the `zeromq` crate's sockets (dev-dependency).

use std::io;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, BufStream};

pub use crate::DEFAULT_MAX_MESSAGE_BYTES;

/// Frames allowed in one message (the remote API uses two: an empty delimiter and a body).
const MAX_FRAMES: usize = 64;

/// A peer's role, as announced in the `READY` command's `Socket-Type` property.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SocketType {
    /// Requests (the client).
    Req,
    /// Replies (the server).
    Rep,
    /// Subscribes (protocol v1's step counter, client side).
    Sub,
    /// Publishes.
    Pub,
}

impl SocketType {
    fn name(self) -> &'static str {
        match self {
            Self::Req => "REQ",
            Self::Rep => "REP",
            Self::Sub => "SUB",
            Self::Pub => "PUB",
        }
    }

    fn peer(self) -> &'static [&'static str] {
        match self {
            Self::Req => &["REP", "ROUTER"],
            Self::Rep => &["REQ", "DEALER"],
            Self::Sub => &["PUB", "XPUB"],
            Self::Pub => &["SUB", "XSUB"],
        }
    }
}

/// Why a connection ended.
#[derive(Debug)]
pub enum ZmtpError {
    /// The transport failed or the peer closed the connection.
    Io(io::Error),
    /// The peer broke the protocol (message says how).
    Protocol(String),
    /// A frame or message was larger than the ceiling (nothing was allocated for it).
    TooLarge {
        /// What the peer declared (or what the message had reached).
        declared: u64,
        /// The ceiling.
        limit: usize,
    },
}

impl std::fmt::Display for ZmtpError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "{e}"),
            Self::Protocol(m) => write!(f, "ZMTP protocol error: {m}"),
            Self::TooLarge { declared, limit } => write!(
                f,
                "the peer sent a message of {declared} bytes, more than the limit of {limit} bytes"
            ),
        }
    }
}

impl std::error::Error for ZmtpError {}

impl From<io::Error> for ZmtpError {
    fn from(e: io::Error) -> Self {
        Self::Io(e)
    }
}

const FLAG_MORE: u8 = 0x01;
const FLAG_LONG: u8 = 0x02;
const FLAG_COMMAND: u8 = 0x04;

/// One ZMTP connection over a byte stream (a TCP socket), buffered both ways: a message
/// leaves in one write at `flush`, and frame headers are read from the buffer, not by a
/// system call each.
#[derive(Debug)]
pub struct Connection<S> {
    stream: BufStream<S>,
    max_message: usize,
}

/// One frame as read: its flags and body.
struct Frame {
    more: bool,
    command: bool,
    body: Vec<u8>,
}

impl<S: AsyncRead + AsyncWrite + Unpin> Connection<S> {
    /// Greets the peer and exchanges `READY` commands (NULL mechanism) as `socket_type`.
    /// Callers bound it with a timeout.
    pub async fn handshake(
        stream: S,
        socket_type: SocketType,
        max_message: usize,
    ) -> Result<Self, ZmtpError> {
        // Greeting: signature, version 3.0, mechanism NULL, as-server 0, filler.
        let mut greeting = [0u8; 64];
        greeting[0] = 0xff;
        greeting[9] = 0x7f;
        greeting[10] = 3;
        greeting[11] = 0;
        greeting[12..16].copy_from_slice(b"NULL");
        let mut stream = BufStream::new(stream);
        stream.write_all(&greeting).await?;
        stream.flush().await?;
        let mut peer = [0u8; 64];
        stream.read_exact(&mut peer[..10]).await?;
        if peer[0] != 0xff || peer[9] & 1 != 1 {
            return Err(ZmtpError::Protocol(
                "the peer's greeting is not ZMTP (wrong signature)".into(),
            ));
        }
        stream.read_exact(&mut peer[10..]).await?;
        if peer[10] < 3 {
            return Err(ZmtpError::Protocol(format!(
                "the peer speaks ZMTP {}.{}; 3.0 or later is required",
                peer[10], peer[11]
            )));
        }
        let mechanism = &peer[12..32];
        if &mechanism[..4] != b"NULL" || mechanism[4..].iter().any(|&b| b != 0) {
            return Err(ZmtpError::Protocol(format!(
                "the peer asks for the security mechanism `{}`; only NULL is spoken",
                String::from_utf8_lossy(mechanism).trim_end_matches('\0')
            )));
        }
        let mut conn = Self {
            stream,
            max_message,
        };
        let mut ready = Vec::with_capacity(64);
        ready.push(5);
        ready.extend_from_slice(b"READY");
        push_property(&mut ready, "Socket-Type", socket_type.name().as_bytes());
        if socket_type == SocketType::Req {
            push_property(&mut ready, "Identity", b"");
        }
        conn.write_frame(&ready, false, true).await?;
        conn.stream.flush().await?;
        let frame = conn.read_frame(0).await?;
        if !frame.command {
            return Err(ZmtpError::Protocol(
                "the peer sent a message before its READY command".into(),
            ));
        }
        let (name, props) = parse_command(&frame.body)?;
        match name {
            "READY" => {}
            "ERROR" => {
                return Err(ZmtpError::Protocol(format!(
                    "the peer refused the connection: {}",
                    String::from_utf8_lossy(props.get(1..).unwrap_or_default())
                )));
            }
            other => {
                return Err(ZmtpError::Protocol(format!(
                    "expected READY, got the command `{other}`"
                )));
            }
        }
        let peer_type = parse_properties(props)?
            .into_iter()
            .find(|(k, _)| k.eq_ignore_ascii_case("Socket-Type"))
            .map(|(_, v)| String::from_utf8_lossy(&v).into_owned())
            .ok_or_else(|| ZmtpError::Protocol("READY without a Socket-Type".into()))?;
        if !socket_type.peer().contains(&peer_type.as_str()) {
            return Err(ZmtpError::Protocol(format!(
                "a {} socket cannot talk to a {peer_type} socket",
                socket_type.name()
            )));
        }
        Ok(conn)
    }

    async fn write_frame(&mut self, body: &[u8], more: bool, command: bool) -> io::Result<()> {
        let mut flags = if more { FLAG_MORE } else { 0 };
        if command {
            flags |= FLAG_COMMAND;
        }
        if body.len() > 255 {
            let mut head = [0u8; 9];
            head[0] = flags | FLAG_LONG;
            head[1..].copy_from_slice(&(body.len() as u64).to_be_bytes());
            self.stream.write_all(&head).await?;
        } else {
            self.stream.write_all(&[flags, body.len() as u8]).await?;
        }
        self.stream.write_all(body).await
    }

    /// Reads one frame whose body may take at most `max_message - used` bytes; the size is
    /// checked before a byte of the body is stored.
    async fn read_frame(&mut self, used: usize) -> Result<Frame, ZmtpError> {
        let flags = self.stream.read_u8().await?;
        if flags & !(FLAG_MORE | FLAG_LONG | FLAG_COMMAND) != 0 {
            return Err(ZmtpError::Protocol(format!(
                "reserved frame flags set ({flags:#04x})"
            )));
        }
        let size = if flags & FLAG_LONG != 0 {
            self.stream.read_u64().await?
        } else {
            u64::from(self.stream.read_u8().await?)
        };
        let room = self.max_message.saturating_sub(used);
        if size > room as u64 {
            return Err(ZmtpError::TooLarge {
                declared: size.saturating_add(used as u64),
                limit: self.max_message,
            });
        }
        // Grow with what actually arrives: a peer that declares and never sends costs
        // nothing.
        let mut body = Vec::with_capacity((size as usize).min(64 << 10));
        (&mut self.stream).take(size).read_to_end(&mut body).await?;
        if body.len() as u64 != size {
            return Err(ZmtpError::Io(io::ErrorKind::UnexpectedEof.into()));
        }
        Ok(Frame {
            more: flags & FLAG_MORE != 0,
            command: flags & FLAG_COMMAND != 0,
            body,
        })
    }

    /// Receives one message (its frames), skipping commands; the whole message is bounded
    /// by the ceiling, its frame count by 64.
    pub async fn recv(&mut self) -> Result<Vec<Vec<u8>>, ZmtpError> {
        let mut frames = Vec::new();
        let mut used = 0usize;
        loop {
            let frame = self.read_frame(used).await?;
            if frame.command {
                if !frames.is_empty() {
                    return Err(ZmtpError::Protocol(
                        "a command inside a multi-frame message".into(),
                    ));
                }
                self.answer_command(&frame.body).await?;
                continue;
            }
            used += frame.body.len();
            frames.push(frame.body);
            if frames.len() > MAX_FRAMES {
                return Err(ZmtpError::Protocol(format!(
                    "a message of more than {MAX_FRAMES} frames"
                )));
            }
            if !frame.more {
                return Ok(frames);
            }
        }
    }

    /// ZMTP 3.1's PING is answered with PONG; other commands are ignored.
    async fn answer_command(&mut self, body: &[u8]) -> Result<(), ZmtpError> {
        let (name, rest) = parse_command(body)?;
        if name == "PING" && rest.len() >= 2 {
            let context = &rest[2..rest.len().min(2 + 16)];
            let mut pong = Vec::with_capacity(5 + context.len());
            pong.push(4);
            pong.extend_from_slice(b"PONG");
            pong.extend_from_slice(context);
            self.write_frame(&pong, false, true).await?;
            self.stream.flush().await?;
        }
        Ok(())
    }

    /// Sends one message made of `frames`.
    pub async fn send(&mut self, frames: &[&[u8]]) -> Result<(), ZmtpError> {
        for (i, f) in frames.iter().enumerate() {
            self.write_frame(f, i + 1 < frames.len(), false).await?;
        }
        self.stream.flush().await?;
        Ok(())
    }

    /// REQ side: sends `body` behind the empty delimiter and returns the reply's body.
    pub async fn request(&mut self, body: &[u8]) -> Result<Vec<u8>, ZmtpError> {
        self.send(&[&[], body]).await?;
        let mut frames = self.recv().await?;
        if frames.len() < 2 || !frames[0].is_empty() {
            return Err(ZmtpError::Protocol(
                "the reply has no empty delimiter frame".into(),
            ));
        }
        Ok(frames.swap_remove(1))
    }

    /// REP side: receives a request; returns its envelope (the frames up to and including
    /// the empty delimiter, echoed in the reply) and its body.
    pub async fn recv_request(&mut self) -> Result<(Vec<Vec<u8>>, Vec<u8>), ZmtpError> {
        let mut frames = self.recv().await?;
        let Some(delimiter) = frames.iter().position(Vec::is_empty) else {
            return Err(ZmtpError::Protocol(
                "a request without the empty delimiter frame".into(),
            ));
        };
        let body: Vec<u8> = frames.drain(delimiter + 1..).flatten().collect();
        Ok((frames, body))
    }

    /// REP side: replies behind the request's envelope.
    pub async fn reply(&mut self, envelope: &[Vec<u8>], body: &[u8]) -> Result<(), ZmtpError> {
        let mut frames: Vec<&[u8]> = envelope.iter().map(Vec::as_slice).collect();
        frames.push(body);
        self.send(&frames).await
    }

    /// SUB side: subscribes to every message (ZMTP 3.0's subscription message).
    pub async fn subscribe_all(&mut self) -> Result<(), ZmtpError> {
        self.send(&[&[1]]).await
    }
}

fn push_property(out: &mut Vec<u8>, name: &str, value: &[u8]) {
    out.push(name.len() as u8);
    out.extend_from_slice(name.as_bytes());
    out.extend_from_slice(&(value.len() as u32).to_be_bytes());
    out.extend_from_slice(value);
}

/// A command's name and the bytes after it.
fn parse_command(body: &[u8]) -> Result<(&str, &[u8]), ZmtpError> {
    let n = *body
        .first()
        .ok_or_else(|| ZmtpError::Protocol("an empty command".into()))? as usize;
    let name = body
        .get(1..1 + n)
        .and_then(|b| std::str::from_utf8(b).ok())
        .ok_or_else(|| ZmtpError::Protocol("a command with a malformed name".into()))?;
    Ok((name, &body[1 + n..]))
}

fn parse_properties(mut b: &[u8]) -> Result<Vec<(String, Vec<u8>)>, ZmtpError> {
    let bad = || ZmtpError::Protocol("malformed READY properties".into());
    let mut out = Vec::new();
    while !b.is_empty() {
        let n = b[0] as usize;
        let name = b.get(1..1 + n).ok_or_else(bad)?;
        let len = b.get(1 + n..5 + n).ok_or_else(bad)?;
        let len = u32::from_be_bytes(len.try_into().map_err(|_| bad())?) as usize;
        let value = b.get(5 + n..5 + n + len).ok_or_else(bad)?;
        out.push((String::from_utf8_lossy(name).into_owned(), value.to_vec()));
        b = &b[5 + n + len..];
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    async fn pair(max: usize) -> (Connection<tokio::io::DuplexStream>, tokio::io::DuplexStream) {
        let (a, b) = tokio::io::duplex(1 << 16);
        let server = tokio::spawn(Connection::handshake(a, SocketType::Rep, max));
        let mut b = b;
        let mut g = [0u8; 64];
        g[0] = 0xff;
        g[9] = 0x7f;
        g[10] = 3;
        g[12..16].copy_from_slice(b"NULL");
        b.write_all(&g).await.unwrap();
        let mut ready = vec![5];
        ready.extend_from_slice(b"READY");
        push_property(&mut ready, "Socket-Type", b"REQ");
        b.write_all(&[FLAG_COMMAND, ready.len() as u8])
            .await
            .unwrap();
        b.write_all(&ready).await.unwrap();
        let mut theirs = [0u8; 64];
        b.read_exact(&mut theirs).await.unwrap();
        let flags = b.read_u8().await.unwrap();
        assert_eq!(flags, FLAG_COMMAND);
        let n = b.read_u8().await.unwrap();
        let mut r = vec![0; n as usize];
        b.read_exact(&mut r).await.unwrap();
        assert_eq!(&r[..6], b"\x05READY");
        (server.await.unwrap().unwrap(), b)
    }

    fn rt() -> tokio::runtime::Runtime {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
    }

    #[test]
    fn a_huge_declared_frame_is_refused_before_allocation() {
        rt().block_on(async {
            let (mut conn, mut peer) = pair(1024).await;
            let mut head = vec![FLAG_LONG];
            head.extend_from_slice(&(64u64 << 30).to_be_bytes());
            peer.write_all(&head).await.unwrap();
            match conn.recv().await {
                Err(ZmtpError::TooLarge { declared, limit }) => {
                    assert_eq!(declared, 64 << 30);
                    assert_eq!(limit, 1024);
                }
                other => panic!("{other:?}"),
            }
        });
    }

    #[test]
    fn many_frames_add_up_against_the_ceiling() {
        rt().block_on(async {
            let (mut conn, mut peer) = pair(1000).await;
            for _ in 0..5 {
                peer.write_all(&[FLAG_MORE, 250]).await.unwrap();
                peer.write_all(&[7u8; 250]).await.unwrap();
            }
            assert!(matches!(conn.recv().await, Err(ZmtpError::TooLarge { .. })));
        });
    }

    #[test]
    fn a_request_round_trips_and_ping_is_answered() {
        rt().block_on(async {
            let (mut conn, mut peer) = pair(1 << 20).await;
            // PING with TTL 0 and context "ab".
            let ping = b"\x04PING\x00\x00ab";
            peer.write_all(&[FLAG_COMMAND, ping.len() as u8])
                .await
                .unwrap();
            peer.write_all(ping).await.unwrap();
            let body = vec![42u8; 300];
            peer.write_all(&[FLAG_MORE, 0]).await.unwrap();
            peer.write_all(&[FLAG_LONG]).await.unwrap();
            peer.write_all(&300u64.to_be_bytes()).await.unwrap();
            peer.write_all(&body).await.unwrap();
            let (env, got) = conn.recv_request().await.unwrap();
            assert_eq!(env, vec![Vec::<u8>::new()]);
            assert_eq!(got, body);
            // The PONG came first, carrying the context.
            let mut pong = [0u8; 9];
            peer.read_exact(&mut pong).await.unwrap();
            assert_eq!(&pong, b"\x04\x07\x04PONGab");
            conn.reply(&env, b"ok").await.unwrap();
            let mut reply = [0u8; 6];
            peer.read_exact(&mut reply).await.unwrap();
            assert_eq!(&reply, &[FLAG_MORE, 0, 0, 2, b'o', b'k']);
        });
    }

    #[test]
    fn bad_greetings_and_types_are_refused() {
        rt().block_on(async {
            let (a, mut b) = tokio::io::duplex(4096);
            let server = tokio::spawn(Connection::handshake(a, SocketType::Rep, 1024));
            b.write_all(b"GET / HTTP/1.1\r\n\r\n").await.unwrap();
            let mut buf = [0u8; 64];
            b.read_exact(&mut buf).await.unwrap();
            assert!(matches!(server.await.unwrap(), Err(ZmtpError::Protocol(_))));
            assert!(parse_properties(&[11, b'S']).is_err());
            assert!(parse_command(&[]).is_err());
            assert!(parse_command(&[9, b'a']).is_err());
        });
    }
}
