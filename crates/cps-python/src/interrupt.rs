//! Long Rust work with the GIL released and Ctrl-C honoured.
//!
//! Python runs signal handlers in the main thread only, between bytecodes, so Rust work
//! runs on a helper thread while the calling thread waits without the GIL and, every
//! 50 ms, lets Python check for signals (and report progress). A KeyboardInterrupt stops
//! the work's [`StopToken`] — a robot that moves brakes within its limits, runs see it
//! through their observer and stop after the current generation, keeping what they
//! finished — and is raised once the work has wound down.

use std::sync::mpsc;
use std::time::Duration;

use cps_robot::StopToken;
use pyo3::prelude::*;

use crate::errors::failure;

/// How often the waiting thread checks for signals.
const POLL: Duration = Duration::from_millis(50);

/// What to do while waiting: called on the calling thread with the GIL, every poll.
pub type OnPoll<'a> = &'a mut dyn FnMut(Python<'_>) -> PyResult<()>;

/// Runs `work(cancel)` on a helper thread with the GIL released. Returns its result and
/// the exception (KeyboardInterrupt, or one raised by `on_poll`) that cancelled it, if
/// any: the caller keeps what was done, then raises it.
pub fn detached_keep<T: Send>(
    py: Python<'_>,
    mut on_poll: Option<OnPoll<'_>>,
    work: impl FnOnce(&StopToken) -> T + Send,
) -> PyResult<(T, Option<PyErr>)> {
    let cancel = StopToken::new();
    let mut interrupt: Option<PyErr> = None;
    let outcome = std::thread::scope(|scope| {
        let (done_tx, done_rx) = mpsc::channel::<()>();
        // A Receiver is not Sync; the waits below borrow it from the detached closure.
        let done_rx = std::sync::Mutex::new(done_rx);
        let cancel = &cancel;
        let handle = scope.spawn(move || {
            let out = work(cancel);
            done_tx.send(()).ok();
            out
        });
        loop {
            let finished = py.detach(|| {
                match done_rx
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
                    .recv_timeout(POLL)
                {
                    Ok(()) | Err(mpsc::RecvTimeoutError::Disconnected) => true,
                    Err(mpsc::RecvTimeoutError::Timeout) => false,
                }
            });
            if finished {
                break py.detach(|| handle.join());
            }
            let polled = match on_poll.as_mut() {
                Some(f) if interrupt.is_none() => f(py),
                _ => Ok(()),
            };
            if let Err(e) = polled.and_then(|()| py.check_signals()) {
                cancel.stop();
                interrupt.get_or_insert(e);
            }
        }
    });
    let value = outcome.map_err(|panic| {
        let what = panic
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_string()))
            .unwrap_or_default();
        failure(format!("internal error in cps (please report it): {what}"))
    })?;
    Ok((value, interrupt))
}

/// [`detached_keep`] for work whose partial result is of no use: raises the
/// KeyboardInterrupt instead of returning.
pub fn detached<T: Send>(py: Python<'_>, work: impl FnOnce(&StopToken) -> T + Send) -> PyResult<T> {
    match detached_keep(py, None, work)? {
        (_, Some(e)) => Err(e),
        (value, None) => Ok(value),
    }
}

/// Multiply-adds below which work runs on the calling thread (GIL released, no helper
/// thread): a few milliseconds at most, so Ctrl-C is still answered promptly, and a
/// short call does not pay for a thread (≈ 0.1 ms with its first-touch page faults).
const INLINE_WORK: f64 = 2e7;

/// Runs `work` with the GIL released: inline when its estimated size (`multiply_adds`)
/// is small, else through [`detached`] so that Ctrl-C can stop it.
pub fn run<T: Send>(
    py: Python<'_>,
    multiply_adds: f64,
    work: impl FnOnce(&StopToken) -> T + Send,
) -> PyResult<T> {
    if multiply_adds < INLINE_WORK {
        let never = StopToken::new();
        Ok(py.detach(|| work(&never)))
    } else {
        detached(py, work)
    }
}

/// Whether a stop was asked for.
pub fn cancelled(cancel: &StopToken) -> bool {
    cancel.is_stopped()
}
