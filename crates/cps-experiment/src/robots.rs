//! Opening an experiment's robot: the [`RobotChoice`] read from `[robot]`
//! ([`crate::sections::robot`]) opened behind the guard of cps's execution contract
//! (`cps-robot`) — the in-process robot, the robot with dynamics, CoppeliaSim, a Franka
//! or a ROS 2 controller, one or a pool. Adding a backend is one [`BackendChoice`] variant with its keys (in
//! `sections/robot/`) and its opening in [`RobotChoice::open`] here; the kinds need no
//! change.

use cps_coppelia::{Client, ClientConfig, FrankaScene};
use cps_drive::contact::RobotAt;
use cps_franka::{FrankaRobot, FrankaSettings};
use cps_robot::{Guarded, KinematicRobot, Policy, Robot, RobotModel};
use cps_ros2::robot::Ros2Robot;

pub use crate::sections::robot::{BackendChoice, RobotChoice, RobotSection};
use crate::{Context, ExperimentError};

impl RobotChoice {
    /// The period the backend is planned at (s): what a movement's targets are spaced
    /// by when it runs there, and what learning on the robot's model steps by. A
    /// CoppeliaSim scene's is its time step, `fallback` until it is open.
    pub fn planned_every(&self, fallback: f64) -> f64 {
        match &self.backend {
            BackendChoice::Kinematic { dt } | BackendChoice::Franka { dt, .. } => *dt,
            BackendChoice::Ros2(s) => s.dt,
            BackendChoice::Dynamics(o) => o.dt,
            BackendChoice::Coppelia { expected_dt, .. } => expected_dt.unwrap_or(fallback),
        }
    }

    /// A short description for summaries: `kinematic (dt 0.01 s)` or the endpoint.
    pub fn describe(&self) -> String {
        match &self.backend {
            BackendChoice::Kinematic { dt } => format!("kinematic (in-process, dt {dt} s)"),
            BackendChoice::Franka { host, arm, dt, .. } => format!(
                "franka ({} at {host}, planned every {dt} s, streamed at 1 kHz)",
                arm.name()
            ),
            BackendChoice::Ros2(s) => format!(
                "ros2 ({}/follow_joint_trajectory, joint states from {}, planned every {} s)",
                s.controller, s.joint_states, s.dt
            ),
            BackendChoice::Dynamics(o) => format!(
                "dynamics (in-process, {} controller, {} drive, {} at {} s, planned every {} s{})",
                o.controller,
                match &o.calibration {
                    Some(c) => format!("calibrated (lag {} ms)", c.lag),
                    None => o.drive.name().to_string(),
                },
                o.integrator.name(),
                o.control_period,
                o.dt,
                if o.noise > 0.0 {
                    format!(", noise {} rad, seed {}", o.noise, o.seed)
                } else {
                    String::new()
                }
            ),
            BackendChoice::Coppelia {
                endpoint,
                simulator_ik,
                ..
            } => format!(
                "coppelia at {endpoint}{}",
                if *simulator_ik {
                    ", CoppeliaSim's IK following the target"
                } else {
                    ""
                }
            ),
        }
    }

    /// [`Self::describe`] once the robot is open, with what it says of its runs (how a
    /// simulator executes, a Franka's limit usage and timing, a ROS 2 controller's goals).
    pub fn describe_opened(&self, robot: &dyn Robot) -> String {
        match robot.report() {
            Some(r) => format!("{}: {r}", self.describe()),
            None => self.describe(),
        }
    }

    /// The scene's robot placed as the scene places it: what plans are checked against on
    /// a real robot.
    pub fn placed_model(&self) -> RobotModel {
        self.model.with_chain(self.setup.chain.clone())
    }

    /// [`Self::placed_model`] with the limits a kinematic simulator has — its joints' range
    /// and speed, which it keeps itself — and none of a real arm's acceleration, jerk,
    /// torque or Cartesian limits: the in-process robot and CoppeliaSim set joint positions
    /// as commanded (cps's closed-loop controller keeps range and speed, not acceleration).
    pub fn simulated_model(&self) -> RobotModel {
        let mut model = self.placed_model();
        model.limits = cps_kinematics::JointLimits::default();
        model.cartesian = None;
        model
    }

    /// Opens the robot with it at its initial configuration (a pool's first simulator),
    /// behind the guard every experiment runs with ([`Policy::EXPERIMENT`]: plans slowed as
    /// their limits need, at most 10x, and approached from where the robot stands).
    pub fn open(&self) -> Result<Box<dyn Robot>, ExperimentError> {
        match &self.backend {
            BackendChoice::Kinematic { dt } => {
                let robot =
                    KinematicRobot::of_model(self.simulated_model(), &self.setup.initial_q, *dt)
                        .context_with(|| "cannot start the in-process robot".into())?;
                Ok(guarded(Box::new(robot)))
            }
            BackendChoice::Dynamics(o) => {
                let robot = cps_dynamics::open(self.placed_model(), &self.setup.initial_q, o)
                    .map_err(|e| {
                        ExperimentError::Message(format!("backend = \"dynamics\": {e}"))
                    })?;
                Ok(guarded(robot))
            }
            BackendChoice::Coppelia { endpoint, .. } => self.open_at(endpoint),
            BackendChoice::Franka { host, .. } => self.open_at(host),
            BackendChoice::Ros2(s) => self.open_at(&s.controller),
        }
    }

    /// The robot a torque-controlled task (`kind = "contact"`) drives, with the world its
    /// free motions are checked in — the scene's table and the experiment's obstacles, with
    /// the contacts they allow — in the robot's base frame. Only a Franka takes torques.
    pub fn torque_robot(&self, drive: cps_dynamics::Drive) -> Result<RobotAt, ExperimentError> {
        let BackendChoice::Franka {
            host,
            arm,
            realtime,
            ..
        } = &self.backend
        else {
            return Err(crate::InputError(format!(
                "kind = \"contact\" needs a robot that takes torques, [robot] backend = \"franka\" (this file's is \"{}\")",
                self.backend.name()
            ))
            .into());
        };
        let world =
            self.model.shapes.as_ref().map(|shapes| {
                std::sync::Arc::new(shapes.moved(&self.setup.chain.base().inverse()))
            });
        Ok(RobotAt {
            host: host.clone(),
            arm: *arm,
            realtime: *realtime,
            drive,
            world,
        })
    }

    /// For learning on what the robot does: a way to open, once per worker, the robot
    /// with dynamics this backend describes, unguarded and without reflexes (a candidate
    /// is judged by what the simulated arm does, the limits are in its cost; the learned
    /// command runs through the guard afterwards), and the period its plans are made at.
    /// `None` for other backends.
    pub fn learning_robots(&self) -> Option<(Box<cps_learn::OpenRobot<'_>>, f64)> {
        let BackendChoice::Dynamics(o) = &self.backend else {
            return None;
        };
        let options = cps_dynamics::DynamicsOptions {
            reflexes: false,
            ..o.clone()
        };
        let dt = options.dt;
        Some((
            Box::new(move || {
                cps_dynamics::open(self.placed_model(), &self.setup.initial_q, &options)
            }),
            dt,
        ))
    }

    /// Opens every robot of the pool at once, each checked as [`Self::open`] checks one,
    /// named by its endpoint; for the kinematic backend, `in_process` in-process robots
    /// (one per worker thread, so that executions run in parallel; at least one). The
    /// first that cannot be opened is the error.
    pub fn open_pool(
        &self,
        in_process: usize,
    ) -> Result<Vec<cps_learn::pool::NamedBackend>, ExperimentError> {
        let pool = match &self.backend {
            BackendChoice::Kinematic { .. } | BackendChoice::Dynamics(_) => {
                return self
                    .backend
                    .pool_names(in_process)
                    .into_iter()
                    .map(|name| Ok((name, self.open()?)))
                    .collect();
            }
            BackendChoice::Ros2(s) => return Ok(vec![(s.controller.clone(), self.open()?)]),
            BackendChoice::Coppelia { pool, .. } | BackendChoice::Franka { pool, .. } => pool,
        };
        std::thread::scope(|scope| {
            let opening: Vec<_> = pool
                .iter()
                .map(|e| scope.spawn(move || self.open_at(e).map(|b| (e.clone(), b))))
                .collect();
            opening
                .into_iter()
                .map(|h| {
                    h.join().unwrap_or_else(|_| {
                        Err(ExperimentError::Message(
                            "opening a simulator panicked".into(),
                        ))
                    })
                })
                .collect()
        })
    }

    /// Whether every robot of an opened pool runs a whole plan itself, as learning on the
    /// executed cost needs (thousands of executions): a CoppeliaSim scene without cps's
    /// executor script steps each move over the network instead, and is refused naming
    /// the script to add.
    pub fn check_runs_plans(
        &self,
        opened: &mut [cps_learn::pool::NamedBackend],
    ) -> Result<(), ExperimentError> {
        let slow = opened
            .iter_mut()
            .position(|(_, b)| b.stepped().is_some_and(|s| !s.stepping().runs_plans()));
        match (slow, &self.backend) {
            (Some(i), BackendChoice::Coppelia { robot_name, .. }) => {
                let endpoint = &opened[i].0;
                Err(ExperimentError::Message(format!(
                    "{endpoint}: the scene has no /{robot_name}/cpsExecutor script, and learning on the executed cost steps thousands of executions: add configs/coppeliasim/cpsExecutor.lua to the scene as a child of /{robot_name} (the stand-in server has it unless started with --without-script)"
                )))
            }
            _ => Ok(()),
        }
    }

    /// Opens the robot at `endpoint` (a simulator's, a Franka's host) with it at its
    /// initial configuration, behind the guard.
    fn open_at(&self, endpoint: &str) -> Result<Box<dyn Robot>, ExperimentError> {
        let setup = &self.setup;
        match &self.backend {
            BackendChoice::Kinematic { .. } | BackendChoice::Dynamics(_) => self.open(),
            BackendChoice::Ros2(settings) => {
                let robot = Ros2Robot::open(settings, self.placed_model())
                    .map_err(|e| ExperimentError::Message(format!("backend = \"ros2\": {e}")))?;
                Ok(guarded(Box::new(robot)))
            }
            BackendChoice::Franka {
                arm, realtime, dt, ..
            } => {
                let settings = FrankaSettings {
                    host: endpoint.to_string(),
                    arm: *arm,
                    realtime: *realtime,
                    dt: *dt,
                };
                let robot = FrankaRobot::open(&settings, self.placed_model()).map_err(|e| {
                    ExperimentError::Message(format!("backend = \"franka\": {endpoint}: {e}"))
                })?;
                Ok(guarded(Box::new(robot)))
            }
            BackendChoice::Coppelia {
                robot_name,
                timeout,
                simulator_ik,
                expected_dt,
                ..
            } => {
                let client = Client::connect(ClientConfig {
                    endpoint: endpoint.to_string(),
                    connect_timeout: *timeout,
                    call_timeout: *timeout,
                    ..ClientConfig::default()
                })
                .context_with(|| format!("backend = \"coppelia\": cannot reach {endpoint}"))?;
                let mut client = client;
                let dt = client
                    .get_simulation_time_step()
                    .context_with(|| format!("{endpoint}: cannot read the simulation time step"))?;
                if let Some(want) = expected_dt
                    && (dt - want).abs() > 1e-9 * want.max(dt)
                {
                    return Err(ExperimentError::Message(format!(
                        "{endpoint}: the simulator steps {dt} s, but the experiment's [robot] dt is {want} s; set the scene's time step to {want} s (`cps-cli sim serve --dt {want}`), or remove dt to use the simulator's"
                    )));
                }
                let mut scene = FrankaScene::open(client, robot_name, self.simulated_model(), dt)
                    .context_with(|| {
                        format!("{endpoint}: the scene has no robot `/{robot_name}` with joints `/{robot_name}_joint1..{}` and `/{robot_name}_tip`", setup.chain.dof())
                    })?;
                if *simulator_ik {
                    scene.follow_ik_target(true).context_with(|| {
                        format!("{endpoint}: control = \"simulator_ik\" needs an IK target `/{robot_name}_target` in the scene")
                    })?;
                }
                // The scene's robot must be the model: compare the tip at the start.
                scene.reset(&setup.initial_q).map_err(|e| {
                    ExperimentError::Message(format!("{endpoint}: cannot reset the scene: {e}"))
                })?;
                let remote = Robot::tool_pose(&mut scene)
                    .map_err(|e| {
                        ExperimentError::Message(format!(
                            "{endpoint}: cannot read the tool pose: {e}"
                        ))
                    })?
                    .translation
                    .vector;
                let local = setup
                    .chain
                    .fk(&setup.initial_q)
                    .context_with(|| "the model's tool at the initial configuration".into())?
                    .translation
                    .vector;
                let gap = (remote - local).norm();
                if gap > 1e-3 {
                    return Err(ExperimentError::Message(format!(
                        "{endpoint}: the scene's `/{robot_name}_tip` is at ({:.4}, {:.4}, {:.4}) at the initial configuration, but the model puts the tool at ({:.4}, {:.4}, {:.4}) ({:.1} mm apart): the experiment's [robot] scene does not describe this simulator's robot",
                        remote.x,
                        remote.y,
                        remote.z,
                        local.x,
                        local.y,
                        local.z,
                        gap * 1e3
                    )));
                }
                Ok(guarded(Box::new(scene)))
            }
        }
    }
}

/// A robot behind the guard every experiment runs with: its approaches go around the
/// robot's shapes and its scene's where the straight way would not keep the margin.
fn guarded(robot: Box<dyn Robot>) -> Box<dyn Robot> {
    Box::new(Guarded::new(robot, Policy::EXPERIMENT).going_around(cps_plan::around))
}
