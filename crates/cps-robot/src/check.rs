//! A plan judged against a robot's limits: its motion sampled as the robot receives it —
//! every [`CHECK_PERIOD`](crate::CHECK_PERIOD) for a robot that interpolates it, at its step
//! for one that steps through it ([`crate::Robot::command_period`]) — differentiated as a
//! controller that receives positions does (backward differences, at rest before the first sample and after the
//! last), torques by inverse dynamics where the model has inertias, and the tool's
//! Cartesian motion where it has Cartesian limits
//! ([`cps_kinematics::check_commands`]). One check for every robot: the same plan gets
//! the same verdict, in the same words, whichever robot it is for.

pub use cps_kinematics::OUTSIDE_SLACK;
use cps_kinematics::{CommandCheck, Excess, Held, Quantity, beyond_allowed, check_commands};

use crate::plan::Plan;
use crate::{RobotError, RobotModel};

/// What a breach is of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Limit {
    /// A joint's quantity (1-based joint).
    Joint {
        /// 1-based joint number.
        joint: usize,
        /// Position, velocity, acceleration, jerk, torque or torque rate.
        quantity: Quantity,
    },
    /// The tool's (or the elbow's) Cartesian motion: one of
    /// [`cps_kinematics::CARTESIAN_QUANTITIES`].
    Tool(&'static str),
    /// A robot's own rule on its commands beyond these (a Franka's distance to stop inside
    /// its range), in words, for 1-based `joint`.
    Robot {
        /// 1-based joint number.
        joint: usize,
        /// The rule, e.g. `stopping distance`.
        rule: &'static str,
    },
}

/// The first place where a plan's motion passes a limit — or, where a robot checks each
/// command as it goes (the Franka's 1 kHz loop), the first command that would: one type
/// for both, `Copy`, made without allocating. A `value` that is not a number is worded as
/// such.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Breach {
    /// What is passed.
    pub limit: Limit,
    /// When (s from the plan's start), at the worst sample of the run of samples beyond it.
    pub time: f64,
    /// Which command that is, counted from 0 at the plan's start in the robot's command
    /// period.
    pub command: usize,
    /// The value there (signed for joints).
    pub value: f64,
    /// The limit it passes (for positions, the bound).
    pub bound: f64,
}

fn unit(quantity: &str) -> &'static str {
    let order = if quantity.ends_with("velocity") {
        1
    } else if quantity.ends_with("acceleration") {
        2
    } else {
        3
    };
    match (quantity.starts_with("translation"), order) {
        (true, 1) => "m/s",
        (true, 2) => "m/s²",
        (true, _) => "m/s³",
        (false, 1) => "rad/s",
        (false, 2) => "rad/s²",
        (false, _) => "rad/s³",
    }
}

impl std::fmt::Display for Breach {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (t, c) = (self.time, self.command);
        if !self.value.is_finite() {
            let (place, what) = match &self.limit {
                Limit::Joint { joint, quantity } => (format!("joint {joint}"), quantity.name()),
                Limit::Tool(q) => ("the tool".to_string(), *q),
                Limit::Robot { joint, .. } => (format!("joint {joint}"), "position"),
            };
            return write!(
                f,
                "{place} at t = {t:.3} s (command {c}): the commanded {} is not a number",
                what.replace('_', " ")
            );
        }
        match &self.limit {
            Limit::Joint {
                joint,
                quantity: Quantity::Position,
            } => write!(
                f,
                "joint {joint} at t = {t:.3} s (command {c}): position {:.6} rad beyond the limit {:.6} rad",
                self.value, self.bound
            ),
            Limit::Joint { joint, quantity } => write!(
                f,
                "joint {joint} at t = {t:.3} s (command {c}): {} {:.6} {} beyond the limit {:.6} {}",
                quantity.name().replace('_', " "),
                self.value,
                quantity.unit(),
                self.bound,
                quantity.unit()
            ),
            Limit::Tool(q) => write!(
                f,
                "the {} at t = {t:.3} s (command {c}): {} {:.6} {} beyond the limit {:.6} {}",
                if q.starts_with("elbow") {
                    "elbow"
                } else {
                    "tool"
                },
                q.replace('_', " "),
                self.value,
                unit(q),
                self.bound,
                unit(q)
            ),
            Limit::Robot { joint, rule } => write!(
                f,
                "joint {joint} at t = {t:.3} s (command {c}): {rule} {:.6} rad, beyond the limit {:.6} rad",
                self.value, self.bound
            ),
        }
    }
}

/// A command the one limit checker ([`cps_kinematics::StreamCheck`]) refused, as the
/// contract words it.
impl From<Excess> for Breach {
    fn from(e: Excess) -> Self {
        let joint = e.judged.joint;
        Breach {
            limit: match e.judged.held {
                Held::Quantity(quantity) => Limit::Joint { joint, quantity },
                Held::Rule(rule) => Limit::Robot { joint, rule },
            },
            time: e.time,
            command: e.command,
            value: e.judged.value,
            bound: e.judged.bound,
        }
    }
}

impl Breach {
    /// How many times slower the plan must run for this breach to go, at least (velocities
    /// shrink with the slowing, accelerations with its square, jerks with its cube; the
    /// dynamic part of a torque like an acceleration); None where no slowing can help (a
    /// position out of range, a value that is not a number).
    pub fn slowing_needed(&self) -> Option<f64> {
        if !self.value.is_finite() {
            return None;
        }
        let ratio = (self.value / self.bound).abs().max(1.0);
        let order = match &self.limit {
            Limit::Joint { quantity, .. } => match quantity {
                Quantity::Position => return None,
                Quantity::Velocity => 1.0,
                Quantity::Acceleration | Quantity::Torque | Quantity::TorqueRate => 2.0,
                Quantity::Jerk => 3.0,
            },
            Limit::Tool(q) if q.ends_with("velocity") => 1.0,
            Limit::Tool(q) if q.ends_with("acceleration") => 2.0,
            Limit::Tool(_) => 3.0,
            Limit::Robot { .. } => return Some(1.25),
        };
        Some(ratio.powf(1.0 / order))
    }
}

/// A plan's verdict: the peak usage of each limit, and the first breach if any.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// Per quantity and joint, and for the tool: the peak usage in percent.
    pub usage: CommandCheck,
    /// The earliest breach (None: every limit holds).
    pub breach: Option<Breach>,
}

/// Checks `plan`'s motion, sampled every `period` (the robot's
/// [`command_period`](crate::Robot::command_period)), against every limit of `model`.
///
/// A joint that starts outside its range (a scene's start may: the thesis's Panda has
/// joint 4 above its bound) may move back towards it: only going further out than where it
/// started (by more than [`OUTSIDE_SLACK`]) is a breach.
pub fn check(model: &RobotModel, plan: &Plan, period: f64) -> Result<Verdict, RobotError> {
    plan.check_dof(model.chain.dof())?;
    let samples = plan.samples(period);
    let usage = check_commands(&model.robot_limits(), 0.0, period, &samples)?;
    let start = plan.start();
    let mut breaches: Vec<Breach> = usage
        .joints
        .violations
        .iter()
        .filter(|v| {
            if v.quantity != Quantity::Position {
                return true;
            }
            !beyond_allowed(start[v.joint - 1], v.value, v.limit)
        })
        .map(|v| Breach {
            limit: Limit::Joint {
                joint: v.joint,
                quantity: v.quantity,
            },
            time: v.time,
            command: (v.time / period).round() as usize,
            value: v.value,
            bound: v.limit,
        })
        .collect();
    if let Some(c) = &usage.cartesian {
        breaches.extend(c.violations.iter().map(|v| Breach {
            limit: Limit::Tool(v.quantity),
            time: v.time,
            command: (v.time / period).round() as usize,
            value: v.value,
            bound: v.limit,
        }));
    }
    let breach = breaches
        .into_iter()
        .min_by(|a, b| a.time.total_cmp(&b.time));
    Ok(Verdict { usage, breach })
}

impl Verdict {
    /// The largest usage (percent) of velocity, acceleration and jerk over the joints.
    pub fn peak_joint_usage(&self) -> [f64; 3] {
        let mut out = [0.0f64; 3];
        for (q, per_joint) in &self.usage.joints.peak_usage {
            let k = match q {
                Quantity::Velocity => 0,
                Quantity::Acceleration => 1,
                Quantity::Jerk => 2,
                _ => continue,
            };
            out[k] = per_joint.iter().fold(out[k], |a, &b| a.max(b));
        }
        out
    }
}
