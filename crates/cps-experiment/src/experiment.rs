//! The experiment file: TOML schema, parsing with locations, and conversion to the
//! library's typed configuration.

use std::ops::Range;
use std::path::Path;

use cps_dmp::DmpConfig;
use cps_learn::{
    CostWeights, Evaluation, LearnError, Parametrisation, PointObstacle, Solver, ViaPoint,
    ViaPointConfig, ViaPointTask,
};
use serde::Deserialize;
use toml::Spanned;

use crate::InputError;
use crate::budget::Ceilings;
pub use crate::plan::{Experiment, Kind};
use cps_outcome::source::location;
use cps_outcome::source::{MAX_FILE_BYTES, read_text};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    experiment: ExperimentSection,
    /// The via-point learner's sections: every kind but contact reads them.
    dmp: Option<Spanned<Dmp>>,
    task: Option<Spanned<Task>>,
    #[serde(default)]
    cost: Option<Spanned<Cost>>,
    optimizer: Option<Spanned<Optimizer>>,
    #[serde(default)]
    output: Output,
    robot: Option<Spanned<crate::robots::RobotSection>>,
    demonstrations: Option<Spanned<crate::plan::DemonstrationsSection>>,
    imitation: Option<Spanned<crate::plan::ImitationSection>>,
    scaling: Option<Spanned<crate::plan::ScalingSection>>,
    joint: Option<Spanned<crate::plan::JointSection>>,
    plant: Option<Spanned<crate::plan::PlantSection>>,
    speedup: Option<Spanned<toml::Value>>,
    orientation: Option<Spanned<crate::plan::OrientationSection>>,
    export: Option<Spanned<cps_movement::export::ExportSection>>,
    promp: Option<Spanned<crate::plan::ProMpSection>>,
    contact: Option<Spanned<crate::sections::contact::ContactSection>>,
    executed: Option<Spanned<crate::plan::ExecutedSection>>,
    clearance: Option<Spanned<crate::sections::clearance::ClearanceSection>>,
    /// The robot's world beyond its scene's: points and shapes, as in scene files.
    #[serde(default)]
    obstacle: Vec<Spanned<cps_movement::scene::ObstacleEntry>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ExperimentSection {
    #[serde(default)]
    kind: Option<Spanned<Kind>>,
    name: Option<String>,
    #[serde(default = "one")]
    seed: u64,
    #[serde(default = "one_spanned")]
    repetitions: Spanned<usize>,
}

fn one() -> u64 {
    1
}

fn one_spanned() -> Spanned<usize> {
    Spanned::new(0..0, 1)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Dmp {
    // Required by the kinds that learn ([`Learner::of`]); a contact file refuses the
    // section whole.
    basis_functions: Option<Spanned<usize>>,
    tau: Option<Spanned<f64>>,
    dt: Option<Spanned<f64>>,
    alpha_z: Option<Spanned<f64>>,
    beta_z: Option<Spanned<f64>>,
    alpha_x: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Task {
    start: Option<Spanned<Vec<f64>>>,
    goal: Option<Spanned<Vec<f64>>>,
    goal_velocity: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    via: Vec<Spanned<Via>>,
    #[serde(default)]
    obstacles: Vec<Spanned<Obstacle>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Obstacle {
    position: Spanned<Vec<f64>>,
    clearance: Spanned<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Via {
    time: Spanned<f64>,
    position: Spanned<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Cost {
    #[serde(default)]
    goal: f64,
    #[serde(default)]
    via: f64,
    #[serde(default)]
    final_velocity: f64,
    #[serde(default)]
    acceleration: f64,
    #[serde(default)]
    jerk: f64,
    #[serde(default)]
    obstacle: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Optimizer {
    #[serde(default)]
    method: Solver,
    #[serde(default)]
    parametrisation: Parametrisation,
    #[serde(default)]
    warm_start: bool,
    #[serde(default)]
    evaluation: Evaluation,
    #[serde(default)]
    polish: bool,
    sigma0: Option<Spanned<f64>>,
    population: Option<Spanned<usize>>,
    generations: Option<Spanned<u64>>,
    tol_fun: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Output {
    #[serde(default = "yes")]
    plots: bool,
}

/// A file without `[output]` gets plots, like one with an empty `[output]`.
impl Default for Output {
    fn default() -> Self {
        Self { plots: true }
    }
}

fn yes() -> bool {
    true
}

impl Experiment {
    /// Reads and validates an experiment file (see [`load`]).
    pub fn from_path(path: &Path, ceilings: &Ceilings) -> Result<Self, InputError> {
        load(path, None, ceilings)
    }

    /// Validates experiment text; `path` names it in messages and places relative scene
    /// files (see [`parse`]).
    pub fn from_text(path: &Path, text: &str, ceilings: &Ceilings) -> Result<Self, InputError> {
        parse(path, text, None, ceilings)
    }
}

/// `config` as the text of a `kind = "viapoint"` experiment file named `name`, every key
/// the file reads for it written out (defaults too), so that [`parse`] gives back the same
/// configuration; `header` goes first, as comment lines. Numbers are written in Rust's
/// shortest round-trip form. Refused: what such a file cannot say (a formulation other
/// than the thesis's, a seed beyond TOML's integers), and a configuration the library
/// refuses.
pub fn viapoint_toml(
    name: &str,
    config: &ViaPointConfig,
    header: &str,
) -> Result<String, InputError> {
    use std::fmt::Write as _;
    let why = |m: String| InputError(format!("the experiment cannot be written: {m}"));
    config.validate().map_err(|e| why(e.to_string()))?;
    config.check_together().map_err(|e| why(e.to_string()))?;
    config.task.validate().map_err(|e| why(e.to_string()))?;
    let task = &config.task;
    let d = &task.dmp;
    if d.formulation != cps_dmp::Formulation::default() {
        return Err(why(format!(
            "a via-point file learns with the \"{}\" formulation, not \"{}\"",
            cps_dmp::Formulation::default(),
            d.formulation
        )));
    }
    let Ok(seed) = i64::try_from(config.seed) else {
        return Err(why(format!(
            "seed {} is beyond TOML's integers (at most 2^63 − 1)",
            config.seed
        )));
    };
    let list = |v: &[f64]| {
        let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
        format!("[{}]", items.join(", "))
    };
    let quoted = toml::Value::String(name.to_string());
    let mut s = String::new();
    for line in header.lines() {
        let _ = writeln!(s, "# {line}");
    }
    let _ = writeln!(
        s,
        "\n[experiment]\nkind = \"viapoint\"\nname = {quoted}\nseed = {seed}\nrepetitions = {}\n",
        config.repetitions
    );
    let _ = writeln!(
        s,
        "[dmp]\nbasis_functions = {}\ntau = {:?}\ndt = {:?}\nalpha_z = {:?}\nbeta_z = {:?}\nalpha_x = {:?}\n",
        d.n_basis, d.tau, d.dt, d.alpha_z, d.beta_z, d.alpha_x
    );
    let _ = writeln!(
        s,
        "[task]\nstart = {}\ngoal = {}\ngoal_velocity = {}\n",
        list(&task.start),
        list(&task.goal),
        list(&task.goal_velocity)
    );
    for v in &task.via {
        let _ = writeln!(
            s,
            "[[task.via]]\ntime = {:?}\nposition = {}\n",
            v.time,
            list(&v.position)
        );
    }
    for o in &task.obstacles {
        let _ = writeln!(
            s,
            "[[task.obstacles]]\nposition = {}\nclearance = {:?}\n",
            list(&o.position),
            o.clearance
        );
    }
    let w = &task.weights;
    let _ = writeln!(
        s,
        "[cost]\ngoal = {:?}\nvia = {:?}\nfinal_velocity = {:?}\nacceleration = {:?}\njerk = {:?}\nobstacle = {:?}\n",
        w.goal, w.via, w.final_velocity, w.acceleration, w.jerk, w.obstacle
    );
    let _ = writeln!(
        s,
        "[optimizer]\nmethod = \"{}\"\nparametrisation = \"{}\"\nwarm_start = {}\nevaluation = \"{}\"\npolish = {}\nsigma0 = {:?}",
        config.solver,
        config.parametrisation,
        config.warm_start,
        config.evaluation,
        config.polish,
        config.sigma0
    );
    if let Some(p) = config.population {
        let _ = writeln!(s, "population = {p}");
    }
    let _ = writeln!(
        s,
        "generations = {}\ntol_fun = {:?}",
        config.generations,
        config.tol_fun.unwrap_or(0.0)
    );
    Ok(s)
}

/// Reads, parses and validates an experiment file. Every error names the file, the line
/// and column where it can, and the rule broken.
pub fn load(
    path: &Path,
    seed_override: Option<u64>,
    ceilings: &Ceilings,
) -> Result<Experiment, InputError> {
    let text = read_text(path, MAX_FILE_BYTES, "experiment file")?;
    parse(path, &text, seed_override, ceilings)
}

/// Parses and validates experiment text (`path` is only used in messages): one pass of
/// the TOML into one schema, each kind's sections read by its own module.
pub fn parse(
    path: &Path,
    text: &str,
    seed_override: Option<u64>,
    ceilings: &Ceilings,
) -> Result<Experiment, InputError> {
    if text.len() as u64 > MAX_FILE_BYTES {
        return Err(InputError(format!(
            "{}: the experiment file has {} bytes, more than the {} cps reads",
            path.display(),
            text.len(),
            cps_outcome::source::bytes(MAX_FILE_BYTES as f64)
        )));
    }
    let file = read_schema(path, text)?;
    let kind = file
        .experiment
        .kind
        .as_ref()
        .map_or(Kind::default(), |k| *k.get_ref());
    let at = |span: &Range<usize>, msg: String| {
        InputError(format!("{}: {msg}", location(path, text, span)))
    };
    if kind == Kind::Contact {
        return parse_contact(path, text, &file, seed_override, &at);
    }
    let learner = Learner::of(&file, path, kind, &at)?;
    let mut config = learner.config(path, kind, seed_override, &at)?;
    let name = file.experiment.name.clone().unwrap_or_else(|| {
        path.file_stem()
            .map_or("experiment".into(), |s| s.to_string_lossy().into_owned())
    });
    let mut plans = crate::plan::parse(&file.sections(path, text, kind), &config)?;
    no_world_without_robot(&file.obstacle, plans.robot.is_none(), &at)?;
    add_scene_obstacles(&file, path, kind, &mut plans, &mut config)?;
    let mut exp = Experiment {
        plan: plans.plan,
        source: path.to_path_buf(),
        name,
        config,
        plots: file.output.plots,
        robot: plans.robot,
        export: plans.export,
        clearance: plans.clearance,
        estimate: None,
    };
    // What the file asks of the machine, refused beyond the ceilings.
    let factors = budget_factors(&file, &learner, &exp);
    let estimate =
        crate::budget::check(&exp, &factors, ceilings, &|span| location(path, text, span))?;
    exp.estimate = Some(estimate);
    Ok(exp)
}

/// The text read once into the schema: a syntax error is "not valid TOML", a schema
/// error names the key; both at their line and column.
fn read_schema(path: &Path, text: &str) -> Result<File, InputError> {
    let at = |e: &toml::de::Error| {
        e.span()
            .map(|s| location(path, text, &s))
            .unwrap_or_else(|| path.display().to_string())
    };
    let document = toml::de::Deserializer::parse(text)
        .map_err(|e| InputError(format!("{}: not valid TOML: {}", at(&e), e.message())))?;
    File::deserialize(document).map_err(|e| InputError(format!("{}: {}", at(&e), e.message())))
}

/// Where a message is placed: a span of the file and the sentence.
type At<'a> = dyn Fn(&Range<usize>, String) -> InputError + 'a;

impl File {
    /// Each kind's own sections, for [`crate::plan::parse`].
    fn sections<'a>(
        &'a self,
        path: &'a Path,
        text: &'a str,
        kind: Kind,
    ) -> crate::sections::Sections<'a> {
        crate::sections::Sections {
            path,
            text,
            kind,
            robot: self.robot.as_ref(),
            demonstrations: self.demonstrations.as_ref(),
            imitation: self.imitation.as_ref(),
            scaling: self.scaling.as_ref(),
            joint: self.joint.as_ref(),
            plant: self.plant.as_ref(),
            speedup: self.speedup.as_ref(),
            orientation: self.orientation.as_ref(),
            export: self.export.as_ref(),
            promp: self.promp.as_ref(),
            contact: self.contact.as_ref(),
            executed: self.executed.as_ref(),
            clearance: self.clearance.as_ref(),
            obstacle: &self.obstacle,
        }
    }
}

/// The via-point learner's sections of a file whose kind reads them.
struct Learner<'a> {
    experiment: &'a ExperimentSection,
    dmp: &'a Dmp,
    basis_functions: &'a Spanned<usize>,
    tau: &'a Spanned<f64>,
    dt: &'a Spanned<f64>,
    task: &'a Task,
    start: &'a Spanned<Vec<f64>>,
    goal: &'a Spanned<Vec<f64>>,
    cost: Option<&'a Spanned<Cost>>,
    optimizer: &'a Optimizer,
    generations: &'a Spanned<u64>,
}

impl<'a> Learner<'a> {
    /// The sections and their keys that have no default, each required.
    fn of(file: &'a File, path: &Path, kind: Kind, at: &At<'_>) -> Result<Self, InputError> {
        let missing = |section: &str| {
            InputError(format!(
                "{}: missing section [{section}] (kind = \"{}\" learns a movement: it reads [dmp], [task] and [optimizer])",
                path.display(),
                kind.name()
            ))
        };
        let dmp = file.dmp.as_ref().ok_or_else(|| missing("dmp"))?;
        let task = file.task.as_ref().ok_or_else(|| missing("task"))?;
        let optimizer = file
            .optimizer
            .as_ref()
            .ok_or_else(|| missing("optimizer"))?;
        fn need<'v, T, U>(
            section: &Spanned<U>,
            value: &'v Option<T>,
            name: &str,
            key: &str,
            at: &At<'_>,
        ) -> Result<&'v T, InputError> {
            value.as_ref().ok_or_else(|| {
                at(
                    &section.span(),
                    format!("missing field `{key}` in [{name}]"),
                )
            })
        }
        let (d, t, o) = (dmp.get_ref(), task.get_ref(), optimizer.get_ref());
        Ok(Learner {
            experiment: &file.experiment,
            dmp: d,
            basis_functions: need(dmp, &d.basis_functions, "dmp", "basis_functions", at)?,
            tau: need(dmp, &d.tau, "dmp", "tau", at)?,
            dt: need(dmp, &d.dt, "dmp", "dt", at)?,
            task: t,
            start: need(task, &t.start, "task", "start", at)?,
            goal: need(task, &t.goal, "task", "goal", at)?,
            cost: file.cost.as_ref(),
            optimizer: o,
            generations: need(optimizer, &o.generations, "optimizer", "generations", at)?,
        })
    }

    /// `[dmp]`: the literature's gains unless given.
    fn dmp_config(&self) -> DmpConfig {
        let d = self.dmp;
        let mut dmp = DmpConfig::new(
            *self.basis_functions.get_ref(),
            *self.tau.get_ref(),
            *self.dt.get_ref(),
        );
        if let Some(v) = &d.alpha_z {
            dmp.alpha_z = *v.get_ref();
            dmp.beta_z = dmp.alpha_z / 4.0;
            dmp.alpha_x = dmp.alpha_z / 3.0;
        }
        if let Some(v) = &d.beta_z {
            dmp.beta_z = *v.get_ref();
        }
        if let Some(v) = &d.alpha_x {
            dmp.alpha_x = *v.get_ref();
        }
        dmp
    }

    /// `[task]` and `[cost]` as the library's task, unchecked.
    fn task(&self) -> ViaPointTask {
        let t = self.task;
        let dims = self.start.get_ref().len();
        let obstacle = if t.obstacles.is_empty() { 0.0 } else { 1e5 };
        ViaPointTask {
            start: self.start.get_ref().clone(),
            goal: self.goal.get_ref().clone(),
            goal_velocity: t
                .goal_velocity
                .as_ref()
                .map_or_else(|| vec![0.0; dims], |v| v.get_ref().clone()),
            via: t
                .via
                .iter()
                .map(|v| ViaPoint {
                    time: *v.get_ref().time.get_ref(),
                    position: v.get_ref().position.get_ref().clone(),
                })
                .collect(),
            dmp: self.dmp_config(),
            weights: match self.cost.map(Spanned::get_ref) {
                Some(c) => CostWeights {
                    goal: c.goal,
                    via: c.via,
                    final_velocity: c.final_velocity,
                    acceleration: c.acceleration,
                    jerk: c.jerk,
                    obstacle: c.obstacle.unwrap_or(obstacle),
                },
                None => CostWeights {
                    obstacle,
                    ..CostWeights::thesis()
                },
            },
            obstacles: t
                .obstacles
                .iter()
                .map(|o| PointObstacle {
                    position: o.get_ref().position.get_ref().clone(),
                    clearance: *o.get_ref().clearance.get_ref(),
                })
                .collect(),
        }
    }

    /// The task, checked by the library; its refusal placed at the key it names.
    fn checked_task(
        &self,
        path: &Path,
        kind: Kind,
        at: &At<'_>,
    ) -> Result<ViaPointTask, InputError> {
        let d: &'a Dmp = self.dmp;
        let task = self.task();
        if let Some(o) = self.task.obstacles.first()
            && !matches!(
                kind,
                Kind::Viapoint
                    | Kind::Scaling
                    | Kind::Imitation
                    | Kind::Promp
                    | Kind::ViapointPose
                    | Kind::ViapointExecuted
            )
        {
            return Err(at(
                &o.span(),
                format!(
                    "[[task.obstacles]] are read only by the kinds that learn tool positions (viapoint, scaling, imitation, promp, viapoint_pose, viapoint_executed); this file has kind = \"{}\"",
                    kind.name()
                ),
            ));
        }
        let Err(e) = task.validate() else {
            return Ok(task);
        };
        let span = match &e {
            LearnError::InvalidTask { field, .. } => self.locate_task_field(field),
            LearnError::Dmp(cps_dmp::DmpError::InvalidConfig { field, .. }) => {
                let gain = |v: &'a Option<Spanned<f64>>| v.as_ref().or(d.alpha_z.as_ref());
                Some(match *field {
                    "tau" => self.tau.span(),
                    "dt" => self.dt.span(),
                    "n_basis" => self.basis_functions.span(),
                    "alpha_z" => d.alpha_z.as_ref().map_or(self.tau.span(), |v| v.span()),
                    "beta_z" => gain(&d.beta_z).map_or(self.tau.span(), |v| v.span()),
                    _ => gain(&d.alpha_x).map_or(self.tau.span(), |v| v.span()),
                })
            }
            _ => None,
        };
        let msg = match &e {
            LearnError::Dmp(cps_dmp::DmpError::InvalidConfig { field, rule, value }) => {
                format!("[dmp] `{}` {rule} (got {value:?})", toml_name(field))
            }
            other => other.to_string(),
        };
        Err(match span {
            Some(s) => at(&s, msg),
            None => InputError(format!("{}: {msg}", path.display())),
        })
    }

    /// The learner's configuration: the checked task and `[optimizer]`'s settings, each
    /// checked by its owner (cps-learn), the file adding the place.
    fn config(
        &self,
        path: &Path,
        kind: Kind,
        seed_override: Option<u64>,
        at: &At<'_>,
    ) -> Result<ViaPointConfig, InputError> {
        let o = self.optimizer;
        let bad = |section: &'static str, span: Range<usize>| {
            move |e: cps_learn::BadSetting| at(&span, format!("[{section}] {e}"))
        };
        let reps = &self.experiment.repetitions;
        let repetitions = ViaPointConfig::check_repetitions(*reps.get_ref())
            .map_err(bad("experiment", reps.span()))?;
        let mut config = ViaPointConfig::new(self.checked_task(path, kind, at)?);
        config.solver = o.method;
        config.parametrisation = o.parametrisation;
        config.warm_start = o.warm_start;
        config.evaluation = o.evaluation;
        config.polish = o.polish;
        config.repetitions = repetitions;
        config.seed = seed_override.unwrap_or(self.experiment.seed);
        if let Some(s) = &o.sigma0 {
            config.sigma0 =
                ViaPointConfig::check_sigma0(*s.get_ref()).map_err(bad("optimizer", s.span()))?;
        }
        if let Some(p) = &o.population {
            let p = ViaPointConfig::check_population(*p.get_ref())
                .map_err(bad("optimizer", p.span()))?;
            config.population = Some(p);
        }
        let g = self.generations;
        config.generations =
            ViaPointConfig::check_generations(*g.get_ref()).map_err(bad("optimizer", g.span()))?;
        // A setting the file leaves out keeps the library's default (as in Python and the
        // studio): tol_fun 1e-9; 0 turns it off.
        if let Some(t) = &o.tol_fun {
            config.tol_fun =
                ViaPointConfig::check_tol_fun(*t.get_ref()).map_err(bad("optimizer", t.span()))?;
        }
        Ok(config)
    }
}

/// The sections a `kind = "contact"` file reads: it learns no via points, so `[dmp]`,
/// `[task]`, `[cost]` and `[optimizer]` are refused by name (and the other kinds'
/// sections by [`crate::plan::parse`]). The learner's configuration is the thesis's,
/// unused.
const CONTACT_READS: &str =
    "kind = \"contact\" reads [experiment], [robot], [contact], [output] and [[obstacle]]";

fn parse_contact(
    path: &Path,
    text: &str,
    file: &File,
    seed_override: Option<u64>,
    at: &At<'_>,
) -> Result<Experiment, InputError> {
    let learner = [
        ("dmp", file.dmp.as_ref().map(Spanned::span)),
        ("task", file.task.as_ref().map(Spanned::span)),
        ("cost", file.cost.as_ref().map(Spanned::span)),
        ("optimizer", file.optimizer.as_ref().map(Spanned::span)),
    ];
    if let Some((name, Some(span))) = learner.into_iter().find(|(_, s)| s.is_some()) {
        return Err(at(
            &span,
            format!("unknown field `{name}`: {CONTACT_READS}"),
        ));
    }
    let mut config = ViaPointConfig::new(ViaPointTask::thesis());
    config.seed = seed_override.unwrap_or(file.experiment.seed);
    let plans = crate::plan::parse(&file.sections(path, text, Kind::Contact), &config)?;
    no_world_without_robot(&file.obstacle, plans.robot.is_none(), at)?;
    let name = file.experiment.name.clone().unwrap_or_else(|| {
        path.file_stem()
            .map_or("contact".into(), |s| s.to_string_lossy().into_owned())
    });
    // What it needs: the recording (every tick, the loop's and the task's record).
    let seconds = match &plans.plan {
        crate::plan::KindPlan::Contact(c) => {
            let p = &c.plan;
            10.0 + p.search / p.speed + 3.0 * p.primitive.duration()
        }
        _ => 60.0,
    };
    let samples = seconds * 1000.0;
    Ok(Experiment {
        plan: plans.plan,
        source: path.to_path_buf(),
        name,
        config,
        plots: file.output.plots,
        robot: plans.robot,
        export: None,
        clearance: None,
        estimate: Some(crate::plan::Estimate {
            memory_bytes: samples * 600.0,
            work: samples * 5e4,
            samples,
            evaluations: 0.0,
            dims: 4,
            parameters: 0,
            population: 0,
        }),
    })
}

/// `[[obstacle]]` is the robot's world: without a `[robot]` it is refused, not ignored.
fn no_world_without_robot(
    obstacles: &[Spanned<cps_movement::scene::ObstacleEntry>],
    no_robot: bool,
    at: &At<'_>,
) -> Result<(), InputError> {
    match obstacles.first() {
        Some(o) if no_robot => Err(at(
            &o.span(),
            "[[obstacle]] places things in the robot's world, and this experiment has no [robot] (a point a learned path keeps clear of without a robot is a [[task.obstacles]])".into(),
        )),
        _ => Ok(()),
    }
}

/// The scene's obstacles join the task's (for the kinds that keep obstacles), each
/// checked against the start and goal; any obstacle asks for CMA-ES, since the exact
/// solver leaves the obstacle term out.
fn add_scene_obstacles(
    file: &File,
    path: &Path,
    kind: Kind,
    plans: &mut crate::plan::Plans,
    config: &mut ViaPointConfig,
) -> Result<(), InputError> {
    let scene_obstacles = plans
        .robot
        .as_ref()
        .map_or(&[][..], |r| r.obstacles.as_slice());
    if let Some(r) = plans.robot.as_ref().filter(|_| !scene_obstacles.is_empty()) {
        if !matches!(kind, Kind::Imitation | Kind::Promp | Kind::ViapointPose) {
            return Err(InputError(format!(
                "{}: the scene {} has obstacles, which kind = \"{}\" cannot keep (it learns joint or effort costs): use a scene without them",
                path.display(),
                r.scene,
                kind.name()
            )));
        }
        let task = &mut config.task;
        for (name, o) in scene_obstacles {
            cps_dmp::check_endpoints(
                &task.start,
                &task.goal,
                &o.position,
                o.clearance,
                &format!("obstacle `{name}` of the scene {}", r.scene),
            )
            .map_err(|e| InputError(format!("{}: {e}", path.display())))?;
            task.obstacles.push(o.clone());
        }
        match file.cost.as_ref().and_then(|c| c.get_ref().obstacle) {
            Some(0.0) => {
                return Err(InputError(format!(
                    "{}: [cost] `obstacle` is 0, so the scene's obstacles would be ignored: give it a weight (e.g. 1e5)",
                    path.display()
                )));
            }
            Some(_) => {}
            None => task.weights.obstacle = task.weights.obstacle.max(1e5),
        }
    }
    config
        .check_together()
        .map_err(|e| InputError(format!("{}: [optimizer] {e}", path.display())))?;
    Ok(())
}

/// The keys that scale an experiment's cost, with how far each is from an ordinary value.
fn budget_factors(file: &File, learner: &Learner<'_>, exp: &Experiment) -> crate::budget::Factors {
    let c = &exp.config;
    let o = learner.optimizer;
    let samples = (c.task.dmp.tau / c.task.dmp.dt).round() + 1.0;
    let mut keys = vec![
        (
            "[dmp] `dt`",
            format!(
                "{} (with tau = {} s)",
                learner.dt.get_ref(),
                learner.tau.get_ref()
            ),
            samples / 1001.0,
            learner.dt.span(),
        ),
        (
            "[dmp] `basis_functions`",
            learner.basis_functions.get_ref().to_string(),
            *learner.basis_functions.get_ref() as f64 / 25.0,
            learner.basis_functions.span(),
        ),
        (
            "[optimizer] `generations`",
            learner.generations.get_ref().to_string(),
            *learner.generations.get_ref() as f64 / 3000.0,
            learner.generations.span(),
        ),
        (
            "[experiment] `repetitions`",
            file.experiment.repetitions.get_ref().to_string(),
            *file.experiment.repetitions.get_ref() as f64 / 5.0,
            file.experiment.repetitions.span(),
        ),
        (
            "[task] `start`",
            format!("{} dimensions", c.task.start.len()),
            c.task.start.len() as f64 / 7.0,
            learner.start.span(),
        ),
    ];
    if let Some(p) = &o.population {
        keys.push((
            "[optimizer] `population`",
            p.get_ref().to_string(),
            *p.get_ref() as f64 / 96.0,
            p.span(),
        ));
    }
    if let Some(count) = file
        .demonstrations
        .as_ref()
        .and_then(|s| s.get_ref().count.as_ref())
    {
        keys.push((
            "[demonstrations] `count`",
            count.get_ref().to_string(),
            *count.get_ref() as f64 / 20.0,
            count.span(),
        ));
    }
    crate::budget::Factors { keys }
}

fn toml_name(field: &str) -> &str {
    if field == "n_basis" {
        "basis_functions"
    } else {
        field
    }
}

impl Learner<'_> {
    /// The span of a task field named like `via[2].time`, `start[1]` or `cost.via`.
    fn locate_task_field(&self, field: &str) -> Option<Range<usize>> {
        let t = self.task;
        let (head, index) = match field.split_once('[') {
            Some((h, rest)) => (
                h,
                rest.split(']').next().and_then(|i| i.parse::<usize>().ok()),
            ),
            None => (field, None),
        };
        Some(match head {
            "start" => self.start.span(),
            "goal" => self.goal.span(),
            "goal_velocity" => t.goal_velocity.as_ref()?.span(),
            "obstacles" => {
                let o = t.obstacles.get(index?)?;
                if field.ends_with(".clearance") {
                    o.get_ref().clearance.span()
                } else if field.contains(".position") {
                    o.get_ref().position.span()
                } else {
                    o.span()
                }
            }
            "via" => {
                let v = t.via.get(index?)?;
                if field.ends_with(".time") {
                    v.get_ref().time.span()
                } else if field.contains(".position") {
                    v.get_ref().position.span()
                } else {
                    v.span()
                }
            }
            _ if head.starts_with("cost") => self.cost?.span(),
            _ => return None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHIPPED: &str = include_str!("../../../experiments/viapoint.toml");

    fn check(text: &str) -> Result<Experiment, InputError> {
        parse(Path::new("x.toml"), text, None, &Ceilings::default())
    }

    #[test]
    fn the_shipped_experiment_parses_to_the_thesis_task() {
        let e = check(SHIPPED).unwrap();
        let thesis = ViaPointTask::thesis();
        assert_eq!(e.config.task.start, thesis.start);
        assert_eq!(e.config.task.goal, thesis.goal);
        assert_eq!(e.config.task.via, thesis.via);
        assert_eq!(e.config.task.weights, thesis.weights);
        assert_eq!(e.config.task.dmp, thesis.dmp);
    }

    /// The writer says every key: a configuration unlike the defaults in each of them
    /// reads back whole, and so does the shipped one; what a file cannot say is refused.
    #[test]
    fn a_written_viapoint_file_reads_back_to_the_same_experiment() {
        let mut c = check(SHIPPED).unwrap().config;
        let round = |c: &ViaPointConfig| {
            let text = viapoint_toml("my \"task\"", c, "saved\nby a test").unwrap();
            let back = check(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
            assert_eq!(back.name, "my \"task\"");
            assert!(text.starts_with("# saved\n# by a test\n"), "{text}");
            back.config
        };
        assert_eq!(round(&c), c);
        let t = &mut c.task;
        t.goal_velocity = vec![0.1, -0.2, 0.3];
        t.dmp.alpha_z = 30.0;
        t.dmp.beta_z = 7.0;
        t.dmp.alpha_x = 9.0;
        t.dmp.dt = 0.004;
        t.weights.obstacle = 123.456;
        t.weights.jerk = 1e-7;
        t.obstacles = vec![PointObstacle {
            position: vec![1.0, 0.1, 1.5],
            clearance: 0.05,
        }];
        c.parametrisation = Parametrisation::ThesisScaling;
        c.solver = Solver::LeastSquares;
        c.warm_start = true;
        c.evaluation = Evaluation::Rollout;
        c.sigma0 = 0.123;
        c.population = None;
        c.generations = 77;
        c.tol_fun = None;
        c.repetitions = 3;
        c.seed = 42;
        assert_eq!(round(&c), c);
        c.population = Some(10);
        c.tol_fun = Some(1e-4);
        c.solver = Solver::Cmaes;
        c.polish = true;
        assert_eq!(round(&c), c);
        let mut robust = c.clone();
        robust.task.dmp.formulation = cps_dmp::Formulation::GoalRobust;
        let e = viapoint_toml("x", &robust, "").unwrap_err().0;
        assert!(e.contains("not \"robust\""), "{e}");
        c.seed = u64::MAX;
        let e = viapoint_toml("x", &c, "").unwrap_err().0;
        assert!(e.contains("beyond TOML's integers"), "{e}");
        c.seed = 1;
        c.sigma0 = -1.0;
        let e = viapoint_toml("x", &c, "").unwrap_err().0;
        assert!(e.contains("`sigma0` must be"), "{e}");
    }

    /// One pass, one schema: a syntax error is not valid TOML; the keys a learning kind
    /// needs are required by it, named with their section.
    #[test]
    fn the_file_is_read_once_and_each_kind_requires_its_own() {
        let e = check("[experiment\nkind = 1").unwrap_err().0;
        assert!(
            e.starts_with("x.toml:1:") && e.contains("not valid TOML"),
            "{e}"
        );
        let e = check(&SHIPPED.replace("tau = 10.0", "")).unwrap_err().0;
        let line = SHIPPED.lines().position(|l| l == "[dmp]").unwrap() + 1;
        assert!(
            e.starts_with(&format!("x.toml:{line}:1: missing field `tau` in [dmp]")),
            "{e}"
        );
        let without = SHIPPED.replace("[optimizer]", "[optimizer_]");
        let e = check(&without).unwrap_err().0;
        assert!(e.contains("unknown field `optimizer_`"), "{e}");
        let cut = SHIPPED.find("[optimizer]").unwrap();
        let e = check(&SHIPPED[..cut]).unwrap_err().0;
        assert!(
            e.contains("missing section [optimizer] (kind = \"viapoint\""),
            "{e}"
        );
    }

    #[test]
    fn plots_are_on_unless_switched_off() {
        let without = SHIPPED.replace("[output]\nplots = true", "");
        assert!(!without.contains("[output]"));
        assert!(check(&without).unwrap().plots);
        let off = SHIPPED.replace("plots = true ", "plots = false ");
        assert!(!check(&off).unwrap().plots);
    }

    #[test]
    fn errors_name_line_column_and_rule() {
        let bad = SHIPPED.replace("tau = 10.0", "tau = -1.0");
        let msg = check(&bad).unwrap_err().0;
        let line = SHIPPED
            .lines()
            .position(|l| l.starts_with("tau = 10.0"))
            .unwrap()
            + 1;
        assert!(msg.starts_with(&format!("x.toml:{line}:")), "{msg}");
        assert!(msg.contains("tau") && msg.contains("> 0"), "{msg}");
    }
}
