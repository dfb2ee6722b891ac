//! The text of input files: bounded reading (size ceilings, regular files only, UTF-8)
//! and `file:line:column` places for messages. Every file format of the crate reads
//! through here.

use std::ops::Range;
use std::path::Path;

use crate::InputError;

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// The largest configuration file read (experiments, scenes, robots, models): 16 MiB.
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// Reads a text file of at most `limit` bytes, refusing a larger one before reading it
/// (and anything that is not a regular file: a FIFO or a device would never end).
pub fn read_text(path: &Path, limit: u64, what: &str) -> Result<String, InputError> {
    use std::io::Read;
    let fail = |m: String| InputError(format!("{}: {m}", path.display()));
    let meta = std::fs::metadata(path).map_err(|e| fail(format!("cannot read the {what}: {e}")))?;
    if !meta.is_file() {
        return Err(fail(format!("the {what} must be a regular file")));
    }
    if meta.len() > limit {
        return Err(fail(format!(
            "the {what} has {} bytes, more than the {} cps reads; is it the right file?",
            meta.len(),
            bytes(limit as f64)
        )));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::fs::File::open(path)
        .and_then(|f| f.take(limit + 1).read_to_end(&mut bytes))
        .map_err(|e| fail(format!("cannot read the {what}: {e}")))?;
    if bytes.len() as u64 > limit {
        return Err(fail(format!(
            "the {what} grew beyond {limit} bytes while being read"
        )));
    }
    String::from_utf8(bytes).map_err(|e| {
        fail(format!(
            "the {what} is not UTF-8 text (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ))
    })
}

/// Bytes in words.
pub fn bytes(b: f64) -> String {
    if b >= GIB {
        format!("{:.1} GiB", b / GIB)
    } else if b >= 1024.0 * 1024.0 {
        format!("{:.0} MiB", b / (1024.0 * 1024.0))
    } else {
        format!("{:.0} KiB", (b / 1024.0).max(1.0))
    }
}

/// `file:line:column` of a byte offset.
pub fn location(path: &Path, text: &str, span: &Range<usize>) -> String {
    let before = &text[..span.start.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("{}:{line}:{column}", path.display())
}
