//! The sections of an experiment file that belong to one kind, each turned into that
//! kind's checked plan: one module per kind (`[demonstrations]` and `[imitation]` in
//! [`imitation`], `[promp]` in [`promp`], `[scaling]`, `[joint]`, `[plant]` in
//! [`energy`], `[orientation]` in [`pose`], `[executed]`, `[contact]`). `Sections` holds
//! a file's optional sections with what names their places in errors; which section
//! belongs to which kind is decided in [`crate::plan`], the robot (`[robot]`) is chosen in
//! [`crate::robots`]. `[clearance]` ([`clearance`]) is read by every kind that learns a
//! robot's movement.

pub mod clearance;
pub mod contact;
pub mod energy;
pub mod executed;
pub mod imitation;
pub mod joint;
pub mod pose;
pub mod promp;
pub mod robot;
pub mod scaling;

use std::ops::Range;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::InputError;
use cps_outcome::source::location;
use robot::RobotSection;

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

/// A limit in words: plain for ordinary magnitudes, exponent form for extreme ones.
pub(crate) fn number(x: f64) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// The optional sections of a file, with what is needed to name places in errors.
pub(crate) struct Sections<'a> {
    pub path: &'a Path,
    pub text: &'a str,
    pub kind: Kind,
    pub robot: Option<&'a Spanned<RobotSection>>,
    pub demonstrations: Option<&'a Spanned<imitation::DemonstrationsSection>>,
    pub imitation: Option<&'a Spanned<imitation::ImitationSection>>,
    pub scaling: Option<&'a Spanned<scaling::ScalingSection>>,
    pub joint: Option<&'a Spanned<joint::JointSection>>,
    pub plant: Option<&'a Spanned<energy::PlantSection>>,
    /// `[speedup]`, no longer part of an experiment: refused with where it went.
    pub speedup: Option<&'a Spanned<toml::Value>>,
    pub orientation: Option<&'a Spanned<pose::OrientationSection>>,
    pub export: Option<&'a Spanned<cps_movement::export::ExportSection>>,
    pub promp: Option<&'a Spanned<promp::ProMpSection>>,
    pub executed: Option<&'a Spanned<executed::ExecutedSection>>,
    pub contact: Option<&'a Spanned<contact::ContactSection>>,
    pub clearance: Option<&'a Spanned<clearance::ClearanceSection>>,
    /// `[[obstacle]]`: the robot's world beyond its scene's.
    pub obstacle: &'a [Spanned<cps_movement::scene::ObstacleEntry>],
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
}
