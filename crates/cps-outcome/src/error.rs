//! The two ways an experiment fails: its input (exit 2 on the command line) or something
//! while it runs (exit 1).

/// A problem with the user's input: a file, a key, a value, a path. The message names the
/// place (file:line:col where there is one) and the rule broken.
#[derive(Debug)]
pub struct InputError(pub String);

impl std::fmt::Display for InputError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for InputError {}

impl From<cps_files::FileError> for InputError {
    fn from(e: cps_files::FileError) -> Self {
        Self(e.to_string())
    }
}

/// A failure while running or writing: what was being done, and why (its `source`).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExperimentError {
    /// `context` failed because of `source`.
    #[error("{context}")]
    Failed {
        /// What was being done, as a sentence.
        context: String,
        /// Why it failed.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A failure described in full by its message.
    #[error("{0}")]
    Message(String),
    /// The input cannot be run (exit 2 on the command line): its sentence names the place.
    #[error(transparent)]
    Input(#[from] InputError),
}

/// `.context(...)` for library results: wraps any error with what was being done.
pub trait Context<T> {
    /// Wraps the error with `context()`, computed only on failure.
    fn context_with(self, context: impl FnOnce() -> String) -> Result<T, ExperimentError>;
}

impl<T, E: std::error::Error + Send + Sync + 'static> Context<T> for Result<T, E> {
    fn context_with(self, context: impl FnOnce() -> String) -> Result<T, ExperimentError> {
        self.map_err(|e| ExperimentError::Failed {
            context: context(),
            source: Box::new(e),
        })
    }
}
