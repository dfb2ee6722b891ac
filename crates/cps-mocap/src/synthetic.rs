//! Synthetic takes with a known rigid-body motion, for tests, benchmarks and examples: a
//! tool carrying markers moves along a smooth loop while turning, sampled at a frame rate
//! in millimetres, optionally with Gaussian noise (seeded) and gaps.

use crate::fit::{Rigid, Vec3, rotation_of};
use crate::take::{Source, Take};

/// The motion and what the cameras saw of it.
#[derive(Debug, Clone, PartialEq)]
pub struct Spec {
    /// Frames per second.
    pub rate: f64,
    /// Number of frames.
    pub frames: usize,
    /// The markers on the tool, in the tool's frame (metres); the tool's origin is their
    /// centroid when they are centred.
    pub markers: Vec<Vec3>,
    /// Their labels.
    pub labels: Vec<String>,
    /// Standard deviation of the noise added to each coordinate, metres.
    pub noise_m: f64,
    /// The seed of the noise.
    pub seed: u64,
    /// Gaps: `(marker, first frame, frames)`.
    pub gaps: Vec<(usize, usize, usize)>,
}

impl Spec {
    /// A tool with `n` markers (3 ≤ n) spread over 180 mm × 160 mm × 100 mm (as a
    /// hand-held tool's), 10 s at 240 Hz,
    /// noise-free.
    pub fn tool(n: usize) -> Self {
        let all = [
            [0.12, 0.0, 0.0],
            [-0.06, 0.08, 0.0],
            [-0.06, -0.08, 0.02],
            [0.0, 0.02, 0.1],
            [0.04, -0.06, -0.04],
            [-0.1, 0.0, 0.06],
        ];
        let markers: Vec<Vec3> = (0..n)
            .map(|i| all[i % all.len()].map(|v| v * (1.0 + (i / all.len()) as f64 * 0.5)))
            .collect();
        Self {
            rate: 240.0,
            frames: 2400,
            labels: (1..=n).map(|i| format!("tool{i}")).collect(),
            markers,
            noise_m: 0.0,
            seed: 1,
            gaps: Vec::new(),
        }
    }
}

/// The tool's pose at time `t` (seconds): a loop of 0.3 m by 0.2 m by 0.1 m around
/// (0.5, 1.0, 0.3) m, turning up to ≈ 1 rad about a slowly moving axis.
pub fn pose(t: f64) -> Rigid {
    let w = 2.0 * std::f64::consts::PI / 10.0;
    let translation = [
        0.5 + 0.3 * (w * t).sin(),
        1.0 + 0.2 * (2.0 * w * t).sin(),
        0.3 + 0.1 * (w * t).cos(),
    ];
    let angle = 1.0 * (w * t).sin();
    let axis = [0.3 + 0.2 * (w * t).cos(), 1.0, 0.5 * (w * t).sin()];
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let (s, c) = (angle / 2.0).sin_cos();
    Rigid {
        rotation: rotation_of([axis[0] / n * s, axis[1] / n * s, axis[2] / n * s, c]),
        translation,
    }
}

/// A deterministic normal sampler (splitmix64 and Box–Muller): the same seed, the same
/// numbers on every machine.
pub struct Normal(pub u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    /// A standard normal sample.
    pub fn sample(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The take (millimetres, C3D-like) and the true pose at each frame.
pub fn take(spec: &Spec) -> (Take, Vec<Rigid>) {
    let m = spec.markers.len();
    let mut rng = Normal(spec.seed);
    let mut xyz = Vec::with_capacity(spec.frames * m);
    let mut residual = Vec::with_capacity(spec.frames * m);
    let mut truth = Vec::with_capacity(spec.frames);
    for f in 0..spec.frames {
        let pose = pose(f as f64 / spec.rate);
        for (j, b) in spec.markers.iter().enumerate() {
            let gap = spec
                .gaps
                .iter()
                .any(|&(g, start, n)| g == j && (start..start + n).contains(&f));
            let p = pose.apply(*b);
            let noisy: [f32; 3] =
                std::array::from_fn(|k| ((p[k] + spec.noise_m * rng.sample()) * 1000.0) as f32);
            if gap {
                xyz.push([f32::NAN; 3]);
                residual.push(-1.0);
            } else {
                xyz.push(noisy);
                residual.push(0.5);
            }
        }
        truth.push(pose);
    }
    (
        millimetre_take(spec.labels.clone(), spec.rate, xyz, residual),
        truth,
    )
}

/// A take of markers in millimetres (frame-major `xyz`, `residual` negative where
/// missing), as a C3D file from an Intel machine would hold it.
pub fn millimetre_take(
    labels: Vec<String>,
    rate: f64,
    xyz: Vec<[f32; 3]>,
    residual: Vec<f32>,
) -> Take {
    Take {
        file: "synthetic".into(),
        source: Source::C3d {
            float: true,
            processor: crate::take::Processor::Intel,
        },
        frames: xyz.len() / labels.len().max(1),
        labels,
        rate,
        first_frame: 1,
        units: "mm".into(),
        metres_per_unit: 0.001,
        xyz,
        residual,
        analog: None,
        rigid_bodies: Vec::new(),
        notes: Vec::new(),
    }
}
