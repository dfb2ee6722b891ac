//! Joint-level controllers: the torques a robot's own controller gives its drives each
//! control period, from what it measures and what it is asked.
//!
//! Each computes the torque it commands without gravity; the robot clips that to its
//! drives' limits, adds the gravity torques (which the robot cancels itself, as a Franka
//! and franky-sim do) and clips again.

use cps_kinematics::{ArmFrames, ArmModel};

/// What the controller is asked for at one control period: positions, velocities and
/// accelerations (rad, rad/s, rad/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Desired<'a> {
    /// Positions.
    pub q: &'a [f64],
    /// Velocities.
    pub dq: &'a [f64],
    /// Accelerations.
    pub ddq: &'a [f64],
}

/// A joint-level controller and its gains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Controller<const N: usize> {
    /// franky-sim's position controller: `kp·(q_d − q) − kv·q̇` plus the Coriolis and
    /// centrifugal torques — no velocity or acceleration feed-forward, so a joint that
    /// follows a steady motion lags it by `kv/kp` seconds.
    JointPd {
        /// Stiffness per joint (N m/rad).
        kp: [f64; N],
        /// Damping per joint (N m s/rad).
        kv: [f64; N],
    },
    /// Computed torque: `M(q)·(q̈_d + kv·(q̇_d − q̇) + kp·(q_d − q))` plus the Coriolis
    /// and centrifugal torques — the model's inverse dynamics fed forward, so the error
    /// obeys `ë + kv·ė + kp·e = 0` while the model is the robot.
    ComputedTorque {
        /// Position gain per joint (1/s²).
        kp: [f64; N],
        /// Velocity gain per joint (1/s).
        kv: [f64; N],
    },
    /// Joint impedance, as cps's torque mode runs it on a Franka: `K·(q_d − q) + D·(q̇_d −
    /// q̇)` plus the Coriolis and centrifugal torques.
    JointImpedance {
        /// Stiffness per joint (N m/rad).
        stiffness: [f64; N],
        /// Damping per joint (N m s/rad).
        damping: [f64; N],
    },
}

/// franky-sim's position gains on the FR3 (its `MujocoSimulator` defaults): kp per joint
/// (N m/rad); kv is a tenth of it.
pub const FRANKY_SIM_KP: [f64; 7] = [4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0];

/// The controller names [`Controller::name`] gives.
pub const CONTROLLERS: [&str; 3] = ["joint_pd", "computed_torque", "joint_impedance"];

impl Controller<7> {
    /// franky-sim's own joint controller ([`FRANKY_SIM_KP`], kv = kp/10).
    pub fn franky_sim() -> Self {
        Controller::JointPd {
            kp: FRANKY_SIM_KP,
            kv: FRANKY_SIM_KP.map(|k| k / 10.0),
        }
    }
}

impl<const N: usize> Controller<N> {
    /// The controller named `name` ([`CONTROLLERS`]) with its two gain vectors, in the
    /// order its variant lists them. Refused: an unknown name, a gain that is negative or
    /// not finite (the sentence names the gain and the joint).
    pub fn by_name(name: &str, first: [f64; N], second: [f64; N]) -> Result<Self, String> {
        let (a, b) = match name {
            "joint_pd" => ("kp", "kv"),
            "computed_torque" => ("kp", "kv"),
            "joint_impedance" => ("stiffness", "damping"),
            other => {
                return Err(format!(
                    "controller `{other}` is not one of {}",
                    CONTROLLERS.join(", ")
                ));
            }
        };
        for (gain, values) in [(a, &first), (b, &second)] {
            if let Some((i, v)) = values
                .iter()
                .enumerate()
                .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
            {
                return Err(format!(
                    "{name}'s {gain} of joint {} is {v}: it must be finite and ≥ 0",
                    i + 1
                ));
            }
        }
        Ok(match name {
            "joint_pd" => Controller::JointPd {
                kp: first,
                kv: second,
            },
            "computed_torque" => Controller::ComputedTorque {
                kp: first,
                kv: second,
            },
            _ => Controller::JointImpedance {
                stiffness: first,
                damping: second,
            },
        })
    }

    /// Its name ([`CONTROLLERS`]).
    pub fn name(&self) -> &'static str {
        match self {
            Controller::JointPd { .. } => "joint_pd",
            Controller::ComputedTorque { .. } => "computed_torque",
            Controller::JointImpedance { .. } => "joint_impedance",
        }
    }

    /// The torques it commands (N m, gravity not included) at the measured `q`, `dq`
    /// (`frames` = `model.frames(q)`) for `desired`.
    pub fn torques(
        &self,
        model: &ArmModel<N>,
        frames: &ArmFrames<N>,
        dq: &[f64; N],
        desired: Desired<'_>,
    ) -> [f64; N] {
        let q = &frames.q;
        let coriolis = model.coriolis(frames, dq);
        match self {
            Controller::JointPd { kp, kv } => {
                std::array::from_fn(|i| kp[i] * (desired.q[i] - q[i]) - kv[i] * dq[i] + coriolis[i])
            }
            Controller::ComputedTorque { kp, kv } => {
                let a = nalgebra::SVector::<f64, N>::from_fn(|i, _| {
                    desired.ddq[i] + kv[i] * (desired.dq[i] - dq[i]) + kp[i] * (desired.q[i] - q[i])
                });
                let t = model.mass_matrix_crba(frames) * a + coriolis;
                t.into()
            }
            Controller::JointImpedance { stiffness, damping } => std::array::from_fn(|i| {
                stiffness[i] * (desired.q[i] - q[i])
                    + damping[i] * (desired.dq[i] - dq[i])
                    + coriolis[i]
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_controllers_are_named() {
        let ok = [1.0; 7];
        assert!(
            Controller::<7>::by_name("pid", ok, ok)
                .unwrap_err()
                .contains("`pid` is not one of joint_pd, computed_torque, joint_impedance")
        );
        let mut bad = ok;
        bad[2] = -5.0;
        assert_eq!(
            Controller::<7>::by_name("joint_pd", ok, bad).unwrap_err(),
            "joint_pd's kv of joint 3 is -5: it must be finite and ≥ 0"
        );
        assert_eq!(
            Controller::<7>::by_name("joint_impedance", [f64::NAN; 7], ok).unwrap_err(),
            "joint_impedance's stiffness of joint 1 is NaN: it must be finite and ≥ 0"
        );
        assert_eq!(Controller::franky_sim().name(), "joint_pd");
    }
}
