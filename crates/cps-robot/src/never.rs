//! Pairs of links a robot's description leaves out of the collision checks, tried on the
//! shapes cps checks. An SRDF's `reason="Never"` comes from sampling configurations on
//! the meshes its author had (MoveIt's setup assistant), not from a proof; on the convex
//! hulls cps checks, franka_description's FR3 puts link2 into link6 at configurations
//! inside its joint ranges (14.6 mm deep at MuJoCo's random samples; 47.4 mm at the
//! witness this search finds, where MuJoCo measures the same).
//!
//! [`closest_approaches`] searches the joint box for each pair's closest approach: seeded
//! uniform samples, then a pattern search (Hooke and Jeeves, 1961) from each pair's
//! closest samples, its steps halved down to a tenth of a milliradian, within the joint
//! ranges. The rare configurations where two links meet lie in thin slivers of the box
//! (a few per thousand uniform samples for link2–link6); the local search walks from the
//! closest samples into them. It is evidence, not a proof: a pair it finds within the
//! margin must be checked; a pair it keeps apart by more than the margin over every
//! sample and every descent may be left out, with the closest approach found said.

use cps_geometry::{Body, CollisionModel};
use cps_kinematics::SerialChain;
use nalgebra::Isometry3;

/// How the joint box is searched.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeverSearch {
    /// Uniformly random configurations within the joint ranges.
    pub samples: usize,
    /// From how many of each pair's closest samples a local search descends.
    pub starts: usize,
    /// The samples' seed: the same seed gives the same approaches.
    pub seed: u64,
}

impl Default for NeverSearch {
    /// 20 000 samples, 4 descents per pair, seed 1: link2–link6's and link5–link7's
    /// penetrations on the FR3 are found from any seed tried.
    fn default() -> Self {
        NeverSearch {
            samples: 20_000,
            starts: 4,
            seed: 1,
        }
    }
}

/// A pair's closest approach over the joint box.
#[derive(Debug, Clone, PartialEq)]
pub struct PairApproach {
    /// The pair's links, as asked.
    pub first: String,
    /// The pair's second link.
    pub second: String,
    /// The smallest signed distance found between any body of the one and any of the
    /// other (m; negative: inside each other, by that depth); infinite when every body of
    /// the one rides on a frame of the other's (they never move relative to each other).
    pub closest: f64,
    /// The joint positions where it was found (rad).
    pub witness: Vec<f64>,
}

/// For each pair of link names in `pairs`, its closest approach over the joint ranges of
/// `chain` (its [`SerialChain::limits`]), the links' `bodies` placed as the guard places
/// them. Errors: a chain without joint ranges; a link of a pair with no body.
pub fn closest_approaches(
    chain: &SerialChain,
    bodies: &[Body],
    pairs: &[(String, String)],
    search: &NeverSearch,
) -> Result<Vec<PairApproach>, String> {
    let (lower, upper) = chain
        .limits()
        .ok_or("the chain has no joint ranges to search within")?;
    let (lower, upper) = (lower.to_vec(), upper.to_vec());
    for (a, b) in pairs {
        for link in [a, b] {
            if !bodies.iter().any(|x| &x.link == link) {
                return Err(format!(
                    "the link `{link}` of the pair ({a}, {b}) has no body"
                ));
            }
        }
    }
    // Every body pair of the asked link pairs, and no other: skip every other link pair.
    let mut links: Vec<&str> = bodies.iter().map(|b| b.link.as_str()).collect();
    links.sort_unstable();
    links.dedup();
    let asked = |x: &str, y: &str| {
        pairs
            .iter()
            .position(|(a, b)| (a == x && b == y) || (a == y && b == x))
    };
    let mut skip = Vec::new();
    for (i, x) in links.iter().enumerate() {
        for y in &links[i + 1..] {
            if asked(x, y).is_none() {
                skip.push((x.to_string(), y.to_string()));
            }
        }
    }
    let model = CollisionModel::new(bodies.to_vec(), Vec::new(), &skip);
    // Which asked pair each of the model's pairs belongs to.
    let owner: Vec<usize> = (0..model.pair_count())
        .map(|p| {
            let (x, y) = model.pair_names(p);
            asked(x, y).expect("the model checks only the asked pairs")
        })
        .collect();
    let mut search_state = Search {
        chain,
        model: &model,
        owner: &owner,
        frames: Vec::with_capacity(chain.dof() + 1),
        distances: vec![f64::INFINITY; pairs.len()],
    };
    // Each pair's closest samples, closest first.
    let mut best: Vec<Vec<(f64, Vec<f64>)>> = vec![Vec::new(); pairs.len()];
    let mut rng = SplitMix(search.seed);
    let mut q = vec![0.0; lower.len()];
    for _ in 0..search.samples {
        for (j, x) in q.iter_mut().enumerate() {
            *x = lower[j] + (upper[j] - lower[j]) * rng.unit();
        }
        search_state.measure(&q)?;
        for (c, kept) in best.iter_mut().enumerate() {
            let d = search_state.distances[c];
            if kept.len() < search.starts.max(1) || d < kept[kept.len() - 1].0 {
                let at = kept.partition_point(|(e, _)| *e <= d);
                kept.insert(at, (d, q.clone()));
                kept.truncate(search.starts.max(1));
            }
        }
    }
    let mut out = Vec::with_capacity(pairs.len());
    for (c, (a, b)) in pairs.iter().enumerate() {
        let (mut closest, mut witness) = (f64::INFINITY, Vec::new());
        for (d0, q0) in &best[c] {
            let (d, q) = search_state.descend(c, *d0, q0.clone(), &lower, &upper)?;
            if d < closest {
                (closest, witness) = (d, q);
            }
        }
        out.push(PairApproach {
            first: a.clone(),
            second: b.clone(),
            closest,
            witness,
        });
    }
    Ok(out)
}

/// The most configurations one descent measures.
const MAX_EVALUATIONS: usize = 20_000;

/// The model of the asked pairs, and the distances at the configuration measured last.
struct Search<'a> {
    chain: &'a SerialChain,
    model: &'a CollisionModel,
    owner: &'a [usize],
    frames: Vec<Isometry3<f64>>,
    distances: Vec<f64>,
}

impl Search<'_> {
    /// Every asked pair's distance at `q` into `distances`.
    fn measure(&mut self, q: &[f64]) -> Result<(), String> {
        self.chain
            .frames_into(q, &mut self.frames)
            .map_err(|e| e.to_string())?;
        self.distances.fill(f64::INFINITY);
        for (p, &c) in self.owner.iter().enumerate() {
            let d = self.model.distance(p, &self.frames).distance;
            self.distances[c] = self.distances[c].min(d);
        }
        Ok(())
    }

    /// Pair `c`'s distance descended from `q` (at distance `d`) by a pattern search within
    /// `[lower, upper]`: each joint moved by ± its step while that brings the pair closer,
    /// the steps halved when no move does, until they are below 0.1 mrad.
    fn descend(
        &mut self,
        c: usize,
        mut d: f64,
        mut q: Vec<f64>,
        lower: &[f64],
        upper: &[f64],
    ) -> Result<(f64, Vec<f64>), String> {
        let mut step = 0.05;
        let mut evaluations = 0;
        while step > 1e-4 && evaluations < MAX_EVALUATIONS {
            let mut moved = false;
            for j in 0..q.len() {
                for sign in [1.0, -1.0] {
                    let old = q[j];
                    q[j] = (old + sign * step).clamp(lower[j], upper[j]);
                    if q[j] == old {
                        continue;
                    }
                    self.measure(&q)?;
                    evaluations += 1;
                    if self.distances[c] < d {
                        d = self.distances[c];
                        moved = true;
                        break;
                    }
                    q[j] = old;
                }
            }
            if !moved {
                step /= 2.0;
            }
        }
        Ok((d, q))
    }
}

/// SplitMix64 (Steele, Lea and Flood, 2014): a seeded stream of numbers, the same on every
/// machine for a seed (the searches' and the planner's samples).
#[derive(Debug, Clone)]
pub struct SplitMix(pub u64);

impl SplitMix {
    /// A uniform number in [0, 1), from the top 53 bits.
    pub fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}
