//! `cps-cli scene check`: where the tool is at a scene's initial configuration and which
//! objects the tool can reach within the joint limits. The scene format and the check
//! are `cps_movement::scene`'s; this prints them.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;

use cps_movement::scene::load_scene;

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
    let scene = load_scene(file)?;
    let reach = scene.reach()?;
    let (tool, outside, rows) = (reach.tool, &reach.outside_limits, &reach.objects);
    if *json {
        let objects: Vec<_> = rows
            .iter()
            .map(|(name, p, r)| match r {
                Ok(s) => serde_json::json!({"name": name, "position": [p.x, p.y, p.z],
                    "reachable": true, "q": s.q, "position_error": s.position_error}),
                Err(e) => serde_json::json!({"name": name, "position": [p.x, p.y, p.z],
                    "reachable": false, "error": e.to_string()}),
            })
            .collect();
        let out = serde_json::json!({
            "robot": scene.robot.name,
            "tool_at_initial_q": [tool.x, tool.y, tool.z],
            "initial_q_outside_limits": outside.iter().map(|o| o.0).collect::<Vec<_>>(),
            "objects": objects,
        });
        say!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        say!(
            "{} ({}): tool at the initial configuration ({:.4}, {:.4}, {:.4}) m",
            scene.robot.name,
            scene.robot.tool,
            tool.x,
            tool.y,
            tool.z
        );
        for (j, v, lo, hi) in outside {
            say!(
                "note: initial joint {j} = {v} lies outside its limits [{lo}, {hi}]; accepted as a start state"
            );
        }
        for (name, p, r) in rows {
            let at = format!("{name:<4} ({:.3}, {:.3}, {:.3})", p.x, p.y, p.z);
            match r {
                Ok(s) => say!(
                    "{at}: reachable within limits (error {:.1e} m), q = [{}]",
                    s.position_error,
                    s.q.iter()
                        .map(|v| format!("{v:.3}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                Err(e) => say!("{at}: NOT reachable: {e}"),
            }
        }
    }
    Ok(if reach.all_reachable() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
