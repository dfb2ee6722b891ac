//! Learning pipelines for cps.
//!
//! Via-point learning (Rueckert & d'Avella 2013, "Learned parametrized dynamic movement
//! primitives with shared synergies for controlling robotic and musculoskeletal systems";
//! thesis §4.5.2): CMA-ES searches the weights of task-space DMPs so that the rolled-out
//! movement passes via points at given times, ends at the goal at rest, and stays smooth.
//!
//! - [`ViaPointTask`]: start, goal, via points, DMP settings and the weighted cost terms
//!   ([`CostWeights`]); each term optional.
//! - [`Parametrisation`] / [`SearchSpace`]: how CMA-ES's parameters map to DMP weights.
//! - [`exact_optimum`]: the cost is an exact quadratic in the weights (the rollout is
//!   affine), so its least-squares optimum is computed directly and every run reports its
//!   gap to it; it also serves as a solver and a warm start.
//! - [`learn_via_points`]: repetitions with derived seeds, in parallel, deterministic.
//!
//! # Example
//! ```
//! use cps_learn::{learn_via_points, ViaPointConfig, ViaPointTask};
//! # fn main() -> Result<(), cps_learn::LearnError> {
//! let mut config = ViaPointConfig::new(ViaPointTask::thesis());
//! config.generations = 50; // a short run for the example
//! let outcome = learn_via_points(&config, &|_, _| std::ops::ControlFlow::Continue(()))?;
//! let run = outcome.best();
//! assert!(run.cost >= outcome.optimum.cost * (1.0 - 1e-12));
//! println!("gap to the exact optimum: {:.2e}", run.gap_to_optimum);
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

mod clearance;
mod energy;
mod error;
mod exact;
mod executed;
mod executions;
mod imitation;
mod joint;
mod joint_executed;
mod keep_clear;
mod lsq;
pub mod pool;
mod pose;
mod robot;
mod search;
mod space;
mod task;
mod viapoint;

pub use clearance::{
    CLEARANCE_STRIDE, Clearance, ClearanceBuffers, Closest, closest, closest_to_world,
};
pub use energy::{
    EffortConfig, EffortCostBreakdown, EffortOutcome, PlantTrajectory, PointMassPlant, effort_cost,
    learn_with_effort,
};
pub use error::LearnError;
pub use exact::{ExactOptimum, QuadraticCost, exact_optimum};
pub use executed::{ExecutedCost, ExecutedErrors, ExecutedWeights, executed_cost};
pub use executions::{Ended, Judge, Judged, Kept, learn_on_executions, pool_failure};
pub use imitation::{
    DemonstrationResult, GivenDemonstration, ImitationConfig, ImitationFit, ImitationOutcome,
    ImitationStage, run_imitation,
};
pub use joint::{
    ExecutedJoints, JointCostBreakdown, JointSpaceConfig, JointSpaceCost, JointSpaceOutcome,
    LIMIT_MARGIN, LimitReport, execute_joint_trajectory, learn_joint_space,
};
pub use joint_executed::{ExecutedJointOutcome, ExecutedSearch, OpenRobot, learn_joint_executed};
pub use keep_clear::{
    ClearanceStage, KeepClear, KeptClear, execute_on_model, keep_clear, keep_likely_clear,
    task_anchor,
};
pub use pose::{
    OrientationCostBreakdown, OrientationErrors, OrientationResult, PoseConfig, PoseOutcome,
    keep_pose_clear, learn_pose, pose_targets,
};
pub use robot::{
    CLEAR_TRIES, RobotSetup, check_way_points, clear_way_points, execute_trajectory,
    execute_trajectory_from, targets_at,
};
pub use space::{Parametrisation, SearchSpace};
pub use task::{
    CostBreakdown, CostWeights, MAX_COORDINATE, MAX_WEIGHT, PointObstacle, TaskErrors, ViaPoint,
    ViaPointTask,
};
pub use viapoint::{
    BadSetting, Evaluation, GenerationRecord, RunResult, SearchStats, SettingConflict, Solver,
    UnknownName, ViaPointConfig, ViaPointObjective, ViaPointOutcome, history_band,
    learn_via_points, run_cmaes,
};
