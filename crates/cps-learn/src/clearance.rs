//! Learning that keeps clear: a cost on how far a joint movement brings the robot's shapes
//! within a clearance of each other and of its scene's obstacles — the pairs the guard
//! checks (`cps_robot::Shapes`).
//!
//! At every [`Clearance::stride`]-th sample `k` of the movement the pairs closer than the
//! clearance `c` give
//! `C_k = w Σ_p (c − d_p(q_k))²`: zero where every pair keeps `c`, growing with the square
//! of how far each falls short (a penetration counts as its depth plus `c`). It is smooth
//! (its gradient is continuous, as the distances' are between convex shapes) and its
//! residual per sample, `√C_k`, keeps Levenberg–Marquardt's residual count fixed. Far
//! pairs cost nothing: a pair whose bounding spheres are `c` apart is not computed.

use std::sync::Arc;

use cps_kinematics::{KinematicsError, SerialChain};
use nalgebra::{Isometry3, Vector3};

/// The clearance a learned movement keeps from the robot's own shapes and its scene's.
#[derive(Debug, Clone)]
pub struct Clearance {
    /// The robot's shapes among the obstacles (the guard's).
    pub shapes: Arc<cps_robot::Shapes>,
    /// The distance every pair of the robot's shapes and its world's keeps (m).
    pub distance: f64,
    /// The distance every pair of the robot's own shapes keeps (m): `[clearance]
    /// self_distance`, the same as `distance` unless a file says otherwise (an arm that
    /// folds close to itself along its path keeps the shelf far and itself near).
    pub self_distance: f64,
    /// The weight of the squared shortfall (per m²).
    pub weight: f64,
    /// Every how many samples the movement is judged (the last always is): at 10 ms
    /// samples, [`CLEARANCE_STRIDE`] judges every 40 ms, where the tool of a
    /// movement at a metre per second moves 4 cm and its distances, smooth along a smooth
    /// path, change by less than the shortfall the cost sees. The guard judges the result
    /// every millisecond.
    pub stride: usize,
}

/// The default [`Clearance::stride`].
pub const CLEARANCE_STRIDE: usize = 4;

impl Clearance {
    /// The farther of the two distances: no pair farther apart falls short.
    pub fn watch(&self) -> f64 {
        self.distance.max(self.self_distance)
    }

    /// The squared shortfall of `contact` (a pair of the shapes' model): of the robot's
    /// own shapes from [`Clearance::self_distance`], of one and an obstacle from
    /// [`Clearance::distance`]; zero when it keeps it.
    pub fn shortfall_squared(&self, contact: &cps_geometry::Contact) -> f64 {
        let keep = match self.shapes.model().pair(contact.pair).1 {
            cps_geometry::Other::Body(_) => self.self_distance,
            cps_geometry::Other::Obstacle(_) => self.distance,
        };
        (keep - contact.separation.distance).max(0.0).powi(2)
    }

    /// Whether the robot at `q` keeps the clearance from itself and its world.
    pub fn kept_at(
        &self,
        chain: &SerialChain,
        q: &[f64],
        b: &mut ClearanceBuffers,
    ) -> Result<bool, KinematicsError> {
        chain.frames_into(q, &mut b.frames)?;
        let model = self.shapes.model();
        model.within_into(&b.frames, self.watch(), &mut b.centres, &mut b.near);
        Ok(b.near.iter().all(|c| self.shortfall_squared(c) == 0.0))
    }

    /// The samples judged of `samples`: every `stride`-th, and the last.
    fn checked(samples: usize, stride: usize) -> impl Iterator<Item = usize> {
        let stride = stride.max(1);
        let last = samples.saturating_sub(1);
        (0..samples)
            .step_by(stride)
            .chain((samples > 0 && !last.is_multiple_of(stride)).then_some(last))
    }
}

/// Where a movement comes closest: the two shapes, the sample and their signed distance.
#[derive(Debug, Clone, PartialEq)]
pub struct Closest {
    /// A link's name.
    pub first: String,
    /// Another link's name, or an obstacle's.
    pub second: String,
    /// The sample's time (s).
    pub time: f64,
    /// Their signed distance (m; negative: overlapping).
    pub distance: f64,
}

/// Reused buffers of one evaluation.
#[derive(Debug, Default, Clone)]
pub struct ClearanceBuffers {
    frames: Vec<Isometry3<f64>>,
    centres: Vec<Vector3<f64>>,
    near: Vec<cps_geometry::Contact>,
    moved: Vec<f64>,
    q: Vec<f64>,
}

/// The last movement walked on this thread: its frames and each pair's lower bound at
/// every judged sample, for the clearance model, sample count, stride and clearance of
/// `key`.
#[derive(Debug, Default)]
struct Reference {
    key: (usize, usize, usize, u64),
    frames: Vec<Isometry3<f64>>,
    lower: Vec<f64>,
    /// The joints at each judged sample.
    q: Vec<f64>,
    /// [`cps_geometry::CollisionModel::reach`] at each.
    reach: Vec<f64>,
    /// How much closer the closest pair could come before it is within the clearance.
    slack: Vec<f64>,
}

thread_local! {
    static REFERENCE: std::cell::RefCell<Reference> = std::cell::RefCell::default();
}

/// A body moved further than this (m) from the remembered movement walks the movement
/// afresh (its lower bounds would compute most pairs).
const REWALK: f64 = 0.01;

/// Taken off a walk's distances before they serve as lower bounds: a warm-started
/// distance and a fresh one may differ in their last bits.
const LOWER_SLACK: f64 = 1e-9;

impl Clearance {
    /// One residual per judged sample of the joint movement `positions(j)` (samples of
    /// joint `j`): `√(w Σ_p (c − d_p)²)` over the pairs closer than `c`. Their squares sum
    /// to [`Clearance::cost`].
    ///
    /// The samples are walked as the guard walks a plan ([`cps_geometry::PathCheck`]: a
    /// pair is computed again only when the motion since could have brought it within
    /// `c`), and the walk is remembered on this thread: a movement close to the last one
    /// walked (a Jacobian column's, a step's) skips the samples whose joints turned too
    /// little to bring any pair within `c` (no point moves further than twice the robot's
    /// reach times the turn, [`cps_geometry::CollisionModel::reach`]) and computes only the
    /// pairs its bodies' motion could have brought within `c` at the others. Every distance
    /// that counts is computed afresh, without a warm start, so the residuals are the same
    /// bits whichever way.
    pub fn residuals<'a>(
        &self,
        chain: &SerialChain,
        samples: usize,
        positions: impl Fn(usize) -> &'a [f64],
        b: &mut ClearanceBuffers,
        out: &mut Vec<f64>,
    ) -> Result<(), KinematicsError> {
        let model: &cps_geometry::CollisionModel = self.shapes.model();
        let key = (
            model as *const _ as usize,
            samples,
            self.stride,
            self.distance.to_bits() ^ self.self_distance.to_bits().rotate_left(1),
        );
        let sw = self.weight.sqrt();
        let start = out.len();
        let checked: Vec<usize> = Self::checked(samples, self.stride).collect();
        let nf = chain.dof() + 1;
        let pairs = model.pair_count();
        let shortfall = |near: &[cps_geometry::Contact]| -> f64 {
            let s: f64 = near.iter().map(|c| self.shortfall_squared(c)).sum();
            sw * s.sqrt()
        };
        let from_reference = REFERENCE.with(|r| -> Result<bool, KinematicsError> {
            let r = r.borrow();
            if r.key != key {
                return Ok(false);
            }
            let dof = chain.dof();
            for (i, &k) in checked.iter().enumerate() {
                // How far any point can have moved from the remembered sample: joint
                // turns times twice the reach (see `CollisionModel::reach`).
                let turned: f64 = (0..dof)
                    .map(|j| (positions(j)[k] - r.q[i * dof + j]).abs())
                    .sum();
                let moved = 2.0 * (r.reach[i] + REWALK) * turned;
                if moved > REWALK {
                    out.truncate(start);
                    return Ok(false);
                }
                if 2.0 * moved <= r.slack[i] {
                    // No pair can have come within the clearance: nothing falls short.
                    out.push(0.0);
                    continue;
                }
                b.q.clear();
                b.q.extend((0..dof).map(|j| positions(j)[k]));
                chain.frames_into(&b.q, &mut b.frames)?;
                model.motions(&r.frames[i * nf..(i + 1) * nf], &b.frames, &mut b.moved);
                if b.moved.iter().any(|&m| m > REWALK) {
                    out.truncate(start);
                    return Ok(false);
                }
                let lower = &r.lower[i * pairs..(i + 1) * pairs];
                model.within_from(lower, &b.moved, &b.frames, self.watch(), &mut b.near);
                out.push(shortfall(&b.near));
            }
            Ok(true)
        })?;
        if from_reference {
            return Ok(());
        }
        // Walked afresh, and remembered.
        let mut walk = cps_geometry::PathCheck::new(self.shapes.model().clone(), self.watch());
        let n = checked.len();
        let mut frames = Vec::with_capacity(n * nf);
        let mut lower = Vec::with_capacity(n * pairs);
        let (mut q, mut reach, mut slack) = (
            Vec::with_capacity(n * chain.dof()),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        for &k in &checked {
            b.q.clear();
            b.q.extend((0..chain.dof()).map(|j| positions(j)[k]));
            chain.frames_into(&b.q, &mut b.frames)?;
            walk.step(&b.frames);
            frames.extend_from_slice(&b.frames);
            lower.extend(walk.lower().iter().map(|l| l - LOWER_SLACK));
            q.extend_from_slice(&b.q);
            reach.push(model.reach(&b.frames));
            let closest = walk.lower().iter().fold(f64::INFINITY, |a, &l| a.min(l));
            slack.push(closest - LOWER_SLACK - self.watch());
            // The pairs that count, computed afresh (the walk's are warm-started).
            b.near.clear();
            b.near
                .extend(walk.near().iter().map(|c| cps_geometry::Contact {
                    pair: c.pair,
                    separation: model.distance(c.pair, &b.frames),
                }));
            out.push(shortfall(&b.near));
        }
        REFERENCE.with(|r| {
            *r.borrow_mut() = Reference {
                key,
                frames,
                lower,
                q,
                reach,
                slack,
            }
        });
        Ok(())
    }

    /// The term's residuals on a robot's recording (its joints at every recorded sample).
    pub fn residuals_of_recording(
        &self,
        chain: &SerialChain,
        recording: &cps_robot::Recording,
        b: &mut ClearanceBuffers,
        out: &mut Vec<f64>,
    ) -> Result<(), KinematicsError> {
        let joints = by_joint(&recording.q);
        self.residuals(chain, recording.q.len(), |j| &joints[j], b, out)
    }

    /// The term's cost on the joint movement (see [`Clearance::residuals`]).
    pub fn cost<'a>(
        &self,
        chain: &SerialChain,
        samples: usize,
        positions: impl Fn(usize) -> &'a [f64],
        b: &mut ClearanceBuffers,
    ) -> Result<f64, KinematicsError> {
        let mut out = Vec::with_capacity(samples);
        self.residuals(chain, samples, positions, b, &mut out)?;
        Ok(out.iter().map(|r| r * r).sum())
    }
}

/// Samples (each a configuration) joint by joint.
pub(crate) fn by_joint(q: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let dof = q.first().map_or(0, Vec::len);
    (0..dof).map(|j| q.iter().map(|s| s[j]).collect()).collect()
}

/// Where the joint movement `positions(j)` at `times` comes closest among `shapes`' pairs
/// (every pair computed within `look` metres; None when none comes that close).
pub fn closest<'a>(
    shapes: &cps_robot::Shapes,
    chain: &SerialChain,
    times: &[f64],
    positions: impl Fn(usize) -> &'a [f64],
    look: f64,
) -> Result<Option<Closest>, KinematicsError> {
    closest_of(shapes, chain, times, positions, look, |_| true)
}

/// As [`closest`], among the pairs of a robot's shape and an obstacle only.
pub fn closest_to_world<'a>(
    shapes: &cps_robot::Shapes,
    chain: &SerialChain,
    times: &[f64],
    positions: impl Fn(usize) -> &'a [f64],
    look: f64,
) -> Result<Option<Closest>, KinematicsError> {
    closest_of(shapes, chain, times, positions, look, |o| {
        matches!(o, cps_geometry::Other::Obstacle(_))
    })
}

fn closest_of<'a>(
    shapes: &cps_robot::Shapes,
    chain: &SerialChain,
    times: &[f64],
    positions: impl Fn(usize) -> &'a [f64],
    look: f64,
    counts: impl Fn(cps_geometry::Other) -> bool,
) -> Result<Option<Closest>, KinematicsError> {
    let model = shapes.model();
    let mut b = ClearanceBuffers::default();
    let mut best: Option<(usize, cps_geometry::Contact)> = None;
    for (k, _) in times.iter().enumerate() {
        b.q.clear();
        b.q.extend((0..chain.dof()).map(|j| positions(j)[k]));
        chain.frames_into(&b.q, &mut b.frames)?;
        model.within_into(&b.frames, look, &mut b.centres, &mut b.near);
        for c in b.near.iter().filter(|c| counts(model.pair(c.pair).1)) {
            if best.is_none_or(|(_, x)| c.separation.distance < x.separation.distance) {
                best = Some((k, *c));
            }
        }
    }
    Ok(best.map(|(k, c)| {
        let (a, b) = model.pair_names(c.pair);
        Closest {
            first: a.to_string(),
            second: b.to_string(),
            time: times[k],
            distance: c.separation.distance,
        }
    }))
}
