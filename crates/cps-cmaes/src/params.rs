//! Strategy parameters: Hansen (2016), "The CMA Evolution Strategy: A Tutorial",
//! arXiv:1604.00772, Table 1, with active (negative) recombination weights.

/// The default strategy parameters for dimension `n` and population `lambda`.
///
/// This is the tutorial's version exactly: `c_mu` has no `+1/4` in its numerator and
/// `c_sigma`'s denominator is `n + mu_eff + 5` (pycma differs in both; evaluations agree
/// within a few per cent on unimodal functions).
#[derive(Debug, Clone, PartialEq)]
pub struct Parameters {
    /// Dimension `n`.
    pub n: usize,
    /// Population size `λ`.
    pub lambda: usize,
    /// Number of positive weights `μ = ⌊λ/2⌋`.
    pub mu: usize,
    /// Recombination weights `w_1 ≥ … ≥ w_λ`: the first `μ` positive and summing to 1,
    /// the rest non-positive, summing to `-min(α_μ⁻, α_μeff⁻, α_posdef⁻)`.
    pub weights: Vec<f64>,
    /// Variance-effective selection mass of the positive weights, `μ_eff`.
    pub mu_eff: f64,
    /// The same for the negative weights, `μ_eff⁻`.
    pub mu_eff_neg: f64,
    /// Learning rate of the mean, `c_m = 1`.
    pub c_m: f64,
    /// Cumulation constant of the step-size path, `c_σ = (μ_eff + 2)/(n + μ_eff + 5)`.
    pub c_sigma: f64,
    /// Step-size damping `d_σ = 1 + 2 max(0, √((μ_eff − 1)/(n + 1)) − 1) + c_σ`.
    pub d_sigma: f64,
    /// Cumulation constant of the rank-one path, `c_c = (4 + μ_eff/n)/(n + 4 + 2μ_eff/n)`.
    pub c_c: f64,
    /// Rank-one learning rate `c_1 = 2/((n + 1.3)² + μ_eff)`.
    pub c1: f64,
    /// Rank-μ learning rate `c_μ = min(1 − c_1, 2(μ_eff − 2 + 1/μ_eff)/((n + 2)² + μ_eff))`.
    pub c_mu: f64,
    /// `E‖N(0, I)‖ ≈ √n (1 − 1/(4n) + 1/(21 n²))`.
    pub chi_n: f64,
}

impl Parameters {
    /// The default population size `4 + ⌊3 ln n⌋`.
    pub fn default_lambda(n: usize) -> usize {
        4 + (3.0 * (n as f64).ln()).floor() as usize
    }

    /// All parameters for dimension `n ≥ 1` and population `lambda ≥ 2`.
    ///
    /// # Panics
    /// If `n == 0` or `lambda < 2` (validated configurations never have those).
    pub fn new(n: usize, lambda: usize) -> Self {
        Self::with_rate_factor(n, lambda, 1.0)
    }

    /// The parameters of the separable variant (sep-CMA-ES, Ros & Hansen 2008): the
    /// covariance is diagonal, so it can be learned `(n + 2)/3` times faster —
    /// `c_1 (n + 2)/3` and `min(1 − c_1', c_μ (n + 2)/3)` — and the negative weights'
    /// positive-definiteness bound follows these rates.
    ///
    /// # Panics
    /// As [`Self::new`].
    pub fn separable(n: usize, lambda: usize) -> Self {
        Self::with_rate_factor(n, lambda, (n as f64 + 2.0) / 3.0)
    }

    fn with_rate_factor(n: usize, lambda: usize, factor: f64) -> Self {
        assert!(n >= 1 && lambda >= 2, "n >= 1 and lambda >= 2");
        let nf = n as f64;
        let mu = lambda / 2;
        let raw: Vec<f64> = (1..=lambda)
            .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
            .collect();
        let (sum_pos, sum_pos2) = raw
            .iter()
            .filter(|w| **w > 0.0)
            .fold((0.0, 0.0), |(s, s2), w| (s + w, s2 + w * w));
        let (sum_neg, sum_neg2) = raw
            .iter()
            .filter(|w| **w < 0.0)
            .fold((0.0, 0.0), |(s, s2), w| (s + w, s2 + w * w));
        let mu_eff = sum_pos * sum_pos / sum_pos2;
        let mu_eff_neg = if sum_neg2 > 0.0 {
            sum_neg * sum_neg / sum_neg2
        } else {
            0.0
        };
        let c_sigma = (mu_eff + 2.0) / (nf + mu_eff + 5.0);
        let d_sigma = 1.0 + 2.0 * (((mu_eff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
        let c_c = (4.0 + mu_eff / nf) / (nf + 4.0 + 2.0 * mu_eff / nf);
        let c1 = factor * 2.0 / ((nf + 1.3) * (nf + 1.3) + mu_eff);
        let c_mu = (1.0 - c1)
            .min(factor * 2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((nf + 2.0) * (nf + 2.0) + mu_eff));
        let alpha_mu_neg = 1.0 + c1 / c_mu;
        let alpha_mueff_neg = 1.0 + 2.0 * mu_eff_neg / (mu_eff + 2.0);
        let alpha_posdef_neg = (1.0 - c1 - c_mu) / (nf * c_mu);
        let neg_total = alpha_mu_neg.min(alpha_mueff_neg).min(alpha_posdef_neg);
        let weights = raw
            .iter()
            .map(|&w| {
                if w >= 0.0 {
                    w / sum_pos
                } else {
                    neg_total * w / -sum_neg
                }
            })
            .collect();
        let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
        Self {
            n,
            lambda,
            mu,
            weights,
            mu_eff,
            mu_eff_neg,
            c_m: 1.0,
            c_sigma,
            d_sigma,
            c_c,
            c1,
            c_mu,
            chi_n,
        }
    }

    /// `min(α_μ⁻, α_μeff⁻, α_posdef⁻)`, the total magnitude of the negative weights.
    pub fn negative_weight_total(&self) -> f64 {
        -self.weights.iter().filter(|w| **w < 0.0).sum::<f64>()
    }

    /// The default number of generations between eigendecompositions:
    /// `max(1, ⌊1 / (2 n (c_1 + c_μ))⌋)` (pycma's lazy-update gap).
    pub fn default_eigen_gap(&self) -> u64 {
        ((1.0 / (2.0 * self.n as f64 * (self.c1 + self.c_mu))).floor() as u64).max(1)
    }
}
