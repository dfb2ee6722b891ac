//! `cps-cli studio`: the local web workbench (`cps-studio`), until Ctrl-C.

use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use clap::Args;
use cps_experiment::InputError;
use cps_studio::{StudioConfig, StudioServer};

/// Arguments of `cps-cli studio`.
#[derive(Args, Debug)]
pub struct StudioArgs {
    /// An experiment file whose via-point task the page starts with.
    file: Option<std::path::PathBuf>,
    /// Address to bind (loopback by default; other hosts only if you bind them).
    #[arg(long, default_value = "127.0.0.1:8080")]
    bind: String,
}

/// Serves the studio until Ctrl-C.
pub fn studio(args: &StudioArgs, interrupted: &AtomicBool) -> Result<ExitCode> {
    let mut config = StudioConfig::new(&args.bind);
    if let Some(file) = &args.file {
        config.initial = Some(cps_studio::files::open_path(file).map_err(|e| InputError(e.0))?);
    }
    let mut server = StudioServer::start(config)
        .map_err(|e| InputError(format!("--bind {}: {e}", args.bind)))?;
    say!(
        "cps studio at {}; open it in a browser, Ctrl-C stops",
        server.url()
    );
    while !interrupted.load(Ordering::Relaxed) {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    server.stop();
    Ok(ExitCode::SUCCESS)
}
