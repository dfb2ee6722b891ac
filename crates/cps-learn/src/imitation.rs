//! The thesis's imitation experiment (§5.2): learned movements become demonstrations,
//! the robot executes them, what it really did is averaged and imitated, and the imitation
//! is executed in turn.
//!
//! 1. **Demonstrations.** The via-point task is perturbed `count` times (each via point
//!    moved by N(0, σ²) per axis, seeded) and each perturbed task is learned with the
//!    via-point learner — or the demonstrations are given as paths
//!    ([`ImitationConfig::given`]: motion-capture takes), and this step is skipped.
//! 2. **Reachability.** Each learned path is followed by inverse kinematics within the
//!    joint limits on one branch ([`check_path`]); paths that leave the reachable set or
//!    would need a branch change are dropped, with the reason.
//! 3. **Execution.** The kept paths are executed on the robot backend with the inverse
//!    controller from the initial configuration (a given path from the configuration
//!    the reachability check found at its start); the tool position and the backend's
//!    clock are recorded.
//! 4. **Imitation.** The recordings are time-normalised and averaged, and the mean is
//!    imitated by ridge regression and by jerk-regularised ridge regression.
//! 5. **Execution of the imitations**, recorded like the demonstrations.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

use cps_dmp::{Combine, DmpConfig, Imitation, Imitator, Lambda, Regression, Trajectory};
use cps_kinematics::{IkConfig, KinematicsError, check_path};
use cps_robot::{Recording, Robot, StopToken};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

use crate::robot::{execute_trajectory_from, targets_at};
use crate::{
    LearnError, RobotSetup, RunResult, ViaPointConfig, ViaPointTask, check_way_points,
    learn_via_points,
};

/// Settings of [`run_imitation`].
#[derive(Debug, Clone)]
pub struct ImitationConfig {
    /// The unperturbed task and the learner of the demonstrations (its `seed` is the
    /// experiment's master seed; `repetitions` is ignored: one run per demonstration).
    pub learner: ViaPointConfig,
    /// Number of demonstrations (thesis: 20).
    pub demonstrations: usize,
    /// Standard deviation of the via-point perturbation per axis, metres (thesis: 0.05).
    pub via_std: f64,
    /// The robot the demonstrations and imitations are executed on.
    pub robot: RobotSetup,
    /// The imitating DMP (thesis: 25 basis functions, τ = 9.5 s).
    pub imitation: DmpConfig,
    /// λ of plain ridge regression (thesis: 1e-12).
    pub ridge_lambda: Lambda,
    /// λ of jerk-regularised ridge regression (default: generalised cross-validation).
    pub jerk_lambda: Lambda,
    /// Demonstrations given as 3-D paths (motion-capture takes in the task's frame):
    /// when there are any, they are the demonstrations, and `demonstrations`, `via_std`
    /// and the learner are not used.
    pub given: Vec<GivenDemonstration>,
    /// A clearance the imitations keep (None: none): each is bent on the robot's model,
    /// as near the mean demonstration as it can stay, before it is executed
    /// ([`crate::keep_clear`]).
    pub clearance: Option<crate::ClearanceStage>,
}

/// A demonstration given as a path rather than learned.
#[derive(Debug, Clone, PartialEq)]
pub struct GivenDemonstration {
    /// Its name (the take's file).
    pub name: String,
    /// The tool's position over time (3 dimensions, metres, seconds from 0).
    pub trajectory: Trajectory,
}

impl ImitationConfig {
    /// The thesis's set-up around `learner` and `robot`: 20 demonstrations, σ = 5 cm,
    /// 25 basis functions, τ = 9.5 s with the learner's dt, ridge λ = 1e-12, jerk λ by GCV.
    pub fn thesis(learner: ViaPointConfig, robot: RobotSetup) -> Self {
        let dt = learner.task.dmp.dt;
        Self {
            learner,
            demonstrations: 20,
            via_std: 0.05,
            robot,
            imitation: DmpConfig::new(25, 9.5, dt),
            ridge_lambda: Lambda::Fixed(1e-12),
            jerk_lambda: Lambda::Auto,
            given: Vec::new(),
            clearance: None,
        }
    }

    /// The seed of demonstration `i` (perturbation and learning), derived from the master
    /// seed so that adding demonstrations does not change the earlier ones.
    pub fn demonstration_seed(&self, i: usize) -> u64 {
        self.learner.repetition_seed(i)
    }

    /// The perturbed task of demonstration `i`.
    pub fn perturbed_task(&self, i: usize) -> ViaPointTask {
        let mut task = self.learner.task.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(self.demonstration_seed(i));
        // σ is validated finite and ≥ 0 before any use.
        let normal = Normal::new(0.0, self.via_std).unwrap_or(Normal::new(0.0, 0.0).unwrap());
        for v in &mut task.via {
            for p in &mut v.position {
                *p += normal.sample(&mut rng);
            }
        }
        task
    }

    fn validate(&self) -> Result<(), LearnError> {
        self.learner.task.validate()?;
        if let Some(g) = self.given.iter().find(|g| g.trajectory.dims() != 3) {
            return Err(LearnError::task(
                "given",
                format!(
                    "{} has {} dimensions; a tool path has 3",
                    g.name,
                    g.trajectory.dims()
                ),
            ));
        }
        if self.demonstrations == 0 {
            return Err(LearnError::task("demonstrations", "must be at least 1"));
        }
        if !(self.via_std.is_finite() && self.via_std >= 0.0) {
            return Err(LearnError::task(
                "via_std",
                format!("must be finite and ≥ 0 (got {})", self.via_std),
            ));
        }
        self.imitation.validate()?;
        Ok(())
    }
}

/// A stage of [`run_imitation`], reported to the progress callback.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImitationStage {
    /// Learning the demonstrations (`done` of `total`).
    Learning,
    /// Checking that the paths are reachable.
    Checking,
    /// Executing demonstrations on the backend.
    Executing,
    /// Fitting the imitations.
    Imitating,
    /// Executing the imitations.
    ExecutingImitations,
}

impl ImitationStage {
    /// A lower-case name for messages and summaries.
    pub fn name(&self) -> &'static str {
        match self {
            ImitationStage::Learning => "learning",
            ImitationStage::Checking => "checking",
            ImitationStage::Executing => "executing",
            ImitationStage::Imitating => "imitating",
            ImitationStage::ExecutingImitations => "executing imitations",
        }
    }
}

/// One demonstration and what became of it.
#[derive(Debug, Clone)]
pub struct DemonstrationResult {
    /// Its index (0-based).
    pub index: usize,
    /// The perturbed task it was learned from (`None`: given).
    pub task: Option<ViaPointTask>,
    /// The learner's result (`None`: given).
    pub learned: Option<RunResult>,
    /// A given demonstration's name.
    pub name: Option<String>,
    /// The configuration a given demonstration is executed from (where the reachability
    /// check found its start).
    pub start_q: Option<Vec<f64>>,
    /// The learned movement on the DMP grid.
    pub trajectory: Trajectory,
    /// Why it was dropped (`None` if it was kept).
    pub dropped: Option<String>,
    /// The robot's recording (kept demonstrations that were executed).
    pub recording: Option<Recording>,
}

/// One imitation of the mean recording.
#[derive(Debug, Clone)]
pub struct ImitationFit {
    /// `ridge` or `jerk_ridge`.
    pub method: &'static str,
    /// The model, its weights, the fit report and the mean it was fitted to.
    pub imitation: Imitation,
    /// The model's rollout.
    pub trajectory: Trajectory,
    /// The robot's recording of the rollout (if execution was reached).
    pub recording: Option<Recording>,
    /// With a clearance: how the imitation was kept clear on the model (its weights and
    /// rollout above are the result).
    pub kept_clear: Option<crate::KeptClear>,
}

impl ImitationFit {
    /// Root-mean-square distance between the rollout and the mean recording on the grid
    /// (metres; all dimensions together).
    pub fn rmse(&self) -> f64 {
        self.imitation
            .report
            .rmse
            .iter()
            .map(|r| r * r)
            .sum::<f64>()
            .sqrt()
    }

    /// Integrated squared jerk of the rollout, summed over the dimensions (m²/s⁵).
    pub fn integrated_squared_jerk(&self) -> f64 {
        self.imitation.report.integrated_squared_jerk.iter().sum()
    }
}

/// What [`run_imitation`] produced; stages not reached (interruption, no demonstration
/// kept) are empty.
#[derive(Debug, Clone)]
pub struct ImitationOutcome {
    /// Every demonstration, kept or dropped.
    pub demonstrations: Vec<DemonstrationResult>,
    /// The imitations (ridge, jerk-regularised ridge).
    pub fits: Vec<ImitationFit>,
    /// Wall time per stage, seconds.
    pub stage_seconds: Vec<(&'static str, f64)>,
    /// False if the run was interrupted or the backend failed.
    pub complete: bool,
    /// Why the run stopped early when the robot backend failed (a simulator that died or
    /// stopped answering): what was done before is kept in the outcome.
    pub failure: Option<String>,
}

impl ImitationOutcome {
    /// The demonstrations that were kept and executed.
    pub fn kept(&self) -> impl Iterator<Item = &DemonstrationResult> {
        self.demonstrations
            .iter()
            .filter(|d| d.dropped.is_none() && d.recording.is_some())
    }

    /// The mean recording the imitations were fitted to, on the imitation grid (one
    /// vector per dimension), if the imitation stage was reached.
    pub fn mean(&self) -> Option<&[Vec<f64>]> {
        self.fits.first().map(|f| f.imitation.reference.as_slice())
    }
}

/// Bends an imitation on the robot's model until it keeps `stage`'s clearance, as near
/// the mean demonstration it was fitted to as it can stay: the anchor is the distance
/// between its rollout and that mean on the imitation grid, weighted as the task weighs
/// a via point's (`w_via` per m² of mean squared distance). `fit` becomes the result.
fn keep_imitation_clear(
    config: &ImitationConfig,
    stage: &crate::ClearanceStage,
    fit: &mut ImitationFit,
    from: &[f64],
    dt: f64,
    progress: &(dyn Fn(&cps_cmaes::GenerationReport<'_>) -> ControlFlow<()> + Sync),
) -> Result<(), LearnError> {
    let dmp = fit.imitation.dmp.clone();
    let reference = &fit.imitation.reference;
    let n = reference.first().map_or(0, Vec::len);
    let scale = (config.learner.task.weights.via / n.max(1) as f64).sqrt();
    let anchor = |w: &[f64], out: &mut Vec<f64>| {
        let y = dmp.rollout(w);
        for (d, r) in reference.iter().enumerate() {
            let p = y.position(d);
            out.extend((0..n).map(|k| scale * (p[k.min(p.len() - 1)] - r[k])));
        }
    };
    let targets = |w: &[f64]| targets_at(&dmp.rollout(w), dt).1;
    let robot = RobotSetup {
        initial_q: from.to_vec(),
        ..config.robot.clone()
    };
    let keep = crate::KeepClear {
        clearance: &stage.clearance,
        robot: &robot,
        dt,
        iterations: stage.iterations,
    };
    let kept = crate::keep_clear(
        &keep,
        fit.imitation.weights.clone(),
        &anchor,
        &targets,
        progress,
    )?;
    fit.imitation.weights.clone_from(&kept.theta);
    fit.trajectory = dmp.rollout(&kept.theta);
    // The fit's errors are the bent rollout's now.
    let report = &mut fit.imitation.report;
    for (d, r) in reference.iter().enumerate() {
        let p = fit.trajectory.position(d);
        let e: Vec<f64> = (0..n).map(|k| p[k.min(p.len() - 1)] - r[k]).collect();
        report.rmse[d] = (e.iter().map(|x| x * x).sum::<f64>() / n.max(1) as f64).sqrt();
        report.max_error[d] = e.iter().fold(0.0, |a: f64, x| a.max(x.abs()));
        let t = fit.trajectory.times();
        let h = if t.len() > 1 { t[1] - t[0] } else { 1.0 };
        report.integrated_squared_jerk[d] = fit
            .trajectory
            .acceleration(d)
            .windows(2)
            .map(|w| ((w[1] - w[0]) / h).powi(2) * h)
            .sum();
    }
    fit.kept_clear = Some(kept);
    Ok(())
}

/// Runs the imitation experiment (see the module documentation) on `backend`.
///
/// Learning and reachability checks run in parallel in the current rayon pool; executions
/// are sequential on the one backend. `progress(stage, done, total)` is called as work
/// finishes and may return `ControlFlow::Break(())` to stop: the outcome then holds the
/// finished stages and `complete == false`. A backend that fails during an execution (a
/// simulator that died or timed out) ends the run the same way, with the reason in
/// `failure`: the executions done before it are kept. `stop` brakes a robot that moves (and
/// ends the run as a failure of that execution). The results do not depend on the number
/// of threads.
pub fn run_imitation(
    config: &ImitationConfig,
    backend: &mut dyn Robot,
    progress: &(dyn Fn(ImitationStage, usize, usize) -> ControlFlow<()> + Sync),
    stop: &StopToken,
) -> Result<ImitationOutcome, LearnError> {
    config.validate()?;
    if backend.model().chain.dof() != config.robot.chain.dof() {
        return Err(KinematicsError::JointCount {
            expected: config.robot.chain.dof(),
            got: backend.model().chain.dof(),
        }
        .into());
    }
    // The unperturbed way points must be reachable: a clear error before any work.
    if config.given.is_empty() {
        check_way_points(&config.learner.task, &config.robot)?;
    }
    let mut out = ImitationOutcome {
        demonstrations: Vec::new(),
        fits: Vec::new(),
        stage_seconds: Vec::new(),
        complete: false,
        failure: None,
    };
    let p = Progress {
        callback: progress,
        halt: AtomicBool::new(false),
        done: AtomicUsize::new(0),
    };
    let ik = IkConfig {
        position_tolerance: 1e-6,
        restarts: 20,
        ..IkConfig::default()
    };
    let dt = backend.dt();
    // Each stage records its time; one that ends the run early returns false.
    let t = Instant::now();
    out.demonstrations = learn_demonstrations(config, &p)?;
    out.stage_seconds
        .push(("learning", t.elapsed().as_secs_f64()));
    let interrupted = out.demonstrations.iter().any(|d| {
        d.learned
            .as_ref()
            .is_some_and(|l| l.termination == "interrupted")
    });
    if p.stopped() || interrupted {
        return Ok(out);
    }
    let t = Instant::now();
    check_reachability(config, &mut out.demonstrations, dt, &ik, &p);
    out.stage_seconds
        .push(("checking", t.elapsed().as_secs_f64()));
    if p.stopped() {
        return Ok(out);
    }
    let t = Instant::now();
    let went_on = execute_demonstrations(config, backend, &mut out, stop, &p);
    out.stage_seconds
        .push(("executing", t.elapsed().as_secs_f64()));
    if !went_on {
        return Ok(out);
    }
    if out.kept().next().is_none() {
        // Nothing to imitate: the outcome says so (no fits); not an error of the run.
        out.complete = true;
        return Ok(out);
    }
    let t = Instant::now();
    out.fits = imitate_recordings(config, &out)?;
    out.stage_seconds
        .push(("imitating", t.elapsed().as_secs_f64()));
    if progress(ImitationStage::Imitating, 1, 1).is_break() {
        return Ok(out);
    }
    let t = Instant::now();
    let went_on = execute_imitations(config, backend, &mut out, dt, &ik, stop, &p);
    if went_on != Some(false) {
        // (A run that could not find an imitation's start or keep it clear records no
        // time for the stage.)
        out.stage_seconds
            .push(("executing imitations", t.elapsed().as_secs_f64()));
    }
    out.complete = went_on == Some(true);
    Ok(out)
}

/// The caller's progress callback, whether it asked to stop, and the work the stage
/// running has done.
struct Progress<'a> {
    callback: &'a (dyn Fn(ImitationStage, usize, usize) -> ControlFlow<()> + Sync),
    halt: AtomicBool,
    done: AtomicUsize,
}

impl Progress<'_> {
    /// One more piece of `stage`'s `total` done, reported.
    fn report(&self, stage: ImitationStage, total: usize) {
        let d = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        if (self.callback)(stage, d, total).is_break() {
            self.halt.store(true, Ordering::Relaxed);
        }
    }

    /// Whether the caller asked to stop.
    fn stopped(&self) -> bool {
        self.halt.load(Ordering::Relaxed)
    }

    /// Whether to go on within `stage` (the caller asked between its pieces).
    fn go_on(&self, stage: ImitationStage, total: usize) -> bool {
        let finished = self.done.load(Ordering::Relaxed);
        if self.stopped() || (self.callback)(stage, finished, total).is_break() {
            self.halt.store(true, Ordering::Relaxed);
            false
        } else {
            true
        }
    }
}

/// Stage 1: the demonstrations learned, in parallel (or the given ones taken).
fn learn_demonstrations(
    config: &ImitationConfig,
    p: &Progress<'_>,
) -> Result<Vec<DemonstrationResult>, LearnError> {
    if !config.given.is_empty() {
        return Ok(config
            .given
            .iter()
            .enumerate()
            .map(|(i, g)| DemonstrationResult {
                index: i,
                task: None,
                learned: None,
                name: Some(g.name.clone()),
                start_q: None,
                trajectory: g.trajectory.clone(),
                dropped: None,
                recording: None,
            })
            .collect());
    }
    let n = config.demonstrations;
    (0..n)
        .into_par_iter()
        .map(|i| {
            let mut learner = config.learner.clone();
            learner.task = config.perturbed_task(i);
            learner.seed = config.demonstration_seed(i);
            learner.repetitions = 1;
            // Every generation asks the caller whether to go on (Ctrl-C reaches the runs).
            let outcome = learn_via_points(&learner, &|_, _| {
                if p.go_on(ImitationStage::Learning, n) {
                    ControlFlow::Continue(())
                } else {
                    ControlFlow::Break(())
                }
            })?;
            p.report(ImitationStage::Learning, n);
            let trajectory = outcome.best_trajectory();
            Ok(DemonstrationResult {
                index: i,
                task: Some(learner.task),
                learned: Some(outcome.best().clone()),
                name: None,
                start_q: None,
                trajectory,
                dropped: None,
                recording: None,
            })
        })
        .collect()
}

/// Stage 2: every path's reachability within the joint limits, in parallel: an unreachable one
/// is dropped with the reason; a given one starts where it was recorded.
fn check_reachability(
    config: &ImitationConfig,
    demonstrations: &mut [DemonstrationResult],
    dt: f64,
    ik: &IkConfig,
    p: &Progress<'_>,
) {
    p.done.store(0, Ordering::Relaxed);
    let n = demonstrations.len();
    let chain = &config.robot.chain;
    let max_step: Option<Vec<f64>> = chain
        .velocity_limits()
        .map(|v| v.iter().map(|v| v * dt).collect());
    let given = !config.given.is_empty();
    let verdicts: Vec<Result<Vec<f64>, String>> = demonstrations
        .par_iter()
        .map(|d| {
            let (times, targets) = targets_at(&d.trajectory, dt);
            let verdict = match check_path(
                chain,
                &targets,
                &times,
                &config.robot.initial_q,
                ik,
                max_step.as_deref(),
            ) {
                Ok(path) => Ok(path.into_iter().next().unwrap_or_default()),
                Err(e) => Err(e.to_string()),
            };
            p.report(ImitationStage::Checking, n);
            verdict
        })
        .collect();
    for (d, v) in demonstrations.iter_mut().zip(verdicts) {
        match v {
            // A given path starts wherever it was recorded: executed from there.
            Ok(q0) => d.start_q = given.then_some(q0),
            Err(e) => d.dropped = Some(e),
        }
    }
}

/// Stage 3: the kept demonstrations executed, one after the other on the backend; false when
/// the run ends here (a stop, or a backend that failed: what was executed is kept, and
/// the failure says what was not).
fn execute_demonstrations(
    config: &ImitationConfig,
    backend: &mut dyn Robot,
    out: &mut ImitationOutcome,
    stop: &StopToken,
    p: &Progress<'_>,
) -> bool {
    let kept = out
        .demonstrations
        .iter()
        .filter(|d| d.dropped.is_none())
        .count();
    p.done.store(0, Ordering::Relaxed);
    for d in out
        .demonstrations
        .iter_mut()
        .filter(|d| d.dropped.is_none())
    {
        let from = d.start_q.as_deref().unwrap_or(&config.robot.initial_q);
        match execute_trajectory_from(backend, &config.robot, &d.trajectory, from, stop) {
            Ok(r) => d.recording = Some(r),
            // The guard refused it (a limit, a collision): dropped, as an unreachable one
            // is; the robot is fine.
            Err(LearnError::Robot(
                e @ (cps_robot::RobotError::CommandRefused { .. }
                | cps_robot::RobotError::Refused { .. }),
            )) => d.dropped = Some(format!("the guard refused it: {e}")),
            Err(e) => {
                out.failure = Some(format!("executing demonstration {}: {e}", d.index));
                return false;
            }
        }
        p.report(ImitationStage::Executing, kept);
        if p.stopped() {
            return false;
        }
    }
    true
}

/// Stage 4: the recordings time-normalised, averaged and imitated (ridge, jerk-regularised
/// ridge).
fn imitate_recordings(
    config: &ImitationConfig,
    out: &ImitationOutcome,
) -> Result<Vec<ImitationFit>, LearnError> {
    let demos = out
        .kept()
        .map(|d| {
            let rec = d
                .recording
                .as_ref()
                .expect("kept demonstrations are executed");
            let rows: Vec<Vec<f64>> = rec.position.iter().map(|p| p.to_vec()).collect();
            cps_dmp::Demonstration::new(rec.time.clone(), &rows)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let template = cps_dmp::DiscreteDmp::new(config.imitation, &[0.0; 3], &[1.0; 3])?;
    let imitator = Imitator::new(template);
    let mut fits = Vec::new();
    for (method, regression) in [
        (
            "ridge",
            Regression::Ridge {
                lambda: config.ridge_lambda,
            },
        ),
        (
            "jerk_ridge",
            Regression::JerkRidge {
                lambda: config.jerk_lambda,
            },
        ),
    ] {
        let imitation = imitator.imitate(&demos, regression, Combine::Mean)?;
        let trajectory = imitation.dmp.rollout(&imitation.weights);
        fits.push(ImitationFit {
            method,
            imitation,
            trajectory,
            recording: None,
            kept_clear: None,
        });
    }
    Ok(fits)
}

/// Stage 5: the imitations executed (each kept clear first, with `[clearance]`): Some(true)
/// when all were; Some(false) when a stop or the backend ended the run during an
/// execution; None when it ended before one (its start not found, or not kept clear).
fn execute_imitations(
    config: &ImitationConfig,
    backend: &mut dyn Robot,
    out: &mut ImitationOutcome,
    dt: f64,
    ik: &IkConfig,
    stop: &StopToken,
    p: &Progress<'_>,
) -> Option<bool> {
    let given = !config.given.is_empty();
    let total = out.fits.len();
    for (i, fit) in out.fits.iter_mut().enumerate() {
        // Given demonstrations start away from the initial configuration: the imitation
        // is executed from the configuration that reaches its start.
        let from = if given {
            match start_configuration(&config.robot, &fit.trajectory, ik) {
                Ok(q) => q,
                Err(e) => {
                    out.failure = Some(format!("the {} imitation's start: {e}", fit.method));
                    return None;
                }
            }
        } else {
            config.robot.initial_q.clone()
        };
        if let Some(stage) = &config.clearance {
            let kept = keep_imitation_clear(config, stage, fit, &from, dt, &|_| {
                if p.stopped() {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            });
            if let Err(e) = kept {
                out.failure = Some(format!("keeping the {} imitation clear: {e}", fit.method));
                return None;
            }
        }
        match execute_trajectory_from(backend, &config.robot, &fit.trajectory, &from, stop) {
            Ok(r) => fit.recording = Some(r),
            Err(e) => {
                out.failure = Some(format!("executing the {} imitation: {e}", fit.method));
                return Some(false);
            }
        }
        if (p.callback)(ImitationStage::ExecutingImitations, i + 1, total).is_break() {
            return Some(false);
        }
    }
    Some(true)
}

/// The configuration at a path's start, found by inverse kinematics from the initial one.
fn start_configuration(
    robot: &RobotSetup,
    traj: &Trajectory,
    ik: &IkConfig,
) -> Result<Vec<f64>, LearnError> {
    let target = cps_kinematics::IkTarget::Position(nalgebra::Vector3::new(
        traj.position_at(0, 0.0),
        traj.position_at(1, 0.0),
        traj.position_at(2, 0.0),
    ));
    Ok(cps_kinematics::solve_ik(&robot.chain, &target, &robot.initial_q, ik)?.q)
}
