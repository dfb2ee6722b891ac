//! Cartesian orientation DMPs on unit quaternions (Ude, Nemec, Petrič & Morimoto 2014),
//! so a tool's orientation can be learned and generated next to its position.
//!
//! State: orientation `q` and scaled angular velocity `η = τ ω` (world frame). With the
//! discrete phase `x` and the Gaussian basis of [`crate::DiscreteDmp`]:
//!
//! `τ η̇ = α_z (β_z · 2 log(g ∗ q̄) − η) + f(x)`, `τ q̇ = ½ η ∗ q`, `f(x) = Φ(x) w` per axis,
//!
//! where `2 log(g ∗ q̄)` is the rotation vector from `q` to the goal `g` (shortest way).
//! The forcing term is not scaled by the start-to-goal rotation (Ude's `diag(2 log(g q̄₀))`
//! scaling vanishes on an axis without rotation, the orientation analogue of start = goal).
//! With [`Formulation::GoalRobust`] the forcing also subtracts `α_z β_z · 2 log(g q̄₀) · x`,
//! the orientation analogue of Hoffmann et al.'s form: a new start or goal then turns the
//! tool smoothly from rest instead of with the spring's full initial pull.
//! Integration is Heun's second-order method on `(q, η)`, every orientation update being
//! the exact quaternion exponential `q ← exp(h η̄ / 2τ) ∗ q` of the step's mean `η̄`, so
//! every sample is a unit quaternion by construction.

use nalgebra::{UnitQuaternion, Vector3};

use crate::{DiscreteDmp, DmpConfig, DmpError, Formulation};

/// A sampled orientation trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct OrientationTrajectory {
    /// Sample times in seconds.
    pub times: Vec<f64>,
    /// Orientation at each sample.
    pub orientation: Vec<UnitQuaternion<f64>>,
    /// Angular velocity (rad/s, world frame) at each sample.
    pub angular_velocity: Vec<Vector3<f64>>,
}

/// An orientation DMP: start and goal orientations, gains, basis and time grid.
#[derive(Debug, Clone)]
pub struct QuaternionDmp {
    grid: DiscreteDmp,
    start: UnitQuaternion<f64>,
    goal: UnitQuaternion<f64>,
}

impl QuaternionDmp {
    /// An orientation DMP from `start` to `goal` with `config` (its formulation chooses
    /// whether the goal-robust term is subtracted; see the module docs). Weights: 3 × `n_basis`, axis-major (x, y, z).
    pub fn new(
        config: DmpConfig,
        start: UnitQuaternion<f64>,
        goal: UnitQuaternion<f64>,
    ) -> Result<Self, DmpError> {
        let finite = |q: &UnitQuaternion<f64>| q.coords.iter().all(|v| v.is_finite());
        if !finite(&start) || !finite(&goal) {
            return Err(DmpError::NotFinite {
                what: "orientation",
                index: 0,
                value: f64::NAN,
            });
        }
        Ok(Self {
            grid: DiscreteDmp::new(config, &[0.0; 3], &[0.0; 3])?,
            start,
            goal,
        })
    }

    /// Number of weights: `3 · n_basis`.
    pub fn n_weights(&self) -> usize {
        self.grid.n_weights()
    }

    /// The start orientation.
    pub fn start(&self) -> UnitQuaternion<f64> {
        self.start
    }

    /// The goal orientation.
    pub fn goal(&self) -> UnitQuaternion<f64> {
        self.goal
    }

    /// The same DMP with another goal.
    pub fn with_goal(&self, goal: UnitQuaternion<f64>) -> Self {
        Self {
            goal,
            ..self.clone()
        }
    }

    /// `α_z β_z · 2 log(g q̄₀)` in the goal-robust form (subtracted from the forcing term
    /// times the phase), zero otherwise.
    fn lift(&self) -> Vector3<f64> {
        let c = self.grid.config();
        match c.formulation {
            Formulation::GoalRobust => {
                c.alpha_z * c.beta_z * (self.goal * self.start.inverse()).scaled_axis()
            }
            Formulation::Ijspeert2013 => Vector3::zeros(),
        }
    }

    /// The configuration (gains, basis, τ, dt, formulation).
    pub fn config(&self) -> &DmpConfig {
        self.grid.config()
    }

    /// The phase at every sample of the grid.
    pub fn phases(&self) -> &[f64] {
        self.grid.phases()
    }

    /// The same DMP with other endpoints and the goal-robust form, and the weights that
    /// give it this DMP's forcing: `w` if it was goal-robust, else `w + α_z β_z 2 log(g
    /// q̄₀)` per axis (exact: the phase is the basis's combination of all ones).
    pub(crate) fn goal_robust(
        &self,
        weights: &[f64],
        start: UnitQuaternion<f64>,
        goal: UnitQuaternion<f64>,
    ) -> Result<(Self, Vec<f64>), DmpError> {
        let nb = self.grid.n_basis();
        let lift = match self.config().formulation {
            Formulation::GoalRobust => Vector3::zeros(),
            Formulation::Ijspeert2013 => {
                let c = self.config();
                c.alpha_z * c.beta_z * (self.goal * self.start.inverse()).scaled_axis()
            }
        };
        let w = weights
            .iter()
            .enumerate()
            .map(|(i, w)| w + lift[i / nb])
            .collect();
        let grid = self
            .grid
            .reformulated(Formulation::GoalRobust, &[0.0; 3], &[0.0; 3])?;
        Ok((Self { grid, start, goal }, w))
    }

    /// Rolls out the DMP on its grid.
    ///
    /// # Panics
    /// If `weights.len() != n_weights()`.
    pub fn rollout(&self, weights: &[f64]) -> OrientationTrajectory {
        assert_eq!(weights.len(), self.n_weights(), "weight vector length");
        let cfg = self.grid.config();
        let (nb, ns) = (self.grid.n_basis(), self.grid.n_samples());
        let h = cfg.step();
        let (tau, az, bz) = (cfg.tau, cfg.alpha_z, cfg.beta_z);
        let mut q = self.start;
        let mut eta = Vector3::zeros();
        let mut out = OrientationTrajectory {
            times: self.grid.times().to_vec(),
            orientation: Vec::with_capacity(ns),
            angular_velocity: Vec::with_capacity(ns),
        };
        // The forcing term of every axis at every sample, column by column of the features
        // (contiguous, so the products vectorise), before the sequential integration.
        let mut forcing = vec![0.0; 3 * ns];
        for (a, fa) in forcing.chunks_exact_mut(ns).enumerate() {
            for i in 0..nb {
                let w = weights[a * nb + i];
                for (f, phi) in fa.iter_mut().zip(self.grid.feature_column(i)) {
                    *f += phi * w;
                }
            }
        }
        // The goal-robust form subtracts α_z β_z · 2 log(g q̄₀) · x (no jump at the start).
        let lift = self.lift();
        let phases = self.grid.phases();
        let f = |k: usize| {
            Vector3::new(forcing[k], forcing[ns + k], forcing[2 * ns + k]) - lift * phases[k]
        };
        let eta_dot = |q: &UnitQuaternion<f64>, eta: &Vector3<f64>, f: &Vector3<f64>| {
            (az * (bz * (self.goal * q.inverse()).scaled_axis() - eta) + f) / tau
        };
        let mut f0 = f(0);
        for k in 0..ns {
            out.orientation.push(q);
            out.angular_velocity.push(eta / tau);
            // Heun's method: predict with the slopes at k, correct with those at the
            // prediction; the orientation turns by the mean angular velocity.
            let f1 = f((k + 1).min(ns - 1));
            let d1 = eta_dot(&q, &eta, &f0);
            let eta_p = eta + h * d1;
            let q_p = UnitQuaternion::from_scaled_axis(eta * (h / tau)) * q;
            let d2 = eta_dot(&q_p, &eta_p, &f1);
            let eta_next = eta + 0.5 * h * (d1 + d2);
            q = UnitQuaternion::from_scaled_axis((eta + eta_next) * (0.5 * h / tau)) * q;
            q.renormalize_fast();
            eta = eta_next;
            f0 = f1;
        }
        out
    }

    /// Learns the weights from an orientation demonstration (time stamps strictly
    /// increasing, at least 3 samples): time-normalised onto the grid (spherical linear
    /// interpolation), angular velocity by central differences of the rotation between
    /// neighbours, the forcing target `f = τ² ω̇ − α_z (β_z 2 log(g q̄) − τ ω)` and ridge
    /// regression with `lambda`. Start and goal are the demonstration's first and last
    /// orientations. Returns the DMP and its weights.
    pub fn learn(
        config: DmpConfig,
        times: &[f64],
        orientations: &[UnitQuaternion<f64>],
        lambda: f64,
    ) -> Result<(Self, Vec<f64>), DmpError> {
        if orientations.len() != times.len() {
            return Err(DmpError::InvalidDemonstration {
                reason: format!(
                    "{} time stamps for {} orientations",
                    times.len(),
                    orientations.len()
                ),
            });
        }
        // Validates times (≥ 3, strictly increasing, finite) through the common checks.
        let rows: Vec<Vec<f64>> = orientations
            .iter()
            .map(|q| q.coords.iter().copied().collect())
            .collect();
        let demo = crate::Demonstration::new(times.to_vec(), &rows)?;
        if !(lambda.is_finite() && lambda >= 0.0) {
            return Err(DmpError::InvalidConfig {
                field: "lambda",
                rule: "must be finite and ≥ 0",
                value: lambda,
            });
        }
        let n = orientations.len();
        let dmp = Self::new(config, orientations[0], orientations[n - 1])?;
        let cfg = *dmp.grid.config();
        let ns = dmp.grid.n_samples();
        let (h, tau, az, bz) = (cfg.step(), cfg.tau, cfg.alpha_z, cfg.beta_z);
        // Resample by slerp at normalised times.
        let (t0, span) = (times[0], demo.duration());
        let mut seg = 0;
        let q: Vec<UnitQuaternion<f64>> = (0..ns)
            .map(|k| {
                let t = t0 + span * k as f64 / (ns - 1) as f64;
                while seg + 2 < n && times[seg + 1] < t {
                    seg += 1;
                }
                let u = ((t - times[seg]) / (times[seg + 1] - times[seg])).clamp(0.0, 1.0);
                orientations[seg]
                    .try_slerp(&orientations[seg + 1], u, 1e-12)
                    .unwrap_or(orientations[seg])
            })
            .collect();
        let rot = |a: usize, b: usize| (q[b] * q[a].inverse()).scaled_axis();
        let omega: Vec<Vector3<f64>> = (0..ns)
            .map(|k| match k {
                0 => rot(0, 1) / h,
                k if k == ns - 1 => rot(ns - 2, ns - 1) / h,
                k => rot(k - 1, k + 1) / (2.0 * h),
            })
            .collect();
        let domega = |k: usize| match k {
            0 => (omega[1] - omega[0]) / h,
            k if k == ns - 1 => (omega[ns - 1] - omega[ns - 2]) / h,
            k => (omega[k + 1] - omega[k - 1]) / (2.0 * h),
        };
        let goal = orientations[n - 1];
        let nb = cfg.n_basis;
        let mut gram = faer::Mat::<f64>::zeros(nb, nb);
        let mut rhs = faer::Mat::<f64>::zeros(nb, 3);
        for k in 0..ns {
            let f = tau * tau * domega(k)
                - az * (bz * (goal * q[k].inverse()).scaled_axis() - tau * omega[k])
                + dmp.lift() * dmp.grid.phases()[k];
            for i in 0..nb {
                let pi = dmp.grid.feature_column(i)[k];
                for j in 0..nb {
                    gram[(i, j)] += pi * dmp.grid.feature_column(j)[k];
                }
                for a in 0..3 {
                    rhs[(i, a)] += pi * f[a];
                }
            }
        }
        for i in 0..nb {
            gram[(i, i)] += lambda;
        }
        let sol = match gram.llt(faer::Side::Lower) {
            Ok(l) => faer::linalg::solvers::Solve::solve(&l, &rhs),
            Err(_) => {
                return Err(DmpError::NumericalFailure(
                    "the orientation regression is singular; use λ > 0".into(),
                ));
            }
        };
        let weights = (0..3)
            .flat_map(|a| (0..nb).map(move |i| (a, i)))
            .map(|(a, i)| sol[(i, a)])
            .collect();
        Ok((dmp, weights))
    }
}
