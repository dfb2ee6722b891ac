//! `[robot]` of the kinds that execute: the scene's robot and start, and which backend
//! executes — the in-process robot, CoppeliaSim, a Franka or a ROS 2 controller — read
//! into a [`RobotChoice`] with every key checked and placed. Opening the chosen robot is
//! [`crate::robots`]'s.

use std::path::Path;
use std::time::Duration;

use cps_learn::RobotSetup;
use cps_robot::ExecutionConfig;
use cps_ros2::robot::Ros2Settings;
use serde::Deserialize;
use toml::Spanned;

use super::{Kind, Sections};
use crate::InputError;
use crate::scene::{THESIS_SCENE, load_scene, parse_scene};

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
    pub model: crate::robot_file::RobotModel,
    /// The scene's named obstacles (added to the task's by the kinds that keep them).
    pub obstacles: Vec<(String, cps_learn::PointObstacle)>,
    /// Whether a learned movement beyond the robot's limits fails the run (`[robot] limits
    /// = "enforce"`, the default) or is only reported (`"report"`).
    pub enforce_limits: bool,
}

impl Sections<'_> {
    /// An endpoint `tcp://host:port` with a port from 1 to 65535; `what` names it.
    fn endpoint(&self, e: &Spanned<String>, what: &str) -> Result<String, InputError> {
        let text = e.get_ref();
        let port = text
            .strip_prefix("tcp://")
            .and_then(|rest| rest.rsplit_once(':'))
            .filter(|(host, _)| !host.is_empty())
            .and_then(|(_, p)| p.parse::<u16>().ok());
        if port.is_none_or(|p| p == 0) {
            return Err(self.err(
                &e.span(),
                format!(
                    "[robot] {what} must look like tcp://host:port with a port from 1 to 65535 (got `{text}`)"
                ),
            ));
        }
        Ok(text.clone())
    }

    /// `[robot] endpoints`: a pool of simulators, for `kind = "viapoint_executed"` only,
    /// not beside `endpoint`, at least one, each once (`localhost` is `127.0.0.1`); without
    /// it, the pool is `endpoint` alone.
    fn pool_endpoints(
        &self,
        section: Option<&RobotSection>,
        endpoint: &str,
    ) -> Result<Vec<String>, InputError> {
        let Some(list) = section.and_then(|r| r.endpoints.as_ref()) else {
            return Ok(vec![endpoint.to_string()]);
        };
        if self.kind != Kind::ViapointExecuted {
            return Err(self.err(
                &list.span(),
                format!(
                    "[robot] `endpoints` (a pool of simulators) is read only by kind = \"viapoint_executed\"; kind = \"{}\" executes on one: use `endpoint`",
                    self.kind.name()
                ),
            ));
        }
        if section.is_some_and(|r| r.endpoint.is_some()) {
            return Err(self.err(
                &list.span(),
                "[robot] give either `endpoint` (one simulator) or `endpoints` (a pool), not both"
                    .into(),
            ));
        }
        if list.get_ref().is_empty() || list.get_ref().len() > 256 {
            return Err(self.err(
                &list.span(),
                format!(
                    "[robot] `endpoints` must name 1 to 256 simulators (got {})",
                    list.get_ref().len()
                ),
            ));
        }
        let mut seen: Vec<(String, usize)> = Vec::new();
        let mut pool = Vec::new();
        for (i, e) in list.get_ref().iter().enumerate() {
            let text = self.endpoint(e, &format!("`endpoints[{i}]`"))?;
            let key = text.replacen("tcp://localhost:", "tcp://127.0.0.1:", 1);
            if let Some((_, j)) = seen.iter().find(|(k, _)| *k == key) {
                return Err(self.err(
                    &e.span(),
                    format!(
                        "[robot] `endpoints[{i}]` and `endpoints[{j}]` name the same simulator ({text}): each simulator runs one candidate at a time, list it once"
                    ),
                ));
            }
            seen.push((key, i));
            pool.push(text);
        }
        Ok(pool)
    }

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
                    crate::scene::FR3_SCENE,
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
            BackendKind::Kinematic => {
                if let Some(e) = section.and_then(|r| r.endpoint.as_ref()) {
                    return Err(self.err(
                        &e.span(),
                        "[robot] `endpoint` is read only with backend = \"coppelia\"".into(),
                    ));
                }
                if let Some(e) = section.and_then(|r| r.endpoints.as_ref()) {
                    return Err(self.err(
                        &e.span(),
                        "[robot] `endpoints` is read only with backend = \"coppelia\"".into(),
                    ));
                }
                if let Some(c) = section.and_then(|r| r.control.as_ref())
                    && *c.get_ref() == Control::SimulatorIk
                {
                    return Err(self.err(
                        &c.span(),
                        "[robot] control = \"simulator_ik\" needs backend = \"coppelia\" (the in-process robot has no IK of its own)".into(),
                    ));
                }
                let dt = match section.and_then(|r| r.dt.as_ref()) {
                    Some(d) => self.within(d, "[robot] `dt`", 1e-4, 1.0, " s")?,
                    None => default_dt,
                };
                BackendChoice::Kinematic { dt }
            }
            BackendKind::Coppelia => {
                if let Some(c) = section.and_then(|r| r.control.as_ref())
                    && *c.get_ref() == Control::SimulatorIk
                    && self.kind == Kind::ViapointJoint
                {
                    return Err(self.err(
                        &c.span(),
                        "[robot] control = \"simulator_ik\" executes tool targets; a joint-space experiment commands the joints itself (use control = \"cps\")".into(),
                    ));
                }
                if let Some(c) = section.and_then(|r| r.control.as_ref())
                    && *c.get_ref() == Control::SimulatorIk
                    && self.kind == Kind::ViapointExecuted
                {
                    return Err(self.err(
                        &c.span(),
                        "[robot] control = \"simulator_ik\" moves the IK target one step at a time; learning on the executed cost sends whole joint sequences to the scene script (use control = \"cps\")".into(),
                    ));
                }
                // A `dt` is the control period the file expects: checked against the
                // simulator's time step when it is reached.
                let expected_dt = match section.and_then(|r| r.dt.as_ref()) {
                    Some(d) => Some(self.within(d, "[robot] `dt`", 1e-4, 1.0, " s")?),
                    None => None,
                };
                let endpoint = match section.and_then(|r| r.endpoint.as_ref()) {
                    None => "tcp://127.0.0.1:23000".to_string(),
                    Some(e) => self.endpoint(e, "`endpoint`")?,
                };
                let pool = self.pool_endpoints(section, &endpoint)?;
                let timeout = match section.and_then(|r| r.timeout.as_ref()) {
                    Some(t) => self.within(t, "[robot] `timeout`", 0.01, 3600.0, " s")?,
                    None => 5.0,
                };
                BackendChoice::Coppelia {
                    endpoint: pool[0].clone(),
                    pool,
                    robot_name: section
                        .and_then(|r| r.name.clone())
                        .unwrap_or_else(|| "Panda".into()),
                    timeout: Duration::from_secs_f64(timeout),
                    simulator_ik: section
                        .and_then(|r| r.control.as_ref())
                        .is_some_and(|c| *c.get_ref() == Control::SimulatorIk),
                    expected_dt,
                }
            }
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

    /// Keys of `[robot]` that belong to another backend than `kind` are named.
    fn backend_keys(&self, r: &RobotSection, kind: BackendKind) -> Result<(), InputError> {
        let franka_only = [
            ("host", r.host.as_ref().map(Spanned::span)),
            ("hosts", r.hosts.as_ref().map(Spanned::span)),
            ("arm", r.arm.as_ref().map(Spanned::span)),
            ("realtime", r.realtime.as_ref().map(Spanned::span)),
        ];
        let coppelia_only = [
            ("endpoint", r.endpoint.as_ref().map(Spanned::span)),
            ("endpoints", r.endpoints.as_ref().map(Spanned::span)),
            ("name", None),
            ("timeout", r.timeout.as_ref().map(Spanned::span)),
            ("control", r.control.as_ref().map(Spanned::span)),
        ];
        let dynamics_only = [
            ("kp", r.kp.as_ref().map(Spanned::span)),
            ("kv", r.kv.as_ref().map(Spanned::span)),
            ("drive", r.drive.as_ref().map(Spanned::span)),
            ("integrator", r.integrator.as_ref().map(Spanned::span)),
            ("noise", r.noise.as_ref().map(Spanned::span)),
            ("seed", r.seed.as_ref().map(Spanned::span)),
            ("calibration", r.calibration.as_ref().map(Spanned::span)),
        ];
        if !matches!(kind, BackendKind::Ros2 | BackendKind::Dynamics)
            && let Some(c) = &r.controller
        {
            return Err(self.err(
                &c.span(),
                "[robot] `controller` is read only with backend = \"ros2\" (the joint_trajectory_controller) or backend = \"dynamics\" (the joint-level controller)".into(),
            ));
        }
        let ros2_only = [
            ("joint_states", r.joint_states.as_ref().map(Spanned::span)),
            ("domain", r.domain.as_ref().map(Spanned::span)),
            (
                "service_mapping",
                r.service_mapping.as_ref().map(Spanned::span),
            ),
        ];
        let groups = [
            (BackendKind::Franka, "franka", &franka_only[..]),
            (BackendKind::Coppelia, "coppelia", &coppelia_only[..]),
            (BackendKind::Ros2, "ros2", &ros2_only[..]),
            (BackendKind::Dynamics, "dynamics", &dynamics_only[..]),
        ];
        for (owner_kind, owner, keys) in groups {
            if owner_kind == kind
                || (owner_kind == BackendKind::Coppelia && kind == BackendKind::Kinematic)
            {
                continue;
            }
            for (key, span) in keys {
                if let Some(span) = span {
                    return Err(self.err(
                        span,
                        format!("[robot] `{key}` is read only with backend = \"{owner}\""),
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

    /// `[robot] calibration`: the file read and checked against the scene's robot; the
    /// keys it replaces (`kp`, `kv`, `drive`; a controller other than `joint_pd`) refused.
    fn calibration(
        &self,
        c: &Spanned<String>,
        r: &RobotSection,
        robot: &crate::robot_file::RobotModel,
    ) -> Result<cps_dynamics::options::CalibrationValues, InputError> {
        for (key, span) in [
            ("kp", r.kp.as_ref().map(Spanned::span)),
            ("kv", r.kv.as_ref().map(Spanned::span)),
            ("drive", r.drive.as_ref().map(Spanned::span)),
        ] {
            if let Some(at) = span {
                return Err(self.err(
                    &at,
                    format!("[robot] `{key}` and `calibration` both say how the robot is driven: give one"),
                ));
            }
        }
        if let Some(ctl) = r.controller.as_ref().filter(|c| c.get_ref() != "joint_pd") {
            return Err(self.err(
                &ctl.span(),
                format!(
                    "[robot] a calibration identifies a joint_pd controller, not {}",
                    ctl.get_ref()
                ),
            ));
        }
        if c.get_ref().trim().is_empty() {
            return Err(self.err(
                &c.span(),
                "[robot] `calibration` is empty: give the path of a calibration file (`cps-cli identify` writes one), relative to this file".into(),
            ));
        }
        let path = self
            .path
            .parent()
            .unwrap_or(Path::new("."))
            .join(c.get_ref());
        let file = crate::calibration::read_calibration(&path)
            .map_err(|e| self.err(&c.span(), format!("[robot] `calibration`: {}", e.0)))?;
        let k = file.calibration;
        let values = cps_dynamics::options::CalibrationValues {
            robot: k.robot,
            kp: k.kp,
            kv: k.kv,
            lag: k.lag_ms,
            armature: k.armature,
            viscous: k.viscous,
            coulomb: k.coulomb,
            speed: k.coulomb_speed,
        };
        let check = if k.controller != "joint_pd" {
            Err((
                "controller",
                format!(
                    "its controller is {}; cps identifies joint_pd",
                    k.controller
                ),
            ))
        } else {
            values.check(
                &robot.name,
                robot.chain.dof(),
                robot.limits.torque.as_deref(),
            )
        };
        check.map_err(|(key, e)| {
            self.err(
                &c.span(),
                format!(
                    "[robot] `calibration`: {}: {e}",
                    crate::calibration::place_of(&path, key)
                ),
            )
        })?;
        Ok(values)
    }

    /// `[robot] backend = "dynamics"`: `controller`, `kp`, `kv`, `drive`, `integrator`,
    /// `noise`, `seed`, `dt` (a whole number of milliseconds: the robot is controlled every
    /// millisecond).
    fn dynamics_choice(
        &self,
        section: Option<&RobotSection>,
        robot: &crate::robot_file::RobotModel,
        default_dt: f64,
    ) -> Result<BackendChoice, InputError> {
        let Some(r) = section else {
            unreachable!("backend = \"dynamics\" is read from a [robot] section")
        };
        let dof = robot.chain.dof();
        if robot.inertia.is_none() || !(6..=7).contains(&dof) {
            let at = self.robot.map_or(0..0, |r| r.span());
            return Err(self.err(
                &at,
                format!(
                    "[robot] backend = \"dynamics\" simulates arms of 6 or 7 joints whose link inertias are known: the scene's robot {} has {dof} joints{} (the built-in scenes' Panda has Gaz et al.'s; a URDF gives them with <inertial>)",
                    robot.name,
                    if robot.inertia.is_none() { " and no link inertias" } else { "" }
                ),
            ));
        }
        let mut o = cps_dynamics::DynamicsOptions::default();
        if let Some(c) = &r.controller {
            if !cps_dynamics::CONTROLLERS.contains(&c.get_ref().as_str()) {
                return Err(self.err(
                    &c.span(),
                    format!(
                        "[robot] `controller` = \"{}\" is not one of {} (backend = \"dynamics\")",
                        c.get_ref(),
                        cps_dynamics::CONTROLLERS.join(", ")
                    ),
                ));
            }
            o.controller = c.get_ref().clone();
        }
        for (key, gains, slot) in [("kp", &r.kp, &mut o.kp), ("kv", &r.kv, &mut o.kv)] {
            if let Some(g) = gains {
                if let Some((i, v)) = g
                    .get_ref()
                    .iter()
                    .enumerate()
                    .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
                {
                    return Err(self.err(
                        &g.span(),
                        format!("[robot] `{key}[{i}]` is {v}: a gain must be finite and ≥ 0"),
                    ));
                }
                if g.get_ref().len() != dof {
                    return Err(self.err(
                        &g.span(),
                        format!(
                            "[robot] `{key}` has {} values: one per joint of the {} ({dof})",
                            g.get_ref().len(),
                            robot.name
                        ),
                    ));
                }
                *slot = Some(g.get_ref().clone());
            }
        }
        if let Some(d) = &r.drive {
            o.drive = cps_dynamics::Drive::parse(d.get_ref()).ok_or_else(|| {
                self.err(
                    &d.span(),
                    format!(
                        "[robot] `drive` = \"{}\" is not one of {}",
                        d.get_ref(),
                        cps_dynamics::Drive::NAMES
                    ),
                )
            })?;
        }
        if let Some(i) = &r.integrator {
            o.integrator = cps_dynamics::Integrator::parse(i.get_ref()).ok_or_else(|| {
                self.err(
                    &i.span(),
                    format!(
                        "[robot] `integrator` = \"{}\" is not one of euler, rk4",
                        i.get_ref()
                    ),
                )
            })?;
        }
        if let Some(n) = &r.noise {
            o.noise = self.within(n, "[robot] `noise`", 0.0, 0.1, " rad")?;
        }
        if let Some(s) = &r.seed {
            o.seed = *s.get_ref();
        }
        if let Some(c) = &r.calibration {
            o.calibration = Some(self.calibration(c, r, robot)?);
        }
        o.dt = match &r.dt {
            Some(d) => {
                let dt = self.within(d, "[robot] `dt`", 1e-3, 0.1, " s")?;
                let ms = dt * 1e3;
                if (ms - ms.round()).abs() > 1e-9 {
                    return Err(self.err(
                        &d.span(),
                        format!("[robot] `dt` = {dt} s must be a whole number of milliseconds (the dynamics robot is controlled every millisecond)"),
                    ));
                }
                dt
            }
            None => default_dt,
        };
        Ok(BackendChoice::Dynamics(o))
    }

    /// `[robot] backend = "ros2"`: `controller`, `joint_states`, `domain`, `dt`.
    fn ros2_choice(
        &self,
        section: Option<&RobotSection>,
        default_dt: f64,
    ) -> Result<BackendChoice, InputError> {
        let Some(r) = section else {
            unreachable!("backend = \"ros2\" is read from a [robot] section")
        };
        let probe = cps_ros2::names::NodeName::new("cps", "/", 0).expect("a valid node name");
        let name = |v: &Spanned<String>, what: &str| -> Result<String, InputError> {
            cps_ros2::names::resolve(&probe, v.get_ref())
                .map_err(|e| self.err(&v.span(), format!("[robot] `{what}`: {e}")))
        };
        let Some(controller) = &r.controller else {
            return Err(InputError(format!(
                "{}: [robot] backend = \"ros2\" needs `controller`, the joint_trajectory_controller's name (e.g. controller = \"/panda_arm_controller\"): cps never guesses which robot to move",
                self.path.display()
            )));
        };
        let controller = name(controller, "controller")?;
        let joint_states = match &r.joint_states {
            Some(j) => name(j, "joint_states")?,
            None => "/joint_states".into(),
        };
        let domain = match &r.domain {
            Some(d) if *d.get_ref() > cps_ros2::names::MAX_DOMAIN => {
                return Err(self.err(
                    &d.span(),
                    format!(
                        "[robot] `domain` must be 0 to {} (got {})",
                        cps_ros2::names::MAX_DOMAIN,
                        d.get_ref()
                    ),
                ));
            }
            Some(d) => Some(*d.get_ref()),
            None => None,
        };
        let dt = match &r.dt {
            Some(d) => self.within(d, "[robot] `dt`", 1e-3, 0.1, " s")?,
            None => default_dt,
        };
        let service_mapping = match &r.service_mapping {
            Some(m) => m
                .get_ref()
                .parse()
                .map_err(|e| self.err(&m.span(), format!("[robot] `service_mapping`: {e}")))?,
            None => Default::default(),
        };
        Ok(BackendChoice::Ros2(Ros2Settings {
            controller,
            joint_states,
            domain,
            service_mapping,
            dt,
            goal_period: None,
            wait: Duration::from_secs(20),
            joint_names: None,
            read_start: true,
        }))
    }

    /// `[robot] backend = "franka"`: `host` or `hosts`, `arm`, `realtime`, `dt`.
    fn franka_choice(
        &self,
        section: Option<&RobotSection>,
        model: &str,
        default_dt: f64,
    ) -> Result<BackendChoice, InputError> {
        use cps_franka::limits::Arm;
        let Some(r) = section else {
            unreachable!("backend = \"franka\" is read from a [robot] section")
        };
        let check_host = |h: &Spanned<String>, what: &str| -> Result<String, InputError> {
            let text = h.get_ref().trim();
            let ok = !text.is_empty()
                && !text.contains("://")
                && !text.contains(char::is_whitespace)
                && text.rsplit_once(':').is_none_or(|(host, p)| {
                    !host.is_empty() && p.parse::<u16>().is_ok_and(|p| p > 0)
                });
            if ok {
                Ok(text.to_string())
            } else {
                Err(self.err(
                    &h.span(),
                    format!(
                        "[robot] {what} must be the robot's address, `ip` or `ip:port` (got `{}`)",
                        h.get_ref()
                    ),
                ))
            }
        };
        let pool = match (&r.host, &r.hosts) {
            (Some(_), Some(list)) => {
                return Err(self.err(
                    &list.span(),
                    "[robot] give either `host` (one robot) or `hosts` (a pool), not both".into(),
                ));
            }
            (None, None) => {
                return Err(InputError(format!(
                    "{}: [robot] backend = \"franka\" needs `host`, the robot's address (e.g. host = \"172.16.0.2\"): cps never guesses which robot to move",
                    self.path.display()
                )));
            }
            (Some(h), None) => vec![check_host(h, "`host`")?],
            (None, Some(list)) => {
                if self.kind != Kind::ViapointExecuted {
                    return Err(self.err(
                        &list.span(),
                        format!(
                            "[robot] `hosts` (a pool of robots) is read only by kind = \"viapoint_executed\"; kind = \"{}\" executes on one: use `host`",
                            self.kind.name()
                        ),
                    ));
                }
                if list.get_ref().is_empty() || list.get_ref().len() > 64 {
                    return Err(self.err(
                        &list.span(),
                        format!(
                            "[robot] `hosts` must name 1 to 64 robots (got {})",
                            list.get_ref().len()
                        ),
                    ));
                }
                let mut pool: Vec<String> = Vec::new();
                for (i, h) in list.get_ref().iter().enumerate() {
                    let text = check_host(h, &format!("`hosts[{i}]`"))?;
                    if let Some(j) = pool.iter().position(|p| *p == text) {
                        return Err(self.err(
                            &h.span(),
                            format!("[robot] `hosts[{i}]` and `hosts[{j}]` name the same robot ({text}): list it once"),
                        ));
                    }
                    pool.push(text);
                }
                pool
            }
        };
        let arm = match &r.arm {
            Some(a) => Arm::from_name(a.get_ref()).ok_or_else(|| {
                self.err(
                    &a.span(),
                    format!("[robot] `arm` must be fr3 or panda (got `{}`)", a.get_ref()),
                )
            })?,
            None => Arm::from_name(model).ok_or_else(|| {
                InputError(format!(
                    "{}: [robot] the scene's robot `{model}` is not a Franka arm: set `arm = \"fr3\"` or `\"panda\"` to say whose limits the commands must keep",
                    self.path.display()
                ))
            })?,
        };
        let realtime = match &r.realtime {
            Some(m) => crate::franka::parse_realtime(m.get_ref()).map_err(|_| {
                self.err(
                    &m.span(),
                    format!(
                        "[robot] `realtime` must be enforce or ignore (got `{}`)",
                        m.get_ref()
                    ),
                )
            })?,
            None => cps_franka::Realtime::Enforce,
        };
        let dt = match r.dt.as_ref() {
            Some(d) => {
                let dt = self.within(d, "[robot] `dt`", 1e-3, 1.0, " s")?;
                if ((dt * 1e3).round() - dt * 1e3).abs() > 1e-6 {
                    return Err(self.err(
                        &d.span(),
                        format!("[robot] `dt` must be a whole number of milliseconds with backend = \"franka\" (the robot takes a command every millisecond; got {dt} s)"),
                    ));
                }
                dt
            }
            None if ((default_dt * 1e3).round() - default_dt * 1e3).abs() > 1e-6
                || default_dt < 1e-3 =>
            {
                return Err(InputError(format!(
                    "{}: the movement is planned every {default_dt} s, not a whole number of milliseconds: set [robot] dt (e.g. 0.01) for the Franka",
                    self.path.display()
                )));
            }
            None => default_dt,
        };
        Ok(BackendChoice::Franka {
            host: pool[0].clone(),
            pool,
            arm,
            realtime,
            dt,
        })
    }
}
