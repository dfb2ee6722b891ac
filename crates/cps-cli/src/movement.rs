//! `cps-cli imitate` and `cps-cli rollout`: DMP models from demonstrations (CSV) and
//! trajectories from models (JSON), for users who want the DMP layer alone.
//!
//! Demonstration CSV: a header row naming the columns, then one row per sample: the time
//! in seconds first, then one column per dimension. Trajectory CSV (written): `time`, each
//! dimension's position, then `<name>_vel` and `<name>_acc` per dimension (SI units).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use cps_dmp::{
    Combine, Demonstration, DmpConfig, DmpModel, Formulation, Imitation, Lambda, Regression,
    imitate,
};

use crate::experiment::InputError;
use crate::plots::{Series, curves_to_file, trajectory_series};
use crate::results_dir::{FileKind, check_file_target};

/// Regression method of `imitate`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Method {
    /// Schaal's locally weighted regression.
    Lwr,
    /// Ridge regression (thesis eq. 51).
    Ridge,
    /// Jerk-regularised ridge regression (thesis eq. 52).
    Jerk,
}

/// Forcing-term formulation.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum FormulationArg {
    /// Ijspeert et al. 2013 (the thesis's): the forcing term scales with goal − start.
    Ijspeert,
    /// Hoffmann/Pastor 2009: independent of goal − start (start ≈ goal works).
    Robust,
}

/// How several demonstrations are combined.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CombineArg {
    /// Average the time-normalised demonstrations, then fit.
    Mean,
    /// One regression over all samples.
    Stack,
}

/// Arguments of `cps-cli imitate`.
#[derive(Args, Debug)]
pub struct ImitateArgs {
    /// Demonstration CSV files (header row; time in seconds, then one column per dimension).
    #[arg(required = true)]
    demos: Vec<PathBuf>,
    /// Gaussian basis functions per dimension.
    #[arg(long, default_value_t = 25)]
    bases: usize,
    /// Regression method.
    #[arg(long, value_enum, default_value = "ridge")]
    method: Method,
    /// Regularisation λ, or `auto` for generalised cross-validation (default: 1e-12 for
    /// ridge as in the thesis, auto for jerk).
    #[arg(long, allow_hyphen_values = true)]
    lambda: Option<String>,
    /// Duration of the model in seconds (default: the demonstrations' mean duration).
    #[arg(long, allow_hyphen_values = true)]
    tau: Option<f64>,
    /// Time step of the model's grid in seconds (default: the first demonstration's mean
    /// sampling interval).
    #[arg(long, allow_hyphen_values = true)]
    dt: Option<f64>,
    /// Forcing-term formulation.
    #[arg(long, value_enum, default_value = "ijspeert")]
    formulation: FormulationArg,
    /// How several demonstrations are combined.
    #[arg(long, value_enum, default_value = "mean")]
    combine: CombineArg,
    /// Where to write the model (JSON).
    #[arg(long)]
    out: PathBuf,
    /// Also draw the demonstration and the model's rollout (PNG, or SVG by extension).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Print the fit report as JSON.
    #[arg(long)]
    json: bool,
    /// Replace existing output files (only files of the kind cps writes there).
    #[arg(long)]
    force: bool,
}

/// Arguments of `cps-cli rollout`.
#[derive(Args, Debug)]
pub struct RolloutArgs {
    /// The model file written by `imitate`.
    model: PathBuf,
    /// New start, one value per dimension, comma-separated.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    start: Option<Vec<f64>>,
    /// New goal, one value per dimension, comma-separated.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    goal: Option<Vec<f64>>,
    /// New duration in seconds.
    #[arg(long, allow_hyphen_values = true)]
    tau: Option<f64>,
    /// New time step in seconds.
    #[arg(long, allow_hyphen_values = true)]
    dt: Option<f64>,
    /// Where to write the trajectory (CSV).
    #[arg(long)]
    out: PathBuf,
    /// Also draw the trajectory (PNG, or SVG by extension).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Replace existing output files (only files of the kind cps writes there).
    #[arg(long)]
    force: bool,
}

/// Checks the output files before any work.
fn check_outputs(
    out: &Path,
    out_kind: FileKind,
    plot: Option<&Path>,
    force: bool,
) -> Result<(), InputError> {
    check_file_target(out, out_kind, force)?;
    if let Some(p) = plot {
        if p == out {
            return Err(InputError(format!(
                "--plot {}: is the same file as --out",
                p.display()
            )));
        }
        check_file_target(p, FileKind::Figure, force)?;
    }
    Ok(())
}

/// Reads a demonstration CSV; errors name the file and the line.
pub fn read_demo(path: &Path) -> Result<(Vec<String>, Demonstration), InputError> {
    let text = crate::experiment::read_text(path, MAX_DEMO_BYTES, "demonstration")?;
    parse_demo(path, &text)
}

/// The largest demonstration file read: 256 MiB (≈ 10⁷ samples of three coordinates).
pub const MAX_DEMO_BYTES: u64 = 256 << 20;
/// The most columns of a demonstration (time and 255 dimensions).
const MAX_DEMO_COLUMNS: usize = 256;

/// Parses demonstration CSV text (`path` names it in errors).
pub fn parse_demo(path: &Path, text: &str) -> Result<(Vec<String>, Demonstration), InputError> {
    let fail = |m: String| InputError(format!("{}: {m}", path.display()));
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header: Vec<String> = reader
        .headers()
        .map_err(|e| fail(format!("cannot read the header: {e}")))?
        .iter()
        .map(str::to_string)
        .collect();
    if header.len() < 2 {
        return Err(fail(format!(
            "the header has {} column(s); needed: time, then one column per dimension",
            header.len()
        )));
    }
    if header.len() > MAX_DEMO_COLUMNS {
        return Err(fail(format!(
            "the header has {} columns; at most {MAX_DEMO_COLUMNS} are read (time and one per dimension)",
            header.len()
        )));
    }
    if header.iter().all(|h| h.parse::<f64>().is_ok()) {
        return Err(fail(
            "line 1: no header row; the first line must name the columns (time, then one per dimension)".into(),
        ));
    }
    let (mut times, mut rows) = (Vec::new(), Vec::new());
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        let record = record.map_err(|e| fail(format!("line {line}: {e}")))?;
        if record.len() != header.len() {
            return Err(fail(format!(
                "line {line}: {} values, the header has {} columns",
                record.len(),
                header.len()
            )));
        }
        let mut values = Vec::with_capacity(record.len());
        for (c, field) in record.iter().enumerate() {
            let v: f64 = field.parse().map_err(|_| {
                fail(format!(
                    "line {line}, column `{}`: `{field}` is not a number",
                    header[c]
                ))
            })?;
            if !v.is_finite() {
                return Err(fail(format!(
                    "line {line}, column `{}`: {v} is not finite",
                    header[c]
                )));
            }
            values.push(v);
        }
        times.push(values[0]);
        rows.push(values[1..].to_vec());
    }
    let demo = Demonstration::new(times, &rows).map_err(|e| {
        // Sample k is on line k + 2: say so.
        let text = e.to_string();
        fail(format!("{text} (sample k is on line k + 2)"))
    })?;
    Ok((header[1..].to_vec(), demo))
}

fn parse_lambda(arg: Option<&str>, method: Method) -> Result<Lambda, InputError> {
    match arg {
        None => Ok(match method {
            Method::Jerk => Lambda::Auto,
            _ => Lambda::Fixed(1e-12),
        }),
        Some("auto") => Ok(Lambda::Auto),
        Some(v) => match v.parse::<f64>() {
            Ok(x) if x.is_finite() && x >= 0.0 => Ok(Lambda::Fixed(x)),
            _ => Err(InputError(format!(
                "--lambda: `{v}` is neither `auto` nor a finite number ≥ 0"
            ))),
        },
    }
}

/// Writes `text` to `path` through a temporary file in the same folder, so a failure never
/// leaves a half-written file.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut tmp = tempfile::NamedTempFile::new_in(dir)
        .with_context(|| format!("cannot write into {}", dir.display()))?;
    std::io::Write::write_all(&mut tmp, bytes)?;
    tmp.persist(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// `cps-cli imitate`.
pub fn run_imitate(args: &ImitateArgs) -> Result<ExitCode> {
    check_outputs(&args.out, FileKind::Model, args.plot.as_deref(), args.force)?;
    let mut demos = Vec::new();
    let mut names: Option<Vec<String>> = None;
    for path in &args.demos {
        let (header, demo) = read_demo(path)?;
        if let Some(n) = &names
            && n.len() != header.len()
        {
            return Err(InputError(format!(
                "{}: {} dimensions, but {} has {}",
                path.display(),
                header.len(),
                args.demos[0].display(),
                n.len()
            ))
            .into());
        }
        names.get_or_insert(header);
        demos.push(demo);
    }
    let names = names.unwrap_or_default();
    let tau = args.tau.unwrap_or_else(|| {
        demos.iter().map(Demonstration::duration).sum::<f64>() / demos.len() as f64
    });
    let dt = args
        .dt
        .unwrap_or_else(|| demos[0].duration() / (demos[0].len() - 1) as f64);
    let config = DmpConfig {
        formulation: match args.formulation {
            FormulationArg::Ijspeert => Formulation::Ijspeert2013,
            FormulationArg::Robust => Formulation::GoalRobust,
        },
        ..DmpConfig::new(args.bases, tau, dt)
    };
    let lambda = parse_lambda(args.lambda.as_deref(), args.method)?;
    let regression = match args.method {
        Method::Lwr => Regression::Lwr,
        Method::Ridge => Regression::Ridge { lambda },
        Method::Jerk => Regression::JerkRidge { lambda },
    };
    let combine = match args.combine {
        CombineArg::Mean => Combine::Mean,
        CombineArg::Stack => Combine::Stack,
    };
    let fit: Imitation = imitate(&config, &demos, regression, combine).map_err(|e| match e {
        cps_dmp::DmpError::InvalidConfig { field, rule, value } => {
            InputError(format!("--{}: {rule} (got {value:?})", cli_name(field)))
        }
        other => InputError(other.to_string()),
    })?;
    let model = DmpModel::new(&fit.dmp, &fit.weights, names.clone());
    write_atomically(&args.out, model.to_json().as_bytes())?;
    if let Some(plot) = &args.plot {
        let traj = fit.dmp.rollout(&fit.weights);
        let series = [
            Series {
                label: "demonstration".into(),
                times: traj.times(),
                values: fit.reference.iter().map(Vec::as_slice).collect(),
                faint: false,
            },
            trajectory_series("DMP", &traj),
        ];
        curves_to_file(plot, &names, &series, &[])?;
    }
    let r = &fit.report;
    if args.json {
        let out = serde_json::json!({
            "model": args.out,
            "dimensions": names,
            "tau": tau,
            "dt": fit.dmp.config().step(),
            "rmse": r.rmse,
            "max_error": r.max_error,
            "lambda": r.lambda,
            "condition_number": r.condition_number,
            "integrated_squared_jerk": r.integrated_squared_jerk,
            "demo_integrated_squared_jerk": r.demo_integrated_squared_jerk,
        });
        say!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        say!(
            "{} demonstration(s), {} dimension(s), {} bases, τ = {tau} s: model written to {}",
            demos.len(),
            names.len(),
            args.bases,
            args.out.display()
        );
        for (d, name) in names.iter().enumerate() {
            say!(
                "  {name}: RMSE {:.3e}, max error {:.3e}, λ {:.3e}, ∫jerk² {:.4e} (demo {:.4e})",
                r.rmse[d],
                r.max_error[d],
                r.lambda[d],
                r.integrated_squared_jerk[d],
                r.demo_integrated_squared_jerk[d]
            );
        }
        say!(
            "  condition number of the regression: {:.3e}",
            r.condition_number
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn cli_name(field: &str) -> &str {
    match field {
        "n_basis" => "bases",
        other => other,
    }
}

/// `cps-cli rollout`.
pub fn run_rollout(args: &RolloutArgs) -> Result<ExitCode> {
    check_outputs(
        &args.out,
        FileKind::TrajectoryCsv,
        args.plot.as_deref(),
        args.force,
    )?;
    let text =
        crate::experiment::read_text(&args.model, crate::experiment::MAX_FILE_BYTES, "model")?;
    let in_model = |e: cps_dmp::DmpError| InputError(format!("{}: {e}", args.model.display()));
    let model = DmpModel::from_json(&text).map_err(in_model)?;
    let (dmp, weights) = model.to_dmp().map_err(in_model)?;
    let dims = dmp.dims();
    let names: Vec<String> = if model.names.is_empty() {
        (0..dims).map(|d| format!("y{d}")).collect()
    } else {
        model.names.clone()
    };
    let check = |what: &str, v: &Option<Vec<f64>>| -> Result<Vec<f64>, InputError> {
        match v {
            None => Ok(if what == "start" {
                dmp.start().to_vec()
            } else {
                dmp.goal().to_vec()
            }),
            Some(v) if v.len() != dims => Err(InputError(format!(
                "--{what}: {} values for a {dims}-dimensional model ({})",
                v.len(),
                names.join(", ")
            ))),
            Some(v)
                if v.iter()
                    .any(|x| !x.is_finite() || x.abs() > cps_learn::MAX_COORDINATE) =>
            {
                Err(InputError(format!(
                    "--{what}: values must be finite and at most {:e} in magnitude",
                    cps_learn::MAX_COORDINATE
                )))
            }
            Some(v) => Ok(v.clone()),
        }
    };
    let (start, goal) = (check("start", &args.start)?, check("goal", &args.goal)?);
    let mut config = *dmp.config();
    if let Some(t) = args.tau {
        config.tau = t;
    }
    if let Some(d) = args.dt {
        config.dt = d;
    }
    let dmp = cps_dmp::DiscreteDmp::new(config, &start, &goal).map_err(|e| match e {
        cps_dmp::DmpError::InvalidConfig { field, rule, value } => {
            InputError(format!("--{field}: {rule} (got {value:?})"))
        }
        other => InputError(other.to_string()),
    })?;
    let traj = dmp.rollout(&weights);
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["time".to_string()];
    header.extend(names.iter().cloned());
    header.extend(names.iter().map(|n| format!("{n}_vel")));
    header.extend(names.iter().map(|n| format!("{n}_acc")));
    w.write_record(&header)?;
    for k in 0..traj.n_samples() {
        let mut row = vec![traj.times()[k]];
        row.extend((0..dims).map(|d| traj.position(d)[k]));
        row.extend((0..dims).map(|d| traj.velocity(d)[k]));
        row.extend((0..dims).map(|d| traj.acceleration(d)[k]));
        w.write_record(row.iter().map(|v| v.to_string()))?;
    }
    let bytes = w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?;
    write_atomically(&args.out, &bytes)?;
    if let Some(plot) = &args.plot {
        let series = [trajectory_series("", &traj)];
        let marks = vec![(0.0, start.clone()), (config.tau, goal.clone())];
        curves_to_file(plot, &names, &series, &marks)?;
    }
    say!(
        "{} samples over {} s written to {}",
        traj.n_samples(),
        config.tau,
        args.out.display()
    );
    Ok(ExitCode::SUCCESS)
}
