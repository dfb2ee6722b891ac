//! `[robot] backend = "dynamics"`: the scene's robot with dynamics, in process — its
//! controller and gains, drive, integrator, noise, or a calibration file.

use std::path::Path;

use toml::Spanned;

use super::{BackendChoice, RobotSection};
use crate::InputError;
use crate::sections::Sections;

/// The keys only this backend reads (`controller` it shares with ros2).
pub(super) fn keys(r: &RobotSection) -> super::Keys {
    vec![
        ("kp", r.kp.as_ref().map(Spanned::span)),
        ("kv", r.kv.as_ref().map(Spanned::span)),
        ("drive", r.drive.as_ref().map(Spanned::span)),
        ("integrator", r.integrator.as_ref().map(Spanned::span)),
        ("noise", r.noise.as_ref().map(Spanned::span)),
        ("seed", r.seed.as_ref().map(Spanned::span)),
        ("calibration", r.calibration.as_ref().map(Spanned::span)),
    ]
}

impl Sections<'_> {
    /// `[robot] calibration`: the file read and checked against the scene's robot; the
    /// keys it replaces (`kp`, `kv`, `drive`; a controller other than `joint_pd`) refused.
    pub(super) fn calibration(
        &self,
        c: &Spanned<String>,
        r: &RobotSection,
        robot: &cps_movement::robot_file::RobotModel,
    ) -> Result<cps_dynamics::options::CalibrationValues, InputError> {
        for (key, span) in [
            ("kp", r.kp.as_ref().map(Spanned::span)),
            ("kv", r.kv.as_ref().map(Spanned::span)),
            ("drive", r.drive.as_ref().map(Spanned::span)),
        ] {
            if let Some(at) = span {
                return Err(self.err(
                    &at,
                    format!("[robot] `{key}` and `calibration` both say how the robot is driven: give one"),
                ));
            }
        }
        if let Some(ctl) = r.controller.as_ref().filter(|c| c.get_ref() != "joint_pd") {
            return Err(self.err(
                &ctl.span(),
                format!(
                    "[robot] a calibration identifies a joint_pd controller, not {}",
                    ctl.get_ref()
                ),
            ));
        }
        if c.get_ref().trim().is_empty() {
            return Err(self.err(
                &c.span(),
                "[robot] `calibration` is empty: give the path of a calibration file (`cps-cli identify` writes one), relative to this file".into(),
            ));
        }
        let path = self
            .path
            .parent()
            .unwrap_or(Path::new("."))
            .join(c.get_ref());
        let file = cps_movement::calibration::read_calibration(&path)
            .map_err(|e| self.err(&c.span(), format!("[robot] `calibration`: {}", e.0)))?;
        let k = file.calibration;
        let values = cps_dynamics::options::CalibrationValues {
            robot: k.robot,
            kp: k.kp,
            kv: k.kv,
            lag: k.lag_ms,
            armature: k.armature,
            viscous: k.viscous,
            coulomb: k.coulomb,
            speed: k.coulomb_speed,
        };
        let check = if k.controller != "joint_pd" {
            Err((
                "controller",
                format!(
                    "its controller is {}; cps identifies joint_pd",
                    k.controller
                ),
            ))
        } else {
            values.check(
                &robot.name,
                robot.chain.dof(),
                robot.limits.torque.as_deref(),
            )
        };
        check.map_err(|(key, e)| {
            self.err(
                &c.span(),
                format!(
                    "[robot] `calibration`: {}: {e}",
                    cps_movement::calibration::place_of(&path, key)
                ),
            )
        })?;
        Ok(values)
    }

    /// `[robot] backend = "dynamics"`: `controller`, `kp`, `kv`, `drive`, `integrator`,
    /// `noise`, `seed`, `dt` (a whole number of milliseconds: the robot is controlled every
    /// millisecond).
    pub(super) fn dynamics_choice(
        &self,
        section: Option<&RobotSection>,
        robot: &cps_movement::robot_file::RobotModel,
        default_dt: f64,
    ) -> Result<BackendChoice, InputError> {
        let Some(r) = section else {
            unreachable!("backend = \"dynamics\" is read from a [robot] section")
        };
        let dof = robot.chain.dof();
        if robot.inertia.is_none() || !(6..=7).contains(&dof) {
            let at = self.robot.map_or(0..0, |r| r.span());
            return Err(self.err(
                &at,
                format!(
                    "[robot] backend = \"dynamics\" simulates arms of 6 or 7 joints whose link inertias are known: the scene's robot {} has {dof} joints{} (the built-in scenes' Panda has Gaz et al.'s; a URDF gives them with <inertial>)",
                    robot.name,
                    if robot.inertia.is_none() { " and no link inertias" } else { "" }
                ),
            ));
        }
        let mut o = cps_dynamics::DynamicsOptions::default();
        if let Some(c) = &r.controller {
            if !cps_dynamics::CONTROLLERS.contains(&c.get_ref().as_str()) {
                return Err(self.err(
                    &c.span(),
                    format!(
                        "[robot] `controller` = \"{}\" is not one of {} (backend = \"dynamics\")",
                        c.get_ref(),
                        cps_dynamics::CONTROLLERS.join(", ")
                    ),
                ));
            }
            o.controller = c.get_ref().clone();
        }
        for (key, gains, slot) in [("kp", &r.kp, &mut o.kp), ("kv", &r.kv, &mut o.kv)] {
            if let Some(g) = gains {
                if let Some((i, v)) = g
                    .get_ref()
                    .iter()
                    .enumerate()
                    .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
                {
                    return Err(self.err(
                        &g.span(),
                        format!("[robot] `{key}[{i}]` is {v}: a gain must be finite and ≥ 0"),
                    ));
                }
                if g.get_ref().len() != dof {
                    return Err(self.err(
                        &g.span(),
                        format!(
                            "[robot] `{key}` has {} values: one per joint of the {} ({dof})",
                            g.get_ref().len(),
                            robot.name
                        ),
                    ));
                }
                *slot = Some(g.get_ref().clone());
            }
        }
        if let Some(d) = &r.drive {
            o.drive = cps_dynamics::Drive::parse(d.get_ref()).ok_or_else(|| {
                self.err(
                    &d.span(),
                    format!(
                        "[robot] `drive` = \"{}\" is not one of {}",
                        d.get_ref(),
                        cps_dynamics::Drive::NAMES
                    ),
                )
            })?;
        }
        if let Some(i) = &r.integrator {
            o.integrator = cps_dynamics::Integrator::parse(i.get_ref()).ok_or_else(|| {
                self.err(
                    &i.span(),
                    format!(
                        "[robot] `integrator` = \"{}\" is not one of euler, rk4",
                        i.get_ref()
                    ),
                )
            })?;
        }
        if let Some(n) = &r.noise {
            o.noise = self.within(n, "[robot] `noise`", 0.0, 0.1, " rad")?;
        }
        if let Some(s) = &r.seed {
            o.seed = *s.get_ref();
        }
        if let Some(c) = &r.calibration {
            o.calibration = Some(self.calibration(c, r, robot)?);
        }
        o.dt = match &r.dt {
            Some(d) => {
                let dt = self.within(d, "[robot] `dt`", 1e-3, 0.1, " s")?;
                let ms = dt * 1e3;
                if (ms - ms.round()).abs() > 1e-9 {
                    return Err(self.err(
                        &d.span(),
                        format!("[robot] `dt` = {dt} s must be a whole number of milliseconds (the dynamics robot is controlled every millisecond)"),
                    ));
                }
                dt
            }
            None => default_dt,
        };
        Ok(BackendChoice::Dynamics(o))
    }
}
