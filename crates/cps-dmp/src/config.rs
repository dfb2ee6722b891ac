//! DMP parameters with literature defaults.

use crate::DmpError;

/// How the forcing term enters the transformation system. Both forms share
/// `tau ż = alpha_z (beta_z (g − y) − z) + f`, `tau ẏ = z` (τ is the movement's duration
/// in seconds: the phase reaches `exp(−alpha_x)` at `t = τ`), with `Φ(x) w =
/// x Σ ψ_i(x) w_i / Σ ψ_i(x)` the weighted basis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Formulation {
    /// Ijspeert et al. (2013), the thesis's form: `f = (g − y0) · Φ(x) w`. A new goal
    /// scales the whole movement by `(g' − y0)/(g − y0)` per dimension (mirrored when the
    /// sign changes); with `g = y0` the forcing term vanishes.
    #[default]
    #[cfg_attr(feature = "serde", serde(rename = "ijspeert"))]
    Ijspeert2013,
    /// Hoffmann et al. (2009) / Pastor et al. (2009): `f = α_z β_z (Φ(x) w − (g − y0) x)`,
    /// independent of `g − y0`: start ≈ goal is fine (e.g. a loop returning to its start),
    /// and a new goal adds a smooth correction instead of rescaling the path.
    #[cfg_attr(feature = "serde", serde(rename = "robust"))]
    GoalRobust,
}

impl Formulation {
    /// Every formulation, in the order of its names.
    pub const ALL: [Formulation; 2] = [Formulation::Ijspeert2013, Formulation::GoalRobust];

    /// Its name, the same in experiment files, on the command line, in Python and in model
    /// files: `"ijspeert"` or `"robust"`.
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Ijspeert2013 => "ijspeert",
            Formulation::GoalRobust => "robust",
        }
    }

    /// The name version 1 model files gave it (`"ijspeert2013"`, `"goal_robust"`): read
    /// in those files, refused everywhere else with its present name.
    pub fn former_name(self) -> &'static str {
        match self {
            Formulation::Ijspeert2013 => "ijspeert2013",
            Formulation::GoalRobust => "goal_robust",
        }
    }
}

crate::names::names!(Formulation, "formulation", former);

/// Parameters of a discrete DMP, shared by all its dimensions.
///
/// Defaults follow Ijspeert et al. (2013) and the thesis: `alpha_z = 25`,
/// `beta_z = alpha_z / 4` (critical damping), `alpha_x = alpha_z / 3`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DmpConfig {
    /// Spring-damper gain `alpha_z` of the transformation system (1/s in units of 1/tau).
    /// Default 25 (Ijspeert et al. 2013).
    pub alpha_z: f64,
    /// Spring gain ratio `beta_z`. Default `alpha_z / 4`, which makes the unforced system
    /// critically damped.
    pub beta_z: f64,
    /// Decay rate `alpha_x` of the canonical system. Default `alpha_z / 3`, so the phase
    /// ends at `exp(-alpha_x) ≈ 2.4e-4` after `tau` seconds.
    pub alpha_x: f64,
    /// Number of Gaussian basis functions per dimension (≥ 1).
    pub n_basis: usize,
    /// Duration of the movement in seconds (> 0). The phase reaches `exp(-alpha_x)` at
    /// `t = tau`; doubling `tau` traces the same path twice as slowly.
    pub tau: f64,
    /// How the forcing term enters; default [`Formulation::Ijspeert2013`].
    #[cfg_attr(feature = "serde", serde(default))]
    pub formulation: Formulation,
    /// Requested time step in seconds (0 < dt < tau). The grid uses
    /// `K = round(tau / dt)` steps of exactly `tau / K`, so the last sample is at `tau`.
    pub dt: f64,
}

impl DmpConfig {
    /// A configuration with the literature's gains and the given basis count, duration and
    /// time step.
    pub fn new(n_basis: usize, tau: f64, dt: f64) -> Self {
        let alpha_z = 25.0;
        Self {
            alpha_z,
            beta_z: alpha_z / 4.0,
            alpha_x: alpha_z / 3.0,
            n_basis,
            tau,
            dt,
            formulation: Formulation::Ijspeert2013,
        }
    }

    /// Checks every field once; the error names the field and the rule it broke.
    pub fn validate(&self) -> Result<(), DmpError> {
        positive("alpha_z", self.alpha_z)?;
        positive("beta_z", self.beta_z)?;
        positive("alpha_x", self.alpha_x)?;
        positive("tau", self.tau)?;
        positive("dt", self.dt)?;
        at_least_one("n_basis", self.n_basis)?;
        // Beyond these the dynamics stop meaning anything: a phase that has decayed below
        // e^-100 leaves every basis function at zero, and gains above 1e4 (in units of
        // 1/tau) make the movement a step.
        at_most("alpha_z", self.alpha_z, MAX_GAIN, "must be at most 1e4")?;
        at_most("beta_z", self.beta_z, MAX_GAIN, "must be at most 1e4")?;
        at_most(
            "alpha_x",
            self.alpha_x,
            MAX_PHASE_DECAY,
            "must be at most 100 (the phase would end below e^-100, every basis function at zero)",
        )?;
        at_most("tau", self.tau, MAX_TAU, "must be at most 1e6 s")?;
        at_most(
            "n_basis",
            self.n_basis as f64,
            MAX_BASIS as f64,
            "must be at most 100000",
        )?;
        if self.dt >= self.tau {
            return Err(DmpError::InvalidConfig {
                field: "dt",
                rule: "must be smaller than tau",
                value: self.dt,
            });
        }
        let steps = self.tau / self.dt;
        if steps > MAX_STEPS as f64 {
            return Err(DmpError::InvalidConfig {
                field: "dt",
                rule: "gives more than 1e7 steps for this tau",
                value: self.dt,
            });
        }
        // The basis features are stored per sample (three copies, 8 bytes each).
        if (steps.round() + 1.0) * self.n_basis as f64 > MAX_FEATURES as f64 {
            return Err(DmpError::InvalidConfig {
                field: "n_basis",
                rule: "times the samples (tau / dt + 1) exceeds 1e8 basis-feature values (≈ 2.4 GB); use fewer basis functions or a larger dt",
                value: self.n_basis as f64,
            });
        }
        Ok(())
    }

    /// Number of steps `K = round(tau / dt)` (at least 1); the grid has `K + 1` samples.
    pub fn n_steps(&self) -> usize {
        ((self.tau / self.dt).round() as usize).max(1)
    }

    /// The step actually used, `tau / K` in seconds.
    pub fn step(&self) -> f64 {
        self.tau / self.n_steps() as f64
    }
}

/// `value` must be finite and > 0; the error names `field`.
pub(crate) fn positive(field: &'static str, value: f64) -> Result<(), DmpError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(DmpError::InvalidConfig {
            field,
            rule: "must be finite and > 0",
            value,
        })
    }
}

/// Most steps `round(tau / dt)` accepted by [`DmpConfig::validate`].
pub const MAX_STEPS: usize = 10_000_000;
/// Largest magnitude of a coordinate (a start, a goal, a via point, a demonstration's
/// sample) that cps takes: 1e6 task units (a thousand kilometres in metres).
pub const MAX_COORDINATE: f64 = 1e6;
/// Most samples × basis functions accepted by [`DmpConfig::validate`].
pub const MAX_FEATURES: usize = 100_000_000;
/// Largest `alpha_z`, `beta_z` accepted by [`DmpConfig::validate`].
pub const MAX_GAIN: f64 = 1e4;
/// Largest `alpha_x` accepted by [`DmpConfig::validate`].
pub const MAX_PHASE_DECAY: f64 = 100.0;
/// Largest `tau` in seconds accepted by [`DmpConfig::validate`].
pub const MAX_TAU: f64 = 1e6;
/// Most basis functions per dimension accepted by [`DmpConfig::validate`].
pub const MAX_BASIS: usize = 100_000;

/// `value` must be at most `max`; the error names `field` and the rule.
pub(crate) fn at_most(
    field: &'static str,
    value: f64,
    max: f64,
    rule: &'static str,
) -> Result<(), DmpError> {
    if value <= max {
        Ok(())
    } else {
        Err(DmpError::InvalidConfig { field, rule, value })
    }
}

/// A count that must be at least 1; the error names `field`.
pub(crate) fn at_least_one(field: &'static str, count: usize) -> Result<(), DmpError> {
    if count == 0 {
        Err(DmpError::InvalidConfig {
            field,
            rule: "must be at least 1",
            value: 0.0,
        })
    } else {
        Ok(())
    }
}
