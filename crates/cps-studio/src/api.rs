//! The studio's JSON API, without HTTP: a request as the page sends it, checked, learned,
//! answered. Every refusal is one sentence naming the field, as the command line would
//! say it of an experiment file.

use cps_dmp::DmpConfig;
use cps_learn::{
    CostWeights, LearnError, Solver, ViaPoint, ViaPointConfig, ViaPointTask, learn_via_points,
};
use serde::{Deserialize, Serialize};

/// The most via points a request may carry.
pub const MAX_VIA: usize = 64;
/// The most trajectory samples a request may ask for (τ / dt).
pub const MAX_SAMPLES: f64 = 20_000.0;
/// The most CMA-ES generations a request may ask for.
pub const MAX_GENERATIONS: u64 = 2_000;
/// The most rollout samples a CMA-ES request may compute (population × generations ×
/// samples): ≈ 2 s of this machine's time (release build). The default request
/// (16 × 1000 × 1001 for a 3-D task of 25 basis functions) uses a twentieth of it.
pub const MAX_SAMPLE_EVALUATIONS: f64 = 3e8;

/// `POST /api/viapoint`'s body.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViaPointRequest {
    /// Start position (1 to 6 coordinates; metres for a robot's tool).
    pub start: Vec<f64>,
    /// Goal position, reached at `tau`.
    pub goal: Vec<f64>,
    /// Duration, seconds.
    pub tau: f64,
    /// Via points, in time order.
    #[serde(default)]
    pub via: Vec<ViaRequest>,
    /// A [`Solver`] by its name: `"exact"` (the least-squares optimum, ≈ ms), `"cmaes"` or
    /// `"least_squares"` (Levenberg–Marquardt from the warm start).
    #[serde(default = "exact")]
    pub solver: String,
    /// Basis functions per dimension (default 25, as the thesis).
    #[serde(default)]
    pub basis_functions: Option<usize>,
    /// Sample period of the answer, seconds (default 0.01).
    #[serde(default)]
    pub dt: Option<f64>,
    /// Cost weights (default: the thesis's).
    #[serde(default)]
    pub weights: Option<WeightsRequest>,
    /// CMA-ES generations (default: the library's, as an experiment file's and Python's,
    /// [`ViaPointConfig::new`]; it stops earlier once converged).
    #[serde(default)]
    pub generations: Option<u64>,
    /// CMA-ES seed (default: the library's).
    #[serde(default)]
    pub seed: Option<u64>,
    /// CMA-ES population (default: the library's, CMA-ES's `4 + ⌊3 ln n⌋`).
    #[serde(default)]
    pub population: Option<usize>,
    /// Also execute the movement on the studio's robot (3-D tasks): reachability, the
    /// robot's poses to animate, the executed tool path.
    #[serde(default)]
    pub robot: bool,
    /// With `robot`: also check the executed movement against every limit at 1 kHz
    /// (default true; the page skips it for the answers while a point is dragged, where
    /// it would take most of the time).
    #[serde(default = "yes")]
    pub limits: bool,
}

fn exact() -> String {
    "exact".into()
}

fn yes() -> bool {
    true
}

/// A via point of a request.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViaRequest {
    /// Seconds, inside (0, τ).
    pub time: f64,
    /// Position.
    pub position: Vec<f64>,
}

/// Cost weights of a request; a missing one keeps the thesis's value.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeightsRequest {
    /// Goal position error.
    pub goal: Option<f64>,
    /// Via-point errors.
    pub via: Option<f64>,
    /// Final velocity.
    pub final_velocity: Option<f64>,
    /// Squared acceleration.
    pub acceleration: Option<f64>,
    /// Squared jerk.
    pub jerk: Option<f64>,
}

/// The answer: the learned movement sampled every `dt`, and how well it meets the task.
#[derive(Debug, Clone, Serialize)]
pub struct ViaPointAnswer {
    /// Sample times, seconds.
    pub t: Vec<f64>,
    /// `position[k]`: the position at `t[k]`.
    pub position: Vec<Vec<f64>>,
    /// Distance from each via point at its time.
    pub via_errors_m: Vec<f64>,
    /// Distance from the goal at τ.
    pub goal_error_m: f64,
    /// The cost.
    pub cost: f64,
    /// The cost term by term.
    pub cost_terms: cps_learn::CostBreakdown,
    /// The exact optimum's cost (the lower bound CMA-ES approaches).
    pub optimum_cost: f64,
    /// The solver's name ([`Solver::name`]).
    pub solver: &'static str,
    /// CMA-ES generations run (0 for the exact solver).
    pub generations: u64,
    /// The movement on the robot, when asked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robot: Option<crate::robot::RobotAnswer>,
}

/// A refusal: the sentence the page shows next to the field.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiError(pub String);

impl std::fmt::Display for ApiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ApiError {}

fn refuse<T>(message: String) -> Result<T, ApiError> {
    Err(ApiError(message))
}

impl ViaPointRequest {
    /// The learning run the request asks for, checked: sizes within the API's ceilings,
    /// then the task as the library validates it.
    pub fn config(&self) -> Result<ViaPointConfig, ApiError> {
        let dims = self.start.len();
        if !(1..=6).contains(&dims) {
            return refuse(format!("start: must have 1 to 6 coordinates (got {dims})"));
        }
        if self.goal.len() != dims {
            return refuse(format!(
                "goal: must have {dims} coordinates, as start (got {})",
                self.goal.len()
            ));
        }
        if self.via.len() > MAX_VIA {
            return refuse(format!(
                "via: at most {MAX_VIA} via points (got {})",
                self.via.len()
            ));
        }
        for (i, v) in self.via.iter().enumerate() {
            if v.position.len() != dims {
                return refuse(format!(
                    "via[{i}].position: must have {dims} coordinates, as start (got {})",
                    v.position.len()
                ));
            }
        }
        let solver: Solver = match self.solver.parse() {
            Ok(s) => s,
            Err(e) => return refuse(format!("solver: {e}")),
        };
        let dt = self.dt.unwrap_or(0.01);
        if !(dt.is_finite() && (1e-4..=1.0).contains(&dt)) {
            return refuse(format!("dt: must be between 0.0001 and 1 s (got {dt})"));
        }
        if !(self.tau.is_finite() && self.tau > 0.0) || self.tau / dt > MAX_SAMPLES {
            return refuse(format!(
                "tau: must be positive with at most {MAX_SAMPLES} samples of dt = {dt} s (got {} s)",
                self.tau
            ));
        }
        let basis = self.basis_functions.unwrap_or(25);
        if !(2..=200).contains(&basis) {
            return refuse(format!(
                "basis_functions: must be between 2 and 200 (got {basis})"
            ));
        }
        let thesis = CostWeights::thesis();
        let w = self.weights.clone().unwrap_or_default();
        let weights = CostWeights {
            goal: w.goal.unwrap_or(thesis.goal),
            via: w.via.unwrap_or(thesis.via),
            final_velocity: w.final_velocity.unwrap_or(thesis.final_velocity),
            acceleration: w.acceleration.unwrap_or(thesis.acceleration),
            jerk: w.jerk.unwrap_or(thesis.jerk),
            obstacle: 0.0,
        };
        let task = ViaPointTask {
            start: self.start.clone(),
            goal: self.goal.clone(),
            goal_velocity: vec![0.0; dims],
            via: self
                .via
                .iter()
                .map(|v| ViaPoint {
                    time: v.time,
                    position: v.position.clone(),
                })
                .collect(),
            dmp: DmpConfig::new(basis, self.tau, dt),
            weights,
            obstacles: Vec::new(),
        };
        task.validate().map_err(|e| ApiError(sentence(e)))?;
        // The library's defaults, as an experiment file's and Python's; each setting given
        // is checked by the library, then against the API's own ceilings.
        let mut config = ViaPointConfig::new(task);
        config.solver = solver;
        let setting = |e: cps_learn::BadSetting| ApiError(e.to_string());
        if let Some(g) = self.generations {
            config.generations = ViaPointConfig::check_generations(g).map_err(setting)?;
            if g > MAX_GENERATIONS {
                return refuse(format!(
                    "generations: a studio request may ask at most {MAX_GENERATIONS} (got {g})"
                ));
            }
        }
        if let Some(p) = self.population {
            config.population = Some(ViaPointConfig::check_population(p).map_err(setting)?);
        }
        if let Some(seed) = self.seed {
            config.seed = seed;
        }
        // Bounded work: CMA-ES's rollouts times their samples.
        if solver == Solver::Cmaes {
            let rollouts = config.population.unwrap_or_else(|| {
                cps_cmaes::Parameters::default_lambda(dims * config.task.dmp.n_basis)
            });
            let samples = self.tau / dt + 1.0;
            let work = rollouts as f64 * config.generations as f64 * samples;
            if work > MAX_SAMPLE_EVALUATIONS {
                return refuse(format!(
                    "generations: {} generations of {rollouts} rollouts of {samples:.0} samples are {work:.1e} sample evaluations, more than the {MAX_SAMPLE_EVALUATIONS:.0e} a studio request may take: fewer generations, a smaller population or a coarser dt",
                    config.generations
                ));
            }
        }
        Ok(config)
    }
}

/// A library error as one sentence, its field first.
fn sentence(e: LearnError) -> String {
    match e {
        // The request calls the cost's weights `weights`.
        LearnError::InvalidTask { field, problem } => match field.strip_prefix("cost.") {
            Some(weight) => format!("weights.{weight}: {problem}"),
            None => format!("{field}: {problem}"),
        },
        other => other.to_string(),
    }
}

/// The studio's robot for a request that asks for it: 3-D tasks only.
fn robot_for<'a>(
    request: &ViaPointRequest,
    robot: Option<&'a crate::robot::StudioRobot>,
) -> Result<&'a crate::robot::StudioRobot, ApiError> {
    match robot {
        None => refuse("robot: this studio has no robot".into()),
        Some(_) if request.start.len() != 3 => refuse(format!(
            "robot: the robot executes tool positions: start needs 3 coordinates (got {})",
            request.start.len()
        )),
        Some(r) => Ok(r),
    }
}

/// The request's configuration and learning outcome; `stop` is polled every generation.
fn learn(
    request: &ViaPointRequest,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<(ViaPointConfig, cps_learn::ViaPointOutcome), ApiError> {
    let config = request.config()?;
    let progress = |_: usize, _: &cps_cmaes::GenerationReport<'_>| {
        if stop() {
            std::ops::ControlFlow::Break(())
        } else {
            std::ops::ControlFlow::Continue(())
        }
    };
    let outcome = learn_via_points(&config, &progress).map_err(|e| ApiError(sentence(e)))?;
    Ok((config, outcome))
}

/// The movement `request` asks for, executed on `robot` and exported as `format`
/// (`ros2-yaml`, `mcap`, `csv-1khz`): the file name and its bytes.
pub fn export(
    request: &ViaPointRequest,
    robot: Option<&crate::robot::StudioRobot>,
    format: &str,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<(String, Vec<u8>), ApiError> {
    let robot = robot_for(request, robot)?;
    let (config, outcome) = learn(request, stop)?;
    robot
        .export(&outcome.best_trajectory(), config.task.dmp.dt, format)
        .map_err(|e| ApiError(format!("format: {e}")))
}

/// Learns what `request` asks and answers it, executed on `robot` if it asks; `stop` is
/// polled every generation.
pub fn viapoint(
    request: &ViaPointRequest,
    robot: Option<&crate::robot::StudioRobot>,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<ViaPointAnswer, ApiError> {
    let robot = if request.robot {
        Some(robot_for(request, robot)?)
    } else {
        None
    };
    let (config, outcome) = learn(request, stop)?;
    let best = outcome.best();
    let traj = outcome.best_trajectory();
    let dims = traj.dims();
    let t = traj.times().to_vec();
    let position = (0..t.len())
        .map(|k| (0..dims).map(|d| traj.position(d)[k]).collect())
        .collect();
    let robot = match robot {
        Some(r) => Some(
            r.execute(&config.task, &traj, request.limits)
                .map_err(ApiError)?,
        ),
        None => None,
    };
    Ok(ViaPointAnswer {
        t,
        position,
        via_errors_m: best.errors.via.clone(),
        goal_error_m: best.errors.goal,
        cost: best.cost,
        cost_terms: best.breakdown,
        optimum_cost: outcome.optimum.cost,
        solver: config.solver.name(),
        generations: best.generations,
        robot,
    })
}
