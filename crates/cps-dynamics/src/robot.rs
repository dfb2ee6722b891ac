//! [`DynamicsRobot`]: the simulated arm as a cps robot. Every control period (1 ms by
//! default) its controller reads the joints (with seeded noise if asked), computes its
//! torques, the drives clip them, gravity is cancelled, and the arm is integrated one
//! step. It runs plans ([`Robot::run`]: the plan's motion sampled at the control period is
//! the controller's target), steps ([`Stepped`]: the commanded positions interpolated over
//! each step) and streams ([`Streaming`]).

use cps_robot::{
    CycleLoss, Ending, Generator, LinkBreak, LossyLink, Plan, RateCheck, Robot, RobotError,
    RobotModel, Run, Stepped, Stepping, StopToken, Streaming,
};
use nalgebra::{Isometry3, IsometryMatrix3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::arm::Arm;
use crate::controller::{Controller, Desired};

/// How a [`DynamicsRobot`] runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicsSettings<const N: usize> {
    /// The joint-level controller.
    pub controller: Controller<N>,
    /// The control and integration period (s): 0.001, a Franka's.
    pub control_period: f64,
    /// The period plans are made at (s).
    pub dt: f64,
    /// Measurement noise: the standard deviation of what each joint reads (rad, 0: none).
    pub noise: f64,
    /// The noise's seed: every run draws the same noise from it, so a plan's result does
    /// not depend on which robot of a pool ran it or what ran before.
    pub seed: u64,
    /// Whether a joint leaving its position range stops the arm, as a real arm's reflex
    /// does (the run brakes and ends failed, saying which joint and where). Off only where
    /// a learner judges candidates by what the arm does, its limits in the cost.
    pub reflexes: bool,
    /// How many control periods old the command the controller acts on is (0 to
    /// [`MAX_LAG`]): a real arm's command reaches its controller late.
    pub lag: usize,
}

/// The longest command lag a dynamics robot simulates (control periods).
pub const MAX_LAG: usize = 7;

/// How far beyond a joint's published range its reflex fires (rad). Plans keep the
/// published range; a real arm's reflex fires at its hardware limits a little beyond it,
/// so an arm resting at a limit (the thesis's Panda start has joint 4 there) is not stopped
/// by the controller's micro-radians of settling.
pub const REFLEX_MARGIN: f64 = 5e-3;

/// How long a stop may take to bring the arm to rest before the run ends anyway (s).
const BRAKE_WITHIN: f64 = 2.0;
/// The speed below which a braking arm counts as at rest (rad/s).
const AT_REST: f64 = 1e-3;

/// A robot arm with dynamics, driven by its joint-level controller.
#[derive(Debug, Clone)]
pub struct DynamicsRobot<const N: usize> {
    model: RobotModel,
    arm: Arm<N>,
    settings: DynamicsSettings<N>,
    rng: ChaCha8Rng,
    noise: Option<Normal<f64>>,
    time: f64,
    /// The stepped interface's last two commands.
    command: [f64; N],
    previous: [f64; N],
    /// Control periods simulated, and those where a drive's torque was clipped.
    ticks: u64,
    clipped: u64,
    /// The joints' position range, when the model has one and reflexes are on.
    range: Option<([f64; N], [f64; N])>,
    /// The last `MAX_LAG + 1` targets (positions, velocities, accelerations), the newest
    /// at `head − 1`: the controller acts on the one `lag` periods older.
    targets: [[[f64; N]; 3]; MAX_LAG + 1],
    head: usize,
    /// The torques the drives applied in the last control period (gravity included).
    applied: [f64; N],
    /// Control periods it loses on purpose while streaming ([`DynamicsRobot::lose_cycles`]).
    loss: Option<CycleLoss>,
    /// Periods lost so far, and streamed commands limited after one.
    lost: u64,
    limited: usize,
}

fn pose(p: &Isometry3<f64>) -> IsometryMatrix3<f64> {
    IsometryMatrix3::from_parts(p.translation, p.rotation.to_rotation_matrix())
}

impl<const N: usize> DynamicsRobot<N> {
    /// The robot `model` (kinematics, names, limits) simulated as `arm` under `settings`.
    /// Errors: a model of another joint count, periods that are not finite and positive, a
    /// plan period that is not a whole number of control periods, noise that is negative
    /// or not finite.
    pub fn new(
        model: RobotModel,
        arm: Arm<N>,
        settings: DynamicsSettings<N>,
    ) -> Result<Self, RobotError> {
        let bad = |m: String| RobotError::Robot {
            robot: "the dynamics robot".into(),
            message: m,
        };
        if model.chain.dof() != N {
            return Err(bad(format!(
                "the model {} has {} joints, the dynamics {N}",
                model.name,
                model.chain.dof()
            )));
        }
        let (period, dt) = (settings.control_period, settings.dt);
        if !(period.is_finite() && period > 0.0 && dt.is_finite() && dt > 0.0) {
            return Err(bad(format!(
                "the control period ({period} s) and the plans' period ({dt} s) must be finite and > 0"
            )));
        }
        let ratio = dt / period;
        if (ratio - ratio.round()).abs() > 1e-9 || ratio.round() < 1.0 {
            return Err(bad(format!(
                "the plans' period {dt} s must be a whole number of control periods ({period} s)"
            )));
        }
        if settings.lag > MAX_LAG {
            return Err(bad(format!(
                "a command lag of {} control periods is more than the {MAX_LAG} simulated",
                settings.lag
            )));
        }
        if !(settings.noise.is_finite() && settings.noise >= 0.0) {
            return Err(bad(format!(
                "measurement noise {} rad must be finite and ≥ 0",
                settings.noise
            )));
        }
        let noise = (settings.noise > 0.0)
            .then(|| Normal::new(0.0, settings.noise).expect("a finite positive deviation"));
        let q = arm.q;
        let range = model
            .chain
            .limits()
            .filter(|_| settings.reflexes)
            .map(|(lo, hi)| {
                (
                    std::array::from_fn(|i| lo[i]),
                    std::array::from_fn(|i| hi[i]),
                )
            });
        Ok(DynamicsRobot {
            model,
            arm,
            settings,
            rng: ChaCha8Rng::seed_from_u64(settings.seed),
            noise,
            time: 0.0,
            command: q,
            previous: q,
            ticks: 0,
            clipped: 0,
            range,
            targets: [[q, [0.0; N], [0.0; N]]; MAX_LAG + 1],
            head: 0,
            applied: [0.0; N],
            loss: None,
            lost: 0,
            limited: 0,
        })
    }

    /// Makes it lose `share` (0 to [`cps_robot::MAX_LOSS`]) of its control periods while
    /// streaming, chosen by `seed` — a test option: its commanded reference is then
    /// extrapolated at constant acceleration through each, as a Franka's is, and every
    /// command it gets is judged against that reference by its model's limits (a breach
    /// would be a Franka's discontinuity reflex: the run fails); the stream reaches it
    /// through cps's limiter ([`cps_robot::LossyLink`]), as the Franka's loop sends it.
    pub fn lose_cycles(&mut self, share: f64, seed: u64) -> Result<(), RobotError> {
        let loss = CycleLoss::new(share, seed).map_err(|source| RobotError::Setting {
            robot: self.name(),
            source,
        })?;
        self.loss = (share > 0.0).then_some(loss);
        Ok(())
    }

    /// The simulated arm (its true state).
    pub fn arm(&self) -> &Arm<N> {
        &self.arm
    }

    /// The torques the drives applied in the last control period, gravity included (what
    /// a Franka reports as `tau_J`).
    pub fn applied_torques(&self) -> [f64; N] {
        self.applied
    }

    /// What the joints read now: the true positions, plus noise when asked for.
    fn measured(&mut self) -> [f64; N] {
        let mut q = self.arm.q;
        if let Some(n) = &self.noise {
            for x in &mut q {
                *x += n.sample(&mut self.rng);
            }
        }
        q
    }

    /// One control period towards `desired` (or, with a lag, towards the target given
    /// `lag` periods ago).
    fn tick(&mut self, desired: Desired<'_>) {
        let lag = self.settings.lag;
        if lag > 0 {
            let slot = &mut self.targets[self.head];
            slot[0].copy_from_slice(desired.q);
            slot[1].copy_from_slice(desired.dq);
            slot[2].copy_from_slice(desired.ddq);
            self.head = (self.head + 1) % (MAX_LAG + 1);
            let old = self.targets[(self.head + MAX_LAG - lag) % (MAX_LAG + 1)];
            return self.tick_towards(Desired {
                q: &old[0],
                dq: &old[1],
                ddq: &old[2],
            });
        }
        self.tick_towards(desired);
    }

    /// Forgets the targets given so far: the arm holds `q` until new ones are `lag` old.
    fn hold_targets(&mut self, q: [f64; N]) {
        self.targets = [[q, [0.0; N], [0.0; N]]; MAX_LAG + 1];
    }

    /// One control period towards `desired`, now.
    fn tick_towards(&mut self, desired: Desired<'_>) {
        let measured = self.measured();
        let seen = self.arm.model.frames(&measured);
        let command =
            self.settings
                .controller
                .torques(&self.arm.model, &seen, &self.arm.dq, desired);
        let limited = self.arm.clip(&command);
        let truth = if self.noise.is_some() {
            self.arm.model.frames(&self.arm.q)
        } else {
            seen
        };
        // The robot cancels gravity itself (with its model, at what it measures).
        let gravity = self.arm.model.gravity(&seen);
        let total: [f64; N] = std::array::from_fn(|i| limited[i] + gravity[i]);
        let applied = self.arm.clip(&total);
        if applied != total || limited != command {
            self.clipped += 1;
        }
        self.applied = applied;
        self.arm
            .step(&truth, &applied, self.settings.control_period);
        self.time += self.settings.control_period;
        self.ticks += 1;
    }

    /// The reflex's sentence when a joint has left its position range.
    fn out_of_range(&self) -> Option<String> {
        let (lo, hi) = self.range.as_ref()?;
        let j = (0..N).find(|&j| {
            self.arm.q[j] < lo[j] - REFLEX_MARGIN || self.arm.q[j] > hi[j] + REFLEX_MARGIN
        })?;
        Some(format!(
            "reflex: joint {} reached {:.4} rad at {:.3} s, beyond its range [{:.4}, {:.4}] rad; the arm braked to rest",
            j + 1,
            self.arm.q[j],
            self.time,
            lo[j],
            hi[j]
        ))
    }

    fn entry(&self) -> (Vec<f64>, IsometryMatrix3<f64>) {
        let f = self.arm.model.frames(&self.arm.q);
        (self.arm.q.to_vec(), pose(&f.tool))
    }

    /// Holds where the arm is when a stop comes until it is at rest (at most
    /// [`BRAKE_WITHIN`]).
    /// Brakes to rest (within [`BRAKE_WITHIN`]) and returns the time it took (s).
    fn brake(&mut self) -> f64 {
        let hold = self.arm.q;
        let zero = [0.0; N];
        let mut t = 0.0;
        while t < BRAKE_WITHIN && self.arm.dq.iter().any(|v| v.abs() > AT_REST) {
            self.tick(Desired {
                q: &hold,
                dq: &zero,
                ddq: &zero,
            });
            t += self.settings.control_period;
        }
        self.command = self.arm.q;
        self.previous = self.arm.q;
        t
    }

    /// Brakes, and records where the arm came to rest: at `at` plus the braking time,
    /// unless the recording already holds that instant (an arm already at rest), so no
    /// two entries of a recording share a time.
    fn brake_into(&mut self, run: &mut Run, at: f64) {
        let t = at + self.brake();
        if run.time.last().is_none_or(|&last| t > last) {
            let (q, tool) = self.entry();
            run.push(t, q, tool);
        }
    }

    fn ticks_per_step(&self) -> usize {
        (self.settings.dt / self.settings.control_period).round() as usize
    }
}

impl<const N: usize> Robot for DynamicsRobot<N> {
    fn name(&self) -> String {
        format!("the dynamics robot ({})", self.settings.controller.name())
    }

    fn model(&self) -> &RobotModel {
        &self.model
    }

    fn dt(&self) -> f64 {
        self.settings.dt
    }

    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        Ok(self.arm.q.to_vec())
    }

    /// The tool's pose from the arm's own frames (what its recordings hold).
    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, RobotError> {
        Ok(self.entry().1)
    }

    /// Its control period: it follows the plan's motion sampled at it.
    fn command_period(&self) -> f64 {
        self.settings.control_period
    }

    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
        plan.check_dof(N)?;
        self.rng = ChaCha8Rng::seed_from_u64(self.settings.seed);
        let motion = plan.motion(self.settings.control_period);
        let per_point = plan.dt() / self.settings.control_period;
        let _moving = stop.moving(); // from the first tick to the last
        let mut run = Run::new(Ending::Finished);
        let points = plan.points().len();
        let mut next = 0;
        for i in 0..motion.len() {
            let t = i as f64 * self.settings.control_period;
            while next < points && ((next as f64 * per_point).round() as usize) <= i {
                let (q, tool) = self.entry();
                run.push(plan.time(next), q, tool);
                next += 1;
            }
            if i + 1 == motion.len() {
                break;
            }
            if stop.is_stopped() {
                self.brake_into(&mut run, t);
                run.ending = Ending::Stopped;
                return Ok(run);
            }
            let (q, dq, ddq) = motion.at(i);
            self.tick(Desired { q, dq, ddq });
            if let Some(reflex) = self.out_of_range() {
                self.brake_into(&mut run, t + self.settings.control_period);
                run.ending = Ending::Failed(reflex);
                return Ok(run);
            }
        }
        // The points the last control period reached (a plan shorter than one period).
        while next < points {
            let (q, tool) = self.entry();
            run.push(plan.time(next), q, tool);
            next += 1;
        }
        self.command = self.arm.q;
        self.previous = self.arm.q;
        Ok(run)
    }

    /// Puts the arm at rest at `q`; with reflexes on, refuses a `q` beyond the joints'
    /// range (a real arm cannot be there).
    fn teleport(&mut self, q: &[f64]) -> Result<bool, RobotError> {
        let q: [f64; N] = q.try_into().map_err(|_| RobotError::Robot {
            robot: self.name(),
            message: format!("{} joint positions given, the arm has {N}", q.len()),
        })?;
        if let Some((lo, hi)) = &self.range
            && let Some(j) =
                (0..N).find(|&j| q[j] < lo[j] - REFLEX_MARGIN || q[j] > hi[j] + REFLEX_MARGIN)
        {
            return Err(RobotError::Robot {
                robot: self.name(),
                message: format!(
                    "cannot be put at rest with joint {} at {:.4} rad, beyond its range [{:.4}, {:.4}] rad: a real arm cannot be there (a scene's initial configuration outside the robot's range?)",
                    j + 1,
                    q[j],
                    lo[j],
                    hi[j]
                ),
            });
        }
        self.arm.q = q;
        self.arm.dq = [0.0; N];
        self.hold_targets(q);
        self.command = q;
        self.previous = q;
        self.time = 0.0;
        Ok(true)
    }

    fn report(&self) -> Option<String> {
        (self.ticks > 0).then(|| {
            let mut text = format!(
                "{} control periods simulated ({}), a drive's torque clipped in {}",
                self.ticks,
                self.settings.controller.name(),
                self.clipped
            );
            if self.loss.is_some() {
                text.push_str(&format!(
                    "; {} periods lost on purpose while streaming, {} commands limited after one",
                    self.lost, self.limited
                ));
            }
            text
        })
    }

    fn stepped(&mut self) -> Option<&mut dyn Stepped> {
        Some(self)
    }

    fn streaming(&mut self) -> Option<&mut dyn Streaming> {
        Some(self)
    }
}

impl<const N: usize> Stepped for DynamicsRobot<N> {
    /// Whole plans: an arm with dynamics runs in time. Its controller's commands are
    /// planned on the model and the arm follows them as a real arm does — iterating a
    /// sample until a lagging arm reaches it would stretch the movement's time.
    fn stepping(&self) -> Stepping {
        Stepping::Plans
    }

    fn time(&mut self) -> Result<f64, RobotError> {
        Ok(self.time)
    }

    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), RobotError> {
        self.command = q.try_into().map_err(|_| RobotError::Robot {
            robot: self.name(),
            message: format!("{} joint positions commanded, the arm has {N}", q.len()),
        })?;
        Ok(())
    }

    /// One step of the plans' period: the command reached from the last one along a
    /// straight line, one control period at a time.
    fn step(&mut self) -> Result<(), RobotError> {
        let ticks = self.ticks_per_step();
        let (from, to) = (self.previous, self.command);
        let velocity: [f64; N] = std::array::from_fn(|i| (to[i] - from[i]) / self.settings.dt);
        let zero = [0.0; N];
        for k in 1..=ticks {
            let s = k as f64 / ticks as f64;
            let q: [f64; N] = std::array::from_fn(|i| from[i] + s * (to[i] - from[i]));
            self.tick(Desired {
                q: &q,
                dq: &velocity,
                ddq: &zero,
            });
            if let Some(reflex) = self.out_of_range() {
                let _ = self.brake();
                return Err(RobotError::Robot {
                    robot: self.name(),
                    message: reflex,
                });
            }
        }
        self.previous = to;
        Ok(())
    }
}

impl<const N: usize> Streaming for DynamicsRobot<N> {
    fn stream(
        &mut self,
        next: &mut Generator<'_>,
        max_commands: usize,
        stop: &StopToken,
    ) -> Result<Run, RobotError> {
        self.rng = ChaCha8Rng::seed_from_u64(self.settings.seed);
        let mut run = Run::new(Ending::Finished);
        let (q, tool) = self.entry();
        run.push(0.0, q, tool);
        let period = self.settings.control_period;
        let mut command = self.arm.q.to_vec();
        let mut previous = self.arm.q;
        let zero = [0.0; N];
        let mut link = self
            .loss
            .map(|loss| LossyLink::new(loss, RateCheck::of_model(&self.model, period, self.arm.q)));
        for k in 0.. {
            if stop.is_stopped() {
                self.brake_into(&mut run, k as f64 * period);
                run.ending = Ending::Stopped;
                break;
            }
            if k == max_commands {
                self.brake_into(&mut run, k as f64 * period);
                run.ending =
                    Ending::Failed(format!("{max_commands} commands were not enough to finish"));
                break;
            }
            let measured = self.measured();
            let seen = cps_robot::Measured {
                q: &measured,
                dq: &self.arm.dq,
                tau: &self.applied,
            };
            let last = next(&seen, k as f64 * period, &mut command);
            let target: [f64; N] =
                command
                    .as_slice()
                    .try_into()
                    .map_err(|_| RobotError::Robot {
                        robot: self.name(),
                        message: format!(
                            "{} joint positions commanded, the arm has {N}",
                            command.len()
                        ),
                    })?;
            if let Some(link) = &mut link {
                // Through a link that loses periods: the arm follows what the robot holds.
                match link.step(&target, last) {
                    Ok(r) => {
                        let r = *r;
                        self.tick(Desired {
                            q: &r.q,
                            dq: &r.v,
                            ddq: &r.a,
                        });
                    }
                    Err(b) => {
                        self.brake_into(&mut run, k as f64 * period);
                        run.ending = Ending::Failed(match b {
                            LinkBreak::Refused(b) => format!(
                                "a command beyond a limit was not sent ({b}); the arm braked to rest"
                            ),
                            LinkBreak::Reflex(b) => format!(
                                "reflex: a command broke a limit against the reference the robot held after a lost period ({b}); the arm braked to rest"
                            ),
                        });
                        break;
                    }
                }
            } else {
                let velocity: [f64; N] =
                    std::array::from_fn(|i| (target[i] - previous[i]) / period);
                self.tick(Desired {
                    q: &target,
                    dq: &velocity,
                    ddq: &zero,
                });
            }
            previous = target;
            let (q, tool) = self.entry();
            run.push((k + 1) as f64 * period, q, tool);
            if let Some(reflex) = self.out_of_range() {
                self.brake_into(&mut run, (k + 1) as f64 * period);
                run.ending = Ending::Failed(reflex);
                break;
            }
            if last {
                break;
            }
        }
        if let Some(link) = link {
            self.lost += link.lost();
            self.limited += link.limited().commands;
        }
        self.command = self.arm.q;
        self.previous = self.arm.q;
        Ok(run)
    }
}
