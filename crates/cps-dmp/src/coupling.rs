//! Coupling terms for point obstacles, and rollouts that feel them.
//!
//! A coupling term `C(y, ẏ)` is added to the transformation system beside the forcing
//! term, in its units: `τ ż = α_z (β_z (g − y) − z) + f + C` (so `C = τ² ÿ` per unit, an
//! acceleration for τ = 1 s). It depends on the state, so a coupled movement is no longer
//! affine in the weights: [`DiscreteDmp::rollout_coupled`] steps the movement on the
//! DMP's grid with the same exact discretisation as [`crate::OnlineDmp`], the coupling
//! evaluated at the start of each step and held over it.
//!
//! Two obstacle terms, for task-space positions (any dimension ≥ 2; written for 2-D and
//! 3-D):
//! - [`SteeringAngle`] (Hoffmann et al. 2009, ICRA, eq. 14–16): the velocity is turned away
//!   from the obstacle at a rate `γ φ exp(−β φ)`, `φ` the angle between the velocity and
//!   the direction to the obstacle; `C = γ R ẏ φ exp(−β φ)` with `R` the rotation by 90°
//!   about `(o − y) × ẏ`. Defaults `γ = 1000`, `β = 20/π` (the paper's).
//! - [`DynamicPotential`] (Park et al. 2008, Humanoids, eq. 12–13): the gradient of
//!   `U = λ (−cos θ)^β ‖ẏ‖ / p`, `p = ‖y − o‖` and `θ` the angle between the velocity and
//!   `y − o`, active only while moving towards the obstacle (`cos θ < 0`); `C = −∇_y U`.
//!   Defaults `λ = 10`, `β = 2`.
//!
//! The rotation `R ẏ` is written without a cross product, `(ẏ (ẏ·a) − a ‖ẏ‖²) /
//! ‖a × ẏ‖` with `a = o − y` and `‖a × ẏ‖² = ‖a‖²‖ẏ‖² − (a·ẏ)²`, so it holds in any
//! dimension. Heading straight at an obstacle (`φ = 0`) or standing still gives no push.

use crate::config::positive;
use crate::{DiscreteDmp, DmpError, OnlineDmp, StepInput, Trajectory};

/// A state-dependent term added to the transformation system (see the module docs).
pub trait Coupling: Sync {
    /// Writes the coupling per dimension at position `y` with physical velocity `v` into
    /// `out` (same length), in the units of the forcing term; it must add to `out`, not
    /// overwrite it, so several terms can be summed.
    fn add(&self, y: &[f64], v: &[f64], out: &mut [f64]);
}

/// Checks an obstacle position: at least 2 finite coordinates.
fn check_obstacle(position: &[f64]) -> Result<(), DmpError> {
    if position.len() < 2 {
        return Err(DmpError::DimensionMismatch {
            what: "obstacle (a task-space point of 2 or more coordinates)",
            got: position.len(),
            expected: 2,
        });
    }
    if let Some((index, &value)) = position.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(DmpError::NotFinite {
            what: "obstacle",
            index,
            value,
        });
    }
    Ok(())
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Refuses an obstacle that sits on the movement's start or goal (within `clearance`,
/// in the task's units): no coupling can keep a movement away from where it must begin or
/// end. `name` names the obstacle in the message.
pub fn check_endpoints(
    start: &[f64],
    goal: &[f64],
    obstacle: &[f64],
    clearance: f64,
    name: &str,
) -> Result<(), DmpError> {
    for (what, p) in [("start", start), ("goal", goal)] {
        let n = p.len().min(obstacle.len());
        let d = (0..n)
            .map(|i| (p[i] - obstacle[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        if d <= clearance {
            return Err(DmpError::BlockedEndpoint(format!(
                "{name} is {d:.3e} from the movement's {what} (closer than {clearance}): the movement cannot avoid a point it must pass; move the obstacle or the {what}"
            )));
        }
    }
    Ok(())
}

/// Hoffmann et al.'s steering-angle term for a point obstacle (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct SteeringAngle {
    obstacle: Vec<f64>,
    gamma: f64,
    beta: f64,
}

impl SteeringAngle {
    /// The term for an obstacle at `obstacle` with the paper's gains `γ = 1000`,
    /// `β = 20/π`.
    pub fn new(obstacle: &[f64]) -> Result<Self, DmpError> {
        Self::with_gains(obstacle, 1000.0, 20.0 / std::f64::consts::PI)
    }

    /// The term with gains `gamma` (strength) and `beta` (how fast it fades with the
    /// angle), both > 0.
    pub fn with_gains(obstacle: &[f64], gamma: f64, beta: f64) -> Result<Self, DmpError> {
        check_obstacle(obstacle)?;
        positive("gamma", gamma)?;
        positive("beta", beta)?;
        Ok(Self {
            obstacle: obstacle.to_vec(),
            gamma,
            beta,
        })
    }

    /// The obstacle's position.
    pub fn obstacle(&self) -> &[f64] {
        &self.obstacle
    }
}

impl Coupling for SteeringAngle {
    fn add(&self, y: &[f64], v: &[f64], out: &mut [f64]) {
        let n = self.obstacle.len().min(y.len());
        let a: Vec<f64> = (0..n).map(|i| self.obstacle[i] - y[i]).collect();
        let v = &v[..n];
        let (aa, vv, av) = (dot(&a, &a), dot(v, v), dot(&a, v));
        let cross2 = aa * vv - av * av;
        if cross2 <= 1e-300 * (aa * vv).max(1e-300) || aa == 0.0 || vv == 0.0 {
            return;
        }
        let phi = (av / (aa * vv).sqrt()).clamp(-1.0, 1.0).acos();
        let gain = self.gamma * phi * (-self.beta * phi).exp() / cross2.sqrt();
        for i in 0..n {
            out[i] += gain * (v[i] * av - a[i] * vv);
        }
    }
}

/// Park et al.'s dynamic potential field for a point obstacle (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicPotential {
    obstacle: Vec<f64>,
    lambda: f64,
    beta: f64,
}

impl DynamicPotential {
    /// The term for an obstacle at `obstacle` with `λ = 10`, `β = 2`.
    pub fn new(obstacle: &[f64]) -> Result<Self, DmpError> {
        Self::with_gains(obstacle, 10.0, 2.0)
    }

    /// The term with gains `lambda` (strength) and `beta` (≥ 1: how narrowly it acts
    /// around the direction of motion).
    pub fn with_gains(obstacle: &[f64], lambda: f64, beta: f64) -> Result<Self, DmpError> {
        check_obstacle(obstacle)?;
        positive("lambda", lambda)?;
        if !(beta.is_finite() && beta >= 1.0) {
            return Err(DmpError::InvalidConfig {
                field: "beta",
                rule: "must be finite and ≥ 1",
                value: beta,
            });
        }
        Ok(Self {
            obstacle: obstacle.to_vec(),
            lambda,
            beta,
        })
    }

    /// The obstacle's position.
    pub fn obstacle(&self) -> &[f64] {
        &self.obstacle
    }
}

impl Coupling for DynamicPotential {
    fn add(&self, y: &[f64], v: &[f64], out: &mut [f64]) {
        let n = self.obstacle.len().min(y.len());
        // x: from the obstacle to the position.
        let x: Vec<f64> = (0..n).map(|i| y[i] - self.obstacle[i]).collect();
        let v = &v[..n];
        let p = dot(&x, &x).sqrt();
        let speed = dot(v, v).sqrt();
        if p == 0.0 || speed == 0.0 {
            return;
        }
        let vx = dot(v, &x);
        let cos = vx / (speed * p);
        if cos >= 0.0 {
            return; // moving away: no potential
        }
        let m = -cos;
        // −∇U = λ‖v‖ [β m^(β−1) ∇cos / p + m^β x / p³], ∇cos = v/(‖v‖p) − (v·x) x/(‖v‖p³).
        let (mb1, mb) = (m.powf(self.beta - 1.0), m.powf(self.beta));
        let k = self.lambda * speed;
        for i in 0..n {
            let grad_cos = v[i] / (speed * p) - vx * x[i] / (speed * p * p * p);
            out[i] += k * (self.beta * mb1 * grad_cos / p + mb * x[i] / (p * p * p));
        }
    }
}

/// The sum of several coupling terms (several obstacles, or both kinds).
#[derive(Default)]
pub struct Couplings(pub Vec<Box<dyn Coupling>>);

impl Coupling for Couplings {
    fn add(&self, y: &[f64], v: &[f64], out: &mut [f64]) {
        for c in &self.0 {
            c.add(y, v, out);
        }
    }
}

impl OnlineDmp {
    /// One step of `dt` seconds with the push of `coupling` (e.g. obstacles) evaluated at
    /// the current position and velocity and held over the step, as
    /// [`DiscreteDmp::rollout_coupled`] does.
    pub fn step_coupled(&mut self, dt: f64, coupling: &dyn Coupling) -> Result<(), DmpError> {
        let dims = self.position().len();
        self.step_coupled_in(dt, coupling, &mut vec![0.0; dims], &mut vec![0.0; dims])
    }

    /// [`Self::step_coupled`] with the velocity and the push computed in `v` and `c`
    /// (the DMP's dimension each), so a loop of steps allocates nothing.
    fn step_coupled_in(
        &mut self,
        dt: f64,
        coupling: &dyn Coupling,
        v: &mut [f64],
        c: &mut [f64],
    ) -> Result<(), DmpError> {
        self.velocity_into(v);
        c.fill(0.0);
        coupling.add(self.position(), v, c);
        self.step_with(
            dt,
            StepInput {
                coupling: Some(c),
                tracking_error: 0.0,
            },
        )
    }
}

impl DiscreteDmp {
    /// The movement with `weights` under `coupling`, on the DMP's grid: stepped with the
    /// exact discretisation of [`OnlineDmp`], the coupling evaluated at the start of each
    /// step (with the velocity there) and held over it. With a coupling that is always zero
    /// it equals [`DiscreteDmp::rollout`] to rounding.
    ///
    /// # Panics
    /// If `weights.len() != self.n_weights()`.
    pub fn rollout_coupled(&self, weights: &[f64], coupling: &dyn Coupling) -> Trajectory {
        let dims = self.dims();
        let times = self.times().to_vec();
        let n = times.len();
        let mut runner = OnlineDmp::new(self, weights);
        let mut traj = Trajectory::zeros(dims, times.clone());
        let (mut v, mut c) = (vec![0.0; dims], vec![0.0; dims]);
        let record = |traj: &mut Trajectory, k: usize, r: &OnlineDmp, v: &mut [f64]| {
            r.velocity_into(v);
            for (d, &v) in v.iter().enumerate() {
                let i = d * n + k;
                traj.position[i] = r.position()[d];
                traj.velocity[i] = v;
                traj.acceleration[i] = r.acceleration()[d];
                traj.forcing[i] = r.forcing()[d];
            }
        };
        record(&mut traj, 0, &runner, &mut v);
        for k in 1..n {
            runner
                .step_coupled_in(times[k] - times[k - 1], coupling, &mut v, &mut c)
                .expect("grid steps are positive");
            record(&mut traj, k, &runner, &mut v);
        }
        traj
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DmpConfig;

    #[test]
    fn the_steering_term_turns_the_velocity_away_by_the_papers_rate() {
        let s = SteeringAngle::new(&[1.0, 0.1]).unwrap();
        let mut c = [0.0; 2];
        s.add(&[0.0, 0.0], &[2.0, 0.0], &mut c);
        let phi = 0.1f64.atan();
        let expect = 1000.0 * phi * (-20.0 / std::f64::consts::PI * phi).exp() * 2.0;
        assert!(c[0].abs() < 1e-12 && (c[1] + expect).abs() < 1e-9, "{c:?}");
        // The same in 3-D, the obstacle out of the x-y plane: push along −z.
        let s = SteeringAngle::new(&[1.0, 0.0, 0.1]).unwrap();
        let mut c = [0.0; 3];
        s.add(&[0.0; 3], &[2.0, 0.0, 0.0], &mut c);
        assert!(c[0].abs() < 1e-12 && c[1].abs() < 1e-12 && (c[2] + expect).abs() < 1e-9);
        // Standing still or heading straight at it: no push.
        let mut c = [0.0; 3];
        s.add(&[0.0; 3], &[0.0; 3], &mut c);
        s.add(&[0.0; 3], &[1.0, 0.0, 0.1], &mut c);
        assert_eq!(c, [0.0; 3]);
    }

    #[test]
    fn the_dynamic_potential_term_is_minus_the_gradient_of_its_potential() {
        let (o, v) = ([0.3, -0.2, 0.5], [0.7, -0.4, 1.1]);
        let field = DynamicPotential::with_gains(&o, 3.0, 2.5).unwrap();
        let potential = |y: &[f64]| {
            let x: Vec<f64> = (0..3).map(|i| y[i] - o[i]).collect();
            let p = dot(&x, &x).sqrt();
            let speed = dot(&v, &v).sqrt();
            let cos = dot(&v, &x) / (speed * p);
            if cos < 0.0 {
                3.0 * (-cos).powf(2.5) * speed / p
            } else {
                0.0
            }
        };
        let y = [0.1, 0.0, 0.1];
        let mut c = [0.0; 3];
        field.add(&y, &v, &mut c);
        for i in 0..3 {
            let h = 1e-6;
            let (mut a, mut b) = (y, y);
            a[i] += h;
            b[i] -= h;
            let fd = -(potential(&a) - potential(&b)) / (2.0 * h);
            assert!(
                (c[i] - fd).abs() < 1e-5 * (1.0 + fd.abs()),
                "{i}: {} vs {fd}",
                c[i]
            );
        }
        assert!(c.iter().any(|x| x.abs() > 0.1));
        // Moving away: nothing.
        let mut c = [0.0; 3];
        field.add(&y, &[-0.7, 0.4, -1.1], &mut c);
        assert_eq!(c, [0.0; 3]);
    }

    #[test]
    fn without_coupling_the_stepped_rollout_is_the_batch_rollout() {
        struct Zero;
        impl Coupling for Zero {
            fn add(&self, _: &[f64], _: &[f64], _: &mut [f64]) {}
        }
        let dmp =
            DiscreteDmp::new(DmpConfig::new(8, 1.5, 0.01), &[0.0, 1.0], &[1.0, -0.5]).unwrap();
        let w: Vec<f64> = (0..16).map(|i| (i as f64 * 0.7).sin() * 50.0).collect();
        let (a, b) = (dmp.rollout(&w), dmp.rollout_coupled(&w, &Zero));
        for d in 0..2 {
            for (x, y) in a.position(d).iter().zip(b.position(d)) {
                assert!((x - y).abs() < 1e-9, "{x} {y}");
            }
            for (x, y) in a.velocity(d).iter().zip(b.velocity(d)) {
                assert!((x - y).abs() < 1e-8);
            }
        }
        // Bad gains and obstacles are refused with the field named.
        assert!(
            SteeringAngle::with_gains(&[0.0, 0.0], -1.0, 1.0)
                .unwrap_err()
                .to_string()
                .contains("gamma")
        );
        assert!(SteeringAngle::new(&[0.0]).is_err());
        assert!(DynamicPotential::new(&[0.0, f64::NAN]).is_err());
        let e = check_endpoints(&[0.0, 0.0], &[1.0, 1.0], &[1.0, 1.0], 1e-3, "obstacle 1");
        assert!(
            e.unwrap_err()
                .to_string()
                .contains("obstacle 1 is 0.000e0 from the movement's goal")
        );
        assert!(check_endpoints(&[0.0, 0.0], &[1.0, 1.0], &[0.5, 0.5], 1e-3, "o").is_ok());
    }
}
