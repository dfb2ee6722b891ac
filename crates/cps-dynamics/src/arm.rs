//! The simulated arm: its rigid bodies ([`ArmModel`]), its joints' friction, its torque
//! limits, and its state integrated one step at a time.
#![allow(clippy::needless_range_loop)] // joint-indexed loops over parallel fixed-size arrays

use cps_kinematics::contact::JointFriction;
use cps_kinematics::{ArmFrames, ArmModel};

/// franky-sim's FR3 drives, as its MJCF (`franky_sim/assets/fr3.xml`) gives them: rotor
/// inertia (`armature`, kg m²) per joint.
pub const FRANKY_SIM_ARMATURE: [f64; 7] = [0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074];

/// The speed (rad/s) over which a franky-sim joint's Coulomb friction rises to its level,
/// as `tanh(q̇ / speed)`. MuJoCo's `frictionloss` is a soft constraint: below its level a
/// torque makes the joint creep at a speed in proportion to it. Measured on franky-sim's
/// FR3 (MuJoCo, its 1 ms step, `implicitfast`, gravity and actuators off, half the
/// friction level on one joint at a time): the creep speed at the full level would be
/// 4.2, 0.87, 4.7, 3.1, 7.1, 3.7 and 3.4 mrad/s on joints 1 to 7. Of the smoothings
/// within that range, 5 mrad/s is the one whose contact observer agrees best with
/// MuJoCo's measured contact force on the shipped contact task (11.22 N in contact at a
/// 10 N profile, against 11.53 N at 4 mrad/s and 11.32 N at 10 mrad/s). The one value
/// the dynamics robot, the contact task's observer and identification use.
pub const FRANKY_SIM_COULOMB_SPEED: f64 = 0.005;

/// franky-sim's FR3 joint friction (its MJCF): viscous 0.21 N m s/rad (`damping`), Coulomb
/// 1.137 N m on joints 1–4, then 0.763, 0.44, 0.248 (`frictionloss`), smoothed over
/// [`FRANKY_SIM_COULOMB_SPEED`].
pub const FRANKY_SIM_FRICTION: JointFriction<7> = JointFriction {
    viscous: [0.21; 7],
    coulomb: [1.137, 1.137, 1.137, 1.137, 0.763, 0.44, 0.248],
    speed: FRANKY_SIM_COULOMB_SPEED,
};

/// How a step is integrated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Integrator {
    /// Semi-implicit (symplectic) Euler, MuJoCo's default: `q̇ += h·q̈`, then `q += h·q̇`.
    /// One evaluation of the dynamics a step.
    #[default]
    SemiImplicitEuler,
    /// The classical fourth-order Runge–Kutta method, the torque held over the step: four
    /// evaluations a step.
    Rk4,
}

impl Integrator {
    /// By name: `euler` or `rk4`.
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "euler" => Some(Integrator::SemiImplicitEuler),
            "rk4" => Some(Integrator::Rk4),
            _ => None,
        }
    }

    /// The name [`Integrator::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::SemiImplicitEuler => "euler",
            Integrator::Rk4 => "rk4",
        }
    }
}

/// An arm with dynamics: where it is, how fast it moves, and what moves it.
#[derive(Debug, Clone)]
pub struct Arm<const N: usize> {
    /// The rigid bodies, with the joints' rotor inertia (armature).
    pub model: ArmModel<N>,
    /// The joints' friction.
    pub friction: JointFriction<N>,
    /// The most torque each joint's drive gives (N m, > 0).
    pub torque_limit: [f64; N],
    /// How steps are integrated.
    pub integrator: Integrator,
    /// Joint positions (rad).
    pub q: [f64; N],
    /// Joint velocities (rad/s).
    pub dq: [f64; N],
}

impl<const N: usize> Arm<N> {
    /// The arm at rest at `q`.
    pub fn at_rest(
        model: ArmModel<N>,
        friction: JointFriction<N>,
        torque_limit: [f64; N],
        q: [f64; N],
    ) -> Self {
        Arm {
            model,
            friction,
            torque_limit,
            integrator: Integrator::default(),
            q,
            dq: [0.0; N],
        }
    }

    /// `tau` clipped to the drives' limits.
    pub fn clip(&self, tau: &[f64; N]) -> [f64; N] {
        std::array::from_fn(|i| tau[i].clamp(-self.torque_limit[i], self.torque_limit[i]))
    }

    /// The joint accelerations that `tau` gives at `q`, `dq`.
    fn acceleration(&self, q: &[f64; N], dq: &[f64; N], tau: &[f64; N]) -> [f64; N] {
        let f = self.model.frames(q);
        self.model
            .forward_dynamics(&f, dq, tau, Some(&self.friction))
    }

    /// Advances the arm by `h` seconds under the joint torques `tau` (already within the
    /// limits), `frames` being [`ArmModel::frames`] of the current positions (the
    /// controller's, reused).
    pub fn step(&mut self, frames: &ArmFrames<N>, tau: &[f64; N], h: f64) {
        match self.integrator {
            Integrator::SemiImplicitEuler => {
                let ddq = self
                    .model
                    .forward_dynamics(frames, &self.dq, tau, Some(&self.friction));
                for i in 0..N {
                    self.dq[i] += h * ddq[i];
                    self.q[i] += h * self.dq[i];
                }
            }
            Integrator::Rk4 => {
                let (q0, v0) = (self.q, self.dq);
                let a1 = self
                    .model
                    .forward_dynamics(frames, &v0, tau, Some(&self.friction));
                let shift = |x: &[f64; N], d: &[f64; N], s: f64| -> [f64; N] {
                    std::array::from_fn(|i| x[i] + s * d[i])
                };
                let (q2, v2) = (shift(&q0, &v0, h / 2.0), shift(&v0, &a1, h / 2.0));
                let a2 = self.acceleration(&q2, &v2, tau);
                let (q3, v3) = (shift(&q0, &v2, h / 2.0), shift(&v0, &a2, h / 2.0));
                let a3 = self.acceleration(&q3, &v3, tau);
                let (q4, v4) = (shift(&q0, &v3, h), shift(&v0, &a3, h));
                let a4 = self.acceleration(&q4, &v4, tau);
                for i in 0..N {
                    self.q[i] = q0[i] + h / 6.0 * (v0[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
                    self.dq[i] = v0[i] + h / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i]);
                }
            }
        }
    }

    /// Kinetic plus potential energy (J), the potential from the model's gravity: what an
    /// arm without friction or torque keeps.
    pub fn energy(&self) -> f64 {
        let f = self.model.frames(&self.q);
        let m = self.model.mass_matrix_crba(&f);
        let v = nalgebra::SVector::<f64, N>::from(self.dq);
        0.5 * v.dot(&(m * v)) + self.model.potential_energy(&f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cps_kinematics::robots::{PandaTool, panda, panda_inertia};

    fn arm(integrator: Integrator) -> Arm<7> {
        let model = ArmModel::<7>::new(&panda(PandaTool::HandTcp), &panda_inertia())
            .unwrap()
            .with_armature([0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074])
            .unwrap();
        let mut a = Arm::at_rest(
            model,
            JointFriction::none(),
            [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0],
            [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8],
        );
        a.integrator = integrator;
        a
    }

    /// The largest energy change over a free fall of `seconds` in steps of `h`, and the
    /// fastest joint speed reached.
    fn free_fall(integrator: Integrator, h: f64, seconds: f64) -> (f64, f64) {
        let mut a = arm(integrator);
        let e0 = a.energy();
        let (mut worst, mut moved): (f64, f64) = (0.0, 0.0);
        for _ in 0..(seconds / h).round() as usize {
            let f = a.model.frames(&a.q);
            a.step(&f, &[0.0; 7], h);
            worst = worst.max((a.energy() - e0).abs());
            moved = moved.max(a.dq.iter().fold(0.0, |m, v| m.max(v.abs())));
        }
        (worst, moved)
    }

    #[test]
    fn a_free_swing_keeps_its_energy_to_each_integrator_s_order() {
        // No torque, no friction: the arm falls and swings, and its energy stays what it
        // was up to the integrator's error, which shrinks with the step as its order says
        // (RK4: 4, semi-implicit Euler: 1).
        let (rk4, moved) = free_fall(Integrator::Rk4, 1e-3, 1.0);
        assert!(moved > 1.0, "the arm should fall: {moved} rad/s");
        let (rk4_half, _) = free_fall(Integrator::Rk4, 5e-4, 1.0);
        assert!(rk4 < 1e-6, "RK4 drift {rk4} J");
        assert!(
            rk4_half < rk4 / 8.0,
            "RK4: {rk4} J, halved step {rk4_half} J"
        );
        let (euler, _) = free_fall(Integrator::SemiImplicitEuler, 1e-3, 1.0);
        let (euler_tenth, _) = free_fall(Integrator::SemiImplicitEuler, 1e-4, 1.0);
        let ratio = euler / euler_tenth;
        assert!(
            (7.0..14.0).contains(&ratio),
            "Euler: {euler} J, a tenth of the step {euler_tenth} J"
        );
    }

    #[test]
    fn torques_are_clipped_to_the_drives() {
        let a = arm(Integrator::default());
        assert_eq!(
            a.clip(&[100.0, -100.0, 1.0, -1.0, 20.0, -20.0, 0.5]),
            [87.0, -87.0, 1.0, -1.0, 12.0, -12.0, 0.5]
        );
    }
}
