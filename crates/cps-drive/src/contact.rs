//! Movements that touch: a force primitive (a DMP over the path on a surface and the
//! force pressed onto it, on one phase — Pastor et al. 2011, Kramberger et al. 2017) and the
//! hybrid task that executes it on a Franka in torque mode: approach until contact, follow
//! the path while the force follows its profile, release, lift off.
//!
//! The primitive has four dimensions: the tool's offset from the point of contact (x, y, z
//! in the robot's base frame; the part along the pressing direction is left to the force)
//! and the force (N) the tool exerts along the pressing direction. It is learned by
//! imitation of a demonstrated profile ([`ForcePrimitive::imitate`]) or from way points
//! ([`ForcePrimitive::from_waypoints`], minimum-jerk between them), in the goal-robust
//! formulation so that a profile may end where it began (0 N to 0 N).
//!
//! [`run_contact`] drives the arm with `cps_franka::control`'s Cartesian impedance, with
//! force along the pressing direction once in contact, and `Sensing`'s momentum observer
//! for the force. Its stages: hold still while the observer's bias is taken; move above the
//! surface; descend at a set speed until the force along the direction exceeds the contact
//! threshold (or give up after the search distance); step the primitive at 1 kHz, its phase
//! slowed by the force error (`1/(1 + gain·|F_d − F|)`, phase stopping); let the force go;
//! lift off. A force above the ceiling at any time ends the task: the force is dropped at
//! once and the tool retreats. Every stop is the loop's controlled stop; every tick is kept.

use std::sync::atomic::AtomicBool;

use cps_dmp::{
    Demonstration, DiscreteDmp, DmpConfig, Formulation, OnlineDmp, Regression, StepInput,
};
use cps_dynamics::Drive;
use cps_franka::control::{
    CartesianGains, CartesianImpedance, ForceAlong, Sensing, SensingOptions,
};
use cps_franka::limits::RateLimits;
use cps_franka::{Connection, FrankaRobot, FrankaSettings, LoopOptions, MotionReport, Torques};
use cps_kinematics::{ArmModel, IkConfig, IkTarget, solve_ik};
use cps_robot::{Guarded, Policy, Robot, StopToken};
use nalgebra::{Isometry3, IsometryMatrix3, Translation3, Vector3, Vector6};

use cps_outcome::InputError;

use crate::error::DriveError;

/// A DMP over the tool's offset on the surface and the pressing force.
#[derive(Debug, Clone)]
pub struct ForcePrimitive {
    /// The four-dimensional DMP (offset x, y, z in m; force in N).
    pub dmp: DiscreteDmp,
    /// Its weights.
    pub weights: Vec<f64>,
}

/// One way point of a contact profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactWaypoint {
    /// Time from contact (s).
    pub t: f64,
    /// The tool's offset from the point of contact (m, base frame).
    pub offset: [f64; 3],
    /// The force pressed along the pressing direction (N, ≥ 0).
    pub force: f64,
}

/// Bases of a force primitive: enough for a press, a slide and a release in a few
/// seconds.
pub const PRIMITIVE_BASES: usize = 30;

impl ForcePrimitive {
    /// Learns the primitive from a demonstration: times (s) and rows `[dx, dy, dz, force]`.
    pub fn imitate(times: Vec<f64>, rows: &[Vec<f64>]) -> Result<Self, DriveError> {
        let bad = |e: cps_dmp::DmpError| InputError(format!("force primitive: {e}"));
        if rows.iter().any(|r| r.len() != 4) {
            return Err(InputError(
                "force primitive: each sample needs four values: dx, dy, dz (m) and force (N)"
                    .into(),
            )
            .into());
        }
        let demo = Demonstration::new(times, rows).map_err(bad)?;
        let duration = demo.duration();
        let mut config = DmpConfig::new(PRIMITIVE_BASES, duration, 1e-3);
        config.formulation = Formulation::GoalRobust;
        let fit = cps_dmp::imitate(&config, &[demo], Regression::default(), Default::default())
            .map_err(bad)?;
        Ok(ForcePrimitive {
            dmp: fit.dmp,
            weights: fit.weights,
        })
    }

    /// The primitive through `points` (at least two, times increasing from 0, forces in
    /// [0, 100] N, offsets within 1 m): minimum-jerk between consecutive way points, sampled
    /// every millisecond, then imitated.
    pub fn from_waypoints(points: &[ContactWaypoint]) -> Result<Self, DriveError> {
        let bad = |i: usize, why: String| InputError(format!("waypoints[{i}]: {why}"));
        if points.len() < 2 {
            return Err(InputError("waypoints: give at least two".into()).into());
        }
        for (i, p) in points.iter().enumerate() {
            if !(p.t.is_finite() && p.force.is_finite() && p.offset.iter().all(|v| v.is_finite())) {
                return Err(bad(i, "every value must be a finite number".into()).into());
            }
            if i == 0 && p.t != 0.0 {
                return Err(
                    bad(i, format!("t = {} s: the first way point is at t = 0", p.t)).into(),
                );
            }
            if i > 0 && p.t <= points[i - 1].t {
                return Err(bad(i, format!("t = {} s: times must increase", p.t)).into());
            }
            if !(0.0..=100.0).contains(&p.force) {
                return Err(bad(
                    i,
                    format!(
                        "force {} N is out of range: it must lie in [0, 100]",
                        p.force
                    ),
                )
                .into());
            }
            if p.offset.iter().any(|v| v.abs() > 1.0) {
                return Err(bad(i, "offset: each component must be at most 1 m".into()).into());
            }
        }
        let end = points.last().map_or(0.0, |p| p.t);
        if end > 120.0 {
            return Err(InputError(format!("waypoints: {end} s long; at most 120 s")).into());
        }
        let n = (end / 1e-3).round() as usize;
        let mut times = Vec::with_capacity(n + 1);
        let mut rows = Vec::with_capacity(n + 1);
        let mut seg = 0;
        for k in 0..=n {
            let t = (k as f64 * 1e-3).min(end);
            while seg + 2 < points.len() && t > points[seg + 1].t {
                seg += 1;
            }
            let (a, b) = (&points[seg], &points[seg + 1]);
            let s = ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0);
            let m = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
            let mut row: Vec<f64> = (0..3)
                .map(|d| a.offset[d] + (b.offset[d] - a.offset[d]) * m)
                .collect();
            row.push(a.force + (b.force - a.force) * m);
            times.push(t);
            rows.push(row);
        }
        Self::imitate(times, &rows)
    }

    /// The primitive's duration (s).
    pub fn duration(&self) -> f64 {
        self.dmp.config().tau
    }
}

/// Everything the contact task needs besides the robot and its model.
#[derive(Debug, Clone)]
pub struct ContactPlan {
    /// Where the approach starts (base frame, m); the tool keeps the orientation it has.
    pub above: [f64; 3],
    /// The direction the tool approaches and presses in (base frame; normalised).
    pub direction: [f64; 3],
    /// How far beyond `above` to search for the surface (m).
    pub search: f64,
    /// The approach speed (m/s).
    pub speed: f64,
    /// Contact is the force along the direction exceeding this (N).
    pub detect: f64,
    /// A force along the direction above this ends the task and retreats (N).
    pub ceiling: f64,
    /// How far to lift off at the end (m).
    pub retreat: f64,
    /// Phase stopping: the primitive's phase runs at `1/(1 + gain·|F_d − F|)` (1/N).
    pub error_gain: f64,
    /// The impedance.
    pub gains: CartesianGains,
    /// The force loop's gains along the direction (kp, ki in 1/s, damping in N s/m).
    pub force_gains: (f64, f64, f64),
    /// Contact sensing.
    pub sensing: SensingOptions,
    /// The profile.
    pub primitive: ForcePrimitive,
}

impl ContactPlan {
    /// Checks the plan's numbers; the sentence names the setting.
    pub fn check(&self) -> Result<(), InputError> {
        let within = |what: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(InputError(format!(
                    "{what}: {v} is out of range: it must lie in [{lo}, {hi}]"
                )))
            }
        };
        within("search (m)", self.search, 0.005, 0.5)?;
        within("speed (m/s)", self.speed, 0.001, 0.1)?;
        within("detect (N)", self.detect, 0.5, 50.0)?;
        within("ceiling (N)", self.ceiling, self.detect, 150.0)?;
        within("retreat (m)", self.retreat, 0.0, 0.3)?;
        within("error_gain (1/N)", self.error_gain, 0.0, 10.0)?;
        let (kp, ki, d) = self.force_gains;
        within("force gain kp", kp, 0.0, 2.0)?;
        within("force gain ki (1/s)", ki, 0.0, 50.0)?;
        within("force damping (N s/m)", d, 0.0, 200.0)?;
        let n = Vector3::from(self.direction);
        if !(n.norm().is_finite() && n.norm() > 1e-6) {
            return Err(InputError("direction: give a non-zero direction".into()));
        }
        if self.above.iter().any(|v| !v.is_finite() || v.abs() > 1.5) {
            return Err(InputError(
                "above: three finite coordinates within 1.5 m of the base".into(),
            ));
        }
        let peak = self.primitive.peak_force();
        if peak >= self.ceiling {
            return Err(InputError(format!(
                "the profile presses up to {peak:.1} N, at or above the ceiling of {} N",
                self.ceiling
            )));
        }
        Ok(())
    }
}

impl ForcePrimitive {
    /// The largest force of the profile's rollout (N).
    pub fn peak_force(&self) -> f64 {
        let traj = self.dmp.rollout(&self.weights);
        traj.position(3).iter().copied().fold(0.0, f64::max)
    }
}

/// Stages of the contact task, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stage {
    /// Holding still while the observer's bias is taken.
    Tare = 0,
    /// Moving above the surface.
    ToAbove = 1,
    /// Settling there.
    Settle = 2,
    /// Descending until contact.
    Search = 3,
    /// Following the primitive in contact.
    Press = 4,
    /// Letting the force go.
    Release = 5,
    /// Lifting off (or retreating).
    Lift = 6,
    /// At rest: the last command.
    Done = 7,
}

impl Stage {
    /// The stage's name.
    pub fn name(self) -> &'static str {
        [
            "tare", "to_above", "settle", "search", "press", "release", "lift", "done",
        ][self as usize]
    }
}

/// One tick of the contact task.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactTick {
    /// Time since the motion started (s).
    pub t: f64,
    /// The robot state's message id.
    pub id: u64,
    /// The stage.
    pub stage: Stage,
    /// The impedance's target position (m).
    pub target: [f64; 3],
    /// The tool's position by the model (m).
    pub tool: [f64; 3],
    /// The force the world exerts on the tool, estimated (N, base frame).
    pub force: [f64; 3],
    /// The robot's own estimate of the external force at its end effector (`O_F_ext_hat_K`,
    /// N, base frame): beside cps's on a real Franka (franky-sim reports zeros).
    pub robot_force: [f64; 3],
    /// The force the tool exerts along the pressing direction, estimated (N).
    pub pressing: f64,
    /// The force asked for along the direction (N; 0 without force control).
    pub desired: f64,
    /// The primitive's phase (1 before contact, falling to ~0).
    pub phase: f64,
}

/// How the contact task ended.
#[derive(Debug, Clone, PartialEq)]
pub enum ContactEnding {
    /// The profile ran through and the tool lifted off.
    Done,
    /// No surface within the search distance: the tool went back up without pressing.
    NoContact {
        /// How far it searched (m).
        searched: f64,
    },
    /// The force exceeded the ceiling: dropped and retreated.
    Ceiling {
        /// The force (N).
        force: f64,
        /// When (s).
        t: f64,
    },
    /// The motion ended otherwise (the loop's ending says how).
    Interrupted,
}

impl ContactEnding {
    /// The ending as a sentence.
    pub fn sentence(&self) -> String {
        match self {
            ContactEnding::Done => "pressed along the profile and lifted off".into(),
            ContactEnding::NoContact { searched } => format!(
                "no contact within the approach distance ({:.0} mm searched): went back up without pressing",
                searched * 1e3
            ),
            ContactEnding::Ceiling { force, t } => format!(
                "the force reached {force:.1} N at t = {t:.3} s, above the ceiling: dropped it and retreated"
            ),
            ContactEnding::Interrupted => "the motion was interrupted".into(),
        }
    }
}

/// What the contact task did.
#[derive(Debug, Clone)]
pub struct ContactOutcome {
    /// The loop's report (every sample, the timing, how the motion ended).
    pub report: MotionReport,
    /// The task's own record, one per tick.
    pub ticks: Vec<ContactTick>,
    /// How the task ended.
    pub ending: ContactEnding,
    /// Where and when contact was sensed.
    pub contact: Option<(f64, [f64; 3])>,
}

impl ContactOutcome {
    /// Over the pressing stage: RMS of (estimated − desired force) (N), the largest
    /// estimated force (N), and the RMS of the tool's distance from its target across the
    /// pressing direction (m).
    pub fn measures(&self, direction: [f64; 3]) -> (f64, f64, f64) {
        let n = Vector3::from(direction).normalize();
        let pressing: Vec<&ContactTick> = self
            .ticks
            .iter()
            .filter(|k| k.stage == Stage::Press)
            .collect();
        let count = pressing.len().max(1) as f64;
        let force_rms = (pressing
            .iter()
            .map(|k| (k.pressing - k.desired).powi(2))
            .sum::<f64>()
            / count)
            .sqrt();
        let peak = self.ticks.iter().map(|k| k.pressing).fold(0.0, f64::max);
        let path_rms = (pressing
            .iter()
            .map(|k| {
                let e = Vector3::from(k.tool) - Vector3::from(k.target);
                (e - n * e.dot(&n)).norm_squared()
            })
            .sum::<f64>()
            / count)
            .sqrt();
        (force_rms, peak, path_rms)
    }
}

fn min_jerk(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
}

/// Seconds held still for the observer's bias, and to settle above the surface.
const TARE: f64 = 0.3;
const SETTLE: f64 = 0.3;
/// Seconds to let the force go and to lift off.
const RELEASE: f64 = 0.3;
const LIFT: f64 = 1.0;

/// Runs the contact task `plan` on the robot behind `conn` whose dynamic model is `model`
/// (from [`cps_franka::control::robot_dynamics`]). Refuses a plan out of range before
/// anything moves.
pub fn run_contact(
    conn: &mut Connection,
    model: &ArmModel<7>,
    limits: RateLimits,
    options: &LoopOptions,
    plan: &ContactPlan,
    stop: &AtomicBool,
) -> Result<ContactOutcome, DriveError> {
    plan.check()?;
    let (state, _) = conn.newest_state(std::time::Duration::from_secs(1))?;
    let start = model.frames(&state.q).tool;
    let n = Vector3::from(plan.direction).normalize();
    let above = Vector3::from(plan.above);
    let to_above = ((above - start.translation.vector).norm() / 0.05).max(1.0);
    let mut law =
        CartesianImpedance::new(plan.gains, state.q).map_err(|e| InputError(e.to_string()))?;
    let mut sensing = Sensing::new(plan.sensing).map_err(|e| InputError(e.to_string()))?;
    let tau = plan.primitive.duration();
    let nominal = TARE + to_above + SETTLE + plan.search / plan.speed + tau + RELEASE + LIFT + 1.0;
    // Phase stopping may stretch the profile up to three times.
    let capacity = ((nominal + 2.0 * tau) * 1000.0) as usize + cps_franka::rt::BRAKE_RESERVE;
    let options = LoopOptions {
        max_ticks: capacity,
        ..*options
    };
    let mut stages = Stages {
        plan,
        n,
        above,
        to_above,
        tau,
        end_phase: (-plan.primitive.dmp.config().alpha_x).exp(),
        force_template: ForceAlong {
            direction: plan.direction,
            force: 0.0,
            kp: plan.force_gains.0,
            ki: plan.force_gains.1,
            damping: plan.force_gains.2,
        },
        online: OnlineDmp::new(&plan.primitive.dmp, &plan.primitive.weights)
            .with_error_gain(plan.error_gain),
        stage: Stage::Tare,
        since_t: 0.0,
        anchor: start.translation.vector,
        contact: None,
        ending: ContactEnding::Interrupted,
        last_force: 0.0,
        cancel: [0.0; 4],
    };
    let mut ticks: Vec<ContactTick> = Vec::with_capacity(capacity);
    let mut last_t = 0.0;
    // The target's velocity, fed forward so the damping does not drag against the path.
    let mut last_target: Option<Vector3<f64>> = None;
    let report = cps_franka::run_torques(conn, limits, &options, stop, |state, t| {
        let frames = model.frames(&state.q);
        let estimate = sensing.update(model, &frames, state, t);
        let dt = t - last_t;
        last_t = t;
        let tool = frames.tool.translation.vector;
        let pressing = -estimate.fixed_rows::<3>(0).dot(&n);
        let (target, force, switching) = stages.step(t, dt, tool, pressing);
        let mut velocity = Vector6::zeros();
        if let Some(last) = last_target
            && dt > 0.0
            && !switching
        {
            // A jump of the target (a stage's new anchor) is not a velocity.
            let v = (target - last) / dt;
            if v.norm() < 0.5 {
                velocity.fixed_rows_mut::<3>(0).copy_from(&v);
            }
        }
        last_target = Some(target);
        let pose = Isometry3::from_parts(Translation3::from(target), start.rotation);
        let tau_c = law.torques(
            model,
            &frames,
            state,
            &pose,
            &velocity,
            force.as_ref(),
            &estimate,
            dt,
        );
        let stage = stages.stage;
        if ticks.len() < ticks.capacity() {
            ticks.push(ContactTick {
                t,
                id: state.message_id,
                stage,
                target: target.into(),
                tool: tool.into(),
                force: [estimate[0], estimate[1], estimate[2]],
                robot_force: [
                    state.o_f_ext_hat_k[0],
                    state.o_f_ext_hat_k[1],
                    state.o_f_ext_hat_k[2],
                ],
                pressing,
                desired: force.map_or(0.0, |f| f.force),
                phase: if stage >= Stage::Press {
                    stages.online.phase()
                } else {
                    1.0
                },
            });
        }
        Torques {
            tau: tau_c,
            finished: stage == Stage::Done,
        }
    })?;
    let ending = if report.ending.complete() {
        stages.ending
    } else {
        ContactEnding::Interrupted
    };
    Ok(ContactOutcome {
        report,
        ticks,
        ending,
        contact: stages.contact,
    })
}

/// The contact task's stages as they go, tick by tick in the realtime loop (nothing here
/// allocates): where the tool is sent and with what force, and how the task ended.
struct Stages<'a> {
    plan: &'a ContactPlan,
    /// The approach's direction (unit) and the point above the surface.
    n: Vector3<f64>,
    above: Vector3<f64>,
    /// The move above's and the force profile's durations (s).
    to_above: f64,
    tau: f64,
    /// The profile's phase at its end.
    end_phase: f64,
    force_template: ForceAlong,
    online: OnlineDmp,
    stage: Stage,
    /// When the stage began and where (its anchor).
    since_t: f64,
    anchor: Vector3<f64>,
    contact: Option<(f64, [f64; 3])>,
    ending: ContactEnding,
    last_force: f64,
    cancel: [f64; 4],
}

impl Stages<'_> {
    /// The target at `t` (the tool at `tool`, pressing with `pressing` N along the
    /// approach), the force to press with, and whether the stage changed this tick (a
    /// new anchor: the target's jump is no velocity).
    fn step(
        &mut self,
        t: f64,
        dt: f64,
        tool: Vector3<f64>,
        pressing: f64,
    ) -> (Vector3<f64>, Option<ForceAlong>, bool) {
        let plan = self.plan;
        let (n, anchor) = (self.n, self.anchor);
        let since = t - self.since_t;
        let mut next: Option<(Stage, Vector3<f64>)> = None;
        if pressing > plan.ceiling && self.stage < Stage::Lift {
            self.ending = ContactEnding::Ceiling { force: pressing, t };
            next = Some((Stage::Lift, tool));
        }
        let mut force = None;
        let target = match self.stage {
            Stage::Tare => {
                if since > TARE {
                    next.get_or_insert((Stage::ToAbove, anchor));
                }
                anchor
            }
            Stage::ToAbove => {
                let p = anchor + (self.above - anchor) * min_jerk(since / self.to_above);
                if since > self.to_above {
                    next.get_or_insert((Stage::Settle, self.above));
                }
                p
            }
            Stage::Settle => {
                if since > SETTLE {
                    next.get_or_insert((Stage::Search, self.above));
                }
                anchor
            }
            Stage::Search => {
                let travelled = plan.speed * since;
                if pressing > plan.detect {
                    self.contact = Some((t, tool.into()));
                    next.get_or_insert((Stage::Press, tool));
                } else if travelled > plan.search {
                    self.ending = ContactEnding::NoContact {
                        searched: travelled,
                    };
                    next.get_or_insert((Stage::Lift, tool));
                }
                anchor + n * travelled
            }
            Stage::Press => {
                let (p, f, done) = self.press(since, dt, pressing);
                force = Some(f);
                if done {
                    self.ending = ContactEnding::Done;
                    next.get_or_insert((Stage::Release, tool));
                }
                anchor + p
            }
            Stage::Release => {
                force = Some(ForceAlong {
                    force: self.last_force * (1.0 - min_jerk(since / RELEASE)),
                    ..self.force_template
                });
                if since > RELEASE {
                    next.get_or_insert((Stage::Lift, anchor));
                }
                anchor
            }
            Stage::Lift | Stage::Done => {
                if self.stage == Stage::Lift && since > LIFT + 0.3 {
                    next.get_or_insert((Stage::Done, anchor - n * plan.retreat));
                }
                anchor - n * (plan.retreat * min_jerk(since / LIFT))
            }
        };
        let switching = next.is_some();
        if let Some((s, a)) = next {
            // A jump to Lift from anywhere drops the force at once.
            (self.stage, self.since_t, self.anchor) = (s, t, a);
        }
        (target, force, switching)
    }

    /// One step of the force profile (`since` the press began): the offset from the
    /// contact point, the force, and whether the profile is over.
    fn press(&mut self, since: f64, dt: f64, pressing: f64) -> (Vector3<f64>, ForceAlong, bool) {
        let over = self.online.phase() <= self.end_phase;
        if over {
            for (c, f) in self.cancel.iter_mut().zip(self.online.forcing()) {
                *c = -f;
            }
        }
        let err = (self.last_force - pressing).abs();
        let input = StepInput {
            coupling: over.then_some(&self.cancel[..]),
            tracking_error: if over { 0.0 } else { err },
        };
        let _ = self.online.step_with(dt.max(1e-4), input);
        let y = self.online.position();
        // The force builds up over the first 0.2 s whatever the profile's start.
        self.last_force =
            y[3].max(0.0) * min_jerk(since / 0.2).max(if since > 0.2 { 1.0 } else { 0.0 });
        let force = ForceAlong {
            force: self.last_force,
            ..self.force_template
        };
        (
            Vector3::new(y[0], y[1], y[2]),
            force,
            over && self.online.time() > self.tau,
        )
    }
}

/// Where and how to reach the robot.
#[derive(Debug, Clone)]
pub struct RobotAt {
    /// Its address.
    pub host: String,
    /// Which arm's limits.
    pub arm: cps_franka::limits::Arm,
    /// Realtime scheduling of the loop.
    pub realtime: cps_franka::Realtime,
    /// Where its joint torques are measured: [`Drive::Rigid`] after the gears (a Franka's
    /// sensors), [`Drive::FrankySim`] before franky-sim's rotor inertia and friction.
    pub drive: Drive,
    /// The world its free motions are checked in, in the robot's base frame: the arm with
    /// its hand among obstacles, the table it presses among the contacts allowed (None:
    /// the arm and hand alone).
    pub world: Option<std::sync::Arc<cps_robot::Shapes>>,
}

/// Connects, checks the robot is ready, and reads its dynamic model (with `robot.drive`
/// applied to the model and to `sensing`).
fn connect_with_model(
    robot: &RobotAt,
    sensing: &mut SensingOptions,
) -> Result<(Connection, ArmModel<7>), DriveError> {
    let mut conn = Connection::connect(&robot.host, Default::default())?;
    let model = dynamics(&mut conn, robot, sensing)?;
    Ok((conn, model))
}

/// The robot's dynamic model read over `conn` (with `robot.drive` applied to the model and
/// to `sensing`), once it is ready.
fn dynamics(
    conn: &mut Connection,
    robot: &RobotAt,
    sensing: &mut SensingOptions,
) -> Result<ArmModel<7>, DriveError> {
    let (state, _) = conn.newest_state(std::time::Duration::from_secs(1))?;
    conn.ensure_ready(&state)?;
    let model = cps_franka::control::robot_dynamics(conn, &state)?;
    let (model, friction) = robot
        .drive
        .apply(model)
        .map_err(|e| DriveError::during("the drive's model", e))?;
    sensing.friction = friction;
    Ok(model)
}

/// [`run_contact`] on the robot `robot`: connects; moves the tool to the approach's start
/// above the surface (`plan.above`, keeping its orientation) as a free motion in joint
/// space — a plan through cps's guard ([`cps_robot::Guarded`]: checked, approached at
/// [`cps_robot::APPROACH_SHARE`] of the limits, braked by `stop`); then reads the robot's
/// model and runs `plan` in torque mode from there.
pub fn contact_on_robot(
    robot: &RobotAt,
    plan: &ContactPlan,
    stop: &StopToken,
) -> Result<ContactOutcome, DriveError> {
    plan.check()?;
    let mut plan = plan.clone();
    let mut model = cps_movement::robot_file::load_robot(robot.arm.name(), Some("hand"), None)?;
    if let Some(world) = &robot.world {
        model.shapes = Some(world.clone());
    }
    let settings = FrankaSettings {
        host: robot.host.clone(),
        arm: robot.arm,
        realtime: robot.realtime,
        dt: 0.01,
    };
    let mut franka = Guarded::new(FrankaRobot::connect(&settings, model)?, Policy::EXPERIMENT)
        .going_around(cps_plan::around);
    let free =
        |e: cps_robot::RobotError| DriveError::during("the free motion above the surface", e);
    let q = franka.joint_positions().map_err(free)?;
    let chain = &franka.model().chain;
    let tool = chain.fk(&q)?;
    let target = IkTarget::Pose(IsometryMatrix3::from_parts(
        Translation3::from(Vector3::from(plan.above)),
        tool.rotation,
    ));
    let above = solve_ik(chain, &target, &q, &IkConfig::default()).map_err(|e| {
        InputError(format!(
            "[contact] `above` ({:.3}, {:.3}, {:.3}) m: the tool cannot be put there with its present orientation: {e}",
            plan.above[0], plan.above[1], plan.above[2]
        ))
    })?;
    franka.move_to(&above.q, stop).map_err(free)?;
    // The free motions are the guard's; the torque loop is no plan: it runs on the
    // connection, each torque checked by cps-franka's 1 kHz loop (rates, the robot's
    // torque limits, the force ceiling), so the guard is let go here.
    let mut franka = franka.into_inner();
    let conn = franka.connection();
    let model = dynamics(conn, robot, &mut plan.sensing)?;
    let options = LoopOptions {
        realtime: robot.realtime,
        ..Default::default()
    };
    let limits = RateLimits::of(robot.arm);
    let _moving = stop.moving();
    run_contact(conn, &model, limits, &options, &plan, stop.flag())
}

/// What [`follow_with_impedance`] recorded.
#[derive(Debug, Clone)]
pub struct Followed {
    /// The loop's report (every sample).
    pub report: MotionReport,
    /// Per sample: the target position (m).
    pub target: Vec<[f64; 3]>,
    /// Per sample: the tool's position by the model (m).
    pub tool: Vec<[f64; 3]>,
    /// Per sample: the estimated wrench the world exerts on the tool (N, N m).
    pub wrench: Vec<[f64; 6]>,
}

/// Follows tool positions `positions` at `times` (s, increasing from 0; the orientation
/// the tool has is held) with a Cartesian impedance of `gains` in torque mode, from where
/// the tool stands (the first position must be within 5 cm of it), and records the
/// estimated external wrench. Between the samples the target moves on a straight line;
/// after the last it is held for 0.5 s.
pub fn follow_with_impedance(
    robot: &RobotAt,
    times: &[f64],
    positions: &[[f64; 3]],
    gains: CartesianGains,
    stop: &AtomicBool,
) -> Result<Followed, DriveError> {
    if times.len() != positions.len() || times.len() < 2 {
        return Err(InputError(format!(
            "impedance: {} times for {} positions; give at least two of each, as many",
            times.len(),
            positions.len()
        ))
        .into());
    }
    if let Some(i) = (0..times.len()).find(|&i| {
        !times[i].is_finite()
            || positions[i].iter().any(|v| !v.is_finite() || v.abs() > 1.5)
            || (i == 0 && times[0] != 0.0)
            || (i > 0 && times[i] <= times[i - 1])
    }) {
        return Err(InputError(format!(
            "impedance: sample {i}: times must start at 0 and increase, positions be finite and within 1.5 m of the base"
        ))
        .into());
    }
    let end = times[times.len() - 1];
    if end > 600.0 {
        return Err(InputError(format!("impedance: {end} s long; at most 600 s")).into());
    }
    let mut sensing = SensingOptions::default();
    let (mut conn, model) = connect_with_model(robot, &mut sensing)?;
    let (state, _) = conn.newest_state(std::time::Duration::from_secs(1))?;
    let start = model.frames(&state.q).tool;
    let gap = (Vector3::from(positions[0]) - start.translation.vector).norm();
    if gap > 0.05 {
        return Err(InputError(format!(
            "impedance: the first position is {:.1} mm from the tool (at most 50 mm): move there first",
            gap * 1e3
        ))
        .into());
    }
    let mut law = CartesianImpedance::new(gains, state.q).map_err(|e| InputError(e.to_string()))?;
    let mut sens = Sensing::new(sensing).map_err(|e| InputError(e.to_string()))?;
    let ticks = ((end + 0.5) * 1000.0) as usize + cps_franka::rt::BRAKE_RESERVE + 10;
    let options = LoopOptions {
        realtime: robot.realtime,
        max_ticks: ticks,
        ..Default::default()
    };
    let (mut target_log, mut tool_log, mut wrench_log) = (
        Vec::with_capacity(ticks),
        Vec::with_capacity(ticks),
        Vec::with_capacity(ticks),
    );
    let mut seg = 0;
    let mut last_t = 0.0;
    let report = cps_franka::run_torques(
        &mut conn,
        RateLimits::of(robot.arm),
        &options,
        stop,
        |s, t| {
            let frames = model.frames(&s.q);
            let w = sens.update(&model, &frames, s, t);
            let dt = t - last_t;
            last_t = t;
            let tt = t.min(end);
            while seg + 2 < times.len() && tt > times[seg + 1] {
                seg += 1;
            }
            let share = ((tt - times[seg]) / (times[seg + 1] - times[seg])).clamp(0.0, 1.0);
            let (a, b) = (
                Vector3::from(positions[seg]),
                Vector3::from(positions[seg + 1]),
            );
            let p = a + (b - a) * share;
            // The segment's velocity fed forward while the target moves along it.
            let mut v = Vector6::zeros();
            if t < end {
                v.fixed_rows_mut::<3>(0)
                    .copy_from(&((b - a) / (times[seg + 1] - times[seg])));
            }
            let pose = Isometry3::from_parts(Translation3::from(p), start.rotation);
            let tau = law.torques(&model, &frames, s, &pose, &v, None, &w, dt);
            if target_log.len() < target_log.capacity() {
                target_log.push(p.into());
                tool_log.push(frames.tool.translation.vector.into());
                wrench_log.push([w[0], w[1], w[2], w[3], w[4], w[5]]);
            }
            Torques {
                tau,
                finished: t >= end + 0.5,
            }
        },
    )?;
    Ok(Followed {
        report,
        target: target_log,
        tool: tool_log,
        wrench: wrench_log,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn press_profile() -> Vec<ContactWaypoint> {
        let w = |t: f64, x: f64, force: f64| ContactWaypoint {
            t,
            offset: [x, 0.0, 0.0],
            force,
        };
        vec![
            w(0.0, 0.0, 0.0),
            w(1.0, 0.0, 10.0),
            w(5.0, 0.2, 10.0),
            w(6.0, 0.2, 0.0),
        ]
    }

    #[test]
    fn a_primitive_from_way_points_passes_through_them() {
        let p = ForcePrimitive::from_waypoints(&press_profile()).unwrap();
        assert!((p.duration() - 6.0).abs() < 1e-12);
        let traj = p.dmp.rollout(&p.weights);
        let at = |t: f64| (t / p.dmp.config().dt).round() as usize;
        // The force holds 10 N between 1 s and 5 s and is 0 at both ends; x slides 0.2 m.
        for t in [1.0, 3.0, 5.0] {
            assert!(
                (traj.position(3)[at(t)] - 10.0).abs() < 0.05,
                "{t}: {}",
                traj.position(3)[at(t)]
            );
        }
        assert!(traj.position(3)[0].abs() < 1e-9 && traj.position(3)[at(6.0)].abs() < 0.05);
        assert!((traj.position(0)[at(5.0)] - 0.2).abs() < 1e-3);
        assert!((p.peak_force() - 10.0).abs() < 0.1);
    }

    #[test]
    fn bad_way_points_and_plans_are_named() {
        let mut w = press_profile();
        w[2].force = 500.0;
        let e = ForcePrimitive::from_waypoints(&w).unwrap_err();
        assert_eq!(
            e.to_string(),
            "waypoints[2]: force 500 N is out of range: it must lie in [0, 100]"
        );
        let mut w = press_profile();
        w[3].t = 4.0;
        assert!(
            ForcePrimitive::from_waypoints(&w)
                .unwrap_err()
                .to_string()
                .contains("waypoints[3]: t = 4 s: times must increase")
        );
        let plan = ContactPlan {
            above: [0.45, 0.0, 0.47],
            direction: [0.0, 0.0, -1.0],
            search: 0.15,
            speed: 0.03,
            detect: 3.0,
            ceiling: 8.0,
            retreat: 0.05,
            error_gain: 0.2,
            gains: CartesianGains::default(),
            force_gains: (0.2, 5.0, 30.0),
            sensing: SensingOptions::default(),
            primitive: ForcePrimitive::from_waypoints(&press_profile()).unwrap(),
        };
        assert!(
            plan.check()
                .unwrap_err()
                .0
                .contains("at or above the ceiling of 8 N")
        );
        let plan = ContactPlan {
            ceiling: 30.0,
            speed: 2.0,
            ..plan
        };
        assert_eq!(
            plan.check().unwrap_err().0,
            "speed (m/s): 2 is out of range: it must lie in [0.001, 0.1]"
        );
    }
}
