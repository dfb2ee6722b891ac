//! Figures like the thesis's: cost per generation (log scale, mean and 95 % band over
//! repetitions), each coordinate over time with the way points, and the 3-D path.
//! Every figure is written as PNG and SVG. Fonts are embedded (DejaVu Sans), so nothing
//! is needed from the system.

use std::sync::Once;

use anyhow::{Result, anyhow};
use cps_dmp::Trajectory;
use cps_learn::{GenerationRecord, ViaPointOutcome, ViaPointTask, history_band};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::output::Staging;

static FONT: Once = Once::new();

fn register_font() {
    FONT.call_once(|| {
        // The bytes are a valid font shipped by the dejavu crate; failure would be a bug.
        plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
            .ok();
    });
}

type DrawResult<DB> =
    std::result::Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Draws one figure to `<stem>.png` and `<stem>.svg`.
fn both(
    stage: &Staging,
    stem: &str,
    size: (u32, u32),
    draw: impl Fn(&DynArea) -> Result<()>,
) -> Result<()> {
    register_font();
    let png = stage.path(&format!("{stem}.png"));
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        draw(&DynArea::Bitmap(&root))?;
        root.present()
            .map_err(|e| anyhow!("cannot write {stem}.png: {e}"))?;
    }
    let svg = stage.path(&format!("{stem}.svg"));
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw(&DynArea::Svg(&root))?;
        root.present()
            .map_err(|e| anyhow!("cannot write {stem}.svg: {e}"))?;
    }
    Ok(())
}

/// A drawing area of either backend, so each figure is written once.
enum DynArea<'a, 'b> {
    Bitmap(&'a DrawingArea<BitMapBackend<'b>, Shift>),
    Svg(&'a DrawingArea<SVGBackend<'b>, Shift>),
}

macro_rules! with_area {
    ($area:expr, $f:expr) => {
        match $area {
            DynArea::Bitmap(a) => $f(*a).map_err(|e| anyhow!("cannot draw the figure: {e}")),
            DynArea::Svg(a) => $f(*a).map_err(|e| anyhow!("cannot draw the figure: {e}")),
        }
    };
}

const COLORS: [RGBColor; 3] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
];

/// Best cost so far per generation (log scale): per arm the mean over its repetitions
/// with the 95 % band, and the exact optimum.
fn cost_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    arms: &[CostArm<'_>],
    optimum: Option<f64>,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let positive = |v: f64| {
        if v.is_finite() && v > 0.0 {
            Some(v)
        } else {
            None
        }
    };
    let all = arms.iter().flat_map(|a| {
        a.runs
            .iter()
            .flat_map(|r| r.iter().filter_map(|h| positive(h.best_so_far)))
    });
    let (lo, hi) = all.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let lo = lo.min(optimum.unwrap_or(f64::INFINITY)).max(1e-300);
    let (lo, hi) = if lo < hi {
        (lo * 0.8, hi * 1.25)
    } else {
        (lo * 0.5, lo * 2.0)
    };
    let bands: Vec<Vec<(f64, f64, f64)>> = arms.iter().map(|a| history_band(&a.runs)).collect();
    let gens = bands.iter().map(Vec::len).max().unwrap_or(0).max(2) as f64;
    let reps = arms.first().map_or(1, |a| a.runs.len());
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!("cost per generation ({reps} repetition(s) each)"),
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(1f64..gens, (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("generation")
        .y_desc("best cost so far")
        .draw()?;
    for (i, (arm, band)) in arms.iter().zip(&bands).enumerate() {
        let (label, color) = (&arm.label, COLORS[i % COLORS.len()]);
        if arm.runs.len() > 1 {
            let mut poly: Vec<(f64, f64)> = band
                .iter()
                .enumerate()
                .map(|(g, b)| ((g + 1) as f64, b.2.clamp(lo, hi)))
                .collect();
            poly.extend(
                band.iter()
                    .enumerate()
                    .rev()
                    .map(|(g, b)| ((g + 1) as f64, b.1.clamp(lo, hi))),
            );
            chart
                .draw_series(std::iter::once(Polygon::new(poly, color.mix(0.2))))?
                .label(format!("{label}: 95 % band"))
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 20, y + 5)], color.mix(0.2).filled())
                });
        }
        let mean = band
            .iter()
            .enumerate()
            .filter_map(|(g, b)| positive(b.0).map(|v| ((g + 1) as f64, v)));
        chart
            .draw_series(LineSeries::new(mean, color.stroke_width(2)))?
            .label(if arm.runs.len() > 1 {
                format!("{label}: mean best cost")
            } else {
                format!("{label}: best cost")
            })
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    if let Some(opt) = optimum {
        chart
            .draw_series(LineSeries::new(
                vec![(1.0, opt), (gens, opt)],
                BLACK.stroke_width(1),
            ))?
            .label("exact optimum")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// One curve family of the cost figure: the histories of its repetitions.
pub struct CostArm<'a> {
    /// Legend label.
    pub label: String,
    /// One history per repetition.
    pub runs: Vec<&'a [GenerationRecord]>,
}

impl<'a> CostArm<'a> {
    /// The repetitions of a via-point outcome.
    pub fn of(label: &str, outcome: &'a ViaPointOutcome) -> Self {
        Self {
            label: label.into(),
            runs: outcome.runs.iter().map(|r| r.history.as_slice()).collect(),
        }
    }
}

/// Draws the cost figure `<stem>.png/.svg` of one or more arms, with the exact optimum
/// when there is one.
pub fn costs(
    stage: &Staging,
    stem: &str,
    arms: &[CostArm<'_>],
    optimum: Option<f64>,
) -> Result<()> {
    both(stage, stem, (1000, 600), |a| {
        with_area!(a, |r| cost_plot(r, arms, optimum))
    })
}

/// One curve family of `curves_plot`: a label, its time stamps and one slice of values
/// per dimension.
pub struct Series<'a> {
    /// Legend label (empty: no legend entry).
    pub label: String,
    /// Time stamps of the values.
    pub times: &'a [f64],
    /// `values[d]` for dimension d, one per time stamp.
    pub values: Vec<&'a [f64]>,
    /// Drawn thin and light (for many recordings) instead of bold.
    pub faint: bool,
}

impl Series<'_> {
    fn style(&self, i: usize) -> ShapeStyle {
        if self.faint {
            RGBColor(150, 150, 150).mix(0.5).stroke_width(1)
        } else {
            COLORS[i % COLORS.len()].stroke_width(2)
        }
    }
}

/// One panel per dimension: every series over time, and marked points `(t, value per
/// dimension)`.
fn curves_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    names: &[String],
    series: &[Series<'_>],
    points: &[(f64, Vec<f64>)],
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let dims = names.len();
    let panels = root.split_evenly((dims, 1));
    let (t0, t_end) = series
        .iter()
        .flat_map(|s| s.times.iter())
        .chain(points.iter().map(|p| &p.0))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| {
            (a.min(t), b.max(t))
        });
    let (t0, t_end) = if t0 < t_end { (t0, t_end) } else { (0.0, 1.0) };
    for (d, panel) in panels.iter().enumerate() {
        let values = series
            .iter()
            .flat_map(|s| s.values[d].iter())
            .chain(points.iter().map(|p| &p.1[d]));
        let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
        let pad = ((hi - lo) * 0.08).max(1e-3);
        let mut chart = ChartBuilder::on(panel)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(t0..t_end, (lo - pad)..(hi + pad))?;
        chart
            .configure_mesh()
            .x_desc("t [s]")
            .y_desc(names[d].as_str())
            .draw()?;
        let mut bold = 0;
        let mut faint_labelled = false;
        for s in series {
            let style = s.style(bold);
            bold += usize::from(!s.faint);
            let drawn = chart.draw_series(LineSeries::new(
                s.times.iter().copied().zip(s.values[d].iter().copied()),
                style,
            ))?;
            // One legend entry per label (faint families share theirs).
            let label = !(s.label.is_empty() || s.faint && faint_labelled);
            if d == 0 && label {
                faint_labelled |= s.faint;
                drawn
                    .label(s.label.clone())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
            }
        }
        chart.draw_series(
            points
                .iter()
                .map(|(t, p)| Circle::new((*t, p[d]), 5, BLACK.filled())),
        )?;
        if d == 0 && series.iter().any(|s| !s.label.is_empty()) {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
        }
    }
    Ok(())
}

/// Draws `curves_plot` to `path` (PNG, or SVG when the name ends in `.svg`).
pub fn curves_to_file(
    path: &std::path::Path,
    names: &[String],
    series: &[Series<'_>],
    points: &[(f64, Vec<f64>)],
) -> Result<()> {
    register_font();
    let size = (1000, 300 * names.len().clamp(1, 4) as u32);
    let svg = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    let fail = |e: String| anyhow!("cannot write the figure {}: {e}", path.display());
    // Drawn beside its place under a temporary name (same extension: the format follows
    // it), then renamed: a failed figure never leaves half a file.
    let name = path
        .file_name()
        .map_or("figure".into(), |n| n.to_string_lossy().into_owned());
    let ext = if svg { "svg" } else { "png" };
    let tmp = path.with_file_name(format!(".{name}.cps-tmp-{}.{ext}", std::process::id()));
    if tmp.exists() {
        return Err(fail(format!(
            "{} is in the way of the temporary figure; remove it",
            tmp.display()
        )));
    }
    let drawn = if svg {
        let root = SVGBackend::new(&tmp, size).into_drawing_area();
        curves_plot(&root, names, series, points)
            .and_then(|()| root.present())
            .map_err(|e| fail(e.to_string()))
    } else {
        let root = BitMapBackend::new(&tmp, size).into_drawing_area();
        curves_plot(&root, names, series, points)
            .and_then(|()| root.present())
            .map_err(|e| fail(e.to_string()))
    };
    if let Err(e) = drawn {
        std::fs::remove_file(&tmp).ok();
        return Err(e);
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        std::fs::remove_file(&tmp).ok();
        fail(e.to_string())
    })
}

/// `x [m]`, `y [m]`, `z [m]` for three dimensions, `y0 [m]`, … otherwise.
pub fn axis_names(dims: usize) -> Vec<String> {
    (0..dims)
        .map(|d| {
            if dims == 3 {
                format!("{} [m]", ["x", "y", "z"][d])
            } else {
                format!("y{d} [m]")
            }
        })
        .collect()
}

/// The way points of a task as `(time, position)` marks.
pub fn way_points(task: &ViaPointTask) -> Vec<(f64, Vec<f64>)> {
    let mut points: Vec<(f64, Vec<f64>)> = vec![(0.0, task.start.clone())];
    points.extend(task.via.iter().map(|v| (v.time, v.position.clone())));
    points.push((task.dmp.tau, task.goal.clone()));
    points
}

/// A 3-D path plot: every series (x, y, z over its samples) and marked points.
fn path_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &[Series<'_>],
    points: &[Vec<f64>],
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let range = |d: usize| {
        let (lo, hi) = series
            .iter()
            .flat_map(|s| s.values[d].iter())
            .chain(points.iter().map(|p| &p[d]))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let pad = ((hi - lo) * 0.05).max(1e-3);
        (lo - pad)..(hi + pad)
    };
    // plotters' vertical axis is its y: pass (x, z, y) so the world's z points up.
    let mut chart = ChartBuilder::on(root)
        .caption("3-D path (world frame)", ("sans-serif", 22))
        .margin(10)
        .build_cartesian_3d(range(0), range(2), range(1))?;
    chart.with_projection(|mut p| {
        p.yaw = 0.6;
        p.pitch = 0.35;
        p.scale = 0.85;
        p.into_matrix()
    });
    chart
        .configure_axes()
        .x_labels(5)
        .y_labels(5)
        .z_labels(5)
        .draw()?;
    let mut bold = 0;
    for s in series {
        let style = s.style(bold);
        bold += usize::from(!s.faint);
        let (x, y, z) = (s.values[0], s.values[1], s.values[2]);
        chart.draw_series(LineSeries::new(
            (0..x.len()).map(|k| (x[k], z[k], y[k])),
            style,
        ))?;
    }
    chart.draw_series(
        points
            .iter()
            .map(|p| Circle::new((p[0], p[2], p[1]), 5, BLACK.filled())),
    )?;
    Ok(())
}

/// Draws the per-coordinate figure (`<stem>.png/.svg`) and, for three dimensions, the 3-D
/// path (`path3d*.png/.svg`).
pub fn figures(
    stage: &Staging,
    stem: &str,
    path_stem: &str,
    series: &[Series<'_>],
    points: &[(f64, Vec<f64>)],
) -> Result<()> {
    let dims = series.first().map_or(0, |s| s.values.len());
    panels(stage, stem, &axis_names(dims), series, points)?;
    if dims == 3 {
        let marks: Vec<Vec<f64>> = points.iter().map(|p| p.1.clone()).collect();
        both(stage, path_stem, (900, 800), |a| {
            with_area!(a, |r| path_plot(r, series, &marks))
        })?;
    }
    Ok(())
}

/// One panel per dimension (named by `names`) of every series, with marked points, to
/// `<stem>.png/.svg`.
pub fn panels(
    stage: &Staging,
    stem: &str,
    names: &[String],
    series: &[Series<'_>],
    points: &[(f64, Vec<f64>)],
) -> Result<()> {
    let height = if names.len() <= 4 { 300 } else { 220 };
    both(
        stage,
        stem,
        (1000, height * names.len().max(1) as u32),
        |a| with_area!(a, |r| curves_plot(r, names, series, points)),
    )
}

/// The series of one trajectory's positions.
pub fn trajectory_series<'a>(label: &str, traj: &'a Trajectory) -> Series<'a> {
    Series {
        label: label.into(),
        times: traj.times(),
        values: (0..traj.dims()).map(|d| traj.position(d)).collect(),
        faint: false,
    }
}

/// Draws every figure of a via-point run into `stage`.
pub fn viapoint(stage: &Staging, outcome: &ViaPointOutcome, task: &ViaPointTask) -> Result<()> {
    costs(
        stage,
        "cost",
        &[CostArm::of("CMA-ES", outcome)],
        Some(outcome.optimum.cost),
    )?;
    let traj = outcome.best_trajectory();
    figures(
        stage,
        "coordinates",
        "path3d",
        &[trajectory_series("", &traj)],
        &way_points(task),
    )
}
