//! `[plant]` of `kind = "viapoint_energy"`: the point mass, its PD controller and the
//! effort weight.

use cps_learn::ViaPointConfig;
use serde::Deserialize;
use toml::Spanned;

use super::Sections;
use crate::InputError;

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

impl Sections<'_> {
    pub(crate) fn energy_plan(&self, learner: &ViaPointConfig) -> Result<EnergyPlan, InputError> {
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
}
