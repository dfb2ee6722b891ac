//! RRT-Connect (Kuffner and LaValle, "RRT-Connect: an efficient approach to single-query
//! path planning", ICRA 2000) and shortcutting (Geraerts and Overmars, "Creating
//! high-quality paths for motion planning", IJRR 2007), on [`Free`]'s exact checks.
//!
//! Two trees grow, one from the start and one from the goal: each round one tree extends
//! one step towards a uniformly random configuration, then the other tries to connect to
//! the new node, step after step; the trees swap roles every round. A path found is
//! shortened by joining two of its points directly wherever the straight segment between
//! them is free, at pairs drawn from the same seeded stream.

use cps_robot::SplitMix;

use crate::free::Free;

/// One tree: its configurations and each node's parent (the root its own).
struct Tree {
    nodes: Vec<Vec<f64>>,
    parent: Vec<usize>,
}

impl Tree {
    fn new(root: &[f64]) -> Self {
        Tree {
            nodes: vec![root.to_vec()],
            parent: vec![0],
        }
    }

    /// The node closest to `q` (Euclidean, in radians).
    fn nearest(&self, q: &[f64]) -> usize {
        let d = |n: &[f64]| -> f64 { n.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum() };
        (0..self.nodes.len())
            .min_by(|&i, &j| d(&self.nodes[i]).total_cmp(&d(&self.nodes[j])))
            .unwrap_or(0)
    }

    /// The path from the root to node `i`.
    fn path_to(&self, mut i: usize) -> Vec<Vec<f64>> {
        let mut out = vec![self.nodes[i].clone()];
        while self.parent[i] != i {
            i = self.parent[i];
            out.push(self.nodes[i].clone());
        }
        out.reverse();
        out
    }
}

/// What one extension did.
#[derive(PartialEq)]
enum Extend {
    /// The target itself was added.
    Reached,
    /// A step towards it was added.
    Advanced,
    /// The step was not free.
    Trapped,
}

/// One step of at most `reach` radians from the node nearest `target` towards it, added
/// when the segment is free.
fn extend(free: &mut Free<'_>, tree: &mut Tree, target: &[f64], reach: f64) -> Extend {
    let near = tree.nearest(target);
    let from = &tree.nodes[near];
    let gap: f64 = from
        .iter()
        .zip(target)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt();
    let (to, outcome) = if gap <= reach {
        (target.to_vec(), Extend::Reached)
    } else {
        let k = reach / gap;
        let to = from
            .iter()
            .zip(target)
            .map(|(a, b)| a + k * (b - a))
            .collect();
        (to, Extend::Advanced)
    };
    if !free.segment(from, &to) {
        return Extend::Trapped;
    }
    tree.nodes.push(to);
    tree.parent.push(near);
    outcome
}

/// What a search tried, for a sentence when it found nothing.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Tried {
    /// Random configurations drawn.
    pub samples: usize,
    /// Nodes of the start's tree and the goal's.
    pub nodes: [usize; 2],
}

/// A free path from `start` to `goal` (both free), its first point `start` and its last
/// `goal`, with what was drawn (nothing when the straight segment is free), or what was
/// tried when none was found within `samples` random configurations.
pub(crate) fn connect(
    free: &mut Free<'_>,
    start: &[f64],
    goal: &[f64],
    samples: usize,
    reach: f64,
    rng: &mut SplitMix,
) -> Result<(Vec<Vec<f64>>, Tried), Tried> {
    if free.segment(start, goal) {
        return Ok((vec![start.to_vec(), goal.to_vec()], Tried::default()));
    }
    let (lower, upper) = {
        let (l, u) = free.range();
        (l.to_vec(), u.to_vec())
    };
    let mut trees = [Tree::new(start), Tree::new(goal)];
    // Which of `trees` grows towards the sample this round (the other connects).
    let mut grows = 0;
    let mut q = vec![0.0; start.len()];
    for drawn in 1..=samples {
        for (j, x) in q.iter_mut().enumerate() {
            *x = lower[j] + (upper[j] - lower[j]) * rng.unit();
        }
        let [a, b] = &mut trees;
        let (growing, other) = if grows == 0 { (a, b) } else { (b, a) };
        if extend(free, growing, &q, reach) != Extend::Trapped {
            let new = growing.nodes.len() - 1;
            let target = growing.nodes[new].clone();
            let mut outcome = Extend::Advanced;
            while outcome == Extend::Advanced {
                outcome = extend(free, other, &target, reach);
            }
            if outcome == Extend::Reached {
                let mut first = growing.path_to(new);
                let mut second = other.path_to(other.nodes.len() - 1);
                // `first` ends at the meeting node, `second` too: join them once.
                second.pop();
                second.reverse();
                first.extend(second);
                if grows == 1 {
                    first.reverse();
                }
                let tried = Tried {
                    samples: drawn,
                    nodes: [trees[0].nodes.len(), trees[1].nodes.len()],
                };
                return Ok((first, tried));
            }
        }
        grows = 1 - grows;
        if drawn == samples {
            break;
        }
    }
    Err(Tried {
        samples,
        nodes: [trees[0].nodes.len(), trees[1].nodes.len()],
    })
}

/// `path` shortened by `rounds` attempts to join two of its points directly (pairs drawn
/// from `rng`), then by dropping every point whose neighbours see each other.
pub(crate) fn shortcut(
    free: &mut Free<'_>,
    mut path: Vec<Vec<f64>>,
    rounds: usize,
    rng: &mut SplitMix,
) -> Vec<Vec<f64>> {
    for _ in 0..rounds {
        if path.len() < 3 {
            break;
        }
        let n = path.len();
        let i = ((rng.unit() * n as f64) as usize).min(n - 1);
        let j = ((rng.unit() * n as f64) as usize).min(n - 1);
        let (i, j) = (i.min(j), i.max(j));
        if j < i + 2 {
            continue;
        }
        if free.segment(&path[i], &path[j]) {
            path.drain(i + 1..j);
        }
    }
    let mut i = 0;
    while i + 2 < path.len() {
        if free.segment(&path[i], &path[i + 2]) {
            path.remove(i + 1);
        } else {
            i += 1;
        }
    }
    path
}
