//! `[robot] backend = "franka"`: a Franka arm (FR3 or Panda) over the Franka Control
//! Interface as a [`RobotBackend`], so the robot kinds (imitation, promp, viapoint_joint,
//! viapoint_executed) execute what they learned on a real or simulated robot.
//!
//! The experiment plans every control period `dt` (10 ms in the shipped files) on the
//! scene's model; the robot takes a command every millisecond. [`FrankaBackend`] runs whole
//! sequences ([`RobotBackend::runs_sequences`]): the planned rows become 1 kHz commands by
//! a cubic spline at rest at both ends ([`commands_at_1khz`]), preceded by an approach
//! from where the robot stands, checked whole against the arm's per-millisecond limits
//! before anything is sent, streamed by `cps-franka`'s realtime loop, and recorded. Row k
//! of the recording is the state the robot reported on the tick its command was sent.
//!
//! A plan made on the model at 10 ms can break the arm's acceleration or jerk limits at
//! 1 kHz (an inverse-kinematics controller turning sharply at a via point). Such a sequence
//! is slowed uniformly — velocities by the factor, accelerations by its square, jerks by its
//! cube — as little as the check needs, at most [`MAX_SLOWING`]×, and the recording's clock
//! says so; a sequence that leaves the joint range is refused.
//!
//! The tool pose of a recording is the scene model's forward kinematics of the measured
//! joints, in the scene's world frame; at opening, the model's tool in the robot's base
//! frame is compared with the robot's own `O_T_EE`, so a scene whose tool is not the
//! robot's end effector is named instead of missing every via point by the difference.
//!
//! Stops: [`STOP`] set by the host program (the command line's Ctrl-C) brakes a moving
//! robot within its limits and ends the execution with an error saying so; [`MOVING`] is
//! true while a motion runs, so a second Ctrl-C does not exit before the brake ends.

use std::sync::atomic::{AtomicBool, Ordering::SeqCst};

use cps_franka::limits::{Arm, DT, Quantity, RateLimits};
use cps_franka::{
    CheckedStream, Connection, Ending, FrankaError, LoopOptions, MotionReport, Realtime,
    START_TOLERANCE, Start, Timeouts, check_trajectory, execute_stream,
};
use cps_kinematics::{JointSpline, KinematicsError, SerialChain};
use cps_kinematics::{RobotBackend, StepRecording};
use nalgebra::{IsometryMatrix3, Matrix4};

use crate::franka::APPROACH_SHARE;

/// Set by the host program to brake every robot an experiment moves (Ctrl-C, SIGTERM).
pub static STOP: AtomicBool = AtomicBool::new(false);

/// True while an experiment's robot moves.
pub static MOVING: AtomicBool = AtomicBool::new(false);

/// The largest distance (m) allowed between the scene model's tool and the robot's own
/// end effector (`O_T_EE`), both in the robot's base frame, at the configuration the robot
/// is found in.
pub const TOOL_AGREEMENT: f64 = 0.005;

/// A Franka arm as an experiment's robot backend.
#[derive(Debug)]
pub struct FrankaBackend {
    host: String,
    conn: Connection,
    limits: RateLimits,
    options: LoopOptions,
    model: SerialChain,
    dt: f64,
    clock: f64,
    /// The largest flange distance between the robot's own URDF and the scene's model.
    model_gap: f64,
    /// The largest uniform slowing a planned sequence needed so far (1 = none).
    slowest: f64,
    /// Every motion's report, approaches included, in order.
    reports: Vec<MotionReport>,
}

/// The settings of [`FrankaBackend::open`].
#[derive(Debug, Clone)]
pub struct FrankaSettings {
    /// `ip` or `ip:port`.
    pub host: String,
    /// Whose limits the commands are checked against.
    pub arm: Arm,
    /// Realtime scheduling of the loop thread.
    pub realtime: Realtime,
    /// The experiment's control period (s): a whole number of milliseconds.
    pub dt: f64,
}

fn backend_error(host: &str, message: impl Into<String>) -> KinematicsError {
    KinematicsError::Backend {
        backend: format!("the Franka at {host}"),
        message: message.into(),
    }
}

fn joints7(q: &[f64], what: &str, host: &str) -> Result<[f64; 7], KinematicsError> {
    <[f64; 7]>::try_from(q)
        .map_err(|_| backend_error(host, format!("{what} has {} joints, not 7", q.len())))
}

/// The 1 kHz commands for `rows` planned every `dt` seconds (row k at time k·dt): a cubic
/// spline through them at rest at both ends, sampled every millisecond from 0 to the last
/// row's time, so row k is command k·dt/1 ms exactly. `dt` must be a whole number of
/// milliseconds.
pub fn commands_at_1khz(rows: &[Vec<f64>], dt: f64) -> Result<Vec<[f64; 7]>, String> {
    commands_slowed(rows, dt, 1.0)
}

/// [`commands_at_1khz`] with the movement slowed by `slowing` ≥ 1 (row k at time
/// k·dt·slowing): velocities shrink by the factor, accelerations by its square, jerks by
/// its cube. Off 1, the rows are passed through the spline rather than copied.
pub fn commands_slowed(rows: &[Vec<f64>], dt: f64, slowing: f64) -> Result<Vec<[f64; 7]>, String> {
    let per_row = (dt / DT).round() as usize;
    if per_row == 0 || ((per_row as f64) * DT - dt).abs() > 1e-9 {
        return Err(format!(
            "the control period {dt} s is not a whole number of milliseconds"
        ));
    }
    if let Some(k) = rows
        .iter()
        .position(|r| r.len() != 7 || r.iter().any(|x| !x.is_finite()))
    {
        return Err(format!(
            "planned row {k} is not seven finite joint positions"
        ));
    }
    match rows.len() {
        0 => return Err("no rows to execute".into()),
        1 => {
            return Ok(vec![
                <[f64; 7]>::try_from(rows[0].as_slice()).expect("seven"),
            ]);
        }
        _ => {}
    }
    let knots: Vec<f64> = (0..rows.len()).map(|k| k as f64 * dt).collect();
    let spline = JointSpline::new(&knots, rows).map_err(|e| e.to_string())?;
    let span = (rows.len() - 1) as f64 * dt;
    let n = if slowing == 1.0 {
        (rows.len() - 1) * per_row
    } else {
        (span * slowing / DT).ceil() as usize
    };
    let mut out = Vec::with_capacity(n + 1);
    let mut q = [0.0; 7];
    for i in 0..=n {
        if slowing != 1.0 {
            spline.positions_into((i as f64 * DT / slowing).min(span), &mut q);
        } else if i % per_row == 0 {
            // On a knot the row itself, not the spline's rounding of it.
            q.copy_from_slice(&rows[i / per_row]);
        } else {
            spline.positions_into(i as f64 * DT, &mut q);
        }
        out.push(q);
    }
    Ok(out)
}

/// The most a planned sequence is slowed to keep the arm's rate limits; a sequence that
/// still breaks one is refused.
pub const MAX_SLOWING: f64 = 10.0;

/// The largest flange distance (m) allowed between the robot's own URDF and the scene's
/// model.
pub const MODEL_AGREEMENT: f64 = 1e-3;

/// The flange of a Franka arm (URDF `link8`): this far along joint 7's z axis (m), from
/// Franka's published kinematics.
const FLANGE: f64 = 0.107;

/// Reads the robot's URDF (GetRobotModel) with cps's URDF loader and compares its flange
/// (`link8`) with the scene model's (base and tool taken off, the flange put on) at 16 configurations spread
/// over the model's range: the largest distance, metres.
fn compare_with_robot_model(conn: &mut Connection, model: &SerialChain) -> Result<f64, String> {
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
    let base_inv = model
        .base()
        .to_homogeneous()
        .try_inverse()
        .ok_or("the scene's base placement is not invertible")?;
    let tool_inv = model
        .tool()
        .to_homogeneous()
        .try_inverse()
        .ok_or("the scene's tool transform is not invertible")?;
    let (lo, hi) = model
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
        // The scene's joint-7 frame, then Franka's flange 0.107 m along its z axis.
        let ours = base_inv
            * model.fk(&q).map_err(|e| e.to_string())?.to_homogeneous()
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

impl FrankaBackend {
    /// Connects, checks that the robot is ready (no error, idle) and that `model` (the
    /// scene's chain, base and tool included) puts the tool where the robot says its end
    /// effector is, within [`TOOL_AGREEMENT`].
    pub fn open(settings: &FrankaSettings, model: &SerialChain) -> Result<Self, String> {
        let host = settings.host.clone();
        if model.dof() != 7 {
            return Err(format!(
                "the scene's robot has {} joints; a Franka has 7",
                model.dof()
            ));
        }
        let mut conn =
            Connection::connect(&host, Timeouts::default()).map_err(|e| e.to_string())?;
        let state = conn.read_state().map_err(|e| e.to_string())?;
        conn.ensure_ready(&state).map_err(|e| e.to_string())?;
        // The model's tool in the robot's base frame against the robot's own O_T_EE.
        let ours = model
            .fk(&state.q)
            .map_err(|e| format!("forward kinematics at the robot's joints: {e}"))?;
        let in_base = model
            .base()
            .to_homogeneous()
            .try_inverse()
            .ok_or("the scene's base placement is not invertible")?
            * ours.to_homogeneous();
        let theirs = Matrix4::from_column_slice(&state.o_t_ee);
        let p = in_base.fixed_view::<3, 1>(0, 3).into_owned();
        let gap = ((p.x - theirs[(0, 3)]).powi(2)
            + (p.y - theirs[(1, 3)]).powi(2)
            + (p.z - theirs[(2, 3)]).powi(2))
        .sqrt();
        if gap > TOOL_AGREEMENT {
            return Err(format!(
                "the robot puts its end effector at ({:.4}, {:.4}, {:.4}) m in its base frame, the scene's model puts its tool at ({:.4}, {:.4}, {:.4}) m ({:.1} mm apart): the scene's tool is not the end effector set on the robot (Desk's end-effector settings, SetEEToK/SetNEToEE), or the scene is not this arm",
                theirs[(0, 3)],
                theirs[(1, 3)],
                theirs[(2, 3)],
                p.x,
                p.y,
                p.z,
                gap * 1e3
            ));
        }
        let model_gap = compare_with_robot_model(&mut conn, model)?;
        if model_gap > MODEL_AGREEMENT {
            return Err(format!(
                "the robot's own model (GetRobotModel's URDF, read up to its flange link8) puts the flange {:.1} mm from where the scene's model does at the same joints: the scene's robot is not this arm",
                model_gap * 1e3
            ));
        }
        Ok(FrankaBackend {
            host,
            model_gap,
            slowest: 1.0,
            conn,
            limits: RateLimits::of(settings.arm),
            options: LoopOptions {
                realtime: settings.realtime,
                ..LoopOptions::default()
            },
            model: model.clone(),
            dt: settings.dt,
            clock: 0.0,
            reports: Vec::new(),
        })
    }

    /// The largest distance (m) between the flange of the robot's own URDF
    /// (GetRobotModel) and the scene model's, over the configurations compared at opening.
    pub fn model_gap(&self) -> f64 {
        self.model_gap
    }

    /// The largest uniform slowing a planned sequence needed to keep the arm's rate limits
    /// (1 = every sequence ran at its planned timing).
    pub fn slowest(&self) -> f64 {
        self.slowest
    }

    /// Every motion's report so far, approaches included.
    pub fn reports(&self) -> &[MotionReport] {
        &self.reports
    }

    /// The planned rows as a checked stream, slowed uniformly as far as the arm's rate
    /// limits need (at most [`MAX_SLOWING`]×): the stream and the slowing.
    fn check_slowed(&mut self, rows: &[Vec<f64>]) -> Result<(CheckedStream, f64), KinematicsError> {
        let state = self
            .conn
            .read_state()
            .map_err(|e| backend_error(&self.host, e.to_string()))?;
        self.conn
            .ensure_ready(&state)
            .map_err(|e| backend_error(&self.host, e.to_string()))?;
        let mut slowing: f64 = 1.0;
        loop {
            let commands = commands_slowed(rows, self.dt, slowing)
                .map_err(|e| backend_error(&self.host, e))?;
            let state = self
                .conn
                .read_state()
                .map_err(|e| backend_error(&self.host, e.to_string()))?;
            let from = cps_franka::rt::start_position(&state);
            match check_trajectory(
                &self.limits,
                from,
                &commands,
                Start::Approach(APPROACH_SHARE),
            ) {
                Ok(stream) => return Ok((stream, slowing)),
                Err(FrankaError::Limit(b)) if slowing < MAX_SLOWING => {
                    // Enough for this breach (velocity ∝ 1/s, acceleration 1/s², jerk
                    // 1/s³), with 5 % to spare; the next breach may need more.
                    let ratio = (b.value / b.limit).abs().max(1.0);
                    let need = match b.quantity {
                        Quantity::Velocity => ratio,
                        Quantity::Acceleration => ratio.sqrt(),
                        Quantity::Jerk => ratio.cbrt(),
                        Quantity::StoppingDistance => 1.25,
                        Quantity::Position | Quantity::NotFinite => {
                            return Err(backend_error(
                                &self.host,
                                format!("refused before sending anything: {b}"),
                            ));
                        }
                    };
                    slowing = (slowing * need * 1.05).min(MAX_SLOWING);
                }
                Err(FrankaError::Limit(b)) => {
                    return Err(backend_error(
                        &self.host,
                        format!(
                            "refused before sending anything: even slowed {MAX_SLOWING}x the planned movement breaks a limit: {b}"
                        ),
                    ));
                }
                Err(other) => return Err(backend_error(&self.host, other.to_string())),
            }
        }
    }

    /// Streams a checked stream and keeps the report; its index. Any ending but a
    /// finished motion is an error naming it (the report is kept in [`Self::reports`]).
    fn send(&mut self, stream: &CheckedStream) -> Result<usize, KinematicsError> {
        let host = self.host.clone();
        if STOP.load(SeqCst) {
            return Err(backend_error(&host, "stopped on request before moving"));
        }
        MOVING.store(true, SeqCst);
        let report = execute_stream(&mut self.conn, self.limits, stream, &self.options, &STOP);
        MOVING.store(false, SeqCst);
        let report = report.map_err(|e| backend_error(&host, e.to_string()))?;
        let ending = report.ending.clone();
        self.reports.push(report);
        if ending != Ending::Finished {
            return Err(backend_error(&host, ending.sentence()));
        }
        Ok(self.reports.len() - 1)
    }

    fn unsupported(&self, what: &str) -> KinematicsError {
        backend_error(
            &self.host,
            format!(
                "{what}: a Franka takes a command every millisecond, so cps streams whole planned sequences (run_joint_targets) instead of stepping"
            ),
        )
    }
}

impl RobotBackend for FrankaBackend {
    fn dof(&self) -> usize {
        7
    }

    fn time_step(&self) -> f64 {
        self.dt
    }

    fn joint_positions(&mut self) -> Result<Vec<f64>, KinematicsError> {
        let host = self.host.clone();
        let s = self
            .conn
            .read_state()
            .map_err(|e| backend_error(&host, e.to_string()))?;
        Ok(s.q.to_vec())
    }

    fn command_joint_positions(&mut self, _q: &[f64]) -> Result<(), KinematicsError> {
        Err(self.unsupported("commanding one configuration"))
    }

    fn command_joint_velocities(&mut self, _dq: &[f64]) -> Result<(), KinematicsError> {
        Err(self.unsupported("commanding one velocity"))
    }

    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, KinematicsError> {
        let q = self.joint_positions()?;
        self.model.fk(&q)
    }

    fn time(&mut self) -> Result<f64, KinematicsError> {
        Ok(self.clock)
    }

    fn step(&mut self) -> Result<(), KinematicsError> {
        Err(self.unsupported("stepping"))
    }

    /// Moves the robot to `q` (a rest-to-rest approach at 20 % of its limits) and sets the
    /// clock to 0.
    fn reset(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        let to = joints7(q, "the start configuration", &self.host)?;
        let state = self
            .conn
            .read_state()
            .map_err(|e| backend_error(&self.host, e.to_string()))?;
        let from = cps_franka::rt::start_position(&state);
        if (0..7).any(|i| (from[i] - to[i]).abs() > START_TOLERANCE) {
            let (stream, _) = self.check_slowed(&[to.to_vec()])?;
            self.send(&stream)?;
        }
        self.clock = 0.0;
        Ok(())
    }

    fn runs_sequences(&self) -> bool {
        true
    }

    /// The peak limit usage of every stream sent (approaches included), the largest
    /// slowing, the loop's worst p99 latency and the ticks missed.
    fn execution_report(&self) -> Option<String> {
        if self.reports.is_empty() {
            return None;
        }
        let mut peak = [0.0f64; 3];
        let (mut p99, mut missed) = (0.0f64, 0u64);
        for r in &self.reports {
            for (p, row) in peak.iter_mut().zip(&r.peak_usage) {
                *p = row.iter().fold(*p, |a, &b| a.max(b));
            }
            p99 = p99.max(r.timing.p99_us);
            missed += r.timing.missed;
        }
        Some(format!(
            "{} motions sent at 1 kHz, at most {:.0} % of the velocity, {:.0} % of the acceleration and {:.0} % of the jerk limits{}; loop p99 {p99:.1} us, {missed} ticks missed",
            self.reports.len(),
            peak[0] * 100.0,
            peak[1] * 100.0,
            peak[2] * 100.0,
            if self.slowest > 1.0 {
                format!(", slowed up to {:.2}x to keep them", self.slowest)
            } else {
                String::new()
            }
        ))
    }

    fn run_joint_targets(
        &mut self,
        targets: &[Vec<f64>],
    ) -> Result<StepRecording, KinematicsError> {
        let (stream, slowing) = self.check_slowed(targets)?;
        let report = self.send(&stream)?;
        self.slowest = self.slowest.max(slowing);
        let per_row = self.dt / DT * slowing;
        let samples = &self.reports[report].samples;
        let mut rec = StepRecording::default();
        for k in 0..targets.len() {
            let index = stream.approach + (k as f64 * per_row).round() as usize;
            let Some(s) = samples.get(index) else {
                return Err(backend_error(
                    &self.host,
                    format!(
                        "the motion ended after {} of {} planned rows",
                        k,
                        targets.len()
                    ),
                ));
            };
            let q = s.q.to_vec();
            rec.tool.push(self.model.fk(&q)?);
            rec.q.push(q);
            rec.time
                .push(self.clock + (k + 1) as f64 * self.dt * slowing);
        }
        self.clock += targets.len() as f64 * self.dt * slowing;
        Ok(rec)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_become_1khz_commands_through_every_row() {
        // A rest-to-rest cosine per joint, planned every 10 ms for 0.1 s.
        let f = |t: f64, j: usize| {
            0.05 * (j + 1) as f64 * (1.0 - (std::f64::consts::PI * t / 0.1).cos())
        };
        let rows: Vec<Vec<f64>> = (0..11)
            .map(|k| (0..7).map(|j| f(k as f64 * 0.01, j)).collect())
            .collect();
        let c = commands_at_1khz(&rows, 0.01).unwrap();
        assert_eq!(c.len(), 101);
        for (k, r) in rows.iter().enumerate() {
            assert_eq!(c[k * 10].as_slice(), r.as_slice());
        }
        // In between, the spline follows the cosine.
        for (i, q) in c.iter().enumerate() {
            for (j, x) in q.iter().enumerate() {
                assert!((x - f(i as f64 * 1e-3, j)).abs() < 1e-4, "ms {i} joint {j}");
            }
        }
        // Slowed twice: twice as long, half the speed, the same path's ends.
        let slow = commands_slowed(&rows, 0.01, 2.0).unwrap();
        assert_eq!(slow.len(), 201);
        assert_eq!(slow[200].as_slice(), rows[10].as_slice());
        let peak = |c: &[[f64; 7]]| {
            c.windows(2)
                .map(|w| (w[1][6] - w[0][6]).abs())
                .fold(0.0, f64::max)
        };
        assert!((peak(&slow) / peak(&c) - 0.5).abs() < 0.01);
        let e = commands_at_1khz(&rows, 0.0105).unwrap_err();
        assert!(e.contains("whole number of milliseconds"), "{e}");
        let mut bad = rows.clone();
        bad[3][2] = f64::NAN;
        assert!(commands_at_1khz(&bad, 0.01).unwrap_err().contains("row 3"));
    }
}
