//! Search spaces: how a CMA-ES parameter vector θ maps to DMP weights w.
//!
//! Every parametrisation here is a fixed diagonal scaling `w = s ∘ θ` built from the DMP
//! alone (its phase, gains and `g − y0`), never from the cost, so it carries over to any
//! cost, quadratic or not. The map is linear, so the rollout stays affine in θ.

use cps_dmp::DiscreteDmp;
use serde::{Deserialize, Serialize};

/// How the optimiser's parameters θ relate to the DMP weights w.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Parametrisation {
    /// θ = w: the raw weights. Badly scaled: late basis functions act through the decayed
    /// phase `x ≈ exp(−alpha_x) ≈ 2.4e-4` and need weights 10⁴ times larger.
    Raw,
    /// The thesis's eq. 55: `w = θ ∘ c_scale` with `c_scale` log-spaced from 1 to
    /// `0.8 alpha_x` over the basis functions of each dimension.
    ThesisScaling,
    /// θ in task units (metres): `w_i = θ_i · alpha_z beta_z / (c_i (g − y0))`. Then
    /// `f / (alpha_z beta_z) ≈ Σ_i θ_i ψ_i / Σ ψ` near the phase of basis i: θ_i is how far
    /// basis i moves the spring's anchor point, in the same units as the way points. All
    /// parameters have the same units and comparable effect, whatever their basis or
    /// dimension. Default.
    #[default]
    AnchorOffset,
}

/// The per-weight scale `s` (w = s ∘ θ) of a parametrisation for a DMP.
#[derive(Debug, Clone, PartialEq)]
pub struct SearchSpace {
    kind: Parametrisation,
    scale: Vec<f64>,
}

impl SearchSpace {
    /// The scaling of `kind` for `dmp`.
    pub fn new(kind: Parametrisation, dmp: &DiscreteDmp) -> Self {
        let n = dmp.n_basis();
        let cfg = dmp.config();
        let mut scale = Vec::with_capacity(dmp.n_weights());
        for d in 0..dmp.dims() {
            for i in 0..n {
                scale.push(match kind {
                    Parametrisation::Raw => 1.0,
                    Parametrisation::ThesisScaling => {
                        let top = 0.8 * cfg.alpha_x;
                        if n == 1 {
                            1.0
                        } else {
                            top.powf(i as f64 / (n - 1) as f64)
                        }
                    }
                    Parametrisation::AnchorOffset => {
                        cfg.alpha_z * cfg.beta_z
                            / (dmp.basis().centers()[i] * dmp.forcing_scale(d).0)
                    }
                });
            }
        }
        Self { kind, scale }
    }

    /// Which parametrisation this is.
    pub fn kind(&self) -> Parametrisation {
        self.kind
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.scale.len()
    }

    /// True if there are no parameters.
    pub fn is_empty(&self) -> bool {
        self.scale.is_empty()
    }

    /// The scale vector `s`.
    pub fn scale(&self) -> &[f64] {
        &self.scale
    }

    /// Weights from parameters: `w = s ∘ θ`.
    pub fn to_weights(&self, theta: &[f64], w: &mut [f64]) {
        for ((w, t), s) in w.iter_mut().zip(theta).zip(&self.scale) {
            *w = t * s;
        }
    }

    /// Weights from parameters, as a new vector.
    pub fn weights(&self, theta: &[f64]) -> Vec<f64> {
        let mut w = vec![0.0; theta.len()];
        self.to_weights(theta, &mut w);
        w
    }

    /// Parameters from weights: `θ = w / s`.
    pub fn to_params(&self, w: &[f64]) -> Vec<f64> {
        w.iter().zip(&self.scale).map(|(w, s)| w / s).collect()
    }
}
