//! Serving over ZMTP (the crate's `zmq` feature): one connection per peer, within
//! [`ServerLimits`], on a runtime thread of its own.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use tokio::net::{TcpListener, TcpStream};
use tokio::sync::oneshot;

use super::log::{LogBuffer, LogLine};
use super::scene::{Sim, handle};
use super::{ServerConfig, ServerLimits};
use crate::CoppeliaError;
use crate::codec;
use crate::zmtp::{Connection, SocketType, ZmtpError};

/// A running stand-in server; dropping it stops it.
#[derive(Debug)]
pub struct StandInServer {
    endpoint: String,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
    stats: Arc<Stats>,
}

/// Counters shared with the serving thread.
#[derive(Debug, Default)]
struct Stats {
    log: Arc<LogBuffer>,
    requests: AtomicU64,
    dropped_peers: AtomicU64,
}

/// One connection: handshake, then request → reply until the peer leaves or misbehaves.
/// After each request the task yields, so every other ready client is served before this
/// one's next request (round-robin: a flooding client delays another by at most one
/// request per connected client).
async fn serve_peer(
    stream: TcpStream,
    sim: Arc<Mutex<Sim>>,
    limits: ServerLimits,
    stats: Arc<Stats>,
) {
    let _ = stream.set_nodelay(true);
    let handshake = Connection::handshake(stream, SocketType::Rep, limits.max_message_bytes);
    let mut conn = match tokio::time::timeout(limits.io_timeout, handshake).await {
        Ok(Ok(c)) => c,
        _ => {
            stats.dropped_peers.fetch_add(1, Ordering::Relaxed);
            return;
        }
    };
    loop {
        let (envelope, body) = match conn.recv_request().await {
            Ok(r) => r,
            Err(ZmtpError::Io(_)) => return,
            Err(_) => {
                stats.dropped_peers.fetch_add(1, Ordering::Relaxed);
                return;
            }
        };
        stats.requests.fetch_add(1, Ordering::Relaxed);
        let reply = {
            let mut sim = sim.lock().unwrap_or_else(|p| p.into_inner());
            codec::encode(&handle(&mut sim, &body))
        };
        let sent = tokio::time::timeout(limits.io_timeout, conn.reply(&envelope, &reply)).await;
        if !matches!(sent, Ok(Ok(()))) {
            stats.dropped_peers.fetch_add(1, Ordering::Relaxed);
            return;
        }
        tokio::task::yield_now().await;
    }
}

impl StandInServer {
    /// Binds and starts serving on a background thread.
    pub fn start(config: ServerConfig) -> Result<Self, CoppeliaError> {
        config
            .scene
            .chain
            .check(&config.scene.initial_q)
            .map_err(|e| CoppeliaError::InvalidConfig(format!("initial joint positions: {e}")))?;
        if !(config.scene.dt.is_finite() && config.scene.dt >= 1e-6 && config.scene.dt <= 10.0) {
            return Err(CoppeliaError::InvalidConfig(
                "the simulation time step must be between 1e-6 s and 10 s".into(),
            ));
        }
        config.limits.check()?;
        let bind = config.bind.trim_start_matches("tcp://").to_string();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let (stop_tx, stop_rx) = oneshot::channel::<()>();
        let stats = Arc::new(Stats::default());
        let counter = Arc::clone(&stats);
        let limits = config.limits.clone();
        let thread = std::thread::Builder::new()
            .name("cps-sim-server".into())
            .spawn(move || {
                let rt = match tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                {
                    Ok(rt) => rt,
                    Err(e) => {
                        let _ = ready_tx.send(Err(format!("cannot start the I/O runtime: {e}")));
                        return;
                    }
                };
                rt.block_on(async move {
                    let listener = match TcpListener::bind(&bind).await {
                        Ok(l) => l,
                        Err(e) => {
                            let _ = ready_tx.send(Err(format!("cannot bind {bind}: {e}")));
                            return;
                        }
                    };
                    let endpoint = match listener.local_addr() {
                        Ok(a) => format!("tcp://{a}"),
                        Err(e) => {
                            let _ = ready_tx.send(Err(format!("cannot bind {bind}: {e}")));
                            return;
                        }
                    };
                    let _ = ready_tx.send(Ok(endpoint));
                    let mut sim = Sim::new(config.scene, limits.client_lease);
                    sim.log = Arc::clone(&counter.log);
                    let sim = Arc::new(Mutex::new(sim));
                    let slots = Arc::new(tokio::sync::Semaphore::new(limits.max_connections));
                    let mut stop_rx = stop_rx;
                    loop {
                        let accepted = tokio::select! {
                            _ = &mut stop_rx => break,
                            a = listener.accept() => a,
                        };
                        let Ok((stream, _)) = accepted else {
                            // Out of descriptors and the like: wait a little, go on.
                            tokio::time::sleep(Duration::from_millis(10)).await;
                            continue;
                        };
                        let Ok(permit) = Arc::clone(&slots).try_acquire_owned() else {
                            counter.dropped_peers.fetch_add(1, Ordering::Relaxed);
                            drop(stream);
                            continue;
                        };
                        let (sim, limits, stats) =
                            (Arc::clone(&sim), limits.clone(), Arc::clone(&counter));
                        tokio::spawn(async move {
                            serve_peer(stream, sim, limits, stats).await;
                            drop(permit);
                        });
                    }
                });
            })
            .map_err(|e| {
                CoppeliaError::InvalidConfig(format!("cannot start the server thread: {e}"))
            })?;
        let endpoint = ready_rx
            .recv()
            .map_err(|_| CoppeliaError::InvalidConfig("the server thread ended early".into()))?
            .map_err(CoppeliaError::InvalidConfig)?;
        Ok(Self {
            endpoint,
            stop: Some(stop_tx),
            thread: Some(thread),
            stats,
        })
    }

    /// The bound endpoint, e.g. `tcp://127.0.0.1:40321`.
    pub fn endpoint(&self) -> &str {
        &self.endpoint
    }

    /// The messages clients sent with `sim.addLog` since the last call (CoppeliaSim
    /// prints them in its status bar; `cps-cli sim serve` prints them on stderr).
    pub fn take_logs(&self) -> Vec<LogLine> {
        self.stats.log.take()
    }

    /// Requests served so far.
    pub fn requests(&self) -> u64 {
        self.stats.requests.load(Ordering::Relaxed)
    }

    /// Peers disconnected for breaking the protocol or a limit (oversized messages, slow
    /// handshakes, replies not taken, connections beyond the limit).
    pub fn dropped_peers(&self) -> u64 {
        self.stats.dropped_peers.load(Ordering::Relaxed)
    }

    /// What the server did, in words: `N requests (M peers dropped for breaking the
    /// protocol or a limit)`.
    pub fn served(&self) -> String {
        format!(
            "{} requests ({} peers dropped for breaking the protocol or a limit)",
            self.requests(),
            self.dropped_peers()
        )
    }

    /// Blocks until the server stops (for `cps-cli sim serve`).
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for StandInServer {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
