//! Scene files (`configs/scenes/`): a robot placed in the world with its initial
//! configuration, named objects (way-point dummies) and point obstacles with the
//! clearance a movement must keep.

use std::path::Path;

use cps_kinematics::{IkConfig, IkSolution, IkTarget, KinematicsError, solve_ik};
use nalgebra::Vector3;
use serde::Deserialize;
use toml::Spanned;

use crate::robot_file::{Frame, RobotModel, load_robot};
use cps_outcome::InputError;
use cps_outcome::source::location;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    robot: RobotSection,
    #[serde(default)]
    object: Vec<Spanned<Object>>,
    #[serde(default)]
    obstacle: Vec<Spanned<ObstacleEntry>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ObstacleEntry {
    name: String,
    position: [f64; 3],
    clearance: f64,
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

/// How the stand-in server runs a scene ([`Scene::server_config`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StandInOptions {
    /// Address to bind.
    pub bind: String,
    /// Simulation step (s), 1e-6 to 10.
    pub dt: f64,
    /// The tip follows `/<robot>_target` every step.
    pub ik_following: bool,
    /// Seconds a silent client keeps its stepping hold, 0.01 to 86400.
    pub client_lease: f64,
    /// The largest request accepted (bytes), 64 to 2³⁰.
    pub max_message_bytes: usize,
    /// Connections served at once, 1 to 4096.
    pub max_clients: usize,
    /// Wall time each simulation step takes, seconds, 0 to 10 (a simulator's physics).
    pub step_cost: f64,
    /// Serve the scene without cps's script `/<robot>/cpsExecutor`, as a CoppeliaSim
    /// scene that lacks it: clients step call by call.
    pub without_script: bool,
}

/// A checked stand-in configuration and what it serves, in words.
#[derive(Debug, Clone)]
pub struct StandIn {
    /// The server's configuration.
    pub config: cps_coppelia::ServerConfig,
    /// The robot's names and the dummies, for the announcement.
    pub describe: String,
}

/// A point obstacle of a scene (`[[obstacle]]`): movements learned in the scene keep
/// `clearance` from `position` (world frame, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstacle {
    /// Where it is.
    pub position: [f64; 3],
    /// The distance to keep (> 0).
    pub clearance: f64,
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
    /// Named point obstacles (`[[obstacle]]`), in file order: movements learned in this
    /// scene keep their clearance.
    pub obstacles: Vec<(String, Obstacle)>,
}

/// Reads a scene file; a relative robot file path is resolved against the scene's folder.
pub fn load_scene(path: &Path) -> Result<Scene, InputError> {
    let text =
        cps_outcome::source::read_text(path, cps_outcome::source::MAX_FILE_BYTES, "scene file")?;
    parse_scene(path, &text)
}

/// The thesis's scene, built in (the text of `configs/scenes/thesis.toml`).
pub const THESIS_SCENE: &str = include_str!("../../../configs/scenes/thesis.toml");

/// The thesis's scene with a Franka Research 3 (the text of `configs/scenes/fr3.toml`):
/// the same table, way points and tool, the base placed so the FR3's start configuration
/// (inside its range, unlike the thesis's) puts the tool at the same start point.
pub const FR3_SCENE: &str = include_str!("../../../configs/scenes/fr3.toml");

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
    let mut obstacles: Vec<(String, Obstacle)> = Vec::new();
    for o in &file.obstacle {
        let v = o.get_ref();
        let at = || location(path, &text, &o.span());
        if v.name.is_empty()
            || v.name.contains('/')
            || objects.iter().any(|(n, _)| n == &v.name)
            || obstacles.iter().any(|(n, _)| n == &v.name)
        {
            return Err(InputError(format!(
                "{}: obstacle names are non-empty, without `/`, and not an object's or another obstacle's (got `{}`)",
                at(),
                v.name
            )));
        }
        if !v.position.iter().all(|x| x.is_finite()) {
            return Err(InputError(format!("{}: `position` must be finite", at())));
        }
        if !(v.clearance.is_finite() && v.clearance > 0.0) {
            return Err(InputError(format!(
                "{}: `clearance` must be finite and > 0 (got {})",
                at(),
                v.clearance
            )));
        }
        obstacles.push((
            v.name.clone(),
            Obstacle {
                position: v.position,
                clearance: v.clearance,
            },
        ));
    }
    Ok(Scene {
        robot,
        initial_q: q.clone(),
        objects,
        obstacles,
    })
}

/// Starts stand-in servers: all of them, or none (the started ones stop when dropped);
/// an address that cannot be bound is named.
pub fn start_stand_ins(
    configs: Vec<StandIn>,
) -> Result<Vec<cps_coppelia::StandInServer>, InputError> {
    configs
        .into_iter()
        .map(|s| {
            let bind = s.config.bind.clone();
            cps_coppelia::StandInServer::start(s.config)
                .map_err(|e| InputError(format!("--bind {bind}: {e}")))
        })
        .collect()
}

/// How [`serve_until`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServeEnd {
    /// `stop` was set.
    Stopped,
    /// The first server served `crash_after` requests (it had this many).
    CrashAsked(u64),
}

/// Serves until `stop` is set (or, with `crash_after`, until the first server has served
/// that many requests, for a front end that then exits as a crashing simulator would),
/// handing what clients logged with `sim.addLog` to `log` as CoppeliaSim's status bar
/// shows it — led by the endpoint when there are several servers.
pub fn serve_until(
    servers: &[cps_coppelia::StandInServer],
    crash_after: Option<u64>,
    stop: &std::sync::atomic::AtomicBool,
    log: &mut dyn FnMut(String),
) -> ServeEnd {
    let forward = |log: &mut dyn FnMut(String)| {
        for s in servers {
            let from = match servers.len() {
                1 => String::new(),
                _ => format!("{} ", s.endpoint()),
            };
            for line in s.take_logs() {
                log(format!(
                    "[{from}sim.addLog {}] {}",
                    line.level, line.message
                ));
            }
        }
    };
    while !stop.load(std::sync::atomic::Ordering::SeqCst) {
        forward(log);
        if let (Some(n), Some(first)) = (crash_after, servers.first())
            && first.requests() >= n
        {
            return ServeEnd::CrashAsked(first.requests());
        }
        let pause = if crash_after.is_some() { 2 } else { 100 };
        std::thread::sleep(std::time::Duration::from_millis(pause));
    }
    forward(log);
    ServeEnd::Stopped
}

/// Where a scene's tool starts and which of its objects the tool can reach
/// ([`Scene::reach`]).
#[derive(Debug)]
pub struct Reach {
    /// The tool position at the initial configuration, world frame.
    pub tool: Vector3<f64>,
    /// Initial joints outside their limits: (1-based joint, value, lower, upper).
    pub outside_limits: Vec<(usize, f64, f64, f64)>,
    /// Per object in file order: its name, position and the IK solution within the joint
    /// limits, or why there is none.
    pub objects: Vec<(String, Vector3<f64>, Result<IkSolution, KinematicsError>)>,
}

impl Reach {
    /// Whether every object is reachable.
    pub fn all_reachable(&self) -> bool {
        self.objects.iter().all(|o| o.2.is_ok())
    }
}

impl Scene {
    /// The thesis's scene (`configs/scenes/thesis.toml`, built in).
    pub fn thesis() -> Result<Self, InputError> {
        parse_scene(Path::new("configs/scenes/thesis.toml"), THESIS_SCENE)
    }

    /// A built-in scene by name (`thesis`, `fr3`) or a scene file.
    pub fn named_or_file(word: &str) -> Result<Self, InputError> {
        match word {
            "thesis" => Self::thesis(),
            "fr3" => parse_scene(Path::new("configs/scenes/fr3.toml"), FR3_SCENE),
            path => load_scene(Path::new(path)),
        }
    }

    /// The robot's name as CoppeliaSim's scene names it (`Panda` for `panda`).
    pub fn sim_robot_name(&self) -> String {
        match self.robot.name.as_str() {
            "panda" => "Panda".to_string(),
            other => other.to_string(),
        }
    }

    /// This scene for the stand-in server: the robot at its initial configuration, a
    /// dummy per object, simulation step `dt`, optionally the tip following
    /// `/<robot>_target`.
    pub fn stand_in(&self, dt: f64, ik_following: bool) -> cps_coppelia::SceneSetup {
        self.stand_in_costing(dt, ik_following, std::time::Duration::ZERO)
    }

    /// [`Self::stand_in`] whose every simulation step takes `step_cost` of wall time.
    pub fn stand_in_costing(
        &self,
        dt: f64,
        ik_following: bool,
        step_cost: std::time::Duration,
    ) -> cps_coppelia::SceneSetup {
        cps_coppelia::SceneSetup {
            robot_name: self.sim_robot_name(),
            chain: self.robot.chain.clone(),
            initial_q: self.initial_q.clone(),
            dummies: self
                .objects
                .iter()
                .map(|(n, p)| (n.clone(), [p.x, p.y, p.z]))
                .chain(
                    self.obstacles
                        .iter()
                        .map(|(n, o)| (n.clone(), [o.position[0], o.position[1], o.position[2]])),
                )
                .collect(),
            dt,
            ik_following,
            step_cost,
            script: true,
        }
    }

    /// The stand-in server's configuration for this scene (`cps-cli sim serve`): the
    /// options checked against their ranges (named by their command-line flags), and the
    /// sentence that announces the server.
    pub fn server_config(&self, options: &StandInOptions) -> Result<StandIn, InputError> {
        let o = options;
        let bad = |flag: &str, value: String, rule: &str| {
            Err(InputError(format!("--{flag} {value}: {rule}")))
        };
        if !(o.dt.is_finite() && (1e-6..=10.0).contains(&o.dt)) {
            return bad(
                "dt",
                format!("{:?}", o.dt),
                "the time step must be between 1e-6 and 10 seconds",
            );
        }
        if !(o.client_lease.is_finite() && (0.01..=86_400.0).contains(&o.client_lease)) {
            return bad(
                "client-lease",
                format!("{:?}", o.client_lease),
                "must be between 0.01 and 86400 seconds",
            );
        }
        if !(64..=1 << 30).contains(&o.max_message_bytes) {
            return bad(
                "max-message-bytes",
                o.max_message_bytes.to_string(),
                "must be between 64 and 1073741824",
            );
        }
        if !(o.step_cost.is_finite() && (0.0..=10.0).contains(&o.step_cost)) {
            return bad(
                "step-cost",
                format!("{:?} ms", o.step_cost * 1e3),
                "must be between 0 and 10000 ms",
            );
        }
        if !(1..=4096).contains(&o.max_clients) {
            return bad(
                "max-clients",
                o.max_clients.to_string(),
                "must be between 1 and 4096",
            );
        }
        let name = self.sim_robot_name();
        let describe = format!(
            "robot /{name}, joints /{name}_joint1..{}, tip /{name}_tip, IK target /{name}_target{}, {} dummies, {}",
            self.robot.chain.dof(),
            if o.ik_following {
                " followed by the tip"
            } else {
                ""
            },
            self.objects.len(),
            if o.without_script {
                "no scene script".to_string()
            } else {
                format!("scene script /{name}/cpsExecutor")
            }
        );
        Ok(StandIn {
            config: cps_coppelia::ServerConfig {
                bind: o.bind.clone(),
                scene: cps_coppelia::SceneSetup {
                    script: !o.without_script,
                    ..self.stand_in_costing(
                        o.dt,
                        o.ik_following,
                        std::time::Duration::from_secs_f64(o.step_cost),
                    )
                },
                limits: cps_coppelia::ServerLimits {
                    max_message_bytes: o.max_message_bytes,
                    max_connections: o.max_clients,
                    client_lease: std::time::Duration::from_secs_f64(o.client_lease),
                    ..cps_coppelia::ServerLimits::default()
                },
            },
            describe,
        })
    }

    /// A pool of `n` stand-in servers (`cps-cli sim pool`): server i binds the host of
    /// `options.bind` at port `base_port + 2i` (CoppeliaSim pairs each remote-API port
    /// with the next one), with the same scene and options. `n` is 1 to 256 and every port
    /// must be at most 65535.
    pub fn pool_configs(
        &self,
        options: &StandInOptions,
        n: usize,
        base_port: u16,
    ) -> Result<Vec<StandIn>, InputError> {
        if !(1..=256).contains(&n) {
            return Err(InputError(format!(
                "--n {n}: a pool has 1 to 256 simulators"
            )));
        }
        let last = u32::from(base_port) + 2 * (n as u32 - 1);
        if base_port == 0 || last > 65_535 {
            return Err(InputError(format!(
                "--base-port {base_port}: {n} simulators take ports {base_port} to {last} (every second one); they must lie within 1 to 65535"
            )));
        }
        let host = options
            .bind
            .rsplit_once(':')
            .map_or(options.bind.as_str(), |(h, _)| h);
        (0..n)
            .map(|i| {
                self.server_config(&StandInOptions {
                    bind: format!("{host}:{}", u32::from(base_port) + 2 * i as u32),
                    ..options.clone()
                })
            })
            .collect()
    }

    /// The tool at the initial configuration and, for every object, an IK solution within
    /// the joint limits from the robot's ready pose (seeded restarts, seed 1).
    pub fn reach(&self) -> Result<Reach, KinematicsError> {
        let chain = &self.robot.chain;
        let tool = chain.fk(&self.initial_q)?.translation.vector;
        let config = IkConfig {
            seed: 1,
            ..IkConfig::default()
        };
        let q = &self.initial_q;
        let outside_limits = chain.limits().map_or(Vec::new(), |(lo, hi)| {
            (0..q.len())
                .filter(|&i| q[i] < lo[i] || q[i] > hi[i])
                .map(|i| (i + 1, q[i], lo[i], hi[i]))
                .collect()
        });
        let objects = self
            .objects
            .iter()
            .map(|(name, p)| {
                let r = solve_ik(chain, &IkTarget::Position(*p), &self.robot.ready, &config);
                (name.clone(), *p, r)
            })
            .collect();
        Ok(Reach {
            tool,
            outside_limits,
            objects,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options() -> StandInOptions {
        StandInOptions {
            bind: "127.0.0.1:0".into(),
            dt: 0.01,
            ik_following: false,
            client_lease: 60.0,
            max_message_bytes: 1 << 20,
            max_clients: 4,
            step_cost: 0.005,
            without_script: false,
        }
    }

    #[test]
    fn stand_in_options_are_checked_and_carried_over() {
        let scene = Scene::thesis().unwrap();
        let ok = scene.server_config(&options()).unwrap();
        assert_eq!(
            ok.config.scene.step_cost,
            std::time::Duration::from_millis(5)
        );
        assert_eq!(ok.config.limits.max_connections, 4);
        for (bad, flag) in [
            (
                StandInOptions {
                    step_cost: -0.001,
                    ..options()
                },
                "--step-cost",
            ),
            (
                StandInOptions {
                    step_cost: f64::NAN,
                    ..options()
                },
                "--step-cost",
            ),
            (
                StandInOptions {
                    client_lease: 0.0,
                    ..options()
                },
                "--client-lease",
            ),
            (
                StandInOptions {
                    max_clients: 0,
                    ..options()
                },
                "--max-clients",
            ),
            (
                StandInOptions {
                    dt: 0.0,
                    ..options()
                },
                "--dt",
            ),
        ] {
            let e = scene.server_config(&bad).unwrap_err().to_string();
            assert!(e.starts_with(flag), "{e}");
        }
        // A pool: ports base, base + 2, …, on the host of `bind`.
        let pool = scene.pool_configs(&options(), 3, 23000).unwrap();
        let binds: Vec<&str> = pool.iter().map(|p| p.config.bind.as_str()).collect();
        assert_eq!(
            binds,
            ["127.0.0.1:23000", "127.0.0.1:23002", "127.0.0.1:23004"]
        );
        assert!(scene.pool_configs(&options(), 0, 23000).is_err());
        let e = scene
            .pool_configs(&options(), 10, 65530)
            .unwrap_err()
            .to_string();
        assert!(e.contains("65548"), "{e}");
    }
}
