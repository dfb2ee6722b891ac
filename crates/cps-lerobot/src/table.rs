//! Parquet files read column by name, row by row (the `parquet` crate's record reader):
//! numbers, text and lists of them, every fault a sentence naming the file.

use std::path::Path;

use crate::error::LeRobotError;

// The reading itself (the `parquet` feature); without it, a refusal in words.
#[cfg(not(feature = "parquet"))]
#[path = "table/absent.rs"]
mod file;
#[cfg(feature = "parquet")]
#[path = "table/parquet.rs"]
mod file;
#[cfg(feature = "parquet")]
pub use file::open;
use file::read_unguarded;

/// One value of a row.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell {
    /// A whole number.
    Int(i64),
    /// A real number.
    Num(f64),
    /// Text.
    Text(String),
    /// A list (a vector feature).
    List(Vec<Cell>),
    /// No value.
    Null,
}

impl Cell {
    /// As a real number (whole numbers too).
    pub fn number(&self) -> Option<f64> {
        match self {
            Cell::Num(v) => Some(*v),
            Cell::Int(v) => Some(*v as f64),
            _ => None,
        }
    }

    /// As a whole number ≥ 0.
    pub fn index(&self) -> Option<usize> {
        match self {
            Cell::Int(v) if *v >= 0 => Some(*v as usize),
            _ => None,
        }
    }
}

/// The largest parquet file read: 16 GiB (LeRobot writes files of about 100 MB).
pub const MAX_PARQUET_BYTES: u64 = 16 << 30;

/// The named columns of the file's rows whose `filter` column (when given) lies in
/// `keep`, each row in `columns`' order. Row groups whose statistics exclude every kept
/// value are skipped unread.
pub fn read(
    path: &Path,
    columns: &[&str],
    filter: Option<(&str, std::ops::RangeInclusive<i64>)>,
) -> Result<Vec<Vec<Cell>>, LeRobotError> {
    cps_files::read::guard(path, "parquet file", || {
        read_unguarded(path, columns, filter)
    })?
}
