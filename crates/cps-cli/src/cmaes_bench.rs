//! `cps-cli cmaes bench`: the standard test functions in the reference set-up
//! (`cps_cmaes::functions`), so anyone can check the optimiser on their own machine
//! against pycma's published counts.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, Subcommand};
use cps_cmaes::functions::{Restarts, TestFunction, reference_run};

use cps_experiment::InputError;

fn function(name: &str) -> TestFunction {
    // Only names of `TestFunction::ALL` pass the parser.
    TestFunction::from_name(name).unwrap_or(TestFunction::Sphere)
}

/// `cps-cli cmaes ...`.
#[derive(Subcommand, Debug)]
pub enum CmaesCommand {
    /// Run a test function for a range of seeds and print evaluations to f ≤ 1e-8.
    Bench(BenchArgs),
}

/// Arguments of `cps-cli cmaes bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// The test function (all with minimum 0).
    #[arg(value_parser = PossibleValuesParser::new(TestFunction::ALL.map(TestFunction::name)).map(|s| function(&s)))]
    function: TestFunction,
    /// Dimension n.
    #[arg(long, default_value_t = 10)]
    dim: usize,
    /// Seeds as `A..B` (inclusive), or one seed.
    #[arg(long, default_value = "1..10")]
    seeds: String,
    /// IPOP restarts (up to 9, population doubled each time).
    #[arg(long, conflicts_with = "bipop")]
    ipop: bool,
    /// BIPOP restarts (up to 9 large-population runs, small ones interleaved).
    #[arg(long)]
    bipop: bool,
    /// The separable variant (sep-CMA-ES: diagonal covariance).
    #[arg(long)]
    separable: bool,
    /// Print a JSON list of `{seed, evaluations, success, best, seconds}`.
    #[arg(long)]
    json: bool,
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

/// `cps-cli cmaes bench`.
pub fn bench(cmd: &CmaesCommand) -> Result<ExitCode> {
    let CmaesCommand::Bench(args) = cmd;
    let n = args.dim;
    if !(1..=10_000).contains(&n) {
        return Err(InputError(format!("--dim: must be between 1 and 10000 (got {n})")).into());
    }
    if !args.separable && n > 5000 {
        return Err(InputError(format!(
            "--dim {n}: the full form stores n × n matrices; use at most 5000, or --separable"
        ))
        .into());
    }
    let (first, last) = parse_seeds(&args.seeds)?;
    let restarts = match (args.ipop, args.bipop) {
        (true, _) => Restarts::Ipop,
        (_, true) => Restarts::Bipop,
        _ => Restarts::None,
    };
    let mut rows = Vec::new();
    for seed in first..=last {
        let start = Instant::now();
        let sol = reference_run(args.function, n, seed, restarts, args.separable)?;
        let seconds = start.elapsed().as_secs_f64();
        let success = sol.best_cost <= 1e-8;
        if !args.json {
            say!(
                "seed {seed:>4}: {:>9} evaluations, {}, best {:.3e}, {:.3} s ({})",
                sol.evaluations,
                if success { "success" } else { "FAILED " },
                sol.best_cost,
                seconds,
                sol.termination
            );
        }
        rows.push((seed, sol.evaluations, success, sol.best_cost, seconds));
    }
    if args.json {
        let list: Vec<_> = rows
            .iter()
            .map(|(seed, e, s, b, t)| {
                serde_json::json!({"seed": seed, "evaluations": e, "success": s, "best": b, "seconds": t})
            })
            .collect();
        say!("{}", serde_json::to_string_pretty(&list)?);
    } else {
        let mut evals: Vec<u64> = rows.iter().filter(|r| r.2).map(|r| r.1).collect();
        evals.sort_unstable();
        let successes = evals.len();
        // The usual median: the mean of the two middle values for an even count.
        let median = match evals.len() {
            0 => 0.0,
            k if k % 2 == 1 => evals[k / 2] as f64,
            k => 0.5 * (evals[k / 2 - 1] + evals[k / 2]) as f64,
        };
        say!(
            "{:?} n = {n}: {successes}/{} successes, median evaluations of the successes {median:.0}",
            args.function,
            rows.len()
        );
    }
    Ok(ExitCode::SUCCESS)
}
