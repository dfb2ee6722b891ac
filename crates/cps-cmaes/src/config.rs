//! User-facing settings of a CMA-ES run.

use crate::{CmaesError, Parameters};

/// Settings of a CMA-ES run. Required: the initial step size `sigma0` and the seed.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CmaesConfig {
    /// Initial step size σ₀ (> 0), in the units of the search space. A good σ₀ is about a
    /// third of the distance to where the optimum may be.
    pub sigma0: f64,
    /// Population size λ; `None` = the default `4 + ⌊3 ln n⌋` (Hansen 2016).
    pub population: Option<usize>,
    /// Seed of the random stream. The same seed gives the same run bit for bit, whatever
    /// the number of threads evaluating the population.
    pub seed: u64,
    /// Generations between the diagnostic eigendecompositions of C (condition number and
    /// the stop rules `TolUpSigma`, `ConditionCov`, `NoEffectAxis`; sampling uses the
    /// Cholesky factor, refreshed every generation); `None` = `n`, at least pycma's lazy
    /// gap `⌊1/(2n(c_1 + c_μ))⌋`; `Some(1)` = every generation.
    pub eigen_gap: Option<u64>,
    /// Optional per-coordinate scales `s` of the initial distribution: C₀ = diag(s²), so
    /// coordinate i starts with standard deviation `sigma0 * s[i]`.
    pub initial_scales: Option<Vec<f64>>,
    /// Optional full initial covariance C₀ (n × n, row-major, symmetric positive
    /// definite): the search starts with `sigma0² · C₀`. A learned distribution (a ProMP's
    /// weights) starts the search in its shape this way. Excludes `initial_scales` and the
    /// separable form.
    #[cfg_attr(feature = "serde", serde(default))]
    pub initial_covariance: Option<Vec<f64>>,
    /// Optional box bounds, handled by the boundary transformation of [`crate::Bounds`]:
    /// every evaluated candidate, and the returned best point and mean, lie in the box;
    /// `x0` must too. (Observers see the search's own, unbounded mean.)
    pub bounds: Option<crate::Bounds>,
    /// The separable variant (sep-CMA-ES, Ros & Hansen 2008): a diagonal covariance,
    /// learned faster ([`crate::Parameters::separable`]), with O(n) memory and O(n λ) time
    /// per generation — for large n or nearly separable costs. It cannot learn
    /// correlations: on a rotated ill-conditioned cost it is much slower than the full form.
    #[cfg_attr(feature = "serde", serde(default))]
    pub separable: bool,
}

/// Largest population [`CmaesConfig::validate`] accepts.
pub const MAX_POPULATION: usize = 1_000_000;
/// Largest dimension [`CmaesConfig::validate`] accepts.
pub const MAX_DIMENSION: usize = 1_000_000;
/// Most values a run may store in one array (population, covariance).
const MAX_VALUES: f64 = 1e8;

impl CmaesConfig {
    /// Default settings with the given initial step size and seed.
    pub fn new(sigma0: f64, seed: u64) -> Self {
        Self {
            sigma0,
            population: None,
            seed,
            eigen_gap: None,
            initial_scales: None,
            initial_covariance: None,
            bounds: None,
            separable: false,
        }
    }

    /// Checks the settings for a problem of dimension `n`; the error names the field. Besides
    /// the ranges of each field, what the run would store is bounded: λ ≤ 1e6, n ≤ 1e6,
    /// λ·n ≤ 1e8 and, for the full form, n² ≤ 2.5e7 (n ≤ 5000).
    pub fn validate(&self, n: usize) -> Result<(), CmaesError> {
        if n == 0 {
            return Err(CmaesError::InvalidConfig {
                field: "x0",
                rule: "must have at least one coordinate",
                value: 0.0,
            });
        }
        if !(self.sigma0.is_finite() && self.sigma0 > 0.0) {
            return Err(CmaesError::InvalidConfig {
                field: "sigma0",
                rule: "must be finite and > 0",
                value: self.sigma0,
            });
        }
        if let Some(l) = self.population
            && l < 2
        {
            return Err(CmaesError::InvalidConfig {
                field: "population",
                rule: "must be at least 2",
                value: l as f64,
            });
        }
        if let Some(l) = self.population
            && l > MAX_POPULATION
        {
            return Err(CmaesError::InvalidConfig {
                field: "population",
                rule: "must be at most 1e6",
                value: l as f64,
            });
        }
        if n > MAX_DIMENSION {
            return Err(CmaesError::InvalidConfig {
                field: "x0",
                rule: "must have at most 1e6 coordinates",
                value: n as f64,
            });
        }
        // The population is stored whole (λ·n values), and the full form keeps n×n
        // matrices: refuse what cannot fit rather than abort on allocation.
        let lambda = self
            .population
            .unwrap_or_else(|| Parameters::default_lambda(n));
        if (lambda as f64) * (n as f64) > MAX_VALUES {
            return Err(CmaesError::InvalidConfig {
                field: "population",
                rule: "times the dimension exceeds 1e8 stored values",
                value: lambda as f64,
            });
        }
        if !self.separable && (n as f64) * (n as f64) > MAX_VALUES / 4.0 {
            return Err(CmaesError::InvalidConfig {
                field: "x0",
                rule: "is too long for the full covariance (n² > 2.5e7); use the separable form",
                value: n as f64,
            });
        }
        if self.eigen_gap == Some(0) {
            return Err(CmaesError::InvalidConfig {
                field: "eigen_gap",
                rule: "must be at least 1",
                value: 0.0,
            });
        }
        if let Some(b) = &self.bounds
            && b.len() != n
        {
            return Err(CmaesError::DimensionMismatch {
                what: "bounds",
                got: b.len(),
                expected: n,
            });
        }
        if let Some(s) = &self.initial_scales {
            if s.len() != n {
                return Err(CmaesError::DimensionMismatch {
                    what: "initial_scales",
                    got: s.len(),
                    expected: n,
                });
            }
            if let Some(&v) = s.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
                return Err(CmaesError::InvalidConfig {
                    field: "initial_scales",
                    rule: "must all be finite and > 0",
                    value: v,
                });
            }
        }
        if let Some(c) = &self.initial_covariance {
            self.validate_covariance(c, n)?;
        }
        Ok(())
    }

    /// Shape, finiteness and symmetry of `initial_covariance` (positive definiteness is
    /// checked when the run factorises it).
    fn validate_covariance(&self, c: &[f64], n: usize) -> Result<(), CmaesError> {
        let bad = |rule: &'static str, value: f64| CmaesError::InvalidConfig {
            field: "initial_covariance",
            rule,
            value,
        };
        if self.initial_scales.is_some() {
            return Err(bad("excludes initial_scales (give one or the other)", 0.0));
        }
        if self.separable {
            return Err(bad(
                "needs the full form (the separable form keeps a diagonal only)",
                0.0,
            ));
        }
        if c.len() != n * n {
            return Err(CmaesError::DimensionMismatch {
                what: "initial_covariance (n × n values)",
                got: c.len(),
                expected: n * n,
            });
        }
        if let Some(&v) = c.iter().find(|v| !v.is_finite()) {
            return Err(bad("must be finite", v));
        }
        if let Some(i) = (0..n).find(|&i| c[i * n + i] <= 0.0) {
            return Err(bad("must have positive variances", c[i * n + i]));
        }
        let scale = c.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for i in 0..n {
            for j in 0..i {
                let d = (c[i * n + j] - c[j * n + i]).abs();
                if d > 1e-12 * scale {
                    return Err(bad("must be symmetric", d));
                }
            }
        }
        Ok(())
    }

    /// The population size for dimension `n`.
    pub fn lambda(&self, n: usize) -> usize {
        self.population
            .unwrap_or_else(|| Parameters::default_lambda(n))
    }
}
