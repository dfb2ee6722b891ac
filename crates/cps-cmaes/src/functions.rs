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

/// The most seeds one [`bench()`] runs.
pub const MAX_SEEDS: u64 = 10_000;

/// The seeds of a benchmark: `A..B` (inclusive, A ≤ B) or one seed, as written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Seeds {
    /// The first seed.
    pub first: u64,
    /// The last seed (inclusive).
    pub last: u64,
}

impl std::str::FromStr for Seeds {
    type Err = String;

    /// `A..B` or one seed; at most [`MAX_SEEDS`] of them.
    fn from_str(text: &str) -> Result<Self, String> {
        let bad = || format!("`{text}` is not `A..B` with A ≤ B, nor one seed");
        let number = |s: &str| s.trim().parse::<u64>().map_err(|_| bad());
        let (first, last) = match text.split_once("..") {
            Some((a, b)) => (number(a)?, number(b)?),
            None => (number(text)?, number(text)?),
        };
        if first > last {
            return Err(bad());
        }
        if last - first >= MAX_SEEDS {
            return Err(format!(
                "`{text}` names {} seeds; at most {MAX_SEEDS} are run at once",
                (last - first).saturating_add(1)
            ));
        }
        Ok(Seeds { first, last })
    }
}

/// A benchmark: `function` in `dim` dimensions, in the reference set-up, for each seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bench {
    /// The test function.
    pub function: TestFunction,
    /// Dimension n: 1 to 10 000, the full form at most 5000.
    pub dim: usize,
    /// The seeds.
    pub seeds: Seeds,
    /// Restarts.
    pub restarts: Restarts,
    /// The separable variant (sep-CMA-ES).
    pub separable: bool,
}

/// One seed's run of a [`bench()`] (as JSON with the `serde` feature: every field but
/// the termination).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct BenchRun {
    /// The seed.
    pub seed: u64,
    /// Evaluations spent.
    pub evaluations: u64,
    /// Whether it reached f ≤ 1e-8.
    pub success: bool,
    /// The best cost found.
    pub best: f64,
    /// Wall time (s).
    pub seconds: f64,
    /// Why it ended.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub termination: crate::Termination,
}

impl std::fmt::Display for BenchRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "seed {:>4}: {:>9} evaluations, {}, best {:.3e}, {:.3} s ({})",
            self.seed,
            self.evaluations,
            if self.success { "success" } else { "FAILED " },
            self.best,
            self.seconds,
            self.termination
        )
    }
}

/// What a [`bench()`] found: its runs, seed by seed.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchSummary {
    /// The benchmark run.
    pub bench: Bench,
    /// One run per seed, in order.
    pub runs: Vec<BenchRun>,
}

impl BenchSummary {
    /// The median evaluations of the successful runs (the mean of the two middle ones
    /// for an even count; 0 without a success).
    pub fn median_evaluations(&self) -> f64 {
        let mut evals: Vec<u64> = self
            .runs
            .iter()
            .filter(|r| r.success)
            .map(|r| r.evaluations)
            .collect();
        evals.sort_unstable();
        match evals.len() {
            0 => 0.0,
            k if k % 2 == 1 => evals[k / 2] as f64,
            k => 0.5 * (evals[k / 2 - 1] + evals[k / 2]) as f64,
        }
    }

    /// How many runs succeeded.
    pub fn successes(&self) -> usize {
        self.runs.iter().filter(|r| r.success).count()
    }
}

impl std::fmt::Display for BenchSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:?} n = {}: {}/{} successes, median evaluations of the successes {:.0}",
            self.bench.function,
            self.bench.dim,
            self.successes(),
            self.runs.len(),
            self.median_evaluations()
        )
    }
}

/// Runs `bench` seed by seed ([`reference_run`]), telling `on_run` of each run as it
/// ends. Errors: a dimension outside 1 to 10 000 (the full form: 5000, its n × n
/// matrices), as [`CmaesError::InvalidConfig`] with the field `dim`.
pub fn bench(bench: &Bench, mut on_run: impl FnMut(&BenchRun)) -> Result<BenchSummary, CmaesError> {
    let n = bench.dim;
    let bad = |rule| CmaesError::InvalidConfig {
        field: "dim",
        rule,
        value: n as f64,
    };
    if !(1..=10_000).contains(&n) {
        return Err(bad("must be between 1 and 10000"));
    }
    if !bench.separable && n > 5000 {
        return Err(bad(
            "must be at most 5000 in the full form, which stores n × n matrices (or use the separable one)",
        ));
    }
    let mut runs = Vec::new();
    for seed in bench.seeds.first..=bench.seeds.last {
        let start = std::time::Instant::now();
        let sol = reference_run(bench.function, n, seed, bench.restarts, bench.separable)?;
        let run = BenchRun {
            seed,
            evaluations: sol.evaluations,
            success: sol.best_cost <= 1e-8,
            best: sol.best_cost,
            seconds: start.elapsed().as_secs_f64(),
            termination: sol.termination,
        };
        on_run(&run);
        runs.push(run);
    }
    Ok(BenchSummary {
        bench: *bench,
        runs,
    })
}
