//! The plan of a run: the experiment-file sections of the kinds beyond plain via-point
//! learning (`[demonstrations]`, `[imitation]`, `[scaling]`, `[joint]`, `[plant]`,
//! `[orientation]`) turned into checked plans. The robot (`[robot]`) is chosen in
//! [`crate::robots`].

use std::ops::Range;
use std::path::Path;

use cps_dmp::{DmpConfig, Lambda};
use cps_learn::{Parametrisation, ViaPointConfig};
use serde::Deserialize;
use toml::Spanned;

use crate::InputError;
use crate::robots::{BackendChoice, RobotChoice, RobotSection};
use crate::source::location;

/// What an experiment file runs (`[experiment] kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// Via-point learning (the default).
    #[default]
    Viapoint,
    /// The thesis's imitation pipeline on a robot backend.
    Imitation,
    /// Parametrisations compared over repetitions (the thesis's scaled vs not scaled).
    Scaling,
    /// Via-point learning with one DMP per joint, judged in task space.
    ViapointJoint,
    /// Via-point learning through a simulated plant with a control-effort term.
    ViapointEnergy,
    /// Via-point learning of position and orientation.
    ViapointPose,
    /// The imitation pipeline's executed demonstrations as a ProMP: its band, conditioned
    /// on a new via point, the conditioned mean executed.
    Promp,
    /// Via-point learning whose cost is measured on the robot: every CMA-ES candidate is
    /// executed (on a pool of simulators) and judged by its recording.
    ViapointExecuted,
    /// A movement that touches, on a Franka in torque mode: approach a surface until
    /// contact, follow a force profile along it, release (`[contact]`).
    Contact,
}

impl Kind {
    /// The name used in files and summaries.
    pub fn name(&self) -> &'static str {
        match self {
            Kind::Viapoint => "viapoint",
            Kind::Imitation => "imitation",
            Kind::Scaling => "scaling",
            Kind::ViapointJoint => "viapoint_joint",
            Kind::ViapointEnergy => "viapoint_energy",
            Kind::ViapointPose => "viapoint_pose",
            Kind::Promp => "promp",
            Kind::ViapointExecuted => "viapoint_executed",
            Kind::Contact => "contact",
        }
    }
}

/// A parsed and validated experiment of one kind (`kind`), with the plan of its kind's
/// own sections.
#[derive(Debug, Clone)]
pub struct Experiment {
    /// What the file runs.
    pub kind: Kind,
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
    /// The imitation pipeline's settings (`kind = "imitation"`).
    pub imitation: Option<ImitationPlan>,
    /// The parametrisations compared (`kind = "scaling"`).
    pub scaling: Option<ScalingPlan>,
    /// The limit penalties (`kind = "viapoint_joint"`).
    pub joint: Option<JointPlan>,
    /// The plant and the speed-up measurement (`kind = "viapoint_energy"`).
    pub energy: Option<EnergyPlan>,
    /// The orientation targets (`kind = "viapoint_pose"`).
    pub pose: Option<PosePlan>,
    /// The ProMP and its via point (`kind = "promp"`).
    pub promp: Option<ProMpPlan>,
    /// The executed cost's own weight (`kind = "viapoint_executed"`).
    pub executed: Option<ExecutedPlan>,
    /// The surface, the force profile and the controller (`kind = "contact"`).
    pub contact: Option<crate::contact_section::ContactSpec>,
    /// Retiming and export of the robot's movement (`[export]`, kinds with a robot).
    pub export: Option<crate::export::ExportPlan>,
    /// What the run needs (memory, work), estimated when the file was read.
    pub estimate: Option<Estimate>,
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

/// A limit in words: plain for ordinary magnitudes, exponent form for extreme ones.
fn number(x: f64) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// `[executed]` of `kind = "viapoint_executed"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExecutedSection {
    tracking: Option<Spanned<f64>>,
    speed_usage: Option<Spanned<f64>>,
}

/// The checked `[executed]` section: the weights the executed cost adds to `[cost]`'s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExecutedPlan {
    /// Squared tracking errors (default 1e5, as a via point's) and squared peak joint
    /// speed usages (default 0: off).
    pub weights: cps_learn::ExecutedWeights,
}

/// `[demonstrations]` of `kind = "imitation"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DemonstrationsSection {
    pub(crate) count: Option<Spanned<usize>>,
    via_std: Option<Spanned<f64>>,
    /// Motion-capture takes (C3D, Motive CSV), relative to the experiment file: they are
    /// the demonstrations, instead of `count` learned ones.
    takes: Option<Spanned<Vec<String>>>,
    /// How each take becomes a demonstration (as `cps-cli mocap import`).
    markers: Option<Spanned<Vec<String>>>,
    rigid_body: Option<Spanned<String>>,
    origin: Option<Spanned<String>>,
    axes: Option<Spanned<Vec<String>>>,
    to_robot: Option<Spanned<String>>,
    y_up: Option<Spanned<bool>>,
    max_gap: Option<Spanned<usize>>,
    cutoff: Option<Spanned<f64>>,
    outlier_mm: Option<Spanned<f64>>,
}

/// `[imitation]` of `kind = "imitation"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImitationSection {
    basis_functions: Option<Spanned<usize>>,
    tau: Option<Spanned<f64>>,
    dt: Option<Spanned<f64>>,
    ridge_lambda: Option<Spanned<f64>>,
    jerk_lambda: Option<Spanned<toml::Value>>,
}

/// The imitation pipeline's settings beyond the learner and the robot.
#[derive(Debug, Clone, PartialEq)]
pub struct ImitationPlan {
    /// Number of demonstrations.
    pub demonstrations: usize,
    /// Demonstrations read from motion-capture takes (`[demonstrations] takes`), in the
    /// task's frame; when there are any they replace the learned ones.
    pub takes: Vec<cps_learn::GivenDemonstration>,
    /// Via-point perturbation per axis, metres.
    pub via_std: f64,
    /// The imitating DMP.
    pub dmp: DmpConfig,
    /// λ of ridge.
    pub ridge_lambda: Lambda,
    /// λ of jerk-regularised ridge.
    pub jerk_lambda: Lambda,
}

/// `[promp]` of `kind = "promp"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProMpSection {
    basis_functions: Option<Spanned<usize>>,
    via: Spanned<ProMpVia>,
}

/// `[promp.via]`: the new via point.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProMpVia {
    time: Spanned<f64>,
    position: Spanned<Vec<f64>>,
    #[serde(default)]
    std: Option<Spanned<f64>>,
}

/// A ProMP experiment's settings beyond the imitation pipeline's.
#[derive(Debug, Clone, PartialEq)]
pub struct ProMpPlan {
    /// Basis functions per dimension.
    pub bases: usize,
    /// The via point's time (s, within the demonstrations' mean duration).
    pub time: f64,
    /// Its position (m).
    pub position: Vec<f64>,
    /// Its standard deviation (m; 0: exact).
    pub std: f64,
}

/// `[scaling]` of `kind = "scaling"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScalingSection {
    compare: Option<Spanned<Vec<Parametrisation>>>,
}

/// The parametrisations a scaling experiment compares.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalingPlan {
    /// In order; each runs the experiment's repetitions.
    pub compare: Vec<Parametrisation>,
}

/// `[joint]` of `kind = "viapoint_joint"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSection {
    limit_weight: Option<Spanned<f64>>,
    speed_limit_weight: Option<Spanned<f64>>,
}

/// The limit penalties of a joint-space experiment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointPlan {
    /// Weight of the squared position-limit excess.
    pub limit_weight: f64,
    /// Weight of the squared speed-limit excess.
    pub speed_limit_weight: f64,
}

/// `[plant]` of `kind = "viapoint_energy"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantSection {
    mass: Option<Spanned<f64>>,
    kp: Option<Spanned<f64>>,
    kv: Option<Spanned<f64>>,
    substeps: Option<Spanned<usize>>,
    effort_weight: Option<Spanned<f64>>,
}

/// The plant of an effort experiment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyPlan {
    /// The plant and controller.
    pub plant: cps_learn::PointMassPlant,
    /// Weight of the control effort.
    pub effort_weight: f64,
}

/// `[orientation]` of `kind = "viapoint_pose"`: each orientation is a unit quaternion
/// `[x, y, z, w]` or roll, pitch, yaw `[r, p, y]` in radians (URDF: about the fixed x, y,
/// z axes); a via orientation `[]` is free.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrientationSection {
    start: Spanned<Vec<f64>>,
    goal: Spanned<Vec<f64>>,
    #[serde(default)]
    via: Vec<Spanned<Vec<f64>>>,
    sigma0: Option<Spanned<f64>>,
    method: Option<Spanned<cps_learn::Solver>>,
}

/// The orientation targets of a pose experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct PosePlan {
    /// Start orientation.
    pub start: nalgebra::UnitQuaternion<f64>,
    /// Goal orientation.
    pub goal: nalgebra::UnitQuaternion<f64>,
    /// One per via point; `None` = free.
    pub via: Vec<Option<nalgebra::UnitQuaternion<f64>>>,
    /// Initial CMA-ES step of the orientation part, radians.
    pub sigma0: f64,
    /// How the orientation part is learned (CMA-ES by default).
    pub method: cps_learn::Solver,
}

/// The optional sections of a file, with what is needed to name places in errors.
pub(crate) struct Sections<'a> {
    pub path: &'a Path,
    pub text: &'a str,
    pub kind: Kind,
    pub robot: Option<&'a Spanned<RobotSection>>,
    pub demonstrations: Option<&'a Spanned<DemonstrationsSection>>,
    pub imitation: Option<&'a Spanned<ImitationSection>>,
    pub scaling: Option<&'a Spanned<ScalingSection>>,
    pub joint: Option<&'a Spanned<JointSection>>,
    pub plant: Option<&'a Spanned<PlantSection>>,
    /// `[speedup]`, no longer part of an experiment: refused with where it went.
    pub speedup: Option<&'a Spanned<toml::Value>>,
    pub orientation: Option<&'a Spanned<OrientationSection>>,
    pub export: Option<&'a Spanned<crate::export::ExportSection>>,
    pub promp: Option<&'a Spanned<ProMpSection>>,
    pub executed: Option<&'a Spanned<ExecutedSection>>,
    pub contact: Option<&'a Spanned<crate::contact_section::ContactSection>>,
}

/// The parsed plans of [`Sections::parse`].
pub(crate) struct Plans {
    pub robot: Option<RobotChoice>,
    pub imitation: Option<ImitationPlan>,
    pub scaling: Option<ScalingPlan>,
    pub joint: Option<JointPlan>,
    pub energy: Option<EnergyPlan>,
    pub pose: Option<PosePlan>,
    pub promp: Option<ProMpPlan>,
    pub executed: Option<ExecutedPlan>,
    pub export: Option<crate::export::ExportPlan>,
    pub contact: Option<crate::contact_section::ContactSpec>,
}

impl Sections<'_> {
    pub(crate) fn err(&self, span: &Range<usize>, msg: String) -> InputError {
        InputError(format!("{}: {msg}", location(self.path, self.text, span)))
    }

    /// A value that must lie in `[lo, hi]` (and be finite), with its unit for the message.
    pub(crate) fn within(
        &self,
        v: &Spanned<f64>,
        what: &str,
        lo: f64,
        hi: f64,
        unit: &str,
    ) -> Result<f64, InputError> {
        let x = *v.get_ref();
        if x.is_finite() && (lo..=hi).contains(&x) {
            Ok(x)
        } else if lo == 0.0 {
            Err(self.err(
                &v.span(),
                format!(
                    "{what} must be finite, ≥ 0 and at most {}{unit} (got {x:?})",
                    number(hi)
                ),
            ))
        } else {
            Err(self.err(
                &v.span(),
                format!(
                    "{what} must be between {} and {}{unit} (got {x:?})",
                    number(lo),
                    number(hi)
                ),
            ))
        }
    }

    /// Checks that each section belongs to the kind and parses them.
    pub fn parse(&self, learner: &ViaPointConfig) -> Result<Plans, InputError> {
        let only = |span: Range<usize>, section: &str, kinds: &str| {
            self.err(
                &span,
                format!(
                    "[{section}] is read only by {kinds}; this file has kind = \"{}\" (remove the section or change [experiment] kind)",
                    self.kind.name()
                ),
            )
        };
        // A pose experiment executes when it names a robot; the other two always do.
        let executes = matches!(
            self.kind,
            Kind::Imitation
                | Kind::ViapointJoint
                | Kind::Promp
                | Kind::ViapointExecuted
                | Kind::Contact
        ) || (self.kind == Kind::ViapointPose && self.robot.is_some());
        if let Some(r) = self.robot
            && !executes
        {
            return Err(only(
                r.span(),
                "robot",
                "kind = \"imitation\", \"promp\", \"viapoint_joint\", \"viapoint_pose\", \"viapoint_executed\" and \"contact\"",
            ));
        }
        let contact = match (self.kind, self.contact) {
            (Kind::Contact, Some(c)) => {
                let dir = self.path.parent().unwrap_or(Path::new("."));
                Some(c.get_ref().plan(dir, &|span, m| self.err(span, m))?)
            }
            (Kind::Contact, None) => {
                return Err(InputError(format!(
                    "{}: kind = \"contact\" needs a [contact] section (the surface's approach and the force profile)",
                    self.path.display()
                )));
            }
            (_, Some(c)) => return Err(only(c.span(), "contact", "kind = \"contact\"")),
            _ => None,
        };
        if let Some(e) = self.executed
            && self.kind != Kind::ViapointExecuted
        {
            return Err(only(e.span(), "executed", "kind = \"viapoint_executed\""));
        }
        let export = match self.export {
            Some(e) if !executes => {
                return Err(only(
                    e.span(),
                    "export",
                    "experiments with a robot (kind = \"imitation\", \"viapoint_joint\", or \"viapoint_pose\" with [robot])",
                ));
            }
            Some(e) => Some(e.get_ref().plan(&|span, m| self.err(span, m))?),
            None => None,
        };
        if let Some(j) = self.joint
            && self.kind != Kind::ViapointJoint
        {
            return Err(only(j.span(), "joint", "kind = \"viapoint_joint\""));
        }
        if let Some(p) = self.plant
            && self.kind != Kind::ViapointEnergy
        {
            return Err(only(p.span(), "plant", "kind = \"viapoint_energy\""));
        }
        if let Some(s) = self.speedup {
            return Err(self.err(
                &s.span(),
                "[speedup] is no longer part of an experiment (a timing is a benchmark, and it made the run many times longer): remove the section; `cargo bench --bench core -- energy_population` measures the parallel speed-up".into(),
            ));
        }
        for (span, name) in [
            (self.demonstrations.map(Spanned::span), "demonstrations"),
            (self.imitation.map(Spanned::span), "imitation"),
        ] {
            if let Some(s) = span
                && !matches!(self.kind, Kind::Imitation | Kind::Promp)
            {
                return Err(only(s, name, "kind = \"imitation\" and \"promp\""));
            }
        }
        if let Some(s) = self.promp
            && self.kind != Kind::Promp
        {
            return Err(only(s.span(), "promp", "kind = \"promp\""));
        }
        if let Some(s) = self.scaling
            && self.kind != Kind::Scaling
        {
            return Err(only(s.span(), "scaling", "kind = \"scaling\""));
        }
        let robot = if executes {
            Some(self.robot_choice(learner.task.dmp.dt)?)
        } else {
            None
        };
        if self.kind == Kind::Contact
            && !matches!(
                robot.as_ref().map(|r| &r.backend),
                Some(BackendChoice::Franka { .. })
            )
        {
            let at = self.robot.map_or(0..0, |r| r.span());
            return Err(self.err(
                &at,
                "kind = \"contact\" drives a Franka in torque mode: give [robot] backend = \"franka\" with its host".into(),
            ));
        }
        let imitation = if matches!(self.kind, Kind::Imitation | Kind::Promp) {
            Some(self.imitation_plan(learner)?)
        } else {
            None
        };
        let promp = if self.kind == Kind::Promp {
            Some(self.promp_plan(learner.task.dmp.tau, imitation.as_ref())?)
        } else {
            None
        };
        let scaling = if self.kind == Kind::Scaling {
            let compare = match self.scaling.and_then(|s| s.get_ref().compare.as_ref()) {
                Some(c) if c.get_ref().is_empty() => {
                    return Err(self.err(
                        &c.span(),
                        "[scaling] `compare` must name at least one parametrisation".into(),
                    ));
                }
                Some(c) => c.get_ref().clone(),
                None => vec![Parametrisation::ThesisScaling, Parametrisation::Raw],
            };
            Some(ScalingPlan { compare })
        } else {
            None
        };
        let joint = if self.kind == Kind::ViapointJoint {
            let section = self.joint.map(Spanned::get_ref);
            let weight = |v: Option<&Spanned<f64>>, name: &str, default: f64| match v {
                Some(v) => self.within(
                    v,
                    &format!("[joint] `{name}`"),
                    0.0,
                    cps_learn::MAX_WEIGHT,
                    "",
                ),
                None => Ok(default),
            };
            Some(JointPlan {
                limit_weight: weight(
                    section.and_then(|s| s.limit_weight.as_ref()),
                    "limit_weight",
                    1e6,
                )?,
                speed_limit_weight: weight(
                    section.and_then(|s| s.speed_limit_weight.as_ref()),
                    "speed_limit_weight",
                    1e3,
                )?,
            })
        } else {
            None
        };
        let energy = if self.kind == Kind::ViapointEnergy {
            Some(self.energy_plan(learner)?)
        } else {
            None
        };
        let pose = match (self.kind, self.orientation) {
            (Kind::ViapointPose, Some(o)) => Some(self.pose_plan(o, learner)?),
            (Kind::ViapointPose, None) => {
                return Err(InputError(format!(
                    "{}: kind = \"viapoint_pose\" needs an [orientation] section (start, goal, one orientation per via point)",
                    self.path.display()
                )));
            }
            (_, Some(o)) => return Err(only(o.span(), "orientation", "kind = \"viapoint_pose\"")),
            _ => None,
        };
        let executed = if self.kind == Kind::ViapointExecuted {
            Some(self.executed_plan(learner)?)
        } else {
            None
        };
        Ok(Plans {
            robot,
            imitation,
            scaling,
            joint,
            energy,
            pose,
            promp,
            executed,
            export,
            contact,
        })
    }

    /// `[executed]` of `kind = "viapoint_executed"`: the tracking weight; the search must
    /// be CMA-ES on 3-D tool positions.
    fn executed_plan(&self, learner: &ViaPointConfig) -> Result<ExecutedPlan, InputError> {
        if learner.solver == cps_learn::Solver::Exact {
            return Err(InputError(format!(
                "{}: kind = \"viapoint_executed\" learns with CMA-ES on the executed cost; the exact solver only knows the analytic cost (it is the warm start here): remove [optimizer] solver = \"exact\"",
                self.path.display()
            )));
        }
        if learner.task.start.len() != 3 {
            return Err(InputError(format!(
                "{}: kind = \"viapoint_executed\" executes tool positions: the task needs 3 coordinates (x, y, z), not {}",
                self.path.display(),
                learner.task.start.len()
            )));
        }
        let section = self.executed.map(Spanned::get_ref);
        let weight = |v: Option<&Spanned<f64>>, name: &str, default: f64| match v {
            Some(v) => self.within(
                v,
                &format!("[executed] `{name}`"),
                0.0,
                cps_learn::MAX_WEIGHT,
                "",
            ),
            None => Ok(default),
        };
        Ok(ExecutedPlan {
            weights: cps_learn::ExecutedWeights {
                tracking: weight(section.and_then(|s| s.tracking.as_ref()), "tracking", 1e5)?,
                speed_usage: weight(
                    section.and_then(|s| s.speed_usage.as_ref()),
                    "speed_usage",
                    0.0,
                )?,
            },
        })
    }

    /// `[promp]`: the basis and the via point, within the demonstrations' duration `tau`
    /// and a 10 m reach; a ProMP needs at least 2 demonstrations.
    fn promp_plan(
        &self,
        tau: f64,
        imitation: Option<&ImitationPlan>,
    ) -> Result<ProMpPlan, InputError> {
        let Some(section) = self.promp else {
            return Err(InputError(format!(
                "{}: kind = \"promp\" needs a [promp] section with the new via point: [promp.via] time = …, position = [x, y, z]",
                self.path.display()
            )));
        };
        let s = section.get_ref();
        if let Some(p) = imitation
            && p.demonstrations < 2
        {
            let span = self
                .demonstrations
                .and_then(|d| d.get_ref().count.as_ref())
                .map_or(section.span(), Spanned::span);
            return Err(self.err(
                &span,
                "a ProMP learns the spread of several demonstrations: [demonstrations] `count` must be at least 2".into(),
            ));
        }
        let bases = match &s.basis_functions {
            Some(n) if !(2..=1000).contains(n.get_ref()) => {
                return Err(self.err(
                    &n.span(),
                    format!(
                        "[promp] `basis_functions` must be between 2 and 1000 (got {})",
                        n.get_ref()
                    ),
                ));
            }
            Some(n) => *n.get_ref(),
            None => 20,
        };
        let v = s.via.get_ref();
        let time = self.within(
            &v.time,
            "[promp.via] `time`",
            0.0,
            tau,
            " s (the movement's duration)",
        )?;
        let position = v.position.get_ref().clone();
        if position.len() != 3 || position.iter().any(|x| !x.is_finite() || x.abs() > 10.0) {
            return Err(self.err(
                &v.position.span(),
                format!(
                    "[promp.via] `position` must be three finite coordinates within 10 m (got {position:?})"
                ),
            ));
        }
        let std = match &v.std {
            Some(s) => self.within(s, "[promp.via] `std`", 0.0, 10.0, " m")?,
            None => 0.0,
        };
        Ok(ProMpPlan {
            bases,
            time,
            position,
            std,
        })
    }

    fn orientation(
        &self,
        v: &Spanned<Vec<f64>>,
        what: &str,
    ) -> Result<nalgebra::UnitQuaternion<f64>, InputError> {
        let x = v.get_ref();
        if x.iter().any(|c| !c.is_finite()) {
            return Err(self.err(&v.span(), format!("[orientation] {what}: not finite")));
        }
        match x.len() {
            4 => {
                let q = nalgebra::Quaternion::new(x[3], x[0], x[1], x[2]);
                let n = q.norm();
                if (n - 1.0).abs() > 1e-3 {
                    return Err(self.err(
                        &v.span(),
                        format!(
                            "[orientation] {what}: a quaternion [x, y, z, w] must have norm 1 (got {n:.6})"
                        ),
                    ));
                }
                Ok(nalgebra::UnitQuaternion::from_quaternion(q))
            }
            3 => Ok(nalgebra::UnitQuaternion::from_euler_angles(x[0], x[1], x[2])),
            n => Err(self.err(
                &v.span(),
                format!(
                    "[orientation] {what}: give a quaternion [x, y, z, w] or roll, pitch, yaw [r, p, y] (got {n} numbers)"
                ),
            )),
        }
    }

    fn pose_plan(
        &self,
        o: &Spanned<OrientationSection>,
        learner: &ViaPointConfig,
    ) -> Result<PosePlan, InputError> {
        let s = o.get_ref();
        if learner.task.start.len() != 3 {
            return Err(self.err(
                &o.span(),
                "[orientation] needs a 3-D position task (x, y, z)".into(),
            ));
        }
        if s.via.len() != learner.task.via.len() {
            return Err(self.err(
                &o.span(),
                format!(
                    "[orientation] `via` has {} orientations for {} [[task.via]] points: give one per via point ([] leaves one free)",
                    s.via.len(),
                    learner.task.via.len()
                ),
            ));
        }
        let via = s
            .via
            .iter()
            .enumerate()
            .map(|(i, v)| {
                if v.get_ref().is_empty() {
                    Ok(None)
                } else {
                    self.orientation(v, &format!("`via[{i}]`")).map(Some)
                }
            })
            .collect::<Result<_, _>>()?;
        Ok(PosePlan {
            start: self.orientation(&s.start, "`start`")?,
            goal: self.orientation(&s.goal, "`goal`")?,
            via,
            sigma0: match &s.sigma0 {
                Some(v) => self.within(v, "[orientation] `sigma0`", 1e-6, 10.0, " rad")?,
                None => 0.3,
            },
            method: match &s.method {
                Some(m) if *m.get_ref() == cps_learn::Solver::Exact => {
                    return Err(self.err(
                        &m.span(),
                        "[orientation] `method` = \"exact\" is for quadratic costs, and the orientation cost is not one: use \"least_squares\" (Levenberg-Marquardt) or \"cmaes\"".into(),
                    ));
                }
                Some(m) => *m.get_ref(),
                None => cps_learn::Solver::Cmaes,
            },
        })
    }

    fn energy_plan(&self, learner: &ViaPointConfig) -> Result<EnergyPlan, InputError> {
        let p = self.plant.map(Spanned::get_ref);
        let mut plant = cps_learn::PointMassPlant::default();
        if let Some(v) = p.and_then(|p| p.mass.as_ref()) {
            plant.mass = self.within(v, "[plant] `mass`", 1e-3, 1e4, " kg")?;
        }
        if let Some(v) = p.and_then(|p| p.kp.as_ref()) {
            plant.kp = self.within(v, "[plant] `kp`", 1e-3, 1e8, " N/m")?;
        }
        if let Some(v) = p.and_then(|p| p.kv.as_ref()) {
            plant.kv = self.within(v, "[plant] `kv`", 1e-3, 1e6, " N·s/m")?;
        }
        if let Some(v) = p.and_then(|p| p.substeps.as_ref()) {
            plant.substeps = *v.get_ref();
        }
        // The library's rules (substeps in range, integration stable for these gains),
        // named at the section.
        if let Err(e) = plant.validate(learner.task.dmp.dt) {
            let span = p
                .and_then(|p| p.substeps.as_ref().map(Spanned::span))
                .or(self.plant.map(Spanned::span))
                .unwrap_or(0..0);
            return Err(self.err(&span, format!("[plant] {e}")));
        }
        let effort_weight = match p.and_then(|p| p.effort_weight.as_ref()) {
            Some(v) => self.within(v, "[plant] `effort_weight`", 0.0, cps_learn::MAX_WEIGHT, "")?,
            None => 1e-2,
        };
        Ok(EnergyPlan {
            plant,
            effort_weight,
        })
    }

    /// `[demonstrations] takes`: each take read and made a demonstration (its errors name
    /// the take, and the key's place in the experiment file).
    fn takes(&self) -> Result<Vec<cps_learn::GivenDemonstration>, InputError> {
        let Some(d) = self.demonstrations.map(Spanned::get_ref) else {
            return Ok(Vec::new());
        };
        let Some(takes) = &d.takes else {
            for (v, key) in [
                (d.markers.as_ref().map(Spanned::span), "markers"),
                (d.rigid_body.as_ref().map(Spanned::span), "rigid_body"),
                (d.to_robot.as_ref().map(Spanned::span), "to_robot"),
            ] {
                if let Some(span) = v {
                    return Err(self.err(
                        &span,
                        format!("[demonstrations] `{key}` describes motion-capture takes: add `takes = [\"take.c3d\", …]`"),
                    ));
                }
            }
            return Ok(Vec::new());
        };
        for (v, key) in [
            (d.count.as_ref().map(Spanned::span), "count"),
            (d.via_std.as_ref().map(Spanned::span), "via_std"),
        ] {
            if let Some(span) = v {
                return Err(self.err(
                    &span,
                    format!("[demonstrations] `{key}` is for learned demonstrations; with `takes` the takes are the demonstrations"),
                ));
            }
        }
        if takes.get_ref().is_empty() {
            return Err(self.err(&takes.span(), "[demonstrations] `takes` is empty".into()));
        }
        let dir = self.path.parent().unwrap_or(Path::new("."));
        let at = |span: Range<usize>, key: &'static str| {
            move |e: String| self.err(&span, format!("[demonstrations] `{key}`: {e}"))
        };
        let words = cps_mocap::demo::Words {
            markers: d
                .markers
                .as_ref()
                .map(|m| m.get_ref().clone())
                .unwrap_or_default(),
            rigid_body: d.rigid_body.as_ref().map(|r| r.get_ref().clone()),
            origin: d
                .origin
                .as_ref()
                .map_or("centroid".into(), |o| o.get_ref().clone()),
            axes: d.axes.as_ref().map(|a| a.get_ref().clone()),
            y_up: d.y_up.as_ref().is_some_and(|y| *y.get_ref()),
            max_gap: d.max_gap.as_ref().map_or(10, |m| *m.get_ref()),
            cutoff_hz: d.cutoff.as_ref().map_or(10.0, |c| *c.get_ref()),
            outlier_mm: d.outlier_mm.as_ref().map_or(20.0, |o| *o.get_ref()),
            frames: None,
        };
        if words.markers.is_empty() && words.rigid_body.is_none() {
            return Err(self.err(
                &takes.span(),
                "[demonstrations] `takes` needs `markers = [\"A\", \"B\", \"C\"]` (the tool's markers) or `rigid_body = \"NAME\"`".into(),
            ));
        }
        let settings = words.settings().map_err(|e| {
            at(d.axes.as_ref().map_or(takes.span(), Spanned::span), "axes")(e.to_string())
        })?;
        let calibration = d.to_robot.as_ref().map(|c| dir.join(c.get_ref()));
        let mut out = Vec::new();
        for name in takes.get_ref() {
            let demo =
                crate::mocap::demonstration(&dir.join(name), &settings, calibration.as_deref())
                    .map_err(|e| at(takes.span(), "takes")(e.0))?;
            let times = demo.t.clone();
            let position: Vec<Vec<f64>> = (0..3)
                .map(|k| demo.position.iter().map(|p| p[k]).collect())
                .collect();
            let zeros = vec![vec![0.0; times.len()]; 3];
            out.push(cps_learn::GivenDemonstration {
                name: name.clone(),
                trajectory: cps_dmp::Trajectory::from_parts(times, &position, &zeros, &zeros),
            });
        }
        Ok(out)
    }

    fn imitation_plan(&self, learner: &ViaPointConfig) -> Result<ImitationPlan, InputError> {
        let takes = self.takes()?;
        let d = self.demonstrations.map(Spanned::get_ref);
        let demonstrations = match d.and_then(|d| d.count.as_ref()) {
            Some(c) if *c.get_ref() == 0 || *c.get_ref() > 10_000 => {
                return Err(self.err(
                    &c.span(),
                    format!(
                        "[demonstrations] `count` must be between 1 and 10000 (got {})",
                        c.get_ref()
                    ),
                ));
            }
            Some(c) => *c.get_ref(),
            None if !takes.is_empty() => takes.len(),
            None => 20,
        };
        let via_std = match d.and_then(|d| d.via_std.as_ref()) {
            Some(v) => self.within(v, "[demonstrations] `via_std`", 0.0, 10.0, " m")?,
            None => 0.05,
        };
        let i = self.imitation.map(Spanned::get_ref);
        let base = learner.task.dmp;
        let mut dmp = DmpConfig::new(25, 9.5, base.dt);
        dmp.alpha_z = base.alpha_z;
        dmp.beta_z = base.beta_z;
        dmp.alpha_x = base.alpha_x;
        if let Some(n) = i.and_then(|i| i.basis_functions.as_ref()) {
            if *n.get_ref() < 2 || *n.get_ref() > 10_000 {
                return Err(self.err(
                    &n.span(),
                    format!(
                        "[imitation] `basis_functions` must be between 2 and 10000 (got {})",
                        n.get_ref()
                    ),
                ));
            }
            dmp.n_basis = *n.get_ref();
        }
        if let Some(t) = i.and_then(|i| i.tau.as_ref()) {
            dmp.tau = self.within(t, "[imitation] `tau`", 1e-3, 1e5, " s")?;
        } else if !takes.is_empty() {
            // The takes' mean duration.
            dmp.tau = takes
                .iter()
                .map(|g| g.trajectory.times().last().copied().unwrap_or(0.0))
                .sum::<f64>()
                / takes.len() as f64;
        }
        if let Some(t) = i.and_then(|i| i.dt.as_ref()) {
            dmp.dt = self.within(t, "[imitation] `dt`", 1e-5, 10.0, " s")?;
        }
        if let Err(e) = dmp.validate() {
            let span = self.imitation.map_or(0..0, Spanned::span);
            return Err(self.err(&span, format!("[imitation] {e}")));
        }
        let ridge_lambda = match i.and_then(|i| i.ridge_lambda.as_ref()) {
            Some(l) if !(l.get_ref().is_finite() && *l.get_ref() >= 0.0) => {
                return Err(self.err(
                    &l.span(),
                    format!(
                        "[imitation] `ridge_lambda` must be finite and ≥ 0 (got {})",
                        l.get_ref()
                    ),
                ));
            }
            Some(l) => Lambda::Fixed(*l.get_ref()),
            None => Lambda::Fixed(1e-12),
        };
        let jerk_lambda = match i.and_then(|i| i.jerk_lambda.as_ref()) {
            None => Lambda::Auto,
            Some(l) => match l.get_ref() {
                toml::Value::String(s) if s == "auto" => Lambda::Auto,
                toml::Value::Float(x) if x.is_finite() && *x >= 0.0 => Lambda::Fixed(*x),
                toml::Value::Integer(x) if *x >= 0 => Lambda::Fixed(*x as f64),
                other => {
                    return Err(self.err(
                        &l.span(),
                        format!(
                            "[imitation] `jerk_lambda` must be \"auto\" or a number ≥ 0 (got {other})"
                        ),
                    ));
                }
            },
        };
        Ok(ImitationPlan {
            demonstrations,
            takes,
            via_std,
            dmp,
            ridge_lambda,
            jerk_lambda,
        })
    }
}

impl Experiment {
    /// The plan in words, for `check`: what is learned, by which search with what budget,
    /// and where it is executed.
    pub fn describe(&self) -> Vec<String> {
        if let Some(c) = &self.contact {
            return c.describe(self.robot.as_ref().map(|r| r.describe()));
        }
        let c = &self.config;
        let task = &c.task;
        let bases = task.dmp.n_basis;
        let via = task.via.len();
        let (dims, what) = match (self.kind, &self.robot) {
            (Kind::ViapointJoint, Some(r)) => (r.setup.chain.dof(), "joint DMPs"),
            _ => (task.start.len(), "position DMPs"),
        };
        let mut learns = format!(
            "learns: {dims} {what} × {bases} basis functions = {} weights, through {via} via point(s) in {} s",
            dims * bases,
            task.dmp.tau
        );
        if self.kind == Kind::ViapointPose {
            learns.push_str(&format!(
                ", and 1 orientation DMP × {bases} (3 × {bases} weights)"
            ));
        }
        let population = c
            .population
            .unwrap_or_else(|| cps_cmaes::Parameters::default_lambda((dims * bases).max(1)));
        let cmaes = |generations: u64, repetitions: usize| {
            format!(
                "CMA-ES{}, population {population}, up to {generations} generations × {repetitions} repetition(s){}",
                if self.kind == Kind::Scaling {
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
        };
        let search = match (self.kind, c.solver) {
            (Kind::Imitation | Kind::Promp, _)
                if self.imitation.as_ref().is_some_and(|p| !p.takes.is_empty()) =>
            {
                let p = self.imitation.as_ref();
                let takes = p.map_or(Vec::new(), |p| {
                    p.takes.iter().map(|t| t.name.clone()).collect::<Vec<_>>()
                });
                format!(
                    "{} motion-capture takes ({}) as the demonstrations, each checked and executed from its own start; their mean imitated by ridge and jerk-regularised ridge with {} basis functions over {:.2} s",
                    takes.len(),
                    takes.join(", "),
                    p.map_or(0, |p| p.dmp.n_basis),
                    p.map_or(0.0, |p| p.dmp.tau)
                ) + &self.promp.as_ref().map_or(String::new(), |p| {
                    format!(
                        "; then a ProMP of the executed demonstrations ({} basis functions per axis) conditioned on {:?} m at {} s, its mean executed",
                        p.bases, p.position, p.time
                    )
                })
            }
            (Kind::Imitation | Kind::Promp, solver) => {
                let p = self.imitation.as_ref();
                format!(
                    "{} demonstrations (via points moved by N(0, {}²) m), each learned by {}; their mean imitated by ridge and jerk-regularised ridge with {} basis functions",
                    p.map_or(0, |p| p.demonstrations),
                    p.map_or(0.0, |p| p.via_std),
                    match solver {
                        cps_learn::Solver::Exact => "the exact solver (no search)".to_string(),
                        cps_learn::Solver::LeastSquares => "Levenberg–Marquardt".to_string(),
                        cps_learn::Solver::Cmaes => cmaes(c.generations, 1),
                    },
                    p.map_or(0, |p| p.dmp.n_basis)
                ) + &self.promp.as_ref().map_or(String::new(), |p| {
                    format!(
                        "; then a ProMP of the executed demonstrations ({} basis functions per axis) conditioned on {:?} m at {} s, its mean executed",
                        p.bases, p.position, p.time
                    )
                })
            }
            (Kind::Viapoint, cps_learn::Solver::Exact) => {
                "the exact least-squares optimum (no search)".to_string()
            }
            (Kind::Scaling, _) => {
                let arms = self.scaling.as_ref().map_or(Vec::new(), |s| {
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
            (_, _) => cmaes(c.generations, c.repetitions),
        };
        let mut lines = vec![learns, format!("search: {search}")];
        if let Some(r) = &self.robot {
            lines.push(format!(
                "robot: {} joints, scene {}, executed on the {} backend",
                r.setup.chain.dof(),
                r.scene,
                r.describe()
            ));
        }
        if let Some(e) = &self.export {
            let formats: Vec<&str> = e.formats.iter().map(|f| f.file_name()).collect();
            lines.push(format!(
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
            ));
        }
        lines
    }

    /// What `cps-cli check` prints for this experiment run on `threads` threads: `ok` and
    /// the kind, what it learns and searches, where it executes and exports, the robot's
    /// reach (checked as the run would, so an unreachable point is an error here) and the
    /// estimate of memory and time.
    pub fn check_lines(&self, threads: usize) -> Result<Vec<String>, InputError> {
        // A contact task has no way points to reach: the search finds its surface.
        let reach = if self.kind == Kind::Contact {
            None
        } else {
            self.check_reach()?
        };
        let mut lines = vec![format!(
            "{}: ok (kind {})",
            self.source.display(),
            self.kind.name()
        )];
        for line in self.describe().into_iter().chain(reach) {
            lines.push(format!("  {line}"));
        }
        if let (Some(c), Some(e)) = (&self.contact, &self.estimate) {
            // A contact task runs in the robot's time, not the machine's.
            lines.push(format!(
                "  runs ≈ {:.0} s on the robot (longer while the force lags its profile), recording ≈ {}",
                c.nominal_seconds(),
                crate::source::bytes(e.memory_bytes)
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
