//! cps: motor-control learning for robot arms.
//!
//! This facade re-exports the workspace's crates so one dependency gives you all of them:
//!
//! - [`dmp`] (`cps-dmp`): Dynamic Movement Primitives and their rollouts.
//! - [`cmaes`] (`cps-cmaes`): CMA-ES with deterministic parallel evaluation.
//! - [`learn`] (`cps-learn`): the learning pipelines (via-point learning).
//! - [`kinematics`] (`cps-kinematics`): robot maths (being built).
//! - [`coppelia`] (`cps-coppelia`): the CoppeliaSim transport (being built).
//!
//! See ARCHITECTURE.md for how they fit, and `cps-cli` for the command line.
//!
//! # Example
//! ```
//! use cps::dmp::{DiscreteDmp, DmpConfig};
//! # fn main() -> Result<(), cps::dmp::DmpError> {
//! let dmp = DiscreteDmp::new(DmpConfig::new(10, 1.0, 0.01), &[0.0], &[1.0])?;
//! let traj = dmp.rollout(&vec![0.0; 10]);
//! assert_eq!(traj.n_samples(), 101);
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

pub use cps_cmaes as cmaes;
pub use cps_coppelia as coppelia;
pub use cps_dmp as dmp;
pub use cps_kinematics as kinematics;
pub use cps_learn as learn;
