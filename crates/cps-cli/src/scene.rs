//! `cps-cli scene check`: where the tool is at a scene's initial configuration and which
//! objects the tool can reach within the joint limits. The scene format and the check
//! are `cps_movement::scene`'s; this prints them.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;

use cps_movement::scene::load_scene;

use crate::robot::print;

/// `cps-cli scene ...`.
#[derive(Subcommand, Debug)]
pub enum SceneCommand {
    /// Load a scene, print the tool at the initial configuration and check that every
    /// object is reachable by the tool within the joint limits (exit 1 if one is not).
    Check {
        /// The scene file (TOML, as configs/scenes/thesis.toml).
        file: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

/// `cps-cli scene check`.
pub fn scene(cmd: &SceneCommand) -> Result<ExitCode> {
    let SceneCommand::Check { file, json } = cmd;
    let reach = load_scene(file)?.reach()?;
    print(&reach, *json)?;
    Ok(ExitCode::from(u8::from(!reach.all_reachable())))
}
