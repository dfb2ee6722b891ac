//! Figures as images (feature `figures`): each [`Plot`] of an outcome drawn as PNG or SVG
//! with plotters — cost per generation (log scale, mean and 95 % band over
//! repetitions), one panel per dimension over time with marked points, and 3-D paths.
//! Fonts are embedded (DejaVu Sans), so nothing is needed from the system.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::ExperimentError;
use crate::outcome::{CostArm, Figure, Plot, Series};

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

const COLORS: [RGBColor; 3] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
];

fn style(s: &Series, i: usize) -> ShapeStyle {
    if s.faint {
        RGBColor(150, 150, 150).mix(0.5).stroke_width(1)
    } else {
        COLORS[i % COLORS.len()].stroke_width(2)
    }
}

/// The canvas size of a plot, pixels.
fn size(plot: &Plot) -> (u32, u32) {
    match plot {
        Plot::Cost { .. } => (1000, 600),
        Plot::Path3d { .. } => (900, 800),
        Plot::Panels { names, .. } => {
            let height = if names.len() <= 4 { 300 } else { 220 };
            (1000, height * names.len().max(1) as u32)
        }
    }
}

fn plot_on<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, plot: &Plot) -> DrawResult<DB> {
    match plot {
        Plot::Cost { arms, optimum } => cost_plot(root, arms, *optimum),
        Plot::Panels {
            names,
            series,
            marks,
        } => curves_plot(root, names, series, marks),
        Plot::Path3d { series, marks } => path_plot(root, series, marks),
    }
}

/// Draws `figure` to `path`: SVG when the name ends in `.svg`, PNG otherwise.
pub fn draw(figure: &Figure, path: &Path) -> Result<(), ExperimentError> {
    register_font();
    let size = size(&figure.plot);
    let svg = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    let fail = |e: String| {
        ExperimentError::Message(format!("cannot write the figure {}: {e}", path.display()))
    };
    if svg {
        let root = SVGBackend::new(path, size).into_drawing_area();
        plot_on(&root, &figure.plot)
            .and_then(|()| root.present())
            .map_err(|e| fail(e.to_string()))
    } else {
        let root = BitMapBackend::new(path, size).into_drawing_area();
        plot_on(&root, &figure.plot)
            .and_then(|()| root.present())
            .map_err(|e| fail(e.to_string()))
    }
}

/// Draws `figure` to a file of its own at `path`: drawn beside it under a temporary name
/// (same extension: the format follows it), then renamed, so a failed figure never leaves
/// half a file.
pub fn draw_file(figure: &Figure, path: &Path) -> Result<(), ExperimentError> {
    let name = path
        .file_name()
        .map_or("figure".into(), |n| n.to_string_lossy().into_owned());
    let svg = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    let ext = if svg { "svg" } else { "png" };
    let tmp = path.with_file_name(format!(".{name}.cps-tmp-{}.{ext}", std::process::id()));
    if tmp.exists() {
        return Err(ExperimentError::Message(format!(
            "cannot write the figure {}: {} is in the way of the temporary figure; remove it",
            path.display(),
            tmp.display()
        )));
    }
    if let Err(e) = draw(figure, &tmp) {
        std::fs::remove_file(&tmp).ok();
        return Err(e);
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        std::fs::remove_file(&tmp).ok();
        ExperimentError::Message(format!("cannot write the figure {}: {e}", path.display()))
    })
}

/// Best cost so far per generation (log scale): per arm the mean over its repetitions
/// with the 95 % band, and the exact optimum.
fn cost_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    arms: &[CostArm],
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
    let (lo, hi) = arms.iter().fold((f64::INFINITY, 0.0f64), |(a, b), arm| {
        (a.min(arm.range.0), b.max(arm.range.1))
    });
    let lo = lo.min(optimum.unwrap_or(f64::INFINITY)).max(1e-300);
    let (lo, hi) = if lo < hi {
        (lo * 0.8, hi * 1.25)
    } else {
        (lo * 0.5, lo * 2.0)
    };
    let bands: Vec<&[(f64, f64, f64)]> = arms.iter().map(|a| a.band.as_slice()).collect();
    let gens = bands.iter().map(|b| b.len()).max().unwrap_or(0).max(2) as f64;
    let reps = arms.first().map_or(1, |a| a.repetitions);
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
        if arm.repetitions > 1 {
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
            .label(if arm.repetitions > 1 {
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

/// One panel per dimension: every series over time, and marked points `(t, value per
/// dimension)`.
fn curves_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    names: &[String],
    series: &[Series],
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
            let style = style(s, bold);
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

/// A 3-D path plot: every series (x, y, z over its samples) and marked points.
fn path_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &[Series],
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
        let style = style(s, bold);
        bold += usize::from(!s.faint);
        let (x, y, z) = (&s.values[0], &s.values[1], &s.values[2]);
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
