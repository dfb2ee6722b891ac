//! Stand-in CoppeliaSim servers for a scene file (`cps-cli sim serve` and `sim pool`): a
//! scene as the server's setup, the server's options checked against their ranges (named
//! by their command-line flags), the servers started, and served until a stop.
//!
//! Files about scenes are cps-movement's ([`Scene`]); starting a server is this layer's.

use cps_coppelia::{SceneSetup, ServerConfig, ServerLimits, StandInServer};
use cps_movement::scene::Scene;
use cps_outcome::InputError;

/// How the stand-in server runs a scene ([`server_config`]).
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
    pub config: ServerConfig,
    /// The robot's names and the dummies, for the announcement.
    pub describe: String,
}

/// `scene` for the stand-in server: the robot at its initial configuration, a dummy per
/// object and per obstacle, simulation step `dt`, optionally the tip following
/// `/<robot>_target`, every simulation step taking `step_cost` of wall time.
pub fn scene_setup(
    scene: &Scene,
    dt: f64,
    ik_following: bool,
    step_cost: std::time::Duration,
) -> SceneSetup {
    SceneSetup {
        robot_name: scene.sim_robot_name(),
        chain: scene.robot.chain.clone(),
        initial_q: scene.initial_q.clone(),
        dummies: scene
            .objects
            .iter()
            .map(|(n, p)| (n.clone(), [p.x, p.y, p.z]))
            .chain(
                scene
                    .obstacles
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
pub fn server_config(scene: &Scene, options: &StandInOptions) -> Result<StandIn, InputError> {
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
    let name = scene.sim_robot_name();
    let describe = format!(
        "robot /{name}, joints /{name}_joint1..{}, tip /{name}_tip, IK target /{name}_target{}, {} dummies, {}",
        scene.robot.chain.dof(),
        if o.ik_following {
            " followed by the tip"
        } else {
            ""
        },
        scene.objects.len(),
        if o.without_script {
            "no scene script".to_string()
        } else {
            format!("scene script /{name}/cpsExecutor")
        }
    );
    Ok(StandIn {
        config: ServerConfig {
            bind: o.bind.clone(),
            scene: SceneSetup {
                script: !o.without_script,
                ..scene_setup(
                    scene,
                    o.dt,
                    o.ik_following,
                    std::time::Duration::from_secs_f64(o.step_cost),
                )
            },
            limits: ServerLimits {
                max_message_bytes: o.max_message_bytes,
                max_connections: o.max_clients,
                client_lease: std::time::Duration::from_secs_f64(o.client_lease),
                ..ServerLimits::default()
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
    scene: &Scene,
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
            server_config(
                scene,
                &StandInOptions {
                    bind: format!("{host}:{}", u32::from(base_port) + 2 * i as u32),
                    ..options.clone()
                },
            )
        })
        .collect()
}

/// Starts stand-in servers: all of them, or none (the started ones stop when dropped);
/// an address that cannot be bound is named.
pub fn start_stand_ins(configs: Vec<StandIn>) -> Result<Vec<StandInServer>, InputError> {
    configs
        .into_iter()
        .map(|s| {
            let bind = s.config.bind.clone();
            StandInServer::start(s.config).map_err(|e| InputError(format!("--bind {bind}: {e}")))
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
    servers: &[StandInServer],
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
        let ok = server_config(&scene, &options()).unwrap();
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
            let e = server_config(&scene, &bad).unwrap_err().to_string();
            assert!(e.starts_with(flag), "{e}");
        }
        // A pool: ports base, base + 2, …, on the host of `bind`.
        let pool = pool_configs(&scene, &options(), 3, 23000).unwrap();
        let binds: Vec<&str> = pool.iter().map(|p| p.config.bind.as_str()).collect();
        assert_eq!(
            binds,
            ["127.0.0.1:23000", "127.0.0.1:23002", "127.0.0.1:23004"]
        );
        assert!(pool_configs(&scene, &options(), 0, 23000).is_err());
        let e = pool_configs(&scene, &options(), 10, 65530)
            .unwrap_err()
            .to_string();
        assert!(e.contains("65548"), "{e}");
    }
}
