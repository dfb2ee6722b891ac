//! What can go wrong reading a file, sizing an allocation or replacing an output: each a
//! sentence naming the place and the rule.

use std::path::PathBuf;

/// A file refused or failed, a count past its ceiling, an output that cannot be replaced.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FileError {
    /// The file could not be opened or read.
    #[error("{}: cannot read the {what}: {source}", path.display())]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// What it was read as ("scene file", "mesh").
        what: String,
        /// The system's reason.
        source: std::io::Error,
    },
    /// Not a regular file: a FIFO, a device, a socket or a folder.
    #[error("{}: the {what} must be a regular file, and this is {kind}", path.display())]
    NotRegular {
        /// The file.
        path: PathBuf,
        /// What it was read as.
        what: String,
        /// What it is ("a FIFO", "a device", "a folder").
        kind: &'static str,
    },
    /// Larger than the ceiling for its kind.
    #[error("{}: the {what} has {size} bytes, more than the {} cps reads{hint}", path.display(), crate::bytes(*ceiling as f64))]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// What it was read as.
        what: String,
        /// Its size (bytes).
        size: u64,
        /// The ceiling (bytes).
        ceiling: u64,
        /// How to go on (`; is it the right file?`).
        hint: String,
    },
    /// Text that is not UTF-8.
    #[error("{}: the {what} is not UTF-8 text (invalid byte at offset {offset})", path.display())]
    NotText {
        /// The file.
        path: PathBuf,
        /// What it was read as.
        what: String,
        /// The first invalid byte.
        offset: usize,
    },
    /// A library reading the file failed inside (a panic caught at the reader's edge):
    /// the file is malformed in a way the library does not say in words.
    #[error("{}: the {what} is malformed: the reader failed inside ({message})", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What it was read as.
        what: String,
        /// The library's words.
        message: String,
    },
    /// A count to allocate for, past its ceiling.
    #[error("{what}: {} would be held in memory, more than the ceiling of {ceiling}; {raise}", crate::number(*count, 4))]
    TooMany {
        /// What is counted, with its place ("rows of walk.csv resampled at 1000 Hz").
        what: String,
        /// The estimate.
        count: f64,
        /// The ceiling.
        ceiling: u64,
        /// What raises it, or what to change.
        raise: String,
    },
    /// An output that is not replaced, or a replacement that failed; the sentence says
    /// where every file is.
    #[error("{}: {message}", path.display())]
    Output {
        /// The output's place.
        path: PathBuf,
        /// What happened and where the files are.
        message: String,
    },
}

impl FileError {
    /// The file the error is about (none for a count).
    pub fn path(&self) -> Option<&std::path::Path> {
        match self {
            Self::Unreadable { path, .. }
            | Self::NotRegular { path, .. }
            | Self::TooLarge { path, .. }
            | Self::NotText { path, .. }
            | Self::Malformed { path, .. }
            | Self::Output { path, .. } => Some(path),
            Self::TooMany { .. } => None,
        }
    }

    /// The sentence without the file's name in front (for errors that print it themselves).
    pub fn reason(&self) -> String {
        let text = self.to_string();
        match self.path() {
            Some(p) => text
                .strip_prefix(&format!("{}: ", p.display()))
                .map_or(text.clone(), str::to_string),
            None => text,
        }
    }

    /// An output's failure.
    pub fn output(path: &std::path::Path, message: impl Into<String>) -> Self {
        Self::Output {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}
