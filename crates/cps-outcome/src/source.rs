//! The text of input files, through cps's one reader (`cps-files`: size ceilings, regular
//! files only, UTF-8), and `file:line:column` places for messages.

use std::ops::Range;
use std::path::Path;

use crate::InputError;

pub use cps_files::bytes;
pub use cps_files::read::MAX_FILE_BYTES;

/// Reads a text file of at most `limit` bytes through cps's one reader
/// ([`cps_files::read`]): anything that is not a regular file (a FIFO would never end) and
/// a file over the limit are refused before a byte is read.
pub fn read_text(path: &Path, limit: u64, what: &str) -> Result<String, InputError> {
    cps_files::read::read_text(path, limit, what).map_err(InputError::from)
}

/// `file:line:column` of a byte offset.
pub fn location(path: &Path, text: &str, span: &Range<usize>) -> String {
    let before = &text[..span.start.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("{}:{line}:{column}", path.display())
}
