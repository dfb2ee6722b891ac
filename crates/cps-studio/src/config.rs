//! How the studio serves, and why it could not start: the same in every build.

/// How the studio serves.
#[derive(Debug, Clone)]
pub struct StudioConfig {
    /// Address to bind; loopback by default (`127.0.0.1:8080`).
    pub bind: String,
    /// The largest request body accepted, bytes (default 64 KiB).
    pub max_body_bytes: usize,
    /// The largest upload accepted (demonstration files, experiment files), bytes
    /// (default 8 MiB).
    pub max_upload_bytes: usize,
    /// Learning runs at once (default: the machine's cores); more wait their turn.
    pub workers: usize,
    /// The robot movements are executed on (default: the thesis's Panda).
    pub robot: Option<crate::robot::StudioRobot>,
    /// The task the page starts with (an experiment file opened with the studio); the
    /// page's own default, the thesis's task, without it.
    pub initial: Option<crate::files::OpenedTask>,
}

impl StudioConfig {
    /// Defaults, bound to `bind`.
    pub fn new(bind: impl Into<String>) -> Self {
        Self {
            bind: bind.into(),
            max_body_bytes: 64 * 1024,
            max_upload_bytes: 8 << 20,
            workers: std::thread::available_parallelism().map_or(2, |n| n.get()),
            robot: crate::robot::StudioRobot::thesis().ok(),
            initial: None,
        }
    }
}

/// Why the studio could not start.
#[derive(Debug, thiserror::Error)]
pub enum StudioError {
    /// The address could not be bound (taken, not local, not an address).
    #[error("cannot listen on {bind}: {message}")]
    Bind {
        /// The address.
        bind: String,
        /// The system's reason.
        message: String,
    },
    /// A setting out of range.
    #[error("invalid setting: {0}")]
    Config(String),
    /// This build has no web server (crate cps-studio without its `web` feature).
    #[error(
        "this build of cps has no web server (crate cps-studio without its `web` feature, as the README's first command builds it); `cargo install --path crates/cps-cli` and the tests build it"
    )]
    NotBuilt,
}
