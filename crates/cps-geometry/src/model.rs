//! A robot's bodies and its scene's obstacles, and the pairs of them that can collide:
//! what the guard checks a plan against.
//!
//! Bodies ride on numbered frames (0 the robot's base, `k` the link joint `k` moves); a
//! caller gives the frames' world poses, from forward kinematics, and gets distances.
//! Pairs that cannot change are left out: two bodies on one frame never move against each
//! other, and a link and the link its joint hangs from touch at the joint whatever its
//! angle (the `skip` pairs, with any pair a robot file declares).
//!
//! A path is checked configuration by configuration with [`PathCheck`]. Between two
//! configurations no point of a body moves further than its bounding sphere's centre
//! does plus the sphere's radius times the chord of its frame's turn, so a pair known to
//! be `d` apart stays apart until the bodies' motion since adds up to `d`: only then is
//! its distance computed again. At a robot's control rate a pair 10 cm apart is computed
//! once in many steps.

use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Vector3};

use crate::shape::{Separation, Shape, distance_hinted};

type V = Vector3<f64>;

/// A shape carried by one of the robot's frames.
#[derive(Debug, Clone)]
pub struct Body {
    /// The link it belongs to (its URDF name).
    pub link: String,
    /// The frame that carries it: 0 the base, `k` the link joint `k` moves.
    pub frame: usize,
    /// Its pose in that frame.
    pub origin: Isometry3<f64>,
    /// Its shape.
    pub shape: Shape,
}

/// A shape fixed in the world (the robot's base frame).
#[derive(Debug, Clone)]
pub struct Obstacle {
    /// Its name, as the scene file gives it.
    pub name: String,
    /// Its pose.
    pub pose: Isometry3<f64>,
    /// Its shape.
    pub shape: Shape,
}

/// The second member of a pair; the first is always a body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Other {
    /// Another of the robot's bodies (index into [`CollisionModel::bodies`]).
    Body(usize),
    /// An obstacle (index into [`CollisionModel::obstacles`]).
    Obstacle(usize),
}

/// Two shapes at a configuration and how far apart they are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Which pair ([`CollisionModel::pair`]).
    pub pair: usize,
    /// Their signed distance (negative: overlapping) and closest points.
    pub separation: Separation,
}

/// A robot's bodies, its scene's obstacles, and the pairs to check.
#[derive(Debug, Clone)]
pub struct CollisionModel {
    bodies: Vec<Body>,
    obstacles: Vec<Obstacle>,
    pairs: Vec<(usize, Other)>,
    /// Per body: its bounding sphere's centre in its frame, and radius.
    body_bounds: Vec<(V, f64)>,
    /// Per obstacle: its bounding sphere's centre in the world, and radius.
    obstacle_bounds: Vec<(V, f64)>,
    frames: usize,
}

impl CollisionModel {
    /// The model of `bodies` among `obstacles`, every pair checked except two bodies on one
    /// frame and the pairs `skip` names (link names, or a link and an obstacle's name; either
    /// order).
    pub fn new(bodies: Vec<Body>, obstacles: Vec<Obstacle>, skip: &[(String, String)]) -> Self {
        let skipped = |a: &str, b: &str| {
            skip.iter()
                .any(|(x, y)| (x == a && y == b) || (x == b && y == a))
        };
        let mut pairs = Vec::new();
        for (i, a) in bodies.iter().enumerate() {
            for (j, b) in bodies.iter().enumerate().skip(i + 1) {
                if a.frame != b.frame && !skipped(&a.link, &b.link) {
                    pairs.push((i, Other::Body(j)));
                }
            }
        }
        for (i, a) in bodies.iter().enumerate() {
            for (k, o) in obstacles.iter().enumerate() {
                if !skipped(&a.link, &o.name) {
                    pairs.push((i, Other::Obstacle(k)));
                }
            }
        }
        // A shape's bounding sphere moved by `pose`.
        let placed = |shape: &Shape, pose: &Isometry3<f64>| {
            let (c, r) = shape.bounds();
            ((pose * Point3::from(c)).coords, r)
        };
        let body_bounds = bodies.iter().map(|b| placed(&b.shape, &b.origin)).collect();
        let obstacle_bounds = obstacles
            .iter()
            .map(|o| placed(&o.shape, &o.pose))
            .collect();
        let frames = bodies.iter().map(|b| b.frame + 1).max().unwrap_or(0);
        CollisionModel {
            bodies,
            obstacles,
            pairs,
            body_bounds,
            obstacle_bounds,
            frames,
        }
    }

    /// Per body: its bounding sphere's centre in its frame, and radius.
    pub fn body_spheres(&self) -> &[(V, f64)] {
        &self.body_bounds
    }

    /// Per obstacle: its bounding sphere's centre in the world, and radius.
    pub fn obstacle_spheres(&self) -> &[(V, f64)] {
        &self.obstacle_bounds
    }

    /// The robot's bodies.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// The scene's obstacles.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// How many frames the bodies ride on (the length [`CollisionModel::distance`]'s
    /// `frames` must have at least).
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// How many pairs are checked.
    pub fn pair_count(&self) -> usize {
        self.pairs.len()
    }

    /// Pair `p`: a body and what it is checked against.
    pub fn pair(&self, p: usize) -> (usize, Other) {
        self.pairs[p]
    }

    /// The names of pair `p`'s members: a link, and a link or an obstacle.
    pub fn pair_names(&self, p: usize) -> (&str, &str) {
        let (a, b) = self.pairs[p];
        let second = match b {
            Other::Body(j) => self.bodies[j].link.as_str(),
            Other::Obstacle(k) => self.obstacles[k].name.as_str(),
        };
        (self.bodies[a].link.as_str(), second)
    }

    /// The signed distance of pair `p` with the frames at `frames` (world poses, indexed
    /// by frame).
    pub fn distance(&self, p: usize, frames: &[Isometry3<f64>]) -> Separation {
        self.distance_hinted(p, frames, &mut [0, 0])
    }

    fn pose(&self, i: usize, frames: &[Isometry3<f64>]) -> Isometry3<f64> {
        frames[self.bodies[i].frame] * self.bodies[i].origin
    }

    /// [`CollisionModel::distance`] from the support points `hints` last ended at (kept
    /// per pair by a caller that measures it again and again): the same distance, found
    /// in fewer steps when the pair moved little.
    pub fn distance_hinted(
        &self,
        p: usize,
        frames: &[Isometry3<f64>],
        hints: &mut [u32; 2],
    ) -> Separation {
        let (a, b) = self.pairs[p];
        let pa = self.pose(a, frames);
        match b {
            Other::Body(j) => distance_hinted(
                &self.bodies[a].shape,
                &pa,
                &self.bodies[j].shape,
                &self.pose(j, frames),
                hints,
            ),
            Other::Obstacle(k) => distance_hinted(
                &self.bodies[a].shape,
                &pa,
                &self.obstacles[k].shape,
                &self.obstacles[k].pose,
                hints,
            ),
        }
    }

    /// A lower bound of pair `p`'s distance at `frames` within `rel` of it
    /// ([`crate::distance_bound`]; `hints` and `dir` kept per pair by the caller).
    pub fn distance_bound(
        &self,
        p: usize,
        frames: &[Isometry3<f64>],
        hints: &mut [u32; 2],
        dir: &mut Vector3<f64>,
        rel: f64,
    ) -> f64 {
        let (a, b) = self.pairs[p];
        let pa = self.pose(a, frames);
        let (shape, pose) = match b {
            Other::Body(j) => (&self.bodies[j].shape, self.pose(j, frames)),
            Other::Obstacle(k) => (&self.obstacles[k].shape, self.obstacles[k].pose),
        };
        crate::distance_bound(&self.bodies[a].shape, &pa, shape, &pose, hints, dir, rel)
    }

    /// Every pair closer than `limit` (m) at `frames`, closest first. Pairs whose bounding
    /// spheres are `limit` apart are not computed.
    pub fn within(&self, frames: &[Isometry3<f64>], limit: f64) -> Vec<Contact> {
        let mut out = Vec::new();
        self.within_into(frames, limit, &mut Vec::new(), &mut out);
        out.sort_by(|x, y| x.separation.distance.total_cmp(&y.separation.distance));
        out
    }

    /// [`CollisionModel::within`] into `out` (cleared first), in pair order, without
    /// allocating once `centres` and `out` have grown: what a cost evaluated at every
    /// sample of a movement takes.
    pub fn within_into(
        &self,
        frames: &[Isometry3<f64>],
        limit: f64,
        centres: &mut Vec<Vector3<f64>>,
        out: &mut Vec<Contact>,
    ) {
        centres.clear();
        centres.extend(
            (0..self.bodies.len()).map(|i| {
                (frames[self.bodies[i].frame] * Point3::from(self.body_bounds[i].0)).coords
            }),
        );
        out.clear();
        for p in 0..self.pairs.len() {
            let (a, b) = self.pairs[p];
            let (cb, rb) = match b {
                Other::Body(j) => (centres[j], self.body_bounds[j].1),
                Other::Obstacle(k) => self.obstacle_bounds[k],
            };
            if (centres[a] - cb).norm() - self.body_bounds[a].1 - rb >= limit {
                continue;
            }
            let s = self.distance(p, frames);
            if s.distance < limit {
                out.push(Contact {
                    pair: p,
                    separation: s,
                });
            }
        }
    }
}

impl CollisionModel {
    /// How far each body may have moved from its pose at `reference` to its pose at
    /// `frames` (m, into `out`, one per body): its bounding sphere's centre's displacement
    /// plus the chord its radius sweeps as its frame turns. A pair `d` apart at `reference`
    /// is at least `d` minus its bodies' motions apart at `frames`.
    pub fn motions(
        &self,
        reference: &[Isometry3<f64>],
        frames: &[Isometry3<f64>],
        out: &mut Vec<f64>,
    ) {
        out.clear();
        out.extend(
            self.bodies
                .iter()
                .zip(&self.body_bounds)
                .map(|(b, (c, r))| {
                    let (f0, f1) = (&reference[b.frame], &frames[b.frame]);
                    let c = Point3::from(*c);
                    let d = f0.rotation.coords.dot(&f1.rotation.coords).abs().min(1.0);
                    (f1 * c - f0 * c).norm() + 2.0 * r * (1.0 - d * d).sqrt()
                }),
        );
    }

    /// How far pair `p`'s two members may have come closer, given each body's motion.
    #[inline]
    fn pair_motion(&self, p: usize, moved: &[f64]) -> f64 {
        let (a, b) = self.pairs[p];
        moved[a]
            + match b {
                Other::Body(j) => moved[j],
                Other::Obstacle(_) => 0.0,
            }
    }

    /// The largest distance (m) from the base frame's origin (`frames[0]`) to any point of
    /// a body or any frame's origin at `frames`. Every joint turns the points beyond it
    /// about an axis through a frame's origin, so joints turned by `δ₁ … δₙ` radians move
    /// no point further than `2 · reach · Σ|δⱼ|` (while the points stay within `reach`).
    pub fn reach(&self, frames: &[Isometry3<f64>]) -> f64 {
        let o = frames[0].translation.vector;
        let origins = frames
            .iter()
            .map(|f| (f.translation.vector - o).norm())
            .fold(0.0, f64::max);
        self.bodies
            .iter()
            .zip(&self.body_bounds)
            .map(|(b, (c, r))| ((frames[b.frame] * Point3::from(*c)).coords - o).norm() + r)
            .fold(origins, f64::max)
    }

    /// Every pair closer than `watch` at `frames` (into `out`, in pair order), given a lower
    /// bound of each pair's distance at a reference configuration (`lower`, as
    /// [`PathCheck::lower`] leaves them) and each body's motion since
    /// ([`CollisionModel::motions`]): a pair is computed only when that motion could have
    /// brought it within `watch`, and then without a warm start, so the same frames give
    /// the same distances whatever was computed before.
    pub fn within_from(
        &self,
        lower: &[f64],
        moved: &[f64],
        frames: &[Isometry3<f64>],
        watch: f64,
        out: &mut Vec<Contact>,
    ) {
        out.clear();
        for (p, low) in lower.iter().enumerate().take(self.pairs.len()) {
            if low - self.pair_motion(p, moved) >= watch {
                continue;
            }
            let s = self.distance(p, frames);
            if s.distance < watch {
                out.push(Contact {
                    pair: p,
                    separation: s,
                });
            }
        }
    }
}

/// A path's check, one configuration after another (see the module's text): the pairs
/// within `watch` of each other are computed exactly at every configuration, the others
/// only when their bodies' motion could have brought them within it. Nothing is allocated
/// after [`PathCheck::new`].
#[derive(Debug, Clone)]
pub struct PathCheck {
    model: Arc<CollisionModel>,
    watch: f64,
    lower: Vec<f64>,
    hints: Vec<[u32; 2]>,
    centres: Vec<V>,
    rotations: Vec<nalgebra::UnitQuaternion<f64>>,
    moved: Vec<f64>,
    started: bool,
    queries: usize,
    near: Vec<Contact>,
}

impl PathCheck {
    /// A check of `model` (shared) that computes exactly every pair closer than `watch`
    /// (m). Not generic on purpose: its loop is compiled, optimised, in this crate, whatever
    /// the caller's optimisation level.
    pub fn new(model: Arc<CollisionModel>, watch: f64) -> Self {
        let (n, pairs) = (model.bodies.len(), model.pairs.len());
        PathCheck {
            model,
            watch,
            lower: vec![f64::NEG_INFINITY; pairs],
            hints: vec![[0, 0]; pairs],
            centres: vec![V::zeros(); n],
            rotations: vec![nalgebra::UnitQuaternion::identity(); n],
            moved: vec![0.0; n],
            started: false,
            queries: 0,
            near: Vec::with_capacity(pairs),
        }
    }

    /// The model checked.
    pub fn model(&self) -> &CollisionModel {
        &self.model
    }

    /// Starts over: the next configuration is checked as a path's first (every pair
    /// computed), as after [`PathCheck::new`].
    pub fn restart(&mut self) {
        self.started = false;
        self.lower.fill(f64::NEG_INFINITY);
    }

    /// Looks for pairs only below `watch` from the next configuration on, when that is
    /// less than the watch so far (a path's closest approach, searched below the closest
    /// found: a pair farther apart is no longer computed).
    pub fn watch_below(&mut self, watch: f64) {
        self.watch = self.watch.min(watch);
    }

    /// How many exact distances were computed so far.
    pub fn queries(&self) -> usize {
        self.queries
    }

    /// Every pair closer than `watch` at the last configuration, in pair order.
    pub fn near(&self) -> &[Contact] {
        &self.near
    }

    /// A lower bound of each pair's distance at the last configuration (exact where it
    /// was computed there), in pair order.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }

    /// The next configuration's frames: the closest pair closer than `watch`, if any.
    pub fn step(&mut self, frames: &[Isometry3<f64>]) -> Option<Contact> {
        let m: &CollisionModel = &self.model;
        for i in 0..m.bodies.len() {
            let f = &frames[m.bodies[i].frame];
            let c = (f * Point3::from(m.body_bounds[i].0)).coords;
            let r = f.rotation;
            self.moved[i] = if self.started {
                // The chord a point at the sphere's radius travels: 2 r sin(θ/2), with
                // cos(θ/2) the two rotations' quaternion dot product.
                let d = r.coords.dot(&self.rotations[i].coords).abs().min(1.0);
                (c - self.centres[i]).norm() + 2.0 * m.body_bounds[i].1 * (1.0 - d * d).sqrt()
            } else {
                f64::INFINITY
            };
            self.centres[i] = c;
            self.rotations[i] = r;
        }
        self.started = true;
        self.near.clear();
        let mut closest: Option<Contact> = None;
        for p in 0..m.pairs.len() {
            self.lower[p] -= m.pair_motion(p, &self.moved);
            if self.lower[p] >= self.watch {
                continue;
            }
            let s = m.distance_hinted(p, frames, &mut self.hints[p]);
            self.queries += 1;
            self.lower[p] = s.distance;
            if s.distance < self.watch {
                let c = Contact {
                    pair: p,
                    separation: s,
                };
                self.near.push(c);
                if closest.is_none_or(|c| s.distance < c.separation.distance) {
                    closest = Some(c);
                }
            }
        }
        closest
    }
}
