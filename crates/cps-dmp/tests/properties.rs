//! Property tests of the DMP crate against analytic facts and reference constructions:
//! discrete rollouts, formulations, online stepping, imitation, rhythmic and orientation
//! DMPs.

#![allow(clippy::needless_range_loop)] // numeric tests index several arrays in step

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
        let single = dmp.rollout(&pop[m * n..(m + 1) * n]);
        for d in 0..3 {
            for (series, reference) in [
                (t.position(d), single.position(d)),
                (t.velocity(d), single.velocity(d)),
                (t.acceleration(d), single.acceleration(d)),
                (t.forcing(d), single.forcing(d)),
            ] {
                for (a, b) in series.iter().zip(reference) {
                    assert!(
                        (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
                        "{m} {d}: {a} vs {b}"
                    );
                }
            }
        }
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

mod imitation {
    use super::weights;
    use cps_dmp::{
        Combine, Demonstration, DiscreteDmp, DmpConfig, DmpError, Formulation, Lambda, Regression,
        imitate,
    };

    /// The minimum-jerk spline through `points` at `times` (at rest at both ends): piecewise
    /// quintics, continuous up to the fourth derivative at the via points — the curve
    /// minimising ∫ jerk² through them.
    fn min_jerk_spline(points: &[[f64; 3]], times: &[f64]) -> impl Fn(f64) -> [f64; 3] {
        let s = points.len() - 1;
        let n = 6 * s;
        let mut coef = vec![[0.0; 3]; n];
        for d in 0..3 {
            let mut a = faer::Mat::<f64>::zeros(n, n);
            let mut b = faer::Mat::<f64>::zeros(n, 1);
            let mut row = 0;
            // r-th derivative of u^j at u.
            let dpow = |j: usize, r: usize, u: f64| -> f64 {
                if r > j {
                    return 0.0;
                }
                let f: f64 = ((j - r + 1)..=j).map(|v| v as f64).product();
                f * u.powi((j - r) as i32)
            };
            for seg in 0..s {
                let t = times[seg + 1] - times[seg];
                for j in 0..6 {
                    a[(row, 6 * seg + j)] = dpow(j, 0, 0.0);
                    a[(row + 1, 6 * seg + j)] = dpow(j, 0, t);
                }
                b[(row, 0)] = points[seg][d];
                b[(row + 1, 0)] = points[seg + 1][d];
                row += 2;
            }
            let t_last = times[s] - times[s - 1];
            for r in 1..=2 {
                for j in 0..6 {
                    a[(row, j)] = dpow(j, r, 0.0);
                    a[(row + 1, 6 * (s - 1) + j)] = dpow(j, r, t_last);
                }
                row += 2;
            }
            for seg in 1..s {
                let t = times[seg] - times[seg - 1];
                for r in 1..=4 {
                    for j in 0..6 {
                        a[(row, 6 * (seg - 1) + j)] = dpow(j, r, t);
                        a[(row, 6 * seg + j)] = -dpow(j, r, 0.0);
                    }
                    row += 1;
                }
            }
            assert_eq!(row, n);
            let x = a.partial_piv_lu().solve(&b);
            for i in 0..n {
                coef[i][d] = x[(i, 0)];
            }
        }
        let times = times.to_vec();
        move |t: f64| {
            let seg = (0..s).find(|&i| t <= times[i + 1]).unwrap_or(s - 1);
            let u = t - times[seg];
            std::array::from_fn(|d| {
                (0..6)
                    .map(|j| coef[6 * seg + j][d] * u.powi(j as i32))
                    .sum()
            })
        }
    }

    use faer::linalg::solvers::Solve;

    /// The thesis's Table 3 points as a smooth minimum-jerk demonstration: 10 s, 1000 samples.
    fn table3_demo() -> Demonstration {
        let points = [
            [0.75, 0.02, 1.87],
            [0.78, 0.60, 1.70],
            [1.12, 0.37, 1.45],
            [1.15, -0.15, 1.20],
            [0.90, -0.53, 1.20],
            [0.55, -0.57, 1.45],
        ];
        let curve = min_jerk_spline(&points, &[0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let times: Vec<f64> = (0..1000).map(|k| 10.0 * k as f64 / 999.0).collect();
        let rows: Vec<Vec<f64>> = times.iter().map(|&t| curve(t).to_vec()).collect();
        Demonstration::new(times, &rows).unwrap()
    }

    #[test]
    fn the_spline_passes_its_points_at_rest_at_the_ends() {
        let demo = table3_demo();
        assert!((demo.sample(0)[1] - 0.02).abs() < 1e-12);
        assert!((demo.sample(999)[2] - 1.45).abs() < 1e-12);
    }

    /// Ridge (thesis λ) reproduces the minimum-jerk demonstration within 1 mm RMSE; the
    /// jerk-regularised fit with λ by cross-validation stays within 2 mm and is smoother.
    #[test]
    fn table3_minimum_jerk_demo_is_learned_within_a_millimetre() {
        let demo = table3_demo();
        let cfg = DmpConfig::new(25, 10.0, 0.01);
        let ridge = imitate(
            &cfg,
            std::slice::from_ref(&demo),
            Regression::default(),
            Combine::Mean,
        )
        .unwrap();
        for d in 0..3 {
            assert!(
                ridge.report.rmse[d] <= 1e-3,
                "ridge rmse {:?}",
                ridge.report.rmse
            );
        }
        let jerk = imitate(
            &cfg,
            &[demo],
            Regression::JerkRidge {
                lambda: Lambda::Auto,
            },
            Combine::Mean,
        )
        .unwrap();
        for d in 0..3 {
            assert!(
                jerk.report.rmse[d] <= 2e-3,
                "jerk rmse {:?}",
                jerk.report.rmse
            );
            assert!(jerk.report.lambda[d] > 0.0);
        }
        let total = |v: &[f64]| v.iter().sum::<f64>();
        eprintln!(
            "table 3 demo: ridge rmse {:?} jerk {:?}; jerk-ridge (GCV λ {:?}) rmse {:?} jerk {:?}; demo jerk {:?}",
            ridge.report.rmse,
            ridge.report.integrated_squared_jerk,
            jerk.report.lambda,
            jerk.report.rmse,
            jerk.report.integrated_squared_jerk,
            ridge.report.demo_integrated_squared_jerk
        );
        assert!(
            total(&jerk.report.integrated_squared_jerk)
                < total(&ridge.report.integrated_squared_jerk),
            "jerk {:?} vs ridge {:?}",
            jerk.report.integrated_squared_jerk,
            ridge.report.integrated_squared_jerk
        );
    }

    /// A trajectory the DMP can represent exactly is learned back to ~1e-6 m, by ridge in
    /// both formulations; LWR, which ignores the overlap of the bases, is only close.
    #[test]
    fn a_representable_trajectory_is_reproduced() {
        for f in [Formulation::Ijspeert2013, Formulation::GoalRobust] {
            let cfg = DmpConfig {
                formulation: f,
                ..DmpConfig::new(15, 2.0, 0.002)
            };
            let dmp = DiscreteDmp::new(cfg, &[0.1, -0.3], &[0.6, 0.2]).unwrap();
            let w = weights(
                dmp.n_weights(),
                9,
                if f == Formulation::GoalRobust {
                    0.05
                } else {
                    20.0
                },
            );
            let truth = dmp.rollout(&w);
            let rows: Vec<Vec<f64>> = (0..dmp.n_samples())
                .map(|k| vec![truth.position(0)[k], truth.position(1)[k]])
                .collect();
            let demo = Demonstration::new(dmp.times().to_vec(), &rows).unwrap();
            let fit = imitate(
                &cfg,
                std::slice::from_ref(&demo),
                Regression::Ridge {
                    lambda: Lambda::Fixed(0.0),
                },
                Combine::Mean,
            )
            .unwrap();
            eprintln!(
                "{f:?}: representable trajectory back to {:?} m",
                fit.report.max_error
            );
            // The residual is the O(h⁴) finite-difference error of the target (and the
            // first-order hold of the rollout), relative to the movement's size.
            let range = (0..2)
                .map(|d| {
                    let p = truth.position(d);
                    p.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v))
                        - p.iter().fold(f64::INFINITY, |m, &v| m.min(v))
                })
                .fold(0.0f64, f64::max);
            for d in 0..2 {
                assert!(
                    fit.report.max_error[d] < 1e-5 * range.max(0.1),
                    "{f:?}: {:?} (range {range})",
                    fit.report.max_error
                );
            }
            let lwr = imitate(&cfg, &[demo], Regression::Lwr, Combine::Mean).unwrap();
            let range = 0.5;
            assert!(
                lwr.report.rmse.iter().all(|&e| e < 0.2 * range),
                "{:?}",
                lwr.report.rmse
            );
        }
    }

    #[test]
    fn several_demonstrations_mean_and_stack() {
        let base = table3_demo();
        // Two demonstrations offset by ±1 cm in z, with their own time stamps.
        let shifted = |dz: f64, stretch: f64| {
            let times: Vec<f64> = base.times().iter().map(|t| 3.0 + t * stretch).collect();
            let rows: Vec<Vec<f64>> = (0..base.len())
                .map(|k| {
                    let s = base.sample(k);
                    vec![s[0], s[1], s[2] + dz]
                })
                .collect();
            Demonstration::new(times, &rows).unwrap()
        };
        let demos = [shifted(0.01, 1.0), shifted(-0.01, 1.3)];
        let cfg = DmpConfig::new(25, 10.0, 0.01);
        let mean = imitate(&cfg, &demos, Regression::default(), Combine::Mean).unwrap();
        let one = imitate(
            &cfg,
            std::slice::from_ref(&base),
            Regression::default(),
            Combine::Mean,
        )
        .unwrap();
        for (a, b) in mean.weights.iter().zip(&one.weights) {
            assert!((a - b).abs() < 1e-6 * (1.0 + b.abs()), "{a} vs {b}");
        }
        let stack = imitate(&cfg, &demos, Regression::default(), Combine::Stack).unwrap();
        assert!(
            stack.report.rmse.iter().all(|&e| e < 2e-3),
            "{:?}",
            stack.report.rmse
        );
    }

    #[test]
    fn bad_demonstrations_and_degenerate_goals_are_errors() {
        let t = vec![0.0, 1.0, 2.0];
        let err = |times: Vec<f64>, rows: Vec<Vec<f64>>| {
            Demonstration::new(times, &rows).unwrap_err().to_string()
        };
        assert!(err(vec![0.0, 1.0], vec![vec![0.0], vec![1.0]]).contains("at least 3 samples"));
        assert!(
            err(vec![0.0, 1.0, 1.0], vec![vec![0.0], vec![1.0], vec![2.0]])
                .contains("sample 2 at 1 s follows 1 s")
        );
        assert!(
            err(t.clone(), vec![vec![0.0], vec![f64::NAN], vec![2.0]])
                .contains("sample 1, coordinate 0 is not finite")
        );
        assert!(
            err(t.clone(), vec![vec![0.0, 1.0], vec![1.0], vec![2.0, 0.0]])
                .contains("sample 1 has 1 values")
        );
        let a = Demonstration::new(t.clone(), &[vec![0.0], vec![1.0], vec![2.0]]).unwrap();
        let b = Demonstration::new(t.clone(), &[vec![0.0, 0.0], vec![1.0, 0.0], vec![2.0, 0.0]])
            .unwrap();
        let cfg = DmpConfig::new(5, 1.0, 0.01);
        let e = imitate(&cfg, &[a, b], Regression::default(), Combine::Mean).unwrap_err();
        assert!(
            e.to_string().contains("demonstration 2 has 2 coordinates"),
            "{e}"
        );
        // A loop back to the start: refused in the Ijspeert form with advice, fine robustly.
        let times: Vec<f64> = (0..200).map(|k| k as f64 / 199.0).collect();
        // Out and back, at rest at both ends.
        let rows: Vec<Vec<f64>> = times
            .iter()
            .map(|t| vec![0.5 * (1.0 - (std::f64::consts::TAU * t).cos())])
            .collect();
        let demo = Demonstration::new(times, &rows).unwrap();
        match imitate(
            &cfg,
            std::slice::from_ref(&demo),
            Regression::default(),
            Combine::Mean,
        ) {
            Err(DmpError::DegenerateAmplitude { dim: 0, .. }) => {}
            other => panic!("{other:?}"),
        }
        let robust = DmpConfig {
            formulation: Formulation::GoalRobust,
            ..DmpConfig::new(20, 1.0, 0.005)
        };
        let fit = imitate(&robust, &[demo], Regression::default(), Combine::Mean).unwrap();
        assert!(fit.report.rmse[0] < 5e-3, "{:?}", fit.report.rmse);
        assert!(imitate(&cfg, &[], Regression::default(), Combine::Mean).is_err());
        let lam = Regression::Ridge {
            lambda: Lambda::Fixed(-1.0),
        };
        let d = Demonstration::new(t, &[vec![0.0], vec![1.0], vec![2.0]]).unwrap();
        assert!(imitate(&cfg, &[d], lam, Combine::Mean).is_err());
    }
}

mod rhythmic {
    use cps_dmp::RhythmicDmp;

    /// One period (2 s) of a two-harmonic movement in 2-D, last sample = first.
    fn period() -> (Vec<f64>, Vec<Vec<f64>>) {
        let times: Vec<f64> = (0..=400).map(|k| 2.0 * k as f64 / 400.0).collect();
        let w = std::f64::consts::PI; // 2π / 2 s
        let rows = times
            .iter()
            .map(|&t| {
                vec![
                    0.3 + 0.1 * (w * t).sin() + 0.03 * (2.0 * w * t).cos(),
                    -0.2 + 0.05 * (w * t).cos(),
                ]
            })
            .collect();
        (times, rows)
    }

    /// Learned from one period, the DMP reproduces it, repeats it period after period,
    /// and its amplitude scales the oscillation about the anchor.
    #[test]
    fn learned_from_one_period_it_is_periodic_and_its_amplitude_scales() {
        let (times, rows) = period();
        let dmp = RhythmicDmp::learn(&times, &rows, 30, 400, 1e-10).unwrap();
        assert!((dmp.tau - 2.0 / std::f64::consts::TAU).abs() < 1e-12);
        let run = dmp.rollout(6.0, 0.005).unwrap(); // three periods
        let per = 400; // samples per period at dt = 5 ms
        let mut worst_fit = 0.0f64;
        let mut worst_period = 0.0f64;
        for d in 0..2 {
            for k in 0..per {
                worst_fit = worst_fit.max((run.position[d][k] - rows[k][d]).abs());
                worst_period =
                    worst_period.max((run.position[d][k + 2 * per] - run.position[d][k]).abs());
            }
        }
        assert!(worst_fit < 1e-4, "fit {worst_fit}");
        assert!(worst_period < 1e-4, "periodicity {worst_period}");
        // Doubling r (with the start scaled about the anchor) doubles y − g.
        let mut big = dmp.clone();
        big.amplitude = vec![2.0, 2.0];
        for d in 0..2 {
            big.start[d] = dmp.anchor[d] + 2.0 * (dmp.start[d] - dmp.anchor[d]);
            big.start_velocity[d] = 2.0 * dmp.start_velocity[d];
        }
        let run2 = big.rollout(6.0, 0.005).unwrap();
        for d in 0..2 {
            for k in 0..run.times.len() {
                let (a, b) = (
                    run.position[d][k] - dmp.anchor[d],
                    run2.position[d][k] - dmp.anchor[d],
                );
                assert!((b - 2.0 * a).abs() < 1e-12, "{d} {k}: {b} vs {a}");
            }
        }
        // Bad input.
        assert!(dmp.rollout(1.0, 0.0).is_err());
        assert!(RhythmicDmp::learn(&times[..2], &rows[..2], 10, 100, 0.0).is_err());
        let mut wrong = dmp.clone();
        wrong.weights.pop();
        assert!(wrong.rollout(1.0, 0.01).is_err());
    }
}

mod orientation {
    use cps_dmp::{DmpConfig, QuaternionDmp};
    use nalgebra::{UnitQuaternion, Vector3};

    fn q(rx: f64, ry: f64, rz: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_scaled_axis(Vector3::new(rx, ry, rz))
    }

    /// Zero weights turn the tool to the goal; every sample is a unit quaternion.
    #[test]
    fn zero_weights_reach_the_goal_orientation_and_stay_unit() {
        let cfg = DmpConfig::new(20, 2.0, 0.002);
        let (start, goal) = (q(0.3, -0.2, 1.0), q(-1.2, 0.4, 2.5));
        let dmp = QuaternionDmp::new(cfg, start, goal).unwrap();
        let run = dmp.rollout(&vec![0.0; dmp.n_weights()]);
        for o in &run.orientation {
            assert!((o.coords.norm() - 1.0).abs() < 1e-12);
        }
        let end = run.orientation.last().unwrap();
        assert!(end.angle_to(&goal) < 2e-3, "{}", end.angle_to(&goal));
        assert!(run.orientation[0].angle_to(&start) < 1e-15);
        // With random weights it still stays unit and ends at the goal.
        let w: Vec<f64> = (0..dmp.n_weights())
            .map(|i| ((i * 37 % 11) as f64 - 5.0) * 3.0)
            .collect();
        let run = dmp.rollout(&w);
        assert!(
            run.orientation
                .iter()
                .all(|o| (o.coords.norm() - 1.0).abs() < 1e-12)
        );
        assert!(run.orientation.last().unwrap().angle_to(&goal) < 5e-3);
    }

    /// An orientation movement learned from its samples is reproduced, and a new goal
    /// is reached.
    #[test]
    fn an_orientation_demo_is_learned_back() {
        let times: Vec<f64> = (0..=500).map(|k| 2.0 * k as f64 / 500.0).collect();
        let demo: Vec<UnitQuaternion<f64>> = times
            .iter()
            .map(|&t| {
                let s = t / 2.0;
                let mj = 10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5);
                q(
                    0.2 + 0.8 * mj,
                    -0.5 * mj + 0.2 * (std::f64::consts::PI * s).sin().powi(2),
                    1.5 * mj,
                )
            })
            .collect();
        let cfg = DmpConfig::new(30, 2.0, 0.004);
        let (dmp, w) = QuaternionDmp::learn(cfg, &times, &demo, 1e-10).unwrap();
        let run = dmp.rollout(&w);
        let worst = run
            .orientation
            .iter()
            .zip(run.times.iter())
            .map(|(o, &t)| o.angle_to(&demo[(t / 2.0 * 500.0).round() as usize]))
            .fold(0.0f64, f64::max);
        assert!(worst < 5e-4, "worst angle error {worst} rad");
        let new_goal = q(0.0, 0.3, 2.0);
        let moved = dmp.with_goal(new_goal).rollout(&w);
        assert!(moved.orientation.last().unwrap().angle_to(&new_goal) < 1e-2);
        assert!(QuaternionDmp::learn(cfg, &times[..2], &demo[..2], 0.0).is_err());
    }
}
