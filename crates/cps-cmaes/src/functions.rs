//! Standard test functions (all with minimum 0), for tests, benchmarks and
//! `cps-cli cmaes bench`, and the reference set-up they are run in ([`reference_run`]).
//!
//! Set-up (after Hansen's and pycma's conventions): x0 = 3·1 and σ0 = 2 (Rosenbrock:
//! x0 = 0, σ0 = 0.5), default λ, success when f ≤ 1e-8, pycma's default termination
//! (tolfun 1e-11, tolx 1e-11, stagnation, tolupsigma, conditioncov, no-effect rules), a
//! budget of 2·10⁶·n evaluations, and with IPOP up to 9 restarts doubling λ, each from
//! the same x0 and σ0 (BIPOP: small-population runs interleaved).

use crate::{
    CmaesConfig, CmaesError, FnObjective, NoObserver, Solution, StopRule, minimize, minimize_bipop,
    minimize_ipop,
};

/// `Σ x_i²`.
pub fn sphere(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum()
}

/// `Σ 10^(6 (i−1)/(n−1)) x_i²` (condition 1e6).
pub fn ellipsoid(x: &[f64]) -> f64 {
    let n = x.len();
    if n == 1 {
        return x[0] * x[0];
    }
    x.iter()
        .enumerate()
        .map(|(i, v)| 10f64.powf(6.0 * i as f64 / (n - 1) as f64) * v * v)
        .sum()
}

/// `x_1² + 10⁶ Σ_{i≥2} x_i²`.
pub fn cigar(x: &[f64]) -> f64 {
    x[0] * x[0] + 1e6 * x[1..].iter().map(|v| v * v).sum::<f64>()
}

/// `10⁶ x_1² + Σ_{i≥2} x_i²`.
pub fn discus(x: &[f64]) -> f64 {
    1e6 * x[0] * x[0] + x[1..].iter().map(|v| v * v).sum::<f64>()
}

/// `Σ_{i<n} 100 (x_{i+1} − x_i²)² + (1 − x_i)²`.
pub fn rosenbrock(x: &[f64]) -> f64 {
    x.windows(2)
        .map(|w| 100.0 * (w[1] - w[0] * w[0]).powi(2) + (1.0 - w[0]).powi(2))
        .sum()
}

/// `10 n + Σ (x_i² − 10 cos 2π x_i)`.
pub fn rastrigin(x: &[f64]) -> f64 {
    10.0 * x.len() as f64
        + x.iter()
            .map(|v| v * v - 10.0 * (2.0 * std::f64::consts::PI * v).cos())
            .sum::<f64>()
}

/// A standard test function by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TestFunction {
    /// [`sphere`].
    Sphere,
    /// [`ellipsoid`].
    Ellipsoid,
    /// [`cigar`].
    Cigar,
    /// [`discus`].
    Discus,
    /// [`rosenbrock`].
    Rosenbrock,
    /// [`rastrigin`].
    Rastrigin,
}

impl TestFunction {
    /// Every test function, in the order of [`TestFunction::name`]s.
    pub const ALL: [TestFunction; 6] = [
        Self::Sphere,
        Self::Ellipsoid,
        Self::Cigar,
        Self::Discus,
        Self::Rosenbrock,
        Self::Rastrigin,
    ];

    /// Its lower-case name (`sphere`, …).
    pub fn name(self) -> &'static str {
        match self {
            Self::Sphere => "sphere",
            Self::Ellipsoid => "ellipsoid",
            Self::Cigar => "cigar",
            Self::Discus => "discus",
            Self::Rosenbrock => "rosenbrock",
            Self::Rastrigin => "rastrigin",
        }
    }

    /// The function of that name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// The function itself.
    pub fn function(self) -> fn(&[f64]) -> f64 {
        match self {
            Self::Sphere => sphere,
            Self::Ellipsoid => ellipsoid,
            Self::Cigar => cigar,
            Self::Discus => discus,
            Self::Rosenbrock => rosenbrock,
            Self::Rastrigin => rastrigin,
        }
    }

    /// The reference start in `n` dimensions: (x0, σ0).
    pub fn reference_start(self, n: usize) -> (Vec<f64>, f64) {
        match self {
            Self::Rosenbrock => (vec![0.0; n], 0.5),
            _ => (vec![3.0; n], 2.0),
        }
    }
}

/// Restarts of a reference run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Restarts {
    /// One run.
    None,
    /// IPOP: up to 9 restarts, the population doubled each time.
    Ipop,
    /// BIPOP: up to 9 large-population restarts, small ones interleaved.
    Bipop,
}

/// Runs `function` in `n` dimensions from its reference start with `seed`, in the
/// reference set-up (module docs); success is `best_cost <= 1e-8`.
pub fn reference_run(
    function: TestFunction,
    n: usize,
    seed: u64,
    restarts: Restarts,
    separable: bool,
) -> Result<Solution, CmaesError> {
    let (x0, sigma0) = function.reference_start(n);
    let rules = StopRule::reference_set(1e-8, n);
    let config = CmaesConfig {
        separable,
        ..CmaesConfig::new(sigma0, seed)
    };
    let f = FnObjective(function.function());
    Ok(match restarts {
        Restarts::None => minimize(&f, &x0, &config, &rules, &mut NoObserver)?,
        Restarts::Ipop => minimize_ipop(&f, &x0, &config, &rules, 9, &mut NoObserver)?.best,
        Restarts::Bipop => minimize_bipop(&f, &x0, &config, &rules, 9, &mut NoObserver)?.best,
    })
}
