//! Gaussian basis functions in phase space (Ijspeert et al. 2013, eq. 43/44 of the thesis).

/// Below this argument `exp` rounds to exactly 0.0 (the smallest subnormal is
/// `exp(−744.44)`; half of it, `exp(−745.13)`, already rounds to 0).
const UNDERFLOW: f64 = -746.0;

/// `psi_i(x) = exp(-h_i (x - c_i)^2)` with centres `c_i = exp(-alpha_x (i-1)/(N-1))`
/// (evenly spaced in time) and widths `h_i = (c_{i+1} - c_i)^-2`, `h_N = h_{N-1}`.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianBasis {
    centers: Vec<f64>,
    widths: Vec<f64>,
}

impl GaussianBasis {
    /// `n ≥ 1` basis functions for a canonical system with decay `alpha_x`.
    ///
    /// With a single basis function the centre is 1 and the width is chosen so the
    /// function falls to `exp(-1)` at the end of the movement.
    ///
    /// # Panics
    /// If `n == 0` (a validated [`crate::DmpConfig`] never has that).
    pub fn new(n: usize, alpha_x: f64) -> Self {
        assert!(n > 0, "a basis needs at least one function");
        if n == 1 {
            let span = 1.0 - (-alpha_x).exp();
            return Self {
                centers: vec![1.0],
                widths: vec![1.0 / (span * span)],
            };
        }
        let centers: Vec<f64> = (0..n)
            .map(|i| (-alpha_x * i as f64 / (n - 1) as f64).exp())
            .collect();
        let mut widths: Vec<f64> = centers
            .windows(2)
            .map(|c| 1.0 / ((c[1] - c[0]) * (c[1] - c[0])))
            .collect();
        widths.push(widths[n - 2]);
        Self { centers, widths }
    }

    /// Number of basis functions.
    pub fn len(&self) -> usize {
        self.centers.len()
    }

    /// Always false: a basis has at least one function.
    pub fn is_empty(&self) -> bool {
        self.centers.is_empty()
    }

    /// The centres `c_i` (phase values, from 1 down to `exp(-alpha_x)`).
    pub fn centers(&self) -> &[f64] {
        &self.centers
    }

    /// The widths `h_i`.
    pub fn widths(&self) -> &[f64] {
        &self.widths
    }

    /// Writes the forcing-term features at phase `x` into `out`:
    /// `out[i] = psi_i(x) * x / sum_j psi_j(x)`. The forcing term of one dimension is
    /// `f(x) = (g - y0) * sum_i out[i] * w_i`.
    ///
    /// # Panics
    /// If `out.len()` differs from [`Self::len`].
    pub fn features(&self, x: f64, out: &mut [f64]) {
        assert_eq!(out.len(), self.len(), "feature buffer length");
        let mut sum = 0.0;
        for ((o, &c), &h) in out.iter_mut().zip(&self.centers).zip(&self.widths) {
            let d = x - c;
            let a = -h * d * d;
            // exp(a) is exactly 0 below ln(2⁻¹⁰⁷⁵) ≈ −745.13; libm reaches that 0 through its
            // slow underflow path, which most of a grid's far tails would take.
            *o = if a < UNDERFLOW { 0.0 } else { a.exp() };
            sum += *o;
        }
        // The nearest centre is at most half a spacing away inside the movement, so the sum
        // is bounded away from zero; guard anyway for phases far outside.
        let scale = if sum > f64::MIN_POSITIVE {
            x / sum
        } else {
            0.0
        };
        for o in out.iter_mut() {
            *o *= scale;
            // Subnormal features (Gaussians far from their centre, below 2.2e-308) are
            // flushed to zero: they change no result representable next to the others,
            // but every SIMD operation touching one costs a microcode assist of ~100
            // cycles on x86 (measured: half the time of a rollout).
            if *o < f64::MIN_POSITIVE {
                *o = 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centres_are_evenly_spaced_in_time() {
        let b = GaussianBasis::new(25, 25.0 / 3.0);
        assert_eq!(b.centers()[0], 1.0);
        assert!((b.centers()[24] - (-25.0f64 / 3.0).exp()).abs() < 1e-16);
        for i in 0..24 {
            let ratio = b.centers()[i + 1] / b.centers()[i];
            assert!((ratio - (-25.0f64 / 3.0 / 24.0).exp()).abs() < 1e-14);
            let gap = b.centers()[i + 1] - b.centers()[i];
            assert!((b.widths()[i] * gap * gap - 1.0).abs() < 1e-12);
        }
        assert_eq!(b.widths()[24], b.widths()[23]);
    }

    #[test]
    fn features_are_never_subnormal() {
        let b = GaussianBasis::new(25, 25.0 / 3.0);
        let mut f = vec![0.0; 25];
        let mut zeros = 0;
        for k in 0..=1000 {
            b.features((-25.0f64 / 3.0 * k as f64 / 1000.0).exp(), &mut f);
            assert!(f.iter().all(|v| *v == 0.0 || v.is_normal()));
            zeros += f.iter().filter(|v| **v == 0.0).count();
        }
        // The far tails underflow: many zeros, which the packed rollout skips.
        assert!(zeros > 5000, "{zeros}");
    }

    #[test]
    fn the_underflow_shortcut_is_what_exp_gives() {
        for a in [-746.0, -746.5, -800.0, -1e4, -1e300, f64::NEG_INFINITY] {
            assert_eq!(f64::exp(a), 0.0, "{a}");
        }
        assert!(f64::exp(-744.4) > 0.0);
    }

    #[test]
    fn features_sum_to_the_phase() {
        let b = GaussianBasis::new(10, 4.0);
        let mut f = vec![0.0; 10];
        for &x in &[1.0, 0.5, 0.1, 0.02] {
            b.features(x, &mut f);
            let s: f64 = f.iter().sum();
            assert!((s - x).abs() < 1e-15 * 10.0, "x = {x}: {s}");
        }
    }
}
