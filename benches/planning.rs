//! The planner's benchmark: problems arms meet — a table with objects to pick among,
//! shelves (small, tall, thin), an open box, a cage — each made from a seed, the FR3 with
//! its hand (franka_description's hulls) at the guard's 5 mm margin, start and goal
//! configurations near the obstacles. Prints, per kind, how many were solved, the planning
//! time's median and 95th percentile, the path length, the clearance and the median of the
//! whole call (the search, the timing and the guard's check at 1 kHz), then all kinds.
//!
//! Run it: `bash benches/planning.sh` (`cargo bench -p cps-bench --bench planning`;
//! `-- --per-kind N` for another count, 20 by default; `--reach R` and `--shortcuts N`
//! for other settings). One thread.

use std::time::Instant;

use cps::geometry::{Obstacle, Shape};
use cps::plan::{PlanError, Settings, plan};
use cps::robot::{RobotModel, SplitMix};
use nalgebra::Isometry3;

/// A box of `size` (m) centred at `at`, in the robot's base frame.
fn board(name: &str, at: [f64; 3], size: [f64; 3]) -> Obstacle {
    Obstacle {
        name: name.to_string(),
        pose: Isometry3::translation(at[0], at[1], at[2]),
        shape: Shape::cuboid(size, name).expect("a positive box"),
    }
}

/// The table the arm stands on (its top at z = 0).
fn table() -> Obstacle {
    board("table", [0.3, 0.0, -0.05], [1.6, 1.6, 0.1])
}

/// A shelf `depth` deep facing the arm at `x`, `width` wide, its boards `thick` thick at
/// the `heights`, its two sides and a back.
fn shelf(x: f64, y: f64, width: f64, depth: f64, heights: &[f64], thick: f64) -> Vec<Obstacle> {
    let top = heights.iter().copied().fold(0.0, f64::max);
    let mut out = vec![
        board(
            "left",
            [x + depth / 2.0, y - width / 2.0, top / 2.0],
            [depth, thick, top],
        ),
        board(
            "right",
            [x + depth / 2.0, y + width / 2.0, top / 2.0],
            [depth, thick, top],
        ),
        board("back", [x + depth, y, top / 2.0], [thick, width, top]),
    ];
    for (k, h) in heights.iter().enumerate() {
        out.push(board(
            &format!("board{k}"),
            [x + depth / 2.0, y, *h],
            [depth, width, thick],
        ));
    }
    out
}

/// One problem kind's scene from `rng`.
fn scene(kind: &str, rng: &mut SplitMix) -> Vec<Obstacle> {
    let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.unit();
    let mut out = vec![table()];
    match kind {
        "table_pick" => {
            for k in 0..4 {
                let s = [u(0.04, 0.12), u(0.04, 0.12), u(0.05, 0.2)];
                out.push(board(
                    &format!("object{k}"),
                    [u(0.35, 0.7), u(-0.45, 0.45), s[2] / 2.0],
                    s,
                ));
            }
        }
        "shelf_small" => {
            let (x, y) = (u(0.5, 0.65), u(-0.2, 0.2));
            out.extend(shelf(x, y, 0.5, 0.3, &[0.25, 0.5], 0.02));
        }
        "shelf_tall" => {
            let (x, y) = (u(0.5, 0.65), u(-0.2, 0.2));
            out.extend(shelf(x, y, 0.6, 0.3, &[0.3, 0.6, 0.9, 1.2], 0.02));
        }
        "shelf_thin" => {
            let (x, y) = (u(0.45, 0.6), u(-0.2, 0.2));
            out.extend(shelf(x, y, 0.4, 0.25, &[0.2, 0.4, 0.6], 0.01));
        }
        "box" => {
            let (x, y, w, h) = (u(0.45, 0.6), u(-0.3, 0.3), u(0.25, 0.35), u(0.15, 0.25));
            for (name, at, size) in [
                ("front", [x - w / 2.0, y, h / 2.0], [0.01, w, h]),
                ("rear", [x + w / 2.0, y, h / 2.0], [0.01, w, h]),
                ("side_a", [x, y - w / 2.0, h / 2.0], [w, 0.01, h]),
                ("side_b", [x, y + w / 2.0, h / 2.0], [w, 0.01, h]),
            ] {
                out.push(board(name, at, size));
            }
        }
        "cage" => {
            // Posts around the arm and two bars above, a gap in front.
            for k in 0..6 {
                let a = std::f64::consts::PI * (0.35 + 1.3 * k as f64 / 5.0) + u(-0.05, 0.05);
                let r = u(0.55, 0.65);
                out.push(board(
                    &format!("post{k}"),
                    [r * a.cos(), r * a.sin(), 0.5],
                    [0.04, 0.04, 1.0],
                ));
            }
            out.push(board("bar_x", [0.0, 0.0, u(1.05, 1.15)], [1.2, 0.04, 0.04]));
            out.push(board("bar_y", [0.0, 0.0, u(1.05, 1.15)], [0.04, 1.2, 0.04]));
        }
        other => unreachable!("no kind {other}"),
    }
    out
}

/// A configuration within the ranges, free at the margin, whose hand is within 15 cm of
/// an obstacle other than the table.
fn near(robot: &RobotModel, rng: &mut SplitMix) -> Vec<f64> {
    let shapes = robot.shapes.as_ref().expect("the FR3 has shapes");
    let model = shapes.model();
    let (lower, upper) = robot.chain.limits().expect("the FR3 has ranges");
    let mut frames = Vec::new();
    loop {
        let q: Vec<f64> = (0..7)
            .map(|j| lower[j] + (upper[j] - lower[j]) * rng.unit())
            .collect();
        robot.chain.frames_into(&q, &mut frames).expect("7 joints");
        if !model.within(&frames, shapes.margin()).is_empty() {
            continue;
        }
        let close = model.within(&frames, 0.15).iter().any(|c| {
            let (a, b) = model.pair_names(c.pair);
            a.ends_with("hand") && b != "table"
        });
        if close {
            return q;
        }
    }
}

fn quantile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let per_kind = args
        .iter()
        .position(|a| a == "--per-kind")
        .and_then(|i| args.get(i + 1))
        .and_then(|n| n.parse().ok())
        .unwrap_or(20);
    let number = |flag: &str| -> Option<f64> {
        let i = args.iter().position(|a| a == flag)?;
        args.get(i + 1)?.parse().ok()
    };
    let settings = Settings {
        reach: number("--reach").unwrap_or(Settings::default().reach),
        shortcuts: number("--shortcuts").map_or(Settings::default().shortcuts, |n| n as usize),
        ..Settings::default()
    };
    let fr3 =
        cps::movement::robot_file::load_robot("fr3", Some("hand"), None).expect("the built-in FR3");
    let kinds = [
        "table_pick",
        "shelf_small",
        "shelf_tall",
        "shelf_thin",
        "box",
        "cage",
    ];
    println!(
        "{:<12} {:>8} {:>10} {:>10} {:>10} {:>11} {:>12} {:>10}",
        "kind", "solved", "median ms", "p95 ms", "max ms", "length rad", "clearance mm", "whole ms"
    );
    let mut all = Vec::new();
    let mut all_wholes = Vec::new();
    let (mut solved_all, mut total) = (0, 0);
    for (k, kind) in kinds.iter().enumerate() {
        let mut rng = SplitMix(1000 + k as u64);
        let (mut times, mut lengths, mut clear) = (Vec::new(), Vec::new(), f64::INFINITY);
        let mut wholes = Vec::new();
        let mut solved = 0;
        for _ in 0..per_kind {
            let robot = fr3
                .in_scene(
                    scene(kind, &mut rng),
                    vec![("fr3_link0".into(), "table".into())],
                    None,
                )
                .expect("a scene");
            let (from, to) = (near(&robot, &mut rng), near(&robot, &mut rng));
            let started = Instant::now();
            let result = plan(&robot, &from, &to, &settings);
            let seconds = started.elapsed().as_secs_f64();
            total += 1;
            match result {
                Ok(p) => {
                    solved += 1;
                    times.push(1e3 * p.planning_seconds);
                    wholes.push(1e3 * seconds);
                    lengths.push(p.length);
                    clear = clear.min(p.clearance.unwrap_or(f64::INFINITY));
                }
                Err(PlanError::NoPath { .. }) => times.push(1e3 * seconds),
                Err(e) => panic!("{kind}: {e}"),
            }
        }
        solved_all += solved;
        times.sort_by(f64::total_cmp);
        all.extend_from_slice(&times);
        all_wholes.extend_from_slice(&wholes);
        let mean = lengths.iter().sum::<f64>() / lengths.len().max(1) as f64;
        wholes.sort_by(f64::total_cmp);
        println!(
            "{kind:<12} {:>8} {:>10.2} {:>10.2} {:>10.2} {:>11.3} {:>12.1} {:>10.2}",
            format!("{solved}/{per_kind}"),
            quantile(&times, 0.5),
            quantile(&times, 0.95),
            times.last().copied().unwrap_or(f64::NAN),
            mean,
            1e3 * clear,
            quantile(&wholes, 0.5)
        );
    }
    all.sort_by(f64::total_cmp);
    all_wholes.sort_by(f64::total_cmp);
    println!(
        "{:<12} {:>8} {:>10.2} {:>10.2} {:>10.2} {:>11} {:>12} {:>10.2}",
        "all",
        format!("{solved_all}/{total}"),
        quantile(&all, 0.5),
        quantile(&all, 0.95),
        all.last().copied().unwrap_or(f64::NAN),
        "",
        "",
        quantile(&all_wholes, 0.5)
    );
}
