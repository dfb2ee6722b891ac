//! `cps-cli sim serve` and `cps-cli sim pool`: stand-in CoppeliaSim servers on this
//! machine, one or a pool.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use anyhow::Result;
use clap::{Args, Subcommand};
use cps_drive::stand_in::{self, ServeEnd, StandInOptions, serve_until, start_stand_ins};
use cps_experiment::InputError;
use cps_movement::scene::{Scene, load_scene};

/// What every stand-in server of a command serves.
#[derive(Args, Debug)]
pub struct Served {
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
    /// Serve the scene without cps's script `/<robot>/cpsExecutor` (clients then step
    /// call by call, as in a CoppeliaSim scene that lacks it).
    #[arg(long)]
    without_script: bool,
}

impl Served {
    fn options(&self, bind: &str) -> Result<(Scene, StandInOptions), InputError> {
        let scene = match &self.scene {
            Some(path) => load_scene(path)?,
            None => Scene::thesis()?,
        };
        let options = StandInOptions {
            bind: bind.to_string(),
            dt: self.dt,
            ik_following: self.ik_following,
            client_lease: self.client_lease,
            max_message_bytes: self.max_message_bytes,
            max_clients: self.max_clients,
            step_cost: self.step_cost / 1e3,
            without_script: self.without_script,
        };
        Ok((scene, options))
    }
}

/// `cps-cli sim ...`.
#[derive(Subcommand, Debug)]
pub enum SimCommand {
    /// Serve CoppeliaSim's ZMQ remote API (protocol v2) with a kinematic robot, until
    /// Ctrl-C. Clients (cps or the official Python client) connect to the printed endpoint.
    Serve {
        /// Address to bind (loopback by default; other hosts only if you bind them).
        #[arg(long, default_value = "127.0.0.1:23000")]
        bind: String,
        #[command(flatten)]
        served: Served,
        /// Exit abruptly once this many requests were served, as a crashing simulator
        /// would (to test how clients handle it).
        #[arg(long)]
        crash_after: Option<u64>,
    },
    /// Start N stand-in servers, simulator i on port P + 2i (CoppeliaSim pairs each
    /// remote-API port with the next), until Ctrl-C stops them all.
    Pool {
        /// How many simulators.
        #[arg(long)]
        n: usize,
        /// The first simulator's port.
        #[arg(long, default_value_t = 23000)]
        base_port: u16,
        /// The host to bind (loopback by default).
        #[arg(long, default_value = "127.0.0.1")]
        host: String,
        #[command(flatten)]
        served: Served,
    },
}

/// `cps-cli sim serve|pool`.
pub fn sim(cmd: &SimCommand, interrupted: &AtomicBool) -> Result<ExitCode> {
    let (servers, crash_after) = match cmd {
        SimCommand::Serve {
            bind,
            served,
            crash_after,
        } => {
            let (scene, options) = served.options(bind)?;
            let stand_in = stand_in::server_config(&scene, &options)?;
            let describe = stand_in.describe.clone();
            let servers = start_stand_ins(vec![stand_in])?;
            let at = servers[0].endpoint();
            say!("stand-in CoppeliaSim serving {at} ({describe}); Ctrl-C stops");
            (servers, *crash_after)
        }
        SimCommand::Pool {
            n,
            base_port,
            host,
            served,
        } => {
            let (scene, options) = served.options(&format!("{host}:0"))?;
            let configs = stand_in::pool_configs(&scene, &options, *n, *base_port)?;
            let describe = configs[0].describe.clone();
            let servers = start_stand_ins(configs)?;
            say!("{n} stand-in CoppeliaSim servers ({describe}); Ctrl-C stops them all");
            for s in &servers {
                say!("  {}", s.endpoint());
            }
            (servers, None)
        }
    };
    if let ServeEnd::CrashAsked(requests) =
        serve_until(&servers, crash_after, interrupted, &mut |l| {
            eprintln!("{l}")
        })
    {
        eprintln!("crashing on purpose after {requests} requests (--crash-after)");
        std::process::exit(3);
    }
    for s in &servers {
        say!("{} stopped after {}", s.endpoint(), s.served());
    }
    Ok(ExitCode::SUCCESS)
}
