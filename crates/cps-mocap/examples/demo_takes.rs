//! Writes the example takes of `experiments/mocap_imitation.toml`: three demonstrations of
//! the thesis's way-point path (`experiments/demos/table3_min_jerk.csv`) as a person would
//! give them with a tool carrying four markers — each a little faster or slower and a
//! centimetre off the others, the tool turning a little — recorded at 120 Hz in a Y-up lab
//! in millimetres, with 0.3 mm of noise, an occlusion and a ghost sample; and the lab's
//! calibration (`lab.toml`: four points measured in both frames, 0.3 mm off).
//!
//! `cargo run -p cps-mocap --example demo_takes -- experiments/demos`

use std::fmt::Write;
use std::path::Path;

use cps_mocap::c3d::{self, Format};
use cps_mocap::fit::{Rigid, rotation_of};
use cps_mocap::synthetic::{Normal, millimetre_take};

/// World (z up, metres) → lab (y up, metres).
fn world_to_lab() -> Rigid {
    Rigid {
        rotation: [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],
        translation: [-0.3, 0.05, 0.4],
    }
}

fn main() {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "experiments/demos".into());
    let dir = Path::new(&dir);
    let text = std::fs::read_to_string(dir.join("table3_min_jerk.csv")).expect("the thesis path");
    let path: Vec<[f64; 4]> = text
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l
                .split(',')
                .map(|c| c.trim().parse().expect("a number"))
                .collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    let end = path.last().expect("samples")[0];
    let at = |t: f64| -> [f64; 3] {
        let i = path.partition_point(|p| p[0] <= t).clamp(1, path.len() - 1);
        let (a, b) = (path[i - 1], path[i]);
        let s = ((t - a[0]) / (b[0] - a[0])).clamp(0.0, 1.0);
        [0, 1, 2].map(|k| a[k + 1] + s * (b[k + 1] - a[k + 1]))
    };
    let body = [
        [0.0, 0.0, 0.0],
        [0.14, 0.0, 0.04],
        [0.03, 0.12, 0.06],
        [-0.05, 0.02, 0.15],
    ];
    let labels: Vec<String> = ["tip", "m2", "m3", "m4"]
        .iter()
        .map(|l| format!("Tool:{l}"))
        .collect();
    let lab = world_to_lab();
    let rate = 120.0;
    std::fs::create_dir_all(dir.join("takes")).expect("the takes directory");
    for k in 0..3 {
        let speed = [0.95, 1.0, 1.05][k];
        let duration = end / speed;
        let frames = (duration * rate) as usize + 1;
        let off = [
            [0.0, 0.01, 0.0],
            [0.008, -0.006, 0.004],
            [-0.006, 0.0, -0.008],
        ][k];
        let mut noise = Normal(100 + k as u64);
        let mut xyz = Vec::new();
        let mut residual = Vec::new();
        for f in 0..frames {
            let t = f as f64 / rate;
            let s = (t / duration).min(1.0);
            let bump = (std::f64::consts::PI * s).sin();
            let p = at(s * end);
            let tip = [0, 1, 2].map(|i| p[i] + off[i] * bump);
            let angle = 0.25 * bump;
            let axis = [0.3, 0.2 * k as f64, 1.0];
            let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
            let (sn, c) = (angle / 2.0).sin_cos();
            let tool = Rigid {
                rotation: rotation_of([axis[0] / n * sn, axis[1] / n * sn, axis[2] / n * sn, c]),
                translation: tip,
            };
            for (j, b) in body.iter().enumerate() {
                let w = lab.apply(tool.apply(*b));
                let mut mm = w.map(|v| (v * 1000.0 + 0.3 * noise.sample()) as f32);
                let hidden =
                    (k == 1 && j == 2 && (300..308).contains(&f)) || (k == 0 && j == 3 && f < 5);
                if k == 2 && j == 1 && f == 500 {
                    mm[1] += 40.0; // a ghost: a reflection taken for the marker
                }
                if hidden {
                    xyz.push([f32::NAN; 3]);
                    residual.push(-1.0);
                } else {
                    xyz.push(mm);
                    residual.push(0.4);
                }
            }
        }
        let take = millimetre_take(labels.clone(), rate, xyz, residual);
        let out = dir.join("takes").join(format!("pour_{}.c3d", k + 1));
        std::fs::write(&out, c3d::write(&take, Format::Float).expect("a take")).expect("written");
        println!("{}: {frames} frames at {rate} Hz", out.display());
    }
    // The calibration: four points touched with the robot (world frame) and measured by
    // the cameras (lab, mm, 0.3 mm off).
    let mut noise = Normal(7);
    let mut toml = String::from(
        "# The lab's registration: four points measured by the cameras (lab frame, Y up, mm)\n# and touched with the robot's tool (the experiment's world frame, metres).\nmocap_units = \"mm\"\nmax_residual = 0.002\n",
    );
    for (name, w) in [
        ("table, front left", [0.5, -0.5, 0.8]),
        ("table, front right", [1.2, -0.5, 0.8]),
        ("table, back left", [0.5, 0.6, 0.8]),
        ("post top", [0.9, 0.0, 1.6]),
    ] {
        let l = lab.apply(w).map(|v| v * 1000.0 + 0.3 * noise.sample());
        let _ = write!(
            toml,
            "\n[[points]]\nname = \"{name}\"\nmocap = [{:.2}, {:.2}, {:.2}]\nrobot = [{}, {}, {}]\n",
            l[0], l[1], l[2], w[0], w[1], w[2]
        );
    }
    std::fs::write(dir.join("takes").join("lab.toml"), toml).expect("written");
    println!("{}", dir.join("takes").join("lab.toml").display());
}
