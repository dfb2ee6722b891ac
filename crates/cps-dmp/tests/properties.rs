//! Property tests of the discrete DMP against analytic facts.

use cps_dmp::{DiscreteDmp, DmpConfig};
use proptest::prelude::*;

fn weights(n: usize, seed: u64, scale: f64) -> Vec<f64> {
    // A cheap deterministic pseudo-random vector.
    (0..n)
        .map(|i| ((((i as u64 + 1) * 2654435761) ^ seed) % 2001) as f64 / 1000.0 - 1.0)
        .map(|v| v * scale)
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// The same weights with τ and 2τ trace the same path, twice as slowly: on matching
    /// grids (dt and 2 dt) positions agree to rounding, velocities halve, accelerations
    /// quarter.
    #[test]
    fn tau_invariance_on_matching_grids(seed in 0u64..1000, tau in 0.5f64..20.0, nb in 3usize..30) {
        let (y0, g) = ([0.3, -1.0], [1.2, 0.4]);
        let a = DiscreteDmp::new(DmpConfig::new(nb, tau, tau / 500.0), &y0, &g).unwrap();
        let b = DiscreteDmp::new(DmpConfig::new(nb, 2.0 * tau, 2.0 * tau / 500.0), &y0, &g).unwrap();
        let w = weights(a.n_weights(), seed, 300.0);
        let (ta, tb) = (a.rollout(&w), b.rollout(&w));
        for d in 0..2 {
            let scale = ta.position(d).iter().fold(1.0f64, |m, v| m.max(v.abs()));
            for k in 0..ta.n_samples() {
                prop_assert!((ta.position(d)[k] - tb.position(d)[k]).abs() <= 1e-12 * scale);
                prop_assert!((ta.velocity(d)[k] - 2.0 * tb.velocity(d)[k]).abs() <= 1e-11 * scale / tau);
                prop_assert!((ta.acceleration(d)[k] - 4.0 * tb.acceleration(d)[k]).abs() <= 1e-10 * scale / (tau * tau));
            }
        }
    }

    /// With the same dt, doubling τ samples the same continuous path twice as densely;
    /// the first-order-hold scheme is second order, so the paths agree closely.
    #[test]
    fn tau_invariance_same_dt(seed in 0u64..1000) {
        let a = DiscreteDmp::new(DmpConfig::new(25, 10.0, 0.01), &[0.75], &[0.55]).unwrap();
        let b = DiscreteDmp::new(DmpConfig::new(25, 20.0, 0.01), &[0.75], &[0.55]).unwrap();
        let w = weights(25, seed, 2000.0);
        let (ta, tb) = (a.rollout(&w), b.rollout(&w));
        for k in 0..ta.n_samples() {
            prop_assert!((ta.position(0)[k] - tb.position(0)[2 * k]).abs() < 2e-5, "k = {}", k);
        }
    }

    /// The rollout is affine in the weights: r(a w1 + b w2) = r0 + a (r(w1) - r0) + b (r(w2) - r0).
    #[test]
    fn rollout_is_affine(seed in 0u64..1000, a in -3.0f64..3.0, b in -3.0f64..3.0) {
        let dmp = DiscreteDmp::new(DmpConfig::new(12, 3.0, 0.01), &[0.0, 2.0, -1.0], &[1.0, 1.5, 0.0]).unwrap();
        let n = dmp.n_weights();
        let (w1, w2) = (weights(n, seed, 500.0), weights(n, seed + 7, 500.0));
        let mix: Vec<f64> = w1.iter().zip(&w2).map(|(x, y)| a * x + b * y).collect();
        let (t0, t1, t2, tm) = (dmp.rollout(&vec![0.0; n]), dmp.rollout(&w1), dmp.rollout(&w2), dmp.rollout(&mix));
        for d in 0..3 {
            for k in 0..t0.n_samples() {
                let z = t0.position(d)[k];
                let expect = z + a * (t1.position(d)[k] - z) + b * (t2.position(d)[k] - z);
                prop_assert!((tm.position(d)[k] - expect).abs() < 1e-9 * (1.0 + expect.abs()));
            }
        }
    }

    /// Zero weights: a critically damped spring from y0 to g, never overshooting.
    #[test]
    fn zero_weights_reach_the_goal_monotonically(y0 in -5.0f64..5.0, g in -5.0f64..5.0, tau in 0.2f64..5.0) {
        prop_assume!((g - y0).abs() > 1e-3);
        let dmp = DiscreteDmp::new(DmpConfig::new(10, tau, tau / 400.0), &[y0], &[g]).unwrap();
        let t = dmp.rollout(&[0.0; 10]);
        let err: Vec<f64> = t.position(0).iter().map(|y| (y - g).abs()).collect();
        prop_assert!(err.windows(2).all(|e| e[1] <= e[0] + 1e-12));
        prop_assert!(err[err.len() - 1] < 5.1e-5 * (g - y0).abs());
    }
}

#[test]
fn velocity_and_acceleration_are_the_derivatives_of_position() {
    let dmp = DiscreteDmp::new(DmpConfig::new(25, 10.0, 0.001), &[0.75], &[0.55]).unwrap();
    let t = dmp.rollout(&weights(25, 3, 3000.0));
    let h = t.times()[1];
    let (y, v, a) = (t.position(0), t.velocity(0), t.acceleration(0));
    for k in 1..t.n_samples() - 1 {
        let dv = (y[k + 1] - y[k - 1]) / (2.0 * h);
        let da = (v[k + 1] - v[k - 1]) / (2.0 * h);
        assert!(
            (dv - v[k]).abs() < 1e-4 * (1.0 + v[k].abs()),
            "velocity at {k}"
        );
        assert!(
            (da - a[k]).abs() < 2e-3 * (1.0 + a[k].abs()),
            "acceleration at {k}: {da} vs {}",
            a[k]
        );
    }
}

#[test]
fn batch_rollout_equals_single_rollouts() {
    let dmp = DiscreteDmp::new(
        DmpConfig::new(25, 10.0, 0.01),
        &[0.75, 0.02, 1.87],
        &[0.55, -0.57, 1.45],
    )
    .unwrap();
    let n = dmp.n_weights();
    let pop = weights(5 * n, 11, 800.0);
    let mut out: Vec<_> = (0..5).map(|_| dmp.new_trajectory()).collect();
    dmp.rollout_batch(&pop, &mut out);
    for (m, t) in out.iter().enumerate() {
        assert_eq!(t, &dmp.rollout(&pop[m * n..(m + 1) * n]));
    }
}

#[test]
fn streaming_batch_rollout_matches_single_rollouts() {
    for f in [
        cps_dmp::Formulation::Ijspeert2013,
        cps_dmp::Formulation::GoalRobust,
    ] {
        streaming_matches(f);
    }
}

fn streaming_matches(formulation: cps_dmp::Formulation) {
    use cps_dmp::BATCH_LANES;
    let dmp = DiscreteDmp::new(
        DmpConfig {
            formulation,
            ..DmpConfig::new(25, 10.0, 0.01)
        },
        &[0.75, 0.02, 1.87],
        &[0.55, -0.57, 1.45],
    )
    .unwrap();
    let n = dmp.n_weights();
    for m in [1, 3, BATCH_LANES] {
        let pop = weights(m * n, m as u64, 2000.0);
        let singles: Vec<_> = (0..m)
            .map(|c| dmp.rollout(&pop[c * n..(c + 1) * n]))
            .collect();
        let mut visits = 0;
        dmp.rollout_stream(
            &pop,
            &mut |k: usize,
                  d: usize,
                  y: &cps_dmp::Lanes,
                  v: &cps_dmp::Lanes,
                  a: &cps_dmp::Lanes| {
                visits += 1;
                for l in 0..BATCH_LANES {
                    let t = &singles[l.min(m - 1)];
                    let close = |x: f64, r: f64| (x - r).abs() <= 1e-10 * (1.0 + r.abs());
                    assert!(
                        close(y[l], t.position(d)[k]),
                        "m {m} lane {l} k {k} d {d}: {} vs {}",
                        y[l],
                        t.position(d)[k]
                    );
                    assert!(close(v[l], t.velocity(d)[k]));
                    assert!(close(a[l], t.acceleration(d)[k]));
                }
            },
        );
        assert_eq!(visits, 3 * dmp.n_samples());
    }
}

mod formulations_and_stepping {
    use super::weights;
    use cps_dmp::{DiscreteDmp, DmpConfig, Formulation, OnlineDmp, StepInput};
    use proptest::prelude::*;

    fn config(f: Formulation) -> DmpConfig {
        DmpConfig {
            formulation: f,
            ..DmpConfig::new(20, 2.0, 0.005)
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]

        /// Stepping with the grid's step reproduces the batch rollout, in both
        /// formulations.
        #[test]
        fn step_and_batch_agree(seed in 0u64..1000, robust in any::<bool>()) {
            let f = if robust { Formulation::GoalRobust } else { Formulation::Ijspeert2013 };
            let dmp = DiscreteDmp::new(config(f), &[0.2, -0.5, 1.0], &[0.9, 0.1, 1.0]).unwrap();
            let w = weights(dmp.n_weights(), seed, 200.0);
            let traj = dmp.rollout(&w);
            let mut online = OnlineDmp::new(&dmp, &w);
            let h = dmp.config().step();
            for k in 0..dmp.n_samples() {
                for d in 0..3 {
                    let scale = 1.0 + traj.position(d)[k].abs();
                    prop_assert!((online.position()[d] - traj.position(d)[k]).abs() <= 1e-12 * scale);
                    prop_assert!((online.velocity()[d] - traj.velocity(d)[k]).abs() <= 1e-10 * scale);
                    prop_assert!((online.acceleration()[d] - traj.acceleration(d)[k]).abs() <= 1e-8 * scale);
                }
                online.step(h).unwrap();
            }
        }

        /// Zero weights go to the goal in both forms; the weights enter linearly.
        #[test]
        fn zero_weights_reach_the_goal_and_weights_act_linearly(seed in 0u64..1000, robust in any::<bool>()) {
            let f = if robust { Formulation::GoalRobust } else { Formulation::Ijspeert2013 };
            let dmp = DiscreteDmp::new(DmpConfig { formulation: f, ..DmpConfig::new(15, 3.0, 0.01) }, &[0.0, 1.0], &[1.0, 1.5]).unwrap();
            let zero = dmp.rollout(&vec![0.0; dmp.n_weights()]);
            let end = dmp.n_samples() - 1;
            // The spring-damper with τ = 3 s: within 1 mm of the goal at t = τ, 1e-4 later.
            prop_assert!((zero.position(0)[end] - 1.0).abs() < 1e-2);
            let (a, b) = (weights(dmp.n_weights(), seed, 100.0), weights(dmp.n_weights(), seed + 7, 100.0));
            let sum: Vec<f64> = a.iter().zip(&b).map(|(x, y)| 0.7 * x + 0.3 * y).collect();
            let (ta, tb, ts) = (dmp.rollout(&a), dmp.rollout(&b), dmp.rollout(&sum));
            for k in 0..dmp.n_samples() {
                let mix = 0.7 * ta.position(1)[k] + 0.3 * tb.position(1)[k];
                prop_assert!((ts.position(1)[k] - mix).abs() < 1e-12);
            }
        }
    }

    /// Start = goal: the Ijspeert form cannot move (its forcing scales with g − y0), the
    /// goal-robust form makes the loop its weights describe, and a new goal moves the
    /// Ijspeert path by scaling and the robust one without scaling.
    #[test]
    fn start_equal_to_goal_and_goal_changes() {
        let w = weights(20, 3, 300.0);
        let ij = DiscreteDmp::new(config(Formulation::Ijspeert2013), &[0.5], &[0.5]).unwrap();
        let rb = DiscreteDmp::new(config(Formulation::GoalRobust), &[0.5], &[0.5]).unwrap();
        let (ti, tr) = (ij.rollout(&w), rb.rollout(&w));
        assert!(ti.position(0).iter().all(|&y| (y - 0.5).abs() < 1e-15));
        let excursion = tr
            .position(0)
            .iter()
            .fold(0.0f64, |m, &y| m.max((y - 0.5).abs()));
        assert!(excursion > 0.01, "robust form should move: {excursion}");
        // Ijspeert: doubling g − y0 doubles the displacement from y0 at every sample.
        let a = DiscreteDmp::new(config(Formulation::Ijspeert2013), &[0.0], &[1.0]).unwrap();
        let b = DiscreteDmp::new(config(Formulation::Ijspeert2013), &[0.0], &[2.0]).unwrap();
        let (ta, tb) = (a.rollout(&w), b.rollout(&w));
        for k in 0..a.n_samples() {
            assert!((tb.position(0)[k] - 2.0 * ta.position(0)[k]).abs() < 1e-12);
        }
        // Robust: the displacement changes by the unforced spring's response only,
        // `y_b − y_a = (g_b − g_a) (1 − response)`, the same for any weights.
        let a = DiscreteDmp::new(config(Formulation::GoalRobust), &[0.0], &[1.0]).unwrap();
        let b = DiscreteDmp::new(config(Formulation::GoalRobust), &[0.0], &[2.0]).unwrap();
        let w2 = weights(20, 11, 300.0);
        let diff = |w: &[f64]| -> Vec<f64> {
            let (ta, tb) = (a.rollout(w), b.rollout(w));
            (0..a.n_samples())
                .map(|k| tb.position(0)[k] - ta.position(0)[k])
                .collect()
        };
        let (d1, d2) = (diff(&w), diff(&w2));
        for k in 0..a.n_samples() {
            assert!(
                (d1[k] - d2[k]).abs() < 1e-12,
                "goal change depends on weights at {k}"
            );
        }
    }

    #[test]
    fn live_goal_and_tau_changes_phase_stopping_and_coupling() {
        let dmp =
            DiscreteDmp::new(config(Formulation::GoalRobust), &[0.0, 0.0], &[1.0, 1.0]).unwrap();
        let w = vec![0.0; dmp.n_weights()];
        let h = 0.005;
        // A live goal change: the movement ends at the new goal.
        let mut run = OnlineDmp::new(&dmp, &w);
        for _ in 0..200 {
            run.step(h).unwrap();
        }
        run.set_goal(&[2.0, -1.0]).unwrap();
        for _ in 0..2000 {
            run.step(h).unwrap();
        }
        assert!((run.position()[0] - 2.0).abs() < 1e-6 && (run.position()[1] + 1.0).abs() < 1e-6);
        // A longer τ slows the phase; velocity is continuous across the change.
        let mut run = OnlineDmp::new(&dmp, &weights(dmp.n_weights(), 5, 100.0));
        for _ in 0..100 {
            run.step(h).unwrap();
        }
        let v = run.velocity();
        run.set_tau(4.0).unwrap();
        assert!((run.velocity()[0] - v[0] / 1.0).abs() < 1e-15 * (1.0 + v[0].abs()) * 10.0);
        let x0 = run.phase();
        run.step(h).unwrap();
        let expect = x0 * (-dmp.config().alpha_x * h / 4.0).exp();
        assert!((run.phase() - expect).abs() < 1e-15);
        // Phase stopping: a tracking error of 1 halves the phase rate.
        let x0 = run.phase();
        run.step_with(
            h,
            StepInput {
                tracking_error: 1.0,
                ..StepInput::default()
            },
        )
        .unwrap();
        let expect = x0 * (-dmp.config().alpha_x * 0.5 * h / 4.0).exp();
        assert!((run.phase() - expect).abs() < 1e-15);
        // A constant coupling c shifts the rest point by c / (α_z β_z).
        let mut run = OnlineDmp::new(&dmp, &w);
        let c = [dmp.config().alpha_z * dmp.config().beta_z * 0.1, 0.0];
        for _ in 0..4000 {
            run.step_with(
                h,
                StepInput {
                    coupling: Some(&c),
                    ..StepInput::default()
                },
            )
            .unwrap();
        }
        assert!(
            (run.position()[0] - 1.1).abs() < 1e-9,
            "{}",
            run.position()[0]
        );
        // Bad input.
        assert!(run.step(0.0).is_err() && run.step(f64::NAN).is_err());
        assert!(run.set_goal(&[1.0]).is_err() && run.set_tau(-1.0).is_err());
        assert!(
            run.step_with(
                h,
                StepInput {
                    coupling: Some(&[1.0]),
                    ..StepInput::default()
                }
            )
            .is_err()
        );
    }
}
