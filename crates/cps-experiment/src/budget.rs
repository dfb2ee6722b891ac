//! What an experiment file asks of the machine, estimated before any work and refused
//! beyond a ceiling (`--max-memory`, `--max-work` raise it).
//!
//! The estimate is a sum of the big allocations and the multiply-adds of the dominant
//! loops, from the file's numbers alone:
//!
//! - samples `S = round(τ/dt) + 1`, dimensions `D` (the robot's joints for joint-space
//!   learning), basis functions `B`, parameters `n = D·B`, population `λ` (the file's, or
//!   CMA-ES's default `4 + ⌊3 ln n⌋`), generations `G`, repetitions `R`, and the kind's
//!   multiplier `M` (parametrisations compared, demonstrations learned, the orientation
//!   search of a pose run, the speed-up measurement's generations);
//! - **memory**: the basis features (`3·S·B` doubles: plain and packed), the population's
//!   rollouts (`2·λ·D·3S`), the exact optimum's Jacobian (`3S·D × n`), CMA-ES's matrices
//!   (`6 n²`), the cost history (`6·G·R·M`), the robot's recordings;
//! - **work**: evaluations `λ·G·R·M` × a rollout (`S·D·B`, plus the plant's substeps, FK per
//!   sample), plus the exact optimum (`n` rollouts and a QR of `3S·D × n`).
//!
//! The figures are upper bounds of the order of magnitude, not predictions: a run that
//! converges stops long before its generation budget.

use std::ops::Range;

use crate::InputError;
pub use crate::plan::Estimate;
use crate::plan::{Experiment, Kind};
use cps_outcome::source::bytes;

/// The ceilings a run may not exceed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ceilings {
    /// Bytes of memory (default 4 GiB).
    pub memory_bytes: f64,
    /// Multiply-adds (default 1e13: tens of minutes on one core).
    pub work: f64,
}

impl Default for Ceilings {
    fn default() -> Self {
        Self {
            memory_bytes: 4.0 * GIB,
            work: 1e13,
        }
    }
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

impl Ceilings {
    /// Ceilings of `memory_gib` GiB (0.001 to 1e6) and `work` multiply-adds (1 to 1e20),
    /// as `--max-memory` and `--max-work` give them.
    pub fn new(memory_gib: f64, work: f64) -> Result<Self, InputError> {
        if !(memory_gib.is_finite() && (0.001..=1e6).contains(&memory_gib)) {
            return Err(InputError(format!(
                "--max-memory {memory_gib}: give GiB between 0.001 and 1e6"
            )));
        }
        if !(work.is_finite() && (1.0..=1e20).contains(&work)) {
            return Err(InputError(format!(
                "--max-work {work}: give a count between 1 and 1e20"
            )));
        }
        Ok(Self {
            memory_bytes: memory_gib * GIB,
            work,
        })
    }
}

/// Operations of one control period of the robot with dynamics (the controller, the drives,
/// forward dynamics, a step): 1.34 µs measured on the reference machine (BENCHMARKS.md ›
/// Dynamics) at [`OPERATIONS_PER_SECOND`].
pub const OPERATIONS_PER_CONTROL_PERIOD: f64 = 6700.0;

/// Operations per second of one thread assumed for time estimates: the via-point rollout
/// measured 6.8e9 on the 2-vCPU reference machine (BENCHMARKS.md); rounded down.
pub const OPERATIONS_PER_SECOND: f64 = 5e9;

impl Estimate {
    /// One line for `check`: memory, operations and the time they take on `threads`.
    pub fn describe(&self, threads: usize) -> String {
        let seconds = self.work / (OPERATIONS_PER_SECOND * threads.max(1) as f64);
        format!(
            "needs at most ≈ {} of memory and ≈ {:.1e} operations: ≈ {} on {threads} thread(s) for the whole budget ({} samples per rollout)",
            bytes(self.memory_bytes),
            self.work,
            duration(seconds.max(0.01)),
            self.samples,
        )
    }
}

/// A duration in words: `0.4 s`, `12 s`, `3.5 min`, `2.1 h`.
fn duration(s: f64) -> String {
    if s < 10.0 {
        format!("{s:.1} s")
    } else if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.1} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}

/// The factors of the estimate with the place of the key that sets each, so a refusal can
/// name the one furthest from an ordinary experiment.
pub struct Factors {
    /// `(key as written, its value, how many times an ordinary value it is, its place)`.
    pub keys: Vec<(&'static str, String, f64, Range<usize>)>,
}

/// Estimates what `exp` needs.
pub fn estimate(exp: &Experiment) -> Estimate {
    let c = &exp.config;
    let dmp = &c.task.dmp;
    let samples = (dmp.tau / dmp.dt).round() + 1.0;
    let dims = match (exp.kind(), &exp.robot) {
        (Kind::ViapointJoint, Some(r)) => r.setup.chain.dof(),
        _ => c.task.start.len(),
    };
    let basis = dmp.n_basis as f64;
    let n = dims * dmp.n_basis;
    let population = c
        .population
        .unwrap_or_else(|| cps_cmaes::Parameters::default_lambda(n.max(1)));
    let (g, r) = (c.generations as f64, c.repetitions as f64);
    let d = dims as f64;
    let mut multiplier = 1.0;
    let mut per_sample_extra = 0.0;
    let mut recordings = 0.0;
    match exp.kind() {
        Kind::Scaling => {
            multiplier = exp.scaling().map_or(1, |s| s.compare.len()) as f64;
        }
        Kind::Imitation | Kind::Promp => {
            if let Some(p) = exp.imitation() {
                multiplier = p.demonstrations as f64;
                let robot_samples = exp.robot.as_ref().map_or(samples, |rb| match rb.backend {
                    crate::robots::BackendChoice::Kinematic { dt } => dmp.tau / dt + 1.0,
                    crate::robots::BackendChoice::Dynamics(ref o) => dmp.tau / o.dt + 1.0,
                    _ => samples,
                });
                let dof = exp.robot.as_ref().map_or(7, |rb| rb.setup.chain.dof()) as f64;
                recordings = (p.demonstrations as f64 + 2.0) * robot_samples * (6.0 + dof) * 8.0;
                // The imitation's design matrix: samples × bases.
                let im_samples = p.dmp.tau / p.dmp.dt + 1.0;
                recordings += 4.0 * im_samples * p.dmp.n_basis as f64 * 8.0;
            }
        }
        // Extra operations per sample and dimension of a rollout beyond the forcing term,
        // calibrated on the shipped experiments (seconds per evaluation, see
        // `OPERATIONS_PER_SECOND`): FK and limits per joint, the orientation DMP's
        // quaternion integration, the plant's substeps.
        Kind::ViapointJoint => per_sample_extra = 20.0,
        // Every evaluation executes: the controller's step (FK, Jacobian, a 7×7 solve)
        // per control period.
        Kind::ViapointExecuted => per_sample_extra = 2000.0,
        Kind::ViapointPose => {
            multiplier = 2.0;
            per_sample_extra = 300.0;
        }
        Kind::ViapointEnergy => {
            let e = exp.energy();
            per_sample_extra = e.map_or(10, |e| e.plant.substeps) as f64 * 25.0;
        }
        Kind::Viapoint | Kind::Contact => {}
    }
    let lambda = population as f64;
    let nf = n as f64;
    use cps_learn::Solver;
    // Evaluations of one search by `solver` with `g` generations (iterations): CMA-ES a
    // population each, Levenberg–Marquardt a Jacobian (n) and about two trial steps each;
    // the exact solver none (the effort task's least squares is its exact solve too).
    let search = |solver: Solver| match (solver, exp.kind()) {
        (Solver::Exact, _) | (Solver::LeastSquares, Kind::ViapointEnergy) => 0.0,
        (Solver::LeastSquares, _) => (nf + 2.0) * g,
        (Solver::Cmaes, _) => lambda * g,
    };
    let mut evaluations = match (exp.kind(), exp.pose()) {
        // Position and orientation, each by its own solver.
        (Kind::ViapointPose, Some(p)) => search(c.solver) + search(p.method),
        (Kind::Imitation | Kind::Promp | Kind::Viapoint | Kind::Scaling, _) => {
            search(c.solver) * r * multiplier
        }
        _ => search(c.solver) * r * multiplier,
    };
    // The polish after CMA-ES: at most 1000 Levenberg–Marquardt iterations.
    if c.polish && c.solver == Solver::Cmaes {
        evaluations += 1000.0 * (nf + 2.0) * r;
    }
    let rollout = samples * d * (basis + per_sample_extra);
    // CMA-ES evaluates a quadratic cost by its quadratic form (n² multiply-adds), not a
    // rollout.
    let quadratic = c.solver == Solver::Cmaes
        && c.evaluation != cps_learn::Evaluation::Rollout
        && c.task.obstacles.is_empty()
        && matches!(
            exp.kind(),
            Kind::Viapoint | Kind::Scaling | Kind::ViapointEnergy
        );
    let per_evaluation = if quadratic { 2.0 * nf * nf } else { rollout };
    let rows = 3.0 * samples * d;
    let exact = nf * rollout + rows * nf * nf;
    // Learning on the executions of the robot with dynamics: at most a Jacobian (n
    // executions) and two trial runs an iteration, each a control period's dynamics per
    // simulated period.
    let executions = match (exp.joint(), exp.robot.as_ref().map(|r| &r.backend)) {
        (Some(j), Some(crate::robots::BackendChoice::Dynamics(o)))
            if exp.kind() == Kind::ViapointJoint
                && j.learn_on == crate::plan::LearnOn::Execution =>
        {
            (nf + 2.0) * g * (dmp.tau / o.control_period) * OPERATIONS_PER_CONTROL_PERIOD
        }
        _ => 0.0,
    };
    let work = evaluations * per_evaluation + exact * multiplier.max(1.0) + executions;
    let memory = 8.0
        * (3.0 * samples * basis
            + 2.0 * lambda * d * 3.0 * samples
            + rows * nf
            + 6.0 * nf * nf
            + 6.0 * g * r * multiplier)
        + recordings;
    Estimate {
        memory_bytes: memory,
        work,
        samples,
        evaluations,
        dims,
        parameters: n,
        population,
    }
}

/// Refuses `exp` when its estimate exceeds a ceiling, naming the key (with its place) that
/// is furthest above an ordinary experiment's value.
pub fn check(
    exp: &Experiment,
    factors: &Factors,
    ceilings: &Ceilings,
    locate: &dyn Fn(&Range<usize>) -> String,
) -> Result<Estimate, InputError> {
    let e = estimate(exp);
    let over_memory = e.memory_bytes > ceilings.memory_bytes;
    let over_work = e.work > ceilings.work;
    if !over_memory && !over_work {
        return Ok(e);
    }
    let culprit = factors.keys.iter().max_by(|a, b| a.2.total_cmp(&b.2));
    let (what, ceiling, flag) = if over_memory {
        (
            format!("≈ {} of memory", bytes(e.memory_bytes)),
            bytes(ceilings.memory_bytes),
            "--max-memory GIB",
        )
    } else {
        (
            format!("≈ {:.1e} operations", e.work),
            format!("{:.1e}", ceilings.work),
            "--max-work OPS",
        )
    };
    let detail = format!(
        "this experiment would need {what}, above the ceiling of {ceiling} ({} samples per rollout, {} parameters, population {}, up to {:.1e} cost evaluations); lower it, or raise the ceiling with {flag} if the machine can take it",
        e.samples, e.parameters, e.population, e.evaluations
    );
    Err(InputError(match culprit {
        Some((key, value, _, span)) => {
            format!("{}: {key} = {value}: {detail}", locate(span))
        }
        None => detail,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_read_well() {
        assert_eq!(bytes(3.0 * GIB), "3.0 GiB");
        assert_eq!(bytes(5.0 * 1024.0 * 1024.0), "5 MiB");
        assert_eq!(bytes(10.0), "1 KiB");
    }
}
