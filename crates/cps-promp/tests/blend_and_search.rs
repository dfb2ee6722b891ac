//! Co-activation against the product-of-Gaussians formula, and a ProMP as the start of a
//! CMA-ES search: the search that starts in the ProMP's shape finds the maximum a
//! posteriori weights (whose closed form is Gaussian conditioning) in far fewer
//! evaluations than one that starts isotropic.

use cps_cmaes::{CmaesConfig, FnObjective, NoObserver, StopRule, minimize};
use cps_promp::{Activation, Observation, ProMp, blend};
use nalgebra::{DMatrix, DVector};

/// A 1-D ProMP with smooth correlated weights: `Σ = A Aᵀ + ε I`.
fn promp(bases: usize, shift: f64, eps: f64) -> ProMp {
    let mean: Vec<f64> = (0..bases)
        .map(|i| (2.0 * i as f64 / (bases - 1) as f64 + shift).sin())
        .collect();
    let a = DMatrix::from_fn(bases, 3, |i, j| {
        let k = i as f64 / (bases - 1) as f64;
        let c = j as f64 / 2.0;
        0.3 * (-(k - c) * (k - c) / 0.1).exp()
    });
    let cov = &a * a.transpose() + DMatrix::identity(bases, bases) * eps;
    ProMp::new(1, bases, 1.0, mean, cov.as_slice().to_vec()).unwrap()
}

#[test]
fn co_activation_is_the_weighted_product_of_the_gaussians() {
    let (p, q) = (promp(12, 0.0, 1e-4), promp(12, 1.5, 4e-4));
    let (a1, a2) = (|_: f64| 0.3, |_: f64| 0.7);
    let times = [0.0, 0.25, 0.6, 1.0];
    let b = blend(
        &[
            Activation {
                promp: &p,
                alpha: &a1,
            },
            Activation {
                promp: &q,
                alpha: &a2,
            },
        ],
        &times,
    )
    .unwrap();
    for (r, &t) in b.iter().zip(&times) {
        // The scalar product of two Gaussians, each to the power of its activation.
        let (m1, v1) = (p.mean_at(t).0[0], p.covariance_at(t).0[(0, 0)]);
        let (m2, v2) = (q.mean_at(t).0[0], q.covariance_at(t).0[(0, 0)]);
        let prec = 0.3 / v1 + 0.7 / v2;
        let mean = (0.3 * m1 / v1 + 0.7 * m2 / v2) / prec;
        assert!(
            (r.mean[0] - mean).abs() < 1e-9,
            "t {t}: {} vs {mean}",
            r.mean[0]
        );
        assert!(((r.cov[(0, 0)] - 1.0 / prec) / (1.0 / prec)).abs() < 1e-6);
    }
    // A ProMP blended with itself (activations summing to 1) is unchanged.
    let half = |_: f64| 0.5;
    let same = blend(
        &[
            Activation {
                promp: &p,
                alpha: &half,
            },
            Activation {
                promp: &p,
                alpha: &half,
            },
        ],
        &[0.4],
    )
    .unwrap();
    assert!((same[0].mean[0] - p.mean_at(0.4).0[0]).abs() < 1e-12);
    assert!((same[0].std()[0] - p.covariance_at(0.4).0[(0, 0)].sqrt()).abs() < 1e-9);
}

#[test]
fn a_sigmoid_hands_the_movement_over_and_a_via_point_dominates_where_it_is_set() {
    let (p, q) = (promp(12, 0.0, 1e-4), promp(12, 1.5, 1e-4));
    let s = |t: f64| 1.0 / (1.0 + (-(t - 0.5) / 0.02).exp());
    let first = |t: f64| 1.0 - s(t);
    let b = blend(
        &[
            Activation {
                promp: &p,
                alpha: &first,
            },
            Activation {
                promp: &q,
                alpha: &s,
            },
        ],
        &[0.1, 0.9],
    )
    .unwrap();
    assert!((b[0].mean[0] - p.mean_at(0.1).0[0]).abs() < 1e-6);
    assert!((b[1].mean[0] - q.mean_at(0.9).0[0]).abs() < 1e-6);
    // Co-activated with a ProMP conditioned exactly on a point, the blend passes through it.
    let via = q
        .condition(&[Observation::position(0.5, vec![2.0], 0.0)])
        .unwrap();
    let one = |_: f64| 1.0;
    let b = blend(
        &[
            Activation {
                promp: &p,
                alpha: &one,
            },
            Activation {
                promp: &via,
                alpha: &one,
            },
        ],
        &[0.5],
    )
    .unwrap();
    assert!((b[0].mean[0] - 2.0).abs() < 1e-4, "{}", b[0].mean[0]);
    // Bad input: no active part, a negative activation, different dimensions.
    let zero = |_: f64| 0.0;
    let neg = |_: f64| -1.0;
    let err = |parts: &[Activation<'_>]| blend(parts, &[0.2]).unwrap_err().to_string();
    assert!(
        err(&[Activation {
            promp: &p,
            alpha: &zero
        }])
        .contains("every activation is 0")
    );
    assert!(
        err(&[Activation {
            promp: &p,
            alpha: &neg
        }])
        .contains("must be finite and ≥ 0")
    );
    let two = ProMp::new(
        2,
        3,
        1.0,
        vec![0.0; 6],
        DMatrix::<f64>::identity(6, 6).as_slice().to_vec(),
    )
    .unwrap();
    assert!(
        err(&[
            Activation {
                promp: &p,
                alpha: &one
            },
            Activation {
                promp: &two,
                alpha: &one
            }
        ])
        .contains("share their dimensions")
    );
}

/// Evaluations CMA-ES needs to bring `cost − best` below 1e-9, from `x0`, `sigma0` and an
/// optional initial covariance.
fn evaluations(
    cost: &(dyn Fn(&[f64]) -> f64 + Sync),
    best: f64,
    x0: &[f64],
    sigma0: f64,
    c0: Option<Vec<f64>>,
) -> (u64, Vec<f64>) {
    let config = CmaesConfig {
        initial_covariance: c0,
        ..CmaesConfig::new(sigma0, 7)
    };
    let rules = [
        StopRule::TargetCost(best + 1e-9),
        StopRule::MaxEvaluations(200_000),
    ];
    let sol = minimize(&FnObjective(cost), x0, &config, &rules, &mut NoObserver).unwrap();
    assert!(
        sol.best_cost <= best + 1e-9,
        "did not converge: {}",
        sol.best_cost
    );
    (sol.evaluations, sol.best_x)
}

#[test]
fn cmaes_started_from_a_promp_finds_the_conditioned_weights_fast() {
    let p = promp(15, 0.3, 1e-4);
    let (t, target, std) = (0.5, 1.5, 0.05);
    // Maximum a posteriori weights of "pass near `target` at t": the negative log of
    // prior × likelihood, whose minimiser is the conditioned mean.
    let cov = p.weight_cov().clone();
    let prec = cov.clone().try_inverse().unwrap();
    let mu = DVector::from_column_slice(p.weight_mean());
    let (phi, _) = p.features(t);
    let cost = move |w: &[f64]| {
        let w = DVector::from_column_slice(w);
        let d = &w - &mu;
        let miss = (&phi * &w)[0] - target;
        0.5 * (d.transpose() * &prec * &d)[0] + 0.5 * miss * miss / (std * std)
    };
    let post = p
        .condition(&[Observation::position(t, vec![target], std)])
        .unwrap();
    let best = cost(post.weight_mean());
    let start = p.search_start();
    let (shaped, x) = evaluations(&cost, best, &start.x0, start.sigma0, Some(start.covariance));
    // The optimum found is the conditioned mean.
    let gap = x
        .iter()
        .zip(post.weight_mean())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(gap < 1e-3, "{gap}");
    let (isotropic, _) = evaluations(&cost, best, &start.x0, start.sigma0, None);
    assert!(
        (shaped as f64) < 0.5 * isotropic as f64,
        "from the ProMP: {shaped} evaluations, isotropic: {isotropic}"
    );
    eprintln!("evaluations: from the ProMP {shaped}, isotropic {isotropic}");
}
