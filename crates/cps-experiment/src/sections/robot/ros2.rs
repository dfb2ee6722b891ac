//! `[robot] backend = "ros2"`: a ros2_control joint_trajectory_controller on a ROS 2
//! graph — its name, the joint states' topic, the domain, the services' mapping.

use std::time::Duration;

use cps_ros2::robot::Ros2Settings;
use toml::Spanned;

use super::{BackendChoice, RobotSection};
use crate::InputError;
use crate::sections::Sections;

/// The keys only this backend reads (`controller` it shares with dynamics).
pub(super) fn keys(r: &RobotSection) -> super::Keys {
    vec![
        ("joint_states", r.joint_states.as_ref().map(Spanned::span)),
        ("domain", r.domain.as_ref().map(Spanned::span)),
        (
            "service_mapping",
            r.service_mapping.as_ref().map(Spanned::span),
        ),
    ]
}

impl Sections<'_> {
    /// `[robot] backend = "ros2"`: `controller`, `joint_states`, `domain`, `dt`.
    pub(super) fn ros2_choice(
        &self,
        section: Option<&RobotSection>,
        default_dt: f64,
    ) -> Result<BackendChoice, InputError> {
        let Some(r) = section else {
            unreachable!("backend = \"ros2\" is read from a [robot] section")
        };
        let probe = cps_ros2::names::NodeName::new("cps", "/", 0).expect("a valid node name");
        let name = |v: &Spanned<String>, what: &str| -> Result<String, InputError> {
            cps_ros2::names::resolve(&probe, v.get_ref())
                .map_err(|e| self.err(&v.span(), format!("[robot] `{what}`: {e}")))
        };
        let Some(controller) = &r.controller else {
            return Err(InputError(format!(
                "{}: [robot] backend = \"ros2\" needs `controller`, the joint_trajectory_controller's name (e.g. controller = \"/panda_arm_controller\"): cps never guesses which robot to move",
                self.path.display()
            )));
        };
        let controller = name(controller, "controller")?;
        let joint_states = match &r.joint_states {
            Some(j) => name(j, "joint_states")?,
            None => "/joint_states".into(),
        };
        let domain = match &r.domain {
            Some(d) if *d.get_ref() > cps_ros2::names::MAX_DOMAIN => {
                return Err(self.err(
                    &d.span(),
                    format!(
                        "[robot] `domain` must be 0 to {} (got {})",
                        cps_ros2::names::MAX_DOMAIN,
                        d.get_ref()
                    ),
                ));
            }
            Some(d) => Some(*d.get_ref()),
            None => None,
        };
        let dt = match &r.dt {
            Some(d) => self.within(d, "[robot] `dt`", 1e-3, 0.1, " s")?,
            None => default_dt,
        };
        let service_mapping = match &r.service_mapping {
            Some(m) => m
                .get_ref()
                .parse()
                .map_err(|e| self.err(&m.span(), format!("[robot] `service_mapping`: {e}")))?,
            None => Default::default(),
        };
        Ok(BackendChoice::Ros2(Ros2Settings {
            controller,
            joint_states,
            domain,
            service_mapping,
            dt,
            goal_period: None,
            wait: Duration::from_secs(20),
            joint_names: None,
            read_start: true,
        }))
    }
}
