//! Figures as images (feature `figures`): each [`Plot`] of an outcome drawn as PNG or SVG
//! with plotters — cost per generation (log scale, mean and 95 % band over
//! repetitions), one panel per dimension over time with marked points, and 3-D paths.
//! Fonts are embedded (DejaVu Sans), so nothing is needed from the system.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use cps_outcome::ExperimentError;
use plotters::coord::CoordTranslate;

use cps_outcome::outcome::{CostArm, Figure, Mark, MarkKind, Panels, Plot, Series};

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

/// Curve colours (colour-blind-safe order of the tab10 palette), start green, goal red.
const COLORS: [RGBColor; 5] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];
const GREY: RGBColor = RGBColor(150, 150, 150);
const START: RGBColor = RGBColor(44, 160, 44);
const GOAL: RGBColor = RGBColor(214, 39, 40);
/// Obstacles: purple crosses.
const OBSTACLE: RGBColor = RGBColor(148, 103, 189);
const LIMIT: RGBColor = RGBColor(214, 39, 40);
/// Width of the legend column beside the data, pixels.
const LEGEND_WIDTH: u32 = 250;

/// The canvas size of a plot, pixels (the legend column included).
fn size(plot: &Plot) -> (u32, u32) {
    match plot {
        Plot::Cost { .. } => (1000 + LEGEND_WIDTH, 600),
        Plot::Path3d { .. } => (900 + LEGEND_WIDTH, 800),
        Plot::Panels(p) => {
            let height = if p.names.len() <= 4 { 300 } else { 220 };
            (1000 + LEGEND_WIDTH, height * p.names.len().max(1) as u32)
        }
    }
}

fn plot_on<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, plot: &Plot) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let (w, _) = root.dim_in_pixel();
    let (area, side) = root.split_horizontally(w.saturating_sub(LEGEND_WIDTH));
    let legend = match plot {
        Plot::Cost { arms, optimum } => cost_plot(&area, arms, *optimum)?,
        Plot::Panels(p) => panels_plot(&area, p)?,
        Plot::Path3d { series, marks } => path_plot(&area, series, marks)?,
    };
    draw_legend(&side, &legend)
}

/// How a legend entry is drawn.
#[derive(Clone, Copy)]
enum Swatch {
    Line(RGBColor, u32, bool),
    Faint,
    Area(RGBColor),
    Mark(MarkKind),
    Limit,
}

/// The legend, in the column beside the data (never over it); one entry per label.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, Swatch)],
) -> DrawResult<DB> {
    let font = ("sans-serif", 15).into_font().color(&BLACK);
    let mut seen: Vec<&str> = Vec::new();
    let mut y = 40;
    for (label, swatch) in entries {
        if label.is_empty() || seen.contains(&label.as_str()) {
            continue;
        }
        seen.push(label);
        let (x0, x1, yc) = (10, 40, y + 8);
        match *swatch {
            Swatch::Line(c, w, dashed) => {
                if dashed {
                    area.draw(&PathElement::new(
                        vec![(x0, yc), (x0 + 10, yc)],
                        c.stroke_width(w),
                    ))?;
                    area.draw(&PathElement::new(
                        vec![(x0 + 18, yc), (x1, yc)],
                        c.stroke_width(w),
                    ))?;
                } else {
                    area.draw(&PathElement::new(
                        vec![(x0, yc), (x1, yc)],
                        c.stroke_width(w),
                    ))?;
                }
            }
            Swatch::Faint => {
                area.draw(&PathElement::new(
                    vec![(x0, yc), (x1, yc)],
                    GREY.stroke_width(1),
                ))?;
            }
            Swatch::Area(c) => {
                area.draw(&Rectangle::new(
                    [(x0, yc - 6), (x1, yc + 6)],
                    c.mix(0.3).filled(),
                ))?;
            }
            Swatch::Limit => {
                area.draw(&Rectangle::new(
                    [(x0, yc - 6), (x1, yc + 6)],
                    LIMIT.mix(0.12).filled(),
                ))?;
                area.draw(&PathElement::new(
                    vec![(x0, yc - 6), (x1, yc - 6)],
                    LIMIT.stroke_width(1),
                ))?;
            }
            Swatch::Mark(kind) => draw_marker(area, ((x0 + x1) / 2, yc), kind)?,
        }
        // Long labels wrap at word boundaries to stay in the column.
        let mut row = String::new();
        for word in label.split(' ') {
            if !row.is_empty() && row.chars().count() + 1 + word.chars().count() > 24 {
                area.draw(&Text::new(row.clone(), (x1 + 8, y), font.clone()))?;
                y += 18;
                row.clear();
            }
            if !row.is_empty() {
                row.push(' ');
            }
            row.push_str(word);
        }
        area.draw(&Text::new(row, (x1 + 8, y), font.clone()))?;
        y += 26;
    }
    Ok(())
}

/// A mark's symbol at pixel `p`: start a green triangle, goal a red square, via points
/// black dots.
fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: (i32, i32),
    kind: MarkKind,
) -> DrawResult<DB> {
    match kind {
        MarkKind::Start => area.draw(&TriangleMarker::new(p, 9, START.filled())),
        MarkKind::Goal => area.draw(&Rectangle::new(
            [(p.0 - 6, p.1 - 6), (p.0 + 6, p.1 + 6)],
            GOAL.filled(),
        )),
        MarkKind::Via => area.draw(&Circle::new(p, 5, BLACK.filled())),
        MarkKind::Gap => area.draw(&Circle::new(p, 5, OBSTACLE.stroke_width(2))),
        MarkKind::Obstacle => area.draw(&Cross::new(p, 7, OBSTACLE.stroke_width(3))),
    }
}

/// A mark's symbol at `at` in a chart's coordinates (2-D or 3-D), via points labelled.
fn mark_at<DB: DrawingBackend, CT: CoordTranslate>(
    chart: &mut ChartContext<'_, DB, CT>,
    at: CT::From,
    m: &Mark,
) -> DrawResult<DB>
where
    CT::From: Clone + 'static,
{
    match m.kind {
        MarkKind::Start => {
            chart.draw_series(std::iter::once(TriangleMarker::new(at, 9, START.filled())))?;
        }
        MarkKind::Goal => {
            chart.draw_series(std::iter::once(
                EmptyElement::at(at) + Rectangle::new([(-6, -6), (6, 6)], GOAL.filled()),
            ))?;
        }
        MarkKind::Via => {
            chart.draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Circle::new((0, 0), 5, BLACK.filled())
                    + Text::new(m.label.clone(), (7, -20), ("sans-serif", 14)),
            ))?;
        }
        MarkKind::Gap => {
            chart.draw_series(std::iter::once(
                EmptyElement::at(at) + Circle::new((0, 0), 5, OBSTACLE.stroke_width(2)),
            ))?;
        }
        MarkKind::Obstacle => {
            chart.draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Cross::new((0, 0), 7, OBSTACLE.stroke_width(3))
                    + Text::new(m.label.clone(), (9, -20), ("sans-serif", 14)),
            ))?;
        }
    }
    Ok(())
}

/// The legend entries of marks (one per kind present).
fn mark_entries(marks: &[Mark]) -> Vec<(String, Swatch)> {
    let mut out = Vec::new();
    for (kind, label) in [
        (MarkKind::Start, "start"),
        (MarkKind::Via, "via points p1, p2, …"),
        (MarkKind::Goal, "goal"),
        (MarkKind::Obstacle, "obstacles o1, o2, …"),
        (MarkKind::Gap, "gaps filled (motion capture)"),
    ] {
        if marks.iter().any(|m| m.kind == kind) {
            out.push((label.to_string(), Swatch::Mark(kind)));
        }
    }
    out
}

/// The tick labels of an axis spanning `range`, read as numbers: as many decimals as the
/// axis needs, no `-0`, exponent form for very large or small magnitudes.
pub fn tick(range: f64) -> impl Fn(&f64) -> String {
    let step = (range.abs() / 8.0).max(1e-300);
    let decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    move |v: &f64| {
        let v = *v;
        let a = v.abs();
        if a < step * 1e-6 {
            return "0".into();
        }
        if !(1e-4..1e5).contains(&a) {
            let s = format!("{v:.1e}");
            return s.replace(".0e", "e");
        }
        let s = format!("{v:.decimals$}");
        if s.trim_start_matches('-')
            .chars()
            .all(|c| c == '0' || c == '.')
        {
            "0".into()
        } else {
            s
        }
    }
}

/// A tick label on a log₁₀ axis: `1e-3`, `0.01`, `1`, `100` at powers of ten, two
/// significant digits (`3.2e3`) between them.
pub fn log_tick(v: &f64) -> String {
    let x = 10f64.powf(*v);
    if (v - v.round()).abs() > 1e-6 {
        return format!("{x:.1e}");
    }
    if (1e-2..1e4).contains(&x) {
        let s = format!("{x:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{x:.0e}")
    }
}

/// The style of the i-th bold series: a colour, the first widest and solid, later ones
/// dashed and narrower, so that none hides another.
fn bold(i: usize) -> (RGBColor, u32, bool) {
    (COLORS[i % COLORS.len()], if i == 0 { 3 } else { 2 }, i > 0)
}

/// The runs of consecutive finite points of a curve (NaN breaks it).
fn finite_runs(points: impl Iterator<Item = (f64, f64)>) -> Vec<Vec<(f64, f64)>> {
    let mut runs = vec![Vec::new()];
    for (x, y) in points {
        if x.is_finite() && y.is_finite() {
            if let Some(r) = runs.last_mut() {
                r.push((x, y));
            }
        } else if runs.last().is_some_and(|r| !r.is_empty()) {
            runs.push(Vec::new());
        }
    }
    runs.retain(|r| !r.is_empty());
    runs
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
        // Drawn into memory, then encoded by the `png` crate (plotters' own encoder would
        // bring the whole `image` crate for one format).
        let (w, h) = size;
        let mut rgb = vec![255u8; w as usize * h as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
            plot_on(&root, &figure.plot)
                .and_then(|()| root.present())
                .map_err(|e| fail(e.to_string()))?;
        }
        encode_png(path, &rgb, size).map_err(fail)
    }
}

/// Writes an RGB image as a PNG file (8 bits a channel, default compression).
fn encode_png(path: &Path, rgb: &[u8], (w, h): (u32, u32)) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
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
) -> Result<Vec<(String, Swatch)>, DrawingAreaErrorKind<DB::ErrorType>> {
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
    let lo = lo
        .min(
            optimum
                .filter(|o| o.is_finite() && *o > 0.0)
                .unwrap_or(f64::INFINITY),
        )
        .max(1e-300);
    // No positive finite cost at all: an empty axis of two decades, never an endless one.
    let (lo, hi) = if !lo.is_finite() {
        (0.1, 10.0)
    } else if lo < hi {
        (lo * 0.8, hi * 1.25)
    } else {
        (lo * 0.5, lo * 2.0)
    };
    let gens = arms.iter().map(|a| a.band.len()).max().unwrap_or(0).max(2) as f64;
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
    let xfmt = tick(gens);
    let yfmt = |v: &f64| log_tick(&v.log10());
    chart
        .configure_mesh()
        .x_desc("generation")
        .y_desc("best cost so far")
        .x_label_formatter(&xfmt)
        .y_label_formatter(&yfmt)
        .draw()?;
    let mut legend = Vec::new();
    // Bands first, then every mean line over them.
    for (i, arm) in arms.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        if arm.repetitions > 1 {
            let band = &arm.band;
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
            chart.draw_series(std::iter::once(Polygon::new(poly, color.mix(0.3))))?;
            legend.push((format!("{}: 95 % band", arm.label), Swatch::Area(color)));
        }
    }
    for (i, arm) in arms.iter().enumerate() {
        let (color, width, dashed) = bold(i);
        let mean: Vec<(f64, f64)> = arm
            .band
            .iter()
            .enumerate()
            .filter_map(|(g, b)| positive(b.0).map(|v| ((g + 1) as f64, v)))
            .collect();
        line(&mut chart, mean, color.stroke_width(width), dashed)?;
        let label = if arm.repetitions > 1 {
            format!("{}: mean best cost", arm.label)
        } else {
            format!("{}: best cost", arm.label)
        };
        legend.push((label, Swatch::Line(color, width, dashed)));
    }
    if let Some(opt) = optimum {
        chart.draw_series(LineSeries::new(
            vec![(1.0, opt), (gens, opt)],
            BLACK.stroke_width(1),
        ))?;
        legend.push(("exact optimum".into(), Swatch::Line(BLACK, 1, false)));
    }
    Ok(legend)
}

/// Draws a curve, solid or dashed.
fn line<DB: DrawingBackend, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'_, DB, CT>,
    points: Vec<(f64, f64)>,
    style: ShapeStyle,
    dashed: bool,
) -> DrawResult<DB> {
    if dashed {
        chart.draw_series(DashedLineSeries::new(points, 10, 6, style))?;
    } else {
        chart.draw_series(LineSeries::new(points, style))?;
    }
    Ok(())
}

/// One panel per dimension: bands, limits, every series over the shared axis, and marks.
fn panels_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    p: &Panels,
) -> Result<Vec<(String, Swatch)>, DrawingAreaErrorKind<DB::ErrorType>> {
    let dims = p.names.len();
    let areas = root.split_evenly((dims.max(1), 1));
    let log = |v: f64| {
        if p.log_y {
            if v > 0.0 { v.log10() } else { f64::NAN }
        } else {
            v
        }
    };
    let xs = p
        .series
        .iter()
        .flat_map(|s| s.times.iter())
        .chain(p.bands.iter().flat_map(|b| b.times.iter()))
        .chain(p.marks.iter().map(|m| &m.time))
        .copied()
        .filter(|t| t.is_finite());
    let (t0, t1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
        (a.min(t), b.max(t))
    });
    let (t0, t1) = if t0 < t1 { (t0, t1) } else { (0.0, 1.0) };
    let xfmt = tick(t1 - t0);
    let mut legend = Vec::new();
    for (d, area) in areas.iter().enumerate() {
        let limit = p.limits.get(d).copied().flatten();
        let values = p
            .series
            .iter()
            .flat_map(|s| s.values[d].iter())
            .chain(
                p.bands
                    .iter()
                    .flat_map(|b| b.lower[d].iter().chain(&b.upper[d])),
            )
            .chain(p.marks.iter().filter_map(|m| m.values.get(d)))
            .copied()
            .chain(limit.into_iter().flat_map(|(a, b)| [a, b]))
            .map(log)
            .filter(|v| v.is_finite());
        let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 1.0) };
        let pad = ((hi - lo) * 0.1).max(if p.log_y { 0.1 } else { 1e-3 });
        let (lo, hi) = (lo - pad, hi + pad);
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, lo..hi)?;
        let yfmt = tick(hi - lo);
        let ylog = |v: &f64| log_tick(v);
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(p.x_name.as_str())
            .y_desc(p.names[d].as_str())
            .x_label_formatter(&xfmt)
            .light_line_style(WHITE.mix(0.0));
        if p.log_y {
            mesh.y_label_formatter(&ylog);
        } else {
            mesh.y_label_formatter(&yfmt);
        }
        mesh.draw()?;
        if let Some((a, b)) = limit {
            // Outside the limits shaded, the limits as lines.
            for (from, to) in [(lo, log(a)), (log(b), hi)] {
                if from < to {
                    chart.draw_series(std::iter::once(Rectangle::new(
                        [(t0, from), (t1, to)],
                        LIMIT.mix(0.12).filled(),
                    )))?;
                }
            }
            for v in [a, b] {
                chart.draw_series(DashedLineSeries::new(
                    vec![(t0, log(v)), (t1, log(v))],
                    8,
                    5,
                    LIMIT.stroke_width(1),
                ))?;
            }
            legend.push(("limits (outside shaded)".to_string(), Swatch::Limit));
        }
        for (i, b) in p.bands.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let mut poly: Vec<(f64, f64)> = b
                .times
                .iter()
                .zip(&b.upper[d])
                .map(|(&t, &v)| (t, log(v)))
                .collect();
            poly.extend(
                b.times
                    .iter()
                    .zip(&b.lower[d])
                    .rev()
                    .map(|(&t, &v)| (t, log(v))),
            );
            poly.retain(|q| q.1.is_finite());
            chart.draw_series(std::iter::once(Polygon::new(poly, color.mix(0.25))))?;
            legend.push((b.label.clone(), Swatch::Area(color)));
        }
        // Faint families first, bold ones over them in order.
        for s in p.series.iter().filter(|s| s.faint) {
            for run in finite_runs(s.times.iter().zip(&s.values[d]).map(|(&t, &v)| (t, log(v)))) {
                chart.draw_series(LineSeries::new(run, GREY.mix(0.6).stroke_width(1)))?;
            }
            legend.push((s.label.clone(), Swatch::Faint));
        }
        for (i, s) in p.series.iter().filter(|s| !s.faint).enumerate() {
            let (color, width, dashed) = bold(i);
            let runs = finite_runs(s.times.iter().zip(&s.values[d]).map(|(&t, &v)| (t, log(v))));
            if runs.is_empty() {
                continue;
            }
            for run in runs {
                line(&mut chart, run, color.stroke_width(width), dashed)?;
            }
            legend.push((s.label.clone(), Swatch::Line(color, width, dashed)));
        }
        for m in &p.marks {
            let Some(&v) = m.values.get(d) else { continue };
            mark_at(&mut chart, (m.time, log(v)), m)?;
        }
    }
    legend.extend(mark_entries(&p.marks));
    Ok(legend)
}

/// A 3-D path plot: every series (x, y, z over its samples), marks, axis names.
fn path_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &[Series],
    marks: &[Mark],
) -> Result<Vec<(String, Swatch)>, DrawingAreaErrorKind<DB::ErrorType>> {
    let range = |d: usize| {
        let (lo, hi) = series
            .iter()
            .flat_map(|s| s.values[d].iter())
            .chain(marks.iter().filter_map(|m| m.values.get(d)))
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 1.0) };
        let pad = ((hi - lo) * 0.05).max(1e-3);
        (lo - pad)..(hi + pad)
    };
    let (rx, ry, rz) = (range(0), range(1), range(2));
    // plotters' vertical axis is its y: pass (x, z, y) so the world's z points up.
    let mut chart = ChartBuilder::on(root)
        .caption("3-D path (world frame)", ("sans-serif", 22))
        .margin(20)
        .build_cartesian_3d(rx.clone(), rz.clone(), ry.clone())?;
    chart.with_projection(|mut p| {
        p.yaw = 0.6;
        p.pitch = 0.35;
        p.scale = 0.8;
        p.into_matrix()
    });
    let (fx, fy, fz) = (
        tick(rx.end - rx.start),
        tick(ry.end - ry.start),
        tick(rz.end - rz.start),
    );
    chart
        .configure_axes()
        .x_labels(5)
        .y_labels(5)
        .z_labels(5)
        .x_formatter(&fx)
        .y_formatter(&fz)
        .z_formatter(&fy)
        .draw()?;
    // Axis names at the middle of the edges that carry the tick labels.
    let font = ("sans-serif", 17).into_font().color(&BLACK);
    let mid = |r: &std::ops::Range<f64>| 0.5 * (r.start + r.end);
    for (text, at) in [
        (
            "x [m]",
            (mid(&rx), rz.start, ry.end + 0.15 * (ry.end - ry.start)),
        ),
        (
            "y [m]",
            (rx.end + 0.15 * (rx.end - rx.start), rz.start, mid(&ry)),
        ),
        (
            "z [m]",
            (rx.start, rz.end + 0.08 * (rz.end - rz.start), ry.end),
        ),
    ] {
        chart.draw_series(std::iter::once(Text::new(text, at, font.clone())))?;
    }
    let mut legend = Vec::new();
    for s in series.iter().filter(|s| s.faint) {
        let (x, y, z) = (&s.values[0], &s.values[1], &s.values[2]);
        chart.draw_series(LineSeries::new(
            (0..x.len()).map(|k| (x[k], z[k], y[k])),
            GREY.mix(0.6).stroke_width(1),
        ))?;
        legend.push((s.label.clone(), Swatch::Faint));
    }
    for (i, s) in series.iter().filter(|s| !s.faint).enumerate() {
        let (color, width, dashed) = bold(i);
        let (x, y, z) = (&s.values[0], &s.values[1], &s.values[2]);
        let points = (0..x.len()).map(|k| (x[k], z[k], y[k]));
        if dashed {
            chart.draw_series(DashedLineSeries::new(
                points,
                10,
                6,
                color.stroke_width(width),
            ))?;
        } else {
            chart.draw_series(LineSeries::new(points, color.stroke_width(width)))?;
        }
        legend.push((s.label.clone(), Swatch::Line(color, width, dashed)));
    }
    for m in marks.iter().filter(|m| m.values.len() >= 3) {
        let at = (m.values[0], m.values[2], m.values[1]);
        mark_at(&mut chart, at, m)?;
    }
    legend.extend(mark_entries(marks));
    Ok(legend)
}
