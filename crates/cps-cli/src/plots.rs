//! Figures like the thesis's: cost per generation (log scale, mean and 95 % band over
//! repetitions), each coordinate over time with the way points, and the 3-D path.
//! Every figure is written as PNG and SVG. Fonts are embedded (DejaVu Sans), so nothing
//! is needed from the system.

use std::sync::Once;

use anyhow::{Result, anyhow};
use cps_dmp::Trajectory;
use cps_learn::{ViaPointOutcome, ViaPointTask, history_band};
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
        root.present().map_err(|e| anyhow!("{stem}.png: {e:?}"))?;
    }
    let svg = stage.path(&format!("{stem}.svg"));
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw(&DynArea::Svg(&root))?;
        root.present().map_err(|e| anyhow!("{stem}.svg: {e:?}"))?;
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
            DynArea::Bitmap(a) => $f(*a).map_err(|e| anyhow!("plot: {e:?}")),
            DynArea::Svg(a) => $f(*a).map_err(|e| anyhow!("plot: {e:?}")),
        }
    };
}

const COLORS: [RGBColor; 3] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
];

fn cost_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    outcome: &ViaPointOutcome,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let band = history_band(&outcome.runs);
    let positive = |v: f64| {
        if v.is_finite() && v > 0.0 {
            Some(v)
        } else {
            None
        }
    };
    let all = outcome
        .runs
        .iter()
        .flat_map(|r| r.history.iter().filter_map(|h| positive(h.best_so_far)));
    let (lo, hi) = all.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let lo = lo.min(outcome.optimum.cost).max(1e-300);
    let (lo, hi) = if lo < hi {
        (lo * 0.8, hi * 1.25)
    } else {
        (lo * 0.5, lo * 2.0)
    };
    let gens = band.len().max(2) as f64;
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!("cost per generation ({} repetition(s))", outcome.runs.len()),
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
    if outcome.runs.len() > 1 {
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
            .draw_series(std::iter::once(Polygon::new(poly, COLORS[0].mix(0.25))))?
            .label("95 % band")
            .legend(|(x, y)| {
                Rectangle::new([(x, y - 5), (x + 20, y + 5)], COLORS[0].mix(0.25).filled())
            });
    }
    let mean = band
        .iter()
        .enumerate()
        .filter_map(|(g, b)| positive(b.0).map(|v| ((g + 1) as f64, v)));
    chart
        .draw_series(LineSeries::new(mean, COLORS[0].stroke_width(2)))?
        .label(if outcome.runs.len() > 1 {
            "mean best cost"
        } else {
            "best cost"
        })
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], COLORS[0].stroke_width(2)));
    let opt = outcome.optimum.cost;
    chart
        .draw_series(LineSeries::new(
            vec![(1.0, opt), (gens, opt)],
            BLACK.stroke_width(1),
        ))?
        .label("exact optimum")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// One curve family of [`curves_plot`]: a label and one slice of values per dimension.
pub struct Series<'a> {
    /// Legend label.
    pub label: String,
    /// `values[d]` for dimension d, on the shared time axis.
    pub values: Vec<&'a [f64]>,
    /// Drawn thin and light (for many recordings) instead of bold.
    pub faint: bool,
}

/// One panel per dimension: every series over time, and marked points `(t, value per
/// dimension)`.
fn curves_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    times: &[f64],
    names: &[String],
    series: &[Series<'_>],
    points: &[(f64, Vec<f64>)],
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let dims = names.len();
    let panels = root.split_evenly((dims, 1));
    let t_end = times.last().copied().unwrap_or(1.0).max(1e-9);
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
            .build_cartesian_2d(times[0]..t_end, (lo - pad)..(hi + pad))?;
        chart
            .configure_mesh()
            .x_desc("t [s]")
            .y_desc(names[d].as_str())
            .draw()?;
        for (i, s) in series.iter().enumerate() {
            let style = if s.faint {
                RGBColor(150, 150, 150).mix(0.5).stroke_width(1)
            } else {
                COLORS[i % 3].stroke_width(2)
            };
            let drawn = chart.draw_series(LineSeries::new(
                times.iter().copied().zip(s.values[d].iter().copied()),
                style,
            ))?;
            if d == 0 && !s.label.is_empty() {
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

/// Draws [`curves_plot`] to `path` (PNG, or SVG when the name ends in `.svg`).
pub fn curves_to_file(
    path: &std::path::Path,
    times: &[f64],
    names: &[String],
    series: &[Series<'_>],
    points: &[(f64, Vec<f64>)],
) -> Result<()> {
    register_font();
    let size = (1000, 300 * names.len().clamp(1, 4) as u32);
    let svg = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    let fail = |e: String| anyhow!("{}: {e}", path.display());
    if svg {
        let root = SVGBackend::new(path, size).into_drawing_area();
        curves_plot(&root, times, names, series, points).map_err(|e| fail(format!("{e:?}")))?;
        root.present().map_err(|e| fail(format!("{e:?}")))?;
    } else {
        let root = BitMapBackend::new(path, size).into_drawing_area();
        curves_plot(&root, times, names, series, points).map_err(|e| fail(format!("{e:?}")))?;
        root.present().map_err(|e| fail(format!("{e:?}")))?;
    }
    Ok(())
}

fn coordinate_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    traj: &Trajectory,
    task: &ViaPointTask,
) -> DrawResult<DB> {
    let dims = traj.dims();
    let mut points: Vec<(f64, Vec<f64>)> = vec![(0.0, task.start.clone())];
    points.extend(task.via.iter().map(|v| (v.time, v.position.clone())));
    points.push((task.dmp.tau, task.goal.clone()));
    let names: Vec<String> = (0..dims)
        .map(|d| {
            if dims == 3 {
                format!("{} [m]", ["x", "y", "z"][d])
            } else {
                format!("y{d} [m]")
            }
        })
        .collect();
    let series = [Series {
        label: String::new(),
        values: (0..dims).map(|d| traj.position(d)).collect(),
        faint: false,
    }];
    curves_plot(root, traj.times(), &names, &series, &points)
}

fn path_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    traj: &Trajectory,
    task: &ViaPointTask,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let (x, y, z) = (traj.position(0), traj.position(1), traj.position(2));
    let mut pts: Vec<[f64; 3]> = vec![[task.start[0], task.start[1], task.start[2]]];
    pts.extend(
        task.via
            .iter()
            .map(|v| [v.position[0], v.position[1], v.position[2]]),
    );
    pts.push([task.goal[0], task.goal[1], task.goal[2]]);
    let range = |v: &[f64], d: usize| {
        let (lo, hi) = v
            .iter()
            .chain(pts.iter().map(|p| &p[d]))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let pad = ((hi - lo) * 0.05).max(1e-3);
        (lo - pad)..(hi + pad)
    };
    // plotters' vertical axis is its y: pass (x, z, y) so the world's z points up.
    let mut chart = ChartBuilder::on(root)
        .caption(
            "3-D path (world frame) with the way points",
            ("sans-serif", 22),
        )
        .margin(10)
        .build_cartesian_3d(range(x, 0), range(z, 2), range(y, 1))?;
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
    chart.draw_series(LineSeries::new(
        (0..x.len()).map(|k| (x[k], z[k], y[k])),
        COLORS[0].stroke_width(2),
    ))?;
    chart.draw_series(
        pts.iter()
            .map(|p| Circle::new((p[0], p[2], p[1]), 5, BLACK.filled())),
    )?;
    Ok(())
}

/// Draws every figure of a via-point run into `stage`.
pub fn viapoint(stage: &Staging, outcome: &ViaPointOutcome, task: &ViaPointTask) -> Result<()> {
    both(stage, "cost", (1000, 600), |a| {
        with_area!(a, |r| cost_plot(r, outcome))
    })?;
    let traj = outcome.best_trajectory();
    both(stage, "coordinates", (1000, 900), |a| {
        with_area!(a, |r| coordinate_plot(r, &traj, task))
    })?;
    if traj.dims() == 3 {
        both(stage, "path3d", (900, 800), |a| {
            with_area!(a, |r| path_plot(r, &traj, task))
        })?;
    }
    Ok(())
}
