//! ProMPs against their defining properties: exact conditioning, several via points at
//! once, the sampled moments equal the predicted ones, and fitting exact samples recovers
//! the distribution.

use cps_promp::{Observation, ProMp};
use nalgebra::DMatrix;

const BASES: usize = 50;

/// A known 2-D weight distribution: smooth means, and a covariance with correlations
/// along the basis and between the two dimensions.
fn known() -> ProMp {
    let n = 2 * BASES;
    let mean: Vec<f64> = (0..n)
        .map(|i| {
            let (d, k) = (i / BASES, (i % BASES) as f64 / (BASES - 1) as f64);
            if d == 0 { (3.0 * k).sin() } else { 0.5 - k * k }
        })
        .collect();
    // Σ = A Aᵀ with A: smooth bumps shared by both dimensions (cross-covariance).
    let a = DMatrix::from_fn(n, 6, |i, j| {
        let (d, k) = (i / BASES, (i % BASES) as f64 / (BASES - 1) as f64);
        let c = j as f64 / 5.0;
        let bump = (-(k - c) * (k - c) / 0.02).exp();
        0.15 * bump * if d == 0 { 1.0 } else { 0.5 + 0.1 * j as f64 }
    });
    let cov = &a * a.transpose() + DMatrix::identity(n, n) * 1e-6;
    ProMp::new(2, BASES, 1.0, mean, cov.transpose().as_slice().to_vec()).unwrap()
}

fn grid(n: usize) -> Vec<f64> {
    (0..n).map(|k| k as f64 / (n - 1) as f64).collect()
}

#[test]
fn conditioning_on_an_exact_point_gives_that_mean_and_no_variance_there() {
    let p = known();
    let c = p
        .condition(&[Observation::position(0.4, vec![1.2, -0.3], 0.0)])
        .unwrap();
    let (m, _) = c.mean_at(0.4);
    assert!(
        (m[0] - 1.2).abs() < 1e-8 && (m[1] + 0.3).abs() < 1e-8,
        "{m:?}"
    );
    let (cov, _) = c.covariance_at(0.4);
    assert!(cov.amax() < 1e-8, "{cov}");
    // Elsewhere the spread remains, and the prior's is larger than the posterior's.
    let (far, _) = c.covariance_at(0.95);
    let (prior, _) = p.covariance_at(0.4);
    assert!(far[(0, 0)] > 1e-4 && prior[(0, 0)] > 1e-3);
    // A via point with a standard deviation: at its time, the position's distribution is
    // the Gaussian product of the prior's and the observation's (the 2 × 2 formula).
    let soft = p
        .condition(&[Observation::position(0.4, vec![1.2, -0.3], 0.05)])
        .unwrap();
    let (m, _) = soft.mean_at(0.4);
    let (m0, _) = p.mean_at(0.4);
    let obs = DMatrix::identity(2, 2) * 0.0025;
    let gain = &prior * (&prior + &obs).try_inverse().unwrap();
    let want = nalgebra::DVector::from_vec(m0.clone())
        + &gain * (nalgebra::DVector::from_vec(vec![1.2, -0.3]) - nalgebra::DVector::from_vec(m0));
    let want_cov = &prior - &gain * &prior;
    assert!((want[0] - m[0]).abs() < 1e-9 && (want[1] - m[1]).abs() < 1e-9);
    assert!((soft.covariance_at(0.4).0 - want_cov).amax() < 1e-9);
}

#[test]
fn several_via_points_with_velocities_are_all_met() {
    let p = known();
    let obs = [
        Observation::position(0.2, vec![0.1, 0.6], 0.0),
        Observation::position(0.5, vec![1.5, 0.0], 0.0).with_velocity(vec![0.0, -1.0], 0.0),
        Observation::position(0.9, vec![0.2, -0.5], 0.0),
    ];
    let c = p.condition(&obs).unwrap();
    for o in &obs {
        let (m, v) = c.mean_at(o.time);
        for d in 0..2 {
            assert!(
                (m[d] - o.position.as_ref().unwrap()[d]).abs() < 1e-7,
                "{m:?}"
            );
        }
        if let Some(want) = &o.velocity {
            for d in 0..2 {
                assert!((v[d] - want[d]).abs() < 1e-6, "{v:?}");
            }
        }
    }
    // Samples of the conditioned ProMP pass through the points too.
    for w in c.sample(20, 3).unwrap() {
        let y = c.trajectory(&w, &[0.2, 0.5, 0.9]);
        assert!(
            (y[1][0] - 1.5).abs() < 1e-4 && (y[2][1] + 0.5).abs() < 1e-4,
            "{y:?}"
        );
    }
    // Contradicting exact points: named.
    let e = p
        .condition(&[
            Observation::position(0.3, vec![0.0, 0.0], 0.0),
            Observation::position(0.3, vec![1.0, 0.0], 0.0),
        ])
        .unwrap_err();
    assert!(e.to_string().contains("contradict"), "{e}");
}

/// 100 demonstrations drawn from the known distribution, fitted with 50 bases: the
/// fitted ProMP's sampled mean and standard deviation match its predicted ones within
/// 0.01 at every step.
#[test]
fn sampled_moments_match_the_predicted_ones() {
    let truth = known();
    let t = grid(101);
    let demos: Vec<(Vec<f64>, Vec<Vec<f64>>)> = truth
        .sample(100, 11)
        .unwrap()
        .iter()
        .map(|w| (t.clone(), truth.trajectory(w, &t)))
        .collect();
    let fitted = ProMp::fit(&demos, BASES, 1.0).unwrap();
    let k = 20_000;
    let samples = fitted.sample(k, 12).unwrap();
    let steps = grid(41);
    let trajs: Vec<Vec<Vec<f64>>> = samples
        .iter()
        .map(|w| fitted.trajectory(w, &steps))
        .collect();
    let mut worst: f64 = 0.0;
    for (s, &time) in steps.iter().enumerate() {
        let (mean, _) = fitted.mean_at(time);
        let (cov, _) = fitted.covariance_at(time);
        for d in 0..2 {
            let xs: Vec<f64> = trajs.iter().map(|y| y[s][d]).collect();
            let m = xs.iter().sum::<f64>() / k as f64;
            let sd = (xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (k - 1) as f64).sqrt();
            worst = worst
                .max((m - mean[d]).abs())
                .max((sd - cov[(d, d)].sqrt()).abs());
        }
    }
    assert!(worst < 0.01, "largest difference {worst}");
}

/// Demonstrations that are exact ProMP trajectories give back their weights: the fitted
/// mean and covariance are those of the drawn weights (and near the true ones).
#[test]
fn fitting_exact_samples_recovers_mean_and_covariance() {
    let truth = known();
    let t = grid(201);
    let weights = truth.sample(100, 21).unwrap();
    let demos: Vec<(Vec<f64>, Vec<Vec<f64>>)> = weights
        .iter()
        .map(|w| (t.clone(), truth.trajectory(w, &t)))
        .collect();
    let fitted = ProMp::fit(&demos, BASES, 1.0).unwrap();
    let n = 2 * BASES;
    let m = weights.len() as f64;
    let mean: Vec<f64> = (0..n)
        .map(|i| weights.iter().map(|w| w[i]).sum::<f64>() / m)
        .collect();
    let worst_mean = fitted
        .weight_mean()
        .iter()
        .zip(&mean)
        .fold(0.0_f64, |a, (x, y)| a.max((x - y).abs()));
    assert!(worst_mean < 1e-4, "{worst_mean}");
    let emp = DMatrix::from_fn(n, n, |i, j| {
        weights
            .iter()
            .map(|w| (w[i] - mean[i]) * (w[j] - mean[j]))
            .sum::<f64>()
            / (m - 1.0)
    });
    let scale = emp.amax();
    assert!((fitted.weight_cov() - &emp).amax() < 1e-3 * scale);
    // And the trajectory distribution is the truth's within sampling error.
    let (a, _) = fitted.covariance_at(0.5);
    let (b, _) = truth.covariance_at(0.5);
    assert!(
        ((a[(0, 0)] - b[(0, 0)]) / b[(0, 0)]).abs() < 0.35,
        "{a} {b}"
    );
}

#[test]
fn bad_input_is_named() {
    let e = ProMp::fit(&[], 10, 1.0).unwrap_err();
    assert!(e.to_string().contains("at least 2 demonstrations"));
    let t = grid(11);
    let good = (t.clone(), t.iter().map(|x| vec![*x]).collect::<Vec<_>>());
    let mut back = good.clone();
    back.0[4] = back.0[3];
    let e = ProMp::fit(&[good.clone(), back], 10, 1.0).unwrap_err();
    assert!(
        e.to_string()
            .contains("demonstration 2: times must increase (sample 5"),
        "{e}"
    );
    let p = ProMp::fit(&[good.clone(), good], 10, 1.0).unwrap();
    let e = p
        .condition(&[Observation::position(1.5, vec![0.0], 0.0)])
        .unwrap_err();
    assert!(e.to_string().contains("via point 1: the time 1.5 s"), "{e}");
    let e = p
        .condition(&[Observation::position(0.5, vec![0.0, 1.0], 0.0)])
        .unwrap_err();
    assert!(e.to_string().contains("needs 1 values"), "{e}");
}
