//! The one reader and the one writer of cps: every file cps reads and every output it
//! replaces goes through here, so "bad input never hangs, never exhausts memory" and
//! "your files are safe" are properties of one crate rather than of each surface.
//!
//! - [`read`]: a file is read only if it is a regular file (a FIFO would wait forever, a
//!   device never ends, a folder is not a file), and only up to a ceiling the caller
//!   names, checked before reading.
//! - [`count`]: what a reader or a command would allocate for (rows resampled over a time
//!   span, frames × rate, triangles after instancing, points) is estimated first and
//!   refused past a ceiling, with the key or flag that raises it.
//! - [`replace`]: an output is written beside its place, the old one moved aside, the new
//!   one moved in, and only then what cps made of the old one removed — never following a
//!   symbolic link, never removing anything before the new output is complete, never
//!   leaving neither.
//!
//! The crate depends on nothing of cps's: every layer, the numerics' file formats
//! included, reads through it.
#![deny(missing_docs)]

pub mod count;
mod error;
pub mod read;
pub mod replace;

pub use error::FileError;

/// A byte count in words (`3 KiB`, `16 MiB`, `4.0 GiB`).
pub fn bytes(b: f64) -> String {
    const GIB: f64 = 1024.0 * 1024.0 * 1024.0;
    if b >= GIB {
        format!("{:.1} GiB", b / GIB)
    } else if b >= 1024.0 * 1024.0 {
        format!("{:.0} MiB", b / (1024.0 * 1024.0))
    } else {
        format!("{:.0} KiB", (b / 1024.0).max(1.0))
    }
}

/// A number for a message: at most `digits` significant digits, and never hundreds of
/// them (`1e300` stays `1e300`, `0.1 + 0.2` prints `0.3`).
pub fn number(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".into();
    }
    let digits = digits.max(1);
    let magnitude = x.abs().log10().floor();
    if !(-4.0..9.0).contains(&magnitude) {
        let s = format!("{:.*e}", digits - 1, x);
        // Trim the mantissa's trailing zeros: 1.500e3 → 1.5e3.
        return match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        };
    }
    let decimals = (digits as f64 - 1.0 - magnitude).max(0.0) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_at_every_magnitude() {
        assert_eq!(number(1e300, 6), "1e300");
        assert_eq!(number(-2.5e-12, 6), "-2.5e-12");
        assert_eq!(number(0.1 + 0.2, 6), "0.3");
        assert_eq!(number(1234.5678, 6), "1234.57");
        assert_eq!(number(1e7, 6), "10000000");
        assert_eq!(number(0.0, 6), "0");
        assert_eq!(number(f64::NAN, 6), "NaN");
        assert!(number(f64::MAX, 6).len() < 16);
        assert_eq!(bytes(4.0 * 1024.0 * 1024.0 * 1024.0), "4.0 GiB");
    }
}
