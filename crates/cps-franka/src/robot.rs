//! A Franka as a robot of cps's execution contract ([`cps_robot::Robot`]): a plan's
//! motion streamed at 1 kHz by the realtime loop and recorded, so the experiments, the
//! command line and Python drive a Franka as they drive any robot — through the guard
//! (limits, approach, slowing) and with a stop token.
//!
//! A plan's motion (the spline through its points, at rest at both ends) is sampled every
//! millisecond; the stream starts where the robot holds its position (its last desired
//! position), blended into when the two differ by less than
//! [`START_TOLERANCE`](cps_robot::START_TOLERANCE), is
//! checked whole against the arm's per-millisecond limits ([`check_trajectory`]) and
//! streamed ([`execute_stream`]). Entry k of the run is the state the robot reported on the
//! tick of point k's time. The tool poses are the model's forward kinematics of the
//! measured joints, in the model's world frame.
//!
//! At opening, the model's tool in the robot's base frame is compared with the robot's own
//! `O_T_EE`, and the model's flange with the robot's own URDF (`GetRobotModel`), so a
//! model that is not this arm is named instead of missing every target by the difference.

use cps_robot::{
    BLEND_SHARE, Breach, Ending as RunEnding, Generator, Plan, Robot, RobotError, RobotModel, Run,
    StopToken, Streaming,
};
use nalgebra::{IsometryMatrix3, Matrix4};

use crate::FrankaError;
use crate::limits::{Arm, DT, RateLimits};
use crate::motion::{CheckedStream, Start, check_trajectory, execute_stream, record_states};
use crate::rt::{
    JointPositions, LoopOptions, MotionEnd, MotionReport, Realtime, run_joint_positions,
    start_position,
};
use crate::session::{Connection, Timeouts};

/// The largest distance (m) allowed between the model's tool and the robot's own end
/// effector (`O_T_EE`), both in the robot's base frame, at the configuration the robot is
/// found in.
pub const TOOL_AGREEMENT: f64 = 0.005;

/// The largest flange distance (m) allowed between the robot's own URDF and the model.
pub const MODEL_AGREEMENT: f64 = 1e-3;

/// The flange of a Franka arm (URDF `link8`): this far along joint 7's z axis (m), from
/// Franka's published kinematics.
const FLANGE: f64 = 0.107;

/// How to reach a Franka.
#[derive(Debug, Clone)]
pub struct FrankaSettings {
    /// `ip` or `ip:port`.
    pub host: String,
    /// Whose limits the commands are checked against.
    pub arm: Arm,
    /// Realtime scheduling of the loop thread.
    pub realtime: Realtime,
    /// The period (s) plans are made at for it (experiments; any period is streamed).
    pub dt: f64,
}

/// A Franka arm driven through the execution contract.
#[derive(Debug)]
pub struct FrankaRobot {
    host: String,
    conn: Connection,
    limits: RateLimits,
    options: LoopOptions,
    model: RobotModel,
    dt: f64,
    /// The largest flange distance between the robot's own URDF and the model.
    model_gap: Option<f64>,
    /// Every motion's report, in order.
    reports: Vec<MotionReport>,
    /// The stream of the last motion (its approach, its commands).
    last_stream: Option<CheckedStream>,
    /// The last plan checked, from where, and its stream: the guard's check and the run
    /// that follows it build the stream once.
    checked: Option<(Plan, [f64; 7], CheckedStream)>,
    /// The last recording without motion.
    recorded: Vec<crate::Sample>,
}

fn robot_error(host: &str, message: impl Into<String>) -> RobotError {
    RobotError::Robot {
        robot: format!("the Franka at {host}"),
        message: message.into(),
    }
}

fn franka_error(host: &str, e: FrankaError) -> RobotError {
    robot_error(host, e.to_string())
}

/// Reads the robot's URDF (GetRobotModel) with cps's URDF loader and compares its flange
/// (`link8`) with the model's (base and tool taken off, the flange put on) at 16
/// configurations spread over the model's range: the largest distance, metres.
fn compare_with_robot_model(conn: &mut Connection, model: &RobotModel) -> Result<f64, String> {
    let chain = &model.chain;
    let xml = conn
        .robot_model()
        .map_err(|e| format!("cannot read the robot's own model (GetRobotModel): {e}"))?;
    let urdf = cps_kinematics::chain_from_urdf(&xml, Some("link8"))
        .map_err(|e| format!("the robot's own model (GetRobotModel) cannot be read: {e}"))?;
    if urdf.chain.dof() != 7 {
        return Err(format!(
            "the robot's own model has {} joints up to link8, not 7",
            urdf.chain.dof()
        ));
    }
    let base_inv = chain
        .base()
        .to_homogeneous()
        .try_inverse()
        .ok_or("the model's base placement is not invertible")?;
    let tool_inv = chain
        .tool()
        .to_homogeneous()
        .try_inverse()
        .ok_or("the model's tool transform is not invertible")?;
    let (lo, hi) = chain
        .limits()
        .map(|(l, h)| (l.to_vec(), h.to_vec()))
        .unwrap_or((vec![-2.8; 7], vec![2.8; 7]));
    let flange = nalgebra::Translation3::new(0.0, 0.0, FLANGE).to_homogeneous();
    let mut worst: f64 = 0.0;
    for k in 0..16 {
        // Deterministic points inside the range (a low-discrepancy walk per joint).
        let q: Vec<f64> = (0..7)
            .map(|j| {
                let u = ((k as f64 + 0.5) * (0.618_034 + 0.1 * j as f64)).fract();
                lo[j] + (0.05 + 0.9 * u) * (hi[j] - lo[j])
            })
            .collect();
        // The model's joint-7 frame, then Franka's flange 0.107 m along its z axis.
        let ours = base_inv
            * chain.fk(&q).map_err(|e| e.to_string())?.to_homogeneous()
            * tool_inv
            * flange;
        let theirs = urdf.chain.fk(&q).map_err(|e| e.to_string())?;
        let p = theirs.translation.vector;
        let gap = ((ours[(0, 3)] - p.x).powi(2)
            + (ours[(1, 3)] - p.y).powi(2)
            + (ours[(2, 3)] - p.z).powi(2))
        .sqrt();
        worst = worst.max(gap);
    }
    Ok(worst)
}

impl FrankaRobot {
    /// Connects; `model` (7 joints) is what tool poses are computed with, and what plans are
    /// checked against with the arm's own limits in place of the model's (its joint range,
    /// speed, acceleration, jerk, torque and torque rate: the robot enforces these, whatever
    /// robot a scene names). Every motion checks first that the robot is ready (no error,
    /// idle); a recording does not (the arm may be guided by hand meanwhile). Nothing is
    /// compared with the robot's own model: for a model that is the arm itself (the
    /// built-in `fr3` or `panda` at its flange, the robot's base frame as the world).
    pub fn connect(settings: &FrankaSettings, model: RobotModel) -> Result<Self, RobotError> {
        let host = settings.host.clone();
        if model.chain.dof() != 7 {
            return Err(robot_error(
                &host,
                format!("the model has {} joints; a Franka has 7", model.chain.dof()),
            ));
        }
        if !(settings.dt.is_finite() && settings.dt > 0.0) {
            return Err(robot_error(
                &host,
                format!(
                    "the planning period {} s must be finite and > 0",
                    settings.dt
                ),
            ));
        }
        let limits = RateLimits::of(settings.arm);
        let model = with_arm_limits(model, &limits).map_err(|e| robot_error(&host, e))?;
        let conn =
            Connection::connect(&host, Timeouts::default()).map_err(|e| franka_error(&host, e))?;
        Ok(FrankaRobot {
            host,
            conn,
            limits,
            options: LoopOptions {
                realtime: settings.realtime,
                ..LoopOptions::default()
            },
            model,
            dt: settings.dt,
            model_gap: None,
            reports: Vec::new(),
            last_stream: None,
            checked: None,
            recorded: Vec::new(),
        })
    }

    /// [`FrankaRobot::connect`], then checks that `model` (a scene's robot: base and tool
    /// placed) puts the tool where the robot says its end effector is (within
    /// [`TOOL_AGREEMENT`]) and its flange where the robot's own URDF does (within
    /// [`MODEL_AGREEMENT`]).
    pub fn open(settings: &FrankaSettings, model: RobotModel) -> Result<Self, RobotError> {
        let mut robot = FrankaRobot::connect(settings, model)?;
        let host = robot.host.clone();
        let state = robot
            .conn
            .read_state()
            .map_err(|e| franka_error(&host, e))?;
        robot
            .conn
            .ensure_ready(&state)
            .map_err(|e| franka_error(&host, e))?;
        let chain = &robot.model.chain;
        let ours = chain.fk(&state.q).map_err(|e| {
            robot_error(
                &host,
                format!("forward kinematics at the robot's joints: {e}"),
            )
        })?;
        let in_base =
            chain.base().to_homogeneous().try_inverse().ok_or_else(|| {
                robot_error(&host, "the scene's base placement is not invertible")
            })? * ours.to_homogeneous();
        let theirs = Matrix4::from_column_slice(&state.o_t_ee);
        let p = in_base.fixed_view::<3, 1>(0, 3).into_owned();
        let gap = ((p.x - theirs[(0, 3)]).powi(2)
            + (p.y - theirs[(1, 3)]).powi(2)
            + (p.z - theirs[(2, 3)]).powi(2))
        .sqrt();
        if gap > TOOL_AGREEMENT {
            return Err(robot_error(
                &host,
                format!(
                    "the robot puts its end effector at ({:.4}, {:.4}, {:.4}) m in its base frame, the scene's model puts its tool at ({:.4}, {:.4}, {:.4}) m ({:.1} mm apart): the scene's tool is not the end effector set on the robot (Desk's end-effector settings, SetEEToK/SetNEToEE), or the scene is not this arm",
                    theirs[(0, 3)],
                    theirs[(1, 3)],
                    theirs[(2, 3)],
                    p.x,
                    p.y,
                    p.z,
                    gap * 1e3
                ),
            ));
        }
        let model_gap = compare_with_robot_model(&mut robot.conn, &robot.model)
            .map_err(|e| robot_error(&host, e))?;
        if model_gap > MODEL_AGREEMENT {
            return Err(robot_error(
                &host,
                format!(
                    "the robot's own model (GetRobotModel's URDF, read up to its flange link8) puts the flange {:.1} mm from where the scene's model does at the same joints: the scene's robot is not this arm",
                    model_gap * 1e3
                ),
            ));
        }
        robot.model_gap = Some(model_gap);
        Ok(robot)
    }

    /// The robot's address.
    pub fn host(&self) -> &str {
        &self.host
    }

    /// The arm's per-millisecond limits.
    pub fn rate_limits(&self) -> &RateLimits {
        &self.limits
    }

    /// The largest distance (m) between the flange of the robot's own URDF and the model's,
    /// over the configurations compared at opening ([`FrankaRobot::open`]).
    pub fn model_gap(&self) -> Option<f64> {
        self.model_gap
    }

    /// Every motion's report so far (approaches included, in the motion they were part
    /// of).
    pub fn reports(&self) -> &[MotionReport] {
        &self.reports
    }

    /// The samples of the last recording ([`Robot::record`]): the state at the robot's rate,
    /// `q_c` its desired position.
    pub fn last_recording(&self) -> &[crate::Sample] {
        &self.recorded
    }

    /// The stream of the last motion: its 1 kHz commands, how many were the blend or
    /// approach into the plan, where the robot was.
    pub fn last_stream(&self) -> Option<&CheckedStream> {
        self.last_stream.as_ref()
    }

    /// The connection, for what the contract does not cover (the gripper's state, torque
    /// control, guiding by hand).
    pub fn connection(&mut self) -> &mut Connection {
        &mut self.conn
    }

    /// A run stopped before it moved: where the robot stands, as every robot reports it.
    fn stopped_before_moving(&mut self) -> Result<Run, RobotError> {
        let q = Robot::joint_positions(self)?;
        let tool = self.model.chain.fk(&q)?;
        let mut run = Run::new(RunEnding::Stopped);
        run.push(0.0, q, tool);
        Ok(run)
    }

    /// A plan's motion as 1 kHz commands, checked from where the robot holds its position
    /// (a difference within [`START_TOLERANCE`] blended into), kept in `self.checked`
    /// (built once for the guard's check and the run that follows it, never copied); its
    /// breach if it has one.
    fn stream(&mut self, plan: &Plan) -> Result<Option<Breach>, RobotError> {
        plan.check_dof(7)?;
        let host = self.host.clone();
        let state = self.conn.read_state().map_err(|e| franka_error(&host, e))?;
        self.conn
            .ensure_ready(&state)
            .map_err(|e| franka_error(&host, e))?;
        let from = start_position(&state);
        // The same plan from the same place: the stream the guard's check built.
        if let Some((p, f, _)) = &self.checked
            && *f == from
            && p == plan
        {
            return Ok(None);
        }
        self.checked = None;
        let commands: Vec<[f64; 7]> = plan
            .samples(DT)
            .iter()
            .map(|q| <[f64; 7]>::try_from(q.as_slice()).expect("seven joints"))
            .collect();
        match check_trajectory(&self.limits, from, &commands, Start::Approach(BLEND_SHARE)) {
            Ok(stream) => {
                self.checked = Some((plan.clone(), from, stream));
                Ok(None)
            }
            Err(FrankaError::Limit(b)) => Ok(Some(b)),
            Err(e) => Err(franka_error(&host, e)),
        }
    }
}

/// `model` with the arm's limits in place of its own.
fn with_arm_limits(mut model: RobotModel, limits: &RateLimits) -> Result<RobotModel, String> {
    model.chain = model
        .chain
        .with_limits(&limits.q_min, &limits.q_max)
        .and_then(|c| c.with_velocity_limits(&limits.dq_max))
        .map_err(|e| format!("the arm's limits on the model: {e}"))?;
    model.limits = cps_kinematics::JointLimits {
        acceleration: Some(limits.ddq_max.to_vec()),
        jerk: Some(limits.dddq_max.to_vec()),
        torque: Some(limits.tau_max.to_vec()),
        torque_rate: Some(limits.dtau_max.to_vec()),
    };
    // Joint motion: the arm holds no Cartesian limit on it.
    model.cartesian = None;
    Ok(model)
}

fn ending(report: &MotionReport) -> RunEnding {
    match &report.ending {
        MotionEnd::Finished => RunEnding::Finished,
        MotionEnd::Stopped => RunEnding::Stopped,
        // A refused command with the loop's side of it: how long the robot went without
        // an answer, and what the reference tracker could confirm.
        e @ MotionEnd::LimitBrake(_) => {
            let (t, r, l) = (&report.timing, &report.reference, &report.limited);
            RunEnding::Failed(format!(
                "{} (the loop: at most {} robot periods between answers, {} ticks missed, {} states stale, {} answers withheld as late; {} cycles extrapolated by the robot, {} states unconfirmed; the refused command {:.3} mrad from where the robot's reference was heading, {} commands limited before it, by at most {:.3} mrad; realtime scheduling {})",
                e.sentence(),
                t.longest_gap,
                t.missed,
                t.stale,
                t.withheld,
                r.extrapolated,
                r.unconfirmed,
                1e3 * l.refused_gap,
                l.commands,
                1e3 * l.deviation,
                if t.realtime { "on" } else { "off" }
            ))
        }
        other => RunEnding::Failed(other.sentence()),
    }
}

impl Streaming for FrankaRobot {
    /// The 1 kHz loop limits every command against the reference the robot holds.
    fn limits_each_command(&self) -> bool {
        true
    }

    /// The generator runs inside the realtime loop, once per tick, with the measured joints;
    /// every command passes the arm's per-millisecond check or the robot brakes. One entry
    /// per tick.
    fn stream(
        &mut self,
        next: &mut Generator<'_>,
        max_commands: usize,
        stop: &StopToken,
    ) -> Result<Run, RobotError> {
        let host = self.host.clone();
        if stop.is_stopped() {
            return self.stopped_before_moving();
        }
        let state = self.conn.read_state().map_err(|e| franka_error(&host, e))?;
        self.conn
            .ensure_ready(&state)
            .map_err(|e| franka_error(&host, e))?;
        let options = LoopOptions {
            max_ticks: max_commands + 10 + crate::rt::BRAKE_RESERVE,
            ..self.options
        };
        let report = {
            let _moving = stop.moving();
            run_joint_positions(
                &mut self.conn,
                self.limits,
                &options,
                stop.flag(),
                |state, t| {
                    let mut q = [0.0; 7];
                    let measured = cps_robot::Measured {
                        q: &state.q,
                        dq: &state.dq,
                        tau: &state.tau_j,
                    };
                    let finished = next(&measured, t, &mut q);
                    JointPositions { q, finished }
                },
            )
        }
        .map_err(|e| franka_error(&host, e))?;
        let mut run = Run::new(ending(&report));
        for s in &report.samples {
            let q = s.q.to_vec();
            let tool = self.model.chain.fk(&q)?;
            run.push(s.t, q, tool);
        }
        self.reports.push(report);
        self.last_stream = None;
        Ok(run)
    }
}

impl Robot for FrankaRobot {
    fn name(&self) -> String {
        format!("the Franka at {}", self.host)
    }

    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn dt(&self) -> f64 {
        self.dt
    }

    /// Where the robot holds its position (its last desired position, where a motion
    /// starts; the measured one when it reports none).
    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        let host = self.host.clone();
        let s = self.conn.read_state().map_err(|e| franka_error(&host, e))?;
        Ok(start_position(&s).to_vec())
    }

    /// The model's tool at the measured joints.
    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, RobotError> {
        let host = self.host.clone();
        let s = self.conn.read_state().map_err(|e| franka_error(&host, e))?;
        Ok(self.model.chain.fk(&s.q)?)
    }

    /// The arm's own rules on the plan's 1 kHz commands (the FR3's position-dependent
    /// speed, the distance a stop needs), from where it holds its position.
    fn check(&mut self, plan: &Plan) -> Result<Option<Breach>, RobotError> {
        self.stream(plan)
    }

    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
        let host = self.host.clone();
        if let Some(b) = self.stream(plan)? {
            return Err(RobotError::Refused {
                robot: self.name(),
                reason: cps_robot::Refusal::Limit(b),
            });
        }
        let (_, _, stream) = self
            .checked
            .take()
            .expect("stream() keeps the checked stream");
        if stop.is_stopped() {
            return self.stopped_before_moving();
        }
        let report = {
            let _moving = stop.moving();
            execute_stream(
                &mut self.conn,
                self.limits,
                &stream,
                &self.options,
                stop.flag(),
            )
        }
        .map_err(|e| franka_error(&host, e))?;
        let mut run = Run::new(ending(&report));
        for k in 0..plan.points().len() {
            // The sample that answered the point's time on the stream's clock.
            let Some(s) = report
                .sample_at_clock(stream.approach as f64 * DT + plan.time(k))
                .map(|i| &report.samples[i])
            else {
                break;
            };
            let q = s.q.to_vec();
            let tool = self.model.chain.fk(&q)?;
            run.push(plan.time(k), q, tool);
        }
        if run.ending == RunEnding::Finished && run.len() < plan.points().len() {
            run.ending = RunEnding::Failed(format!(
                "the motion ended after {} of {} planned points",
                run.len(),
                plan.points().len()
            ));
        }
        self.reports.push(report);
        self.last_stream = Some(stream);
        Ok(run)
    }

    fn streaming(&mut self) -> Option<&mut dyn Streaming> {
        Some(self)
    }

    /// The state at the robot's rate (1 kHz) without a motion ([`record_states`]); a lost
    /// connection ends it with what came, as [`RunEnding::Failed`].
    fn record(
        &mut self,
        duration: std::time::Duration,
        stop: &StopToken,
    ) -> Result<Run, RobotError> {
        let host = self.host.clone();
        let (samples, lost) = record_states(&mut self.conn, duration, stop.flag())
            .map_err(|e| franka_error(&host, e))?;
        let mut run = Run::new(match lost {
            Some(r) => RunEnding::Failed(format!("the connection was lost: {r}")),
            None if stop.is_stopped() => RunEnding::Stopped,
            None => RunEnding::Finished,
        });
        for s in &samples {
            let q = s.q.to_vec();
            let tool = self.model.chain.fk(&q)?;
            run.push(s.t, q, tool);
        }
        self.recorded = samples;
        Ok(run)
    }

    /// The peak limit usage of every stream sent, the loop's worst p99 latency and the
    /// ticks missed.
    fn report(&self) -> Option<String> {
        if self.reports.is_empty() {
            return None;
        }
        let mut peak = [0.0f64; 3];
        let mut p99 = 0.0f64;
        let mut cycles = crate::Cycles::default();
        for r in &self.reports {
            for (p, row) in peak.iter_mut().zip(&r.peak_usage) {
                *p = row.iter().fold(*p, |a, &b| a.max(b));
            }
            p99 = p99.max(r.timing.p99_us);
            cycles.add(&r.cycles());
        }
        Some(format!(
            "{} motions sent at 1 kHz, at most {:.0} % of the velocity, {:.0} % of the acceleration and {:.0} % of the jerk limits; loop p99 {p99:.1} us, {} ticks missed, {} states stale; {} cycles extrapolated by the robot, {} commands dropped, {} answers withheld as late, {} states unconfirmed, {} commands limited (largest change {:.6} rad)",
            self.reports.len(),
            peak[0] * 100.0,
            peak[1] * 100.0,
            peak[2] * 100.0,
            cycles.missed,
            cycles.stale,
            cycles.extrapolated,
            cycles.dropped,
            cycles.withheld,
            cycles.unconfirmed,
            cycles.limited,
            cycles.largest_change,
        ))
    }
}
