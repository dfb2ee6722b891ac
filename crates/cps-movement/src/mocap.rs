//! Motion capture for the command line, Python and experiment files: a take shown
//! (`mocap show`), made a demonstration CSV with its report and figures (`mocap import`),
//! and read as the demonstrations of an experiment. The reading and the numerics are
//! `cps-mocap`'s; this module adds files, words and figures.

use std::path::{Path, PathBuf};

use cps_mocap::demo::{Demonstration, Settings, demonstrate, read_take};
use cps_mocap::register::Calibration;
use cps_mocap::{MocapError, Take};
use serde_json::{Value, json};

use cps_outcome::outcome::{Figure, Mark, MarkKind, Panels, Plot, Series};
use cps_outcome::{ExperimentError, InputError};

/// A take's problem as input (exit 2 on the command line).
pub fn mocap_error(e: MocapError) -> InputError {
    InputError(e.to_string())
}

/// Reads a take (`.c3d`, or a Motive `.csv` export).
pub fn read(path: &Path) -> Result<Take, InputError> {
    read_take(path).map_err(mocap_error)
}

/// Makes the demonstration of a take; `calibration` is a registration file.
pub fn demonstration(
    take: &Path,
    settings: &Settings,
    calibration: Option<&Path>,
) -> Result<Demonstration, InputError> {
    let mut s = settings.clone();
    if let Some(c) = calibration {
        s.calibration = Some(Calibration::read(c).map_err(mocap_error)?);
    }
    let t = read(take)?;
    demonstrate(&t, &s).map_err(mocap_error)
}

/// Motion-capture takes (`names`, relative to `dir`) made demonstrations as
/// `demonstration` makes each: the tool's path over time in the task's frame (its
/// velocities and accelerations left at zero for the learner to estimate), in the order
/// given. An experiment's `[demonstrations] takes` are read here. Errors name the take.
pub fn demonstrations(
    dir: &Path,
    names: &[String],
    settings: &Settings,
    calibration: Option<&Path>,
) -> Result<Vec<(String, cps_dmp::Trajectory)>, InputError> {
    let mut out = Vec::with_capacity(names.len());
    for name in names {
        let demo = demonstration(&dir.join(name), settings, calibration)?;
        let times = demo.t.clone();
        let position: Vec<Vec<f64>> = (0..3)
            .map(|k| demo.position.iter().map(|p| p[k]).collect())
            .collect();
        let zeros = vec![vec![0.0; times.len()]; 3];
        out.push((
            name.clone(),
            cps_dmp::Trajectory::from_parts(times, &position, &zeros, &zeros),
        ));
    }
    Ok(out)
}

/// `mocap show`: a take read, to say its labels, rate, frames, units, each marker's gaps,
/// analog channels and rigid bodies.
pub fn show(path: &Path) -> Result<Shown, InputError> {
    Ok(Shown {
        path: path.to_path_buf(),
        take: read(path)?,
    })
}

/// A take and where it is (`mocap show`).
#[derive(Debug, Clone)]
pub struct Shown {
    /// The file.
    pub path: PathBuf,
    /// The take.
    pub take: cps_mocap::take::Take,
}

impl Shown {
    /// Its format in words.
    fn kind(&self) -> String {
        match self.take.source {
            cps_mocap::take::Source::C3d { float, processor } => format!(
                "C3D ({}, {processor:?})",
                if float {
                    "floating point"
                } else {
                    "16-bit integers"
                }
            ),
            cps_mocap::take::Source::MotiveCsv => "Motive CSV".into(),
        }
    }

    fn bodies(&self) -> Vec<&str> {
        self.take
            .rigid_bodies
            .iter()
            .map(|b| b.name.as_str())
            .collect()
    }
}

/// `{"file", "format", "frames", "rate_hz", "duration_s", "first_frame", "units",
/// "metres_per_unit", "markers": [{"label", "missing_frames", "gaps",
/// "longest_gap_frames", "gap_frames"}], "rigid_bodies", "analog", "notes"}`.
impl serde::Serialize for Shown {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let t = &self.take;
        let markers: Vec<Value> = (0..t.markers())
            .map(|m| {
                let gaps = t.gaps(m);
                let missing: usize = gaps.iter().map(|g| g.len()).sum();
                let longest = gaps.iter().map(|g| g.len()).max().unwrap_or(0);
                json!({
                    "label": t.labels[m],
                    "missing_frames": missing,
                    "gaps": gaps.len(),
                    "longest_gap_frames": longest,
                    "gap_frames": gaps.iter().map(|g| [t.first_frame + g.start as u64, t.first_frame + g.end as u64 - 1]).collect::<Vec<_>>(),
                })
            })
            .collect();
        json!({
            "file": self.path.display().to_string(),
            "format": self.kind(),
            "frames": t.frames,
            "rate_hz": t.rate,
            "duration_s": t.duration(),
            "first_frame": t.first_frame,
            "units": t.units,
            "metres_per_unit": t.metres_per_unit,
            "markers": markers,
            "rigid_bodies": self.bodies(),
            "analog": t.analog.as_ref().map(|a| json!({
                "labels": a.labels, "units": a.units, "rate_hz": a.rate,
                "samples_per_frame": a.samples_per_frame,
            })),
            "notes": t.notes,
        })
        .serialize(s)
    }
}

impl std::fmt::Display for Shown {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let t = &self.take;
        writeln!(f, "{}: {}", self.path.display(), self.kind())?;
        writeln!(
            f,
            "  {} frames at {} Hz ({:.3} s), first frame {}; lengths in {} ({} m each)",
            t.frames,
            t.rate,
            t.duration(),
            t.first_frame,
            t.units,
            t.metres_per_unit
        )?;
        write!(f, "  {} markers:", t.markers())?;
        for m in 0..t.markers() {
            let gaps = t.gaps(m);
            let missing: usize = gaps.iter().map(|g| g.len()).sum();
            let longest = gaps.iter().map(|g| g.len()).max().unwrap_or(0);
            let seen = 100.0 * (t.frames - missing) as f64 / t.frames.max(1) as f64;
            write!(f, "\n    {:<24} seen {seen:>6.2} %", t.labels[m])?;
            if !gaps.is_empty() {
                let from = gaps
                    .iter()
                    .max_by_key(|g| g.len())
                    .map_or(0, |g| t.first_frame + g.start as u64);
                write!(
                    f,
                    ", {} gap(s), longest {longest} frames (from frame {from})",
                    gaps.len()
                )?;
            }
        }
        let bodies = self.bodies();
        if !bodies.is_empty() {
            write!(f, "\n  rigid bodies: {}", bodies.join(", "))?;
        }
        if let Some(a) = &t.analog {
            let labels = a.labels.join(", ");
            write!(
                f,
                "\n  {} analog channel(s) at {} Hz: {labels}",
                a.channels(),
                a.rate
            )?;
        }
        for n in &t.notes {
            write!(f, "\n  note: {n}")?;
        }
        Ok(())
    }
}

/// What `mocap import` writes besides the demonstration.
#[derive(Debug, Clone, Default)]
pub struct ImportFiles {
    /// A registration file (`--to-robot`).
    pub calibration: Option<PathBuf>,
    /// Figures: `<stem>_markers.png` and `<stem>_demonstration.png` beside this path's
    /// stem (`--plot demo.png`); SVG when it ends in `.svg`.
    pub plot: Option<PathBuf>,
    /// The robot whose reach the demonstration figure shows and the report checks (the
    /// demonstration in its base frame).
    pub robot: Option<String>,
    /// Or a scene (`thesis`, `fr3` or a file) whose placed robot's reach is shown (the
    /// demonstration in the scene's world frame).
    pub scene: Option<String>,
    /// Replace an existing output.
    pub force: bool,
}

/// `mocap import`: the demonstration of a take written to `out` (`t,x,y,z,qx,qy,qz,qw`),
/// with figures if asked; nothing is written when the take is refused.
pub fn import(
    take: &Path,
    settings: &Settings,
    files: &ImportFiles,
    out: &Path,
) -> Result<Imported, ExperimentError> {
    if out.exists() && !files.force {
        return Err(InputError(format!(
            "{} exists; add --force to replace it",
            out.display()
        ))
        .into());
    }
    let demo = demonstration(take, settings, files.calibration.as_deref())?;
    let reach = match (&files.scene, &files.robot) {
        (Some(s), _) => {
            let scene = crate::scene::Scene::named_or_file(s)?;
            Some(reach_of(
                &scene.robot.chain,
                &format!("{} in scene {s}", scene.robot.name),
            ))
        }
        (None, Some(r)) => Some(reach_of(
            &crate::robot_file::load_robot(r, None, None)?.chain,
            r,
        )),
        (None, None) => None,
    };
    cps_outcome::files::write_file(out, demo.csv().as_bytes())?;
    let mut written = vec![out.display().to_string()];
    if let Some(plot) = &files.plot {
        for f in figures(&demo, reach.clone()) {
            let path = figure_path(plot, &f.name);
            draw(&f, &path)?;
            written.push(path.display().to_string());
        }
    }
    let beyond = reach.as_ref().map(|r| {
        demo.position
            .iter()
            .filter(|p| cps_mocap::fit::norm(cps_mocap::fit::sub(**p, r.centre)) > r.radius)
            .count()
    });
    Ok(Imported {
        out: out.to_path_buf(),
        report: demo.report,
        beyond,
        reach,
        figures: written.split_off(1),
    })
}

/// A take made a demonstration (`mocap import`): its report, what lies beyond the robot's
/// reach, the figures drawn.
#[derive(Debug, Clone)]
pub struct Imported {
    /// The demonstration written.
    pub out: PathBuf,
    /// How it was made from the take.
    pub report: cps_mocap::demo::Report,
    /// Poses beyond the robot's reach (with `--robot` or `--scene`).
    pub beyond: Option<usize>,
    /// That reach.
    pub reach: Option<Reach>,
    /// The figures drawn.
    pub figures: Vec<String>,
}

/// `{"demonstration", "report", "beyond_reach", "reach_m", "figures"}`.
impl serde::Serialize for Imported {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        json!({
            "demonstration": self.out.display().to_string(),
            "report": serde_json::to_value(&self.report).unwrap_or_default(),
            "beyond_reach": self.beyond,
            "reach_m": self.reach.as_ref().map(|r| r.radius),
            "figures": self.figures,
        })
        .serialize(s)
    }
}

impl std::fmt::Display for Imported {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let r = &self.report;
        write!(
            f,
            "{}: {} poses over {:.3} s (frames {}–{} of {}, cut {} at the start and {} at the end), from {}",
            self.out.display(),
            r.frames,
            r.duration_s,
            r.kept_frames[0],
            r.kept_frames[1],
            r.frames_in_take,
            r.cut[0],
            r.cut[1],
            r.from
        )?;
        write!(
            f,
            "\n  markers within {:.3} mm RMS of the body on average, {:.3} mm at worst; {} frame(s) fitted with fewer than all markers",
            r.fit_rms_mean_m * 1e3,
            r.fit_rms_max_m * 1e3,
            r.frames_with_fewer_markers
        )?;
        for m in r
            .markers
            .iter()
            .filter(|m| m.missing_frames + m.outliers > 0)
        {
            write!(
                f,
                "\n  {}: {} frame(s) missing, {} gap(s) filled ({} frames, longest {}), {} outlier(s) rejected",
                m.label,
                m.missing_frames,
                m.gaps_filled,
                m.frames_filled,
                m.longest_filled,
                m.outliers,
            )?;
            if !m.open_gaps.is_empty() {
                write!(f, ", {} gap(s) left open", m.open_gaps.len())?;
            }
        }
        match &r.registration {
            Some(g) => write!(
                f,
                "\n  in the robot's frame: registration from {} points, {:.3} mm RMS ({:.3} mm at `{}`)",
                g.points,
                g.rms_m * 1e3,
                g.max_m * 1e3,
                g.worst
            )?,
            None => write!(
                f,
                "\n  frame: {} (no registration: the take's own axes)",
                r.frame
            )?,
        }
        if let (Some(n), Some(reach)) = (self.beyond, &self.reach) {
            let c = reach.centre;
            write!(
                f,
                "\n  {n} of {} poses lie beyond the reach of the {} ({:.3} m from its shoulder at ({:.3}, {:.3}, {:.3}) m)",
                r.frames, reach.robot, reach.radius, c[0], c[1], c[2]
            )?;
        }
        for w in &self.figures {
            write!(f, "\n  figure: {w}")?;
        }
        Ok(())
    }
}

/// A robot's reach: a sphere about the centroid of 4 000 random tool positions within its
/// limits (seed 1) — its shoulder, for an arm — holding them all; `name` names it.
fn reach_of(chain: &cps_kinematics::SerialChain, name: &str) -> Reach {
    let pts = cps_kinematics::sample_workspace(chain, 4000, 1);
    let n = pts.len().max(1) as f64;
    let centre = [
        pts.iter().map(|p| p.x).sum::<f64>() / n,
        pts.iter().map(|p| p.y).sum::<f64>() / n,
        pts.iter().map(|p| p.z).sum::<f64>() / n,
    ];
    let radius = pts
        .iter()
        .map(|p| cps_mocap::fit::norm(cps_mocap::fit::sub([p.x, p.y, p.z], centre)))
        .fold(0.0, f64::max);
    Reach {
        radius,
        centre,
        robot: name.to_string(),
    }
}

/// A robot's reach as a sphere.
#[derive(Debug, Clone, PartialEq)]
pub struct Reach {
    /// Radius, metres.
    pub radius: f64,
    /// Centre in the robot's base frame.
    pub centre: [f64; 3],
    /// The robot.
    pub robot: String,
}

fn figure_path(plot: &Path, name: &str) -> PathBuf {
    let stem = plot
        .file_stem()
        .map_or("mocap".into(), |s| s.to_string_lossy().into_owned());
    let ext = plot
        .extension()
        .map_or("png".into(), |e| e.to_string_lossy().into_owned());
    plot.with_file_name(format!("{stem}_{name}.{ext}"))
}

#[cfg(feature = "figures")]
fn draw(f: &Figure, path: &Path) -> Result<(), ExperimentError> {
    cps_report::figures::draw_file(f, path)
}

#[cfg(not(feature = "figures"))]
fn draw(_: &Figure, path: &Path) -> Result<(), ExperimentError> {
    Err(ExperimentError::Message(format!(
        "cannot draw {}: cps-experiment was built without its `figures` feature",
        path.display()
    )))
}

/// The figures of a demonstration: its markers and the fitted body over time (a marker's
/// line breaks where it was not seen), and its path in the output frame with the robot's
/// reach (its sphere's equator, at the shoulder's height) when a reach is given.
pub fn figures(demo: &Demonstration, reach: Option<Reach>) -> Vec<Figure> {
    let t = demo.t.clone();
    let mut series: Vec<Series> = demo
        .markers
        .iter()
        .zip(&demo.seen)
        .zip(&demo.labels)
        .map(|((track, seen), label)| {
            let values = (0..3)
                .map(|k| {
                    track
                        .iter()
                        .zip(seen)
                        .map(|(p, s)| if *s { p[k] } else { f64::NAN })
                        .collect()
                })
                .collect();
            Series::new(label.clone(), t.clone(), values).faint()
        })
        .collect();
    series.push(Series::new(
        "body",
        t.clone(),
        (0..3)
            .map(|k| demo.position.iter().map(|p| p[k]).collect())
            .collect(),
    ));
    let gaps: Vec<Mark> = demo
        .seen
        .iter()
        .zip(&demo.markers)
        .flat_map(|(seen, track)| {
            cps_mocap::take::runs(seen.iter().map(|s| !s))
                .into_iter()
                .map(move |g| (g.start, track[g.start]))
        })
        .filter(|(_, p)| p[0].is_finite())
        .map(|(i, p)| Mark {
            time: demo.t[i],
            values: p.to_vec(),
            kind: MarkKind::Gap,
            label: String::new(),
        })
        .take(50)
        .collect();
    let mut out = vec![Figure {
        name: "markers".into(),
        caption: format!(
            "{}: the markers (faint; a line breaks where a marker was not seen, a hollow circle where a filled gap begins) and the fitted body's origin (bold), in the demonstration's frame ({})",
            demo.report.file, demo.report.frame
        ),
        plot: Plot::Panels(
            Panels::new(vec!["x [m]".into(), "y [m]".into(), "z [m]".into()], series).marks(gaps),
        ),
    }];
    let mut paths = vec![Series::new(
        "demonstration",
        t.clone(),
        (0..3)
            .map(|k| demo.position.iter().map(|p| p[k]).collect())
            .collect(),
    )];
    if let Some(Reach {
        radius: r,
        centre,
        robot: name,
    }) = &reach
    {
        let n = 181;
        let circle: Vec<f64> = (0..n)
            .map(|i| i as f64 * std::f64::consts::TAU / (n - 1) as f64)
            .collect();
        paths.push(
            Series::new(
                format!("reach of the {name} ({r:.2} m)"),
                circle.clone(),
                vec![
                    circle.iter().map(|a| centre[0] + r * a.cos()).collect(),
                    circle.iter().map(|a| centre[1] + r * a.sin()).collect(),
                    vec![centre[2]; n],
                ],
            )
            .faint(),
        );
    }
    let marks = match (demo.position.first(), demo.position.last()) {
        (Some(a), Some(b)) => vec![
            Mark {
                time: 0.0,
                values: a.to_vec(),
                kind: MarkKind::Start,
                label: "start".into(),
            },
            Mark {
                time: *demo.t.last().unwrap_or(&0.0),
                values: b.to_vec(),
                kind: MarkKind::Goal,
                label: "end".into(),
            },
        ],
        _ => Vec::new(),
    };
    out.push(Figure {
        name: "demonstration".into(),
        caption: format!(
            "The demonstration's path in the {} frame{}",
            if demo.report.registration.is_some() {
                "robot's"
            } else {
                "take's"
            },
            if reach.is_some() {
                ", with the robot's reach about its base"
            } else {
                ""
            }
        ),
        plot: Plot::Path3d {
            series: paths,
            marks,
        },
    });
    out
}
