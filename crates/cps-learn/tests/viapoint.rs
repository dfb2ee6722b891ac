//! Via-point learning against exact facts: the cost is an exact quadratic in the weights,
//! the least-squares optimum is a minimum in every search space, CMA-ES approaches it, and
//! runs are reproducible at any thread count.

use std::ops::ControlFlow;

use cps_learn::{
    Evaluation, LearnError, Parametrisation, QuadraticCost, SearchSpace, Solver, ViaPointConfig,
    ViaPointTask, exact_optimum, learn_via_points,
};

fn cost_at(task: &ViaPointTask, space: &SearchSpace, theta: &[f64]) -> f64 {
    let dmp = task.build_dmp().unwrap();
    let mut w = vec![0.0; theta.len()];
    space.to_weights(theta, &mut w);
    task.cost(&dmp.rollout(&w))
}

fn direction(n: usize, seed: u64) -> Vec<f64> {
    (0..n)
        .map(|i| ((((i as u64 + 3) * 0x9E37_79B9) ^ seed) % 1000) as f64 / 500.0 - 1.0)
        .collect()
}

fn quiet() -> impl Fn(usize, &cps_cmaes::GenerationReport<'_>) -> ControlFlow<()> + Sync {
    |_, _| ControlFlow::Continue(())
}

#[test]
fn the_cost_is_an_exact_quadratic_in_the_parameters() {
    let task = ViaPointTask::thesis();
    let dmp = task.build_dmp().unwrap();
    let space = SearchSpace::new(Parametrisation::AnchorOffset, &dmp);
    let x = direction(space.len(), 1);
    let d = direction(space.len(), 2);
    let at = |s: f64| {
        cost_at(
            &task,
            &space,
            &x.iter().zip(&d).map(|(a, b)| a + s * b).collect::<Vec<_>>(),
        )
    };
    // A quadratic's third finite difference vanishes; check against the scale of the values.
    let (c0, c1, c2, c3) = (at(0.0), at(0.1), at(0.2), at(0.3));
    let third = c3 - 3.0 * c2 + 3.0 * c1 - c0;
    assert!(
        third.abs() < 1e-9 * c0.abs().max(1.0),
        "third difference {third} (cost {c0})"
    );
}

#[test]
fn the_quadratic_form_equals_the_rollout_cost_in_every_space() {
    let task = ViaPointTask::thesis();
    let dmp = task.build_dmp().unwrap();
    for kind in [
        Parametrisation::AnchorOffset,
        Parametrisation::ThesisScaling,
        Parametrisation::Raw,
    ] {
        let space = SearchSpace::new(kind, &dmp);
        let q = QuadraticCost::of_task(&task, &dmp, &space).unwrap();
        let opt = exact_optimum(&task, &dmp, &space).unwrap();
        assert!((q.minimum() - opt.cost).abs() < 1e-9 * opt.cost, "{kind:?}");
        let mut scratch = Vec::new();
        // Far from the minimum (costs of 1e4 to 1e7) and close to it (a thousandth more).
        for (seed, scale) in [(3, 1.0), (4, 0.1), (5, 1e-4)] {
            let d = direction(space.len(), seed);
            let step = if kind == Parametrisation::AnchorOffset {
                scale
            } else {
                // Weights: a unit of θ moves the movement far less than a metre.
                scale * 100.0
            };
            let theta: Vec<f64> = q
                .minimiser()
                .iter()
                .zip(&d)
                .map(|(m, d)| m + step * d)
                .collect();
            let (by_form, by_rollout) =
                (q.cost(&theta, &mut scratch), cost_at(&task, &space, &theta));
            assert!(
                (by_form - by_rollout).abs() < 1e-9 * by_rollout,
                "{kind:?}, step {step}: quadratic form {by_form}, rollout {by_rollout}"
            );
            assert!(by_rollout > opt.cost);
        }
    }
}

#[test]
fn cma_es_learns_the_same_by_the_quadratic_form_as_by_rollouts() {
    // CMA-ES uses the costs' ranks (and tolfun their spread), so equal costs to rounding
    // give the same search, generation for generation.
    let run = |evaluation| {
        let config = ViaPointConfig {
            evaluation,
            population: Some(32),
            generations: 150,
            ..ViaPointConfig::new(ViaPointTask::thesis())
        };
        learn_via_points(&config, &quiet()).unwrap()
    };
    let (rollout, quadratic) = (run(Evaluation::Rollout), run(Evaluation::Auto));
    assert_eq!(rollout.evaluation, Evaluation::Rollout);
    assert_eq!(quadratic.evaluation, Evaluation::Quadratic);
    let (a, b) = (rollout.best(), quadratic.best());
    assert_eq!(a.generations, b.generations);
    assert!(
        a.cost < 0.1 * a.history[0].best,
        "it learned: {} from {}",
        a.cost,
        a.history[0].best
    );
    assert!(
        (a.cost - b.cost).abs() < 1e-9 * a.cost,
        "{} vs {}",
        a.cost,
        b.cost
    );
    for (x, y) in a.params.iter().zip(&b.params) {
        assert!((x - y).abs() < 1e-9, "{x} vs {y}");
    }
}

#[test]
fn the_quadratic_form_is_refused_with_obstacles() {
    let mut task = ViaPointTask::thesis();
    task.obstacles.push(cps_learn::PointObstacle {
        position: vec![1.18, 0.10, 1.31],
        clearance: 0.08,
    });
    task.weights.obstacle = 1e6;
    let config = ViaPointConfig {
        evaluation: Evaluation::Quadratic,
        ..ViaPointConfig::new(task.clone())
    };
    let err = learn_via_points(&config, &quiet()).unwrap_err().to_string();
    assert!(
        err.contains("quadratic") && err.contains("obstacles"),
        "{err}"
    );
    // Auto picks the rollout there.
    let config = ViaPointConfig {
        generations: 3,
        ..ViaPointConfig::new(task)
    };
    assert_eq!(
        learn_via_points(&config, &quiet()).unwrap().evaluation,
        Evaluation::Rollout
    );
}

#[test]
fn the_exact_optimum_is_a_minimum_in_every_space() {
    let task = ViaPointTask::thesis();
    let dmp = task.build_dmp().unwrap();
    let mut costs = Vec::new();
    for kind in [
        Parametrisation::AnchorOffset,
        Parametrisation::ThesisScaling,
        Parametrisation::Raw,
    ] {
        let space = SearchSpace::new(kind, &dmp);
        let opt = exact_optimum(&task, &dmp, &space).unwrap();
        assert!((cost_at(&task, &space, &opt.params) - opt.cost).abs() <= 1e-12 * opt.cost);
        // Every step away raises the cost (quadratic with a positive definite Hessian).
        for seed in 0..8 {
            let d = direction(space.len(), seed);
            for step in [1e-4, 1e-2] {
                let scale = space.scale().iter().map(|s| 1.0 / s).collect::<Vec<_>>();
                let p: Vec<f64> = opt
                    .params
                    .iter()
                    .zip(&d)
                    .zip(&scale)
                    .map(|((p, d), s)| p + step * d * s * space.scale()[0])
                    .collect();
                assert!(
                    cost_at(&task, &space, &p) >= opt.cost * (1.0 - 1e-12),
                    "{kind:?}, seed {seed}, step {step}"
                );
            }
        }
        costs.push(opt.cost);
    }
    // The optimum does not depend on the parametrisation (it is a linear reparametrisation).
    for c in &costs[1..] {
        assert!((c - costs[0]).abs() <= 1e-6 * costs[0], "{costs:?}");
    }
    // The thesis's penalties pin the via points to micrometres at the optimum.
    let opt = exact_optimum(
        &task,
        &dmp,
        &SearchSpace::new(Parametrisation::AnchorOffset, &dmp),
    )
    .unwrap();
    let errors = task.errors(&dmp.rollout(&opt.weights));
    assert!(errors.max_position_error() < 1e-4, "{errors:?}");
}

#[test]
fn anchor_offsets_condition_the_problem_far_better_than_raw_weights() {
    let task = ViaPointTask::thesis();
    let dmp = task.build_dmp().unwrap();
    let cond = |k| {
        exact_optimum(&task, &dmp, &SearchSpace::new(k, &dmp))
            .unwrap()
            .hessian_condition
    };
    let (raw, thesis, anchor) = (
        cond(Parametrisation::Raw),
        cond(Parametrisation::ThesisScaling),
        cond(Parametrisation::AnchorOffset),
    );
    assert!(anchor * 1e5 < raw, "anchor {anchor:e} raw {raw:e}");
    assert!(anchor * 1e4 < thesis, "anchor {anchor:e} thesis {thesis:e}");
}

#[test]
fn cmaes_from_the_exact_optimum_stays_there_and_exact_solver_reports_zero_gap() {
    let mut config = ViaPointConfig::new(ViaPointTask::thesis());
    config.warm_start = true;
    config.sigma0 = 1e-4;
    config.generations = 30;
    let out = learn_via_points(&config, &quiet()).unwrap();
    assert!(
        out.best().gap_to_optimum.abs() < 1e-6,
        "{}",
        out.best().gap_to_optimum
    );
    config.solver = Solver::Exact;
    let out = learn_via_points(&config, &quiet()).unwrap();
    assert_eq!(out.best().gap_to_optimum, 0.0);
    assert_eq!(out.best().termination, "exact");
}

#[test]
fn cmaes_improves_from_zero_weights_and_every_run_is_no_better_than_the_optimum() {
    let mut config = ViaPointConfig::new(ViaPointTask::thesis());
    config.generations = 300;
    config.repetitions = 3;
    let out = learn_via_points(&config, &quiet()).unwrap();
    assert_eq!(out.runs.len(), 3);
    for r in &out.runs {
        let first = r.history[0].best_so_far;
        assert!(r.cost < first / 200.0, "{} vs {first}", r.cost);
        assert!(r.cost >= out.optimum.cost * (1.0 - 1e-9));
        assert!(
            r.history
                .windows(2)
                .all(|h| h[1].best_so_far <= h[0].best_so_far)
        );
    }
    let seeds: std::collections::HashSet<u64> = out.runs.iter().map(|r| r.seed).collect();
    assert_eq!(seeds.len(), 3, "repetitions use distinct derived seeds");
}

#[test]
fn same_seed_same_result_at_any_thread_count() {
    let mut config = ViaPointConfig::new(ViaPointTask::thesis());
    config.generations = 60;
    config.repetitions = 2;
    let go = |t: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap();
        pool.install(|| learn_via_points(&config, &quiet()).unwrap())
    };
    let (a, b) = (go(1), go(2));
    for (x, y) in a.runs.iter().zip(&b.runs) {
        assert_eq!(x.weights, y.weights);
        assert_eq!(x.cost.to_bits(), y.cost.to_bits());
        assert_eq!(x.history, y.history);
    }
}

#[test]
fn ill_posed_tasks_are_errors_naming_the_field() {
    let field = |task: ViaPointTask| match task.validate() {
        Err(LearnError::InvalidTask { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    let mut t = ViaPointTask::thesis();
    t.via[2].time = 11.0;
    assert_eq!(field(t), "via[2].time");
    let mut t = ViaPointTask::thesis();
    t.via[1].time = 1.0;
    assert_eq!(field(t), "via[1].time");
    let mut t = ViaPointTask::thesis();
    t.via[0].position.pop();
    assert_eq!(field(t), "via[0].position");
    let mut t = ViaPointTask::thesis();
    t.goal[1] = t.start[1];
    assert_eq!(field(t), "goal[1]");
    let mut t = ViaPointTask::thesis();
    t.weights.via = -1.0;
    assert_eq!(field(t), "cost.via");
    let mut t = ViaPointTask::thesis();
    t.start[2] = f64::NAN;
    assert_eq!(field(t), "start[2]");
}

#[test]
fn batched_costs_equal_rollout_costs() {
    let mut task = ViaPointTask::thesis();
    task.weights.jerk = 1e-4; // exercise every term
    task.via[1].time = 4.004; // off the grid: interpolated
    let dmp = task.build_dmp().unwrap();
    let space = SearchSpace::new(Parametrisation::AnchorOffset, &dmp);
    let n = space.len();
    for m in [1usize, 5, 8] {
        let mut w = vec![0.0; m * n];
        for c in 0..m {
            let theta: Vec<f64> = direction(n, c as u64 + 10)
                .iter()
                .map(|v| v * 0.3)
                .collect();
            space.to_weights(&theta, &mut w[c * n..(c + 1) * n]);
        }
        let mut batched = vec![0.0; m];
        let mut trajs: Vec<_> = (0..m).map(|_| dmp.new_trajectory()).collect();
        task.costs_batched(&dmp, &w, &mut trajs, &mut batched);
        for c in 0..m {
            // Against the residual path (term by term, one rollout per candidate).
            let direct = task.breakdown(&dmp.rollout(&w[c * n..(c + 1) * n])).total();
            assert!(
                (batched[c] - direct).abs() <= 1e-12 * direct,
                "m {m} candidate {c}: {} vs {direct}",
                batched[c]
            );
        }
    }
}

#[test]
fn the_obstacle_term_penalises_intrusion_and_leaves_the_exact_optimum_a_lower_bound() {
    use cps_learn::{CostWeights, PointObstacle};
    let plain = ViaPointTask::thesis();
    let dmp = plain.build_dmp().unwrap();
    let space = SearchSpace::new(Parametrisation::AnchorOffset, &dmp);
    let free = exact_optimum(&plain, &dmp, &space).unwrap();
    let traj = dmp.rollout(&free.weights);
    // An obstacle on the obstacle-free optimum's path at t = 5 s.
    let k = 500;
    let on_path: Vec<f64> = (0..3).map(|d| traj.position(d)[k]).collect();
    let task = ViaPointTask {
        obstacles: vec![PointObstacle {
            position: on_path.clone(),
            clearance: 0.08,
        }],
        weights: CostWeights {
            obstacle: 1e6,
            ..CostWeights::thesis()
        },
        ..plain.clone()
    };
    // The term by hand: Σ_k max(0, r − d_k)², weighted.
    let by_hand: f64 = (0..traj.n_samples())
        .map(|k| {
            let d = (0..3)
                .map(|i| (traj.position(i)[k] - on_path[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            1e6 * (0.08 - d).max(0.0).powi(2)
        })
        .sum();
    let b = task.breakdown(&traj);
    assert!((b.obstacle - by_hand).abs() < 1e-9 * by_hand && by_hand > 1.0);
    assert!((task.cost(&traj) - b.total()).abs() < 1e-9 * b.total());
    assert_eq!(task.obstacle_distances(&traj)[0], 0.0);
    // The exact optimum ignores the term (same parameters, quadratic cost only).
    let exact = exact_optimum(&task, &dmp, &space).unwrap();
    assert!((exact.cost - free.cost).abs() < 1e-9 * free.cost);
    // CMA-ES from there bends the path out of the clearance at a cost above that bound.
    let config = ViaPointConfig {
        warm_start: true,
        sigma0: 0.05,
        population: Some(32),
        generations: 1500,
        tol_fun: Some(1e-4),
        ..ViaPointConfig::new(task)
    };
    let out = learn_via_points(&config, &quiet()).unwrap();
    let best = out.best();
    let traj = out.best_trajectory();
    let d = config.task.obstacle_distances(&traj)[0];
    assert!(d > 0.075, "{d}");
    assert!(best.cost >= exact.cost && best.gap_to_optimum >= 0.0);
    assert!(best.errors.max_position_error() < 1e-3);
}
