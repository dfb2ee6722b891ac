//! ProMPs from files, for `cps-cli promp` and the `promp` experiment kind: fitting from
//! demonstration CSVs (read as `imitate` reads them), the versioned JSON model, via points
//! from the command line, seeded samples and the mean ± σ table, each with its answer and
//! figure.

use std::path::Path;

use cps_promp::{Observation, ProMp, ProMpError, ProMpModel};

use crate::movement::{Columns, read_labelled, with_units};
use cps_outcome::InputError;
use cps_outcome::outcome::{
    Band, Column, Figure, Format, Mark, MarkKind, Panels, Plot, Series, Table,
};

/// The largest ProMP file read: 256 MiB.
pub const MAX_PROMP_BYTES: u64 = 256 << 20;
/// The most samples `promp sample` draws at once.
pub const MAX_SAMPLES: usize = 100_000;
/// The most values a grid of samples or statistics may hold (samples × steps × dims).
const MAX_GRID_VALUES: f64 = 2e7;

/// A ProMP with the names of its dimensions and how many demonstrations made it.
#[derive(Debug, Clone)]
pub struct NamedProMp {
    /// The distribution.
    pub promp: ProMp,
    /// The dimensions' names (`y1`, … when the file had none).
    pub names: Vec<String>,
    /// Demonstrations it was fitted to (0: unknown).
    pub demonstrations: usize,
}

fn promp_error(place: &str, e: ProMpError) -> InputError {
    InputError(format!("{place}: {e}"))
}

/// `y1`, `y2`, … for a ProMP of `dims` dimensions without names.
fn default_names(dims: usize) -> Vec<String> {
    (1..=dims).map(|d| format!("y{d}")).collect()
}

impl NamedProMp {
    /// The JSON file's text.
    pub fn to_json(&self) -> String {
        ProMpModel::new(&self.promp, self.names.clone(), self.demonstrations).to_json()
    }

    /// Reads and checks a ProMP file (at most [`MAX_PROMP_BYTES`]); errors name the file.
    pub fn read(path: &Path) -> Result<Self, InputError> {
        let text = cps_outcome::source::read_text(path, MAX_PROMP_BYTES, "ProMP file")?;
        let place = path.display().to_string();
        let model = ProMpModel::from_json(&text).map_err(|e| promp_error(&place, e))?;
        let promp = model.to_promp().map_err(|e| promp_error(&place, e))?;
        let names = if model.names.is_empty() {
            default_names(promp.dims())
        } else {
            model.names
        };
        Ok(NamedProMp {
            promp,
            names,
            demonstrations: model.demonstrations,
        })
    }

    /// The time grid of `dt` seconds over the movement: `K = round(T/dt)` steps of exactly
    /// `T/K`, refusing a step that is not positive, longer than the movement, or that would
    /// make `per_step · (K + 1)` values exceed 2·10⁷.
    pub fn grid(&self, dt: f64, per_step: usize) -> Result<Vec<f64>, InputError> {
        let t = self.promp.duration();
        if !(dt.is_finite() && dt > 0.0 && dt <= t) {
            return Err(InputError(format!(
                "--dt {dt}: the time step must be > 0 and at most the movement's {t} s"
            )));
        }
        let k = (t / dt).round().max(1.0);
        if (k + 1.0) * per_step as f64 > MAX_GRID_VALUES {
            return Err(InputError(format!(
                "--dt {dt}: {k} steps × {per_step} values exceed the 2·10⁷ values written at once; take a larger --dt or fewer samples"
            )));
        }
        let k = k as usize;
        Ok((0..=k).map(|i| t * i as f64 / k as f64).collect())
    }

    /// The mean and standard deviation over `times`: `t`, the means by name, then
    /// `<name>_std`.
    pub fn stats_table(&self, times: &[f64]) -> Table {
        let stats = self.promp.stats(times);
        let mut table =
            Table::new("stats").with(Column::numbers("t", times.to_vec(), Format::Plain));
        for (d, name) in self.names.iter().enumerate() {
            let mean = stats.iter().map(|(m, _)| m[d]).collect();
            table.push(Column::numbers(name.clone(), mean, Format::Plain));
        }
        for (d, name) in self.names.iter().enumerate() {
            let std = stats.iter().map(|(_, s)| s[d]).collect();
            table.push(Column::numbers(format!("{name}_std"), std, Format::Plain));
        }
        table
    }

    /// `count` seeded samples over `times`, each a table in the demonstration format (`t`,
    /// then one column per dimension) named `sample_001`, `sample_002`, ….
    pub fn sample_tables(
        &self,
        count: usize,
        seed: u64,
        times: &[f64],
    ) -> Result<Vec<Table>, InputError> {
        if count == 0 || count > MAX_SAMPLES {
            return Err(InputError(format!(
                "--n {count}: draw between 1 and {MAX_SAMPLES} samples"
            )));
        }
        let samples = self
            .promp
            .sample_trajectories(count, seed, times)
            .map_err(|e| InputError(format!("cannot sample: {e}")))?;
        let width = count.to_string().len().max(3);
        let dims = self.names.len();
        Ok(samples
            .chunks(times.len() * dims)
            .enumerate()
            .map(|(k, flat)| {
                let rows: Vec<&[f64]> = flat.chunks(dims).collect();
                let mut table = Table::new(format!("sample_{:0width$}", k + 1))
                    .with(Column::numbers("t", times.to_vec(), Format::Plain));
                for (d, name) in self.names.iter().enumerate() {
                    let v = rows.iter().map(|r| r[d]).collect();
                    table.push(Column::numbers(name.clone(), v, Format::Plain));
                }
                table
            })
            .collect())
    }

    /// The mean and the mean ± 2σ band over `times`, labelled `label`.
    fn band(&self, label: &str, times: &[f64]) -> (Series, Band) {
        let stats = self.promp.stats(times);
        let dims = self.names.len();
        let per_dim = |f: &dyn Fn(f64, f64) -> f64| -> Vec<Vec<f64>> {
            (0..dims)
                .map(|d| stats.iter().map(|(m, s)| f(m[d], s[d])).collect())
                .collect()
        };
        (
            Series::new(format!("{label} mean"), times.to_vec(), per_dim(&|m, _| m)),
            Band {
                label: format!("{label} ± 2σ"),
                times: times.to_vec(),
                lower: per_dim(&|m, s| m - 2.0 * s),
                upper: per_dim(&|m, s| m + 2.0 * s),
            },
        )
    }

    /// Panels of the mean and its ±2σ band, with `extra` series (demonstrations) drawn
    /// faint, the `prior`'s band when given, and marked via points.
    pub fn figure(
        &self,
        name: &str,
        extra: Vec<Series>,
        prior: Option<&NamedProMp>,
        vias: &[Observation],
    ) -> Figure {
        let times = plot_grid(self.promp.duration());
        let mut series = extra;
        let mut bands = Vec::new();
        if let Some(p) = prior {
            let (m, b) = p.band("prior", &times);
            series.push(m.faint());
            bands.push(b);
        }
        let (m, b) = self.band(
            if prior.is_some() {
                "conditioned"
            } else {
                "ProMP"
            },
            &times,
        );
        series.push(m);
        bands.push(b);
        let marks = vias
            .iter()
            .enumerate()
            .filter_map(|(k, o)| {
                o.position.as_ref().map(|p| Mark {
                    time: o.time,
                    values: p.clone(),
                    kind: MarkKind::Via,
                    label: format!("p{}", k + 1),
                })
            })
            .collect();
        Figure {
            name: name.into(),
            caption: if prior.is_some() {
                "The ProMP before (faint) and after conditioning on the via points: means and mean ± 2σ bands.".into()
            } else {
                "The demonstrations (faint), the ProMP's mean and its mean ± 2σ band.".into()
            },
            plot: Plot::Panels(
                Panels::new(with_units(&self.names), series)
                    .bands(bands)
                    .marks(marks),
            ),
        }
    }

    /// The mean standard deviation over the movement, per dimension (200 points).
    fn mean_std(&self) -> Vec<f64> {
        let times = plot_grid(self.promp.duration());
        let stats = self.promp.stats(&times);
        (0..self.names.len())
            .map(|d| stats.iter().map(|(_, s)| s[d]).sum::<f64>() / stats.len() as f64)
            .collect()
    }
}

/// `cps-cli promp sample`: `count` seeded samples of the ProMP file `model` on a grid of
/// `dt`, one CSV each in the result folder `out` (checked first, written out of sight
/// and moved into place); the sentence saying what was written.
pub fn write_samples(
    model: &Path,
    out: &Path,
    force: bool,
    count: usize,
    seed: u64,
    dt: f64,
) -> Result<String, cps_outcome::ExperimentError> {
    let stage = cps_outcome::results_dir::Staging::prepare(out, force)?;
    let promp = NamedProMp::read(model)?;
    let times = promp.grid(dt, count.saturating_mul(promp.names.len() + 1))?;
    for table in promp.sample_tables(count, seed, &times)? {
        let csv = cps_outcome::files::table_csv(&table)?;
        stage.write(&format!("{}.csv", table.name), &csv)?;
    }
    stage.commit()?;
    Ok(format!(
        "{count} samples (seed {seed}) of {} steps written to {}",
        times.len(),
        out.display()
    ))
}

/// `cps-cli promp stats`: the mean and σ of the ProMP file `model` on a grid of `dt`
/// written to the CSV `out` (checked first); the sentence saying what was written.
pub fn write_stats(
    model: &Path,
    out: &Path,
    force: bool,
    dt: f64,
) -> Result<String, cps_outcome::ExperimentError> {
    use cps_outcome::results_dir::{FileKind, check_file_target};
    check_file_target(out, FileKind::TrajectoryCsv, force)?;
    let promp = NamedProMp::read(model)?;
    let times = promp.grid(dt, 2 * promp.names.len() + 1)?;
    let csv = cps_outcome::files::table_csv(&promp.stats_table(&times))?;
    cps_outcome::files::write_file(out, &csv)?;
    Ok(format!(
        "mean and σ at {} times written to {}",
        times.len(),
        out.display()
    ))
}

/// 201 evenly spaced times over `[0, duration]`.
fn plot_grid(duration: f64) -> Vec<f64> {
    (0..=200).map(|k| duration * k as f64 / 200.0).collect()
}

/// A ProMP fitted to demonstration files, with the demonstrations (time-normalised) for
/// its figure and what the fit had to regularise.
#[derive(Debug)]
pub struct Fitted {
    /// The ProMP.
    pub promp: NamedProMp,
    /// The demonstrations, time-normalised to the ProMP's duration.
    pub demos: Vec<(Vec<f64>, Vec<Vec<f64>>)>,
    /// Sentences on the regularisation that applied (too few demonstrations or samples).
    pub notes: Vec<String>,
}

/// Reads demonstration files (as `imitate` reads them) and fits a ProMP of `bases` basis
/// functions per dimension over `duration` seconds (default: the demonstrations' mean
/// duration).
pub fn fit_files(
    paths: &[&Path],
    columns: Columns<'_>,
    lerobot: &crate::lerobot::Pick,
    bases: usize,
    duration: Option<f64>,
) -> Result<Fitted, InputError> {
    if !(2..=10_000).contains(&bases) {
        return Err(InputError(format!(
            "--bases {bases}: between 2 and 10000 basis functions per dimension"
        )));
    }
    let (names, read) = read_labelled(paths, columns, lerobot)?;
    if read.len() < 2 {
        return Err(InputError(format!(
            "a ProMP learns the spread of several demonstrations: give at least 2 files or dataset episodes (got {})",
            read.len()
        )));
    }
    let raw = read
        .iter()
        .map(|(_, demo)| {
            let rows = (0..demo.len()).map(|k| demo.sample(k).to_vec()).collect();
            (demo.times().to_vec(), rows)
        })
        .collect();
    let labels: Vec<String> = read.iter().map(|(l, _)| l.clone()).collect();
    fit_demos(raw, names, &labels, bases, duration)
}

/// Fits a ProMP to demonstrations in memory (`(times, rows)` each, `labels` naming them
/// in messages) over `duration` seconds (default: their mean duration).
pub fn fit_demos(
    raw: Vec<(Vec<f64>, Vec<Vec<f64>>)>,
    names: Vec<String>,
    labels: &[String],
    bases: usize,
    duration: Option<f64>,
) -> Result<Fitted, InputError> {
    if raw.len() < 2 {
        return Err(InputError(format!(
            "a ProMP learns the spread of several demonstrations: at least 2 are needed (got {})",
            raw.len()
        )));
    }
    let duration = match duration {
        Some(t) if t.is_finite() && t > 0.0 => t,
        Some(t) => {
            return Err(InputError(format!(
                "--duration {t}: must be finite and > 0"
            )));
        }
        None => raw.iter().map(|(t, _)| t[t.len() - 1] - t[0]).sum::<f64>() / raw.len() as f64,
    };
    let weights = names.len() * bases;
    let mut notes = Vec::new();
    if raw.len() <= weights {
        notes.push(format!(
            "{} demonstrations for {weights} weights: their covariance has rank at most {}; a ridge of 1e-10 × the largest weight variance keeps it invertible, so conditioning and sampling move along the demonstrated variations only",
            raw.len(),
            raw.len() - 1
        ));
    }
    if let Some((k, (t, _))) = raw.iter().enumerate().find(|(_, (t, _))| t.len() < bases) {
        notes.push(format!(
            "{}: {} samples for {bases} basis functions; its weights are the ridge solution (λ = 1e-8 × the basis Gram matrix's mean diagonal), the smoothest that fits",
            labels.get(k).map_or("a demonstration", String::as_str),
            t.len()
        ));
    }
    let promp = ProMp::fit(&raw, bases, duration)
        .map_err(|e| InputError(name_demo(&e.to_string(), labels)))?;
    let demonstrations = raw.len();
    let demos = raw
        .into_iter()
        .map(|(t, y)| {
            let (t0, span) = (t[0], t[t.len() - 1] - t[0]);
            (t.iter().map(|s| (s - t0) / span * duration).collect(), y)
        })
        .collect();
    Ok(Fitted {
        promp: NamedProMp {
            promp,
            names,
            demonstrations,
        },
        demos,
        notes,
    })
}

/// Replaces "demonstration k" in a fitting error by its label (a file's name).
fn name_demo(message: &str, labels: &[String]) -> String {
    if let Some(rest) = message.strip_prefix("demonstration ")
        && let Some((k, tail)) = rest.split_once(':')
        && let Ok(k) = k.parse::<usize>()
        && let Some(p) = labels.get(k.wrapping_sub(1))
    {
        return format!("{p}:{tail}");
    }
    message.to_string()
}

impl Fitted {
    /// The demonstrations (faint), the mean and the ±2σ band.
    pub fn figure(&self) -> Figure {
        let demos = self
            .demos
            .iter()
            .map(|(t, y)| {
                let values = (0..self.promp.names.len())
                    .map(|d| y.iter().map(|r| r[d]).collect())
                    .collect();
                Series::new("demonstrations", t.clone(), values).faint()
            })
            .collect();
        self.promp.figure("promp", demos, None, &[])
    }
}

/// Via points from the command line: `--at` times, a `--position` each, one `--std` for
/// all or one each (default 0: exact), and optionally a `--velocity` each with its
/// `--velocity-std`.
#[derive(Debug, Clone, Default)]
pub struct ViaPoints {
    /// Times, seconds.
    pub at: Vec<f64>,
    /// One position per time, one value per dimension.
    pub positions: Vec<Vec<f64>>,
    /// Standard deviations of the positions: none (0), one for all, or one per via point.
    pub stds: Vec<f64>,
    /// Velocities: none, or one per via point.
    pub velocities: Vec<Vec<f64>>,
    /// Standard deviations of the velocities: none (0), one for all, or one per via point.
    pub velocity_stds: Vec<f64>,
}

impl ViaPoints {
    /// Via points from the command line's texts: `positions` and `velocities` are
    /// comma-separated values (`0.4,0.1,0.3`), one text per via point.
    pub fn parse(
        at: &[f64],
        positions: &[String],
        stds: &[f64],
        velocities: &[String],
        velocity_stds: &[f64],
    ) -> Result<Self, InputError> {
        let vectors = |texts: &[String], flag: &str| -> Result<Vec<Vec<f64>>, InputError> {
            texts
                .iter()
                .map(|t| {
                    t.split(',')
                        .map(|v| {
                            v.trim()
                                .parse::<f64>()
                                .ok()
                                .filter(|x| x.is_finite())
                                .ok_or_else(|| {
                                    InputError(format!(
                                        "{flag} {t}: `{}` is not a finite number",
                                        v.trim()
                                    ))
                                })
                        })
                        .collect()
                })
                .collect()
        };
        Ok(ViaPoints {
            at: at.to_vec(),
            positions: vectors(positions, "--position")?,
            stds: stds.to_vec(),
            velocities: vectors(velocities, "--velocity")?,
            velocity_stds: velocity_stds.to_vec(),
        })
    }

    /// The observations for `promp`, checked: counts, dimensions, times within the
    /// movement, standard deviations ≥ 0.
    pub fn observations(&self, promp: &NamedProMp) -> Result<Vec<Observation>, InputError> {
        let n = self.at.len();
        let dims = promp.names.len();
        if n == 0 {
            return Err(InputError(
                "give at least one via point: --at T --position x,y,…".into(),
            ));
        }
        if self.positions.len() != n {
            return Err(InputError(format!(
                "{n} --at times but {} --position values: give one position per time",
                self.positions.len()
            )));
        }
        if !self.velocities.is_empty() && self.velocities.len() != n {
            return Err(InputError(format!(
                "{n} --at times but {} --velocity values: give none or one per time",
                self.velocities.len()
            )));
        }
        let pick = |v: &[f64], k: usize, flag: &str| -> Result<f64, InputError> {
            let s = match v.len() {
                0 => 0.0,
                1 => v[0],
                m if m == n => v[k],
                m => {
                    return Err(InputError(format!(
                        "{m} {flag} values for {n} via points: give one for all or one each"
                    )));
                }
            };
            if s.is_finite() && s >= 0.0 {
                Ok(s)
            } else {
                Err(InputError(format!(
                    "{flag} {s}: a standard deviation must be finite and ≥ 0"
                )))
            }
        };
        let t_max = promp.promp.duration();
        let mut out = Vec::with_capacity(n);
        for k in 0..n {
            let t = self.at[k];
            if !(t.is_finite() && (0.0..=t_max).contains(&t)) {
                return Err(InputError(format!(
                    "--at {t}: outside the demonstrated movement, 0 to {t_max} s"
                )));
            }
            let dims_of = |v: &Vec<f64>, flag: &str| {
                if v.len() == dims {
                    Ok(())
                } else {
                    Err(InputError(format!(
                        "{flag} {} (via point {}): {} values, the ProMP has {dims} dimensions ({})",
                        v.iter().map(f64::to_string).collect::<Vec<_>>().join(","),
                        k + 1,
                        v.len(),
                        promp.names.join(", ")
                    )))
                }
            };
            dims_of(&self.positions[k], "--position")?;
            let mut o =
                Observation::position(t, self.positions[k].clone(), pick(&self.stds, k, "--std")?);
            if let Some(v) = self.velocities.get(k) {
                dims_of(v, "--velocity")?;
                o = o.with_velocity(v.clone(), pick(&self.velocity_stds, k, "--velocity-std")?);
            }
            out.push(o);
        }
        Ok(out)
    }
}

/// A ProMP conditioned on via points.
#[derive(Debug)]
pub struct Conditioned {
    /// The ProMP before.
    pub prior: NamedProMp,
    /// After.
    pub posterior: NamedProMp,
    /// The via points.
    pub via: Vec<Observation>,
}

/// Conditions `prior` on `via`; a singular combination is a clear error.
pub fn condition(prior: NamedProMp, via: &ViaPoints) -> Result<Conditioned, InputError> {
    let obs = via.observations(&prior)?;
    let promp = prior
        .promp
        .condition(&obs)
        .map_err(|e| InputError(e.to_string()))?;
    Ok(Conditioned {
        posterior: NamedProMp {
            promp,
            ..prior.clone()
        },
        prior,
        via: obs,
    })
}

impl Conditioned {
    /// The prior's and the posterior's bands with the via points marked.
    pub fn figure(&self) -> Figure {
        self.posterior
            .figure("conditioned", Vec::new(), Some(&self.prior), &self.via)
    }
}

/// What `cps-cli promp fit` prints for the file written to `out`: JSON `{"model",
/// "dimensions", "demonstrations", "bases", "duration", "mean_std", "notes"}` or lines.
impl crate::robot_file::SaysSaved for Fitted {
    fn said(&self, out: &Path) -> (serde_json::Value, Vec<String>) {
        let p = &self.promp;
        let mean_std = p.mean_std();
        let json = serde_json::json!({
            "model": out,
            "dimensions": p.names,
            "demonstrations": p.demonstrations,
            "bases": p.promp.bases(),
            "duration": p.promp.duration(),
            "mean_std": mean_std,
            "notes": self.notes,
        });
        let mut lines = vec![format!(
            "{} demonstrations, {} dimension(s), {} bases, {} s: ProMP written to {}",
            p.demonstrations,
            p.names.len(),
            p.promp.bases(),
            p.promp.duration(),
            out.display()
        )];
        for (name, s) in p.names.iter().zip(&mean_std) {
            lines.push(format!("  {name}: mean σ over the movement {s:.4e}"));
        }
        lines.extend(self.notes.iter().map(|n| format!("note: {n}")));
        (json, lines)
    }
}

/// What `cps-cli promp condition` prints: per via point, the mean and σ before and
/// after, and a note for a point more than 3σ outside the demonstrations; JSON
/// `{"model", "via_points": [{"time", "position", "prior_mean", "prior_std", "mean",
/// "std", "prior_sigmas"}]}`.
impl crate::robot_file::SaysSaved for Conditioned {
    fn said(&self, out: &Path) -> (serde_json::Value, Vec<String>) {
        let mut lines = vec![format!(
            "conditioned on {} via point(s): ProMP written to {}",
            self.via.len(),
            out.display()
        )];
        let mut points = Vec::new();
        for (k, o) in self.via.iter().enumerate() {
            let at = [o.time];
            let (m0, s0) = self.prior.promp.stats(&at).remove(0);
            let (m1, s1) = self.posterior.promp.stats(&at).remove(0);
            let fmt = |v: &[f64]| {
                v.iter()
                    .map(|x| format!("{x:.4}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            lines.push(format!(
                "  p{} at {} s: mean ({}) σ ({}) → mean ({}) σ ({})",
                k + 1,
                o.time,
                fmt(&m0),
                fmt(&s0),
                fmt(&m1),
                fmt(&s1)
            ));
            // How far outside the demonstrated spread the point lies, in prior σ.
            let obs_var = |d: usize| {
                o.position_cov
                    .get(d * (m0.len() + 1))
                    .copied()
                    .unwrap_or(0.0)
            };
            let sigmas = o.position.as_ref().map_or(0.0, |p| {
                (0..p.len())
                    .map(|d| (p[d] - m0[d]).abs() / (s0[d] * s0[d] + obs_var(d)).sqrt().max(1e-300))
                    .fold(0.0, f64::max)
            });
            if sigmas > 3.0 {
                lines.push(format!(
                    "  note: p{} lies {sigmas:.1} σ from the demonstrated mean; to meet it the ProMP leaves the demonstrated variations, which can bend the movement (give it a --std, or a point inside the band)",
                    k + 1
                ));
            }
            points.push(serde_json::json!({
                "time": o.time, "position": o.position,
                "prior_mean": m0, "prior_std": s0, "mean": m1, "std": s1,
                "prior_sigmas": sigmas,
            }));
        }
        (
            serde_json::json!({ "model": out, "via_points": points }),
            lines,
        )
    }
}
