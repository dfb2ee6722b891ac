//! What a robot is asked to do and what it did.
//!
//! A [`Plan`] is joint positions at times `0, dt, 2·dt, …`: the first point is where the
//! robot must stand when the plan starts, the motion between the points is the cubic
//! spline through them that starts and ends at rest ([`Plan::samples`], [`Plan::position_at`]). Every robot runs
//! that motion at its own rate — a Franka samples it every millisecond, a ros2_control
//! controller gets the points with the spline's velocities, the in-process stand-in and a
//! simulator step through the points — and every check judges that motion, sampled every
//! [`CHECK_PERIOD`], whichever robot will run it.
//!
//! A [`Run`] is what the robot did: its measured joints and tool pose at each point's time,
//! how the run ended, and how the guard changed the plan (slowed, approached).

use cps_kinematics::{JointSpline, KinematicsError, PathPoint};
use nalgebra::IsometryMatrix3;

use crate::RobotError;

/// The period every plan's motion is checked at: one millisecond, the command period of
/// the fastest robot cps drives (a Franka), so what is checked is what any robot can see.
pub const CHECK_PERIOD: f64 = 1e-3;

/// The most points a plan may have (an hour at 1 kHz): a bound on what one plan allocates.
pub const MAX_POINTS: usize = 3_600_001;

/// Joint positions at a constant period, from where the robot stands.
///
/// A plan may rest in between: [`Plan::then`] joins two plans at a point where the motion
/// stops (an approach to a trajectory's start, then the trajectory), and each part is its
/// own spline from rest to rest.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    dt: f64,
    points: Vec<Vec<f64>>,
    /// Indices of the points where the motion rests between two parts (ascending, each
    /// inside the plan).
    rests: Vec<usize>,
}

/// A plan's motion sampled at a constant period ([`Plan::motion`]): positions, velocities
/// and accelerations, row-major (sample `i`, joint `j` at `i·dof + j`).
#[derive(Debug, Clone, PartialEq)]
pub struct SampledMotion {
    /// Joints.
    pub dof: usize,
    /// The period between samples (s).
    pub period: f64,
    /// Positions (rad).
    pub q: Vec<f64>,
    /// Velocities (rad/s; zero where the motion holds and at its ends).
    pub dq: Vec<f64>,
    /// Accelerations (rad/s²).
    pub ddq: Vec<f64>,
}

impl SampledMotion {
    /// Samples.
    pub fn len(&self) -> usize {
        self.q.len() / self.dof.max(1)
    }

    /// Whether there is no sample (never, for a plan's motion).
    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }

    /// Sample `i`'s positions, velocities and accelerations.
    pub fn at(&self, i: usize) -> (&[f64], &[f64], &[f64]) {
        let r = i * self.dof..(i + 1) * self.dof;
        (&self.q[r.clone()], &self.dq[r.clone()], &self.ddq[r])
    }
}

impl Plan {
    /// A plan of `points` (one row of joint positions each, radians) every `dt` seconds; the
    /// first is where the robot must stand at the start.
    ///
    /// Errors: `dt` not finite and positive, no points, more than [`MAX_POINTS`], rows of
    /// different lengths, a value that is not finite (the message names its row and joint).
    pub fn new(dt: f64, points: Vec<Vec<f64>>) -> Result<Self, RobotError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(RobotError::Plan(format!(
                "the period between points must be finite and > 0 s (got {dt})"
            )));
        }
        let Some(first) = points.first() else {
            return Err(RobotError::Plan("a plan needs at least one point".into()));
        };
        if points.len() > MAX_POINTS {
            return Err(RobotError::Plan(format!(
                "{} points is more than the {MAX_POINTS} a plan may have",
                points.len()
            )));
        }
        let dof = first.len();
        if dof == 0 {
            return Err(RobotError::Plan("a point has no joints".into()));
        }
        for (k, row) in points.iter().enumerate() {
            if row.len() != dof {
                return Err(RobotError::Plan(format!(
                    "point {k} has {} joint positions, point 0 has {dof}",
                    row.len()
                )));
            }
            if let Some(j) = row.iter().position(|x| !x.is_finite()) {
                return Err(RobotError::Plan(format!(
                    "point {k}, joint {}: {} is not a finite position",
                    j + 1,
                    row[j]
                )));
            }
        }
        Ok(Plan {
            dt,
            points,
            rests: Vec::new(),
        })
    }

    /// A plan that holds `q` (one point): where a robot must be, with nothing to move.
    pub fn hold(dt: f64, q: &[f64]) -> Result<Self, RobotError> {
        Plan::new(dt, vec![q.to_vec()])
    }

    /// Seconds between points.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The points, the first where the robot starts.
    pub fn points(&self) -> &[Vec<f64>] {
        &self.points
    }

    /// Joints per point.
    pub fn dof(&self) -> usize {
        self.points[0].len()
    }

    /// Where the robot must stand at the start.
    pub fn start(&self) -> &[f64] {
        &self.points[0]
    }

    /// Where the plan ends.
    pub fn end(&self) -> &[f64] {
        &self.points[self.points.len() - 1]
    }

    /// Seconds from the first point to the last.
    pub fn duration(&self) -> f64 {
        (self.points.len() - 1) as f64 * self.dt
    }

    /// The time of point `k` (s).
    pub fn time(&self, k: usize) -> f64 {
        k as f64 * self.dt
    }

    /// The points where the motion rests between parts ([`Plan::then`]).
    pub fn rests(&self) -> &[usize] {
        &self.rests
    }

    /// The parts of the plan as ranges of point indices, each from rest to rest (one part
    /// unless the plan was joined with [`Plan::then`]).
    pub fn parts(&self) -> Vec<std::ops::Range<usize>> {
        let mut bounds = vec![0];
        bounds.extend(&self.rests);
        bounds.push(self.points.len() - 1);
        bounds.windows(2).map(|w| w[0]..w[1] + 1).collect()
    }

    /// This plan, then `next` from rest at this plan's end: one plan that stops where the
    /// two meet. `next` must start where this one ends (within 1e-9 rad) and have the same
    /// period.
    pub fn then(&self, next: &Plan) -> Result<Plan, RobotError> {
        if (next.dt - self.dt).abs() > 1e-12 * self.dt {
            return Err(RobotError::Plan(format!(
                "plans every {} s and every {} s cannot be joined",
                self.dt, next.dt
            )));
        }
        next.check_dof(self.dof())?;
        if self
            .end()
            .iter()
            .zip(next.start())
            .any(|(a, b)| (a - b).abs() > 1e-9)
        {
            return Err(RobotError::Plan(
                "a plan joined to another must start where the other ends".into(),
            ));
        }
        let junction = self.points.len() - 1;
        let mut points = self.points.clone();
        points.extend(next.points[1..].iter().cloned());
        let mut rests = self.rests.clone();
        if junction > 0 && next.points.len() > 1 {
            rests.push(junction);
        }
        rests.extend(next.rests.iter().map(|r| r + junction));
        if points.len() > MAX_POINTS {
            return Err(RobotError::Plan(format!(
                "{} points is more than the {MAX_POINTS} a plan may have",
                points.len()
            )));
        }
        Ok(Plan {
            dt: self.dt,
            points,
            rests,
        })
    }

    /// The motion of one part (see [`Plan::parts`]): the cubic spline through its points at
    /// their times, at rest at both ends, its parameter the plan's time (None for a part of
    /// one point, which holds).
    fn part_motion(&self, part: &std::ops::Range<usize>) -> Option<JointSpline> {
        if part.len() < 2 {
            return None;
        }
        let knots: Vec<f64> = part.clone().map(|k| self.time(k)).collect();
        // Strictly increasing, finite knots and finite rows of one length: cannot fail.
        JointSpline::new(&knots, &self.points[part.clone()]).ok()
    }

    /// The joint positions of the motion at time `t` (s, clamped to the plan's span).
    pub fn position_at(&self, t: f64) -> Vec<f64> {
        let t = t.clamp(0.0, self.duration());
        for part in self.parts() {
            if t <= self.time(part.end - 1) + 1e-12 {
                return match self.part_motion(&part) {
                    Some(s) => s.positions(t),
                    None => self.points[part.start].clone(),
                };
            }
        }
        self.end().to_vec()
    }

    /// The motion's positions, velocities, accelerations and jerks at time `t` (s, clamped
    /// to the plan's span; all derivatives zero where it holds).
    pub fn state_at(&self, t: f64) -> PathPoint {
        let t = t.clamp(0.0, self.duration());
        let parts = self.parts();
        let part = parts
            .iter()
            .find(|p| t <= self.time(p.end - 1) + 1e-12)
            .unwrap_or(&parts[parts.len() - 1]);
        match self.part_motion(part) {
            Some(s) => s.point(t),
            None => {
                let n = self.dof();
                PathPoint {
                    q: self.points[part.start].clone(),
                    d1: vec![0.0; n],
                    d2: vec![0.0; n],
                    d3: vec![0.0; n],
                }
            }
        }
    }

    /// The motion sampled every `period` seconds from 0 to the end (the last sample exactly
    /// at the end). Where a sample falls on a point (the plan's period a whole multiple of
    /// `period`), it is the point itself, not the spline's rounding of it.
    pub fn samples(&self, period: f64) -> Vec<Vec<f64>> {
        let span = self.duration();
        if span == 0.0 {
            return vec![self.points[0].clone()];
        }
        let n = (span / period - 1e-9).ceil().max(1.0) as usize;
        let ratio = self.dt / period;
        let per_point = ratio.round();
        let on_knots = per_point >= 1.0 && (ratio - per_point).abs() < 1e-9;
        let parts = self.parts();
        let splines: Vec<Option<JointSpline>> = parts.iter().map(|p| self.part_motion(p)).collect();
        let mut part = 0;
        let mut out = Vec::with_capacity(n + 1);
        for i in 0..=n {
            if on_knots && i % per_point as usize == 0 {
                out.push(self.points[i / per_point as usize].clone());
                continue;
            }
            if i == n {
                out.push(self.end().to_vec());
                continue;
            }
            let t = i as f64 * period;
            while part + 1 < parts.len() && t > self.time(parts[part].end - 1) {
                part += 1;
            }
            out.push(match &splines[part] {
                Some(s) => s.positions(t),
                None => self.points[parts[part].start].clone(),
            });
        }
        out
    }

    /// The motion's positions, velocities and accelerations every `period` seconds from 0
    /// to the end, the last sample exactly at the end (as [`Plan::samples`]): what a robot
    /// that takes positions and their derivatives each control period is fed, computed
    /// once before it moves.
    pub fn motion(&self, period: f64) -> SampledMotion {
        let n = self.dof();
        let span = self.duration();
        let count = if span == 0.0 {
            1
        } else {
            (span / period - 1e-9).ceil().max(1.0) as usize + 1
        };
        let mut out = SampledMotion {
            dof: n,
            period,
            q: self.samples(period).concat(),
            dq: vec![0.0; count * n],
            ddq: vec![0.0; count * n],
        };
        let parts = self.parts();
        let splines: Vec<Option<JointSpline>> = parts.iter().map(|p| self.part_motion(p)).collect();
        let mut part = 0;
        let mut point = PathPoint {
            q: vec![0.0; n],
            d1: vec![0.0; n],
            d2: vec![0.0; n],
            d3: vec![0.0; n],
        };
        for i in 0..count.saturating_sub(1) {
            let t = i as f64 * period;
            while part + 1 < parts.len() && t > self.time(parts[part].end - 1) {
                part += 1;
            }
            if let Some(s) = &splines[part] {
                s.point_into(t, &mut point);
                out.dq[i * n..(i + 1) * n].copy_from_slice(&point.d1);
                out.ddq[i * n..(i + 1) * n].copy_from_slice(&point.d2);
            }
        }
        out
    }

    /// The same path `factor` (≥ 1) times slower: the same points, each `factor` times
    /// later, so velocities shrink by the factor, accelerations by its square and jerks by
    /// its cube.
    pub fn slowed(&self, factor: f64) -> Plan {
        Plan {
            dt: self.dt * factor,
            points: self.points.clone(),
            rests: self.rests.clone(),
        }
    }

    /// The same motion with points every `dt` seconds instead (the last point at the end,
    /// the period shortened so that it falls on a point): what a robot that steps at `dt`
    /// runs of a plan made at another period.
    pub fn resampled(&self, dt: f64) -> Result<Plan, RobotError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(RobotError::Plan(format!(
                "the period between points must be finite and > 0 s (got {dt})"
            )));
        }
        if (self.dt - dt).abs() <= 1e-12 * dt {
            return Ok(self.clone());
        }
        let span = self.duration();
        let n = (span / dt - 1e-9).ceil().max(0.0) as usize;
        if n + 1 > MAX_POINTS {
            return Err(RobotError::Plan(format!(
                "the plan's {span} s every {dt} s would be more than {MAX_POINTS} points"
            )));
        }
        if n == 0 {
            return Plan::new(dt, vec![self.start().to_vec()]);
        }
        let step = span / n as f64;
        let points = (0..=n)
            .map(|k| {
                if k == n {
                    self.end().to_vec()
                } else {
                    self.position_at(k as f64 * step)
                }
            })
            .collect();
        Plan::new(step, points)
    }

    /// Checks the plan is for a robot of `dof` joints.
    pub fn check_dof(&self, dof: usize) -> Result<(), RobotError> {
        if self.dof() != dof {
            return Err(RobotError::Kinematics(KinematicsError::JointCount {
                expected: dof,
                got: self.dof(),
            }));
        }
        Ok(())
    }
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// Every point was run.
    Finished,
    /// A stop was asked for ([`crate::StopToken`]): the robot braked within its limits.
    Stopped,
    /// The robot or its connection failed while moving; what was recorded is kept.
    Failed(String),
}

impl Ending {
    /// Whether every point was run.
    pub fn complete(&self) -> bool {
        matches!(self, Ending::Finished)
    }

    /// The ending in words.
    pub fn sentence(&self) -> String {
        match self {
            Ending::Finished => "the plan ran to its end".into(),
            Ending::Stopped => "stopped on request: the robot braked within its limits".into(),
            Ending::Failed(why) => format!("the run failed: {why}"),
        }
    }
}

/// What a robot did with a plan: one entry per point it reached, at that point's time.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Seconds from the plan's start (entry 0, the first point, at 0; after a slowing, the
    /// slowed times).
    pub time: Vec<f64>,
    /// Measured joint positions (rad).
    pub q: Vec<Vec<f64>>,
    /// The tool's pose in the world frame (the robot's own reading, or its model's forward
    /// kinematics of the measured joints).
    pub tool: Vec<IsometryMatrix3<f64>>,
    /// How it ended (entries stop where it stopped).
    pub ending: Ending,
    /// How many times slower than planned the guard ran it (1 = as planned).
    pub slowing: f64,
    /// Seconds of approach the guard ran before the plan's first point (0 = none).
    pub approach_s: f64,
}

impl Run {
    /// An empty run that ended as `ending`.
    pub fn new(ending: Ending) -> Self {
        Run {
            time: Vec::new(),
            q: Vec::new(),
            tool: Vec::new(),
            ending,
            slowing: 1.0,
            approach_s: 0.0,
        }
    }

    /// Entries recorded.
    pub fn len(&self) -> usize {
        self.time.len()
    }

    /// Whether nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }

    /// Appends one entry.
    pub fn push(&mut self, time: f64, q: Vec<f64>, tool: IsometryMatrix3<f64>) {
        self.time.push(time);
        self.q.push(q);
        self.tool.push(tool);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cosine(dt: f64, n: usize) -> Plan {
        let f = |t: f64, j: usize| {
            0.05 * (j + 1) as f64 * (1.0 - (std::f64::consts::PI * t / 0.1).cos())
        };
        Plan::new(
            dt,
            (0..=n)
                .map(|k| (0..7).map(|j| f(k as f64 * dt, j)).collect())
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn samples_pass_through_every_point_and_follow_the_motion_between() {
        let f = |t: f64, j: usize| {
            0.05 * (j + 1) as f64 * (1.0 - (std::f64::consts::PI * t / 0.1).cos())
        };
        let plan = cosine(0.01, 10);
        let c = plan.samples(CHECK_PERIOD);
        assert_eq!(c.len(), 101);
        for (k, r) in plan.points().iter().enumerate() {
            assert_eq!(c[k * 10].as_slice(), r.as_slice());
        }
        for (i, q) in c.iter().enumerate() {
            for (j, x) in q.iter().enumerate() {
                assert!((x - f(i as f64 * 1e-3, j)).abs() < 1e-4, "ms {i} joint {j}");
            }
        }
        // Slowed twice: twice as long, half the speed, the same ends.
        let slow = plan.slowed(2.0).samples(CHECK_PERIOD);
        assert_eq!(slow.len(), 201);
        assert_eq!(slow[200].as_slice(), plan.end());
        let peak = |c: &[Vec<f64>]| {
            c.windows(2)
                .map(|w| (w[1][6] - w[0][6]).abs())
                .fold(0.0, f64::max)
        };
        assert!((peak(&slow) / peak(&c) - 0.5).abs() < 0.01);
        // Resampled at another period: the same motion, every point on it.
        let fine = plan.resampled(0.002).unwrap();
        assert_eq!(fine.points().len(), 51);
        for (k, p) in fine.points().iter().enumerate() {
            for (j, x) in p.iter().enumerate() {
                assert!((x - f(k as f64 * 0.002, j)).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn the_sampled_motion_carries_the_spline_s_derivatives() {
        // The cosine's velocity and acceleration, which the spline through its points
        // follows.
        let w = std::f64::consts::PI / 0.1;
        let plan = cosine(0.01, 10);
        let m = plan.motion(CHECK_PERIOD);
        assert_eq!(m.len(), 101);
        assert_eq!(m.q, plan.samples(CHECK_PERIOD).concat());
        for i in 1..100 {
            let t = i as f64 * 1e-3;
            let (_, dq, ddq) = m.at(i);
            for j in 0..7 {
                let a = 0.05 * (j + 1) as f64;
                assert!(
                    (dq[j] - a * w * (w * t).sin()).abs() < 0.02 * a * w,
                    "dq {i} {j}"
                );
                assert!((ddq[j] - a * w * w * (w * t).cos()).abs() < 0.1 * a * w * w);
            }
        }
        // From rest to rest.
        assert!(m.at(0).1.iter().chain(m.at(100).1).all(|v| v.abs() < 1e-9));
    }

    #[test]
    fn bad_plans_are_named() {
        let e = Plan::new(0.0, vec![vec![0.0]]).unwrap_err().to_string();
        assert!(e.contains("> 0 s"), "{e}");
        assert!(Plan::new(0.01, vec![]).is_err());
        let e = Plan::new(0.01, vec![vec![0.0, 0.0], vec![0.0]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("point 1 has 1"), "{e}");
        let e = Plan::new(0.01, vec![vec![0.0, 0.0], vec![0.0, f64::NAN]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("point 1, joint 2"), "{e}");
        let one = Plan::hold(0.01, &[1.0, 2.0]).unwrap();
        assert_eq!(one.samples(CHECK_PERIOD), vec![vec![1.0, 2.0]]);
        assert_eq!(one.duration(), 0.0);
    }
}
