//! Probabilistic movement primitives (ProMPs; A. Paraschos, C. Daniel, J. Peters,
//! G. Neumann, "Probabilistic Movement Primitives", NeurIPS 2013, and "Using probabilistic
//! movement primitives in robotics", Autonomous Robots 42, 2018).
//!
//! A ProMP is a Gaussian over the weights `w` of a basis: the position of dimension `d` at
//! phase `z = t / T` is `y_d(z) = ψ(z)ᵀ w_d`, with `ψ` normalised Gaussian bumps evenly
//! spaced over `[0, 1]`, and `w ~ N(μ_w, Σ_w)` over all dimensions at once (so the
//! covariance between dimensions is kept). From it:
//!
//! - [`ProMp::fit`]: the distribution of N demonstrations, each time-normalised to the
//!   phase and fitted by ridge regression per dimension; `Σ_w` is their sample covariance
//!   plus a small ridge so that it stays invertible.
//! - [`ProMp::mean_at`], [`ProMp::covariance_at`]: the mean and covariance of position and
//!   velocity over time (`Φ μ_w`, `Φ Σ_w Φᵀ`).
//! - [`ProMp::condition`]: the distribution given one or several via points, each a
//!   position and optionally a velocity with its own covariance (zero: met exactly),
//!   by Gaussian conditioning of the weights.
//! - [`ProMp::sample`]: seeded weight samples and their trajectories.
//! - [`blend`]: co-activation of several ProMPs with activations over time (the product
//!   of their distributions, each to the power of its activation).
//! - [`ProMp::search_start`]: the mean and covariance as CMA-ES's `x0` and `C0`.
//! - `ProMpModel` (feature `serde`): the versioned JSON file format.
//!
//! # Example
//! ```
//! use cps_promp::{ProMp, Observation};
//! // Ten straight demonstrations from 0 to 1 with different slopes at the end.
//! let demos: Vec<(Vec<f64>, Vec<Vec<f64>>)> = (0..10)
//!     .map(|i| {
//!         let t: Vec<f64> = (0..101).map(|k| k as f64 / 100.0).collect();
//!         let y = t.iter().map(|&s| vec![s + 0.05 * i as f64 * s * s]).collect();
//!         (t, y)
//!     })
//!     .collect();
//! let promp = ProMp::fit(&demos, 10, 1.0)?;
//! // Pass through 0.6 at t = 0.5, exactly.
//! let via = promp.condition(&[Observation::position(0.5, vec![0.6], 0.0)])?;
//! assert!((via.mean_at(0.5).0[0] - 0.6).abs() < 1e-9);
//! assert!(via.covariance_at(0.5).0[(0, 0)] < 1e-9);
//! # Ok::<(), cps_promp::ProMpError>(())
//! ```
#![deny(missing_docs)]

#[cfg(feature = "serde")]
pub mod model;
mod promp;

#[cfg(feature = "serde")]
pub use model::{PROMP_FORMAT, PROMP_VERSION, ProMpModel};
pub use promp::{Activation, Blended, Observation, ProMp, ProMpError, SearchStart, blend};
