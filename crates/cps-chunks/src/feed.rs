//! Where chunks come from on a robot's command loop: a source polled every period, which
//! also takes back every chunk once the executor is done with it, so that nothing is
//! allocated or freed on the loop. Two sources: [`Replay`] (a recorded stream, each chunk
//! handed over at its arrival time) and the live pair [`live`] — a [`ChunkFeed`] a policy
//! pushes into from its own thread (Python, a socket's listener) and a [`LiveSource`] on
//! the loop, joined by bounded channels that neither side blocks on; the loop publishes
//! the measured state into a [`StateCell`] the feed reads without a lock.
//!
//! The channels are std's bounded ones (`sync_channel`): `try_send` and `try_recv` are
//! atomic operations on a ring; they take the channel's lock only to wake a side blocked
//! in `recv` or `send`, and neither side here ever blocks, so the loop never locks.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError, sync_channel};
use std::sync::{Arc, atomic::AtomicBool};

use crate::FeedError;
use crate::chunk::Chunk;
use crate::executor::Refused;
use cps_robot::Measured;

/// What the executor made of a chunk.
#[derive(Debug, Clone, PartialEq)]
pub enum ChunkVerdict {
    /// Taken, with how many of its targets were already past.
    Taken {
        /// Targets skipped.
        skipped: usize,
    },
    /// Refused, the motion going on as before.
    Refused(Refused),
}

/// Where the executor's chunks come from (see the module's text). Every method runs on the
/// robot's loop: none may block, lock or allocate.
pub trait ChunkSource: Send {
    /// The next chunk handed over by `now` (s since the run's start), if any; called until
    /// it answers None, each period. The source numbers the chunks it hands over from 0.
    fn poll(&mut self, now: f64) -> Option<Chunk>;
    /// What became of chunk `index`.
    fn judged(&mut self, index: usize, verdict: ChunkVerdict);
    /// Chunk `index` back, once the executor no longer follows it.
    fn retire(&mut self, index: usize, chunk: Chunk);
    /// Whether no chunk will come any more (the stream is over, the feed closed).
    fn ended(&self) -> bool;
    /// What the robot measured at `t` and the command in force, each period (a live
    /// source publishes them to the policy). Default: nothing.
    fn publish(&mut self, t: f64, measured: &Measured<'_>, command: &[f64]) {
        let _ = (t, measured, command);
    }
    /// The run is over (called once, after the loop). Default: nothing.
    fn over(&mut self) {}
}

/// Every chunk of a run with what became of it, in the order they came: what a recording
/// keeps (the replay file) and the report counts.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChunkLog {
    /// The chunks, in order, each with its verdict (None: the run ended before it was
    /// judged).
    pub entries: Vec<(Chunk, Option<ChunkVerdict>)>,
    /// Entries the loop could not hand back because the feed's side did not take them in
    /// time (counted, not kept).
    pub lost: usize,
    /// A feed's sink that failed ([`ChunkFeed::stream_to`]): the first failure.
    pub unwritten: Option<String>,
}

/// A recorded chunk stream replayed: each chunk handed over at the first period at or
/// after its `arrived_s` (a chunk whose arrival goes back is handed over right after the
/// one before, and the executor refuses it as it would live).
#[derive(Debug, Clone)]
pub struct Replay {
    slots: Vec<Option<Chunk>>,
    verdicts: Vec<Option<ChunkVerdict>>,
    next: usize,
}

impl Replay {
    /// A replay of `chunks`, in their order.
    pub fn new(chunks: Vec<Chunk>) -> Replay {
        let n = chunks.len();
        Replay {
            slots: chunks.into_iter().map(Some).collect(),
            verdicts: vec![None; n],
            next: 0,
        }
    }

    /// The chunks with their verdicts (chunks still held by an executor that was not asked
    /// for them back are missing).
    pub fn into_log(self) -> ChunkLog {
        ChunkLog {
            entries: self
                .slots
                .into_iter()
                .zip(self.verdicts)
                .filter_map(|(c, v)| c.map(|c| (c, v)))
                .collect(),
            lost: 0,
            unwritten: None,
        }
    }
}

impl ChunkSource for Replay {
    fn poll(&mut self, now: f64) -> Option<Chunk> {
        let chunk = self.slots.get_mut(self.next)?;
        if chunk.as_ref().is_some_and(|c| c.arrived_s <= now) {
            self.next += 1;
            chunk.take()
        } else {
            None
        }
    }
    fn judged(&mut self, index: usize, verdict: ChunkVerdict) {
        if let Some(v) = self.verdicts.get_mut(index) {
            *v = Some(verdict);
        }
    }
    fn retire(&mut self, index: usize, chunk: Chunk) {
        if let Some(slot) = self.slots.get_mut(index) {
            *slot = Some(chunk);
        }
    }
    fn ended(&self) -> bool {
        self.next == self.slots.len()
    }
}

/// The measured state shared between the loop (one writer) and a policy's thread: a
/// sequence lock over atomics — the writer never waits, a reader retries while a write is
/// under way. It holds, for `dof` joints, the positions, velocities, torques and the
/// command in force, in that order.
#[derive(Debug)]
pub struct StateCell {
    seq: AtomicU64,
    t: AtomicU64,
    values: Vec<AtomicU64>,
}

/// What a live robot measured in a period, as a policy's thread reads it
/// ([`ChunkFeed::observe`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Observed {
    /// The period's time on the executor's clock (s since the run started).
    pub t: f64,
    /// Joint positions (rad).
    pub q: Vec<f64>,
    /// Joint velocities (rad/s).
    pub dq: Vec<f64>,
    /// Joint torques (N m; see [`Measured::tau`]).
    pub tau: Vec<f64>,
    /// The command in force in that period (rad): what the executor targets now.
    pub command: Vec<f64>,
}

impl StateCell {
    /// A cell for `dof` joints, empty (no state yet: time NaN).
    pub fn new(dof: usize) -> StateCell {
        StateCell {
            seq: AtomicU64::new(0),
            t: AtomicU64::new(f64::NAN.to_bits()),
            values: (0..4 * dof).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    /// Writes the state (one writer only): what was measured and the command in force.
    pub fn write(&self, t: f64, measured: &Measured<'_>, command: &[f64]) {
        let dof = self.values.len() / 4;
        self.seq.fetch_add(1, Ordering::AcqRel);
        self.t.store(t.to_bits(), Ordering::Release);
        let parts = [measured.q, measured.dq, measured.tau, command];
        for (cells, part) in self.values.chunks(dof.max(1)).zip(parts) {
            for (cell, x) in cells.iter().zip(part) {
                cell.store(x.to_bits(), Ordering::Release);
            }
        }
        self.seq.fetch_add(1, Ordering::AcqRel);
    }

    /// The last state written into `out` (its first `out.len()` values: the positions,
    /// then the velocities, the torques, the command) with its time, or None before the
    /// first.
    pub fn read(&self, out: &mut [f64]) -> Option<f64> {
        loop {
            let before = self.seq.load(Ordering::Acquire);
            if before % 2 == 1 {
                std::hint::spin_loop();
                continue;
            }
            let t = f64::from_bits(self.t.load(Ordering::Acquire));
            for (x, cell) in out.iter_mut().zip(&self.values) {
                *x = f64::from_bits(cell.load(Ordering::Acquire));
            }
            if self.seq.load(Ordering::Acquire) == before {
                return (!t.is_nan()).then_some(t);
            }
        }
    }
}

/// What the loop hands back to the feed's side.
enum Back {
    ChunkVerdict(usize, ChunkVerdict),
    Chunk(usize, Chunk),
}

/// Chunks waiting for the loop: a policy is never more than a few ahead.
const WAITING: usize = 16;
/// Verdicts and chunks on their way back before the feed's side takes them.
const RETURNING: usize = 4096;

/// A policy's end of a live chunk stream (see [`live`]): pushes chunks, reads the robot's
/// state, keeps the log. Dropping it (or [`ChunkFeed::close`]) ends the stream: the arm
/// brakes to rest and the run ends.
pub struct ChunkFeed {
    to_loop: Option<SyncSender<Chunk>>,
    back: Receiver<Back>,
    state: Arc<StateCell>,
    running: Arc<AtomicBool>,
    dof: usize,
    log: Vec<(Option<Chunk>, Option<ChunkVerdict>)>,
    pushed: usize,
    sink: Option<Sink>,
    /// Chunks handed to the sink, in order: entries before this keep their times only.
    flushed: usize,
    /// The sink's first failure.
    unwritten: Option<String>,
}

/// Where a feed hands each chunk, in order, once the loop is done with it (a file).
pub type Sink = Box<dyn FnMut(usize, &Chunk) -> std::io::Result<()> + Send>;

/// With a sink: the most chunks the feed holds whole, waiting for an earlier one the arm
/// still follows to come back (refused chunks come back at once; a taken one when the
/// next is taken). A policy sending faster is refused until the arm catches up.
pub const MAX_HELD: usize = 64;

/// The loop's end of a live chunk stream (see [`live`]).
pub struct LiveSource {
    from_feed: Receiver<Chunk>,
    back: SyncSender<Back>,
    state: Arc<StateCell>,
    running: Arc<AtomicBool>,
    closed: bool,
    next: usize,
    lost: usize,
    /// For a simulated robot: the wall clock its time is held to (set at the first
    /// period).
    pace: Option<Option<std::time::Instant>>,
}

/// A live chunk stream for a robot of `dof` joints: the feed for the policy's thread, the
/// source for the robot's loop.
pub fn live(dof: usize) -> (ChunkFeed, LiveSource) {
    let (to_loop, from_feed) = sync_channel(WAITING);
    let (back_tx, back) = sync_channel(RETURNING);
    let state = Arc::new(StateCell::new(dof));
    let running = Arc::new(AtomicBool::new(true));
    (
        ChunkFeed {
            to_loop: Some(to_loop),
            back,
            state: state.clone(),
            running: running.clone(),
            dof,
            log: Vec::new(),
            pushed: 0,
            sink: None,
            flushed: 0,
            unwritten: None,
        },
        LiveSource {
            from_feed,
            back: back_tx,
            state,
            running,
            closed: false,
            next: 0,
            lost: 0,
            pace: None,
        },
    )
}

impl ChunkFeed {
    /// The robot's joint count.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// The robot's last measured joints and their time on the executor's clock (s since
    /// the run started), or None before the loop's first period.
    pub fn state(&mut self) -> Option<(f64, Vec<f64>)> {
        self.collect();
        let mut q = vec![0.0; self.dof];
        self.state.read(&mut q).map(|t| (t, q))
    }

    /// Everything the robot measured in its last period, with the command in force, or
    /// None before the loop's first period.
    pub fn observe(&mut self) -> Option<Observed> {
        self.collect();
        let dof = self.dof;
        let mut all = vec![0.0; 4 * dof];
        let t = self.state.read(&mut all)?;
        let part = |k: usize| all[k * dof..(k + 1) * dof].to_vec();
        Some(Observed {
            t,
            q: part(0),
            dq: part(1),
            tau: part(2),
            command: part(3),
        })
    }

    /// Whether the run is still going (false once it ended: finished, stopped, failed).
    pub fn running(&self) -> bool {
        self.running.load(Ordering::Acquire)
    }

    /// Hands `chunk` to the loop, which stamps its arrival when it takes it (within a
    /// period). Errors, in a sentence: the run is over or the feed closed, or the loop has
    /// chunks waiting it has not taken (a policy far ahead of the robot).
    pub fn push(&mut self, chunk: Chunk) -> Result<(), FeedError> {
        self.collect();
        let Some(tx) = &self.to_loop else {
            return Err(FeedError::Closed);
        };
        if self.sink.is_some() && self.pushed - self.flushed >= MAX_HELD {
            return Err(FeedError::Held(MAX_HELD));
        }
        match tx.try_send(chunk) {
            Ok(()) => {
                self.pushed += 1;
                Ok(())
            }
            Err(TrySendError::Full(_)) => Err(FeedError::Waiting(WAITING)),
            Err(TrySendError::Disconnected(_)) => Err(FeedError::Over),
        }
    }

    /// From now on, hands each chunk to `sink` in order once the loop is done with it, and
    /// keeps only its times and verdict: the memory a stream takes is bounded (at most
    /// [`MAX_HELD`] chunks whole) however long it runs.
    pub fn stream_to(&mut self, sink: Sink) {
        self.sink = Some(sink);
    }

    /// Ends the stream: the loop brakes the arm to rest and ends the run.
    pub fn close(&mut self) {
        self.to_loop = None;
    }

    /// Takes in what the loop handed back.
    fn collect(&mut self) {
        while let Ok(b) = self.back.try_recv() {
            let i = match &b {
                Back::ChunkVerdict(i, _) | Back::Chunk(i, _) => *i,
            };
            if self.log.len() <= i {
                self.log.resize_with(i + 1, || (None, None));
            }
            match b {
                Back::ChunkVerdict(_, v) => self.log[i].1 = Some(v),
                Back::Chunk(_, c) => self.log[i].0 = Some(c),
            }
        }
        let Some(sink) = &mut self.sink else {
            return;
        };
        while let Some((Some(c), _)) = self.log.get_mut(self.flushed) {
            hand_over(sink, &mut self.unwritten, self.flushed, c);
            self.flushed += 1;
        }
    }

    /// The log, once the run is over and its source handed back.
    pub fn into_log(mut self, source: LiveSource) -> ChunkLog {
        let lost = source.lost;
        drop(source);
        self.collect();
        // The end: chunks the loop never handed back leave holes; the rest are written.
        if let Some(sink) = &mut self.sink {
            for (i, (c, _)) in self.log.iter_mut().enumerate().skip(self.flushed) {
                if let Some(c) = c {
                    hand_over(sink, &mut self.unwritten, i, c);
                }
            }
        }
        ChunkLog {
            entries: self
                .log
                .into_iter()
                .filter_map(|(c, v)| c.map(|c| (c, v)))
                .collect(),
            lost,
            unwritten: self.unwritten,
        }
    }
}

/// Chunk `i` to the sink (its first failure kept), then only its times kept.
fn hand_over(sink: &mut Sink, unwritten: &mut Option<String>, i: usize, c: &mut Chunk) {
    if let Err(e) = sink(i, c)
        && unwritten.is_none()
    {
        *unwritten = Some(format!("chunk {i}: {e}"));
    }
    c.targets = Vec::new();
}

impl LiveSource {
    fn send(&mut self, b: Back) {
        if self.back.try_send(b).is_err() {
            // The feed's side has not taken the log in for a long while: the entry is
            // counted, not kept (nothing may grow on the loop).
            self.lost += 1;
        }
    }

    /// The same source holding a simulated robot to the wall clock: each period waits
    /// until its time has come, so a policy in another thread meets the robot as it would
    /// a real one. Not for a real robot's loop (its own clock paces it).
    pub fn paced(mut self) -> LiveSource {
        self.pace = Some(None);
        self
    }
}

impl ChunkSource for LiveSource {
    fn poll(&mut self, now: f64) -> Option<Chunk> {
        match self.from_feed.try_recv() {
            Ok(mut c) => {
                self.next += 1;
                c.arrived_s = now;
                Some(c)
            }
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => {
                self.closed = true;
                None
            }
        }
    }
    fn judged(&mut self, index: usize, verdict: ChunkVerdict) {
        self.send(Back::ChunkVerdict(index, verdict));
    }
    fn retire(&mut self, index: usize, chunk: Chunk) {
        self.send(Back::Chunk(index, chunk));
    }
    fn ended(&self) -> bool {
        self.closed
    }
    fn over(&mut self) {
        self.running.store(false, Ordering::Release);
    }
    fn publish(&mut self, t: f64, measured: &Measured<'_>, command: &[f64]) {
        if let Some(origin) = &mut self.pace {
            let origin = *origin.get_or_insert_with(std::time::Instant::now);
            let due = origin + std::time::Duration::from_secs_f64(t.max(0.0));
            let now = std::time::Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        self.state.write(t, measured, command);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(obs: f64) -> Chunk {
        Chunk::new(obs, obs, 10.0, vec![vec![0.0, 0.0]; 3], None, 2).unwrap()
    }

    #[test]
    fn a_replay_hands_each_chunk_over_at_its_arrival_and_keeps_it() {
        let mut r = Replay::new(vec![chunk(0.0), chunk(0.1)]);
        assert!(r.poll(0.0).is_some() && r.poll(0.05).is_none() && !r.ended());
        let c = r.poll(0.1).unwrap();
        assert!(r.ended() && r.poll(1.0).is_none());
        r.judged(1, ChunkVerdict::Taken { skipped: 0 });
        r.retire(1, c);
        let log = r.into_log();
        assert_eq!(log.entries.len(), 1, "chunk 0 was never handed back");
        assert_eq!(log.entries[0].1, Some(ChunkVerdict::Taken { skipped: 0 }));
    }

    /// The sweep: `follow --listen` kept every chunk ever sent (1.15 GB after 1.4 s of
    /// maximum-size chunks). With a sink, each chunk goes to it in order once the loop hands
    /// it back, and only its times stay; one the arm still follows holds at most
    /// `MAX_HELD` after it, and a policy sending faster is refused until it comes back.
    #[test]
    fn a_streamed_feed_writes_chunks_in_order_and_holds_a_bounded_window() {
        let (mut feed, mut source) = live(2);
        let written = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let w = written.clone();
        feed.stream_to(Box::new(move |i, c| {
            w.lock().unwrap().push((i, c.targets.len()));
            Ok(())
        }));
        // Chunk 0 is followed; the later ones are refused and come back at once, but wait
        // for chunk 0 to be written first.
        feed.push(chunk(0.0)).unwrap();
        let followed = source.poll(0.0).unwrap();
        source.judged(0, ChunkVerdict::Taken { skipped: 0 });
        let mut pushed = 1;
        let refused = loop {
            match feed.push(chunk(0.0)) {
                Ok(()) => pushed += 1,
                Err(e) => break e.to_string(),
            }
            let c = source.poll(0.0).unwrap();
            source.judged(
                pushed - 1,
                ChunkVerdict::Refused(Refused::Late {
                    last_s: 0.0,
                    now: 1.0,
                }),
            );
            source.retire(pushed - 1, c);
        };
        assert_eq!(pushed, MAX_HELD, "{refused}");
        assert!(
            refused.contains("faster than the arm takes them"),
            "{refused}"
        );
        assert!(
            written.lock().unwrap().is_empty(),
            "nothing written out of order"
        );
        // Chunk 0 comes back: it and every one held behind it are written, in order.
        source.retire(0, followed);
        feed.push(chunk(0.0)).unwrap();
        let w = written.lock().unwrap().clone();
        assert_eq!(w.len(), MAX_HELD);
        assert!(
            w.iter().enumerate().all(|(k, (i, n))| k == *i && *n == 3),
            "{w:?}"
        );
        // What the feed keeps of them is their times.
        assert!(
            feed.log[..MAX_HELD]
                .iter()
                .all(|(c, _)| c.as_ref().is_some_and(|c| c.targets.is_empty()))
        );
    }

    #[test]
    fn a_live_feed_reaches_the_loop_and_gets_its_log_back() {
        let (mut feed, mut source) = live(2);
        assert!(feed.state().is_none());
        let m = Measured {
            q: &[0.1, 0.2],
            dq: &[1.0, 2.0],
            tau: &[3.0, 4.0],
        };
        source.publish(0.5, &m, &[0.3, 0.4]);
        assert_eq!(feed.state(), Some((0.5, vec![0.1, 0.2])));
        let seen = feed.observe().unwrap();
        assert_eq!(
            (seen.t, seen.q, seen.dq, seen.tau, seen.command),
            (
                0.5,
                vec![0.1, 0.2],
                vec![1.0, 2.0],
                vec![3.0, 4.0],
                vec![0.3, 0.4]
            )
        );
        feed.push(chunk(0.4)).unwrap();
        let c = source.poll(0.6).unwrap();
        assert_eq!(c.arrived_s, 0.6, "stamped on arrival");
        source.judged(0, ChunkVerdict::Taken { skipped: 2 });
        source.retire(0, c);
        for _ in 0..WAITING {
            feed.push(chunk(0.5)).unwrap();
        }
        let full = feed.push(chunk(0.5)).unwrap_err().to_string();
        assert!(full.contains("waiting for the robot's loop"), "{full}");
        feed.close();
        while source.poll(0.7).is_some() {}
        assert!(source.ended());
        source.over();
        assert!(!feed.running());
        let log = feed.into_log(source);
        assert_eq!(log.entries.len(), 1);
        assert_eq!(log.entries[0].0.arrived_s, 0.6);
    }

    #[test]
    fn the_state_cell_never_tears_under_a_concurrent_writer() {
        let cell = Arc::new(StateCell::new(7));
        let writer = {
            let cell = cell.clone();
            std::thread::spawn(move || {
                for k in 0..200_000 {
                    let x = [k as f64; 7];
                    let m = Measured {
                        q: &x,
                        dq: &x,
                        tau: &x,
                    };
                    cell.write(x[0], &m, &x);
                }
            })
        };
        let mut q = [0.0; 28];
        let mut reads = 0;
        while !writer.is_finished() || reads == 0 {
            if let Some(t) = cell.read(&mut q) {
                assert!(q.iter().all(|x| *x == t), "torn: {t} {q:?}");
                reads += 1;
            }
        }
        writer.join().unwrap();
    }
}
