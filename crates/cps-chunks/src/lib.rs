//! The chunk executor: what a learned policy (ACT, a diffusion policy, π0…) hands a robot
//! — action chunks, `H` joint targets at a known rate predicted from an observation —
//! followed on a streaming robot's command loop within its limits, above the contract
//! (`cps-robot`) it runs on.
//!
//! - [`chunk`]: a [`Chunk`], checked whole when made; [`StandIn`], a seeded policy
//!   stand-in.
//! - [`mod@follow`]: the [`Follower`], a moving reference followed one period at a time within
//!   velocity, acceleration and jerk limits: the executor's core.
//! - [`executor`]: the [`ChunkExecutor`], robot-free: chunks pushed as they arrive, the
//!   newest one's cubic as the follower's reference, refusals ([`Refused`]), braking on a
//!   stall.
//! - [`feed`]: where chunks come from on a loop — [`Replay`] (a recording) and the live
//!   pair [`live`] ([`ChunkFeed`], [`LiveSource`]) over bounded channels; nothing
//!   allocated or locked on the loop.
//! - [`run`]: the executor on a [`cps_robot::Streaming`] robot behind the guard
//!   ([`follow()`]); a recording's commands as a plan checked whole first
//!   ([`replay_plan`]); the follower's limits from a model ([`follow_limits`]).
//! - [`report`]: a run judged in numbers ([`FollowReport`]).
//! - [`error`]: [`FollowError`] and [`FeedError`].
//!
//! # Example
//! ```
//! use cps_chunks::{Chunk, ChunkExecutor, ChunkSettings, FollowLimits, Offer};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let limits = [FollowLimits { velocity: 2.0, acceleration: 10.0, jerk: 5000.0 }];
//! let mut ex = ChunkExecutor::new(&[0.0], &limits, 0.001, ChunkSettings::default())?;
//! // Ten targets at 10 Hz toward 0.1 rad, observed at 0 s and arrived at once.
//! let targets = (1..=10).map(|k| vec![0.01 * k as f64]).collect();
//! let chunk = Chunk::new(0.0, 0.0, 10.0, targets, None, 1)?;
//! assert!(matches!(ex.offer(chunk, 0.0), Offer::Taken { skipped: 0, .. }));
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

pub mod chunk;
pub mod error;
pub mod executor;
pub mod feed;
pub mod follow;
pub mod report;
pub mod run;

pub use chunk::{Chunk, ChunkError, StandIn};
pub use error::{FeedError, FollowError};
pub use executor::{CLOCK_TOLERANCE_S, ChunkCounts, ChunkExecutor, ChunkSettings, Offer, Refused};
pub use feed::{
    ChunkFeed, ChunkLog, ChunkSource, ChunkVerdict, LiveSource, MAX_HELD, Observed, Replay, Sink,
    StateCell, live,
};
pub use follow::{FollowLimits, Follower, GAINS};
pub use report::{BOUNDARY_MS, FollowReport, Peaks, Spread};
pub use run::{
    FollowSettings, Followed, TORQUE_RATE_SHARE, TakenAt, executor_for, follow, follow_limits,
    replay_plan, replay_with,
};
