//! Dynamic Movement Primitives (DMPs) for cps.
//!
//! A DMP turns a weight vector into a smooth trajectory from a start `y0` to a goal `g`
//! (Ijspeert et al. 2013, "Dynamical Movement Primitives: Learning Attractor Models for
//! Motor Behaviors"). This crate holds the discrete core:
//!
//! - [`DmpConfig`]: gains (`alpha_z`, `beta_z`, `alpha_x`), number of basis functions,
//!   duration `tau` in seconds and time step `dt`, validated once.
//! - [`CanonicalSystem`]: the phase `x(t) = exp(-alpha_x t / tau)`, stepped exactly.
//! - [`GaussianBasis`]: the basis functions `psi_i(x)` spread evenly in time.
//! - [`DiscreteDmp`]: one DMP per dimension sharing phase, basis and `tau`, with everything
//!   that does not depend on the weights precomputed, so that [`DiscreteDmp::rollout_into`]
//!   is one small matrix product plus a cheap linear recurrence.
//! - [`Trajectory`]: position, **physical** velocity (m/s) and acceleration (m/s²) on the
//!   time grid, one contiguous slice per dimension.
//!
//! The rollout is linear (affine) in the weights, which is what lets `cps-learn` compute
//! the exact optimum of quadratic costs.
//!
//! # Example
//! ```
//! use cps_dmp::{DiscreteDmp, DmpConfig};
//! # fn main() -> Result<(), cps_dmp::DmpError> {
//! let config = DmpConfig::new(25, 10.0, 0.01); // 25 bases, tau = 10 s, dt = 10 ms
//! let dmp = DiscreteDmp::new(config, &[0.75, 0.02, 1.87], &[0.55, -0.57, 1.45])?;
//! let weights = vec![0.0; dmp.n_weights()]; // 3 dims x 25 bases
//! let traj = dmp.rollout(&weights);
//! let end = traj.n_samples() - 1;
//! assert!((traj.position(2)[end] - 1.45).abs() < 1e-2); // zero weights: to the goal
//! assert_eq!(traj.times()[end], 10.0);
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

mod basis;
mod canonical;
mod config;
mod discretize;
mod dmp;
mod error;
mod imitation;
mod jet;
#[cfg(feature = "serde")]
mod model;
mod online;
mod quaternion;
mod rhythmic;
mod trajectory;

pub use basis::GaussianBasis;
pub use canonical::CanonicalSystem;
pub use config::{DmpConfig, Formulation};
pub use dmp::{BATCH_LANES, DiscreteDmp, Lanes, StreamVisitor};
pub use error::DmpError;
pub use imitation::{
    Combine, Demonstration, FitReport, Imitation, Imitator, Lambda, Regression, imitate,
};
#[cfg(feature = "serde")]
pub use model::{BasisRecord, ConfigRecord, DmpModel, MODEL_FORMAT, MODEL_VERSION};
pub use online::{OnlineDmp, StepInput};
pub use quaternion::{OrientationTrajectory, QuaternionDmp};
pub use rhythmic::{RhythmicDmp, RhythmicRollout};
pub use trajectory::{Trajectory, locate_on_grid};
