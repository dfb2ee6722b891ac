//! Stopping a run: a token handed to everything that moves a robot, instead of global flags.
//!
//! The host program makes one [`StopToken`] per command (the command line per process,
//! Python per call) and passes clones down: the command line's Ctrl-C and SIGTERM handler,
//! Python's KeyboardInterrupt and a library caller's cancel all call [`StopToken::stop`];
//! every robot loop polls [`StopToken::is_stopped`] (a relaxed atomic load, nothing
//! allocated or locked) and brakes within its limits. While a robot moves it holds a
//! [`Moving`] guard, so a host can tell that a second Ctrl-C must not end the process
//! before the brake has finished.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

#[derive(Debug, Default)]
struct Shared {
    stop: AtomicBool,
    moving: AtomicUsize,
}

/// A request to stop, shared between whoever may ask (a signal handler, a caller) and
/// whatever runs (a robot's loop, a learner between generations). Cloning shares it.
#[derive(Debug, Clone, Default)]
pub struct StopToken(Arc<Shared>);

impl StopToken {
    /// A token nobody has stopped yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks every run holding this token to stop: robots brake within their limits, learners
    /// stop after the current generation. It cannot be taken back.
    pub fn stop(&self) {
        self.0.stop.store(true, Ordering::SeqCst);
    }

    /// Whether a stop was asked for.
    #[inline]
    pub fn is_stopped(&self) -> bool {
        self.0.stop.load(Ordering::Relaxed)
    }

    /// The flag itself, for loops written against `&AtomicBool` (cps-franka's realtime loop,
    /// cps-ros2's action client): it is set when the token is stopped.
    pub fn flag(&self) -> &AtomicBool {
        &self.0.stop
    }

    /// Marks a robot as moving until the guard is dropped.
    pub fn moving(&self) -> Moving {
        self.0.moving.fetch_add(1, Ordering::SeqCst);
        Moving(self.0.clone())
    }

    /// Whether any robot holding this token is moving now (a host must not end the process
    /// then: the robot's controlled stop has to finish first).
    pub fn is_moving(&self) -> bool {
        self.0.moving.load(Ordering::SeqCst) > 0
    }
}

/// Held while a robot moves (see [`StopToken::moving`]).
#[derive(Debug)]
#[must_use = "the robot counts as moving only while the guard lives"]
pub struct Moving(Arc<Shared>);

impl Drop for Moving {
    fn drop(&mut self) {
        self.0.moving.fetch_sub(1, Ordering::SeqCst);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_stop_and_the_moving_count() {
        let token = StopToken::new();
        let other = token.clone();
        assert!(!other.is_stopped() && !other.is_moving());
        {
            let _a = token.moving();
            let _b = other.moving();
            assert!(token.is_moving());
        }
        assert!(!token.is_moving());
        other.stop();
        assert!(token.is_stopped());
        assert!(token.flag().load(Ordering::Relaxed));
    }
}
