//! Standard test functions (all with minimum 0), for tests, benchmarks and
//! `cps-cli cmaes bench`.

/// `Σ x_i²`.
pub fn sphere(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum()
}

/// `Σ 10^(6 (i−1)/(n−1)) x_i²` (condition 1e6).
pub fn ellipsoid(x: &[f64]) -> f64 {
    let n = x.len();
    if n == 1 {
        return x[0] * x[0];
    }
    x.iter()
        .enumerate()
        .map(|(i, v)| 10f64.powf(6.0 * i as f64 / (n - 1) as f64) * v * v)
        .sum()
}

/// `x_1² + 10⁶ Σ_{i≥2} x_i²`.
pub fn cigar(x: &[f64]) -> f64 {
    x[0] * x[0] + 1e6 * x[1..].iter().map(|v| v * v).sum::<f64>()
}

/// `10⁶ x_1² + Σ_{i≥2} x_i²`.
pub fn discus(x: &[f64]) -> f64 {
    1e6 * x[0] * x[0] + x[1..].iter().map(|v| v * v).sum::<f64>()
}

/// `Σ_{i<n} 100 (x_{i+1} − x_i²)² + (1 − x_i)²`.
pub fn rosenbrock(x: &[f64]) -> f64 {
    x.windows(2)
        .map(|w| 100.0 * (w[1] - w[0] * w[0]).powi(2) + (1.0 - w[0]).powi(2))
        .sum()
}

/// `10 n + Σ (x_i² − 10 cos 2π x_i)`.
pub fn rastrigin(x: &[f64]) -> f64 {
    10.0 * x.len() as f64
        + x.iter()
            .map(|v| v * v - 10.0 * (2.0 * std::f64::consts::PI * v).cos())
            .sum::<f64>()
}
