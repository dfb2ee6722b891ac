//! Action chunks on a robot: the [`ChunkExecutor`] stepped on a [`cps_robot::Streaming`] robot's
//! command loop behind the guard ([`follow`]), chunks taken from a [`ChunkSource`] each
//! period, and what a run did ([`Followed`]) judged in numbers ([`crate::FollowReport`]).
//!
//! The executor's commands depend on the chunks and their arrival times alone, not on what
//! the robot measures, so a recorded stream's commands are known before anything moves:
//! a replay is checked whole by the guard as a plan is ([`replay_plan`]); a live stream's
//! commands are within the limits by the executor's construction and judged one by one by
//! the guard's collision watch and the robot's own loop.

use crate::FollowError;
use crate::chunk::Chunk;
use crate::executor::{ChunkCounts, ChunkExecutor, ChunkSettings, Offer};
use crate::feed::{ChunkSource, ChunkVerdict};
use crate::follow::FollowLimits;
use cps_robot::Robot;
use cps_robot::RobotModel;
use cps_robot::StopToken;
use cps_robot::{Guarded, Measured};
use cps_robot::{Plan, Run};

/// How a run follows chunks: the executor's settings, the share of the robot's limits it
/// moves within, and when the run ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowSettings {
    /// The executor's (stall timeout, largest gap).
    pub chunks: ChunkSettings,
    /// The share of each velocity, acceleration and jerk limit the commands keep within
    /// (default 0.95: the robot's own check at 100 % always has room).
    pub limit_share: f64,
    /// Seconds the arm may stand at rest with no chunk before the run ends (default 5; a
    /// replay ends as soon as its last chunk is followed and the arm is at rest).
    pub idle_end_s: f64,
    /// The longest run (s; default 300): the commands' recording is made this long before
    /// the loop starts, so that nothing grows on it.
    pub max_duration_s: f64,
}

impl Default for FollowSettings {
    fn default() -> Self {
        FollowSettings {
            chunks: ChunkSettings::default(),
            limit_share: 0.95,
            idle_end_s: 5.0,
            max_duration_s: 300.0,
        }
    }
}

impl FollowSettings {
    /// The defaults with the executor's stall timeout (s) and largest gap (rad).
    pub fn with_chunks(stall_timeout_s: f64, max_gap_rad: f64) -> FollowSettings {
        FollowSettings {
            chunks: ChunkSettings {
                stall_timeout_s,
                max_gap_rad,
            },
            ..FollowSettings::default()
        }
    }

    /// Checks every setting, in a sentence naming it.
    pub fn check(&self) -> Result<(), FollowError> {
        let positive = |setting: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(FollowError::Seconds { setting, value })
            }
        };
        positive("stall timeout", self.chunks.stall_timeout_s)?;
        positive("idle end", self.idle_end_s)?;
        positive("max duration", self.max_duration_s)?;
        if !(self.chunks.max_gap_rad.is_finite() && self.chunks.max_gap_rad > 0.0) {
            return Err(FollowError::MaxGap(self.chunks.max_gap_rad));
        }
        if !(self.limit_share > 0.0 && self.limit_share <= 1.0) {
            return Err(FollowError::LimitShare(self.limit_share));
        }
        Ok(())
    }
}

/// The share of a torque-rate limit the follower's jerk may use up through the mass
/// matrix at the start: the rest is room for the configuration's change, the velocity
/// products and gravity's gradient, which the jerk does not drive.
pub const TORQUE_RATE_SHARE: f64 = 0.5;

/// The follower's limits for `model` starting at `q0`: its joints' velocity, acceleration
/// and jerk limits at `share`; where the model has torque-rate limits and inertias, each
/// jerk lowered by its joint's inertia, then all together by their coupling, so that the
/// mass matrix at `q0` turns them into at most [`TORQUE_RATE_SHARE`] of each torque-rate
/// limit. Errors, in a sentence: the robot's
/// data lack a limit.
pub fn follow_limits(
    model: &RobotModel,
    share: f64,
    q0: &[f64],
) -> Result<Vec<FollowLimits>, FollowError> {
    let n = model.chain.dof();
    let missing = |quantity: &'static str| FollowError::MissingLimits {
        robot: model.name.clone(),
        quantity,
    };
    let v = model
        .chain
        .velocity_limits()
        .ok_or_else(|| missing("velocity"))?;
    let a = model
        .limits
        .acceleration
        .as_deref()
        .ok_or_else(|| missing("acceleration"))?;
    let j = model
        .limits
        .jerk
        .as_deref()
        .ok_or_else(|| missing("jerk"))?;
    let mut jerk: Vec<f64> = j.iter().map(|x| x * share).collect();
    if let (Some(rate), Some(links)) = (&model.limits.torque_rate, &model.inertia) {
        let g = nalgebra::Vector3::zeros();
        let zero = vec![0.0; n];
        // The mass matrix at q0, column k the torques of a unit acceleration of joint k.
        let mut mass = vec![vec![0.0; n]; n];
        for k in 0..n {
            let mut e = zero.clone();
            e[k] = 1.0;
            let col = model
                .chain
                .inverse_dynamics(links, g, q0, &zero, &e)
                .map_err(|source| FollowError::MassMatrix {
                    robot: model.name.clone(),
                    source,
                })?;
            for (i, m) in col.iter().enumerate() {
                mass[i][k] = m.abs();
            }
        }
        let room = |i: usize| TORQUE_RATE_SHARE * share * rate[i];
        // Each joint's jerk by its own inertia, then all together by the coupling.
        for k in 0..n {
            if mass[k][k] > 0.0 {
                jerk[k] = jerk[k].min(room(k) / mass[k][k]);
            }
        }
        let scale = (0..n)
            .map(|i| room(i) / (0..n).map(|k| mass[i][k] * jerk[k]).sum::<f64>())
            .fold(1.0, f64::min);
        for x in &mut jerk {
            *x *= scale;
        }
    }
    Ok((0..n)
        .map(|i| FollowLimits {
            velocity: v[i] * share,
            acceleration: a[i] * share,
            jerk: jerk[i],
        })
        .collect())
}

/// An executor for `model` at rest at `q0`, stepped every `dt`: its limits at the
/// settings' share, chunks outside its joint range refused.
pub fn executor_for(
    model: &RobotModel,
    q0: &[f64],
    dt: f64,
    settings: &FollowSettings,
) -> Result<ChunkExecutor, FollowError> {
    settings.check()?;
    let limits = follow_limits(model, settings.limit_share, q0)?;
    let ex = ChunkExecutor::new(q0, &limits, dt, settings.chunks)?;
    Ok(match model.chain.limits() {
        Some((lower, upper)) => ex.with_range(lower, upper),
        None => ex,
    })
}

/// One period of a run: the chunks handed over by `t` offered, then the command for the
/// period ending at `t + dt` written into `out`. True when the run is over: the stream
/// ended and its last chunk was followed to its end (or the arm stood idle, with no fresh
/// chunk, for `idle_end_s`), and the arm is at rest.
struct Stepper {
    ex: ChunkExecutor,
    dt: f64,
    idle_end_s: f64,
    /// The chunk index the executor follows, and the next index.
    current: Option<usize>,
    next: usize,
    /// When the last chunk came (or the start).
    last_activity: f64,
    /// When each stall began (capacity made before the loop; later stalls only counted).
    stalls: Vec<f64>,
}

/// A chunk the executor took, as [`replay_with`] tells of it.
#[derive(Debug)]
pub struct TakenAt<'a> {
    /// Its index in the stream.
    pub chunk: usize,
    /// When it was taken (s).
    pub t: f64,
    /// The executor, having just taken it (its last command the one for `t`).
    pub executor: &'a ChunkExecutor,
    /// Whether the stream is over with it (it will be followed to its end).
    pub last: bool,
}

impl Stepper {
    /// `on_taken` hears of every chunk taken, as it is taken.
    fn step(
        &mut self,
        source: &mut dyn ChunkSource,
        t: f64,
        out: &mut [f64],
        on_taken: &mut dyn FnMut(&TakenAt<'_>),
    ) -> bool {
        while let Some(chunk) = source.poll(t) {
            let i = self.next;
            self.next += 1;
            self.last_activity = t;
            match self.ex.offer(chunk, t) {
                Offer::Taken { skipped, replaced } => {
                    source.judged(i, ChunkVerdict::Taken { skipped });
                    if let (Some(old), Some(j)) = (replaced, self.current) {
                        source.retire(j, old);
                    }
                    self.current = Some(i);
                    on_taken(&TakenAt {
                        chunk: i,
                        t,
                        executor: &self.ex,
                        last: source.ended(),
                    });
                }
                Offer::Refused { why, chunk } => {
                    source.judged(i, ChunkVerdict::Refused(why));
                    source.retire(i, chunk);
                }
            }
        }
        let ended = source.ended();
        if ended {
            // The stream is over: its last chunk is followed to its end.
            self.ex.last_chunk();
        }
        let stalls = self.ex.counts().stalls;
        out.copy_from_slice(self.ex.tick(t + self.dt));
        if self.ex.counts().stalls > stalls && self.stalls.len() < self.stalls.capacity() {
            self.stalls.push(t + self.dt);
        }
        let idle = self.ex.stalled_or_idle() && t - self.last_activity >= self.idle_end_s;
        ((ended && self.ex.chunk_done(t)) || idle) && self.ex.at_rest()
    }

    /// Hands the chunk the executor still follows back to the source.
    fn finish(&mut self, source: &mut dyn ChunkSource) {
        if let (Some(c), Some(i)) = (self.ex.take_chunk(), self.current.take()) {
            source.retire(i, c);
        }
    }
}

/// What a run of chunks did.
#[derive(Debug, Clone)]
pub struct Followed {
    /// What the robot measured, one entry per command period (entry 0 at the start).
    pub run: Run,
    /// The command of each period, in order (the first for the period after entry 0).
    pub commands: Vec<Vec<f64>>,
    /// The command period (s).
    pub dt: f64,
    /// The limits the commands kept within.
    pub limits: Vec<FollowLimits>,
    /// Chunks taken, refused, targets skipped, stalls.
    pub counts: ChunkCounts,
    /// When each stall began (s).
    pub stalls: Vec<f64>,
}

/// The commands a recorded stream makes from rest at `q0` (what [`follow`] will send for
/// it, whatever the robot measures), as a plan every `dt` from `q0`: the guard checks it
/// whole before anything moves.
pub fn replay_plan(
    model: &RobotModel,
    q0: &[f64],
    dt: f64,
    chunks: &[Chunk],
    settings: &FollowSettings,
) -> Result<Plan, FollowError> {
    replay_with(model, q0, dt, chunks, settings, &mut |_| {}).map(|(plan, _)| plan)
}

/// [`replay_plan`], telling `on_taken` of each chunk as the executor takes it (a ROS 2
/// controller's replacement trajectories start there), and returning the chunks with
/// their verdicts too.
pub fn replay_with(
    model: &RobotModel,
    q0: &[f64],
    dt: f64,
    chunks: &[Chunk],
    settings: &FollowSettings,
    on_taken: &mut dyn FnMut(&TakenAt<'_>),
) -> Result<(Plan, crate::feed::ChunkLog), FollowError> {
    let mut source = crate::feed::Replay::new(chunks.to_vec());
    let mut stepper = stepper(model, q0, dt, settings)?;
    let mut points = vec![q0.to_vec()];
    let mut out = q0.to_vec();
    let max = (settings.max_duration_s / dt).ceil() as usize;
    for k in 0..max {
        let over = stepper.step(&mut source, k as f64 * dt, &mut out, on_taken);
        points.push(out.clone());
        if over {
            stepper.finish(&mut source);
            let plan = Plan::new(dt, points)?;
            return Ok((plan, source.into_log()));
        }
    }
    Err(FollowError::RunTooLong(settings.max_duration_s))
}

fn stepper(
    model: &RobotModel,
    q0: &[f64],
    dt: f64,
    settings: &FollowSettings,
) -> Result<Stepper, FollowError> {
    Ok(Stepper {
        ex: executor_for(model, q0, dt, settings)?,
        dt,
        idle_end_s: settings.idle_end_s,
        current: None,
        next: 0,
        last_activity: 0.0,
        stalls: Vec::with_capacity(256),
    })
}

/// Follows the chunks of `source` on a streaming robot behind its guard, from where it
/// stands, until the stream ends (or stands idle) and the arm is at rest, `stop` is
/// asked (the robot brakes), or the longest run passes. `nominal`: the commands' plan
/// when they are known before (a replay's [`replay_plan`]), checked whole by the guard;
/// without it the guard checks the arm holding where it stands. Every command keeps the
/// robot's velocity, acceleration and jerk limits at the settings' share.
///
/// Errors: the settings or the robot's limits (a sentence), the robot does not stream, the
/// guard refused the nominal plan (nothing sent).
pub fn follow<R: Robot>(
    robot: &mut Guarded<R>,
    source: &mut dyn ChunkSource,
    nominal: Option<&Plan>,
    settings: &FollowSettings,
    stop: &StopToken,
) -> Result<Followed, FollowError> {
    let q0 = robot.joint_positions()?;
    let dt = robot.command_period();
    let model = robot.model().clone();
    let mut stepper = stepper(&model, &q0, dt, settings)?;
    let hold;
    let nominal = match nominal {
        Some(p) => p,
        None => {
            hold = Plan::new(dt, vec![q0.clone(), q0.clone()])?;
            &hold
        }
    };
    let max_commands = (settings.max_duration_s / dt).ceil() as usize;
    let dof = q0.len();
    // The commands' recording, made (and its pages touched) before the loop starts.
    let mut flat: Vec<f64> = cps_robot::prefaulted((max_commands + 1) * dof);
    // The command in force, published with each period's state.
    let mut in_force = q0.clone();
    let mut next = |measured: &Measured<'_>, t: f64, out: &mut [f64]| -> bool {
        source.publish(t, measured, &in_force);
        let over = stepper.step(source, t, out, &mut |_| {});
        in_force.copy_from_slice(out);
        if flat.len() + dof <= flat.capacity() {
            flat.extend_from_slice(out);
        }
        over
    };
    let run = robot.stream(nominal, &mut next, max_commands, stop);
    stepper.finish(source);
    source.over();
    let run = run?;
    Ok(Followed {
        run,
        commands: flat.chunks(dof).map(<[f64]>::to_vec).collect(),
        dt,
        limits: stepper.ex.limits().to_vec(),
        counts: stepper.ex.counts().clone(),
        stalls: stepper.stalls,
    })
}

#[cfg(test)]
mod tests {
    use crate::{FollowError, FollowSettings, Follower};

    #[test]
    fn a_caller_tells_the_cases_apart_by_their_variant_and_reads_their_sentence() {
        let period = Follower::new(&[0.0], &[crate::follow::testing::FR3], 0.0).unwrap_err();
        assert!(matches!(period, FollowError::Period(p) if p == 0.0));
        assert_eq!(period.to_string(), "the period 0 s is not a period");
        let settings = FollowSettings {
            limit_share: 1.5,
            ..FollowSettings::default()
        };
        assert!(matches!(settings.check(), Err(FollowError::LimitShare(s)) if s == 1.5));
    }
}
