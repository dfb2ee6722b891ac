//! DMP parameters with literature defaults.

use crate::DmpError;

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
        }
    }

    /// Checks every field once; the error names the field and the rule it broke.
    pub fn validate(&self) -> Result<(), DmpError> {
        let positive = |field, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(DmpError::InvalidConfig {
                    field,
                    rule: "must be finite and > 0",
                    value,
                })
            }
        };
        positive("alpha_z", self.alpha_z)?;
        positive("beta_z", self.beta_z)?;
        positive("alpha_x", self.alpha_x)?;
        positive("tau", self.tau)?;
        positive("dt", self.dt)?;
        if self.n_basis == 0 {
            return Err(DmpError::InvalidConfig {
                field: "n_basis",
                rule: "must be at least 1",
                value: 0.0,
            });
        }
        if self.dt >= self.tau {
            return Err(DmpError::InvalidConfig {
                field: "dt",
                rule: "must be smaller than tau",
                value: self.dt,
            });
        }
        if self.tau / self.dt > 1e8 {
            return Err(DmpError::InvalidConfig {
                field: "dt",
                rule: "gives more than 1e8 steps for this tau",
                value: self.dt,
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
