//! Movements in sequence: several DMPs chained into one movement that is continuous in
//! position, velocity and acceleration at every junction.
//!
//! Each segment after the first starts where and how the previous one ends: from its
//! position (the segment's own start is replaced by it, its shape translated there, in
//! the goal-robust form) with its velocity. Its acceleration there would still jump,
//! since the goal, the forcing term and τ change; a correction `c₀ x(t)` added to the
//! segment's forcing term, with `c₀` the jump times τ², removes the jump and fades with
//! the segment's phase. It is exact within the basis: the phase is the basis's combination
//! of all ones, so the correction is a shift of every weight of the segment by `c₀ /
//! (α_z β_z)`. Each segment is integrated with the exact scheme of [`OnlineDmp`] on its own
//! grid; the input is continuous across the junction, so the movement is C² there to
//! rounding.

use crate::{DiscreteDmp, DmpError, Formulation, OnlineDmp, Trajectory};

/// A sequence: the movement and the segments as they were run (each later one
/// goal-robust, started at the junction, its weights shifted by the correction).
#[derive(Debug, Clone)]
pub struct Sequenced {
    /// The whole movement: every segment's samples, each junction once.
    pub trajectory: Trajectory,
    /// The segments as run: DMP and weights.
    pub segments: Vec<(DiscreteDmp, Vec<f64>)>,
    /// The junction times (s), one fewer than the segments.
    pub junctions: Vec<f64>,
}

/// Whether a sequence corrects the acceleration at its junctions ([`sequence_with`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Junction {
    /// Continuous position, velocity and acceleration (the correction of the module docs).
    C2,
    /// Continuous position and velocity only: each later segment starts from the previous
    /// one's state as it is (the acceleration jumps; for comparison).
    C1,
}

/// The segments `(dmp, weights)` run one after the other, C² at every junction (see the
/// module docs). The first segment starts at its start at rest; every segment's goal and
/// duration are its own.
pub fn sequence(segments: &[(&DiscreteDmp, &[f64])]) -> Result<Sequenced, DmpError> {
    sequence_with(segments, Junction::C2)
}

/// [`sequence`] with the choice of junction.
pub fn sequence_with(
    segments: &[(&DiscreteDmp, &[f64])],
    junction: Junction,
) -> Result<Sequenced, DmpError> {
    let Some(&(first, w0)) = segments.first() else {
        return Err(DmpError::CannotRetarget(
            "a sequence needs at least one movement".into(),
        ));
    };
    let dims = first.dims();
    for (i, (dmp, w)) in segments.iter().enumerate() {
        if dmp.dims() != dims {
            return Err(DmpError::DimensionMismatch {
                what: if i == 0 {
                    "segment"
                } else {
                    "a later segment's dimensions"
                },
                got: dmp.dims(),
                expected: dims,
            });
        }
        if w.len() != dmp.n_weights() {
            return Err(DmpError::DimensionMismatch {
                what: "segment weights",
                got: w.len(),
                expected: dmp.n_weights(),
            });
        }
    }
    let mut times = Vec::new();
    let mut rows: Vec<[Vec<f64>; 4]> = Vec::new(); // position, velocity, acceleration, forcing
    let mut runner = OnlineDmp::new(first, w0);
    let mut offset = 0.0;
    let mut used = Vec::with_capacity(segments.len());
    let mut junctions = Vec::new();
    for (i, &(dmp, w)) in segments.iter().enumerate() {
        if i == 0 {
            used.push((dmp.clone(), w.to_vec()));
        } else {
            let (next, d, w) = continue_with(&runner, dmp, w, junction)?;
            runner = next;
            used.push((d, w));
            junctions.push(offset);
        }
        let grid = dmp.times();
        if i == 0 {
            times.push(0.0);
            rows.push(state(&runner));
        }
        for k in 1..grid.len() {
            runner.step(grid[k] - grid[k - 1])?;
            times.push(offset + grid[k]);
            rows.push(state(&runner));
        }
        offset += grid[grid.len() - 1];
    }
    let n = times.len();
    let mut traj = Trajectory::zeros(dims, times);
    for (k, [p, v, a, f]) in rows.iter().enumerate() {
        for (d, (((p, v), a), f)) in p.iter().zip(v).zip(a).zip(f).enumerate() {
            let i = d * n + k;
            traj.position[i] = *p;
            traj.velocity[i] = *v;
            traj.acceleration[i] = *a;
            traj.forcing[i] = *f;
        }
    }
    Ok(Sequenced {
        trajectory: traj,
        segments: used,
        junctions,
    })
}

fn state(r: &OnlineDmp) -> [Vec<f64>; 4] {
    [
        r.position().to_vec(),
        r.velocity(),
        r.acceleration().to_vec(),
        r.forcing().to_vec(),
    ]
}

/// The runner of `dmp` (weights `w`) continuing the state of `prev` with the same
/// position, velocity and (with [`Junction::C2`]) acceleration; the DMP and weights it runs.
fn continue_with(
    prev: &OnlineDmp,
    dmp: &DiscreteDmp,
    w: &[f64],
    junction: Junction,
) -> Result<(OnlineDmp, DiscreteDmp, Vec<f64>), DmpError> {
    let y = prev.position().to_vec();
    let v = prev.velocity();
    let a = prev.acceleration().to_vec();
    let base = dmp.goal_robust_weights(w);
    let moved = dmp.reformulated(Formulation::GoalRobust, &y, dmp.goal())?;
    let plain = OnlineDmp::new(&moved, &base).with_velocity(&v)?;
    if junction == Junction::C1 {
        return Ok((plain, moved, base));
    }
    let c = moved.config();
    let (k, tau2) = (c.alpha_z * c.beta_z, c.tau * c.tau);
    let nb = moved.n_basis();
    let shifted: Vec<f64> = base
        .iter()
        .enumerate()
        .map(|(i, w)| {
            let d = i / nb;
            w + tau2 * (a[d] - plain.acceleration()[d]) / k
        })
        .collect();
    let runner = OnlineDmp::new(&moved, &shifted).with_velocity(&v)?;
    Ok((runner, moved, shifted))
}
