//! Running a DMP step by step inside a control loop.

use crate::discretize::StepCoefficients;
use crate::{CanonicalSystem, DiscreteDmp, DmpError, Formulation};

/// Per-step inputs of [`OnlineDmp::step_with`].
#[derive(Debug, Clone, Copy, Default)]
pub struct StepInput<'a> {
    /// Additive coupling term per dimension, in the units of `f` (added to
    /// `tau ż`), held constant over the step: e.g. an obstacle-avoidance push.
    pub coupling: Option<&'a [f64]>,
    /// Tracking error `e ≥ 0` between the robot and the DMP (metres): the phase slows by
    /// `1/(1 + gain · e)` (phase stopping, Ijspeert et al. 2013), so the movement waits
    /// for a robot that lags.
    pub tracking_error: f64,
}

/// A DMP advanced one control period at a time, with the goal and the duration τ
/// changeable between steps.
///
/// Stepping uses the same exact discretisation as [`DiscreteDmp::rollout_into`] (the
/// forcing term held linearly over the step), so stepping with the grid's step `tau/K`
/// reproduces the batch rollout to rounding; any other `dt` is integrated just as
/// exactly for that step length.
#[derive(Debug, Clone)]
pub struct OnlineDmp {
    dmp: DiscreteDmp,
    weights: Vec<f64>,
    goal: Vec<f64>,
    tau: f64,
    error_gain: f64,
    x: f64,
    t: f64,
    y: Vec<f64>,
    z: Vec<f64>,
    /// Forcing `f` at the current phase, per dimension (held in sync with `x`).
    f: Vec<f64>,
    /// The forcing at the start of the step being taken.
    f_prev: Vec<f64>,
    /// Acceleration at the current sample.
    acc: Vec<f64>,
    features: Vec<f64>,
    /// Step coefficients and the (tau, dt) they were made for.
    cache: Option<(f64, f64, StepCoefficients)>,
}

impl OnlineDmp {
    /// Starts `dmp` with `weights` at its start, phase 1, time 0.
    ///
    /// # Panics
    /// If `weights.len() != dmp.n_weights()`.
    pub fn new(dmp: &DiscreteDmp, weights: &[f64]) -> Self {
        assert_eq!(weights.len(), dmp.n_weights(), "weight vector length");
        let dims = dmp.dims();
        let mut runner = Self {
            dmp: dmp.clone(),
            weights: weights.to_vec(),
            goal: dmp.goal().to_vec(),
            tau: dmp.config().tau,
            error_gain: 1.0,
            x: 1.0,
            t: 0.0,
            y: dmp.start().to_vec(),
            z: vec![0.0; dims],
            f: vec![0.0; dims],
            f_prev: vec![0.0; dims],
            acc: vec![0.0; dims],
            features: vec![0.0; dmp.n_basis()],
            cache: None,
        };
        runner.update_forcing();
        runner.update_acceleration();
        runner
    }

    /// The acceleration of the current state without coupling: `(α_z β_z (g − y) − α_z z +
    /// f) / τ²`.
    fn update_acceleration(&mut self) {
        let cfg = self.dmp.config();
        let k = cfg.alpha_z * cfg.beta_z;
        for d in 0..self.dmp.dims() {
            let u = k * self.goal[d] + self.f[d];
            self.acc[d] = (u - k * self.y[d] - cfg.alpha_z * self.z[d]) / (self.tau * self.tau);
        }
    }

    /// Starts moving with physical velocity `v` (units per second) instead of at rest —
    /// for a movement that continues another one.
    pub fn with_velocity(mut self, v: &[f64]) -> Result<Self, DmpError> {
        if v.len() != self.dmp.dims() {
            return Err(DmpError::DimensionMismatch {
                what: "velocity",
                got: v.len(),
                expected: self.dmp.dims(),
            });
        }
        if let Some((index, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return Err(DmpError::NotFinite {
                what: "velocity",
                index,
                value,
            });
        }
        for (z, v) in self.z.iter_mut().zip(v) {
            *z = v * self.tau;
        }
        self.update_acceleration();
        Ok(self)
    }

    /// Sets the phase-stopping gain (1/m, default 1): the phase runs at `1/(1 + gain · e)`.
    pub fn with_error_gain(mut self, gain: f64) -> Self {
        self.error_gain = gain.max(0.0);
        self
    }

    /// The forcing term at the current phase and goal.
    fn update_forcing(&mut self) {
        self.dmp.basis().features(self.x, &mut self.features);
        let nb = self.dmp.n_basis();
        for d in 0..self.dmp.dims() {
            let (a, b) = self.scale(d);
            let w = &self.weights[d * nb..(d + 1) * nb];
            let phi_w: f64 = self.features.iter().zip(w).map(|(p, w)| p * w).sum();
            self.f[d] = a * phi_w + b * self.x;
        }
    }

    /// `(a, b)` of `f = a Φw + b x` for the current goal.
    fn scale(&self, d: usize) -> (f64, f64) {
        let cfg = self.dmp.config();
        let amp = self.goal[d] - self.dmp.start()[d];
        match cfg.formulation {
            Formulation::Ijspeert2013 => (amp, 0.0),
            Formulation::GoalRobust => {
                let k = cfg.alpha_z * cfg.beta_z;
                (k, -k * amp)
            }
        }
    }

    /// Changes the goal from the next step on (live goal change).
    pub fn set_goal(&mut self, goal: &[f64]) -> Result<(), DmpError> {
        if goal.len() != self.dmp.dims() {
            return Err(DmpError::DimensionMismatch {
                what: "goal",
                got: goal.len(),
                expected: self.dmp.dims(),
            });
        }
        if let Some((index, &value)) = goal.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(DmpError::NotFinite {
                what: "goal",
                index,
                value,
            });
        }
        self.goal.copy_from_slice(goal);
        self.update_forcing();
        Ok(())
    }

    /// Changes the duration τ (seconds, > 0) from the next step on: the rest of the
    /// movement runs faster or slower. The physical velocity stays continuous (the scaled
    /// state `z = τ ẏ` is rescaled).
    pub fn set_tau(&mut self, tau: f64) -> Result<(), DmpError> {
        if !(tau.is_finite() && tau > 0.0) {
            return Err(DmpError::InvalidConfig {
                field: "tau",
                rule: "must be finite and > 0",
                value: tau,
            });
        }
        for z in &mut self.z {
            *z *= tau / self.tau;
        }
        self.tau = tau;
        Ok(())
    }

    /// One step of `dt` seconds without coupling.
    pub fn step(&mut self, dt: f64) -> Result<(), DmpError> {
        self.step_with(dt, StepInput::default())
    }

    /// One step of `dt` seconds (> 0) with coupling and phase stopping.
    pub fn step_with(&mut self, dt: f64, input: StepInput<'_>) -> Result<(), DmpError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(DmpError::InvalidConfig {
                field: "dt",
                rule: "must be finite and > 0",
                value: dt,
            });
        }
        let dims = self.dmp.dims();
        if let Some(c) = input.coupling
            && c.len() != dims
        {
            return Err(DmpError::DimensionMismatch {
                what: "coupling",
                got: c.len(),
                expected: dims,
            });
        }
        let cfg = *self.dmp.config();
        let coeff = match self.cache {
            Some((tau, h, c)) if tau == self.tau && h == dt => c,
            _ => {
                let c = StepCoefficients::new(cfg.alpha_z, cfg.beta_z, self.tau, dt);
                self.cache = Some((self.tau, dt, c));
                c
            }
        };
        let cs = CanonicalSystem {
            alpha_x: cfg.alpha_x,
            tau: self.tau,
        };
        let slow = CanonicalSystem::coupling_factor(self.error_gain * input.tracking_error);
        std::mem::swap(&mut self.f, &mut self.f_prev);
        self.x = cs.step(self.x, dt, slow);
        self.update_forcing();
        for d in 0..dims {
            let c = input.coupling.map_or(0.0, |c| c[d]);
            let ug = coeff.goal_input(self.goal[d]) + c;
            let (u0, u1) = (ug + self.f_prev[d], ug + self.f[d]);
            (self.y[d], self.z[d]) = coeff.advance(self.y[d], self.z[d], u0, u1);
            self.acc[d] = coeff.acceleration(u1, self.y[d], self.z[d]);
        }
        self.t += dt;
        Ok(())
    }

    /// The forcing term at the current phase, per dimension, in the units of a coupling
    /// term: a coupling of `−forcing()` switches the movement's shape off, leaving the
    /// critically damped spring to the goal (how a movement whose phase is over settles).
    pub fn forcing(&self) -> &[f64] {
        &self.f
    }

    /// Current position.
    pub fn position(&self) -> &[f64] {
        &self.y
    }

    /// Current physical velocity `ẏ = z / τ` (units per second).
    pub fn velocity(&self) -> Vec<f64> {
        self.z.iter().map(|z| z / self.tau).collect()
    }

    /// [`Self::velocity`] into `out` (no allocation).
    pub(crate) fn velocity_into(&self, out: &mut [f64]) {
        for (o, z) in out.iter_mut().zip(&self.z) {
            *o = z / self.tau;
        }
    }

    /// Current physical acceleration (units per second²), with the coupling of the last
    /// step.
    pub fn acceleration(&self) -> &[f64] {
        &self.acc
    }

    /// Current phase `x`.
    pub fn phase(&self) -> f64 {
        self.x
    }

    /// Time since the start in seconds (sum of the steps).
    pub fn time(&self) -> f64 {
        self.t
    }

    /// The current goal.
    pub fn goal(&self) -> &[f64] {
        &self.goal
    }

    /// The current duration τ.
    pub fn tau(&self) -> f64 {
        self.tau
    }
}
