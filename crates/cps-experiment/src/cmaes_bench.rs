//! `cps-cli cmaes bench`: the standard test functions in the reference set-up
//! (`cps_cmaes::functions`), so anyone can check the optimiser on their own machine
//! against pycma's published counts.

use std::time::Instant;

use cps_cmaes::functions::{Restarts, TestFunction, reference_run};
use serde_json::json;

use crate::{ExperimentError, InputError};
use cps_movement::robot_file::Answer;

/// A benchmark's settings.
#[derive(Debug, Clone)]
pub struct Bench {
    /// The test function.
    pub function: TestFunction,
    /// Dimension n (1 to 10 000; the full form at most 5000).
    pub dim: usize,
    /// Seeds as `A..B` (inclusive) or one seed; at most 10 000.
    pub seeds: String,
    /// Restarts.
    pub restarts: Restarts,
    /// The separable variant.
    pub separable: bool,
}

fn parse_seeds(text: &str) -> Result<(u64, u64), InputError> {
    let bad = || {
        InputError(format!(
            "--seeds: `{text}` is not `A..B` with A ≤ B, nor one seed"
        ))
    };
    let (a, b): (u64, u64) = match text.split_once("..") {
        Some((a, b)) => (
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
        ),
        None => {
            let s = text.trim().parse().map_err(|_| bad())?;
            (s, s)
        }
    };
    if a > b {
        return Err(bad());
    }
    if b - a >= 10_000 {
        return Err(InputError(format!(
            "--seeds: `{text}` names {} seeds; at most 10000 are run at once",
            (b - a).saturating_add(1)
        )));
    }
    Ok((a, b))
}

/// Runs the benchmark: one line per seed to `progress` as it finishes, then the answer
/// (JSON: a list of `{seed, evaluations, success, best, seconds}`; lines: the summary with
/// the median evaluations of the successes, f ≤ 1e-8).
pub fn run(bench: &Bench, mut progress: impl FnMut(&str)) -> Result<Answer, ExperimentError> {
    let n = bench.dim;
    if !(1..=10_000).contains(&n) {
        return Err(InputError(format!("--dim: must be between 1 and 10000 (got {n})")).into());
    }
    if !bench.separable && n > 5000 {
        return Err(InputError(format!(
            "--dim {n}: the full form stores n × n matrices; use at most 5000, or --separable"
        ))
        .into());
    }
    let (first, last) = parse_seeds(&bench.seeds)?;
    let mut rows = Vec::new();
    for seed in first..=last {
        let start = Instant::now();
        let sol = reference_run(bench.function, n, seed, bench.restarts, bench.separable)
            .map_err(|e| ExperimentError::Message(e.to_string()))?;
        let seconds = start.elapsed().as_secs_f64();
        let success = sol.best_cost <= 1e-8;
        progress(&format!(
            "seed {seed:>4}: {:>9} evaluations, {}, best {:.3e}, {:.3} s ({})",
            sol.evaluations,
            if success { "success" } else { "FAILED " },
            sol.best_cost,
            seconds,
            sol.termination
        ));
        rows.push((seed, sol.evaluations, success, sol.best_cost, seconds));
    }
    let list: Vec<_> = rows
        .iter()
        .map(|(seed, e, s, b, t)| json!({"seed": seed, "evaluations": e, "success": s, "best": b, "seconds": t}))
        .collect();
    let mut evals: Vec<u64> = rows.iter().filter(|r| r.2).map(|r| r.1).collect();
    evals.sort_unstable();
    // The usual median: the mean of the two middle values for an even count.
    let median = match evals.len() {
        0 => 0.0,
        k if k % 2 == 1 => evals[k / 2] as f64,
        k => 0.5 * (evals[k / 2 - 1] + evals[k / 2]) as f64,
    };
    let line = format!(
        "{:?} n = {n}: {}/{} successes, median evaluations of the successes {median:.0}",
        bench.function,
        evals.len(),
        rows.len()
    );
    Ok(Answer {
        json: json!(list),
        lines: vec![line],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_are_read_and_bounded() {
        assert_eq!(parse_seeds("3..7").unwrap(), (3, 7));
        assert_eq!(parse_seeds(" 5 ").unwrap(), (5, 5));
        assert!(parse_seeds("7..3").is_err());
        assert!(
            parse_seeds("0..20000")
                .unwrap_err()
                .0
                .contains("20001 seeds")
        );
    }
}
