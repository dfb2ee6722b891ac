//! Single movements, for users who want the DMP layer alone: demonstrations read from CSV,
//! a DMP model imitated from them, a model's rollout with a new start, goal or τ — each
//! with its table and figure in the result model.
//!
//! cps's CSV dialect, for every trajectory it reads or writes: a header row naming the
//! columns, then one row per sample; `t` (seconds) first, then the positions by name
//! (`x`, `q1`, …), then optional derivatives `<name>_vel` and `<name>_acc`, then other
//! named quantities (SI units). A plain demonstration is the same without derivatives;
//! `imitate` reads both ([`parse_demo_columns`]).

use std::path::Path;

use cps_dmp::{
    Combine, Demonstration, DiscreteDmp, DmpConfig, DmpError, DmpModel, Imitation, Regression,
    Trajectory,
};

use cps_outcome::InputError;
use cps_outcome::outcome::{Column, Figure, Format, Mark, MarkKind, Panels, Plot, Series, Table};

/// The largest demonstration file read: 256 MiB (≈ 10⁷ samples of three coordinates).
pub const MAX_DEMO_BYTES: u64 = 256 << 20;
/// The most columns of a demonstration (time and 255 dimensions).
const MAX_DEMO_COLUMNS: usize = 256;

/// Reads a demonstration CSV: the names of its dimensions and the samples. Errors name
/// the file and the line. `columns` chooses the position columns by name (see
/// [`parse_demo_columns`]).
pub fn read_demo(
    path: &Path,
    columns: Option<&[String]>,
) -> Result<(Vec<String>, Demonstration), InputError> {
    let text = cps_outcome::source::read_text(path, MAX_DEMO_BYTES, "demonstration")?;
    parse_demo_columns(path, &text, columns)
}

/// Parses demonstration CSV text (`path` names it in errors), choosing the position
/// columns as [`parse_demo_columns`] does by default.
pub fn parse_demo(path: &Path, text: &str) -> Result<(Vec<String>, Demonstration), InputError> {
    parse_demo_columns(path, text, None)
}

/// Whether a column holds a derivative in cps's CSV dialect (`<name>_vel`, `<name>_acc`).
fn is_derivative(name: &str) -> bool {
    name.ends_with("_vel") || name.ends_with("_acc")
}

/// Parses demonstration CSV text: a header, the time in seconds first, then the columns.
/// The dimensions are `columns` when given (by name); otherwise, in a file of cps's
/// dialect (positions `x`, derivatives `x_vel`, `x_acc`), the columns that have a `_vel`
/// column beside them — so every trajectory cps writes reads back as its positions — and
/// in a plain demonstration (no `_vel`/`_acc` columns) every column after the time.
pub fn parse_demo_columns(
    path: &Path,
    text: &str,
    columns: Option<&[String]>,
) -> Result<(Vec<String>, Demonstration), InputError> {
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
    let picked = pick_columns(&header, columns).map_err(fail)?;
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
        let value = |c: usize| -> Result<f64, InputError> {
            let field = &record[c];
            let v: f64 = field.parse().map_err(|_| {
                fail(format!(
                    "line {line}, column `{}`: `{field}` is not a number",
                    header[c]
                ))
            })?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(fail(format!(
                    "line {line}, column `{}`: {v} is not finite",
                    header[c]
                )))
            }
        };
        times.push(value(0)?);
        rows.push(
            picked
                .iter()
                .map(|&c| value(c))
                .collect::<Result<Vec<_>, _>>()?,
        );
    }
    let demo = Demonstration::new(times, &rows).map_err(|e| {
        // Sample k is on line k + 2: say so.
        let text = e.to_string();
        fail(format!("{text} (sample k is on line k + 2)"))
    })?;
    Ok((picked.iter().map(|&c| header[c].clone()).collect(), demo))
}

/// The indices of the position columns (see [`parse_demo_columns`]).
pub(crate) fn pick_columns(
    header: &[String],
    columns: Option<&[String]>,
) -> Result<Vec<usize>, String> {
    let data = &header[1..];
    let index = |name: &str| header.iter().skip(1).position(|h| h == name).map(|i| i + 1);
    if let Some(wanted) = columns {
        let mut picked = Vec::new();
        for name in wanted {
            match index(name) {
                Some(i) if !picked.contains(&i) => picked.push(i),
                Some(_) => return Err(format!("--columns: `{name}` is named twice")),
                None => {
                    return Err(format!(
                        "--columns: there is no column `{name}` (the columns after the time `{}` are: {})",
                        header[0],
                        data.join(", ")
                    ));
                }
            }
        }
        return Ok(picked);
    }
    if !data.iter().any(|h| is_derivative(h)) {
        return Ok((1..header.len()).collect());
    }
    let picked: Vec<usize> = (1..header.len())
        .filter(|&i| !is_derivative(&header[i]) && index(&format!("{}_vel", header[i])).is_some())
        .collect();
    if picked.is_empty() {
        return Err(format!(
            "the columns {} are derivatives (`_vel`, `_acc`) but no position column has its `_vel` beside it; choose the positions with --columns",
            data.iter()
                .filter(|h| is_derivative(h))
                .map(|h| format!("`{h}`"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    Ok(picked)
}

/// How to imitate demonstrations ([`imitate_files`]).
#[derive(Debug, Clone, Copy)]
pub struct ImitationSpec {
    /// Gaussian basis functions per dimension.
    pub bases: usize,
    /// The regression (and its λ).
    pub regression: Regression,
    /// Duration of the model in seconds (default: the demonstrations' mean duration).
    pub tau: Option<f64>,
    /// Time step of the model's grid (default: the first demonstration's mean sampling
    /// interval).
    pub dt: Option<f64>,
    /// The forcing term's formulation.
    pub formulation: cps_dmp::Formulation,
    /// How several demonstrations are combined.
    pub combine: Combine,
}

/// The position columns to read from each demonstration (`None`: as
/// [`parse_demo_columns`] chooses).
pub type Columns<'a> = Option<&'a [String]>;

/// A DMP imitated from demonstration files.
#[derive(Debug)]
pub struct Imitated {
    /// The names of the dimensions (the demonstrations' header).
    pub names: Vec<String>,
    /// How many demonstrations were read.
    pub demonstrations: usize,
    /// The fit (model, weights, the reference it was fitted to, the report).
    pub fit: Imitation,
}

impl Imitated {
    /// The model as the JSON file format.
    pub fn model(&self) -> DmpModel {
        DmpModel::new(&self.fit.dmp, &self.fit.weights, self.names.clone())
    }

    /// The demonstration (the fitted reference) and the model's rollout, one panel per
    /// dimension.
    pub fn figure(&self) -> Figure {
        let traj = self.fit.dmp.rollout(&self.fit.weights);
        let series = vec![
            Series::new(
                "demonstration",
                traj.times().to_vec(),
                self.fit.reference.clone(),
            ),
            trajectory_series("DMP", &traj),
        ];
        Figure {
            name: "imitation".into(),
            caption: "The demonstration and the DMP's rollout.".into(),
            plot: Plot::Panels(Panels::new(with_units(&self.names), series)),
        }
    }
}

/// Axis names with units for dimensions named as cps names them: joints `q1…` in
/// radians, positions `x`, `tool_y`, … in metres; other names as they are.
pub(crate) fn with_units(names: &[String]) -> Vec<String> {
    names
        .iter()
        .map(|n| {
            let joint = n
                .strip_prefix('q')
                .is_some_and(|r| !r.is_empty() && r.chars().all(|c| c.is_ascii_digit()));
            let last = n.rsplit('_').next().unwrap_or(n);
            if joint {
                format!("{n} [rad]")
            } else if matches!(last, "x" | "y" | "z")
                || n.starts_with('y') && n[1..].parse::<u32>().is_ok()
            {
                format!("{n} [m]")
            } else {
                n.clone()
            }
        })
        .collect()
}

/// The command line's name of a DMP configuration field.
fn option_name(field: &str) -> &str {
    match field {
        "n_basis" => "bases",
        other => other,
    }
}

/// Reads demonstrations that must all have the same dimensions: their names (the first
/// source's) and the demonstrations. A path is a demonstration file, or a LeRobot
/// dataset's folder whose episodes `lerobot` picks (one demonstration each).
pub fn read_demos(
    paths: &[&Path],
    columns: Columns<'_>,
    lerobot: &crate::lerobot::Pick,
) -> Result<(Vec<String>, Vec<Demonstration>), InputError> {
    let (names, labelled) = read_labelled(paths, columns, lerobot)?;
    Ok((names, labelled.into_iter().map(|(_, d)| d).collect()))
}

pub use crate::lerobot::Labelled;

/// [`read_demos`], each demonstration with the words that name it in messages (its
/// file, or `<dataset> episode <k>`).
pub fn read_labelled(
    paths: &[&Path],
    columns: Columns<'_>,
    lerobot: &crate::lerobot::Pick,
) -> Result<(Vec<String>, Labelled), InputError> {
    let mut demos = Vec::new();
    let mut names: Option<Vec<String>> = None;
    for path in paths {
        // A folder is a LeRobot dataset (or refused as one, saying what it lacks).
        let (header, read) = if path.is_dir() {
            crate::lerobot::demonstrations(path, lerobot, columns)?
        } else {
            let (header, demo) = read_demo(path, columns)?;
            (header, vec![(path.display().to_string(), demo)])
        };
        if let Some(n) = &names
            && n.len() != header.len()
        {
            return Err(InputError(format!(
                "{}: {} dimensions ({}), but {} has {} ({}): every demonstration must have the same dimensions",
                path.display(),
                header.len(),
                header.join(", "),
                paths[0].display(),
                n.len(),
                n.join(", ")
            )));
        }
        names.get_or_insert(header);
        demos.extend(read);
    }
    Ok((names.unwrap_or_default(), demos))
}

/// Reads demonstrations ([`read_demos`]) and imitates them with one DMP per dimension.
pub fn imitate_files(
    paths: &[&Path],
    columns: Columns<'_>,
    lerobot: &crate::lerobot::Pick,
    spec: &ImitationSpec,
) -> Result<Imitated, InputError> {
    let (names, demos) = read_demos(paths, columns, lerobot)?;
    imitate_demos(names, &demos, spec)
}

/// Imitates demonstrations in memory (`names` their dimensions) with one DMP per
/// dimension, as [`imitate_files`] does.
pub fn imitate_demos(
    names: Vec<String>,
    demos: &[Demonstration],
    spec: &ImitationSpec,
) -> Result<Imitated, InputError> {
    let Some(first) = demos.first() else {
        return Err(InputError("no demonstration given".into()));
    };
    let tau = spec.tau.unwrap_or_else(|| {
        demos.iter().map(Demonstration::duration).sum::<f64>() / demos.len() as f64
    });
    let dt = spec
        .dt
        .unwrap_or_else(|| first.duration() / (first.len() - 1) as f64);
    let config = DmpConfig {
        formulation: spec.formulation,
        ..DmpConfig::new(spec.bases, tau, dt)
    };
    let fit =
        cps_dmp::imitate(&config, demos, spec.regression, spec.combine).map_err(|e| match e {
            DmpError::InvalidConfig { field, rule, value } => {
                InputError(format!("--{}: {rule} (got {value:?})", option_name(field)))
            }
            // The way past it, in the command line's words.
            e @ DmpError::DegenerateAmplitude { .. } => {
                InputError(format!("{e}: pass --formulation robust"))
            }
            other => InputError(other.to_string()),
        })?;
    Ok(Imitated {
        names,
        demonstrations: demos.len(),
        fit,
    })
}

/// What to change in a model's rollout ([`rollout_file`]); `None` keeps the model's.
#[derive(Debug, Clone, Default)]
pub struct RolloutSpec {
    /// New start, one value per dimension.
    pub start: Option<Vec<f64>>,
    /// New goal, one value per dimension.
    pub goal: Option<Vec<f64>>,
    /// New duration, seconds.
    pub tau: Option<f64>,
    /// New time step, seconds.
    pub dt: Option<f64>,
}

/// A model's rollout.
#[derive(Debug)]
pub struct RolledOut {
    /// The names of the dimensions (`y0`, … when the model has none).
    pub names: Vec<String>,
    /// The start used.
    pub start: Vec<f64>,
    /// The goal used.
    pub goal: Vec<f64>,
    /// The duration used, seconds.
    pub tau: f64,
    /// The trajectory.
    pub trajectory: Trajectory,
    /// Sentences on how the new start or goal distorts the model's shape (see
    /// [`DiscreteDmp::shape_warnings`]).
    pub warnings: Vec<String>,
}

impl RolledOut {
    /// `t`, positions, `<name>_vel`, `<name>_acc` (shortest round-trip decimals).
    pub fn table(&self) -> Table {
        rollout_table(&self.names, &self.trajectory)
    }

    /// The trajectory per dimension, with the start and goal marked.
    pub fn figure(&self) -> Figure {
        let (traj, tau) = (&self.trajectory, self.tau);
        Figure {
            name: "rollout".into(),
            caption: "The rollout per dimension; dots are the start and the goal.".into(),
            plot: Plot::Panels(
                Panels::new(
                    with_units(&self.names),
                    vec![trajectory_series("rollout", traj)],
                )
                .marks(vec![
                    Mark {
                        time: 0.0,
                        values: self.start.clone(),
                        kind: MarkKind::Start,
                        label: "start".into(),
                    },
                    Mark {
                        time: tau,
                        values: self.goal.clone(),
                        kind: MarkKind::Goal,
                        label: "goal".into(),
                    },
                ]),
            ),
        }
    }
}

/// Reads a model file (at most 16 MiB) and checks it: the
/// record, its DMP and its weights. Errors name the file.
pub fn read_model(path: &Path) -> Result<(DmpModel, DiscreteDmp, Vec<f64>), InputError> {
    let text = cps_outcome::source::read_text(path, cps_outcome::source::MAX_FILE_BYTES, "model")?;
    let in_model = |e: DmpError| InputError(format!("{}: {e}", path.display()));
    let file = DmpModel::from_json(&text).map_err(in_model)?;
    let (dmp, weights) = file.to_dmp().map_err(in_model)?;
    Ok((file, dmp, weights))
}

/// Reads a model file and rolls it out with the changes of `spec`.
pub fn rollout_file(model: &Path, spec: &RolloutSpec) -> Result<RolledOut, InputError> {
    let (file, dmp, weights) = read_model(model)?;
    let dims = dmp.dims();
    let names: Vec<String> = if file.names.is_empty() {
        (0..dims).map(|d| format!("y{d}")).collect()
    } else {
        file.names.clone()
    };
    let check = |what: &str, v: &Option<Vec<f64>>, model: &[f64]| match v {
        None => Ok(model.to_vec()),
        Some(v) if v.len() != dims => Err(InputError(format!(
            "--{what}: {} values for a {dims}-dimensional model ({})",
            v.len(),
            names.join(", ")
        ))),
        Some(v)
            if v.iter()
                .any(|x| !x.is_finite() || x.abs() > cps_dmp::MAX_COORDINATE) =>
        {
            Err(InputError(format!(
                "--{what}: values must be finite and at most {:e} in magnitude",
                cps_dmp::MAX_COORDINATE
            )))
        }
        Some(v) => Ok(v.clone()),
    };
    let start = check("start", &spec.start, dmp.start())?;
    let goal = check("goal", &spec.goal, dmp.goal())?;
    let warnings = dmp.shape_warnings(&names, &start, &goal);
    let mut config = *dmp.config();
    if let Some(t) = spec.tau {
        config.tau = t;
    }
    if let Some(d) = spec.dt {
        config.dt = d;
    }
    let dmp = DiscreteDmp::new(config, &start, &goal).map_err(|e| match e {
        DmpError::InvalidConfig { field, rule, value } => {
            InputError(format!("--{field}: {rule} (got {value:?})"))
        }
        other => InputError(other.to_string()),
    })?;
    Ok(RolledOut {
        names,
        start,
        goal,
        tau: config.tau,
        trajectory: dmp.rollout(&weights),
        warnings,
    })
}

/// A trajectory as `t`, positions, `<name>_vel`, `<name>_acc` columns.
pub fn rollout_table(names: &[String], traj: &Trajectory) -> Table {
    let mut t =
        Table::new("trajectory").with(Column::numbers("t", traj.times().to_vec(), Format::Plain));
    for (suffix, q) in [
        ("", Trajectory::position as fn(&Trajectory, usize) -> &[f64]),
        ("_vel", Trajectory::velocity),
        ("_acc", Trajectory::acceleration),
    ] {
        for (d, n) in names.iter().enumerate() {
            t.push(Column::numbers(
                format!("{n}{suffix}"),
                q(traj, d).to_vec(),
                Format::Plain,
            ));
        }
    }
    t
}

/// The positions of a trajectory as a bold series of a figure.
pub fn trajectory_series(label: impl Into<String>, traj: &Trajectory) -> Series {
    Series::new(
        label,
        traj.times().to_vec(),
        (0..traj.dims())
            .map(|d| traj.position(d).to_vec())
            .collect(),
    )
}

/// What `cps-cli imitate` prints for the model written to `out`: JSON `{"model",
/// "dimensions", "tau", "dt", "rmse", "max_error", "lambda", "condition_number",
/// "integrated_squared_jerk", "demo_integrated_squared_jerk"}`, or the fit in words.
impl crate::robot_file::SaysSaved for Imitated {
    fn said(&self, out: &Path) -> (serde_json::Value, Vec<String>) {
        let (fit, names) = (&self.fit, &self.names);
        let (tau, r) = (fit.dmp.config().tau, &fit.report);
        let json = serde_json::json!({
            "model": out,
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
        let mut lines = vec![format!(
            "{} demonstration(s), {} dimension(s), {} bases, τ = {tau} s: model written to {}",
            self.demonstrations,
            names.len(),
            fit.dmp.n_basis(),
            out.display()
        )];
        for (d, name) in names.iter().enumerate() {
            lines.push(format!(
                "  {name}: RMSE {:.3e}, max error {:.3e}, λ {:.3e}, ∫jerk² {:.4e} (demo {:.4e})",
                r.rmse[d],
                r.max_error[d],
                r.lambda[d],
                r.integrated_squared_jerk[d],
                r.demo_integrated_squared_jerk[d]
            ));
        }
        lines.push(format!(
            "  condition number of the regression: {:.3e}",
            r.condition_number
        ));
        (json, lines)
    }
}
