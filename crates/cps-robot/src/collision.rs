//! The robot's shape in its world, as the guard checks every plan against it: the robot's
//! bodies (one per collision element of its links), the scene's obstacles, the pairs that
//! always touch (links a joint joins; pairs a robot file declares) and the contacts a scene
//! allows (a tool on the table it presses), and the clearance every other pair keeps.
//!
//! A plan is checked at every sample the limits are checked at (the robot's command
//! period, at most [`crate::CHECK_PERIOD`] apart), with [`cps_geometry::PathCheck`]: a
//! pair far apart is computed again only when the motion since could have closed the gap.
//! A pair closer than the margin is a [`Collision`], refused before anything moves; no
//! slowing can help it, since the path is the same at any speed.

use std::sync::Arc;

use cps_geometry::{Body, CollisionModel, Contact, Obstacle, PathCheck};
use nalgebra::Isometry3;

use crate::RobotError;
use crate::plan::Plan;
use crate::setting::SettingError;

/// The clearance (m) every pair keeps unless a robot or a run sets another: room for the
/// meshes' own error (franka_description's collision meshes are a few millimetres
/// larger than the links) and a controller's tracking error.
pub const DEFAULT_MARGIN: f64 = 0.005;

/// Why a pair of links may go unchecked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Why {
    /// A joint joins them: their shapes touch where it turns.
    Joined,
    /// Their shapes ride on one frame: they never move relative to each other (a hand
    /// and its fingers held open).
    Fixed,
    /// The robot's description says so, unverified (a robot file's pairs).
    Declared,
    /// Searched over the joint ranges ([`crate::closest_approaches`]), they came no closer
    /// than this (m; negative: inside each other): left out while the margin is smaller,
    /// checked otherwise.
    Searched(f64),
}

/// A pair of links the robot's description leaves out of the checks, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct LeftOut {
    /// A link's name.
    pub first: String,
    /// The other link's name.
    pub second: String,
    /// Why.
    pub why: Why,
}

impl LeftOut {
    /// Each of `pairs`, left out for the one reason `why`.
    pub fn each(pairs: impl IntoIterator<Item = (String, String)>, why: Why) -> Vec<LeftOut> {
        pairs
            .into_iter()
            .map(|(first, second)| LeftOut { first, second, why })
            .collect()
    }

    /// Whether the pair goes unchecked at clearance `margin`: joined or declared, or
    /// searched and found farther apart than the margin.
    pub fn skipped_at(&self, margin: f64) -> bool {
        match self.why {
            Why::Joined | Why::Fixed | Why::Declared => true,
            Why::Searched(closest) => closest > margin,
        }
    }

    /// The pair and its reason, in words.
    pub fn describe(&self) -> String {
        let why = match self.why {
            Why::Joined => "a joint joins them".to_string(),
            Why::Fixed => "on one frame, they never move relative to each other".to_string(),
            Why::Declared => "the robot's file says they never meet (not searched)".to_string(),
            Why::Searched(d) if d < 0.0 => format!(
                "the description leaves them out, but they meet {:.1} mm deep within the joint ranges",
                -1e3 * d
            ),
            Why::Searched(d) => format!(
                "no closer than {:.1} mm over the joint ranges (searched)",
                1e3 * d
            ),
        };
        format!("{} – {}: {why}", self.first, self.second)
    }
}

/// A robot's collision geometry among its scene's obstacles, with the clearance kept.
#[derive(Debug, Clone)]
pub struct Shapes {
    bodies: Vec<Body>,
    left_out: Vec<LeftOut>,
    obstacles: Vec<Obstacle>,
    allowed: Vec<(String, String)>,
    margin: f64,
    model: Arc<CollisionModel>,
}

impl Shapes {
    /// The robot's `bodies` alone, the pairs of links in `touching` never checked
    /// ([`Why::Declared`]), at [`DEFAULT_MARGIN`].
    pub fn new(bodies: Vec<Body>, touching: Vec<(String, String)>) -> Self {
        Self::leaving_out(bodies, LeftOut::each(touching, Why::Declared))
    }

    /// The robot's `bodies` alone at [`DEFAULT_MARGIN`], the pairs `left_out` unchecked
    /// where [`LeftOut::skipped_at`] the margin says so.
    pub fn leaving_out(bodies: Vec<Body>, left_out: Vec<LeftOut>) -> Self {
        let shapes = Shapes {
            bodies,
            left_out,
            obstacles: Vec::new(),
            allowed: Vec::new(),
            margin: DEFAULT_MARGIN,
            model: Arc::new(CollisionModel::new(Vec::new(), Vec::new(), &[])),
        };
        shapes.among(Vec::new(), Vec::new())
    }

    /// The same robot among `obstacles` (replacing any before), where the pairs in
    /// `allowed` (a link and an obstacle, or two links, by name) may touch. Errors: a name
    /// in `allowed` that is neither a link nor an obstacle, two obstacles of one name.
    pub fn with_obstacles(
        &self,
        obstacles: Vec<Obstacle>,
        allowed: Vec<(String, String)>,
    ) -> Result<Self, SettingError> {
        for (i, o) in obstacles.iter().enumerate() {
            if obstacles[..i].iter().any(|p| p.name == o.name) {
                return Err(SettingError::DuplicateObstacle(o.name.clone()));
            }
            if self.bodies.iter().any(|b| b.link == o.name) {
                return Err(SettingError::ObstacleNamedAsLink(o.name.clone()));
            }
        }
        for name in allowed.iter().flat_map(|(a, b)| [a, b]) {
            let known = self.bodies.iter().any(|b| &b.link == name)
                || obstacles.iter().any(|o| &o.name == name);
            if !known {
                return Err(SettingError::UnknownContactName {
                    name: name.clone(),
                    links: self.links().join(", "),
                });
            }
        }
        Ok(self.among(obstacles, allowed))
    }

    /// The same robot among `obstacles` with `allowed`, its pairs' model built anew
    /// (checked by the caller).
    fn among(&self, obstacles: Vec<Obstacle>, allowed: Vec<(String, String)>) -> Self {
        let skip: Vec<(String, String)> = self
            .left_out
            .iter()
            .filter(|l| l.skipped_at(self.margin))
            .map(|l| (l.first.clone(), l.second.clone()))
            .chain(allowed.iter().cloned())
            .collect();
        let model = Arc::new(CollisionModel::new(
            self.bodies.clone(),
            obstacles.clone(),
            &skip,
        ));
        Shapes {
            obstacles,
            allowed,
            model,
            ..self.clone()
        }
    }

    /// The same robot with its obstacles moved by `to` (each pose `to * pose`): a scene's
    /// obstacles, placed in its world, brought into the frame of the robot's base
    /// (`to` = the base's pose inverted) for a robot whose own model starts at its base,
    /// as a Franka's does.
    pub fn moved(&self, to: &Isometry3<f64>) -> Self {
        let obstacles: Vec<Obstacle> = self
            .obstacles
            .iter()
            .map(|o| Obstacle {
                pose: to * o.pose,
                ..o.clone()
            })
            .collect();
        self.among(obstacles, self.allowed.clone())
    }

    /// The same shapes with clearance `margin` (m): a pair left out for being searched
    /// farther apart than the old margin is checked when it is not farther than the new
    /// one. Errors: not finite, or negative.
    pub fn with_margin(&self, margin: f64) -> Result<Self, SettingError> {
        if !(margin.is_finite() && margin >= 0.0) {
            return Err(SettingError::Margin(margin));
        }
        let with = Shapes {
            margin,
            ..self.clone()
        };
        Ok(with.among(self.obstacles.clone(), self.allowed.clone()))
    }

    /// The clearance (m) every checked pair keeps.
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// The robot's bodies.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// The scene's obstacles.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// The pairs of links the description leaves out, each with why; those
    /// [`LeftOut::skipped_at`] the margin go unchecked, the others are checked.
    pub fn left_out(&self) -> &[LeftOut] {
        &self.left_out
    }

    /// The contacts the scene allows.
    pub fn allowed(&self) -> &[(String, String)] {
        &self.allowed
    }

    /// The pairs checked, as one model (shared).
    pub fn model(&self) -> &Arc<CollisionModel> {
        &self.model
    }

    /// The names of the links that have shapes, in order, each once.
    pub fn links(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for b in &self.bodies {
            if !out.contains(&b.link) {
                out.push(b.link.clone());
            }
        }
        out
    }

    /// The pair of `contact`, closer than the margin at `time` (`command`), in words.
    pub fn collision(&self, contact: &Contact, time: f64, command: usize) -> Collision {
        let (a, b) = self.model.pair_names(contact.pair);
        Collision {
            first: a.to_string(),
            second: b.to_string(),
            time,
            command,
            distance: contact.separation.distance,
            margin: self.margin,
        }
    }
}

/// Two bodies closer than the clearance margin — or overlapping — at a time of a plan, or
/// at a command sent one at a time.
#[derive(Debug, Clone, PartialEq)]
pub struct Collision {
    /// A link's name.
    pub first: String,
    /// Another link's name, or an obstacle's.
    pub second: String,
    /// When (s from the plan's start).
    pub time: f64,
    /// Which command that is, counted from 0 at the plan's start.
    pub command: usize,
    /// Their signed distance (m): negative where they overlap (the depth).
    pub distance: f64,
    /// The clearance they had to keep (m).
    pub margin: f64,
}

impl std::fmt::Display for Collision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (t, c) = (self.time, self.command);
        let place = format!(
            "`{}` and `{}` at t = {t:.3} s (command {c})",
            self.first, self.second
        );
        if self.distance < 0.0 {
            write!(
                f,
                "{place} collide: {:.1} mm deep in each other (signed distance {:.4} m)",
                -1e3 * self.distance,
                self.distance
            )
        } else {
            write!(
                f,
                "{place} come {:.1} mm apart, within the clearance margin of {:.1} mm",
                1e3 * self.distance,
                1e3 * self.margin
            )
        }
    }
}

/// A check of one configuration after another against `shapes`, allocation-free after
/// it is made: the guard's, for commands sent one at a time and for a plan's samples.
#[derive(Debug, Clone)]
pub struct ShapeWatch {
    shapes: Arc<Shapes>,
    check: PathCheck,
    frames: Vec<Isometry3<f64>>,
}

impl ShapeWatch {
    /// A watch of `shapes` for a chain of `dof` joints.
    pub fn new(shapes: Arc<Shapes>, dof: usize) -> Self {
        let check = PathCheck::new(shapes.model().clone(), shapes.margin());
        ShapeWatch {
            shapes,
            check,
            frames: Vec::with_capacity(dof + 1),
        }
    }

    /// Starts a new path: the next configuration is checked as a first one.
    pub fn restart(&mut self) {
        self.check.restart();
    }

    /// Judges the configuration `q` of `chain`: the closest pair within the margin, if any.
    pub fn judge(
        &mut self,
        chain: &cps_kinematics::SerialChain,
        q: &[f64],
        time: f64,
        command: usize,
    ) -> Result<Option<Collision>, RobotError> {
        Ok(self
            .contact(chain, q)?
            .map(|c| self.shapes.collision(&c, time, command)))
    }

    /// As [`ShapeWatch::judge`], without allocating (on a robot's loop): the closest
    /// pair's contact, for [`Shapes::collision`] to put in words afterwards.
    pub fn contact(
        &mut self,
        chain: &cps_kinematics::SerialChain,
        q: &[f64],
    ) -> Result<Option<Contact>, cps_kinematics::KinematicsError> {
        chain.frames_into(q, &mut self.frames)?;
        Ok(self.check.step(&self.frames))
    }

    /// The shapes watched.
    pub fn shapes(&self) -> &Arc<Shapes> {
        &self.shapes
    }
}

/// The first sample of `plan`, sampled every `period` (at most
/// [`crate::CHECK_PERIOD`]), where two bodies of `shapes` come closer than its margin —
/// or None when every pair keeps clear.
pub fn check_shapes(
    shapes: &Arc<Shapes>,
    chain: &cps_kinematics::SerialChain,
    plan: &Plan,
    period: f64,
) -> Result<Option<Collision>, RobotError> {
    let step = period.min(crate::CHECK_PERIOD);
    let mut watch = ShapeWatch::new(shapes.clone(), chain.dof());
    for (k, q) in plan.samples(step).iter().enumerate() {
        let t = k as f64 * step;
        if let Some(c) = watch.judge(chain, q, t, (t / period).round() as usize)? {
            return Ok(Some(c));
        }
    }
    Ok(None)
}
