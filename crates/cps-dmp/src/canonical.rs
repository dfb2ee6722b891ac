//! The discrete canonical system `tau * dx/dt = -alpha_x * x`, `x(0) = 1`.

/// The phase of a discrete DMP.
///
/// `x(t) = exp(-alpha_x * t / tau)`; it starts at 1 and reaches `exp(-alpha_x)` at
/// `t = tau`. Phase stopping (error coupling) slows the phase by a factor
/// `c = 1 / (1 + e)` where `e ≥ 0` is a tracking error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CanonicalSystem {
    /// Decay rate `alpha_x`.
    pub alpha_x: f64,
    /// Duration `tau` in seconds.
    pub tau: f64,
}

impl CanonicalSystem {
    /// The phase at time `t` seconds (no coupling).
    pub fn phase(&self, t: f64) -> f64 {
        (-self.alpha_x * t / self.tau).exp()
    }

    /// One exact step of length `dt` seconds from phase `x` with coupling factor
    /// `coupling` in `(0, 1]` (1 = no phase stopping): `x * exp(-alpha_x * coupling * dt / tau)`.
    pub fn step(&self, x: f64, dt: f64, coupling: f64) -> f64 {
        x * (-self.alpha_x * coupling * dt / self.tau).exp()
    }

    /// The coupling factor `1 / (1 + error)` for a non-negative tracking error.
    pub fn coupling_factor(error: f64) -> f64 {
        1.0 / (1.0 + error.max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_steps_match_the_closed_form() {
        let cs = CanonicalSystem {
            alpha_x: 25.0 / 3.0,
            tau: 10.0,
        };
        let mut x = 1.0;
        for _ in 0..1000 {
            x = cs.step(x, 0.01, 1.0);
        }
        assert!((x - (-25.0f64 / 3.0).exp()).abs() < 1e-15);
        assert!((cs.phase(10.0) - x).abs() < 1e-15);
    }

    #[test]
    fn coupling_slows_the_phase() {
        let cs = CanonicalSystem {
            alpha_x: 8.0,
            tau: 1.0,
        };
        let free = cs.step(1.0, 0.1, 1.0);
        let held = cs.step(1.0, 0.1, CanonicalSystem::coupling_factor(1.0));
        assert!(held > free);
        assert!((held - (-0.4f64).exp()).abs() < 1e-15);
    }
}
