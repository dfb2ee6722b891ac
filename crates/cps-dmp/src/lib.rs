//! Dynamic Movement Primitives (DMPs) for cps.
//!
//! A DMP turns a weight vector into a smooth trajectory from a start `y0` to a goal `g`
//! (Ijspeert et al. 2013, "Dynamical Movement Primitives: Learning Attractor Models for
//! Motor Behaviors"). τ is always a duration in seconds; velocities and accelerations are
//! physical (SI).
//!
//! - [`DmpConfig`]: gains (`alpha_z`, `beta_z`, `alpha_x`), number of basis functions,
//!   duration `tau`, time step `dt` and the [`Formulation`] (Ijspeert 2013, or the
//!   goal-robust Hoffmann/Pastor 2009 form), validated once.
//! - [`DiscreteDmp`]: one DMP per dimension sharing phase ([`CanonicalSystem`]), basis
//!   ([`GaussianBasis`]) and `tau`, with everything that does not depend on the weights
//!   precomputed, so that [`DiscreteDmp::rollout_into`] is one small matrix product plus a
//!   cheap exact linear recurrence advanced eight samples at a time;
//!   [`DiscreteDmp::rollout_batch`] rolls out a population. [`Trajectory`] holds the
//!   samples.
//! - [`OnlineDmp`]: the same model stepped one control period at a time, with live goal
//!   and τ changes, phase stopping and coupling terms.
//! - [`imitate`] / [`Imitator`]: weights from demonstrations ([`Demonstration`]) by LWR,
//!   ridge or jerk-regularised ridge, λ fixed or by cross-validation, with a [`FitReport`].
//! - [`DiscreteDmp::retarget`] ([`Retarget`]): a learned movement carried to a new start
//!   and goal rotated and scaled as a whole (no mirrored dimension, no blown-up one), and
//!   [`PoseDmp`]: position and orientation on one phase, carried together.
//! - [`sequence`]: several DMPs chained into one movement, C² at every junction.
//! - [`Coupling`] terms for point obstacles ([`SteeringAngle`], Hoffmann et al. 2009;
//!   [`DynamicPotential`], Park et al. 2008) and [`DiscreteDmp::rollout_coupled`].
//! - [`RhythmicDmp`] (periodic movements) and [`QuaternionDmp`] (tool orientations).
//! - `DmpModel` (feature `serde`): learned DMPs as versioned JSON.
//!
//! The rollout is affine in the weights, which is what lets `cps-learn` compute the exact
//! optimum of quadratic costs.
//!
//! # Example
//! ```
//! use cps_dmp::{imitate, Combine, Demonstration, DiscreteDmp, DmpConfig, Regression};
//! # fn main() -> Result<(), cps_dmp::DmpError> {
//! let config = DmpConfig::new(25, 10.0, 0.01); // 25 bases, tau = 10 s, dt = 10 ms
//! let dmp = DiscreteDmp::new(config, &[0.75, 0.02, 1.87], &[0.55, -0.57, 1.45])?;
//! let traj = dmp.rollout(&vec![0.0; dmp.n_weights()]); // 3 dims x 25 bases
//! let end = traj.n_samples() - 1;
//! assert!((traj.position(2)[end] - 1.45).abs() < 1e-2); // zero weights: to the goal
//!
//! // Learn the weights back from that movement, sampled at its own time stamps.
//! let rows: Vec<Vec<f64>> = (0..traj.n_samples())
//!     .map(|k| (0..3).map(|d| traj.position(d)[k]).collect())
//!     .collect();
//! let demo = Demonstration::new(traj.times().to_vec(), &rows)?;
//! let fit = imitate(&config, &[demo], Regression::default(), Combine::Mean)?;
//! assert!(fit.report.rmse.iter().all(|&e| e < 1e-5));
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

mod basis;
mod canonical;
mod config;
mod coupling;
mod discretize;
mod dmp;
mod error;
mod generalize;
mod imitation;
mod jet;
#[cfg(feature = "serde")]
mod model;
mod names;
mod online;
mod pose;
mod quaternion;
mod rhythmic;
mod sequence;
mod trajectory;

pub use basis::GaussianBasis;
pub use canonical::CanonicalSystem;
pub use config::{
    DmpConfig, Formulation, MAX_BASIS, MAX_COORDINATE, MAX_FEATURES, MAX_GAIN, MAX_PHASE_DECAY,
    MAX_STEPS, MAX_TAU,
};
pub use coupling::{Coupling, Couplings, DynamicPotential, SteeringAngle, check_endpoints};
pub use dmp::DiscreteDmp;
pub use error::DmpError;
pub use generalize::{Retarget, Retargeted, SHAPE_SCALING_WARNED, rotation_between};
pub use imitation::{
    Combine, Demonstration, FitReport, Imitation, Imitator, Lambda, Method, Regression, imitate,
};
#[cfg(feature = "serde")]
pub use model::{BasisRecord, ConfigRecord, DmpModel, MODEL_FORMAT, MODEL_VERSION};
pub use online::{OnlineDmp, StepInput};
pub use pose::{PoseDmp, RetargetedPose};
pub use quaternion::{OrientationTrajectory, QuaternionDmp};
pub use rhythmic::{RhythmicDmp, RhythmicRollout};
pub use sequence::{Junction, Sequenced, sequence, sequence_with};
pub use trajectory::{Trajectory, locate_on_grid};
