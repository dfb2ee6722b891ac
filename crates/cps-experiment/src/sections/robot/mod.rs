//! `[robot]` of the kinds that execute: the scene's robot and start, and which backend
//! executes — the in-process robot, CoppeliaSim, a Franka, a ROS 2 controller or the robot
//! with dynamics — read into a [`RobotChoice`] with every key checked and placed. One
//! module per backend (`kinematic`, `coppelia`, `franka`, `ros2`, `dynamics`) holds the
//! keys only it reads and turns them into its [`BackendChoice`]; this module holds the
//! section as serde reads it, the keys every backend shares (`scene`, `tolerance`,
//! `max_iterations_per_sample`, `limits`) and the dispatch. Opening the chosen robot is
//! [`crate::robots`]'s.

use std::path::Path;
use std::time::Duration;

use cps_learn::RobotSetup;
use cps_robot::ExecutionConfig;
use cps_ros2::robot::Ros2Settings;
use serde::Deserialize;
use toml::Spanned;

mod coppelia;
mod dynamics;
mod franka;
mod kinematic;
mod ros2;

use super::Sections;
use crate::InputError;
use cps_movement::scene::{THESIS_SCENE, load_scene, parse_scene};

/// `[robot]`: the robot, where it stands and which backend executes on it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSection {
    /// `thesis` (the built-in scene, `configs/scenes/thesis.toml`), `fr3` (the same with a
    /// Franka Research 3, `configs/scenes/fr3.toml`) or a scene file (robot, base, initial
    /// configuration), relative to the experiment file; default: `thesis`.
    scene: Option<Spanned<String>>,
    #[serde(default)]
    backend: BackendKind,
    endpoint: Option<Spanned<String>>,
    /// A pool of simulators (`kind = "viapoint_executed"`).
    endpoints: Option<Spanned<Vec<Spanned<String>>>>,
    /// The robot's alias in CoppeliaSim (`/Panda`, `/Panda_joint1`, …).
    name: Option<String>,
    dt: Option<Spanned<f64>>,
    timeout: Option<Spanned<f64>>,
    tolerance: Option<Spanned<f64>>,
    max_iterations_per_sample: Option<Spanned<usize>>,
    control: Option<Spanned<Control>>,
    /// `backend = "franka"`: the robot's address (`ip` or `ip:port`).
    host: Option<Spanned<String>>,
    /// `backend = "franka"`, `kind = "viapoint_executed"`: several robots.
    hosts: Option<Spanned<Vec<Spanned<String>>>>,
    /// `backend = "franka"`: `fr3` or `panda` (default: the scene's robot).
    arm: Option<Spanned<String>>,
    /// `backend = "franka"`: `enforce` (default) or `ignore`.
    realtime: Option<Spanned<String>>,
    /// `backend = "ros2"`: the joint_trajectory_controller (`/panda_arm_controller`);
    /// `backend = "dynamics"`: the joint-level controller (`joint_pd`, `computed_torque`,
    /// `joint_impedance`).
    controller: Option<Spanned<String>>,
    /// `backend = "dynamics"`: the controller's first gains, one per joint (kp, or the
    /// impedance's stiffness).
    kp: Option<Spanned<Vec<f64>>>,
    /// `backend = "dynamics"`: its second gains (kv, or the impedance's damping).
    kv: Option<Spanned<Vec<f64>>>,
    /// `backend = "dynamics"`: the joints' drive (`franky-sim`, `rigid`).
    drive: Option<Spanned<String>>,
    /// `backend = "dynamics"`: `euler` (default) or `rk4`.
    integrator: Option<Spanned<String>>,
    /// `backend = "dynamics"`: measurement noise, rad (default 0).
    noise: Option<Spanned<f64>>,
    /// `backend = "dynamics"`: the noise's seed (default 0).
    seed: Option<Spanned<u64>>,
    /// `backend = "dynamics"`: a calibration file (`cps-cli identify`), relative to the
    /// experiment file: the robot's identified gains, lag and drives.
    calibration: Option<Spanned<String>>,
    /// `backend = "ros2"`: the JointState topic (default `/joint_states`).
    joint_states: Option<Spanned<String>>,
    /// `backend = "ros2"`: the DDS domain (default: `ROS_DOMAIN_ID`, else 0).
    domain: Option<Spanned<u16>>,
    /// `backend = "ros2"`: the services' request/reply mapping (`auto`, `cyclone`,
    /// `fastdds`; default `auto`: the controller's middleware's).
    service_mapping: Option<Spanned<String>>,
    /// What a learned movement beyond the robot's limits is: `enforce` (default: a failed
    /// run, exit 1) or `report` (a result whose `limit_usage` says so, for reproducing a
    /// study whose robot was not the real one — it is not a movement to send).
    limits: Option<Spanned<String>>,
    /// The clearance (m) every pair of the robot's bodies, and each body and an obstacle,
    /// keeps in this run (default: the scene's, else the robot's).
    margin: Option<Spanned<f64>>,
}

/// Who moves the joints on a CoppeliaSim backend.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
enum Control {
    /// cps's inverse controller commands the joints.
    Cps,
    /// CoppeliaSim's IK makes the tip follow `/<robot>_target`, which cps moves.
    SimulatorIk,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
enum BackendKind {
    #[default]
    Kinematic,
    Coppelia,
    Franka,
    Ros2,
    Dynamics,
}

/// The keys of `[robot]` a backend alone reads, with where each stands in the file (None:
/// a key read without its place).
type Keys = Vec<(&'static str, Option<std::ops::Range<usize>>)>;

impl BackendKind {
    /// Every backend, in the order a stray key is looked for.
    const ALL: [BackendKind; 5] = [
        BackendKind::Franka,
        BackendKind::Coppelia,
        BackendKind::Ros2,
        BackendKind::Dynamics,
        BackendKind::Kinematic,
    ];

    /// Its word in `[robot] backend`.
    fn word(self) -> &'static str {
        match self {
            BackendKind::Kinematic => "kinematic",
            BackendKind::Coppelia => "coppelia",
            BackendKind::Franka => "franka",
            BackendKind::Ros2 => "ros2",
            BackendKind::Dynamics => "dynamics",
        }
    }

    /// The keys of `r` only this backend reads (each module's `keys`).
    fn keys(self, r: &RobotSection) -> Keys {
        match self {
            BackendKind::Kinematic => Vec::new(),
            BackendKind::Coppelia => coppelia::keys(r),
            BackendKind::Franka => franka::keys(r),
            BackendKind::Ros2 => ros2::keys(r),
            BackendKind::Dynamics => dynamics::keys(r),
        }
    }
}

/// Where trajectories are executed.
#[derive(Debug, Clone, PartialEq)]
pub enum BackendChoice {
    /// The in-process kinematic robot, stepped every `dt` seconds.
    Kinematic {
        /// Control period, seconds.
        dt: f64,
    },
    /// CoppeliaSim (or `cps-cli sim serve`) over the ZMQ remote API.
    Coppelia {
        /// `tcp://host:port`.
        endpoint: String,
        /// Every simulator of the pool (`[robot] endpoints`; else `endpoint` alone).
        pool: Vec<String>,
        /// The robot's alias in the scene.
        robot_name: String,
        /// Connect and per-call timeout.
        timeout: Duration,
        /// Execute through CoppeliaSim's IK following `/<robot>_target` instead of cps's
        /// controller.
        simulator_ik: bool,
        /// The control period the file expects (`[robot] dt`); the simulator's time step
        /// must match it.
        expected_dt: Option<f64>,
    },
    /// A Franka arm over the Franka Control Interface (`[robot] backend = "franka"`).
    Franka {
        /// The robot's address (a pool's first).
        host: String,
        /// Every robot of the pool (`[robot] hosts`; else `host` alone).
        pool: Vec<String>,
        /// Whose limits the commands are checked against.
        arm: cps_franka::limits::Arm,
        /// Realtime scheduling of the loop thread.
        realtime: cps_franka::Realtime,
        /// The control period the movement is planned at (s), a whole number of ms.
        dt: f64,
    },
    /// A ROS 2 robot through ros2_control's joint_trajectory_controller
    /// (`[robot] backend = "ros2"`).
    Ros2(Ros2Settings),
    /// The scene's robot with dynamics, in process (`[robot] backend = "dynamics"`): one
    /// per worker thread.
    Dynamics(cps_dynamics::DynamicsOptions),
}

impl BackendChoice {
    /// Whether the backend is a simulator cps drives (the in-process robots, the dynamics
    /// robot, CoppeliaSim), where letting a motion finish after a stop costs seconds of
    /// simulated time and nothing else; a Franka or a ROS 2 arm is taken as a real robot,
    /// which stops at once. A new backend says which it is here (the match is exhaustive).
    pub fn is_simulator(&self) -> bool {
        match self {
            BackendChoice::Kinematic { .. }
            | BackendChoice::Dynamics(_)
            | BackendChoice::Coppelia { .. } => true,
            BackendChoice::Franka { .. } | BackendChoice::Ros2(_) => false,
        }
    }

    /// Its name in `[robot] backend = "…"`.
    pub fn name(&self) -> &'static str {
        match self {
            BackendChoice::Kinematic { .. } => "kinematic",
            BackendChoice::Coppelia { .. } => "coppelia",
            BackendChoice::Franka { .. } => "franka",
            BackendChoice::Ros2(_) => "ros2",
            BackendChoice::Dynamics(_) => "dynamics",
        }
    }

    /// What the robots a run executes on are, in a sentence's words (`in-process
    /// robot(s)`, `dynamics robot(s)`, `robot(s)` for real ones, `simulator(s)`).
    pub fn executed_on(&self) -> &'static str {
        match self {
            BackendChoice::Kinematic { .. } => "in-process robot(s)",
            BackendChoice::Dynamics(_) => "dynamics robot(s)",
            BackendChoice::Franka { .. } | BackendChoice::Ros2(_) => "robot(s)",
            BackendChoice::Coppelia { .. } => "simulator(s)",
        }
    }

    /// A pool of several endpoints in a summary's words (`coppelia (a pool of
    /// simulators)`, `franka (a pool of 3 robots)`); None for one robot, described by
    /// [`RobotChoice::describe`].
    pub fn pool_description(&self) -> Option<String> {
        match self {
            BackendChoice::Coppelia { .. } => Some("coppelia (a pool of simulators)".into()),
            BackendChoice::Franka { pool, .. } if pool.len() > 1 => {
                Some(format!("franka (a pool of {} robots)", pool.len()))
            }
            _ => None,
        }
    }

    /// The names of the backends an experiment opens: the pool's endpoints or hosts, or
    /// `in_process` in-process robots (one per worker thread; at least one).
    pub fn pool_names(&self, in_process: usize) -> Vec<String> {
        match self {
            BackendChoice::Kinematic { .. } => (1..=in_process.max(1))
                .map(|i| format!("in-process robot {i}"))
                .collect(),
            BackendChoice::Dynamics(_) => (1..=in_process.max(1))
                .map(|i| format!("dynamics robot {i}"))
                .collect(),
            BackendChoice::Coppelia { pool, .. } | BackendChoice::Franka { pool, .. } => {
                pool.clone()
            }
            BackendChoice::Ros2(s) => vec![s.controller.clone()],
        }
    }
}

/// The robot of an experiment: its model and start, and the backend.
#[derive(Debug, Clone)]
pub struct RobotChoice {
    /// Model, initial configuration, execution settings.
    pub setup: RobotSetup,
    /// Which backend.
    pub backend: BackendChoice,
    /// The scene it came from (for summaries).
    pub scene: String,
    /// The scene's robot: name, joint names, limits beyond range and speed, inertias
    /// (its chain is `setup.chain`).
    pub model: cps_movement::robot_file::RobotModel,
    /// The scene's named obstacles (added to the task's by the kinds that keep them).
    pub obstacles: Vec<(String, cps_learn::PointObstacle)>,
    /// Whether a learned movement beyond the robot's limits fails the run (`[robot] limits
    /// = "enforce"`, the default) or is only reported (`"report"`).
    pub enforce_limits: bool,
}

impl Sections<'_> {
    pub(crate) fn robot_choice(&self, default_dt: f64) -> Result<RobotChoice, InputError> {
        let section = self.robot.map(Spanned::get_ref);
        let built_in = || {
            parse_scene(Path::new("configs/scenes/thesis.toml"), THESIS_SCENE)
                .map(|s| (s, "thesis (built in)".to_string()))
        };
        let (scene, scene_name) = match section.and_then(|r| r.scene.as_ref()) {
            // The built-in scenes by name: a file that names one runs from any folder.
            Some(s) if s.get_ref() == "thesis" => built_in()?,
            Some(s) if s.get_ref() == "fr3" => (
                parse_scene(
                    Path::new("configs/scenes/fr3.toml"),
                    cps_movement::scene::FR3_SCENE,
                )?,
                "fr3 (built in)".to_string(),
            ),
            Some(s) => {
                let p = self
                    .path
                    .parent()
                    .unwrap_or(Path::new("."))
                    .join(s.get_ref());
                if !p.exists() {
                    return Err(self.err(
                        &s.span(),
                        format!(
                            "[robot] `scene`: {} does not exist (paths are relative to the experiment file; `scene = \"thesis\"` is the built-in thesis scene)",
                            p.display()
                        ),
                    ));
                }
                (load_scene(&p)?, p.display().to_string())
            }
            None => built_in()?,
        };
        let mut scene = scene;
        if let Some(m) = section.and_then(|r| r.margin.as_ref()) {
            let margin = self.within(m, "[robot] `margin`", 0.0, 0.5, " m")?;
            scene.robot = scene
                .robot
                .with_margin(margin)
                .map_err(|e| self.err(&m.span(), format!("[robot] `margin`: {e}")))?;
        }
        if !self.obstacle.is_empty() {
            scene = self.with_obstacles(scene)?;
        }
        let mut execution = ExecutionConfig::default();
        if let Some(t) = section.and_then(|r| r.tolerance.as_ref()) {
            execution.tolerance = self.within(t, "[robot] `tolerance`", 1e-9, 0.1, " m")?;
        }
        if let Some(m) = section.and_then(|r| r.max_iterations_per_sample.as_ref()) {
            if *m.get_ref() == 0 || *m.get_ref() > 10_000 {
                return Err(self.err(
                    &m.span(),
                    format!(
                        "[robot] `max_iterations_per_sample` must be between 1 and 10000 (got {})",
                        m.get_ref()
                    ),
                ));
            }
            execution.max_iterations_per_sample = *m.get_ref();
        }
        let kind = section.map_or(BackendKind::Kinematic, |r| r.backend);
        if let Some(r) = section {
            self.backend_keys(r, kind)?;
        }
        let backend = match kind {
            BackendKind::Franka => self.franka_choice(section, &scene.robot.name, default_dt)?,
            BackendKind::Ros2 => self.ros2_choice(section, default_dt)?,
            BackendKind::Dynamics => self.dynamics_choice(section, &scene.robot, default_dt)?,
            BackendKind::Kinematic => self.kinematic_choice(section, default_dt)?,
            BackendKind::Coppelia => self.coppelia_choice(section)?,
        };
        let enforce_limits = match section.and_then(|r| r.limits.as_ref()) {
            None => true,
            Some(l) if l.get_ref() == "enforce" => true,
            Some(l) if l.get_ref() == "report" => false,
            Some(l) => {
                return Err(self.err(
                    &l.span(),
                    format!(
                        "[robot] `limits` = \"{}\" is not one of enforce (a movement beyond the robot's limits fails the run), report",
                        l.get_ref()
                    ),
                ));
            }
        };
        Ok(RobotChoice {
            enforce_limits,
            setup: RobotSetup {
                chain: scene.robot.chain.clone(),
                initial_q: scene.initial_q,
                execution,
            },
            backend,
            scene: scene_name,
            obstacles: scene
                .obstacles
                .into_iter()
                .map(|(name, o)| {
                    (
                        name,
                        cps_learn::PointObstacle {
                            position: o.position.to_vec(),
                            clearance: o.clearance,
                        },
                    )
                })
                .collect(),
            model: scene.robot,
        })
    }

    /// The experiment's `[[obstacle]]`s added to its scene's: points join the scene's
    /// points, shapes the robot's world (the start checked clear of them).
    fn with_obstacles(
        &self,
        mut scene: cps_movement::scene::Scene,
    ) -> Result<cps_movement::scene::Scene, InputError> {
        let mut taken: Vec<String> = scene.objects.iter().map(|(n, _)| n.clone()).collect();
        taken.extend(scene.obstacles.iter().map(|(n, _)| n.clone()));
        taken.extend(scene.shapes.iter().map(|o| o.name.clone()));
        let more =
            cps_movement::scene::parse_obstacles(self.path, self.text, self.obstacle, &taken)?;
        let first = &self.obstacle[0];
        let at = |m: String| self.err(&first.span(), format!("[[obstacle]]: {m}"));
        if !more.shapes.is_empty() {
            let Some(shapes) = scene.robot.shapes.clone() else {
                return Err(at(format!(
                    "the robot `{}` has no collision geometry to keep shaped obstacles with",
                    scene.robot.name
                )));
            };
            let mut obstacles = shapes.obstacles().to_vec();
            obstacles.extend(more.shapes.iter().cloned());
            let mut allowed = shapes.allowed().to_vec();
            allowed.extend(more.allowed);
            scene.robot = scene
                .robot
                .in_scene(obstacles, allowed, None)
                .map_err(|e| at(e.to_string()))?;
            cps_movement::scene::start_clear(&scene.robot, &scene.initial_q)
                .map_err(|m| at(format!("at the scene's start, {m}")))?;
            scene.shapes.extend(more.shapes);
        }
        scene.obstacles.extend(more.points);
        Ok(scene)
    }

    /// Keys of `[robot]` that belong to another backend than `kind` are named.
    fn backend_keys(&self, r: &RobotSection, kind: BackendKind) -> Result<(), InputError> {
        if !matches!(kind, BackendKind::Ros2 | BackendKind::Dynamics)
            && let Some(c) = &r.controller
        {
            return Err(self.err(
                &c.span(),
                "[robot] `controller` is read only with backend = \"ros2\" (the joint_trajectory_controller) or backend = \"dynamics\" (the joint-level controller)".into(),
            ));
        }
        for owner in BackendKind::ALL {
            if owner == kind || (owner == BackendKind::Coppelia && kind == BackendKind::Kinematic) {
                continue;
            }
            for (key, span) in owner.keys(r) {
                if let Some(span) = span {
                    return Err(self.err(
                        &span,
                        format!(
                            "[robot] `{key}` is read only with backend = \"{}\"",
                            owner.word()
                        ),
                    ));
                }
            }
        }
        if matches!(
            kind,
            BackendKind::Franka | BackendKind::Ros2 | BackendKind::Dynamics
        ) && r.name.is_some()
        {
            return Err(InputError(format!(
                "{}: [robot] `name` (the robot's alias in CoppeliaSim) is read only with backend = \"coppelia\"",
                self.path.display()
            )));
        }
        Ok(())
    }
}
