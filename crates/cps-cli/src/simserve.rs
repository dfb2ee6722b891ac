//! `cps-cli sim serve`: the stand-in CoppeliaSim server on this machine.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Result;
use clap::Subcommand;
use cps_coppelia::StandInServer;

use cps_experiment::InputError;
use cps_experiment::scene::{Scene, StandInOptions, load_scene};

/// `cps-cli sim ...`.
#[derive(Subcommand, Debug)]
pub enum SimCommand {
    /// Serve CoppeliaSim's ZMQ remote API (protocol v2) with a kinematic robot, until
    /// Ctrl-C. Clients (cps or the official Python client) connect to the printed endpoint.
    Serve {
        /// Address to bind (loopback by default; other hosts only if you bind them).
        #[arg(long, default_value = "127.0.0.1:23000")]
        bind: String,
        /// Scene file (default: the thesis's scene, configs/scenes/thesis.toml).
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Simulation time step in seconds.
        #[arg(long, default_value_t = 0.05)]
        dt: f64,
        /// Make the tip follow `/<robot>_target` at every step, like CoppeliaSim's IK in
        /// the thesis's scene (otherwise the joints move only when set).
        #[arg(long)]
        ik_following: bool,
        /// A client silent for this many seconds loses its stepping hold, so the
        /// simulation runs on for the others (0.01 to 86400).
        #[arg(long, default_value_t = 60.0, allow_hyphen_values = true)]
        client_lease: f64,
        /// The largest request accepted, in bytes; a peer declaring more is disconnected
        /// before anything is allocated (64 to 1073741824).
        #[arg(long, default_value_t = cps_coppelia::DEFAULT_MAX_MESSAGE_BYTES)]
        max_message_bytes: usize,
        /// Connections served at once; more are closed on arrival (1 to 4096).
        #[arg(long, default_value_t = 64)]
        max_clients: usize,
        /// Make every simulation step take this many milliseconds of wall time (sleeping),
        /// as a simulator's physics would (CoppeliaSim: ≈ 5–8 ms a step).
        #[arg(
            long,
            default_value_t = 0.0,
            allow_hyphen_values = true,
            value_name = "MS"
        )]
        step_cost: f64,
        /// Exit abruptly once this many requests were served, as a crashing simulator
        /// would (to test how clients handle it).
        #[arg(long)]
        crash_after: Option<u64>,
    },
}

/// `cps-cli sim serve`.
pub fn sim(cmd: &SimCommand, interrupted: &AtomicBool) -> Result<ExitCode> {
    let SimCommand::Serve {
        bind,
        scene,
        dt,
        ik_following,
        client_lease,
        max_message_bytes,
        max_clients,
        step_cost,
        crash_after,
    } = cmd;
    let scene = match scene {
        Some(path) => load_scene(path)?,
        None => Scene::thesis()?,
    };
    let stand_in = scene.server_config(&StandInOptions {
        bind: bind.clone(),
        dt: *dt,
        ik_following: *ik_following,
        client_lease: *client_lease,
        max_message_bytes: *max_message_bytes,
        max_clients: *max_clients,
        step_cost: *step_cost / 1e3,
    })?;
    let server = StandInServer::start(stand_in.config)
        .map_err(|e| InputError(format!("--bind {bind}: {e}")))?;
    say!(
        "stand-in CoppeliaSim serving {} ({}); Ctrl-C stops",
        server.endpoint(),
        stand_in.describe
    );
    while !interrupted.load(Ordering::SeqCst) {
        // What clients log with sim.addLog goes to stderr, as CoppeliaSim's status bar.
        for line in server.take_logs() {
            eprintln!("[sim.addLog {}] {}", line.level, line.message);
        }
        if crash_after.is_some_and(|n| server.requests() >= n) {
            eprintln!(
                "crashing on purpose after {} requests (--crash-after)",
                server.requests()
            );
            std::process::exit(3);
        }
        std::thread::sleep(Duration::from_millis(if crash_after.is_some() {
            2
        } else {
            100
        }));
    }
    for line in server.take_logs() {
        eprintln!("[sim.addLog {}] {}", line.level, line.message);
    }
    say!(
        "stopped after {} requests ({} peers dropped for breaking the protocol or a limit)",
        server.requests(),
        server.dropped_peers()
    );
    Ok(ExitCode::SUCCESS)
}
