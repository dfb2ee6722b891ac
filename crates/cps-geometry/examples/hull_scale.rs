//! Times the convex hull of `n` points on a sphere (every point a vertex: quickhull's
//! worst case for the rounds): `cargo run --release -p cps-geometry --example hull_scale 100000`.
fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(100_000);
    let mut s = 88172645463325252u64;
    let mut r = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let pts: Vec<nalgebra::Vector3<f64>> = (0..n)
        .map(|_| nalgebra::Vector3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize() * 0.1)
        .collect();
    let t = std::time::Instant::now();
    let h = cps_geometry::Hull::new(&pts, "sphere").expect("a sphere's points span a solid");
    println!(
        "{n} points: {} vertices, {:.3} s",
        h.vertices().len(),
        t.elapsed().as_secs_f64()
    );
}
