//! Collision-free motion between two configurations of a robot: around the robot itself
//! and its scene's obstacles, at the guard's margin, on the very shapes the guard checks.
//!
//! [`plan`] searches a path with RRT-Connect (two trees, one from each end), checks every
//! straight segment of it exactly by conservative advancement (no configuration between
//! samples is skipped: the bodies' motion along a segment is bounded in advance), shortens
//! it, times each segment as a rest-to-rest move within the robot's velocity, acceleration
//! and jerk limits, and verifies the timed motion as the guard verifies any plan — every
//! limit and every pair at the control period — before returning it. The same seed gives
//! the same path.
//!
//! ```
//! use cps_plan::{Settings, plan};
//! let fr3 = cps_robot::RobotModel::of_chain(
//!     "fr3",
//!     cps_kinematics::robots::fr3(cps_kinematics::robots::PandaTool::HandTcp),
//! );
//! let (from, to) = ([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8], [0.5, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8]);
//! let planned = plan(&fr3, &from, &to, &Settings::default())?;
//! assert_eq!(planned.waypoints, vec![from.to_vec(), to.to_vec()]);
//! # Ok::<(), cps_plan::PlanError>(())
//! ```
#![deny(missing_docs)]

mod free;
mod join;
mod rrt;

use std::time::Instant;

use cps_robot::{Plan, RobotModel, SplitMix};
pub use join::{JoinError, Joined, Part, Stretch, join};
pub use rrt::Tried;

/// How a path is searched and timed.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The seed of the random configurations: the same seed, the same path.
    pub seed: u64,
    /// The most random configurations drawn before giving up.
    pub samples: usize,
    /// The longest step a tree takes towards a sample (rad, Euclidean over the joints).
    pub reach: f64,
    /// Attempts at joining two points of the path directly.
    pub shortcuts: usize,
    /// The share of the robot's velocity, acceleration and jerk limits each segment is
    /// timed at.
    pub share: f64,
    /// The control period the motion is sampled, timed and verified at (s).
    pub dt: f64,
}

impl Default for Settings {
    /// Seed 1, 20 000 samples, steps of 1 rad, 20 shortcuts, half the limits, 1 ms. (On
    /// the benchmark, steps of 0.5, 1 and 2 rad: medians of 7.5, 5.3 and 4.1 ms, paths 1–6 %
    /// shorter and 7–20 % longer than at 1 rad; 50 shortcuts instead of 20: 1.5 times the
    /// time, lengths within 2 %.)
    fn default() -> Self {
        Settings {
            seed: 1,
            samples: 20_000,
            reach: 1.0,
            shortcuts: 20,
            share: 0.5,
            dt: 0.001,
        }
    }
}

impl Settings {
    /// The settings checked, once for every caller: the share of the limits in (0, 1], a
    /// step and a control period positive and finite.
    pub fn check(&self) -> Result<(), PlanError> {
        let bad = |setting, rule, value| PlanError::Setting {
            setting,
            rule,
            value,
        };
        if !(self.share > 0.0 && self.share <= 1.0) {
            return Err(bad("share", "a share of the limits in (0, 1]", self.share));
        }
        if !(self.reach.is_finite() && self.reach > 0.0) {
            return Err(bad(
                "reach",
                "a step in radians, finite and positive",
                self.reach,
            ));
        }
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(bad(
                "dt",
                "a control period in seconds, finite and positive",
                self.dt,
            ));
        }
        Ok(())
    }
}

/// Which end of the path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    /// Where the path starts.
    Start,
    /// Where it ends.
    Goal,
}

impl std::fmt::Display for End {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            End::Start => "start",
            End::Goal => "goal",
        })
    }
}

/// Why no path is returned.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// A configuration with the wrong number of joints.
    #[error("the {end} has {got} joint values; the robot has {expected} joints")]
    JointCount {
        /// Which end.
        end: End,
        /// The robot's joints.
        expected: usize,
        /// The values given.
        got: usize,
    },
    /// A value that is not a finite number.
    #[error("the {end}'s joint {joint} is not a finite number")]
    NotFinite {
        /// Which end.
        end: End,
        /// The joint (1-based).
        joint: usize,
    },
    /// A joint outside its range.
    #[error(
        "the {end}'s joint {joint} = {value:.4} rad is outside its range [{lower:.4}, {upper:.4}]"
    )]
    OutOfRange {
        /// Which end.
        end: End,
        /// The joint (1-based).
        joint: usize,
        /// Its value.
        value: f64,
        /// Its range's lower end.
        lower: f64,
        /// Its range's upper end.
        upper: f64,
    },
    /// An end where two shapes come within the margin.
    #[error("the {end} is in collision: `{first}` and `{second}` {}", words(*.distance, *.margin))]
    InCollision {
        /// Which end.
        end: End,
        /// A link.
        first: String,
        /// A link or an obstacle.
        second: String,
        /// Their signed distance (m).
        distance: f64,
        /// The margin (m).
        margin: f64,
    },
    /// No path within the samples.
    #[error(
        "no collision-free path found within {} random configurations (trees of {} and {} nodes grown from the start and the goal): the way may be closed, or narrow — raise the samples, or choose another seed",
        .tried.samples, .tried.nodes[0], .tried.nodes[1]
    )]
    NoPath {
        /// What was tried.
        tried: Tried,
    },
    /// A setting out of its range ([`Settings::check`]).
    #[error("{setting}: {rule} (got {value})")]
    Setting {
        /// The setting's name.
        setting: &'static str,
        /// What it must be.
        rule: &'static str,
        /// What it is.
        value: f64,
    },
    /// A goal pose no configuration within the ranges reaches.
    #[error("the goal pose is out of reach: {0}")]
    Unreachable(String),
    /// The timed motion failed the guard's own check (a defect of the planner).
    #[error("the planned motion failed the guard's check: {0}")]
    Unverified(String),
    /// The robot's model could not be used.
    #[error(transparent)]
    Robot(#[from] cps_robot::RobotError),
    /// Kinematics failed.
    #[error(transparent)]
    Kinematics(#[from] cps_kinematics::KinematicsError),
}

impl PlanError {
    /// The end a bad input is at (None: not an end's fault).
    pub fn end(&self) -> Option<End> {
        match self {
            PlanError::JointCount { end, .. }
            | PlanError::NotFinite { end, .. }
            | PlanError::OutOfRange { end, .. }
            | PlanError::InCollision { end, .. } => Some(*end),
            _ => None,
        }
    }

    /// Whether what was given is at fault (an end or a setting), not the search.
    pub fn is_input(&self) -> bool {
        self.end().is_some() || matches!(self, PlanError::Setting { .. })
    }
}

fn words(distance: f64, margin: f64) -> String {
    if distance < 0.0 {
        format!("are {:.1} mm deep in each other", -1e3 * distance)
    } else {
        format!(
            "come {:.1} mm apart, within the clearance margin of {:.1} mm",
            1e3 * distance,
            1e3 * margin
        )
    }
}

/// A path found, timed and verified.
#[derive(Debug, Clone)]
pub struct Planned {
    /// Its corners: the start, the points it turns at, the goal.
    pub waypoints: Vec<Vec<f64>>,
    /// The timed motion, every control period, at rest at each corner.
    pub plan: Plan,
    /// Its length in joint space (rad, Euclidean, summed over the segments).
    pub length: f64,
    /// The smallest distance of any checked pair along it (m, looked for up to 0.1 m: 0.1
    /// means none closer; None for a robot without shapes), every tenth control period.
    pub clearance: Option<f64>,
    /// What the search drew (no samples: the straight segment was free).
    pub tried: Tried,
    /// Configurations whose shapes were measured.
    pub measured: usize,
    /// Seconds the search and the shortening took.
    pub planning_seconds: f64,
    /// Seconds the timing and the verification took.
    pub verifying_seconds: f64,
}

/// The farthest the clearance is looked for (m).
const CLEARANCE_CAP: f64 = 0.1;

/// A collision-free path of `robot` from `from` to `to`, timed and verified (see the
/// crate's text). Errors: an end with the wrong joints, outside the ranges or in collision
/// (naming the pair); no path within [`Settings::samples`].
pub fn plan(
    robot: &RobotModel,
    from: &[f64],
    to: &[f64],
    settings: &Settings,
) -> Result<Planned, PlanError> {
    let started = Instant::now();
    settings.check()?;
    let chain = &robot.chain;
    let dof = chain.dof();
    let (lower, upper) = match chain.limits() {
        Some((l, u)) => (l.to_vec(), u.to_vec()),
        None => (
            vec![-std::f64::consts::PI; dof],
            vec![std::f64::consts::PI; dof],
        ),
    };
    for (end, q) in [(End::Start, from), (End::Goal, to)] {
        if q.len() != dof {
            return Err(PlanError::JointCount {
                end,
                expected: dof,
                got: q.len(),
            });
        }
        if let Some(j) = q.iter().position(|x| !x.is_finite()) {
            return Err(PlanError::NotFinite { end, joint: j + 1 });
        }
        if let Some(j) = (0..dof).find(|&j| q[j] < lower[j] || q[j] > upper[j]) {
            return Err(PlanError::OutOfRange {
                end,
                joint: j + 1,
                value: q[j],
                lower: lower[j],
                upper: upper[j],
            });
        }
    }
    let Some(shapes) = &robot.shapes else {
        // Nothing to go around: the straight segment.
        let waypoints = vec![from.to_vec(), to.to_vec()];
        return timed(robot, waypoints, Tried::default(), 0, started, settings);
    };
    let model = shapes.model();
    let mut free = free::Free::new(chain, model, shapes.margin(), lower, upper)?;
    for (end, q) in [(End::Start, from), (End::Goal, to)] {
        if let Some(c) = free.contact(q) {
            let (first, second) = model.pair_names(c.pair);
            return Err(PlanError::InCollision {
                end,
                first: first.to_string(),
                second: second.to_string(),
                distance: c.separation.distance,
                margin: shapes.margin(),
            });
        }
    }
    let mut rng = SplitMix(settings.seed);
    let (path, tried) = rrt::connect(
        &mut free,
        from,
        to,
        settings.samples,
        settings.reach,
        &mut rng,
    )
    .map_err(|tried| PlanError::NoPath { tried })?;
    let waypoints = rrt::shortcut(&mut free, path, settings.shortcuts, &mut rng);
    let measured = free.measured;
    timed(robot, waypoints, tried, measured, started, settings)
}

/// The configuration that puts `robot`'s tool at `target` (its world frame) and keeps the
/// margin, closest to `near` (the path's start, so the way there is short): inverse
/// kinematics from `near`, then from `tries` configurations drawn with `seed` within the
/// joint ranges; every solution is judged, the clear one nearest `near` kept. Errors: no
/// solution reaches the target ([`PlanError::Unreachable`]); every one found is in
/// collision (the goal's [`PlanError::InCollision`], naming the pair of the first).
pub fn reach(
    robot: &RobotModel,
    target: &cps_kinematics::IkTarget,
    near: &[f64],
    tries: usize,
    seed: u64,
) -> Result<Vec<f64>, PlanError> {
    let chain = &robot.chain;
    let config = cps_kinematics::IkConfig {
        restarts: 0,
        ..cps_kinematics::IkConfig::default()
    };
    let (lower, upper) = chain
        .limits()
        .map(|(l, u)| (l.to_vec(), u.to_vec()))
        .ok_or_else(|| PlanError::Unreachable("the robot has no joint ranges".into()))?;
    let mut free = robot
        .shapes
        .as_ref()
        .map(|s| free::Free::new(chain, s.model(), s.margin(), lower.clone(), upper.clone()))
        .transpose()?;
    let mut rng = SplitMix(seed);
    let gap = |q: &[f64]| -> f64 { q.iter().zip(near).map(|(a, b)| (a - b) * (a - b)).sum() };
    let (mut best, mut blocked, mut last): (Option<Vec<f64>>, Option<PlanError>, String) =
        (None, None, String::new());
    for k in 0..=tries {
        let from: Vec<f64> = if k == 0 {
            near.to_vec()
        } else {
            (0..lower.len())
                .map(|j| lower[j] + (upper[j] - lower[j]) * rng.unit())
                .collect()
        };
        let q = match cps_kinematics::solve_ik(chain, target, &from, &config) {
            Ok(s) => s.q,
            Err(e) => {
                last = e.to_string();
                continue;
            }
        };
        if best.as_ref().is_some_and(|b| gap(b) <= gap(&q)) {
            continue;
        }
        let contact = free.as_mut().and_then(|f| f.contact(&q));
        match (contact, robot.shapes.as_ref()) {
            (Some(c), Some(shapes)) => {
                if blocked.is_none() {
                    let (first, second) = shapes.model().pair_names(c.pair);
                    blocked = Some(PlanError::InCollision {
                        end: End::Goal,
                        first: first.to_string(),
                        second: second.to_string(),
                        distance: c.separation.distance,
                        margin: shapes.margin(),
                    });
                }
            }
            _ => best = Some(q),
        }
    }
    best.ok_or_else(|| blocked.unwrap_or(PlanError::Unreachable(last)))
}

/// A way around for the guard's approaches ([`cps_robot::Guarded::going_around`]): a path
/// from `from` to `to` with the default search, timed at `share` of the limits every `dt`
/// seconds, verified; or why there is none, in words.
pub fn around(
    robot: &RobotModel,
    from: &[f64],
    to: &[f64],
    share: f64,
    dt: f64,
) -> Result<Plan, String> {
    let settings = Settings {
        share,
        dt,
        ..Settings::default()
    };
    plan(robot, from, to, &settings)
        .map(|p| p.plan)
        .map_err(|e| e.to_string())
}

/// The waypoints timed segment by segment and verified, and the clearance measured.
fn timed(
    robot: &RobotModel,
    waypoints: Vec<Vec<f64>>,
    tried: Tried,
    measured: usize,
    started: Instant,
    settings: &Settings,
) -> Result<Planned, PlanError> {
    let planning_seconds = started.elapsed().as_secs_f64();
    let verifying = Instant::now();
    let dt = settings.dt;
    let mut plan: Option<Plan> = None;
    for pair in waypoints.windows(2) {
        let segment = cps_robot::approach(robot, &pair[0], &pair[1], settings.share, dt)?;
        plan = Some(match plan {
            None => segment,
            Some(p) => p.then(&segment)?,
        });
    }
    let plan = plan.ok_or_else(|| PlanError::Unverified("a path of one point".into()))?;
    let verdict = cps_robot::check(robot, &plan, dt)?;
    if let Some(b) = verdict.breach {
        return Err(PlanError::Unverified(b.to_string()));
    }
    let mut clearance = None;
    if let Some(shapes) = &robot.shapes {
        if let Some(c) = cps_robot::check_shapes(shapes, &robot.chain, &plan, dt)? {
            return Err(PlanError::Unverified(c.to_string()));
        }
        // Every tenth control period, each pair looked for only below the closest so far
        // and computed only when its bodies' motion could have brought it there.
        let mut walk = cps_geometry::PathCheck::new(shapes.model().clone(), CLEARANCE_CAP);
        let (mut frames, mut closest) = (Vec::new(), CLEARANCE_CAP);
        let samples = plan.samples(dt);
        for q in samples.iter().step_by(10).chain(samples.last()) {
            robot.chain.frames_into(q, &mut frames)?;
            walk.watch_below(closest);
            if let Some(c) = walk.step(&frames) {
                closest = closest.min(c.separation.distance);
            }
        }
        clearance = Some(closest);
    }
    let length = waypoints
        .windows(2)
        .map(|w| {
            w[0].iter()
                .zip(&w[1])
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt()
        })
        .sum();
    Ok(Planned {
        waypoints,
        plan,
        length,
        clearance,
        tried,
        measured,
        planning_seconds,
        verifying_seconds: verifying.elapsed().as_secs_f64(),
    })
}

// The guard's approach goes around (`Guarded::going_around(cps_plan::around)`): where the
// straight approach to a plan's start would sweep the arm through a post, the guard
// without a way around refuses it naming the pair, and with one the in-process robot gets
// there — every configuration it passed keeping the margin.
#[cfg(test)]
pub(crate) mod tests {
    use std::sync::Arc;

    use cps_geometry::{Body, Obstacle, Shape};
    use cps_kinematics::robots::{PandaTool, fr3};
    use cps_robot::{
        Guarded, KinematicRobot, Plan, Policy, Refusal, Robot, RobotError, RobotModel, Shapes,
        StopToken,
    };
    use nalgebra::Isometry3;

    pub(crate) const LEFT: [f64; 7] = [-1.0, 0.5, 0.0, -1.5, 0.0, 2.0, 0.785];
    pub(crate) const RIGHT: [f64; 7] = [1.0, 0.5, 0.0, -1.5, 0.0, 2.0, 0.785];

    /// An FR3 of balls on its forearm, wrist and flange, a post 10 cm square and a metre tall
    /// 55 cm in front of its base.
    pub(crate) fn robot() -> RobotModel {
        let mut model = RobotModel::of_chain("balls", fr3(PandaTool::Flange));
        let bodies = (3..=7)
            .map(|frame| Body {
                link: format!("link{frame}"),
                frame,
                origin: Isometry3::identity(),
                shape: Shape::sphere(0.06, "ball").unwrap(),
            })
            .collect();
        // Balls two joints apart or less overlap where the chain's frames meet.
        let joined = (3..7)
            .flat_map(|k| [1, 2].map(|d| (format!("link{k}"), format!("link{}", (k + d).min(7)))))
            .collect();
        let post = Obstacle {
            name: "post".into(),
            pose: Isometry3::translation(0.55, 0.0, 0.5),
            shape: Shape::cuboid([0.1, 0.1, 1.0], "post").unwrap(),
        };
        let shapes = Shapes::new(bodies, joined)
            .with_obstacles(vec![post], Vec::new())
            .unwrap();
        model.shapes = Some(Arc::new(shapes));
        model
    }

    /// A setting out of its range is refused by name, by `check` and by `plan` alike.
    #[test]
    fn settings_out_of_range_are_named() {
        use crate::{PlanError, Settings, plan};
        for (bad, name) in [
            (
                Settings {
                    share: 0.0,
                    ..Settings::default()
                },
                "share",
            ),
            (
                Settings {
                    share: 1.5,
                    ..Settings::default()
                },
                "share",
            ),
            (
                Settings {
                    reach: f64::NAN,
                    ..Settings::default()
                },
                "reach",
            ),
            (
                Settings {
                    dt: -0.001,
                    ..Settings::default()
                },
                "dt",
            ),
        ] {
            let e = bad.check().unwrap_err();
            assert!(e.to_string().starts_with(&format!("{name}: ")), "{e}");
            assert!(e.is_input());
            let e = plan(&robot(), &LEFT, &LEFT, &bad).unwrap_err();
            assert!(
                matches!(e, PlanError::Setting { setting, .. } if setting == name),
                "{e}"
            );
        }
        assert!(Settings::default().check().is_ok());
    }

    #[test]
    fn the_guards_approach_goes_around_a_post_the_straight_one_hits() {
        let model = robot();
        // A plan that holds at RIGHT for a second; the robot stands at LEFT.
        let plan = Plan::new(0.01, vec![RIGHT.to_vec(); 101]).unwrap();
        let stop = StopToken::new();
        let at_left = || KinematicRobot::of_model(model.clone(), &LEFT, 0.001).unwrap();
        let mut straight = Guarded::new(at_left(), Policy::EXPERIMENT);
        match straight.run(&plan, &stop) {
            Err(RobotError::Refused {
                reason: Refusal::Collision(c),
                ..
            }) => assert_eq!(c.second, "post", "{c:?}"),
            other => panic!("the straight approach: {other:?}"),
        }
        let mut around = Guarded::new(at_left(), Policy::EXPERIMENT).going_around(super::around);
        let run = around.run(&plan, &stop).unwrap();
        assert!(run.ending.complete(), "{:?}", run.ending);
        assert!(run.approach_s > 0.0);
        let last = run.q.last().unwrap();
        for (a, b) in last.iter().zip(RIGHT) {
            assert!((a - b).abs() < 1e-9, "{last:?}");
        }
        // Every configuration the robot passed keeps the margin.
        let shapes = model.shapes.as_ref().unwrap();
        let mut frames = Vec::new();
        let mut closest = f64::INFINITY;
        for q in &run.q {
            model.chain.frames_into(q, &mut frames).unwrap();
            for c in shapes.model().within(&frames, 0.1) {
                closest = closest.min(c.separation.distance);
            }
        }
        assert!(closest >= shapes.margin(), "{closest}");
    }
}
