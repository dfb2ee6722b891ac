//! Counts estimated before they are allocated: a reader or a command asks here first how
//! many rows, frames, triangles or points it is about to hold, and a count past its ceiling
//! is refused with the key or flag that raises it — as `run`'s memory ceiling refuses a
//! run before it starts.

use crate::FileError;

/// Rows of a trajectory resampled at a rate over a span: 10 million (an hour at 1 kHz is
/// 3.6 million; 10 million rows of 7 joints are 560 MB of doubles).
pub const MAX_ROWS: u64 = 10_000_000;

/// Returns `count` as a `usize` when it is finite and at most `ceiling`; otherwise a
/// sentence naming `what` (the count and its place) and `raise` (what to change).
pub fn within(count: f64, ceiling: u64, what: &str, raise: &str) -> Result<usize, FileError> {
    if count.is_finite() && count >= 0.0 && count <= ceiling as f64 {
        Ok(count.ceil() as usize)
    } else {
        Err(FileError::TooMany {
            what: what.to_string(),
            count,
            ceiling,
            raise: raise.to_string(),
        })
    }
}

/// Rows of a span `span` (s) sampled every `dt` (s), both ends included, within
/// [`MAX_ROWS`].
pub fn rows(span: f64, dt: f64, what: &str, raise: &str) -> Result<usize, FileError> {
    let n = if span.is_finite() && dt > 0.0 && dt.is_finite() {
        (span / dt).round() + 1.0
    } else {
        f64::INFINITY
    };
    within(n, MAX_ROWS, what, raise)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_past_their_ceiling_name_the_key_that_raises_them() {
        assert_eq!(within(12.0, 100, "points", "x").unwrap(), 12);
        let e = rows(
            1e7,
            1e-3,
            "rows of walk.csv at 1 kHz",
            "shorten the recording",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("1e10") && e.contains("10000000") && e.contains("shorten"),
            "{e}"
        );
        assert!(rows(1e300, 1e-3, "rows", "").is_err());
        assert!(rows(f64::NAN, 1e-3, "rows", "").is_err());
        assert!(within(-1.0, 10, "rows", "").is_err());
        assert_eq!(rows(1.0, 1e-3, "rows", "").unwrap(), 1001);
    }
}
