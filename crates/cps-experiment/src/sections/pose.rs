//! `[orientation]` of `kind = "viapoint_pose"`: start, goal and via orientations, and how
//! the orientation part is learned.

use cps_learn::ViaPointConfig;
use serde::Deserialize;
use toml::Spanned;

use super::Sections;
use crate::InputError;

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

impl Sections<'_> {
    pub(crate) fn orientation(
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

    pub(crate) fn pose_plan(
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
}
