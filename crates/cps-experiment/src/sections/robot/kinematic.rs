//! `[robot] backend = "kinematic"` (the default): the in-process robot, stepped every
//! `dt`; the keys of a simulator it has not are named.

use super::{BackendChoice, Control, RobotSection};
use crate::InputError;
use crate::sections::Sections;

impl Sections<'_> {
    /// The in-process robot: `dt` (default: the movement's).
    pub(super) fn kinematic_choice(
        &self,
        section: Option<&RobotSection>,
        default_dt: f64,
    ) -> Result<BackendChoice, InputError> {
        if let Some(e) = section.and_then(|r| r.endpoint.as_ref()) {
            return Err(self.err(
                &e.span(),
                "[robot] `endpoint` is read only with backend = \"coppelia\"".into(),
            ));
        }
        if let Some(e) = section.and_then(|r| r.endpoints.as_ref()) {
            return Err(self.err(
                &e.span(),
                "[robot] `endpoints` is read only with backend = \"coppelia\"".into(),
            ));
        }
        if let Some(c) = section.and_then(|r| r.control.as_ref())
            && *c.get_ref() == Control::SimulatorIk
        {
            return Err(self.err(
                    &c.span(),
                    "[robot] control = \"simulator_ik\" needs backend = \"coppelia\" (the in-process robot has no IK of its own)".into(),
                ));
        }
        let dt = match section.and_then(|r| r.dt.as_ref()) {
            Some(d) => self.within(d, "[robot] `dt`", 1e-4, 1.0, " s")?,
            None => default_dt,
        };
        Ok(BackendChoice::Kinematic { dt })
    }
}
