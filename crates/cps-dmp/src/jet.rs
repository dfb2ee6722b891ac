//! Truncated Taylor series ("jets") of order 3, for exact derivatives without symbolic
//! maths: a jet holds `f(t), f'(t), f''(t)/2, f'''(t)/6`, and arithmetic on jets follows
//! the Cauchy product, so evaluating a formula on the jet of `t` yields its derivatives
//! exactly (to rounding).

/// Taylor coefficients `[f, f', f''/2!, f'''/3!]` at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Jet(pub [f64; 4]);

impl Jet {
    /// The independent variable at `t`.
    pub fn variable(t: f64) -> Jet {
        Jet([t, 1.0, 0.0, 0.0])
    }

    /// A constant.
    pub fn constant(c: f64) -> Jet {
        Jet([c, 0.0, 0.0, 0.0])
    }

    /// The n-th derivative (n ≤ 3).
    pub fn derivative(&self, n: usize) -> f64 {
        const FACT: [f64; 4] = [1.0, 1.0, 2.0, 6.0];
        self.0[n] * FACT[n]
    }

    pub fn add(self, o: Jet) -> Jet {
        Jet(std::array::from_fn(|i| self.0[i] + o.0[i]))
    }

    pub fn scale(self, s: f64) -> Jet {
        Jet(self.0.map(|v| v * s))
    }

    pub fn offset(self, c: f64) -> Jet {
        let mut j = self;
        j.0[0] += c;
        j
    }

    pub fn mul(self, o: Jet) -> Jet {
        let (a, b) = (self.0, o.0);
        Jet(std::array::from_fn(|n| {
            (0..=n).map(|j| a[j] * b[n - j]).sum()
        }))
    }

    /// `self / o`; `o`'s value must not be 0.
    pub fn div(self, o: Jet) -> Jet {
        let (a, b) = (self.0, o.0);
        let mut q = [0.0; 4];
        for n in 0..4 {
            let s: f64 = (1..=n).map(|j| b[j] * q[n - j]).sum();
            q[n] = (a[n] - s) / b[0];
        }
        Jet(q)
    }

    pub fn exp(self) -> Jet {
        let a = self.0;
        let mut e = [a[0].exp(), 0.0, 0.0, 0.0];
        for n in 1..4 {
            e[n] = (1..=n).map(|j| j as f64 * a[j] * e[n - j]).sum::<f64>() / n as f64;
        }
        Jet(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_of_a_known_function() {
        // f(t) = exp(−2t) t² / (1 + t): compare with central differences of high order.
        let f = |t: Jet| t.scale(-2.0).exp().mul(t.mul(t)).div(t.offset(1.0));
        let g = |t: f64| (-2.0 * t).exp() * t * t / (1.0 + t);
        let t0 = 0.7;
        let j = f(Jet::variable(t0));
        assert!((j.derivative(0) - g(t0)).abs() < 1e-15);
        let h = 1e-3;
        let d1 =
            (g(t0 - 2.0 * h) - 8.0 * g(t0 - h) + 8.0 * g(t0 + h) - g(t0 + 2.0 * h)) / (12.0 * h);
        let d3 = (-g(t0 - 2.0 * h) + 2.0 * g(t0 - h) - 2.0 * g(t0 + h) + g(t0 + 2.0 * h))
            / (2.0 * h * h * h);
        assert!(
            (j.derivative(1) - d1).abs() < 1e-9,
            "{} vs {d1}",
            j.derivative(1)
        );
        assert!(
            (j.derivative(3) - d3).abs() < 1e-4,
            "{} vs {d3}",
            j.derivative(3)
        );
        assert_eq!(Jet::constant(3.0).derivative(2), 0.0);
    }
}
