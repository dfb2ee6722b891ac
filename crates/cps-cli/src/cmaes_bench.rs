//! `cps-cli cmaes bench`: its arguments and its output; the run is `cps_cmaes::functions::bench`.

use std::process::ExitCode;

use anyhow::Result;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, Subcommand};
use cps_cmaes::CmaesError;
use cps_cmaes::functions::{Bench, Restarts, Seeds, TestFunction, bench as run};
use cps_outcome::InputError;

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
    seeds: Seeds,
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

/// `cps-cli cmaes bench`.
pub fn bench(cmd: &CmaesCommand) -> Result<ExitCode> {
    let CmaesCommand::Bench(args) = cmd;
    let restarts = match (args.ipop, args.bipop) {
        (true, _) => Restarts::Ipop,
        (_, true) => Restarts::Bipop,
        _ => Restarts::None,
    };
    let settings = Bench {
        function: args.function,
        dim: args.dim,
        seeds: args.seeds,
        restarts,
        separable: args.separable,
    };
    let summary = run(&settings, |r| {
        if !args.json {
            say!("{r}");
        }
    })
    .map_err(|e| match e {
        CmaesError::InvalidConfig { field: "dim", .. } => InputError(format!("--dim: {e}")).into(),
        other => anyhow::Error::new(other),
    })?;
    if args.json {
        say!("{}", serde_json::to_string_pretty(&summary.runs)?);
    } else {
        say!("{summary}");
    }
    Ok(ExitCode::SUCCESS)
}
