//! A Franka from files: one state (`cps-cli franka state`), a joint trajectory file
//! executed at 1 kHz and recorded (`franka execute`), the robot's state recorded for a
//! while (`franka record`), or floating while a person guides it (`franka guide`). The protocol, the loop and the limit checks are `cps-franka`'s;
//! this module reads and writes the files and words the answers.
//!
//! A recording is a CSV `t,q1..q7,dq1..dq7,tau1..tau7,q_d1..q_d7,tool_x,tool_y,tool_z` at the
//! robot's rate (measured positions, velocities and torques, the commanded positions, the
//! tool's position from the robot's own kinematics), with a report beside it
//! (`<stem>.report.json`) that says whether it is complete and why not.

use std::path::Path;
use std::sync::Arc;

use cps_franka::limits::{Arm, DT, RateLimits};
use cps_franka::{
    Connection, FrankaRobot, FrankaSettings, Gripper, GripperCommand, LoopOptions, MotionEnd,
    MotionReport, Realtime, RobotState, Sample, Timeouts,
};
use cps_kinematics::Quantity;
use cps_robot::{
    Guarded, Limit, OnBreach, OnStart, Plan, Policy, Refusal, Robot, RobotError, Shapes, StopToken,
};
use serde_json::{Value, json};

use cps_movement::limits::{JointTrajectory, at_rate, read_joint_trajectory};
use cps_movement::retiming::{RetimeMode, retime_samples};
use cps_movement::robot_file::load_robot;
use cps_outcome::outcome::{Column, Format, Table};
use cps_outcome::{Ended, InputError};

use crate::error::DriveError;
use crate::said::{HandAt, Recorded, StateAt, fmt7};
use crate::scene::scene_world;

use crate::recording::{check_record_target, report_path};

/// The share of each velocity, acceleration and jerk limit `--retime` plans at, so that
/// the robot's check (at 100 %) always has room.
pub const RETIME_SHARE: f64 = 0.95;

/// Which arm, by name (`fr3`, `panda`).
pub fn parse_arm(name: &str) -> Result<Arm, InputError> {
    Arm::from_name(name).ok_or_else(|| {
        InputError(format!(
            "--arm: `{name}` is not a Franka arm (fr3 or panda)"
        ))
    })
}

/// `enforce`, `ignore` or `off` ([`Realtime::WORDS`]).
pub fn parse_realtime(name: &str) -> Result<Realtime, InputError> {
    Realtime::from_word(name).ok_or_else(|| {
        InputError(format!(
            "--realtime: `{name}` is not enforce, ignore or off"
        ))
    })
}

fn connect(host: &str) -> Result<Connection, DriveError> {
    Ok(Connection::connect(host, Timeouts::default())?)
}

/// `cps-cli franka state`: one state of the robot at `host`.
pub fn state(host: &str) -> Result<StateAt, DriveError> {
    let state: RobotState = connect(host)?.read_state()?;
    Ok(StateAt {
        host: host.to_string(),
        state,
    })
}

/// What `franka execute` does.
#[derive(Debug, Clone)]
pub struct ExecuteSettings {
    /// The robot's address.
    pub host: String,
    /// Which arm's limits.
    pub arm: Arm,
    /// Retime the trajectory to the limits first (else its own timing, checked).
    pub retime: bool,
    /// Move to the trajectory's start first when the robot is elsewhere (else refuse).
    pub approach: bool,
    /// Realtime scheduling of the loop.
    pub realtime: Realtime,
    /// The world every command is checked in, in the robot's base frame ([`scene_world`]):
    /// the arm's shapes among a scene's obstacles. None: the arm and its hand alone.
    pub world: Option<Arc<Shapes>>,
}

impl ExecuteSettings {
    /// The Franka at `host` with the arm and the loop's scheduling named in words (`fr3`
    /// or `panda`; `enforce` or `ignore`), nothing retimed or approached. Errors: a word
    /// that is not one of them, in a sentence.
    pub fn parse(host: &str, arm: &str, realtime: &str) -> Result<Self, InputError> {
        Ok(ExecuteSettings {
            host: host.to_string(),
            arm: parse_arm(arm)?,
            retime: false,
            approach: false,
            realtime: parse_realtime(realtime)?,
            world: None,
        })
    }

    /// These settings with every command checked among the obstacles of the scene file at
    /// `scene` ([`scene_world`]) as well as against the arm itself; unchanged for None.
    /// Errors: the scene file's, and a scene whose robot is another arm.
    pub fn in_scene(self, scene: Option<&Path>) -> Result<Self, DriveError> {
        Ok(ExecuteSettings {
            world: scene.map(|s| scene_world(s, self.arm)).transpose()?,
            ..self
        })
    }
}

/// A joint trajectory file made ready for a Franka: 1 kHz commands from t = 0 (what
/// [`execute`] streams through the guard, which makes its own [`cps_robot::Prepared`] plan).
#[derive(Debug, Clone)]
pub struct FrankaCommands {
    /// Where the trajectory came from (its file), for messages.
    pub source: String,
    /// One command per millisecond.
    pub commands: Vec<[f64; 7]>,
    /// Whether it was retimed, resampled, or taken command by command.
    pub how: &'static str,
}

/// Reads a joint trajectory (`t`, then seven positions in rad) and makes it 1 kHz commands:
/// retimed to the arm's limits (at [`RETIME_SHARE`]), or resampled by a cubic spline that
/// starts and ends at rest, or taken as it is when it is sampled at 1 kHz.
pub fn prepare(file: &Path, arm: Arm, retime: bool) -> Result<FrankaCommands, DriveError> {
    let traj: JointTrajectory = read_joint_trajectory(file, 7)?;
    prepare_samples(&file.display().to_string(), &traj, arm, retime)
}

/// [`prepare`] for a trajectory in memory, called `name` in messages (times strictly
/// increasing and finite, seven finite positions a row).
pub fn prepare_samples(
    name: &str,
    traj: &JointTrajectory,
    arm: Arm,
    retime: bool,
) -> Result<FrankaCommands, DriveError> {
    if traj.times.is_empty() || traj.q.len() != traj.times.len() {
        return Err(InputError(format!(
            "{name}: {} times for {} rows of positions",
            traj.times.len(),
            traj.q.len()
        ))
        .into());
    }
    if let Some(k) = traj
        .times
        .windows(2)
        .position(|w| w[1] <= w[0] || !w[1].is_finite())
    {
        return Err(InputError(format!(
            "{name}: time {} follows {}: times must increase strictly",
            traj.times[k + 1],
            traj.times[k]
        ))
        .into());
    }
    if let Some((k, row)) = traj
        .q
        .iter()
        .enumerate()
        .find(|(_, r)| r.len() != 7 || r.iter().any(|x| !x.is_finite()))
    {
        return Err(InputError(format!(
            "{name}: row {k} has {} values{}; a Franka needs seven finite joint positions (rad)",
            row.len(),
            if row.iter().any(|x| !x.is_finite()) {
                " (not all finite)"
            } else {
                ""
            }
        ))
        .into());
    }
    let (rows, how) = if retime {
        let mut model = load_robot(arm.name(), Some("flange"), None)?;
        let l = RateLimits::of(arm).scaled(RETIME_SHARE);
        model.chain = model.chain.clone().with_velocity_limits(&l.dq_max)?;
        model.limits.acceleration = Some(l.ddq_max.to_vec());
        model.limits.jerk = Some(l.dddq_max.to_vec());
        let r = retime_samples(&model, traj, 1000.0, RetimeMode::Fastest).map_err(|e| {
            InputError(format!(
                "{name}: cannot be retimed for the {}: {e}",
                arm.name()
            ))
        })?;
        (r.trajectory.q, "retimed")
    } else {
        let (_, _, rows, resampled) = at_rate(traj, 1000.0)?;
        (
            rows,
            if resampled {
                "resampled at 1 kHz"
            } else {
                "taken command by command"
            },
        )
    };
    let commands = rows
        .iter()
        .map(|r| <[f64; 7]>::try_from(r.as_slice()).expect("seven joints"))
        .collect();
    Ok(FrankaCommands {
        source: name.to_string(),
        commands,
        how,
    })
}

/// An execution: what was sent, what the robot did.
#[derive(Debug, Clone)]
pub struct Executed {
    /// The robot's address.
    pub host: String,
    /// The arm.
    pub arm: Arm,
    /// The loop's report (every tick, the approach's included).
    pub report: MotionReport,
    /// Robot periods before the trajectory's start (an approach, a blend into it), on the
    /// stream's clock: the trajectory's first sample is
    /// `report.sample_at_clock(approach as f64 * 1e-3)`.
    pub approach: usize,
    /// How the file was made commands.
    pub how: &'static str,
}

/// The arm's own model (its flange, its base frame as the world) with its limits, and its
/// shapes with the Franka Hand's (the hand franky-sim and most arms carry; an arm without
/// one is only checked more carefully): what a trajectory file for it is checked against.
pub(crate) fn arm_model(arm: Arm) -> Result<cps_robot::RobotModel, DriveError> {
    let mut model = load_robot(arm.name(), Some("flange"), None)?;
    let with_hand = load_robot(arm.name(), Some("hand"), None)?;
    model.shapes = with_hand.shapes;
    Ok(model)
}

/// `model` checked among `world` where one is given.
pub(crate) fn in_world(
    mut model: cps_robot::RobotModel,
    world: Option<&Arc<Shapes>>,
) -> cps_robot::RobotModel {
    if let Some(w) = world {
        model.shapes = Some(w.clone());
    }
    model
}

/// Connects to the Franka of `settings`, behind the guard with `policy`.
pub(crate) fn guarded_arm(
    settings: &ExecuteSettings,
    policy: Policy,
) -> Result<Guarded<FrankaRobot>, DriveError> {
    let robot = FrankaRobot::connect(
        &FrankaSettings {
            host: settings.host.clone(),
            arm: settings.arm,
            realtime: settings.realtime,
            dt: DT,
        },
        in_world(arm_model(settings.arm)?, settings.world.as_ref()),
    )?;
    // `--approach` goes around the arm's shapes and its scene's where straight would not.
    Ok(Guarded::new(robot, policy).going_around(cps_plan::around))
}

/// A refusal of the guard in the words of `franka execute` (`source` names the file):
/// what to pass to get past it.
fn refusal(source: &str, arm: Arm, e: RobotError) -> DriveError {
    let sentence = match &e {
        RobotError::Refused { reason, .. } => match reason {
            Refusal::Start { .. } => format!(
                "{source}: refused before sending anything: {reason}; pass --approach to move there first"
            ),
            Refusal::Limit(b)
                if matches!(
                    b.limit,
                    Limit::Joint {
                        quantity: Quantity::Position,
                        ..
                    }
                ) =>
            {
                format!(
                    "{source}: refused before sending anything: {b}: the trajectory leaves the {}'s joint range (was it planned for another arm? --arm fr3|panda)",
                    arm.name()
                )
            }
            // No timing helps: the path itself comes too close (to the arm, or to the
            // scene's obstacles with --scene).
            Refusal::Collision(_) => format!("{source}: refused before sending anything: {reason}"),
            _ => format!(
                "{source}: refused before sending anything: {reason} (pass --retime to retime it to the {}'s limits)",
                arm.name()
            ),
        },
        _ => return DriveError::during(source, e),
    };
    DriveError::Refused {
        sentence,
        source: Box::new(e),
    }
}

/// Connects, checks the prepared commands from where the robot is (an approach first when
/// asked) through the guard every robot runs behind, executes them and returns the
/// recording. A check that fails returns an error and nothing is sent; once the motion
/// started, every ending is an [`Executed`].
pub fn execute(
    prepared: &FrankaCommands,
    settings: &ExecuteSettings,
    stop: &StopToken,
) -> Result<Executed, DriveError> {
    let mut robot = guarded_arm(
        settings,
        Policy {
            on_breach: OnBreach::Refuse,
            on_start: if settings.approach {
                OnStart::Approach
            } else {
                OnStart::Refuse
            },
        },
    )?;
    let plan = Plan::new(DT, prepared.commands.iter().map(|q| q.to_vec()).collect())
        .map_err(|e| InputError(format!("{}: {e}", prepared.source)))?;
    let run = robot
        .run(&plan, stop)
        .map_err(|e| refusal(&prepared.source, settings.arm, e))?;
    let franka = robot.inner();
    let report = franka
        .reports()
        .last()
        .cloned()
        .ok_or_else(|| DriveError::Failed("the robot sent no report".into()))?;
    let blend = franka.last_stream().map_or(0, |s| s.approach);
    Ok(Executed {
        host: settings.host.clone(),
        arm: settings.arm,
        report,
        approach: blend + (run.approach_s / DT).round() as usize,
        how: prepared.how,
    })
}

/// How `franka execute-dmp` steps a model online.
#[derive(Debug, Clone, PartialEq)]
pub struct DmpSettings {
    /// Phase stopping gain (1/rad): the phase runs at `1/(1 + gain · e)` with `e` the
    /// distance between the measured joints and the last command (Ijspeert et al. 2013).
    pub error_gain: f64,
    /// The movement's duration τ (s; default the model's).
    pub tau: Option<f64>,
    /// The goal (rad; default the model's).
    pub goal: Option<Vec<f64>>,
}

/// Whether a DMP stepped online has ended: its phase is over and every joint moves
/// slower than 0.1 mrad/s (holding the last command then keeps every limit).
fn settled(q: &[f64; 7], prev: &[f64; 7], phase_over: bool) -> bool {
    phase_over && q.iter().zip(prev).all(|(a, b)| (a - b).abs() < 1e-4 * 1e-3)
}

/// Default phase-stopping gain (1/rad): 10 mrad of lag slows the phase by 9 %.
pub const DEFAULT_ERROR_GAIN: f64 = 10.0;

/// `franka execute-dmp`: a joint-space DMP model (seven dimensions, as `imitate` writes
/// from a joint recording) started where the robot is and stepped online at the robot's
/// rate with phase stopping: when the robot lags its commands (a push, a contact) the
/// phase slows, and it resumes when the lag shrinks. Its nominal movement (no lag) is
/// checked against the arm's limits before anything is sent; every command is checked
/// again while streaming.
pub fn execute_model(
    model: &Path,
    settings: &ExecuteSettings,
    online: &DmpSettings,
    stop: &StopToken,
) -> Result<Executed, DriveError> {
    use cps_dmp::{OnlineDmp, StepInput};
    let (file, dmp, weights) = cps_movement::movement::read_model(model)?;
    if dmp.dims() != 7 {
        return Err(InputError(format!(
            "{}: a {}-dimensional model; the robot steps joint-space models of seven dimensions (imitate a joint recording: cps-cli imitate rec.csv --columns q1,q2,q3,q4,q5,q6,q7)",
            model.display(),
            dmp.dims()
        ))
        .into());
    }
    if !(online.error_gain.is_finite() && online.error_gain >= 0.0) {
        return Err(InputError(format!(
            "--error-gain: {} must be finite and >= 0",
            online.error_gain
        ))
        .into());
    }
    let goal = online.goal.clone().unwrap_or_else(|| file.goal.clone());
    if goal.len() != 7 || goal.iter().any(|g| !g.is_finite()) {
        return Err(InputError("--goal: seven finite joint positions (rad)".into()).into());
    }
    let mut robot = guarded_arm(settings, Policy::STRICT)?;
    let here = robot.joint_positions()?;
    let from = <[f64; 7]>::try_from(here.as_slice()).expect("seven joints");
    let dmp = dmp
        .with_endpoints(&from, &goal)
        .map_err(|e| InputError(format!("{}: {e}", model.display())))?;
    let tau = online.tau.unwrap_or(dmp.config().tau);
    let fresh = || -> Result<OnlineDmp, DriveError> {
        let mut o = OnlineDmp::new(&dmp, &weights).with_error_gain(online.error_gain);
        o.set_tau(tau)
            .map_err(|e| InputError(format!("--tau: {e}")))?;
        Ok(o)
    };
    // The nominal movement at 1 kHz (no lag), checked whole by the guard before anything
    // is sent.
    let end_phase = (-dmp.config().alpha_x).exp();
    let mut nominal = fresh()?;
    // The robot holds `from` while the Move starts: the stream starts there, at rest.
    let mut commands = Vec::with_capacity((tau * 1000.0) as usize + 2);
    commands.push(from.to_vec());
    let mut prev = from;
    let mut cancel = [0.0; 7];
    loop {
        let over = nominal.phase() <= end_phase;
        if over {
            for (c, f) in cancel.iter_mut().zip(nominal.forcing()) {
                *c = -f;
            }
        }
        let input = StepInput {
            coupling: over.then_some(&cancel[..]),
            tracking_error: 0.0,
        };
        nominal.step_with(1e-3, input)?;
        let q = <[f64; 7]>::try_from(nominal.position()).expect("seven joints");
        commands.push(q.to_vec());
        if settled(&q, &prev, over) || commands.len() > (10.0 * tau * 1000.0) as usize {
            break;
        }
        prev = q;
    }
    let name = model.display().to_string();
    let nominal_plan = Plan::new(DT, commands)?;
    // Online: one step per tick, the phase slowed by the measured lag. Phase stopping may
    // stretch the movement: room for four times its nominal length (then the robot is
    // braked).
    let mut runner = fresh()?;
    let mut last = from;
    let mut cancel = [0.0; 7];
    let max = 4 * nominal_plan.points().len() + 10_000;
    let mut next = |measured: &cps_robot::Measured<'_>, _t: f64, out: &mut [f64]| -> bool {
        let lag = (0..7)
            .map(|j| (measured.q[j] - last[j]).powi(2))
            .sum::<f64>()
            .sqrt();
        // Once the phase is over the shape is switched off and the spring settles the
        // movement at the goal (a forcing left at the tail of a fit would drift).
        let over = runner.phase() <= end_phase;
        if over {
            for (c, f) in cancel.iter_mut().zip(runner.forcing()) {
                *c = -f;
            }
        }
        let input = StepInput {
            coupling: over.then_some(&cancel[..]),
            tracking_error: if over { 0.0 } else { lag },
        };
        let stepped = runner.step_with(1e-3, input);
        let mut q = last;
        if stepped.is_ok() {
            q.copy_from_slice(runner.position());
        }
        let finished = settled(&q, &last, over) || stepped.is_err();
        last = q;
        out.copy_from_slice(&q);
        finished
    };
    robot.stream(&nominal_plan, &mut next, max, stop).map_err(|e| match e {
        RobotError::Refused { robot, reason } => DriveError::Refused {
            sentence: format!(
                "{name}: refused before sending anything: the model's movement from where the robot is breaks a limit: {reason} (a longer --tau slows it)"
            ),
            source: Box::new(RobotError::Refused { robot, reason }),
        },
        other => DriveError::during(&name, other),
    })?;
    let report = robot
        .inner()
        .reports()
        .last()
        .cloned()
        .ok_or_else(|| DriveError::Failed("the robot sent no report".into()))?;
    Ok(Executed {
        host: settings.host.clone(),
        arm: settings.arm,
        report,
        approach: 0,
        how: "a DMP stepped online with phase stopping",
    })
}

/// The recording as a table: `t`, `q1..7`, `dq1..7`, `tau1..7`, `q_d1..7`, `tool_x,y,z`.
pub fn recording_table(samples: &[Sample]) -> Table {
    let mut table = Table::new("recording").with(Column::numbers(
        "t",
        samples.iter().map(|s| s.t).collect(),
        Format::Plain,
    ));
    for (name, k) in [("q", 0), ("dq", 1), ("tau", 2), ("q_d", 3)] {
        let get = |s: &Sample| [s.q, s.dq, s.tau, s.q_c][k];
        for j in 0..7 {
            table.push(Column::numbers(
                format!("{name}{}", j + 1),
                samples.iter().map(|s| get(s)[j]).collect(),
                Format::Plain,
            ));
        }
    }
    for (k, axis) in ["tool_x", "tool_y", "tool_z"].into_iter().enumerate() {
        table.push(Column::numbers(
            axis,
            samples.iter().map(|s| s.tool[k]).collect(),
            Format::Plain,
        ));
    }
    table
}

impl Executed {
    /// Whether the motion ran to its end.
    pub fn complete(&self) -> bool {
        self.report.ending.complete()
    }

    /// The robot time (s, the recording's `t`) at which the trajectory's first command was
    /// due: after the approach, and after the motion's opening at rest
    /// ([`cps_franka::MotionReport::clock_start`]).
    pub fn start_s(&self) -> f64 {
        self.report.clock_start.unwrap_or(0.0) + self.approach as f64 * 1e-3
    }

    /// Per joint, RMS and largest |measured − commanded| over the recording (rad).
    pub fn tracking(&self) -> ([f64; 7], [f64; 7]) {
        let (mut rms, mut max) = ([0.0; 7], [0.0f64; 7]);
        let n = self.report.samples.len().max(1) as f64;
        for s in &self.report.samples {
            for j in 0..7 {
                let e = s.q[j] - s.q_c[j];
                rms[j] += e * e;
                max[j] = max[j].max(e.abs());
            }
        }
        (rms.map(|x| (x / n).sqrt()), max)
    }

    /// The report: `{"complete", "ending", "host", "arm", "samples", "duration_s",
    /// "approach_s", "timing", "tracking", "limit_usage_percent"}`.
    pub fn json(&self) -> Value {
        let (rms, max) = self.tracking();
        let usage = |k: usize| self.report.peak_usage[k].map(|u| (u * 1e4).round() / 100.0);
        json!({
            "complete": self.complete(),
            "ending": self.report.ending.sentence(),
            "host": self.host,
            "arm": self.arm.name(),
            "trajectory": self.how,
            "samples": self.report.samples.len(),
            "duration_s": self.report.samples.last().map_or(0.0, |s| s.t),
            "approach_s": self.start_s(),
            "brake_ticks": self.report.brake_ticks,
            "timing": timing_json(&self.report),
            "tracking": { "rms_rad": rms, "max_rad": max },
            "limit_usage_percent": { "velocity": usage(0), "acceleration": usage(1), "jerk": usage(2) },
        })
    }

    /// The report in lines.
    pub fn lines(&self, record: &Path) -> Vec<String> {
        let (rms, max) = self.tracking();
        let peak = |k: usize| {
            self.report.peak_usage[k]
                .iter()
                .copied()
                .fold(0.0, f64::max)
                * 100.0
        };
        let mut lines = vec![
            format!("{}: {}", self.host, self.report.ending.sentence()),
            format!(
                "  {} samples over {:.3} s ({}; approach {:.3} s), recorded in {}",
                self.report.samples.len(),
                self.report.samples.last().map_or(0.0, |s| s.t),
                self.how,
                self.start_s(),
                record.display()
            ),
        ];
        lines.extend(timing_lines(&self.report));
        lines.extend([
            format!("  tracking (measured - commanded) RMS [{}] rad", fmt7(&rms)),
            format!("                                  max [{}] rad", fmt7(&max)),
            format!(
                "  limit usage of what was sent: velocity {:.1} %, acceleration {:.1} %, jerk {:.1} %",
                peak(0),
                peak(1),
                peak(2)
            ),
        ]);
        lines
    }
}

/// A motion's loop in a report: its timing, and what it saw of the robot's cycles
/// (missed, stale, extrapolated by the robot, dropped; commands limited).
pub fn timing_json(report: &MotionReport) -> Value {
    let (t, c) = (&report.timing, report.cycles());
    json!({
        "ticks": t.ticks, "median_us": t.median_us, "p99_us": t.p99_us, "max_us": t.max_us,
        "missed_ticks": t.missed, "stale_states": t.stale, "realtime": t.realtime,
        "withheld_answers": t.withheld, "extrapolated_cycles": c.extrapolated, "dropped_commands": c.dropped,
        "applied_late": report.reference.applied_late,
        "reference_unconfirmed": report.reference.unconfirmed,
        "limited_commands": c.limited, "largest_limit_change": c.largest_change,
        "success_rate_min": c.success_rate_min,
    })
}

/// A motion's loop in two report lines (see [`timing_json`]).
pub fn timing_lines(report: &MotionReport) -> [String; 2] {
    let t = &report.timing;
    [
        format!(
            "  loop: state in -> command out median {:.1} us, p99 {:.1} us, max {:.1} us; {}",
            t.median_us,
            t.p99_us,
            t.max_us,
            if t.realtime {
                "SCHED_FIFO"
            } else {
                "normal priority"
            },
        ),
        format!("  cycles: {}", report.cycles().sentence()),
    ]
}

/// Writes a recording and its report (complete or not), each atomically.
pub fn write_recording(
    record: &Path,
    samples: &[Sample],
    report: &Value,
) -> Result<(), DriveError> {
    write_table_and_report(record, &recording_table(samples), report)
}

/// Writes `table` at `record` and `report` beside it (`<stem>.report.json`).
pub(crate) fn write_table_and_report(
    record: &Path,
    table: &Table,
    report: &Value,
) -> Result<(), DriveError> {
    let csv = cps_outcome::files::table_csv(table)?;
    cps_outcome::files::write_file(record, &csv)?;
    let text = format!("{report:#}");
    Ok(cps_outcome::files::write_file(
        &report_path(record),
        text.as_bytes(),
    )?)
}

/// The robot's state for `seconds` (in (0, 3600]) or until `stop`, in memory, with its
/// report `{"complete", "ending", "host", "samples", "duration_s"}`: the arm's
/// [`Robot::record`], nothing commanded.
pub fn record_samples(
    host: &str,
    seconds: f64,
    stop: &StopToken,
) -> Result<(Vec<Sample>, Value), DriveError> {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 3600.0) {
        return Err(InputError(format!("--duration: {seconds} s is not in (0, 3600]")).into());
    }
    let mut robot = FrankaRobot::connect(
        &FrankaSettings {
            host: host.to_string(),
            arm: Arm::Fr3,
            realtime: Realtime::Ignore,
            dt: DT,
        },
        arm_model(Arm::Fr3)?,
    )?;
    let run = robot.record(std::time::Duration::from_secs_f64(seconds), stop)?;
    let samples = robot.last_recording().to_vec();
    let duration = samples.last().map_or(0.0, |s| s.t);
    let ending = match &run.ending {
        cps_robot::Ending::Failed(r) => r.clone(),
        cps_robot::Ending::Stopped => "stopped on request".into(),
        cps_robot::Ending::Finished => "recorded for the whole duration".into(),
    };
    let report = json!({ "complete": run.ending.complete(), "ending": ending, "host": host, "samples": samples.len(), "duration_s": duration });
    Ok((samples, report))
}

/// `franka record`: the robot's state for `seconds` (or until `stop`), written to `out`
/// (checked first: a new file, or `force`); returns the report (`complete` false when the
/// connection was lost or it was stopped) and how it ended (failed: the connection lost).
pub fn record(
    host: &str,
    seconds: f64,
    out: &Path,
    force: bool,
    stop: &StopToken,
) -> Result<(Recorded, Ended), DriveError> {
    check_record_target(out, force)?;
    let (samples, report) = record_samples(host, seconds, stop)?;
    write_recording(out, &samples, &report)?;
    let (complete, stopped) = (report["complete"] == true, stop.is_stopped());
    let code = match (stopped, complete) {
        (true, _) => Ended::Stopped,
        (false, done) => Ended::of(done),
    };
    let recorded = Recorded {
        host: host.to_string(),
        out: out.to_path_buf(),
        samples: samples.len(),
        duration_s: report["duration_s"].as_f64().unwrap_or(0.0),
        guided: false,
        report,
    };
    Ok((recorded, code))
}

/// What `franka guide` needs beyond the recording's path.
#[derive(Debug, Clone)]
pub struct GuideSettings {
    /// The robot's address.
    pub host: String,
    /// Which arm's range and limits.
    pub arm: Arm,
    /// Realtime scheduling of the loop.
    pub realtime: Realtime,
    /// Seconds to record (Ctrl-C ends it earlier).
    pub seconds: f64,
    /// Damping on every joint (N m s/rad); None: cps's defaults (3 on joints 1–4, 1 on 5–6,
    /// 0.5 on 7).
    pub damping: Option<f64>,
}

/// The arm floating (gravity compensated by the robot, lightly damped) for the settings'
/// seconds or until `stop`, recorded in memory: the samples and the report `{"complete",
/// "ending", "host", "arm", "samples", "duration_s", "damping", "timing"}`.
pub fn guide_samples(
    settings: &GuideSettings,
    stop: &StopToken,
) -> Result<(Vec<Sample>, Value), DriveError> {
    let mut guiding = cps_franka::guide::Guiding {
        duration: settings.seconds,
        ..Default::default()
    };
    if let Some(d) = settings.damping {
        guiding.damping = [d; 7];
    }
    guiding.check().map_err(|e| InputError(e.to_string()))?;
    let (host, arm) = (&settings.host, settings.arm);
    let mut robot = connect(host)?;
    let options = LoopOptions {
        realtime: settings.realtime,
        ..Default::default()
    };
    let limits = RateLimits::of(arm);
    let report = {
        let _moving = stop.moving();
        cps_franka::guide::run_guiding(&mut robot, limits, &options, stop.flag(), &guiding)
    }?;
    let json = json!({
        "complete": report.ending.complete(),
        "ending": report.ending.sentence(),
        "host": host,
        "arm": arm.name(),
        "samples": report.samples.len(),
        "duration_s": report.samples.last().map_or(0.0, |s| s.t),
        "damping": guiding.damping,
        "timing": timing_json(&report),
    });
    Ok((report.samples, json))
}

/// `franka guide`: [`guide_samples`] written to `out` (checked first: a new file, or
/// `force`) with its report; the recording has the columns of `franka execute --record`,
/// ready for `cps-cli imitate`. Returns the answer and how it ended (completed,
/// stopped, or failed otherwise).
pub fn guide(
    settings: &GuideSettings,
    out: &Path,
    force: bool,
    stop: &StopToken,
) -> Result<(Recorded, Ended), DriveError> {
    check_record_target(out, force)?;
    let (samples, json) = guide_samples(settings, stop)?;
    write_recording(out, &samples, &json)?;
    let code = if json["complete"] == true {
        Ended::Completed
    } else if stop.is_stopped() {
        Ended::Stopped
    } else {
        Ended::Failed
    };
    let recorded = Recorded {
        host: settings.host.clone(),
        out: out.to_path_buf(),
        samples: samples.len(),
        duration_s: samples.last().map_or(0.0, |s| s.t),
        guided: true,
        report: json,
    };
    Ok((recorded, code))
}

/// A gripper action of `franka gripper`: `home`, `move`, `grasp`, `stop`, `state`.
pub fn gripper_command(
    action: &str,
    width: Option<f64>,
    speed: f64,
    force: f64,
    epsilon: f64,
) -> Result<Option<GripperCommand>, InputError> {
    let need = |w: Option<f64>| {
        w.ok_or_else(|| InputError(format!("franka gripper {action}: give the width in metres")))
    };
    Ok(Some(match action {
        "home" => GripperCommand::Homing,
        "stop" => GripperCommand::Stop,
        "state" => return Ok(None),
        "move" => GripperCommand::Move {
            width: need(width)?,
            speed,
        },
        "grasp" => GripperCommand::Grasp {
            width: need(width)?,
            epsilon_inner: epsilon,
            epsilon_outer: epsilon,
            speed,
            force,
        },
        other => {
            return Err(InputError(format!(
                "franka gripper: `{other}` is not an action (home, move, grasp, stop, state)"
            )));
        }
    }))
}

/// `franka gripper`: runs `command` (none: only the state) on the hand of the robot at
/// `host` and answers with the state after it: `{"width", "max_width", "is_grasped",
/// "temperature", "grasped"?}`. Bad arguments are refused before anything is sent.
pub fn gripper(host: &str, command: Option<GripperCommand>) -> Result<HandAt, DriveError> {
    let mut hand = Gripper::connect(host, std::time::Duration::from_secs(3))?;
    let held = match command {
        Some(c) => Some(hand.run(c)?),
        None => None,
    };
    let state = hand.state(std::time::Duration::from_secs(1))?;
    let grasped = held.filter(|_| matches!(command, Some(GripperCommand::Grasp { .. })));
    Ok(HandAt {
        host: host.to_string(),
        state,
        grasped,
    })
}

/// `franka execute` whole: the recording's target checked first; a joint trajectory CSV
/// prepared and executed ([`execute`]) or a DMP model (`.json`) stepped online
/// ([`execute_model`], with `online`); the recording and its report written (complete or
/// not). Returns the answer and how it ended ([`ended`]).
pub fn execute_file(
    file: &Path,
    settings: &ExecuteSettings,
    online: &DmpSettings,
    record: &Path,
    force: bool,
    stop: &StopToken,
) -> Result<(ExecutedTo, Ended), DriveError> {
    check_record_target(record, force)?;
    let is_model = file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let done = if is_model {
        execute_model(file, settings, online, stop)?
    } else {
        if online.tau.is_some() || online.goal.is_some() {
            return Err(InputError(format!(
                "{}: --tau and --goal apply to DMP models (.json), not to trajectories",
                file.display()
            ))
            .into());
        }
        let prepared = prepare(file, settings.arm, settings.retime)?;
        execute(&prepared, settings, stop)?
    };
    let report = done.json();
    write_recording(record, &done.report.samples, &report)?;
    let ended = ended(&done.report.ending);
    let executed = ExecutedTo {
        executed: done,
        record: record.to_path_buf(),
        report,
        more: Vec::new(),
    };
    Ok((executed, ended))
}

/// `franka execute` and `franka follow`: what was sent and what the robot did, recorded
/// at `record`.
#[derive(Debug, Clone)]
pub struct ExecutedTo {
    /// The execution.
    pub executed: Executed,
    /// Where its recording is.
    pub record: std::path::PathBuf,
    /// Its report, as written beside the recording.
    pub report: Value,
    /// Lines said after the execution's own (a follow's chunks).
    pub more: Vec<String>,
}

/// The report.
impl serde::Serialize for ExecutedTo {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.report.serialize(s)
    }
}

impl std::fmt::Display for ExecutedTo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let lines = self.executed.lines(&self.record);
        for (i, line) in lines.iter().chain(&self.more).enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            f.write_str(line)?;
        }
        Ok(())
    }
}

/// How an execution ended: completed when it finished, stopped on request, failed
/// otherwise.
pub fn ended(ending: &MotionEnd) -> Ended {
    match ending {
        MotionEnd::Finished => Ended::Completed,
        MotionEnd::Stopped => Ended::Stopped,
        _ => Ended::Failed,
    }
}
