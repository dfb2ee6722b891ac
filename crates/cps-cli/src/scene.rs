//! Scene files (`configs/scenes/`): a robot placed in the world with its initial
//! configuration, and named objects (way-point dummies). `cps-cli scene check` reports
//! where the tool is and which objects the tool can reach within the joint limits.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use cps_kinematics::{IkConfig, IkTarget, SerialChain, solve_ik};
use nalgebra::Vector3;
use serde::Deserialize;
use toml::Spanned;

use crate::experiment::{InputError, location};
use crate::robot_file::{Frame, RobotModel, load_robot};

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

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    robot: RobotSection,
    #[serde(default)]
    object: Vec<Spanned<Object>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotSection {
    model: String,
    tool: Option<String>,
    tip: Option<String>,
    initial_q: Spanned<Vec<f64>>,
    base: Option<Frame>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Object {
    name: String,
    position: [f64; 3],
}

/// A loaded scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The robot, placed at the scene's base.
    pub robot: RobotModel,
    /// The initial joint configuration.
    pub initial_q: Vec<f64>,
    /// Named objects and their world positions, in file order.
    pub objects: Vec<(String, Vector3<f64>)>,
}

/// Reads a scene file; a relative robot file path is resolved against the scene's folder.
pub fn load_scene(path: &Path) -> Result<Scene, InputError> {
    let text = crate::experiment::read_text(path, crate::experiment::MAX_FILE_BYTES, "scene file")?;
    parse_scene(path, &text)
}

/// The thesis's scene, built in (the text of `configs/scenes/thesis.toml`).
pub const THESIS_SCENE: &str = include_str!("../../../configs/scenes/thesis.toml");

/// Parses scene text (`path` names it in messages and resolves relative robot files).
pub fn parse_scene(path: &Path, text: &str) -> Result<Scene, InputError> {
    let text = text.to_string();
    let file: File = toml::from_str(&text).map_err(|e| {
        let at = e
            .span()
            .map(|s| location(path, &text, &s))
            .unwrap_or_else(|| path.display().to_string());
        InputError(format!("{at}: {}", e.message()))
    })?;
    let r = &file.robot;
    let model = if r.model.contains('.') {
        let p = path.parent().unwrap_or(Path::new(".")).join(&r.model);
        p.to_string_lossy().into_owned()
    } else {
        r.model.clone()
    };
    let mut robot = load_robot(&model, r.tool.as_deref(), r.tip.as_deref())
        .map_err(|e| InputError(format!("{}: [robot] {e}", path.display())))?;
    if let Some(b) = &r.base {
        let iso = b
            .isometry()
            .map_err(|m| InputError(format!("{}: [robot.base] {m}", path.display())))?;
        robot.chain = robot.chain.clone().with_base(iso);
    }
    let q = r.initial_q.get_ref();
    robot.chain.check(q).map_err(|e| {
        InputError(format!(
            "{}: [robot] `initial_q`: {e}",
            location(path, &text, &r.initial_q.span())
        ))
    })?;
    let mut objects = Vec::new();
    for o in &file.object {
        let v = o.get_ref();
        let at = || location(path, &text, &o.span());
        if v.name.is_empty() || v.name.contains('/') {
            return Err(InputError(format!(
                "{}: object names are non-empty and without `/` (got `{}`)",
                at(),
                v.name
            )));
        }
        if objects.iter().any(|(n, _)| n == &v.name) {
            return Err(InputError(format!(
                "{}: a second object named `{}`",
                at(),
                v.name
            )));
        }
        if !v.position.iter().all(|x| x.is_finite()) {
            return Err(InputError(format!("{}: `position` must be finite", at())));
        }
        objects.push((v.name.clone(), Vector3::from(v.position)));
    }
    Ok(Scene {
        robot,
        initial_q: q.clone(),
        objects,
    })
}

/// Joints of `q` outside the chain's limits, as (1-based joint, value, lower, upper).
fn outside_limits(chain: &SerialChain, q: &[f64]) -> Vec<(usize, f64, f64, f64)> {
    chain.limits().map_or(Vec::new(), |(lo, hi)| {
        (0..q.len())
            .filter(|&i| q[i] < lo[i] || q[i] > hi[i])
            .map(|i| (i + 1, q[i], lo[i], hi[i]))
            .collect()
    })
}

/// `cps-cli scene check`.
pub fn scene(cmd: &SceneCommand) -> Result<ExitCode> {
    let SceneCommand::Check { file, json } = cmd;
    let scene = load_scene(file)?;
    let chain = &scene.robot.chain;
    let tool = chain.fk(&scene.initial_q)?.translation.vector;
    let config = IkConfig {
        seed: 1,
        ..IkConfig::default()
    };
    let mut rows = Vec::new();
    let mut all = true;
    for (name, p) in &scene.objects {
        let r = solve_ik(chain, &IkTarget::Position(*p), &scene.robot.ready, &config);
        all &= r.is_ok();
        rows.push((name.clone(), *p, r));
    }
    let outside = outside_limits(chain, &scene.initial_q);
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
        for (j, v, lo, hi) in &outside {
            say!(
                "note: initial joint {j} = {v} lies outside its limits [{lo}, {hi}]; accepted as a start state"
            );
        }
        for (name, p, r) in &rows {
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
    Ok(if all {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
