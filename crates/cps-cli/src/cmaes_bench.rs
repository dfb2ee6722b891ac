//! `cps-cli cmaes bench`: the standard test functions in the reference set-up, so anyone
//! can check the optimiser on their own machine against pycma's published counts.
//!
//! Set-up (issue "cps-cmaes", after Hansen's and pycma's conventions): x0 = 3·1 and σ0 = 2
//! (Rosenbrock: x0 = 0, σ0 = 0.5), default λ, success when f ≤ 1e-8, pycma's default
//! termination (tolfun 1e-11, tolx 1e-11, stagnation, tolupsigma, conditioncov,
//! no-effect rules), a budget of 2·10⁶·n evaluations, and with `--ipop` up to 9 restarts
//! doubling λ, each from the same x0 and σ0 (`--bipop`: BIPOP, small-population runs
//! interleaved).

use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use clap::{Args, Subcommand, ValueEnum};
use cps_cmaes::{
    CmaesConfig, FnObjective, NoObserver, StopRule, functions, minimize, minimize_bipop,
    minimize_ipop,
};

use cps_experiment::InputError;

/// A standard test function (all with minimum 0).
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Function {
    /// Σ x_i².
    Sphere,
    /// Σ 10^(6(i−1)/(n−1)) x_i² (condition 1e6).
    Ellipsoid,
    /// x_1² + 10⁶ Σ_{i≥2} x_i².
    Cigar,
    /// 10⁶ x_1² + Σ_{i≥2} x_i².
    Discus,
    /// Σ 100 (x_{i+1} − x_i²)² + (1 − x_i)².
    Rosenbrock,
    /// 10 n + Σ (x_i² − 10 cos 2π x_i).
    Rastrigin,
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
    /// The test function.
    #[arg(value_enum)]
    function: Function,
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
    let f: fn(&[f64]) -> f64 = match args.function {
        Function::Sphere => functions::sphere,
        Function::Ellipsoid => functions::ellipsoid,
        Function::Cigar => functions::cigar,
        Function::Discus => functions::discus,
        Function::Rosenbrock => functions::rosenbrock,
        Function::Rastrigin => functions::rastrigin,
    };
    let (x0, sigma0) = match args.function {
        Function::Rosenbrock => (vec![0.0; n], 0.5),
        _ => (vec![3.0; n], 2.0),
    };
    let rules = StopRule::reference_set(1e-8, n);
    let mut rows = Vec::new();
    for seed in first..=last {
        let config = CmaesConfig {
            separable: args.separable,
            ..CmaesConfig::new(sigma0, seed)
        };
        let start = Instant::now();
        let sol = if args.ipop {
            minimize_ipop(&FnObjective(f), &x0, &config, &rules, 9, &mut NoObserver)?.best
        } else if args.bipop {
            minimize_bipop(&FnObjective(f), &x0, &config, &rules, 9, &mut NoObserver)?.best
        } else {
            minimize(&FnObjective(f), &x0, &config, &rules, &mut NoObserver)?
        };
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
