//! The thesis's Franka scene over the remote API: the robot `/Panda`, its joints
//! `/Panda_joint1..7`, tool tip `/Panda_tip`, IK target `/Panda_target`, way points `/p0`,
//! `/p1`, …, `/pT`; and the scene's robot as a [`Robot`] of the execution contract (and a
//! [`Stepped`] one) that drives the joints.

use std::time::{Duration, Instant};

use cps_kinematics::KinematicsError;
use cps_robot::{Ending, Plan, Robot, RobotError, RobotModel, Run, Stepped, Stepping, StopToken};
use nalgebra::{IsometryMatrix3, Vector3};

use crate::codec;
use crate::executor::{self, Progress, StepRecording};
use crate::sim::{HANDLE_WORLD, SIMULATION_STOPPED};
use crate::{Client, CoppeliaError, Protocol};

/// The longest wait between two looks at a running sequence (s): a stop is seen within it.
pub const STOP_POLL: f64 = 0.01;

/// The handles of a robot in a CoppeliaSim scene, named as in the thesis.
#[derive(Debug)]
pub struct FrankaScene {
    client: Client,
    joints: Vec<i64>,
    tip: i64,
    dt: f64,
    /// `/<robot>_target` while the scene's IK follows it (see [`FrankaScene::follow_ik_target`]).
    target: Option<i64>,
    robot: String,
    /// cps's scene script `/<robot>/cpsExecutor`, when the scene has it and it is used.
    script: Option<i64>,
    /// The robot's model (what plans are checked against).
    model: RobotModel,
    /// The joints as last read, while nothing has moved them since (a read costs a call
    /// per joint).
    fresh: Option<Vec<f64>>,
}

impl FrankaScene {
    /// Looks up `/<robot>_joint1..dof` and `/<robot>_tip` (the thesis: robot `Panda`,
    /// seven joints; `dof` is `model`'s), and cps's scene script `/<robot>/cpsExecutor` if
    /// the scene has it (protocol v2; see [`crate::executor`]). `dt` is the scene's
    /// simulation time step in seconds; `model` the robot the scene holds, whose limits
    /// plans are checked against.
    pub fn open(
        mut client: Client,
        robot: &str,
        model: RobotModel,
        dt: f64,
    ) -> Result<Self, CoppeliaError> {
        let dof = model.chain.dof();
        let joints = (1..=dof)
            .map(|i| client.get_object(&format!("/{robot}_joint{i}")))
            .collect::<Result<Vec<_>, _>>()?;
        let tip = client.get_object(&format!("/{robot}_tip"))?;
        let script = if client.protocol() == Protocol::V2 {
            match client.get_object(&format!("/{robot}/{}", executor::SCRIPT_ALIAS)) {
                Ok(h) => Some(h),
                Err(CoppeliaError::Remote { .. }) => None,
                Err(e) => return Err(e),
            }
        } else {
            None
        };
        Ok(Self {
            client,
            joints,
            tip,
            dt,
            target: None,
            robot: robot.to_string(),
            script,
            model,
            fresh: None,
        })
    }

    /// True if the scene has cps's script and trajectories are executed through it (a
    /// few calls per trajectory instead of several per step).
    pub fn has_script(&self) -> bool {
        self.script.is_some()
    }

    /// Stops using cps's scene script: every step is then commanded and read in calls of
    /// its own, as for a scene without the script (for comparisons).
    pub fn without_script(&mut self) {
        self.script = None;
    }

    /// Runs one part of a sequence through the scene script: load it, let the simulation
    /// run freely, wait for the recording (or stop the script where it is, once `stop` is
    /// stopped: then true), take the stepping hold back.
    fn run_part(
        &mut self,
        script: i64,
        rows: &[Vec<f64>],
        stop: &StopToken,
    ) -> Result<(StepRecording, bool), RobotError> {
        self.fresh = None;
        let endpoint = self.client.endpoint().to_string();
        let dof = self.joints.len();
        let flat: Vec<f64> = rows.iter().flatten().copied().collect();
        let loaded =
            self.client
                .call_script_function(executor::LOAD, script, vec![codec::floats(&flat)])?;
        if loaded.first().and_then(codec::as_i64) != Some(rows.len() as i64) {
            return Err(executor::backend_error(
                &endpoint,
                format!(
                    "{} did not take the {} steps it was sent",
                    executor::LOAD,
                    rows.len()
                ),
            ));
        }
        self.client.set_stepping(false)?;
        let result = self.await_run(script, rows.len(), dof, stop);
        let hold = self.client.set_stepping(true);
        let rec = result?;
        hold?;
        Ok(rec)
    }

    /// Polls `cpsResult` until the run is over, sleeping between polls for the time the
    /// remaining steps take at the pace seen so far, at most [`STOP_POLL`], so a stop is
    /// seen within that: the script is then told to stop where it is (`cpsStop`) and its
    /// recording so far returned, with true. No progress for the call timeout is a
    /// [`CoppeliaError::Timeout`] (another client holding the simulation, or a hung
    /// simulator).
    fn await_run(
        &mut self,
        script: i64,
        total: usize,
        dof: usize,
        stop: &StopToken,
    ) -> Result<(StepRecording, bool), RobotError> {
        let endpoint = self.client.endpoint().to_string();
        let start = Instant::now();
        let mut progress = (start, 0);
        loop {
            if stop.is_stopped() {
                let reply = self
                    .client
                    .call_script_function(executor::STOP, script, vec![])?;
                let value = reply.first().ok_or_else(|| {
                    executor::backend_error(
                        &endpoint,
                        format!("{} returned nothing", executor::STOP),
                    )
                })?;
                let rec = executor::read_stopped(value, total, dof).map_err(|m| {
                    executor::backend_error(&endpoint, format!("{}: {m}", executor::STOP))
                })?;
                return Ok((rec, true));
            }
            let reply = self
                .client
                .call_script_function(executor::RESULT, script, vec![])?;
            let value = reply.first().ok_or_else(|| {
                executor::backend_error(&endpoint, format!("{} returned nothing", executor::RESULT))
            })?;
            let done = match executor::read_result(value, total, dof).map_err(|m| {
                executor::backend_error(&endpoint, format!("{}: {m}", executor::RESULT))
            })? {
                Progress::Done(rec) => return Ok((rec, false)),
                Progress::Running(done) => done,
            };
            let now = Instant::now();
            if done > progress.1 {
                progress = (now, done);
            } else if now - progress.0 > self.client.call_timeout() {
                return Err(CoppeliaError::Timeout {
                    endpoint,
                    function: format!(
                        "{} (the simulation stood still at step {done} of {total}: is another client holding it in stepping mode?)",
                        executor::RESULT
                    ),
                    timeout_ms: self.client.call_timeout().as_millis() as u64,
                }
                .into());
            }
            let pace = if done == 0 {
                0.005
            } else {
                (total - done) as f64 * start.elapsed().as_secs_f64() / done as f64
            };
            std::thread::sleep(Duration::from_secs_f64(pace.clamp(0.001, STOP_POLL)));
        }
    }

    /// Switches to CoppeliaSim's own inverse kinematics: trajectories are then executed
    /// by moving `/<robot>_target` (the thesis's `/Panda_target`), which the scene's IK
    /// makes the tip follow at every step, instead of commanding joints from cps's
    /// controller. The scene must run that IK (the thesis's scene does;
    /// `cps-cli sim serve --ik-following` does).
    pub fn follow_ik_target(&mut self, on: bool) -> Result<(), CoppeliaError> {
        self.target = if on {
            Some(self.client.get_object(&format!("/{}_target", self.robot))?)
        } else {
            None
        };
        Ok(())
    }

    /// Starts the simulation in stepping mode, so that [`Stepped::step`] advances it
    /// exactly one time step.
    pub fn start_stepping(&mut self) -> Result<(), CoppeliaError> {
        self.fresh = None;
        self.client.start_simulation()?;
        self.client.set_stepping(true)?;
        Ok(())
    }

    /// Stops the simulation (which also ends stepping) and waits until it has stopped:
    /// CoppeliaSim stops asynchronously, restoring the scene over a few passes. Gives up
    /// with [`CoppeliaError::Timeout`] after 10 s.
    pub fn stop(&mut self) -> Result<(), CoppeliaError> {
        self.fresh = None;
        self.client.stop_simulation()?;
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while self.client.get_simulation_state()? != SIMULATION_STOPPED {
            if std::time::Instant::now() > deadline {
                return Err(CoppeliaError::Timeout {
                    endpoint: self.client.endpoint().to_string(),
                    function: "sim.stopSimulation (waiting for the stopped state)".into(),
                    timeout_ms: 10_000,
                });
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        Ok(())
    }

    /// The client, for calls this type does not wrap.
    pub fn client(&mut self) -> &mut Client {
        // Whatever the caller does through it may move the joints.
        self.fresh = None;
        &mut self.client
    }

    /// The way points of the scene: `/p0`, `/p1`, … as long as they exist, then `/pT`
    /// (world positions, metres).
    pub fn way_points(&mut self) -> Result<Vec<(String, Vector3<f64>)>, CoppeliaError> {
        let mut out = Vec::new();
        let mut names: Vec<String> = Vec::new();
        for i in 0.. {
            let name = format!("p{i}");
            match self.client.get_object(&format!("/{name}")) {
                Ok(h) => {
                    let p = self.client.get_object_position(h, HANDLE_WORLD)?;
                    out.push((name.clone(), Vector3::from(p)));
                    names.push(name);
                }
                Err(CoppeliaError::Remote { .. }) => break,
                Err(e) => return Err(e),
            }
        }
        if let Ok(h) = self.client.get_object("/pT") {
            let p = self.client.get_object_position(h, HANDLE_WORLD)?;
            out.push(("pT".into(), Vector3::from(p)));
        }
        Ok(out)
    }
}

impl FrankaScene {
    fn name(&self) -> String {
        format!("CoppeliaSim at {}", self.client.endpoint())
    }

    fn read_joints(&mut self) -> Result<Vec<f64>, RobotError> {
        if let Some(q) = &self.fresh {
            return Ok(q.clone());
        }
        let joints = self.joints.clone();
        let q = joints
            .iter()
            .map(|&j| self.client.get_joint_position(j))
            .collect::<Result<Vec<_>, _>>()?;
        self.fresh = Some(q.clone());
        Ok(q)
    }

    fn read_tool(&mut self) -> Result<IsometryMatrix3<f64>, RobotError> {
        let pose = self.client.get_object_pose(self.tip, HANDLE_WORLD)?;
        Ok(IsometryMatrix3::from_parts(
            pose.translation,
            pose.rotation.to_rotation_matrix(),
        ))
    }

    /// True if whole sequences run inside the simulator through cps's scene script (see
    /// [`Stepped::stepping`]: whole plans, or targets with plans).
    pub fn runs_sequences(&self) -> bool {
        self.script.is_some()
    }

    /// Runs `targets` (one joint-position row per step): before step k the robot is
    /// commanded row k, then steps once; after each step the measured joints, the tool pose
    /// and the clock are recorded. Through cps's scene script when the scene has it
    /// ([`crate::executor`]), in parts of at most [`executor::MAX_STEPS`] steps — a few
    /// calls a sequence; otherwise one call per command, step and reading.
    pub fn run_joint_targets(&mut self, targets: &[Vec<f64>]) -> Result<StepRecording, RobotError> {
        self.run_joint_targets_until(targets, &StopToken::new())
            .map(|(rec, _)| rec)
    }

    /// [`FrankaScene::run_joint_targets`], ended where it is once `stop` is stopped (seen
    /// within [`STOP_POLL`] through the scene script, at the next step without it): the
    /// recording so far, and whether it was stopped.
    pub fn run_joint_targets_until(
        &mut self,
        targets: &[Vec<f64>],
        stop: &StopToken,
    ) -> Result<(StepRecording, bool), RobotError> {
        let (rec, outcome) = self.run_joint_targets_partly(targets, stop);
        outcome.map(|stopped| (rec, stopped))
    }

    /// [`FrankaScene::run_joint_targets_until`] that keeps what was recorded when it
    /// fails: the recording, and how it ended — `Ok(false)` ran to the end, `Ok(true)`
    /// stopped, `Err` failed (the steps of a part the scene script was running when the
    /// simulator went away are lost with it; those of the parts before are kept).
    fn run_joint_targets_partly(
        &mut self,
        targets: &[Vec<f64>],
        stop: &StopToken,
    ) -> (StepRecording, Result<bool, RobotError>) {
        let mut rec = StepRecording::default();
        let dof = self.joints.len();
        if let Some(row) = targets.iter().find(|r| r.len() != dof) {
            let e = KinematicsError::JointCount {
                expected: dof,
                got: row.len(),
            };
            return (rec, Err(e.into()));
        }
        let Some(script) = self.script else {
            for row in targets {
                if stop.is_stopped() {
                    return (rec, Ok(true));
                }
                let step = (|| -> Result<(), RobotError> {
                    Stepped::command_joint_positions(self, row)?;
                    Stepped::step(self)?;
                    let q = self.read_joints()?;
                    let tool = self.read_tool()?;
                    let t = Stepped::time(self)?;
                    rec.q.push(q);
                    rec.tool.push(tool);
                    rec.time.push(t);
                    Ok(())
                })();
                if let Err(e) = step {
                    return (rec, Err(e));
                }
            }
            return (rec, Ok(false));
        };
        for part in targets.chunks(executor::MAX_STEPS) {
            match self.run_part(script, part, stop) {
                Ok((r, stopped)) => {
                    rec.time.extend(r.time);
                    rec.q.extend(r.q);
                    rec.tool.extend(r.tool);
                    if stopped {
                        return (rec, Ok(true));
                    }
                }
                Err(e) => return (rec, Err(e)),
            }
        }
        (rec, Ok(false))
    }

    /// Stops the simulation (CoppeliaSim restores the scene and resets its clock), sets
    /// the joints to `q` and starts stepping again. Following the IK target, the target is
    /// put on the tip first, so the robot stays where it was set.
    pub fn reset(&mut self, q: &[f64]) -> Result<(), RobotError> {
        self.stop()?;
        Stepped::command_joint_positions(self, q)?;
        if let Some(target) = self.target {
            let tip = self.client.get_object_pose(self.tip, HANDLE_WORLD)?;
            self.client.set_object_pose(target, &tip, HANDLE_WORLD)?;
        }
        self.start_stepping()?;
        Ok(())
    }
}

impl Stepped for FrankaScene {
    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), RobotError> {
        if q.len() != self.joints.len() {
            return Err(KinematicsError::JointCount {
                expected: self.joints.len(),
                got: q.len(),
            }
            .into());
        }
        self.fresh = None;
        let joints = self.joints.clone();
        for (j, v) in joints.iter().zip(q) {
            self.client.set_joint_position(*j, *v)?;
        }
        Ok(())
    }

    fn time(&mut self) -> Result<f64, RobotError> {
        Ok(self.client.get_simulation_time()?)
    }

    fn step(&mut self) -> Result<(), RobotError> {
        // Following the IK target, a step moves the joints without a joint command.
        self.fresh = None;
        Ok(self.client.step()?)
    }

    /// Targets when the scene's IK follows `/<robot>_target`; else whole plans when the
    /// scene has cps's script (a few exchanges a plan); else joint commands.
    fn stepping(&self) -> Stepping {
        match (self.target, &self.script) {
            (Some(_), script) => Stepping::Targets {
                plans: script.is_some(),
            },
            (None, Some(_)) => Stepping::Plans,
            (None, None) => Stepping::Joints,
        }
    }

    /// Moves `/<robot>_target`: its position for a position target (orientation kept),
    /// its whole pose for a pose target.
    fn command_target(&mut self, target: &cps_kinematics::IkTarget) -> Result<(), RobotError> {
        let Some(handle) = self.target else {
            return Err(RobotError::Robot {
                robot: self.name(),
                message: "not following the IK target: call follow_ik_target(true) first".into(),
            });
        };
        match target {
            cps_kinematics::IkTarget::Position(p) => {
                self.client
                    .set_object_position(handle, [p.x, p.y, p.z], HANDLE_WORLD)?;
            }
            cps_kinematics::IkTarget::Pose(pose) => {
                let iso = nalgebra::Isometry3::from_parts(
                    pose.translation,
                    nalgebra::UnitQuaternion::from_rotation_matrix(&pose.rotation),
                );
                self.client.set_object_pose(handle, &iso, HANDLE_WORLD)?;
            }
        }
        Ok(())
    }
}

impl Robot for FrankaScene {
    fn name(&self) -> String {
        FrankaScene::name(self)
    }

    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn dt(&self) -> f64 {
        self.dt
    }

    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        self.read_joints()
    }

    /// The simulation's step: the scene steps through a plan's motion sampled at it.
    fn command_period(&self) -> f64 {
        self.dt
    }

    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, RobotError> {
        self.read_tool()
    }

    /// Through cps's scene script when the scene has it
    /// ([`FrankaScene::run_joint_targets`]), otherwise one call per command, step and
    /// reading ([`cps_robot::run_stepped`]). The plan's motion is sampled at the scene's
    /// step, and each of the plan's points gets the step at its time.
    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
        plan.check_dof(self.joints.len())?;
        if self.script.is_none() {
            return cps_robot::run_stepped(self, plan, stop);
        }
        let samples = plan.samples(self.dt);
        let t0 = self.client.get_simulation_time()?;
        let first = (self.read_joints()?, self.read_tool()?);
        if stop.is_stopped() {
            let mut run = Run::new(Ending::Stopped);
            run.push(0.0, first.0, first.1);
            return Ok(run);
        }
        let moving = stop.moving(); // while the scene script runs the sequence
        let (rec, outcome) = self.run_joint_targets_partly(&samples[1..], stop);
        drop(moving);
        // Once the scene script was sent the sequence, the robot may have moved: a failure
        // then ends the run Failed with what was recorded (the start, and every part the
        // script finished), not an error.
        let (stopped, failed) = match outcome {
            Ok(stopped) => (stopped, None),
            Err(e) => (false, Some(e.to_string())),
        };
        // A stop that came after the script's last step found the motion finished.
        let stopped = stopped && rec.time.len() + 1 < samples.len();
        let cut = stopped || failed.is_some();
        let mut run = Run::new(match failed {
            Some(why) => Ending::Failed(why),
            None if stopped => Ending::Stopped,
            None => Ending::Finished,
        });
        let at = |i: usize| -> (f64, Vec<f64>, IsometryMatrix3<f64>) {
            if i == 0 {
                (0.0, first.0.clone(), first.1)
            } else {
                (rec.time[i - 1] - t0, rec.q[i - 1].clone(), rec.tool[i - 1])
            }
        };
        let exact =
            samples.len() == plan.points().len() && (plan.dt() - self.dt).abs() <= 1e-12 * self.dt;
        for k in 0..plan.points().len() {
            let i = if exact {
                k
            } else {
                cps_robot::step_of(plan, k, self.dt, samples.len())
            };
            if cut && i > rec.time.len() {
                break; // not reached: the run was stopped or failed before
            }
            let (t, q, tool) = at(i.min(rec.time.len()));
            run.push(if exact { t } else { plan.time(k) }, q, tool);
        }
        Ok(run)
    }

    fn teleport(&mut self, q: &[f64]) -> Result<bool, RobotError> {
        self.reset(q)?;
        Ok(true)
    }

    /// How the scene executes: through cps's script, or stepped call by call.
    fn report(&self) -> Option<String> {
        let robot = &self.robot;
        if self.target.is_some() {
            None
        } else if self.script.is_some() {
            Some(format!(
                "trajectories run by the scene's /{robot}/{} script",
                executor::SCRIPT_ALIAS
            ))
        } else {
            Some(format!(
                "stepped call by call: the scene has no /{robot}/{} script (configs/coppeliasim/cpsExecutor.lua)",
                executor::SCRIPT_ALIAS
            ))
        }
    }

    fn stepped(&mut self) -> Option<&mut dyn Stepped> {
        Some(self)
    }
}
