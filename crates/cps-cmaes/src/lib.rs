//! A CMA-ES for cps, built on faer.
//!
//! The (μ/μ_W, λ)-CMA-ES of Hansen (2016), "The CMA Evolution Strategy: A Tutorial"
//! (arXiv:1604.00772), with active (negative) covariance weights and the tutorial's
//! default parameters ([`Parameters`]). It knows nothing of robots: it minimises a cost
//! over a parameter vector through the [`Objective`] trait.
//!
//! - [`Cmaes`]: the state with [`Cmaes::ask`] / [`Cmaes::tell`]; sampling by the Cholesky
//!   factor of C (Krause et al. 2016; no eigendecomposition in the loop), bit-symmetric
//!   covariance, repair on numerical failure, NaN costs ranked last, box bounds,
//!   checkpoints, and a separable (diagonal) variant for large n.
//! - [`minimize`]: the driver: budget and [`StopRule`]s (a documented enum), an
//!   [`Observer`] after each generation, parallel evaluation with rayon.
//! - [`minimize_ipop`] / [`minimize_bipop`]: IPOP and BIPOP restarts for multimodal costs.
//! - [`functions`]: the standard test functions.
//!
//! Determinism: candidates are drawn from a ChaCha8 stream keyed by (seed, generation)
//! before anything is evaluated, and costs are ranked with a total order (ties by
//! index), so a seed gives the same bits at any thread count.
//!
//! # Example
//! ```
//! use cps_cmaes::{minimize, functions, CmaesConfig, FnObjective, NoObserver, StopRule};
//! # fn main() -> Result<(), cps_cmaes::CmaesError> {
//! let config = CmaesConfig::new(2.0, 42); // sigma0 = 2, seed 42
//! let rules = [StopRule::TargetCost(1e-10), StopRule::MaxGenerations(2000)];
//! let sol = minimize(&FnObjective(functions::sphere), &[3.0; 10], &config, &rules, &mut NoObserver)?;
//! assert!(sol.best_cost <= 1e-10);
//! assert_eq!(sol.termination.name(), "target_cost");
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

mod bounds;
mod cmaes;
mod config;
mod driver;
mod error;
pub mod functions;
mod params;
mod stop;

pub use bounds::Bounds;
pub use cmaes::{CHECKPOINT_FORMAT, CHECKPOINT_VERSION, Checkpoint, Cmaes};
pub use config::{CmaesConfig, MAX_DIMENSION, MAX_POPULATION};
pub use driver::{
    CandidateError, FnObjective, GenerationReport, NoObserver, Objective, Observer,
    RestartSolution, Solution, evaluate_through_batch, minimize, minimize_bipop, minimize_ipop,
    resume,
};
pub use error::{CmaesError, EndSearch, ObjectiveError};
pub use params::Parameters;
pub use stop::{StopRule, Termination};
