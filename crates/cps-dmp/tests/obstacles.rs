//! Obstacle coupling against movement_primitives' reference scenario
//! (`test/test_obstacle_avoidance.py`): start 0, goal 1, a point obstacle at 0.5 in every
//! coordinate, 10 weights per dimension, dt 0.01, τ = 1 s. Without coupling the straight
//! path passes within 0.03 of the obstacle; with it, from 20 random starts (numpy's
//! `RandomState(42)`, `0.2 + 0.2·randn`, the same starts as the reference), the path keeps
//! away from it and still reaches the goal. movement_primitives measured here: 0.104 in
//! 2-D and 0.153 in 3-D.

use cps_dmp::{Coupling, DiscreteDmp, DmpConfig, DynamicPotential, SteeringAngle, Trajectory};

const STARTS_2D: [[f64; 2]; 20] = [
    [0.29934283060224653, 0.17234713976576307],
    [0.3295377076201385, 0.5046059712816051],
    [0.15316932505533282, 0.1531726086101639],
    [0.5158425631014782, 0.35348694583058177],
    [0.10610512281300959, 0.308512008717193],
    [0.10731646143750756, 0.10685404928594865],
    [0.24839245431320683, -0.18265604893155957],
    [-0.14498356650260658, 0.08754249415180547],
    [-0.00256622406688475, 0.2628494665190548],
    [0.01839518489575781, -0.0824607402670583],
    [0.4931297537843109, 0.15484473990269287],
    [0.2135056409375848, -0.08494963724269133],
    [0.09112345509496347, 0.2221845179419732],
    [-0.03019871548446057, 0.2751396036691344],
    [0.07987226201623901, 0.14166125004134467],
    [0.07965867755412062, 0.5704556369017876],
    [0.19730055505241323, -0.01154218579118008],
    [0.36450898242063784, -0.04416872999420446],
    [0.24177271900095107, -0.19193402477595511],
    [-0.06563720977968612, 0.23937224717382471],
];

const STARTS_3D: [[f64; 3]; 20] = [
    [0.29934283060224653, 0.17234713976576307, 0.3295377076201385],
    [0.5046059712816051, 0.15316932505533282, 0.1531726086101639],
    [0.5158425631014782, 0.35348694583058177, 0.10610512281300959],
    [0.308512008717193, 0.10731646143750756, 0.10685404928594865],
    [
        0.24839245431320683,
        -0.18265604893155957,
        -0.14498356650260658,
    ],
    [
        0.08754249415180547,
        -0.00256622406688475,
        0.2628494665190548,
    ],
    [0.01839518489575781, -0.0824607402670583, 0.4931297537843109],
    [
        0.15484473990269287,
        0.2135056409375848,
        -0.08494963724269133,
    ],
    [
        0.09112345509496347,
        0.2221845179419732,
        -0.03019871548446057,
    ],
    [0.2751396036691344, 0.07987226201623901, 0.14166125004134467],
    [0.07965867755412062, 0.5704556369017876, 0.19730055505241323],
    [
        -0.01154218579118008,
        0.36450898242063784,
        -0.04416872999420446,
    ],
    [
        0.24177271900095107,
        -0.19193402477595511,
        -0.06563720977968612,
    ],
    [0.23937224717382471, 0.3476933159990821, 0.23427365623799412],
    [
        0.1768703435223519,
        0.13977926088214226,
        -0.09570439807348546,
    ],
    [0.05603115832105829, 0.1078722458080425, 0.4114244452437832],
    [0.2687236579136923, -0.15260803107254678, 0.264816793878959],
    [0.1229835439167367, 0.06461559993880825, 0.3223352577681736],
    [0.40619990449919013, 0.38625602382323976, 0.0321564953554723],
    [0.1381575248297571, 0.2662526862807128, 0.39510902542447185],
];

fn min_distance(traj: &Trajectory, obstacle: &[f64]) -> f64 {
    (0..traj.n_samples())
        .map(|k| {
            (0..obstacle.len())
                .map(|d| (traj.position(d)[k] - obstacle[d]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

fn end_error(traj: &Trajectory) -> f64 {
    let k = traj.n_samples() - 1;
    (0..traj.dims())
        .map(|d| (traj.position(d)[k] - 1.0).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The worst (smallest) distance and the largest end error over the starts.
fn scenario(starts: &[Vec<f64>], coupling: &dyn Fn(&[f64]) -> Box<dyn Coupling>) -> (f64, f64) {
    let n = starts[0].len();
    let obstacle = vec![0.5; n];
    let config = DmpConfig::new(10, 1.0, 0.01);
    let dmp = DiscreteDmp::new(config, &vec![0.0; n], &vec![1.0; n]).unwrap();
    let w = vec![0.0; dmp.n_weights()];
    let plain = dmp.rollout(&w);
    assert!(min_distance(&plain, &obstacle) < 0.03);
    let (mut worst, mut end) = (f64::INFINITY, 0.0f64);
    for s in starts {
        let d = dmp.with_endpoints(s, &vec![1.0; n]).unwrap();
        let traj = d.rollout_coupled(&w, coupling(&obstacle).as_ref());
        worst = worst.min(min_distance(&traj, &obstacle));
        end = end.max(end_error(&traj));
    }
    (worst, end)
}

fn starts2() -> Vec<Vec<f64>> {
    STARTS_2D.iter().map(|s| s.to_vec()).collect()
}

fn starts3() -> Vec<Vec<f64>> {
    STARTS_3D.iter().map(|s| s.to_vec()).collect()
}

#[test]
fn the_steering_angle_term_keeps_the_reference_distances_and_reaches_the_goal() {
    let steer = |o: &[f64]| Box::new(SteeringAngle::new(o).unwrap()) as Box<dyn Coupling>;
    let (d2, e2) = scenario(&starts2(), &steer);
    let (d3, e3) = scenario(&starts3(), &steer);
    eprintln!("steering angle: 2-D {d2:.4} (end {e2:.1e}), 3-D {d3:.4} (end {e3:.1e})");
    assert!(d2 > 0.1, "2-D: {d2}");
    assert!(d3 > 0.13, "3-D: {d3}");
    assert!(e2 < 1e-2 && e3 < 1e-2, "{e2} {e3}");
}

#[test]
fn the_dynamic_potential_keeps_away_too() {
    let field = |o: &[f64]| Box::new(DynamicPotential::new(o).unwrap()) as Box<dyn Coupling>;
    let (d2, e2) = scenario(&starts2(), &field);
    let (d3, e3) = scenario(&starts3(), &field);
    eprintln!("dynamic potential: 2-D {d2:.4} (end {e2:.1e}), 3-D {d3:.4} (end {e3:.1e})");
    assert!(d2 > 0.1 && d3 > 0.1, "{d2} {d3}");
    assert!(e2 < 1e-2 && e3 < 1e-2, "{e2} {e3}");
}
