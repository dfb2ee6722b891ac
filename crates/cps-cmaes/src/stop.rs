//! Stopping rules and the reason a run ended.

/// A rule that ends a run. Rules are checked after every generation, in the order given;
/// the first that fires is reported as the [`Termination`].
///
/// Thresholds follow pycma's and Hansen's (2016) conventions where they exist.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum StopRule {
    /// Stop after this many generations.
    MaxGenerations(u64),
    /// Stop once this many objective evaluations have been spent (checked per generation,
    /// so a run never exceeds it: the last generation that would is not started).
    MaxEvaluations(u64),
    /// Stop when the best cost so far is ≤ this value.
    TargetCost(f64),
    /// Stop when the range of the best costs over the last `10 + ⌈30 n / λ⌉` generations
    /// and of the current population's costs are both below this value.
    TolFun(f64),
    /// Stop when `σ · max(|p_c,i|, √C_ii) < tol` for every coordinate (the distribution
    /// has shrunk below the resolution the user cares about).
    TolX(f64),
    /// Stop when `σ / σ₀ > tol · √λ_max(C)`: the step size has blown up (divergence, e.g.
    /// on an unbounded linear function). pycma's default is 1e20.
    TolUpSigma(f64),
    /// Stop when the condition number of C exceeds this value (pycma: 1e14).
    ConditionCov(f64),
    /// Stop when the best and the `⌈0.1 + λ/4⌉`-th best cost of a generation are equal in
    /// this many consecutive generations (a flat region: ranking carries no information).
    FlatFitness(u64),
    /// Stop when neither the best nor the median costs improve any more (pycma's
    /// tolstagnation): with `T = 100 + 100 n^1.5 / λ` and G generations run (at least
    /// `n (5 + 100/λ)`), the median of the last `l = max(T/10, G/10)` values is not below
    /// the median of the `l` before them, in both histories.
    Stagnation,
    /// Stop when adding 0.1 σ times a principal axis of C to the mean leaves it unchanged
    /// (the axis is cycled through generation by generation).
    NoEffectAxis,
    /// Stop when adding 0.2 σ √C_ii to any coordinate of the mean leaves it unchanged.
    NoEffectCoord,
}

impl StopRule {
    /// Safety rules a long run should always carry: divergence, conditioning and numerical
    /// no-effect criteria with pycma's thresholds.
    pub fn safety_defaults() -> Vec<StopRule> {
        vec![
            StopRule::TolUpSigma(1e20),
            StopRule::ConditionCov(1e14),
            StopRule::NoEffectAxis,
            StopRule::NoEffectCoord,
        ]
    }
}

impl StopRule {
    /// The reference set-up of benchmarks (pycma's default termination): reach `target`,
    /// or stop by tolfun 1e-11, tolx 1e-11, stagnation or a safety rule, within a budget
    /// of 2·10⁶·n evaluations. Used by `cps-cli cmaes bench` and the reference tests.
    pub fn reference_set(target: f64, n: usize) -> Vec<StopRule> {
        let mut rules = vec![
            StopRule::TargetCost(target),
            StopRule::MaxEvaluations(2_000_000 * n as u64),
            StopRule::TolFun(1e-11),
            StopRule::TolX(1e-11),
            StopRule::Stagnation,
        ];
        rules.extend(StopRule::safety_defaults());
        rules
    }
}

/// Why a run ended.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Termination {
    /// A [`StopRule`] fired.
    Rule(StopRule),
    /// An observer asked to stop (e.g. the user pressed Ctrl-C).
    Interrupted,
    /// The objective ended the search ([`crate::EndSearch`]): it can evaluate no more (a
    /// pool of robots gone, a stop asked mid-generation). The generation it could not
    /// finish is not counted.
    Ended,
}

impl Termination {
    /// A short stable name: `max_generations`, `target_cost`, `tolfun`, …, `interrupted`.
    pub fn name(&self) -> &'static str {
        match self {
            Termination::Interrupted => "interrupted",
            Termination::Ended => "ended",
            Termination::Rule(r) => match r {
                StopRule::MaxGenerations(_) => "max_generations",
                StopRule::MaxEvaluations(_) => "max_evaluations",
                StopRule::TargetCost(_) => "target_cost",
                StopRule::TolFun(_) => "tolfun",
                StopRule::TolX(_) => "tolx",
                StopRule::TolUpSigma(_) => "tolupsigma",
                StopRule::ConditionCov(_) => "conditioncov",
                StopRule::FlatFitness(_) => "flat_fitness",
                StopRule::Stagnation => "stagnation",
                StopRule::NoEffectAxis => "noeffectaxis",
                StopRule::NoEffectCoord => "noeffectcoord",
            },
        }
    }
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
