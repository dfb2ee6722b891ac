//! Writes a synthetic take with a known motion as C3D: the example takes and the
//! benchmark's files.
//!
//! `cargo run --release -p cps-mocap --example synthetic_take -- OUT.c3d [--markers N]
//! [--rate HZ] [--seconds S] [--noise-mm MM] [--gaps] [--integer SCALE]`

use cps_mocap::c3d::{self, Format};
use cps_mocap::synthetic::{Spec, take};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(out) = args.first() else {
        eprintln!(
            "usage: synthetic_take OUT.c3d [--markers N] [--rate HZ] [--seconds S] [--noise-mm MM] [--gaps] [--integer SCALE]"
        );
        std::process::exit(2);
    };
    let value = |name: &str, default: f64| -> f64 {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .map_or(default, |v| {
                v.parse().unwrap_or_else(|_| {
                    eprintln!("{name}: {v} is not a number");
                    std::process::exit(2)
                })
            })
    };
    let mut spec = Spec::tool(value("--markers", 4.0) as usize);
    spec.rate = value("--rate", 240.0);
    spec.frames = (value("--seconds", 10.0) * spec.rate) as usize;
    spec.noise_m = value("--noise-mm", 0.0) / 1e3;
    if args.iter().any(|a| a == "--gaps") {
        let f = spec.frames;
        spec.gaps = vec![(1, f / 5, 6), (2, f / 2, 9), (0, 3 * f / 4, 4)];
    }
    let format = if args.iter().any(|a| a == "--integer") {
        Format::Integer {
            scale: value("--integer", 0.1) as f32,
        }
    } else {
        Format::Float
    };
    let (t, _) = take(&spec);
    let bytes = c3d::write(&t, format).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    if let Err(e) = std::fs::write(out, bytes) {
        eprintln!("{out}: {e}");
        std::process::exit(1);
    }
    println!(
        "{out}: {} markers × {} frames at {} Hz",
        spec.markers.len(),
        spec.frames,
        spec.rate
    );
}
