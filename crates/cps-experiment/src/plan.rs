//! The plan of a run: an experiment's sections checked against its kind and turned into
//! one [`Experiment`] — the learner's configuration, the robot, and the plan of the kind's
//! own sections (each parsed by its module in `sections/`); what it is in words for
//! `cps-cli check`.

use std::ops::Range;
use std::path::Path;

use cps_learn::ViaPointConfig;
use toml::Spanned;

use crate::InputError;
use crate::robots::{BackendChoice, RobotChoice};
pub use crate::sections::Kind;
use crate::sections::Sections;
pub use crate::sections::energy::{EnergyPlan, PlantSection};
pub use crate::sections::executed::{ExecutedPlan, ExecutedSection};
pub use crate::sections::imitation::{DemonstrationsSection, ImitationPlan, ImitationSection};
pub use crate::sections::joint::{JointPlan, JointSection, LearnOn};
pub use crate::sections::pose::{OrientationSection, PosePlan};
pub use crate::sections::promp::{ProMpPlan, ProMpSection, ProMpVia};
pub use crate::sections::scaling::{ScalingPlan, ScalingSection};

/// A parsed and validated experiment: its kind with that kind's own plan ([`KindPlan`]),
/// the learner's configuration, the robot and what the run needs.
#[derive(Debug, Clone)]
pub struct Experiment {
    /// What the file runs, with the plan of its kind's own sections.
    pub plan: KindPlan,
    /// The file it was read from (names it in messages).
    pub source: std::path::PathBuf,
    /// Experiment name (file stem unless given).
    pub name: String,
    /// The learner's configuration.
    pub config: ViaPointConfig,
    /// Whether to draw plots.
    pub plots: bool,
    /// The robot and backend (`[robot]`), for kinds that execute.
    pub robot: Option<RobotChoice>,
    /// Retiming and export of the robot's movement (`[export]`, kinds with a robot).
    pub export: Option<cps_movement::export::ExportPlan>,
    /// The clearance learning keeps (`[clearance]`, kinds that learn a robot's movement).
    pub clearance: Option<crate::sections::clearance::ClearancePlan>,
    /// What the run needs (memory, work), estimated when the file was read.
    pub estimate: Option<Estimate>,
}

/// An experiment kind with the checked plan of its own sections: one variant per kind,
/// so a kind's plan exists exactly when the file is of that kind. A new kind is a variant
/// here, its [`Kind`] word, its sections' module in `sections/`, its run in `kinds/`.
#[derive(Debug, Clone)]
pub enum KindPlan {
    /// Via-point learning (`kind = "viapoint"`): the learner's configuration is all.
    Viapoint,
    /// The imitation pipeline's settings (`kind = "imitation"`).
    Imitation(ImitationPlan),
    /// The parametrisations compared (`kind = "scaling"`).
    Scaling(ScalingPlan),
    /// The limit penalties (`kind = "viapoint_joint"`).
    ViapointJoint(JointPlan),
    /// The plant and its effort term (`kind = "viapoint_energy"`).
    ViapointEnergy(EnergyPlan),
    /// The orientation targets (`kind = "viapoint_pose"`).
    ViapointPose(PosePlan),
    /// The demonstrations imitated, and the ProMP and its via point (`kind = "promp"`).
    Promp(ImitationPlan, ProMpPlan),
    /// The executed cost's own weight (`kind = "viapoint_executed"`).
    ViapointExecuted(ExecutedPlan),
    /// The surface, the force profile and the controller (`kind = "contact"`; boxed: it
    /// is the largest plan by far).
    Contact(Box<crate::sections::contact::ContactSpec>),
}

impl KindPlan {
    /// Its kind.
    pub fn kind(&self) -> Kind {
        match self {
            KindPlan::Viapoint => Kind::Viapoint,
            KindPlan::Imitation(_) => Kind::Imitation,
            KindPlan::Scaling(_) => Kind::Scaling,
            KindPlan::ViapointJoint(_) => Kind::ViapointJoint,
            KindPlan::ViapointEnergy(_) => Kind::ViapointEnergy,
            KindPlan::ViapointPose(_) => Kind::ViapointPose,
            KindPlan::Promp(..) => Kind::Promp,
            KindPlan::ViapointExecuted(_) => Kind::ViapointExecuted,
            KindPlan::Contact(_) => Kind::Contact,
        }
    }
}

impl Experiment {
    /// What the file runs.
    pub fn kind(&self) -> Kind {
        self.plan.kind()
    }

    /// The imitation pipeline's settings: the imitation and ProMP kinds'.
    pub fn imitation(&self) -> Option<&ImitationPlan> {
        match &self.plan {
            KindPlan::Imitation(p) | KindPlan::Promp(p, _) => Some(p),
            _ => None,
        }
    }

    /// The parametrisations compared, for the scaling kind.
    pub fn scaling(&self) -> Option<&ScalingPlan> {
        match &self.plan {
            KindPlan::Scaling(p) => Some(p),
            _ => None,
        }
    }

    /// The limit penalties, for the joint kind.
    pub fn joint(&self) -> Option<JointPlan> {
        match &self.plan {
            KindPlan::ViapointJoint(p) => Some(*p),
            _ => None,
        }
    }

    /// The plant, for the energy kind.
    pub fn energy(&self) -> Option<&EnergyPlan> {
        match &self.plan {
            KindPlan::ViapointEnergy(p) => Some(p),
            _ => None,
        }
    }

    /// The orientation targets, for the pose kind.
    pub fn pose(&self) -> Option<&PosePlan> {
        match &self.plan {
            KindPlan::ViapointPose(p) => Some(p),
            _ => None,
        }
    }

    /// The ProMP and its via point, for the ProMP kind.
    pub fn promp(&self) -> Option<&ProMpPlan> {
        match &self.plan {
            KindPlan::Promp(_, p) => Some(p),
            _ => None,
        }
    }

    /// The contact task, for the contact kind.
    pub fn contact(&self) -> Option<&crate::sections::contact::ContactSpec> {
        match &self.plan {
            KindPlan::Contact(p) => Some(p),
            _ => None,
        }
    }
}

/// What a run would need (computed by [`crate::budget`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Peak memory, bytes.
    pub memory_bytes: f64,
    /// Multiply-adds.
    pub work: f64,
    /// Samples of one rollout.
    pub samples: f64,
    /// Cost evaluations at the full budget.
    pub evaluations: f64,
    /// Dimensions learned (task or joints).
    pub dims: usize,
    /// Parameters searched.
    pub parameters: usize,
    /// Population per generation.
    pub population: usize,
}

/// The parsed plans of [`parse`].
pub(crate) struct Plans {
    pub robot: Option<RobotChoice>,
    pub plan: KindPlan,
    pub export: Option<cps_movement::export::ExportPlan>,
    pub clearance: Option<crate::sections::clearance::ClearancePlan>,
}

/// Checks that each section belongs to the kind and parses them.
pub(crate) fn parse(file: &Sections<'_>, learner: &ViaPointConfig) -> Result<Plans, InputError> {
    // A pose experiment executes when it names a robot; the other kinds that execute
    // always do.
    let executes = matches!(
        file.kind,
        Kind::Imitation
            | Kind::ViapointJoint
            | Kind::Promp
            | Kind::ViapointExecuted
            | Kind::Contact
    ) || (file.kind == Kind::ViapointPose && file.robot.is_some());
    file.refuse_other_kinds_sections(executes)?;
    let contact = match (file.kind, file.contact) {
        (Kind::Contact, Some(c)) => {
            let dir = file.path.parent().unwrap_or(Path::new("."));
            Some(c.get_ref().plan(dir, &|span, m| file.err(span, m))?)
        }
        (Kind::Contact, None) => {
            return Err(InputError(format!(
                "{}: kind = \"contact\" needs a [contact] section (the surface's approach and the force profile)",
                file.path.display()
            )));
        }
        _ => None,
    };
    let export = match file.export {
        Some(e) => Some(e.get_ref().plan(&|span, m| file.err(span, m))?),
        None => None,
    };
    let robot = if executes {
        Some(file.robot_choice(learner.task.dmp.dt)?)
    } else {
        None
    };
    if file.kind == Kind::Contact
        && !matches!(
            robot.as_ref().map(|r| &r.backend),
            Some(BackendChoice::Franka { .. })
        )
    {
        let at = file.robot.map_or(0..0, |r| r.span());
        return Err(file.err(
            &at,
            "kind = \"contact\" drives a Franka in torque mode: give [robot] backend = \"franka\" with its host".into(),
        ));
    }
    let plan = file.kind_plan(learner, robot.as_ref(), contact)?;
    let clearance = file.clearance_plan(robot.as_ref())?;
    Ok(Plans {
        robot,
        plan,
        export,
        clearance,
    })
}

/// A section's place, its name, the kinds that read it and those kinds in words.
type Owners<'a> = (Option<Range<usize>>, &'static str, &'a [Kind], &'static str);

impl Sections<'_> {
    /// Refuses, by name, a section that another kind reads (`executes`: whether this
    /// experiment has a robot, which `[robot]` and `[export]` need).
    fn refuse_other_kinds_sections(&self, executes: bool) -> Result<(), InputError> {
        use Kind::*;
        if let Some(s) = self.speedup {
            return Err(self.err(
                &s.span(),
                "[speedup] is no longer part of an experiment (a timing is a benchmark, and it made the run many times longer): remove the section; `cargo bench --bench core -- energy_population` measures the parallel speed-up".into(),
            ));
        }
        let with_robot: &[Kind] = if executes { &[self.kind] } else { &[] };
        // Each section, the kinds that read it, and those kinds in words.
        let owners: [Owners<'_>; 11] = [
            (
                self.robot.map(Spanned::span),
                "robot",
                with_robot,
                "kind = \"imitation\", \"promp\", \"viapoint_joint\", \"viapoint_pose\", \"viapoint_executed\" and \"contact\"",
            ),
            (
                self.contact.map(Spanned::span),
                "contact",
                &[Contact],
                "kind = \"contact\"",
            ),
            (
                self.executed.map(Spanned::span),
                "executed",
                &[ViapointExecuted],
                "kind = \"viapoint_executed\"",
            ),
            (
                self.export.map(Spanned::span),
                "export",
                with_robot,
                "experiments with a robot (kind = \"imitation\", \"viapoint_joint\", or \"viapoint_pose\" with [robot])",
            ),
            (
                self.joint.map(Spanned::span),
                "joint",
                &[ViapointJoint],
                "kind = \"viapoint_joint\"",
            ),
            (
                self.plant.map(Spanned::span),
                "plant",
                &[ViapointEnergy],
                "kind = \"viapoint_energy\"",
            ),
            (
                self.demonstrations.map(Spanned::span),
                "demonstrations",
                &[Imitation, Promp],
                "kind = \"imitation\" and \"promp\"",
            ),
            (
                self.imitation.map(Spanned::span),
                "imitation",
                &[Imitation, Promp],
                "kind = \"imitation\" and \"promp\"",
            ),
            (
                self.promp.map(Spanned::span),
                "promp",
                &[Promp],
                "kind = \"promp\"",
            ),
            (
                self.scaling.map(Spanned::span),
                "scaling",
                &[Scaling],
                "kind = \"scaling\"",
            ),
            (
                self.orientation.map(Spanned::span),
                "orientation",
                &[ViapointPose],
                "kind = \"viapoint_pose\"",
            ),
        ];
        for (span, section, kinds, words) in owners {
            if let Some(span) = span
                && !kinds.contains(&self.kind)
            {
                return Err(self.err(
                    &span,
                    format!(
                        "[{section}] is read only by {words}; this file has kind = \"{}\" (remove the section or change [experiment] kind)",
                        self.kind.name()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The kind's own plan from its sections.
    fn kind_plan(
        &self,
        learner: &ViaPointConfig,
        robot: Option<&RobotChoice>,
        contact: Option<crate::sections::contact::ContactSpec>,
    ) -> Result<KindPlan, InputError> {
        Ok(match self.kind {
            Kind::Viapoint => KindPlan::Viapoint,
            Kind::Imitation => KindPlan::Imitation(self.imitation_plan(learner, robot)?),
            Kind::Promp => {
                let imitation = self.imitation_plan(learner, robot)?;
                let promp = self.promp_plan(learner.task.dmp.tau, Some(&imitation))?;
                KindPlan::Promp(imitation, promp)
            }
            Kind::Scaling => KindPlan::Scaling(self.scaling_plan()?),
            Kind::ViapointJoint => {
                let dynamics =
                    matches!(robot.map(|r| &r.backend), Some(BackendChoice::Dynamics(_)));
                KindPlan::ViapointJoint(self.joint_plan(dynamics)?)
            }
            Kind::ViapointEnergy => KindPlan::ViapointEnergy(self.energy_plan(learner)?),
            Kind::ViapointPose => match self.orientation {
                Some(o) => KindPlan::ViapointPose(self.pose_plan(o, learner)?),
                None => {
                    return Err(InputError(format!(
                        "{}: kind = \"viapoint_pose\" needs an [orientation] section (start, goal, one orientation per via point)",
                        self.path.display()
                    )));
                }
            },
            Kind::ViapointExecuted => KindPlan::ViapointExecuted(self.executed_plan(learner)?),
            Kind::Contact => KindPlan::Contact(Box::new(
                contact.expect("a contact file has its plan (parse reads it first)"),
            )),
        })
    }
}

impl Experiment {
    /// The plan in words, for `check`: what is learned, by which search with what budget,
    /// and where it is executed.
    pub fn describe(&self) -> Vec<String> {
        if let Some(c) = self.contact() {
            return c.describe(self.robot.as_ref().map(|r| r.describe()));
        }
        let task = &self.config.task;
        let bases = task.dmp.n_basis;
        let (dims, what) = match (self.kind(), &self.robot) {
            (Kind::ViapointJoint, Some(r)) => (r.setup.chain.dof(), "joint DMPs"),
            _ => (task.start.len(), "position DMPs"),
        };
        let mut learns = format!(
            "learns: {dims} {what} × {bases} basis functions = {} weights, through {} via point(s) in {} s",
            dims * bases,
            task.via.len(),
            task.dmp.tau
        );
        if self.kind() == Kind::ViapointPose {
            learns.push_str(&format!(
                ", and 1 orientation DMP × {bases} (3 × {bases} weights)"
            ));
        }
        let mut lines = vec![learns, format!("search: {}", self.search_words(dims))];
        if let Some(r) = &self.robot {
            lines.push(format!(
                "robot: {} joints, scene {}, executed on the {} backend",
                r.setup.chain.dof(),
                r.scene,
                r.describe()
            ));
        }
        lines.extend(self.clearance_words());
        lines.extend(self.export_words());
        lines
    }

    /// CMA-ES's budget in words, for `dims` learned dimensions.
    fn cmaes_words(&self, dims: usize, generations: u64, repetitions: usize) -> String {
        let c = &self.config;
        let bases = c.task.dmp.n_basis;
        let population = c
            .population
            .unwrap_or_else(|| cps_cmaes::Parameters::default_lambda((dims * bases).max(1)));
        format!(
            "CMA-ES{}, population {population}, up to {generations} generations × {repetitions} repetition(s){}",
            if self.kind() == Kind::Scaling {
                String::new()
            } else {
                format!(" in the {} search space", c.parametrisation.name())
            },
            if c.warm_start {
                ", warm-started at the exact optimum"
            } else {
                ""
            }
        )
    }

    /// How the kind searches, in words.
    fn search_words(&self, dims: usize) -> String {
        let c = &self.config;
        let cmaes = |generations, repetitions| self.cmaes_words(dims, generations, repetitions);
        match (self.kind(), c.solver) {
            (Kind::Imitation | Kind::Promp, solver) => self.imitation_words(solver, dims),
            (Kind::Viapoint, cps_learn::Solver::Exact) => {
                "the exact least-squares optimum (no search)".to_string()
            }
            (Kind::Scaling, _) => {
                let arms = self.scaling().map_or(Vec::new(), |s| {
                    s.compare.iter().map(|p| p.name()).collect::<Vec<_>>()
                });
                format!(
                    "{}, for each of {} search spaces ({})",
                    cmaes(c.generations, c.repetitions),
                    arms.len(),
                    arms.join(", ")
                )
            }
            (Kind::ViapointPose, _) => format!(
                "{}, then the orientation the same way",
                cmaes(c.generations, 1)
            ),
            (Kind::ViapointEnergy, cps_learn::Solver::Exact) => {
                "the exact least-squares optimum through the plant (no search)".to_string()
            }
            (Kind::ViapointEnergy, _) => format!(
                "{}; judged against the exact optimum through the plant",
                cmaes(c.generations, 1)
            ),
            (Kind::ViapointJoint, solver) => {
                let model = match solver {
                    cps_learn::Solver::Exact => {
                        "the exact optimum of the IK way points".to_string()
                    }
                    cps_learn::Solver::LeastSquares => format!(
                        "Levenberg–Marquardt on the model, up to {} iterations",
                        c.generations
                    ),
                    cps_learn::Solver::Cmaes => cmaes(c.generations, c.repetitions),
                };
                match self.joint().map(|j| j.learn_on) {
                    Some(LearnOn::Execution) => format!(
                        "{model}; then on the executions: Levenberg–Marquardt, up to {} iterations, each candidate run on the robot with dynamics ({} s, a Jacobian of {} runs kept while its steps gain)",
                        c.generations,
                        c.task.dmp.tau,
                        dims * c.task.dmp.n_basis
                    ),
                    _ => model,
                }
            }
            (_, _) => cmaes(c.generations, c.repetitions),
        }
    }

    /// How imitation and ProMP experiments get and learn their demonstrations, in words.
    fn imitation_words(&self, solver: cps_learn::Solver, dims: usize) -> String {
        let c = &self.config;
        let p = self.imitation();
        let learned = if let Some(p) = p.filter(|p| !p.takes.is_empty()) {
            let takes: Vec<String> = p.takes.iter().map(|t| t.name.clone()).collect();
            format!(
                "{} given demonstrations ({}), each checked and executed from its own start; their mean imitated by ridge and jerk-regularised ridge with {} basis functions over {:.2} s",
                takes.len(),
                takes.join(", "),
                p.dmp.n_basis,
                p.dmp.tau
            )
        } else {
            format!(
                "{} demonstrations (via points moved by N(0, {}²) m), each learned by {}; their mean imitated by ridge and jerk-regularised ridge with {} basis functions",
                p.map_or(0, |p| p.demonstrations),
                p.map_or(0.0, |p| p.via_std),
                match solver {
                    cps_learn::Solver::Exact => "the exact solver (no search)".to_string(),
                    cps_learn::Solver::LeastSquares => "Levenberg–Marquardt".to_string(),
                    cps_learn::Solver::Cmaes => self.cmaes_words(dims, c.generations, 1),
                },
                p.map_or(0, |p| p.dmp.n_basis)
            )
        };
        learned
            + &self.promp().map_or(String::new(), |p| {
                format!(
                    "; then a ProMP of the executed demonstrations ({} basis functions per axis) conditioned on {:?} m at {} s, its mean executed",
                    p.bases, p.position, p.time
                )
            })
    }

    /// The clearance kept, in words (none without a `[clearance]`).
    fn clearance_words(&self) -> Option<String> {
        let k = self.clearance.as_ref()?;
        let c = &k.clearance;
        let how = match self.kind() {
            Kind::ViapointJoint => "in the cost".to_string(),
            Kind::ViapointExecuted => "in every execution's cost".to_string(),
            _ => format!(
                "after learning, on the model (Levenberg–Marquardt, up to {} iterations)",
                k.iterations
            ),
        };
        let itself = if c.self_distance == c.distance {
            String::new()
        } else {
            format!(" ({:.1} mm between two of its own)", c.self_distance * 1e3)
        };
        Some(format!(
            "clearance: {:.1} mm between every pair of the robot's {} collision shapes and its world's {} obstacle(s){itself}, weight {:e} per m², {how}",
            c.distance * 1e3,
            c.shapes.bodies().len(),
            c.shapes.obstacles().len(),
            c.weight
        ))
    }

    /// What is exported, in words (none without an `[export]`).
    fn export_words(&self) -> Option<String> {
        let e = self.export.as_ref()?;
        let formats: Vec<&str> = e.formats.iter().map(|f| f.file_name()).collect();
        Some(format!(
            "export: {}{}",
            e.retime
                .map_or("the movement's own timing".to_string(), |m| format!(
                    "the movement retimed ({}) at 1 kHz",
                    m.name()
                )),
            if formats.is_empty() {
                String::new()
            } else {
                format!(", written as {}", formats.join(", "))
            }
        ))
    }

    /// What `cps-cli check` prints for this experiment run on `threads` threads: `ok` and
    /// the kind, what it learns and searches, where it executes and exports, the robot's
    /// reach (checked as the run would, so an unreachable point is an error here) and the
    /// estimate of memory and time.
    pub fn check_lines(&self, threads: usize) -> Result<Vec<String>, InputError> {
        // A contact task has no way points to reach: the search finds its surface.
        let reach = if self.kind() == Kind::Contact {
            None
        } else {
            self.check_reach()?
        };
        let mut lines = vec![format!(
            "{}: ok (kind {})",
            self.source.display(),
            self.kind().name()
        )];
        for line in self.describe().into_iter().chain(reach) {
            lines.push(format!("  {line}"));
        }
        if let (Some(c), Some(e)) = (self.contact(), &self.estimate) {
            // A contact task runs in the robot's time, not the machine's.
            lines.push(format!(
                "  runs ≈ {:.0} s on the robot (longer while the force lags its profile), recording ≈ {}",
                c.nominal_seconds(),
                cps_outcome::source::bytes(e.memory_bytes)
            ));
        } else if let Some(e) = &self.estimate {
            lines.push(format!("  {}", e.describe(threads)));
        }
        Ok(lines)
    }

    /// Whether the robot can reach the start, every via point and the goal within its
    /// joint limits (kinds with a robot); the sentence names the first point it cannot,
    /// as the run would.
    pub fn check_reach(&self) -> Result<Option<String>, InputError> {
        let Some(r) = &self.robot else {
            return Ok(None);
        };
        match cps_learn::check_way_points(&self.config.task, &r.setup) {
            Ok(_) => Ok(Some(format!(
                "reach: the start, {} via point(s) and the goal are reachable within the joint limits",
                self.config.task.via.len()
            ))),
            Err(e) => Err(InputError(format!("{}: {e}", self.source.display()))),
        }
    }
}
