//! Carrying a learned movement to a new start and goal without distorting it.
//!
//! The thesis's form (Ijspeert et al. 2013) scales the forcing term of each dimension by
//! its own `g − y0`: a goal on the other side of the start mirrors that dimension, a
//! dimension that hardly moved in the demonstration is blown up by a huge factor (or
//! flattened), and a goal rotated relative to the demonstration shears the shape. Here the
//! movement is first written in the goal-robust form (Hoffmann et al. 2009), whose forcing
//! does not depend on the endpoints, and then its forcing is transformed as a whole by
//! `S = s R` ([`Retarget`]): `R` the smallest rotation that turns the demonstration's
//! start→goal direction into the new one (in the plane of the two; in one dimension, a
//! sign), `s` a scale. Because the transformation system is linear with scalar gains, the
//! movement relative to the goal is transformed by the same `S`:
//!
//! `y'(t) = g' + S (y(t) − g)` exactly, when `S (g − y0) = g' − y0'` ([`Retarget::Similar`]).
//!
//! With [`Retarget::Rotate`] (`s = 1`) or [`Retarget::Translate`] (`S = I`) the shape keeps
//! its size and the difference in distance is taken up by the goal-robust form's smooth
//! correction; that is the right choice for a movement that returns near its start (a
//! circle, a wipe), whose start→goal distance says nothing about its size. A
//! [`PoseDmp`](crate::PoseDmp) applies the same `R` to the orientation's forcing, on one
//! shared phase (Koutras & Doulgeri 2020 give this rotation-and-scale form for the task
//! space).

use nalgebra::DMatrix;

use crate::{DiscreteDmp, DmpError, Formulation};

/// How a movement is carried to new endpoints (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Retarget {
    /// Shape and size as demonstrated, translated; the new start→goal distance is taken
    /// up smoothly (the goal-robust form as it is).
    Translate,
    /// Rotated so that the start→goal direction points at the new goal; size kept. The
    /// default: it never blows a movement up, whatever its start→goal distance.
    #[default]
    Rotate,
    /// Rotated and scaled by the ratio of the start→goal distances: the whole movement is
    /// the demonstration under a similarity transform. Refused when the demonstration
    /// returns to (within 1e-9 of its extent) its start, which gives no direction; for a
    /// movement that ends near its start the scale is huge (check [`Retargeted::scale`]).
    Similar,
}

/// A movement carried to new endpoints: the goal-robust DMP and its weights, and the
/// transform `S = scale · rotation` its forcing went through.
#[derive(Debug, Clone)]
pub struct Retargeted {
    /// The DMP (goal-robust form, the new endpoints, the same grid).
    pub dmp: DiscreteDmp,
    /// Its weights.
    pub weights: Vec<f64>,
    /// `R`, dims × dims.
    pub rotation: DMatrix<f64>,
    /// `s`.
    pub scale: f64,
}

/// How far a new start or goal may scale an Ijspeert model's forcing term before cps
/// says the shape will be distorted: by more than this factor up or down.
pub const SHAPE_SCALING_WARNED: f64 = 2.0;

impl DiscreteDmp {
    /// Sentences on how rolling this model (its start and goal the ones it was learned
    /// with) out from `start` to `goal` distorts its shape: in the Ijspeert formulation the
    /// forcing term of each dimension scales by `(goal − start) / (g − y0)`, so a factor
    /// below zero mirrors the shape and one beyond [`SHAPE_SCALING_WARNED`] (either way)
    /// stretches or squashes it; a dimension whose learned amplitude is zero cannot be
    /// scaled at all. None for the goal-robust formulation, whose shape a new start or
    /// goal only corrects smoothly.
    pub fn shape_warnings(&self, names: &[String], start: &[f64], goal: &[f64]) -> Vec<String> {
        if self.config().formulation != Formulation::Ijspeert2013 {
            return Vec::new();
        }
        let mut out = Vec::new();
        for d in 0..self.dims() {
            let name = names.get(d).cloned().unwrap_or_else(|| format!("y{d}"));
            let learned = self.goal()[d] - self.start()[d];
            let now = goal.get(d).copied().unwrap_or(0.0) - start.get(d).copied().unwrap_or(0.0);
            if learned == 0.0 {
                continue;
            }
            let k = now / learned;
            let how = if k < 0.0 {
                format!("mirrors it (×{k:.2})")
            } else if k > SHAPE_SCALING_WARNED {
                format!("stretches it ×{k:.2}")
            } else if k < 1.0 / SHAPE_SCALING_WARNED {
                format!("squashes it ×{k:.2}")
            } else {
                continue;
            };
            out.push(format!(
                "{name}: goal − start is {now:.4} where the model learned {learned:.4}, which {how} in the thesis's (Ijspeert) formulation; imitate with --formulation robust to keep the shape"
            ));
        }
        out
    }

    /// The same DMP in another formulation and with other endpoints (the grid does not
    /// depend on the formulation).
    pub(crate) fn reformulated(
        &self,
        formulation: Formulation,
        start: &[f64],
        goal: &[f64],
    ) -> Result<Self, DmpError> {
        let mut config = *self.config();
        config.formulation = formulation;
        self.with_config_and_endpoints(config, start, goal)
    }

    /// The weights that give this DMP's movement (with `weights`, same endpoints) in the
    /// goal-robust form: `w' = w` if it is goal-robust already, else `(g − y0)(w/(α_z β_z)
    /// + 1)` per dimension (exact: the phase `x` is the basis's combination of all ones).
    pub fn goal_robust_weights(&self, weights: &[f64]) -> Vec<f64> {
        let c = self.config();
        match c.formulation {
            Formulation::GoalRobust => weights.to_vec(),
            Formulation::Ijspeert2013 => {
                let k = c.alpha_z * c.beta_z;
                let nb = self.n_basis();
                weights
                    .iter()
                    .enumerate()
                    .map(|(i, w)| self.amplitude(i / nb) * (w / k + 1.0))
                    .collect()
            }
        }
    }

    /// This movement carried to `start` → `goal` by `mode` (see the module docs).
    ///
    /// # Panics
    /// If `weights.len() != self.n_weights()`.
    pub fn retarget(
        &self,
        weights: &[f64],
        start: &[f64],
        goal: &[f64],
        mode: Retarget,
    ) -> Result<Retargeted, DmpError> {
        assert_eq!(weights.len(), self.n_weights(), "weight vector length");
        let dmp = self.reformulated(Formulation::GoalRobust, start, goal)?;
        let dims = self.dims();
        let old: Vec<f64> = (0..dims).map(|d| self.amplitude(d)).collect();
        let new: Vec<f64> = (0..dims).map(|d| dmp.amplitude(d)).collect();
        let (rotation, scale) = match mode {
            Retarget::Translate => (DMatrix::identity(dims, dims), 1.0),
            Retarget::Rotate => (rotation_between(&old, &new), 1.0),
            Retarget::Similar => {
                let (lo, ln) = (norm(&old), norm(&new));
                let extent = self.extent(weights);
                if lo <= 1e-9 * extent.max(1e-300) {
                    return Err(DmpError::CannotRetarget(format!(
                        "the movement ends {lo:.3e} from its start (it reaches {extent:.3e} away): its start→goal distance gives no direction or size to scale by; use `rotate` or `translate`"
                    )));
                }
                (rotation_between(&old, &new), ln / lo)
            }
        };
        let w = self.goal_robust_weights(weights);
        let nb = self.n_basis();
        let mut out = vec![0.0; w.len()];
        for i in 0..nb {
            for r in 0..dims {
                out[r * nb + i] = scale
                    * (0..dims)
                        .map(|c| rotation[(r, c)] * w[c * nb + i])
                        .sum::<f64>();
            }
        }
        Ok(Retargeted {
            dmp,
            weights: out,
            rotation,
            scale,
        })
    }

    /// The largest distance of the rolled-out movement from its start.
    fn extent(&self, weights: &[f64]) -> f64 {
        let traj = self.rollout(weights);
        (0..traj.n_samples())
            .map(|k| {
                (0..self.dims())
                    .map(|d| (traj.position(d)[k] - self.start()[d]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max)
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// The smallest rotation taking the direction of `from` to that of `to`, in any
/// dimension: a rotation by the angle between them in the plane they span, the identity
/// on its complement. Opposite directions turn by π in the plane of `from` and the
/// coordinate axis most orthogonal to it (a rotation, never a mirror, from 2 dimensions
/// up; in 1 dimension the only way is the sign). A zero vector gives the identity.
pub fn rotation_between(from: &[f64], to: &[f64]) -> DMatrix<f64> {
    let n = from.len();
    let mut r = DMatrix::identity(n, n);
    let (nf, nt) = (norm(from), norm(to));
    if nf == 0.0 || nt == 0.0 {
        return r;
    }
    let u: Vec<f64> = from.iter().map(|x| x / nf).collect();
    let t: Vec<f64> = to.iter().map(|x| x / nt).collect();
    let cos = u
        .iter()
        .zip(&t)
        .map(|(a, b)| a * b)
        .sum::<f64>()
        .clamp(-1.0, 1.0);
    if n == 1 {
        r[(0, 0)] = cos.signum();
        return r;
    }
    // v: the unit vector of the plane orthogonal to u.
    let mut v: Vec<f64> = t.iter().zip(&u).map(|(b, a)| b - cos * a).collect();
    let mut nv = norm(&v);
    if nv < 1e-12 {
        if cos > 0.0 {
            return r; // the same direction
        }
        let axis = (0..n)
            .min_by(|&i, &j| u[i].abs().total_cmp(&u[j].abs()))
            .unwrap_or(0);
        v = (0..n)
            .map(|i| f64::from(u8::from(i == axis)) - u[axis] * u[i])
            .collect();
        nv = norm(&v);
    }
    v.iter_mut().for_each(|x| *x /= nv);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    // R = I + (cos − 1)(u uᵀ + v vᵀ) + sin (v uᵀ − u vᵀ)
    for i in 0..n {
        for j in 0..n {
            r[(i, j)] +=
                (cos - 1.0) * (u[i] * u[j] + v[i] * v[j]) + sin * (v[i] * u[j] - u[i] * v[j]);
        }
    }
    r
}
