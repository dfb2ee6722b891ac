//! `[demonstrations]` and `[imitation]` of `kind = "imitation"` (and `"promp"`): how many
//! demonstrations are learned, or which motion-capture takes are the demonstrations, and
//! the imitating DMP.

use std::ops::Range;
use std::path::Path;

use cps_dmp::{DmpConfig, Lambda};
use cps_learn::ViaPointConfig;
use serde::Deserialize;
use toml::Spanned;

use super::Sections;
use crate::InputError;

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
    /// A LeRobot dataset's folder, relative to the experiment file: its episodes' joint
    /// states, through the robot's kinematics, are the demonstrations.
    lerobot: Option<Spanned<String>>,
    /// Which of the dataset's episodes (default: all).
    episodes: Option<Spanned<Vec<usize>>>,
    /// Which feature of the dataset (default `observation.state`).
    feature: Option<Spanned<String>>,
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
    /// `robust` (default: a shape kept from a new start or goal) or `ijspeert` (the
    /// thesis's: the forcing term scales with goal − start).
    formulation: Option<Spanned<String>>,
}

/// The imitation pipeline's settings beyond the learner and the robot.
#[derive(Debug, Clone, PartialEq)]
pub struct ImitationPlan {
    /// Number of demonstrations.
    pub demonstrations: usize,
    /// Demonstrations given: motion-capture takes (`[demonstrations] takes`) or a LeRobot
    /// dataset's episodes through the robot's kinematics (`[demonstrations] lerobot`), in
    /// the task's frame; when there are any they replace the learned ones.
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

impl Sections<'_> {
    /// `[demonstrations] takes`: each take read and made a demonstration (its errors name
    /// the take, and the key's place in the experiment file).
    pub(crate) fn takes(
        &self,
        robot: Option<&crate::sections::robot::RobotChoice>,
    ) -> Result<Vec<cps_learn::GivenDemonstration>, InputError> {
        let Some(d) = self.demonstrations.map(Spanned::get_ref) else {
            return Ok(Vec::new());
        };
        if d.lerobot.is_some() || d.episodes.is_some() || d.feature.is_some() {
            return self.lerobot(d, robot);
        }
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
        let demos = cps_movement::mocap::demonstrations(
            dir,
            takes.get_ref(),
            &settings,
            calibration.as_deref(),
        )
        .map_err(|e| at(takes.span(), "takes")(e.0))?;
        Ok(demos
            .into_iter()
            .map(|(name, trajectory)| cps_learn::GivenDemonstration { name, trajectory })
            .collect())
    }

    /// `[demonstrations] lerobot`: the dataset's picked episodes, their entries matched
    /// to the experiment robot's joints by name, each frame's tool position by the
    /// robot's kinematics (base placed in the world, tool point set).
    fn lerobot(
        &self,
        d: &DemonstrationsSection,
        robot: Option<&crate::sections::robot::RobotChoice>,
    ) -> Result<Vec<cps_learn::GivenDemonstration>, InputError> {
        let Some(folder) = &d.lerobot else {
            let span = d
                .episodes
                .as_ref()
                .map(Spanned::span)
                .or(d.feature.as_ref().map(Spanned::span))
                .unwrap_or(0..0);
            return Err(self.err(
                &span,
                "[demonstrations] `episodes` and `feature` pick from a LeRobot dataset: add `lerobot = \"folder\"`".into(),
            ));
        };
        for (v, key) in [
            (d.takes.as_ref().map(Spanned::span), "takes"),
            (d.count.as_ref().map(Spanned::span), "count"),
            (d.via_std.as_ref().map(Spanned::span), "via_std"),
        ] {
            if let Some(span) = v {
                return Err(self.err(
                    &span,
                    format!("[demonstrations] `{key}` cannot go with `lerobot`: the dataset's episodes are the demonstrations"),
                ));
            }
        }
        let Some(robot) = robot else {
            return Err(self.err(
                &folder.span(),
                "[demonstrations] `lerobot` needs the experiment's robot".into(),
            ));
        };
        let dir = self.path.parent().unwrap_or(Path::new("."));
        let pick = cps_movement::lerobot::Pick {
            episodes: d.episodes.as_ref().map(|e| e.get_ref().clone()),
            feature: d
                .feature
                .as_ref()
                .map_or("observation.state".into(), |f| f.get_ref().clone()),
            robot: None,
        };
        let at = |e: InputError| {
            self.err(
                &folder.span(),
                format!("[demonstrations] `lerobot`: {}", e.0),
            )
        };
        let joints = robot.model.published_joint_names();
        let (_, demos) = cps_movement::lerobot::joint_demonstrations(
            &dir.join(folder.get_ref()),
            &pick,
            &joints,
        )
        .map_err(at)?;
        demos
            .into_iter()
            .map(|(name, demo)| {
                let mut position: Vec<Vec<f64>> =
                    (0..3).map(|_| Vec::with_capacity(demo.len())).collect();
                for k in 0..demo.len() {
                    let tool = robot
                        .setup
                        .chain
                        .fk(demo.sample(k))
                        .map_err(|e| at(InputError(format!("{name}, frame {k}: {e}"))))?;
                    for (axis, p) in position.iter_mut().enumerate() {
                        p.push(tool.translation.vector[axis]);
                    }
                }
                let zeros = vec![vec![0.0; demo.len()]; 3];
                Ok(cps_learn::GivenDemonstration {
                    name,
                    trajectory: cps_dmp::Trajectory::from_parts(
                        demo.times().to_vec(),
                        &position,
                        &zeros,
                        &zeros,
                    ),
                })
            })
            .collect()
    }

    pub(crate) fn imitation_plan(
        &self,
        learner: &ViaPointConfig,
        robot: Option<&crate::sections::robot::RobotChoice>,
    ) -> Result<ImitationPlan, InputError> {
        let takes = self.takes(robot)?;
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
        dmp.formulation = match i.and_then(|i| i.formulation.as_ref()) {
            None => cps_dmp::Formulation::GoalRobust,
            Some(f) => f
                .get_ref()
                .parse()
                .map_err(|e| self.err(&f.span(), format!("[imitation] `formulation`: {e}")))?,
        };
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
