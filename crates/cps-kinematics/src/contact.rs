//! Contact sensing from joint torques: the generalized-momentum observer (De Luca &
//! Mattone 2003; De Luca, Albu-Schäffer, Haddadin & Hirzinger 2006, "Collision detection
//! and safe reaction with the DLR-III lightweight manipulator arm"), the external wrench
//! at the tool it implies, and a contact flag with hysteresis.
//!
//! With `p = M(q)·q̇` the arm's generalized momentum, the dynamics give
//! `ṗ = τ + Cᵀ(q, q̇)·q̇ − g(q) + τ_ext`. The observer integrates the known part and
//! compares it with the measured momentum:
//!
//! `r(t) = K_O · ( p(t) − p(0) − ∫₀ᵗ (τ + Cᵀq̇ − g + r) ds )`,
//!
//! so that `ṙ = K_O·(τ_ext − r)`: each joint's residual follows the external torque as a
//! first-order filter of time constant `1/K_O`, with no joint acceleration needed. `Cᵀq̇`
//! is taken as `Ṁq̇ − Cq̇` (the property `Ṁ = C + Cᵀ`), `Ṁ` from the mass matrices of
//! consecutive ticks. The wrench at the tool is the damped least-squares solution of
//! `Jᵀ·F = r`.
#![allow(clippy::needless_range_loop)] // joint-indexed loops over parallel fixed-size arrays

use nalgebra::{Matrix6, SMatrix, SVector};

use crate::{ArmFrames, ArmModel, KinematicsError};

/// The generalized-momentum observer of an `N`-joint arm: each joint's residual follows its
/// external torque as a first-order filter of time constant 1/gain.
#[derive(Debug, Clone)]
pub struct MomentumObserver<const N: usize> {
    gain: [f64; N],
    friction: JointFriction<N>,
    started: bool,
    p0: SVector<f64, N>,
    integral: SVector<f64, N>,
    residual: SVector<f64, N>,
    last_mass: SMatrix<f64, N, N>,
}

impl<const N: usize> MomentumObserver<N> {
    /// An observer with gain `gain[i]` per joint (1/s; the residual's bandwidth). De Luca et
    /// al. use 25–100 /s at 1 kHz; above `0.5/dt` the discrete filter rings.
    pub fn new(gain: [f64; N]) -> Result<Self, KinematicsError> {
        if let Some((i, g)) = gain
            .iter()
            .enumerate()
            .find(|(_, g)| !(g.is_finite() && **g > 0.0 && **g <= 500.0))
        {
            return Err(KinematicsError::InvalidModel(format!(
                "momentum observer: joint {}'s gain {g} /s must lie in (0, 500]",
                i + 1
            )));
        }
        Ok(MomentumObserver {
            gain,
            friction: JointFriction::none(),
            started: false,
            p0: SVector::zeros(),
            integral: SVector::zeros(),
            residual: SVector::zeros(),
            last_mass: SMatrix::zeros(),
        })
    }

    /// The same observer for torques measured before the joints' friction (at the motor,
    /// as a simulator's applied torques are): the friction `friction` predicts is taken
    /// off them, so it is not read as an external torque.
    pub fn with_friction(mut self, friction: JointFriction<N>) -> Self {
        self.friction = friction;
        self
    }

    /// Starts over at the next update (the residual reads zero there).
    pub fn reset(&mut self) {
        self.started = false;
        self.residual = SVector::zeros();
    }

    /// The current estimate of the external joint torques (N m).
    pub fn residual(&self) -> SVector<f64, N> {
        self.residual
    }

    /// One tick: the arm at `frames` (its positions) with velocities `dq` under the joint
    /// torques `tau` (the measured link-side torques, gravity included), `dt` seconds after
    /// the previous update. Returns the external joint torques' estimate.
    pub fn update(
        &mut self,
        model: &ArmModel<N>,
        frames: &ArmFrames<N>,
        dq: &[f64; N],
        tau: &[f64; N],
        dt: f64,
    ) -> SVector<f64, N> {
        let mass = model.mass_matrix(frames);
        let v = SVector::from(*dq);
        let p = mass * v;
        if !self.started {
            self.started = true;
            self.p0 = p;
            self.integral = SVector::zeros();
            self.residual = SVector::zeros();
            self.last_mass = mass;
            return self.residual;
        }
        let m_dot = if dt > 0.0 {
            (mass - self.last_mass) / dt
        } else {
            SMatrix::zeros()
        };
        self.last_mass = mass;
        let coriolis_t = m_dot * v - model.coriolis(frames, dq);
        let mut beta = SVector::from(*tau) + coriolis_t - model.gravity(frames);
        for i in 0..N {
            beta[i] -= self.friction.torque(i, dq[i]);
        }
        self.integral += (beta + self.residual) * dt;
        let error = p - self.p0 - self.integral;
        for i in 0..N {
            self.residual[i] = self.gain[i] * error[i];
        }
        self.residual
    }
}

/// Friction in each joint: viscous `F_v·q̇` plus Coulomb `F_c·tanh(q̇/v_s)` (N m), the
/// smooth sign keeping the estimate continuous through zero speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointFriction<const N: usize> {
    /// Viscous coefficient per joint (N m s/rad).
    pub viscous: [f64; N],
    /// Coulomb level per joint (N m).
    pub coulomb: [f64; N],
    /// The speed below which the Coulomb term fades to zero (rad/s).
    pub speed: f64,
}

impl<const N: usize> JointFriction<N> {
    /// No friction.
    pub fn none() -> Self {
        JointFriction {
            viscous: [0.0; N],
            coulomb: [0.0; N],
            speed: 0.01,
        }
    }

    /// Checks that every coefficient is finite and ≥ 0 and the speed > 0.
    pub fn check(&self) -> Result<(), KinematicsError> {
        let bad = self
            .viscous
            .iter()
            .chain(&self.coulomb)
            .any(|v| !(v.is_finite() && *v >= 0.0));
        if bad || !(self.speed.is_finite() && self.speed > 0.0) {
            return Err(KinematicsError::InvalidModel(
                "joint friction: every coefficient must be finite and ≥ 0, the speed > 0".into(),
            ));
        }
        Ok(())
    }

    /// The friction torque of joint `i` moving at `dq` (it opposes the motion: the joint
    /// loses this much of the torque driving it).
    pub fn torque(&self, i: usize, dq: f64) -> f64 {
        self.viscous[i] * dq + self.coulomb[i] * (dq / self.speed).tanh()
    }
}

/// The wrench `[fx, fy, fz, mx, my, mz]` at the tool (world axes, about the tool point)
/// that explains external joint torques `tau_ext` at `frames`: the damped least-squares
/// solution `(J Jᵀ + λ²I)⁻¹ J τ_ext` (λ in metres; 0.01 keeps it bounded near a
/// singularity). The torques are those the arm feels from the world, so a hand pressed
/// down on a table reads a positive z force (the table pushes up).
pub fn external_wrench<const N: usize>(
    frames: &ArmFrames<N>,
    tau_ext: &SVector<f64, N>,
    damping: f64,
) -> SVector<f64, 6> {
    let j = frames.jacobian();
    let a: Matrix6<f64> = j * j.transpose() + Matrix6::identity() * (damping * damping);
    a.cholesky()
        .map(|c| c.solve(&(j * tau_ext)))
        .unwrap_or_else(SVector::zeros)
}

/// A contact flag with hysteresis: raised when the measure (a force, N) exceeds `on`,
/// lowered when it falls below `off`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactFlag {
    on: f64,
    off: f64,
    raised: bool,
}

impl ContactFlag {
    /// A flag raised above `on` and lowered below `off` (`0 ≤ off ≤ on`).
    pub fn new(on: f64, off: f64) -> Result<Self, KinematicsError> {
        if !(on.is_finite() && off.is_finite() && 0.0 <= off && off <= on) {
            return Err(KinematicsError::InvalidModel(format!(
                "contact flag: thresholds on {on} and off {off} must be finite with 0 ≤ off ≤ on"
            )));
        }
        Ok(ContactFlag {
            on,
            off,
            raised: false,
        })
    }

    /// Updates the flag with the current measure; returns whether it is raised.
    pub fn update(&mut self, measure: f64) -> bool {
        if self.raised {
            self.raised = measure >= self.off;
        } else {
            self.raised = measure > self.on;
        }
        self.raised
    }

    /// Whether the flag is raised.
    pub fn raised(&self) -> bool {
        self.raised
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robots::{PandaTool, panda, panda_inertia};

    /// Simulates the Panda (semi-implicit Euler at 0.1 ms) held by a PD law
    /// while `push(t)` acts at the tool; the observer runs at 1 kHz on the simulated state.
    /// Returns (t, applied wrench, estimated wrench) per millisecond.
    fn simulate(push: impl Fn(f64) -> [f64; 6], seconds: f64) -> Vec<(f64, [f64; 6], [f64; 6])> {
        let model = ArmModel::<7>::new(&panda(PandaTool::HandTcp), &panda_inertia()).unwrap();
        let mut observer = MomentumObserver::new([100.0; 7]).unwrap();
        let home = [0.0, -0.5, 0.0, -2.2, 0.0, 1.8, 0.8];
        let (mut q, mut dq) = (home, [0.0; 7]);
        let mut out = Vec::new();
        let h = 1e-4;
        let mut tau = [0.0; 7];
        for step in 0..(seconds / h).round() as usize {
            let t = step as f64 * h;
            let f = model.frames(&q);
            if step % 10 == 0 {
                // The controller and the observer, at 1 kHz.
                // Held by a PD law shaped by the mass matrix (stable at 1 kHz on the wrist).
                let mut pd = SVector::<f64, 7>::zeros();
                for i in 0..7 {
                    pd[i] = 100.0 * (home[i] - q[i]) - 20.0 * dq[i];
                }
                let held = model.mass_matrix(&f) * pd + model.gravity(&f);
                tau = held.into();
                let r = observer.update(&model, &f, &dq, &tau, if step == 0 { 0.0 } else { 1e-3 });
                let w = external_wrench(&f, &r, 0.0);
                out.push((t, push(t), [w[0], w[1], w[2], w[3], w[4], w[5]]));
            }
            let wrench = SVector::<f64, 6>::from(push(t));
            let rhs = SVector::from(tau) + f.jacobian().transpose() * wrench
                - model.coriolis(&f, &dq)
                - model.gravity(&f);
            let ddq = model.mass_matrix(&f).cholesky().unwrap().solve(&rhs);
            for i in 0..7 {
                dq[i] += ddq[i] * h;
                q[i] += dq[i] * h;
            }
        }
        out
    }

    #[test]
    fn the_observer_recovers_a_wrench_pushed_on_the_tool() {
        let push = |t: f64| {
            if t < 0.2 {
                [0.0; 6]
            } else {
                [3.0 * (8.0 * t).sin(), -4.0, 10.0, 0.5, -0.3, 0.2]
            }
        };
        let run = simulate(push, 1.0);
        // Free of contact, the estimate stays near zero while the arm holds still.
        for (t, _, w) in run.iter().filter(|(t, ..)| *t < 0.2) {
            assert!(w.iter().all(|v| v.abs() < 1e-6), "{t}: {w:?}");
        }
        // 100 ms after the push starts (10 time constants) it follows the wrench within
        // what a first-order filter of 10 ms lags behind a 3 N, 8 rad/s wave (0.25 N).
        for (t, applied, w) in run.iter().filter(|(t, ..)| *t > 0.3) {
            for k in 0..6 {
                assert!((applied[k] - w[k]).abs() < 0.3, "{t}: {applied:?} vs {w:?}");
            }
        }
    }

    #[test]
    fn the_residual_follows_a_step_as_a_first_order_filter() {
        let run = simulate(
            |t| {
                if t < 0.1 {
                    [0.0; 6]
                } else {
                    [0.0, 0.0, 10.0, 0.0, 0.0, 0.0]
                }
            },
            0.2,
        );
        // At 1 kHz the filter is r_k = (1 − K·dt)·r_(k−1) + K·dt·τ_ext: ten ticks after the
        // step, 1 − 0.9¹⁰ = 65 % of it (the continuous filter's 1 − e⁻¹ = 63 %).
        let at = |t: f64| run.iter().find(|(s, ..)| (s - t).abs() < 1e-9).unwrap().2[2];
        let expected = 10.0 * (1.0 - 0.9f64.powi(10));
        assert!(
            (at(0.110) - expected).abs() < 0.2,
            "{} vs {expected}",
            at(0.110)
        );
        assert!((at(0.199) - 10.0).abs() < 0.1, "{}", at(0.199));
        let mut flag = ContactFlag::new(3.0, 1.5).unwrap();
        let first = run.iter().find(|(_, _, w)| flag.update(w[2])).unwrap().0;
        // 3 N of 10 N: t = −ln(0.7)/K = 3.6 ms after the step.
        assert!((first - 0.1).abs() < 0.006, "{first}");
    }

    #[test]
    fn bad_gains_and_thresholds_are_named() {
        let e = MomentumObserver::<7>::new([100.0, 100.0, -1.0, 100.0, 100.0, 100.0, 100.0])
            .unwrap_err();
        assert!(e.to_string().contains("joint 3's gain -1"), "{e}");
        assert!(ContactFlag::new(1.0, 2.0).is_err());
        let mut f = ContactFlag::new(3.0, 1.0).unwrap();
        assert!(!f.update(2.9) && f.update(3.1) && f.update(1.5) && !f.update(0.9));
    }
}
