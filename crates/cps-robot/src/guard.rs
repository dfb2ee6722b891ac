//! Limits as a wrapper around any robot: every plan is checked against the robot's limits
//! before anything is sent — refused, or slowed down, as the [`Policy`] says — and a plan
//! that does not start where the robot stands is refused or approached from there. One
//! implementation for every robot, so the same plan is judged the same, in the same words,
//! on the in-process stand-in, a simulator, a Franka and a ROS 2 controller.

use crate::check::{Breach, Verdict, check};
use crate::collision::{Collision, ShapeWatch, check_shapes};
use crate::plan::{Plan, Run};
use crate::robot::{Generator, Robot, Stepped, Streaming};
use crate::watch::CommandWatch;
use crate::{RobotError, RobotModel, StopToken};

/// The share of each velocity, acceleration and jerk limit an approach to a plan's start
/// uses.
pub const APPROACH_SHARE: f64 = 0.2;

/// The share of the limits a blend into a plan's start uses, when the robot stands within
/// [`START_TOLERANCE`] of it but not exactly there (a controller holding a position a hair
/// from the last command).
pub const BLEND_SHARE: f64 = 0.5;

/// The largest distance (rad, any joint) between where the robot stands and a plan's start
/// that is taken without an approach.
pub const START_TOLERANCE: f64 = 1e-3;

/// The most a plan is slowed to keep the limits; a plan that still breaks one is refused.
pub const MAX_SLOWING: f64 = 10.0;

/// What the guard does with a plan that breaks a limit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OnBreach {
    /// Refuse it: nothing is sent.
    Refuse,
    /// Slow it down uniformly, as little as the limits need, at most `max` times (≤
    /// [`MAX_SLOWING`]); refuse it if that is not enough.
    Slow {
        /// The largest slowing allowed.
        max: f64,
    },
}

/// What the guard does with a plan that starts away from where the robot stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnStart {
    /// Refuse it, naming the joint and the distance.
    Refuse,
    /// Move there first: a rest-to-rest approach at [`APPROACH_SHARE`] of the limits, run
    /// with the plan as one motion that rests at the plan's start.
    Approach,
}

/// How a [`Guarded`] robot treats plans.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Policy {
    /// Limits.
    pub on_breach: OnBreach,
    /// The start.
    pub on_start: OnStart,
}

impl Policy {
    /// Refuse whatever breaks a limit or starts elsewhere.
    pub const STRICT: Policy = Policy {
        on_breach: OnBreach::Refuse,
        on_start: OnStart::Refuse,
    };

    /// What experiments run with: slowed as needed (at most [`MAX_SLOWING`]), approached.
    pub const EXPERIMENT: Policy = Policy {
        on_breach: OnBreach::Slow { max: MAX_SLOWING },
        on_start: OnStart::Approach,
    };
}

/// Why a plan was refused before anything was sent.
#[derive(Debug, Clone, PartialEq)]
pub enum Refusal {
    /// It breaks a limit (and the policy refuses).
    Limit(Breach),
    /// Even slowed as far as allowed it breaks a limit.
    EvenSlowed {
        /// The breach at the largest slowing.
        breach: Breach,
        /// That slowing.
        max: f64,
    },
    /// Two bodies come closer than the clearance margin, or collide: no slowing helps (the
    /// path is the same at any speed). Times count from the start of what would be sent
    /// (an approach to the plan's start first, where it needs one).
    Collision(Collision),
    /// It starts too far from where the robot stands (and the policy refuses).
    Start {
        /// 1-based joint of the largest distance.
        joint: usize,
        /// Where that joint stands (rad).
        robot: f64,
        /// Where the plan starts it (rad).
        plan: f64,
    },
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::Limit(b) => write!(f, "{b}"),
            Refusal::Collision(c) => write!(f, "{c}"),
            Refusal::EvenSlowed { breach, max } => {
                write!(f, "even slowed {max}x the plan breaks a limit: {breach}")
            }
            Refusal::Start { joint, robot, plan } => write!(
                f,
                "the plan starts {:.4} rad from where the robot stands at joint {joint} (robot {robot:.4} rad, plan {plan:.4} rad)",
                (plan - robot).abs()
            ),
        }
    }
}

/// The rest-to-rest profile `s(τ) = 35τ⁴ − 84τ⁵ + 70τ⁶ − 20τ⁷` on τ ∈ [0, 1]: its first
/// three derivatives vanish at both ends.
pub fn septic(tau: f64) -> f64 {
    let t4 = tau.powi(4);
    t4 * (35.0 - 84.0 * tau + 70.0 * tau * tau - 20.0 * tau.powi(3))
}

/// Peak |s'|, |s''|, |s'''| of [`septic`] on [0, 1] (derivatives taken analytically and
/// maximised on a fine grid in the tests).
pub const SEPTIC_PEAKS: [f64; 3] = [2.1875, 7.5132, 52.5];

/// A straight move in joint space from `from` to `to` along [`septic`], as long as the
/// slowest joint needs for its distance under `bounds` (per joint: the largest velocity,
/// acceleration and jerk, any of them `None` where not limited), sampled every `dt` (the
/// first sample at `from`, the last exactly at `to`, at least one step).
pub fn rest_to_rest(
    from: &[f64],
    to: &[f64],
    bounds: impl Fn(usize) -> [Option<f64>; 3],
    dt: f64,
) -> Vec<Vec<f64>> {
    let mut duration: f64 = 0.0;
    for i in 0..from.len() {
        let d = (to[i] - from[i]).abs();
        if d == 0.0 {
            continue;
        }
        let [v, a, j] = bounds(i);
        if let Some(v) = v {
            duration = duration.max(SEPTIC_PEAKS[0] * d / v);
        }
        if let Some(a) = a {
            duration = duration.max((SEPTIC_PEAKS[1] * d / a).sqrt());
        }
        if let Some(j) = j {
            duration = duration.max((SEPTIC_PEAKS[2] * d / j).cbrt());
        }
    }
    let steps = ((duration / dt) - 1e-9).ceil().max(1.0) as usize;
    (0..=steps)
        .map(|k| {
            if k == steps {
                return to.to_vec();
            }
            let s = septic(k as f64 / steps as f64);
            from.iter().zip(to).map(|(a, b)| a + (b - a) * s).collect()
        })
        .collect()
}

/// A rest-to-rest move from `from` to `to` ([`rest_to_rest`]) at `share` of the model's
/// velocity, acceleration and jerk limits (those it has; 1 rad/s where it has no speed
/// limit), as a plan every `dt` seconds.
pub fn approach(
    model: &RobotModel,
    from: &[f64],
    to: &[f64],
    share: f64,
    dt: f64,
) -> Result<Plan, RobotError> {
    let speed = model.chain.velocity_limits();
    let limits = &model.limits;
    let points = rest_to_rest(
        from,
        to,
        |i| {
            [
                Some(share * speed.map_or(1.0, |v| v[i])),
                limits.acceleration.as_ref().map(|a| share * a[i]),
                limits.jerk.as_ref().map(|j| share * j[i]),
            ]
        },
        dt,
    );
    Plan::new(dt, points)
}

/// A robot whose every plan passes the guard first (see the module docs).
#[derive(Debug)]
pub struct Guarded<R> {
    robot: R,
    policy: Policy,
    /// The largest slowing a plan needed so far (1 = none).
    slowest: f64,
    /// The verdict on the last plan sent.
    last: Option<Verdict>,
    /// The commands sent one step at a time since the robot last stood (see
    /// [`Stepped for Guarded`](#impl-Stepped-for-Guarded%3CR%3E)).
    watch: Option<CommandWatch>,
    /// Whether a joint command came since the last step.
    commanded: bool,
    /// How the stepped robot is driven, read when its stepped view was last asked for.
    stepping: crate::Stepping,
    /// The stepped commands' collision check (made at the first, when the robot has
    /// shapes; started over with `watch`).
    shapes: Option<ShapeWatch>,
    /// The way around a straight approach that would collide, when one is given.
    around: Option<Around>,
}

/// A planner of approaches around the robot's shapes and its scene: from `from` to `to` of
/// `model`, timed at `share` of its limits every `dt` seconds, or why there is none (as
/// `cps_plan::around`).
pub type Around =
    fn(model: &RobotModel, from: &[f64], to: &[f64], share: f64, dt: f64) -> Result<Plan, String>;

/// A plan made ready by the guard: what will be sent, and how it came to be.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The plan to run: the approach (if any) then the plan, slowed if needed.
    pub plan: Plan,
    /// Points of `plan` that are the approach (0: none); the plan's own points follow.
    pub approach_points: usize,
    /// The slowing applied (1 = none).
    pub slowing: f64,
    /// The verdict on `plan`.
    pub verdict: Verdict,
}

impl<R: Robot> Guarded<R> {
    /// `robot`, with every plan checked under `policy`.
    pub fn new(robot: R, policy: Policy) -> Self {
        Guarded {
            robot,
            policy,
            slowest: 1.0,
            last: None,
            watch: None,
            commanded: false,
            stepping: crate::Stepping::Joints,
            shapes: None,
            around: None,
        }
    }

    /// The same guard, approaching the way `around` plans where the straight approach to a
    /// plan's start would bring two shapes within the margin (the approach it plans is
    /// checked like any other: every pair, every limit).
    pub fn going_around(mut self, around: Around) -> Self {
        self.around = Some(around);
        self
    }

    /// The robot inside.
    pub fn inner(&self) -> &R {
        &self.robot
    }

    /// The robot inside, unwrapped: the guard is let go, and nothing sent to the robot
    /// from then on is its (there is no way to reach the robot mutably while it guards).
    pub fn into_inner(self) -> R {
        self.robot
    }

    /// The policy.
    pub fn policy(&self) -> Policy {
        self.policy
    }

    /// The largest slowing a plan needed so far (1 = every plan ran as planned).
    pub fn slowest(&self) -> f64 {
        self.slowest
    }

    /// The verdict on the last plan sent (its limit usage).
    pub fn last_verdict(&self) -> Option<&Verdict> {
        self.last.as_ref()
    }

    fn refused(&self, reason: Refusal) -> RobotError {
        RobotError::Refused {
            robot: self.robot.name(),
            reason,
        }
    }

    /// The approach from `here` to `plan`'s start: straight, or — where that would bring
    /// two shapes within the margin and a way around is given — the way around it finds
    /// (the straight one when it finds none: the check then refuses it, naming the pair).
    fn approach(&self, here: &[f64], plan: &Plan) -> Result<Plan, RobotError> {
        let model = self.robot.model();
        let straight = approach(model, here, plan.start(), APPROACH_SHARE, plan.dt())?;
        if let (Some(around), Some(shapes)) = (self.around, &model.shapes) {
            let period = self.robot.command_period();
            if check_shapes(shapes, &model.chain, &straight, period)?.is_some()
                && let Ok(way) = around(model, here, plan.start(), APPROACH_SHARE, plan.dt())
            {
                return Ok(way);
            }
        }
        Ok(straight)
    }

    /// Judges `plan` from where the robot stands: the approach it needs (or the refusal),
    /// the slowing its limits need (or the refusal). Nothing is sent.
    pub fn prepare(&mut self, plan: &Plan) -> Result<Prepared, RobotError> {
        let dof = self.robot.model().chain.dof();
        plan.check_dof(dof)?;
        let here = self.robot.standing()?;
        let (joint, gap) = here.as_ref().map_or((0, 0.0), |here| {
            here.iter()
                .zip(plan.start())
                .map(|(a, b)| (a - b).abs())
                .enumerate()
                .fold((0, 0.0f64), |m, (i, g)| if g > m.1 { (i, g) } else { m })
        });
        let approach = if let Some(here) = here.as_ref().filter(|_| gap > START_TOLERANCE) {
            match self.policy.on_start {
                OnStart::Refuse => {
                    return Err(self.refused(Refusal::Start {
                        joint: joint + 1,
                        robot: here[joint],
                        plan: plan.start()[joint],
                    }));
                }
                OnStart::Approach => Some(self.approach(here, plan)?),
            }
        } else {
            None
        };
        let max = match self.policy.on_breach {
            OnBreach::Refuse => 1.0,
            OnBreach::Slow { max } => max.clamp(1.0, MAX_SLOWING),
        };
        if let Some(shapes) = &self.robot.model().shapes {
            // The path is the same at any slowing: checked once, as it would first be sent.
            let whole = match &approach {
                Some(a) => a.resampled(plan.dt())?.then(plan)?,
                None => plan.clone(),
            };
            let model = self.robot.model();
            let period = self.robot.command_period();
            if let Some(c) = check_shapes(shapes, &model.chain, &whole, period)? {
                return Err(self.refused(Refusal::Collision(c)));
            }
        }
        let mut slowing: f64 = 1.0;
        loop {
            let main = if slowing == 1.0 {
                plan.clone()
            } else {
                plan.slowed(slowing)
            };
            let whole = match &approach {
                // The approach at the plan's (slowed) period, then the plan, resting between.
                Some(a) => a.resampled(main.dt())?.then(&main)?,
                None => main,
            };
            let verdict = check(self.robot.model(), &whole, self.robot.command_period())?;
            let breach = match verdict.breach {
                Some(b) => Some(b),
                None => self.robot.check(&whole)?,
            };
            let Some(breach) = breach else {
                let approach_points = approach
                    .as_ref()
                    .map_or(0, |_| whole.points().len() - plan.points().len());
                return Ok(Prepared {
                    plan: whole,
                    approach_points,
                    slowing,
                    verdict,
                });
            };
            let need = breach.slowing_needed();
            match need {
                Some(need) if slowing < max => {
                    // Enough for this breach with 5 % to spare; the next may need more.
                    slowing = (slowing * need * 1.05).min(max);
                }
                _ if max > 1.0 && need.is_some() => {
                    return Err(self.refused(Refusal::EvenSlowed { breach, max }));
                }
                _ => return Err(self.refused(Refusal::Limit(breach))),
            }
        }
    }

    /// Runs a prepared plan ([`Guarded::prepare`]): the robot's entries for the plan's own
    /// points, at their times from the plan's start (after the approach).
    pub fn run_prepared(
        &mut self,
        prepared: Prepared,
        stop: &StopToken,
    ) -> Result<Run, RobotError> {
        self.watch = None; // after a plan, stepped commands count from where it stands
        let mut run = self.robot.run(&prepared.plan, stop)?;
        self.slowest = self.slowest.max(prepared.slowing);
        let skip = prepared.approach_points;
        let t0 = prepared.plan.time(skip);
        if skip > 0 {
            let from = skip.min(run.time.len());
            run.time.drain(..from);
            run.q.drain(..from);
            run.tool.drain(..from);
            for t in &mut run.time {
                *t -= t0;
            }
        }
        run.slowing = prepared.slowing;
        run.approach_s = t0;
        self.last = Some(prepared.verdict);
        Ok(run)
    }

    /// Streams a movement generated online (see [`Streaming`]) after checking its nominal
    /// plan — the movement as it would run on a robot that follows its commands exactly —
    /// as every plan is checked: a nominal movement that breaks a limit or starts away from
    /// the robot is refused (or slowed: not possible online, so refused) before anything is
    /// sent. Errors: the robot does not stream.
    pub fn stream(
        &mut self,
        nominal: &Plan,
        next: &mut Generator<'_>,
        max_commands: usize,
        stop: &StopToken,
    ) -> Result<Run, RobotError> {
        let strict = Policy {
            on_breach: OnBreach::Refuse,
            on_start: OnStart::Refuse,
        };
        let policy = std::mem::replace(&mut self.policy, strict);
        let prepared = self.prepare(nominal);
        self.policy = policy;
        let prepared = prepared?;
        let name = self.robot.name();
        let model = self.robot.model().clone();
        let period = self.robot.command_period();
        // Where the commands start from, for the guard's own limit judge; a robot whose loop
        // limits each command is not asked.
        let judge_limits = self
            .robot
            .streaming()
            .is_some_and(|s| !s.limits_each_command());
        let here = if judge_limits {
            Some(self.robot.joint_positions()?)
        } else {
            None
        };
        let Some(streaming) = self.robot.streaming() else {
            return Err(RobotError::Robot {
                robot: name,
                message: "it runs whole plans only; it takes no command computed online".into(),
            });
        };
        // Each command is judged as it is made — every limit (unless the robot's own loop
        // limits each command) and the shapes; at the first it breaks, it is not sent (the
        // last one accepted is held) and the robot is stopped through a token of the
        // guard's own, which also passes the caller's stop on.
        let mut limits = here.map(|q| CommandWatch::new(&model, &q, period));
        let mut shapes = model
            .shapes
            .clone()
            .map(|s| ShapeWatch::new(s, model.chain.dof()));
        let chain = &model.chain;
        let (inner, mut hit, mut breach, mut count) = (StopToken::new(), None, None, 0usize);
        let _moving = stop.moving();
        let mut judged = |measured: &crate::Measured<'_>, t: f64, out: &mut [f64]| -> bool {
            if stop.is_stopped() {
                inner.stop();
            }
            let last = next(measured, t, out);
            count += 1;
            if breach.is_none()
                && let Some(w) = limits.as_mut()
                && let Err(b) = w.judge(&model, out)
            {
                out.copy_from_slice(w.last());
                breach = Some(b);
                inner.stop();
            }
            if hit.is_none()
                && let Some(w) = shapes.as_mut()
                && let Some(h) = w.contact(chain, out).transpose()
            {
                hit = Some((h, count));
                inner.stop();
            }
            last
        };
        let mut run = streaming.stream(&mut judged, max_commands, &inner)?;
        if let Some(b) = breach {
            run.ending = crate::Ending::Failed(format!(
                "a command computed online broke a limit, so it was not sent and the robot stopped: {b}"
            ));
        } else if let Some((hit, count)) = hit {
            let watch = shapes.as_ref().expect("a hit comes from the shapes");
            let why = match hit {
                Ok(c) => watch
                    .shapes()
                    .collision(&c, count as f64 * period, count)
                    .to_string(),
                Err(e) => e.to_string(),
            };
            run.ending = crate::Ending::Failed(format!(
                "a command came within the clearance margin, so the robot braked: {why}"
            ));
        }
        self.last = Some(prepared.verdict);
        Ok(run)
    }

    /// Moves the robot to `q` at rest ([`move_to`]), every plan checked.
    pub fn move_to(&mut self, q: &[f64], stop: &StopToken) -> Result<(), RobotError> {
        move_to(self, q, stop)
    }
}

/// Moves `robot` to `q` at rest: a simulator is put there ([`Robot::teleport`]); any other
/// robot approaches from where it stands at [`APPROACH_SHARE`] of its limits, as one plan
/// (checked first when the robot is [`Guarded`]). Within [`START_TOLERANCE`] nothing moves.
pub fn move_to(robot: &mut dyn Robot, q: &[f64], stop: &StopToken) -> Result<(), RobotError> {
    if robot.teleport(q)? {
        return Ok(());
    }
    let here = robot.joint_positions()?;
    if here.len() != q.len() {
        return Err(cps_kinematics::KinematicsError::JointCount {
            expected: here.len(),
            got: q.len(),
        }
        .into());
    }
    if here
        .iter()
        .zip(q)
        .all(|(a, b)| (a - b).abs() <= START_TOLERANCE)
    {
        return Ok(());
    }
    let plan = approach(robot.model(), &here, q, APPROACH_SHARE, robot.dt())?;
    let run = robot.run(&plan, stop)?;
    match run.ending {
        crate::Ending::Finished => Ok(()),
        other => Err(RobotError::Robot {
            robot: robot.name(),
            message: format!("moving to the start: {}", other.sentence()),
        }),
    }
}

impl<R: Robot> Robot for Guarded<R> {
    fn name(&self) -> String {
        self.robot.name()
    }
    fn model(&self) -> &RobotModel {
        self.robot.model()
    }
    fn dt(&self) -> f64 {
        self.robot.dt()
    }
    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        self.robot.joint_positions()
    }
    fn command_period(&self) -> f64 {
        self.robot.command_period()
    }
    fn standing(&mut self) -> Result<Option<Vec<f64>>, RobotError> {
        self.robot.standing()
    }
    fn tool_pose(&mut self) -> Result<nalgebra::IsometryMatrix3<f64>, RobotError> {
        self.robot.tool_pose()
    }
    /// Prepares `plan` ([`Guarded::prepare`]: refused, slowed, approached as the policy
    /// says) and runs it.
    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
        let prepared = self.prepare(plan)?;
        self.run_prepared(prepared, stop)
    }
    /// Puts a simulator at `q` unless two of the robot's bodies are closer there than its
    /// margin (refused, nothing moved).
    fn teleport(&mut self, q: &[f64]) -> Result<bool, RobotError> {
        self.watch = None;
        let model = self.robot.model();
        if let Some(shapes) = &model.shapes {
            let mut watch = ShapeWatch::new(shapes.clone(), model.chain.dof());
            if let Some(c) = watch.judge(&model.chain, q, 0.0, 0)? {
                return Err(self.refused(Refusal::Collision(c)));
            }
        }
        self.robot.teleport(q)
    }
    /// Nothing is commanded: the robot's own recording.
    fn record(
        &mut self,
        duration: std::time::Duration,
        stop: &StopToken,
    ) -> Result<Run, RobotError> {
        self.robot.record(duration, stop)
    }
    fn check(&mut self, plan: &Plan) -> Result<Option<Breach>, RobotError> {
        self.robot.check(plan)
    }
    fn report(&self) -> Option<String> {
        let inner = self.robot.report();
        if self.slowest > 1.0 {
            let slowed = format!("slowed up to {:.2}x to keep the limits", self.slowest);
            Some(match inner {
                Some(r) => format!("{r}; {slowed}"),
                None => slowed,
            })
        } else {
            inner
        }
    }
    /// The guard's own stepped view when the robot steps: every joint command judged
    /// before it is sent (see [`Stepped for Guarded`](#impl-Stepped-for-Guarded%3CR%3E)).
    fn stepped(&mut self) -> Option<&mut dyn Stepped> {
        let inner = self.robot.stepped()?;
        self.stepping = inner.stepping();
        Some(self)
    }
    /// None: a guarded robot streams only through [`Guarded::stream`], which checks the
    /// movement's nominal plan first (handing out the inner robot's interface would be a
    /// way around the guard).
    fn streaming(&mut self) -> Option<&mut dyn Streaming> {
        None
    }
}

impl<R: Robot> Guarded<R> {
    /// A stepped command refused: what was sent before stands, this one is not sent.
    fn command_refused(&self, reason: Refusal) -> RobotError {
        RobotError::CommandRefused {
            robot: self.robot.name(),
            reason,
        }
    }

    /// The stepped command `q` judged for collisions (number `command`, at `time`).
    fn judge_shapes(&mut self, q: &[f64], time: f64, command: usize) -> Result<(), RobotError> {
        let model = self.robot.model();
        let Some(shapes) = &model.shapes else {
            return Ok(());
        };
        let watch = self
            .shapes
            .get_or_insert_with(|| ShapeWatch::new(shapes.clone(), model.chain.dof()));
        match watch.judge(&model.chain, q, time, command)? {
            Some(c) => Err(self.command_refused(Refusal::Collision(c))),
            None => Ok(()),
        }
    }

    /// The inner robot's stepped interface (the guard hands out only its own).
    fn inner_stepped(&mut self) -> &mut dyn Stepped {
        self.robot
            .stepped()
            .expect("a guarded robot is stepped only when its robot steps")
    }
}

/// A guarded robot stepped one control period at a time (cps's closed-loop executor on a
/// simulator): each joint command is judged with the checks a plan gets — the position
/// range, velocity, acceleration and jerk by backward differences from where the robot
/// stood at rest, torque and torque rate where the robot has inertias — and one that
/// breaks a limit is refused ([`RobotError::CommandRefused`] with the [`Breach`], the robot
/// holding its last command) instead of sent. A step without a new command holds the last one, and is judged as
/// that. A robot that follows tool
/// targets itself (CoppeliaSim's IK) moves its joints on its own: those are the
/// simulator's, not commands cps sends. The commands count from where the robot stands
/// after a plan, a reset or the first command.
impl<R: Robot> Stepped for Guarded<R> {
    fn time(&mut self) -> Result<f64, RobotError> {
        self.inner_stepped().time()
    }
    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), RobotError> {
        if self.watch.is_none() {
            let here = self.robot.joint_positions()?;
            let dt = self.robot.dt();
            self.watch = Some(CommandWatch::new(self.robot.model(), &here, dt));
            if let Some(w) = self.shapes.as_mut() {
                w.restart();
            }
        }
        let command = self.watch.as_ref().expect("just made").commands() + 1;
        self.judge_shapes(q, command as f64 * self.robot.dt(), command)?;
        let watch = self.watch.as_mut().expect("just made");
        if let Err(breach) = watch.judge(self.robot.model(), q) {
            return Err(self.command_refused(Refusal::Limit(breach)));
        }
        self.commanded = true;
        self.inner_stepped().command_joint_positions(q)
    }
    fn step(&mut self) -> Result<(), RobotError> {
        // No new command: the robot holds its last one, and that is a command too.
        if !self.commanded
            && let Some(watch) = self.watch.as_mut()
        {
            let hold = watch.last().to_vec();
            if let Err(breach) = watch.judge(self.robot.model(), &hold) {
                return Err(self.command_refused(Refusal::Limit(breach)));
            }
        }
        self.commanded = false;
        self.inner_stepped().step()
    }
    fn stepping(&self) -> crate::Stepping {
        self.stepping
    }
    fn command_target(&mut self, target: &cps_kinematics::IkTarget) -> Result<(), RobotError> {
        self.inner_stepped().command_target(target)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn septic_peaks_are_its_derivatives_maxima() {
        let n = 200_000;
        let h = 1.0 / n as f64;
        let d1 =
            |t: f64| 140.0 * t.powi(3) - 420.0 * t.powi(4) + 420.0 * t.powi(5) - 140.0 * t.powi(6);
        let d2 =
            |t: f64| 420.0 * t * t - 1680.0 * t.powi(3) + 2100.0 * t.powi(4) - 840.0 * t.powi(5);
        let d3 = |t: f64| 840.0 * t - 5040.0 * t * t + 8400.0 * t.powi(3) - 4200.0 * t.powi(4);
        let peak =
            |f: &dyn Fn(f64) -> f64| (0..=n).map(|k| f(k as f64 * h).abs()).fold(0.0, f64::max);
        assert!((peak(&d1) - SEPTIC_PEAKS[0]).abs() < 1e-4);
        assert!((peak(&d2) - SEPTIC_PEAKS[1]).abs() < 1e-3 && peak(&d2) <= SEPTIC_PEAKS[1]);
        assert!((peak(&d3) - SEPTIC_PEAKS[2]).abs() < 1e-3);
        // s' is d1, checked against a difference of septic.
        assert!((d1(0.3) - (septic(0.3 + 1e-6) - septic(0.3 - 1e-6)) / 2e-6).abs() < 1e-6);
    }
}
