//! What clients log with `sim.addLog`, kept for the server's owner: bounded, and never a
//! peer's control characters.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// The level names of CoppeliaSim's verbosity constants (flags masked off).
fn verbosity_name(v: i64) -> &'static str {
    match v & 0xfff {
        100 => "none",
        200 => "error",
        300 => "warning",
        400 => "loadinfo",
        410 => "question",
        420 => "script error",
        430 => "script warning",
        450 => "script info",
        500 => "info",
        600 => "debug",
        700 => "trace",
        800 => "trace lua",
        900 => "trace all",
        _ => "log",
    }
}

/// One message of `sim.addLog`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogLine {
    /// The verbosity level's name (`script info`, `warning`, …).
    pub level: &'static str,
    /// The message, control characters replaced, at most 4096 characters.
    pub message: String,
}

/// The messages clients logged, kept until the owner takes them (the oldest dropped
/// beyond 10 000).
#[derive(Debug, Default)]
pub(super) struct LogBuffer {
    lines: Mutex<std::collections::VecDeque<LogLine>>,
    dropped: AtomicU64,
}

impl LogBuffer {
    const MAX_LINES: usize = 10_000;

    pub(super) fn push(&self, verbosity: i64, message: &str) {
        // A peer's text never reaches a terminal as control sequences.
        let message: String = message
            .chars()
            .take(4096)
            .map(|c| if c.is_control() { '·' } else { c })
            .collect();
        let mut lines = self.lines.lock().unwrap_or_else(|p| p.into_inner());
        if lines.len() >= Self::MAX_LINES {
            lines.pop_front();
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
        lines.push_back(LogLine {
            level: verbosity_name(verbosity),
            message,
        });
    }

    #[cfg_attr(not(feature = "zmq"), allow(dead_code))]
    pub(super) fn take(&self) -> Vec<LogLine> {
        let mut lines = self.lines.lock().unwrap_or_else(|p| p.into_inner());
        lines.drain(..).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `sim.addLog` keeps a peer's message for the owner, never its control characters,
    /// at most 4096 characters of it, and at most 10 000 messages (the oldest dropped).
    #[test]
    fn logged_messages_are_kept_bounded_and_harmless() {
        let log = LogBuffer::default();
        log.push(450, "plain");
        log.push(300 | 0x10000, "\x1b[2Jred\x07");
        log.push(7, &"y".repeat(10_000));
        let lines = log.take();
        assert_eq!(
            lines[0],
            LogLine {
                level: "script info",
                message: "plain".into()
            }
        );
        assert_eq!(lines[1].level, "warning");
        assert_eq!(lines[1].message, "·[2Jred·");
        assert_eq!(lines[2].level, "log");
        assert_eq!(lines[2].message.chars().count(), 4096);
        assert!(log.take().is_empty(), "taken once");
        for k in 0..10_005 {
            log.push(450, &k.to_string());
        }
        let lines = log.take();
        assert_eq!(lines.len(), 10_000);
        assert_eq!(lines[0].message, "5");
        assert_eq!(log.dropped.load(Ordering::Relaxed), 5);
    }
}
