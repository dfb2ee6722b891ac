//! What can go wrong reading a take or turning it into a demonstration: always a sentence
//! that names the file and the place in it.

/// A take that cannot be read, or a demonstration that cannot be made from it.
#[derive(Debug, thiserror::Error)]
pub enum MocapError {
    /// The file could not be opened or read.
    #[error("{file}: {message}")]
    Io {
        /// The file.
        file: String,
        /// What the operating system said.
        message: String,
    },
    /// The file is not what it claims to be (truncated, corrupt, sizes that lie): the
    /// place is a byte offset, a parameter, a line or a column.
    #[error("{file}: {message}")]
    Format {
        /// The file.
        file: String,
        /// The problem and where.
        message: String,
    },
    /// The settings ask for what the take does not have (an unknown label, a rigid body
    /// that is not there, a calibration that does not hold).
    #[error("{0}")]
    Input(String),
    /// The take has it, but not well enough to make a demonstration (a marker lost for
    /// too long, too few markers to fit the body).
    #[error("{0}")]
    Refused(String),
}

impl MocapError {
    pub(crate) fn format(file: &str, message: impl Into<String>) -> Self {
        Self::Format {
            file: file.to_string(),
            message: message.into(),
        }
    }
}
