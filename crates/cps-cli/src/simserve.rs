//! `cps-cli sim serve`: the stand-in CoppeliaSim server on this machine.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Result;
use clap::Subcommand;
use cps_coppelia::{SceneSetup, ServerConfig, StandInServer};

use crate::experiment::InputError;
use crate::scene::{THESIS_SCENE, load_scene, parse_scene};

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
    },
}

/// `cps-cli sim serve`.
pub fn sim(cmd: &SimCommand, interrupted: &AtomicBool) -> Result<ExitCode> {
    let SimCommand::Serve {
        bind,
        scene,
        dt,
        ik_following,
    } = cmd;
    let scene = match scene {
        Some(path) => load_scene(path)?,
        None => parse_scene(
            std::path::Path::new("configs/scenes/thesis.toml"),
            THESIS_SCENE,
        )?,
    };
    let robot_name = match scene.robot.name.as_str() {
        "panda" => "Panda".to_string(),
        other => other.to_string(),
    };
    let setup = SceneSetup {
        robot_name: robot_name.clone(),
        chain: scene.robot.chain.clone(),
        initial_q: scene.initial_q.clone(),
        dummies: scene
            .objects
            .iter()
            .map(|(n, p)| (n.clone(), [p.x, p.y, p.z]))
            .collect(),
        dt: *dt,
        ik_following: *ik_following,
    };
    let server = StandInServer::start(ServerConfig {
        bind: bind.clone(),
        scene: setup,
    })
    .map_err(|e| InputError(format!("--bind {bind}: {e}")))?;
    say!(
        "stand-in CoppeliaSim serving {} (robot /{robot_name}, joints /{robot_name}_joint1..{}, tip /{robot_name}_tip, IK target /{robot_name}_target{}, {} dummies); Ctrl-C stops",
        server.endpoint(),
        scene.robot.chain.dof(),
        if *ik_following {
            " followed by the tip"
        } else {
            ""
        },
        scene.objects.len()
    );
    while !interrupted.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(100));
    }
    say!("stopped after {} requests", server.requests());
    Ok(ExitCode::SUCCESS)
}
