//! Behaviour of the CMA-ES against analytic facts: convergence on sphere and a rotated
//! ellipsoid, a healthy covariance, NaN handling, determinism across thread counts; its
//! parameters against Hansen's tutorial formulas; the benchmark's seeds and runs. (All of
//! the crate's tests are here: the library is not compiled a second time for unit tests.)

use std::ops::ControlFlow;

use cps_cmaes::functions::{Bench, Restarts, Seeds, TestFunction, bench};
use cps_cmaes::{
    Cmaes, CmaesConfig, CmaesError, FnObjective, NoObserver, Objective, ObjectiveError, Parameters,
    StopRule, functions, minimize,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A cost function of these tests, behind a reference.
type Cost<'a> = &'a (dyn Fn(&[f64]) -> f64 + Sync);

/// One objective type for every closure of these tests: the driver and its parallel
/// evaluation are compiled once, not once for each closure (4 s of the tests' build).
fn objective(f: Cost<'_>) -> FnObjective<Cost<'_>> {
    FnObjective(f)
}

fn run(
    f: impl Fn(&[f64]) -> f64 + Sync,
    x0: &[f64],
    sigma0: f64,
    seed: u64,
    target: f64,
) -> cps_cmaes::Solution {
    let rules = [
        StopRule::TargetCost(target),
        StopRule::MaxGenerations(20_000),
    ];
    minimize(
        &objective(&f),
        x0,
        &CmaesConfig::new(sigma0, seed),
        &rules,
        &mut NoObserver,
    )
    .unwrap()
}

/// A random orthogonal matrix (Gram-Schmidt on Gaussian columns), row-major.
fn rotation(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut q: Vec<Vec<f64>> = Vec::new();
    while q.len() < n {
        let mut v: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
        for u in &q {
            let d: f64 = v.iter().zip(u).map(|(a, b)| a * b).sum();
            v.iter_mut().zip(u).for_each(|(a, b)| *a -= d * b);
        }
        let norm = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        if norm > 1e-6 {
            q.push(v.iter().map(|a| a / norm).collect());
        }
    }
    q.concat()
}

/// The ellipsoid in coordinates rotated by [`rotation`]`(n, seed)`.
fn rotated_ellipsoid(n: usize, seed: u64) -> impl Fn(&[f64]) -> f64 + Sync {
    let r = rotation(n, seed);
    move |x: &[f64]| {
        let y: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| r[i * n + j] * x[j]).sum())
            .collect();
        functions::ellipsoid(&y)
    }
}

#[test]
fn minimises_the_sphere_to_1e_10() {
    for seed in 1..=3 {
        let sol = run(functions::sphere, &[3.0; 10], 2.0, seed, 1e-10);
        assert!(sol.best_cost <= 1e-10, "seed {seed}: {}", sol.best_cost);
        assert!(sol.best_x.iter().all(|v| v.abs() < 1e-4));
        assert_eq!(sol.termination.name(), "target_cost");
    }
}

#[test]
fn minimises_a_rotated_ellipsoid_to_1e_10() {
    let f = rotated_ellipsoid(10, 7);
    let rotated = run(f, &[3.0; 10], 2.0, 5, 1e-10);
    let plain = run(functions::ellipsoid, &[3.0; 10], 2.0, 5, 1e-10);
    assert!(rotated.best_cost <= 1e-10 && plain.best_cost <= 1e-10);
    // Rotation invariance: similar effort (a separable method would differ by far more).
    let ratio = rotated.evaluations as f64 / plain.evaluations as f64;
    assert!(
        (0.75..1.33).contains(&ratio),
        "{} vs {}",
        rotated.evaluations,
        plain.evaluations
    );
}

/// sep-CMA-ES (diagonal covariance, rates × (n + 2)/3): on the separable ellipsoid at
/// n = 40 it needs a fraction of the full form's evaluations (Ros & Hansen 2008 report
/// about (n + 2)/3 times fewer for the learning phase); on a rotated ellipsoid, whose
/// axes it cannot learn, it needs far more — the diagonal form really is diagonal. Its
/// state holds no matrix, and a checkpoint resumes it bit for bit.
#[test]
fn separable_variant_learns_axes_only() {
    let sep = |seed| CmaesConfig {
        separable: true,
        ..CmaesConfig::new(2.0, seed)
    };
    let solve = |f: &(dyn Fn(&[f64]) -> f64 + Sync), n: usize, config: &CmaesConfig| {
        minimize(
            &objective(&f),
            &vec![3.0; n],
            config,
            &[
                StopRule::TargetCost(1e-8),
                StopRule::MaxEvaluations(400_000),
            ],
            &mut NoObserver,
        )
        .unwrap()
    };
    let f = |x: &[f64]| functions::ellipsoid(x);
    let (diag, full) = (
        solve(&f, 40, &sep(1)),
        solve(&f, 40, &CmaesConfig::new(2.0, 1)),
    );
    assert!(diag.best_cost <= 1e-8 && full.best_cost <= 1e-8);
    assert!(
        (diag.evaluations as f64) < 0.3 * full.evaluations as f64,
        "separable {} vs full {}",
        diag.evaluations,
        full.evaluations
    );
    eprintln!(
        "ellipsoid n = 40: separable {} vs full {} evaluations",
        diag.evaluations, full.evaluations
    );
    let n = 10;
    let rotated = rotated_ellipsoid(n, 7);
    let (diag, full) = (
        solve(&rotated, n, &sep(1)),
        solve(&rotated, n, &CmaesConfig::new(2.0, 1)),
    );
    assert!(full.best_cost <= 1e-8);
    eprintln!(
        "rotated ellipsoid n = 10: separable {} (best {:e}) vs full {} evaluations",
        diag.evaluations, diag.best_cost, full.evaluations
    );
    assert!(
        diag.evaluations as f64 > 3.0 * full.evaluations as f64,
        "separable {} vs full {}",
        diag.evaluations,
        full.evaluations
    );
    let mut es = Cmaes::new(&sep(3), &[1.0; 50]).unwrap();
    assert_eq!(es.covariance().nrows(), 0);
    let step = |es: &mut Cmaes| {
        let costs: Vec<f64> = es
            .ask()
            .chunks_exact(50)
            .map(functions::ellipsoid)
            .collect();
        es.tell(&costs).unwrap();
    };
    for _ in 0..30 {
        step(&mut es);
    }
    let mut resumed = Cmaes::resume(&es.checkpoint()).unwrap();
    for _ in 0..30 {
        step(&mut es);
        step(&mut resumed);
    }
    assert_eq!(es.mean(), resumed.mean());
    assert_eq!(es.covariance_diagonal(), resumed.covariance_diagonal());
    let var = es.covariance_diagonal();
    assert!(var.iter().all(|v| *v > 0.0 && v.is_finite()));
    // The ellipsoid's first axis is 1e6 times less curved than its last: after 60
    // generations the learned variances already differ by more than 10×.
    assert!(var[0] > 10.0 * var[49], "{} vs {}", var[0], var[49]);
}

#[test]
fn covariance_stays_symmetric_positive_definite() {
    // Ill-conditioned objective with the lazy eigendecomposition and active weights.
    let n = 12;
    let mut es = Cmaes::new(&CmaesConfig::new(1.0, 3), &vec![1.0; n]).unwrap();
    for _ in 0..1500 {
        let costs: Vec<f64> = es.ask().chunks(n).map(functions::cigar).collect();
        es.tell(&costs).unwrap();
        let c = es.covariance();
        for i in 0..n {
            for j in 0..n {
                assert_eq!(c[(i, j)].to_bits(), c[(j, i)].to_bits());
            }
        }
        // Positive definite: a Cholesky factorisation must succeed.
        assert!(
            c.llt(faer::Side::Lower).is_ok(),
            "generation {}",
            es.generation()
        );
        assert!(es.sigma().is_finite() && es.sigma() > 0.0);
    }
    assert!(
        es.condition() > 1e5,
        "C learned the cigar's scaling: {}",
        es.condition()
    );
}

#[test]
fn adding_a_constant_changes_nothing() {
    let a = run(functions::sphere, &[3.0; 8], 2.0, 11, 1e-8);
    let b = run(
        |x| functions::sphere(x) + 1000.0,
        &[3.0; 8],
        2.0,
        11,
        1000.0 + 1e-8,
    );
    assert_eq!(a.evaluations, b.evaluations);
    assert_eq!(a.mean, b.mean);
}

#[test]
fn step_size_grows_on_a_linear_function() {
    let mut es = Cmaes::new(&CmaesConfig::new(1.0, 1), &[0.0; 10]).unwrap();
    for _ in 0..60 {
        let costs: Vec<f64> = es.ask().chunks(10).map(|x| x[0]).collect();
        es.tell(&costs).unwrap();
    }
    assert!(es.sigma() > 1e3, "sigma = {}", es.sigma());
}

#[test]
fn nan_and_infinite_costs_rank_last_and_are_counted() {
    let f = |x: &[f64]| {
        // Deterministic in x, not in call order: 30 % of the space answers NaN or +inf.
        let h = (x[0] * 1e6).abs().fract();
        if h < 0.15 {
            f64::NAN
        } else if h < 0.3 {
            f64::INFINITY
        } else {
            functions::sphere(x)
        }
    };
    let sol = run(f, &[3.0; 10], 2.0, 4, 1e-8);
    assert!(sol.best_cost <= 1e-8);
    assert!(sol.non_finite_evaluations > sol.evaluations / 5);
    assert!(sol.mean.iter().all(|v| v.is_finite()) && sol.sigma.is_finite());
}

#[test]
fn same_seed_same_bits_at_any_thread_count() {
    let go = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| run(functions::rosenbrock, &[0.0; 10], 0.5, 9, 1e-9))
    };
    let one = go(1);
    for t in [2, 8] {
        let other = go(t);
        assert_eq!(one.evaluations, other.evaluations);
        assert_eq!(one.best_cost.to_bits(), other.best_cost.to_bits());
        assert_eq!(one.mean, other.mean);
        assert_eq!(one.sigma.to_bits(), other.sigma.to_bits());
    }
}

#[test]
fn objective_errors_name_the_candidate() {
    struct Fails;
    impl Objective for Fails {
        fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
            if x[0] > 0.0 {
                Err("simulator died".into())
            } else {
                Ok(0.0)
            }
        }
    }
    let err = minimize(
        &Fails,
        &[1.0; 4],
        &CmaesConfig::new(0.1, 1),
        &[StopRule::MaxGenerations(5)],
        &mut NoObserver,
    )
    .unwrap_err();
    let msg = format!("{err}");
    assert!(msg.contains("generation 0"), "{msg}");
}

/// An objective that can evaluate no more ends the search: the run keeps the generations
/// before, exactly as an uninterrupted run had them, and does not count the one it could
/// not finish.
#[test]
fn an_objective_may_end_the_search_keeping_what_came_before() {
    struct EndsAt {
        batches: std::sync::atomic::AtomicUsize,
        at: usize,
    }
    impl Objective for EndsAt {
        fn evaluate(&self, x: &[f64]) -> Result<f64, ObjectiveError> {
            Ok(functions::sphere(x))
        }
        fn evaluate_batch(
            &self,
            xs: &[f64],
            dim: usize,
            out: &mut [f64],
        ) -> Result<(), cps_cmaes::CandidateError> {
            let b = self
                .batches
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if b == self.at {
                return Err(cps_cmaes::CandidateError {
                    index: 0,
                    source: Box::new(cps_cmaes::EndSearch),
                });
            }
            for (x, o) in xs.chunks_exact(dim).zip(out.iter_mut()) {
                *o = functions::sphere(x);
            }
            Ok(())
        }
    }
    let config = CmaesConfig::new(0.5, 7);
    let rules = [StopRule::MaxGenerations(3)];
    let ended = minimize(
        &EndsAt {
            batches: 0.into(),
            at: 3,
        },
        &[1.0; 5],
        &config,
        &[StopRule::MaxGenerations(100)],
        &mut NoObserver,
    )
    .unwrap();
    let whole = minimize(
        &objective(&functions::sphere),
        &[1.0; 5],
        &config,
        &rules,
        &mut NoObserver,
    )
    .unwrap();
    assert_eq!(ended.termination, cps_cmaes::Termination::Ended);
    assert_eq!(ended.termination.name(), "ended");
    assert_eq!(ended.generations, 3);
    assert_eq!(ended.evaluations, whole.evaluations);
    assert_eq!(ended.best_x, whole.best_x);
    assert_eq!(ended.mean, whole.mean);
}

#[test]
fn invalid_settings_are_typed_errors() {
    let bad = |cfg: CmaesConfig, x0: &[f64]| Cmaes::new(&cfg, x0).unwrap_err().to_string();
    assert!(bad(CmaesConfig::new(0.0, 1), &[1.0]).contains("sigma0"));
    assert!(bad(CmaesConfig::new(f64::NAN, 1), &[1.0]).contains("sigma0"));
    assert!(
        bad(
            CmaesConfig {
                population: Some(1),
                ..CmaesConfig::new(1.0, 1)
            },
            &[1.0]
        )
        .contains("population")
    );
    assert!(bad(CmaesConfig::new(1.0, 1), &[]).contains("x0"));
    assert!(bad(CmaesConfig::new(1.0, 1), &[f64::INFINITY]).contains("x0"));
    let no_budget = minimize(
        &objective(&functions::sphere),
        &[1.0],
        &CmaesConfig::new(1.0, 1),
        &[StopRule::TargetCost(0.0)],
        &mut NoObserver,
    );
    assert!(no_budget.unwrap_err().to_string().contains("budget"));
}

#[test]
fn an_observer_can_stop_the_run() {
    let mut seen = 0;
    let mut obs = |r: &cps_cmaes::GenerationReport<'_>| {
        seen += 1;
        if r.generation == 7 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    let sol = minimize(
        &objective(&functions::sphere),
        &[1.0; 5],
        &CmaesConfig::new(1.0, 1),
        &[StopRule::MaxGenerations(100)],
        &mut obs,
    )
    .unwrap();
    assert_eq!(sol.generations, 7);
    assert_eq!(sol.termination.name(), "interrupted");
    assert_eq!(seen, 7);
}

/// Median evaluations to f ≤ 1e-8 over seeds 1..10 at n = 10 lie within ±15 % of pycma
/// 4.5.0's, measured independently on this machine kind (x0 = 3·1, σ0 = 2; Rosenbrock
/// x0 = 0, σ0 = 0.5; default λ), and every run succeeds — except that a Rosenbrock run
/// may end in its known local minimum (f ≈ 3.99 near x = (−1, 1, …, 1)), as a few
/// percent of runs do (measured over seeds 1..100: 2 here, 4 with the previous
/// eigendecomposition form); at most one of the ten.
#[test]
fn evaluation_counts_match_pycma_at_n_10() {
    type F = fn(&[f64]) -> f64;
    let cases: [(&str, F, f64, f64, f64); 5] = [
        ("sphere", functions::sphere, 3.0, 2.0, 1437.0),
        ("ellipsoid", functions::ellipsoid, 3.0, 2.0, 4272.0),
        ("cigar", functions::cigar, 3.0, 2.0, 4016.0),
        ("discus", functions::discus, 3.0, 2.0, 3041.0),
        ("rosenbrock", functions::rosenbrock, 0.0, 0.5, 4911.0),
    ];
    for (name, f, x0, sigma0, pycma) in cases {
        let mut evals = Vec::new();
        let mut local = 0;
        for seed in 1..=10 {
            let rules = [
                StopRule::TargetCost(1e-8),
                StopRule::MaxEvaluations(200_000),
            ];
            let sol = minimize(
                &objective(&f),
                &[x0; 10],
                &CmaesConfig::new(sigma0, seed),
                &rules,
                &mut NoObserver,
            )
            .unwrap();
            if sol.best_cost <= 1e-8 {
                evals.push(sol.evaluations);
            } else {
                let in_local_minimum = name == "rosenbrock"
                    && (3.98..3.99).contains(&sol.best_cost)
                    && sol.best_x[0] < -0.9;
                assert!(in_local_minimum, "{name}, seed {seed}: {}", sol.best_cost);
                local += 1;
            }
        }
        assert!(local <= 1, "{name}: {local} runs in the local minimum");
        evals.sort_unstable();
        let m = evals.len();
        let median = (evals[(m - 1) / 2] + evals[m / 2]) as f64 / 2.0;
        let ratio = median / pycma;
        assert!(
            (0.85..=1.15).contains(&ratio),
            "{name}: median {median} vs pycma {pycma} (ratio {ratio:.3})"
        );
    }
}

/// Each stopping rule fires in the situation it is made for, and is reported by name.
mod stopping_rules {
    use super::objective;
    use cps_cmaes::{CmaesConfig, NoObserver, Solution, StopRule, functions, minimize};

    fn stop(f: impl Fn(&[f64]) -> f64 + Sync, x0: &[f64], sigma0: f64, rule: StopRule) -> Solution {
        let rules = [rule, StopRule::MaxGenerations(50_000)];
        minimize(
            &objective(&f),
            x0,
            &CmaesConfig::new(sigma0, 3),
            &rules,
            &mut NoObserver,
        )
        .unwrap()
    }

    #[test]
    fn budgets_and_targets() {
        let s = stop(
            functions::sphere,
            &[1.0; 5],
            0.5,
            StopRule::MaxGenerations(7),
        );
        assert_eq!(
            (s.termination.name(), s.generations),
            ("max_generations", 7)
        );
        let s = stop(
            functions::sphere,
            &[1.0; 5],
            0.5,
            StopRule::MaxEvaluations(100),
        );
        assert_eq!(s.termination.name(), "max_evaluations");
        assert!(
            s.evaluations <= 100 && s.evaluations + 8 > 100,
            "{}",
            s.evaluations
        );
        let s = stop(
            functions::sphere,
            &[1.0; 5],
            0.5,
            StopRule::TargetCost(1e-3),
        );
        assert_eq!(s.termination.name(), "target_cost");
        assert!(s.best_cost <= 1e-3);
    }

    #[test]
    fn convergence_rules_tolfun_and_tolx() {
        let s = stop(functions::sphere, &[1.0; 5], 0.5, StopRule::TolFun(1e-12));
        assert_eq!(s.termination.name(), "tolfun");
        assert!(s.best_cost < 1e-10, "{}", s.best_cost);
        let s = stop(functions::sphere, &[1.0; 5], 0.5, StopRule::TolX(1e-7));
        assert_eq!(s.termination.name(), "tolx");
        // σ·max(|p_c|, √C_ii) < 1e-7 per coordinate: the best point is that close.
        assert!(s.best_cost < 1e-12, "f {}", s.best_cost);
    }

    #[test]
    fn divergence_and_conditioning_rules() {
        // On a linear function the step size grows without bound.
        let s = stop(|x: &[f64]| x[0], &[0.0; 4], 1.0, StopRule::TolUpSigma(1e3));
        assert_eq!(s.termination.name(), "tolupsigma");
        assert!(s.sigma > 1e3, "σ {}", s.sigma);
        // A badly scaled ellipsoid drives the covariance's condition past the threshold.
        let scaled = |x: &[f64]| {
            x.iter()
                .enumerate()
                .map(|(i, v)| 1e4f64.powi(i as i32) * v * v)
                .sum()
        };
        let s = stop(scaled, &[1.0; 4], 1.0, StopRule::ConditionCov(1e6));
        assert_eq!(s.termination.name(), "conditioncov");
    }

    #[test]
    fn flat_and_stagnating_landscapes() {
        let s = stop(|_: &[f64]| 1.0, &[0.0; 3], 1.0, StopRule::FlatFitness(5));
        assert_eq!((s.termination.name(), s.generations), ("flat_fitness", 5));
        // Deterministic noise: no progress is possible, the medians stop improving.
        let noise = |x: &[f64]| {
            let h = x.iter().fold(0xcbf29ce484222325u64, |h, v| {
                (h ^ v.to_bits()).wrapping_mul(0x100000001b3)
            });
            (h >> 11) as f64 / (1u64 << 53) as f64
        };
        let s = stop(noise, &[0.0; 3], 1.0, StopRule::Stagnation);
        assert_eq!(s.termination.name(), "stagnation");
        // pycma's rule needs a history of more than 100 generations (n = 3, λ = 7: the
        // compared windows are 17 generations long).
        assert!((101..=400).contains(&s.generations), "{}", s.generations);
    }

    #[test]
    fn numerical_no_effect_rules() {
        // A step far below the resolution of the mean's coordinates changes nothing.
        let far = [1e20; 3];
        let s = stop(functions::sphere, &far, 1e-6, StopRule::NoEffectAxis);
        assert_eq!(s.termination.name(), "noeffectaxis");
        let s = stop(functions::sphere, &far, 1e-6, StopRule::NoEffectCoord);
        assert_eq!(s.termination.name(), "noeffectcoord");
        // Near the origin neither fires early.
        let s = stop(functions::sphere, &[1.0; 3], 0.5, StopRule::NoEffectCoord);
        assert!(s.generations > 50, "{}", s.generations);
    }
}

/// IPOP on Rastrigin, n = 10, x0 = 3·1, σ0 = 2: every one of seeds 1..10 reaches 1e-8
/// (pycma 4.5.0: 10/10, median 47 142 evaluations).
#[test]
fn ipop_solves_rastrigin_10_for_every_seed() {
    let mut evals = Vec::new();
    for seed in 1..=10 {
        let sol = cps_cmaes::minimize_ipop(
            &objective(&functions::rastrigin),
            &[3.0; 10],
            &CmaesConfig::new(2.0, seed),
            &StopRule::reference_set(1e-8, 10),
            9,
            &mut NoObserver,
        )
        .unwrap();
        assert!(
            sol.best.best_cost <= 1e-8,
            "seed {seed}: {}",
            sol.best.best_cost
        );
        assert_eq!(
            sol.best.evaluations,
            sol.runs.iter().map(|r| r.evaluations).sum::<u64>()
        );
        for (r, run) in sol.runs.iter().enumerate().skip(1) {
            assert!(run.evaluations > 0, "restart {r} ran");
        }
        evals.push(sol.best.evaluations);
    }
    evals.sort_unstable();
    eprintln!(
        "IPOP rastrigin n=10: median {} evaluations (pycma 47 142)",
        (evals[4] + evals[5]) / 2
    );
}

/// BIPOP on Rastrigin n = 10: every seed of 1..5 reaches 1e-8, the evaluations add up,
/// the same seed gives the same sequence, and the sequence is not IPOP's (small-population
/// runs with other λ and σ are interleaved).
#[test]
fn bipop_solves_rastrigin_10_and_is_reproducible() {
    let rules = StopRule::reference_set(1e-8, 10);
    let bipop = |seed| {
        cps_cmaes::minimize_bipop(
            &objective(&functions::rastrigin),
            &[3.0; 10],
            &CmaesConfig::new(2.0, seed),
            &rules,
            9,
            &mut NoObserver,
        )
        .unwrap()
    };
    let mut differs = false;
    for seed in 1..=5 {
        let sol = bipop(seed);
        assert!(
            sol.best.best_cost <= 1e-8,
            "seed {seed}: {}",
            sol.best.best_cost
        );
        assert_eq!(
            sol.best.evaluations,
            sol.runs.iter().map(|r| r.evaluations).sum::<u64>()
        );
        let ipop = cps_cmaes::minimize_ipop(
            &objective(&functions::rastrigin),
            &[3.0; 10],
            &CmaesConfig::new(2.0, seed),
            &rules,
            9,
            &mut NoObserver,
        )
        .unwrap();
        differs |= ipop.best.evaluations != sol.best.evaluations;
    }
    assert!(differs, "BIPOP ran exactly as IPOP for every seed");
    assert_eq!(bipop(3).best.evaluations, bipop(3).best.evaluations);
}

/// The boundary transformation: every image lies in the box, the box's interior is left
/// alone, it is continuous, and its inverse brings any point of the box back.
#[test]
fn the_boundary_transformation_keeps_every_candidate_in_the_box() {
    use cps_cmaes::Bounds;
    let b = Bounds::new(
        vec![-1.0, 0.0, 2.0, f64::NEG_INFINITY],
        vec![1.0, 1e-3, 50.0, 3.0],
    )
    .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut y, mut y2) = ([0.0; 4], [0.0; 4]);
    for _ in 0..100_000 {
        let x: Vec<f64> = (0..4).map(|_| (rng.random::<f64>() - 0.5) * 2e3).collect();
        b.transform(&x, &mut y);
        assert!(b.contains(&y), "{x:?} -> {y:?}");
        // Continuous: a tiny step moves the image by at most about as much.
        let x2: Vec<f64> = x.iter().map(|v| v + 1e-9).collect();
        b.transform(&x2, &mut y2);
        assert!(
            y.iter()
                .zip(&y2)
                .all(|(a, c)| (a - c).abs() <= 2e-9 + 1e-12 * a.abs())
        );
        // Inverse: the preimage maps back.
        let mut z = [0.0; 4];
        b.inverse(&y, &mut z).unwrap();
        b.transform(&z, &mut y2);
        assert!(
            y.iter()
                .zip(&y2)
                .all(|(a, c)| (a - c).abs() <= 1e-9 * (1.0 + a.abs()))
        );
    }
    // The interior (margins (1 + |bound|)/20 or half the width) is the identity.
    b.transform(&[0.3, 5e-4, 20.0, -100.0], &mut y);
    assert_eq!(y[0], 0.3);
    assert_eq!(y[2], 20.0);
    assert_eq!(y[3], -100.0);
    // Near a bound the map bends: ub − (x − ub − a_u)²/(4 a_u), with a_u = 0.1 here, so
    // 1.05 ↦ 1 − 0.05²/0.4 and 1.1 (= ub + a_u) ↦ exactly the bound.
    b.transform(&[1.05, -0.5, 2.0, 3.05], &mut y);
    assert!((y[0] - (1.0 - 0.0025 / 0.4)).abs() < 1e-15, "{}", y[0]);
    assert!(y[3] <= 3.0);
    b.transform(&[1.1, 0.0, 2.0, 0.0], &mut y);
    assert_eq!(y[0], 1.0);
    // Bad bounds and a start outside are named.
    assert!(Bounds::new(vec![1.0], vec![1.0]).is_err());
    assert!(Bounds::new(vec![f64::NAN], vec![1.0]).is_err());
    assert!(b.inverse(&[2.0, 0.0, 3.0, 0.0], &mut y).is_err());
}

/// An optimum outside the box: CMA-ES ends on the bound, exactly, as pycma's
/// BoundTransform does; an optimum inside costs few extra evaluations.
#[test]
fn bounded_searches_end_on_the_bound_or_at_the_inner_optimum() {
    use cps_cmaes::Bounds;
    let n = 10;
    // The sphere centred at 2, box [-1, 1]^n: the best point is 1 in every coordinate.
    let f = |x: &[f64]| x.iter().map(|v| (v - 2.0).powi(2)).sum::<f64>();
    let config = CmaesConfig {
        bounds: Some(Bounds::new(vec![-1.0; n], vec![1.0; n]).unwrap()),
        ..CmaesConfig::new(0.5, 3)
    };
    let rules = [
        StopRule::TargetCost(n as f64 + 1e-10),
        StopRule::MaxGenerations(5_000),
    ];
    let sol = minimize(
        &objective(&f),
        &vec![0.0; n],
        &config,
        &rules,
        &mut NoObserver,
    )
    .unwrap();
    assert!(sol.best_cost <= n as f64 + 1e-10, "{}", sol.best_cost);
    assert!(
        sol.best_x.iter().all(|&v| v <= 1.0 && v > 1.0 - 1e-10),
        "{:?}",
        sol.best_x
    );
    // Rosenbrock inside [-5, 5]^n: solved, with at most 25 % more evaluations.
    let rosen = |x: &[f64]| functions::rosenbrock(x);
    let free = run(rosen, &vec![0.0; n], 0.5, 1, 1e-8);
    let boxed = minimize(
        &objective(&rosen),
        &vec![0.0; n],
        &CmaesConfig {
            bounds: Some(Bounds::new(vec![-5.0; n], vec![5.0; n]).unwrap()),
            ..CmaesConfig::new(0.5, 1)
        },
        &[StopRule::TargetCost(1e-8), StopRule::MaxGenerations(20_000)],
        &mut NoObserver,
    )
    .unwrap();
    assert!(boxed.best_cost <= 1e-8);
    assert!(
        boxed.evaluations as f64 <= 1.25 * free.evaluations as f64,
        "{} vs {}",
        boxed.evaluations,
        free.evaluations
    );
}

/// A checkpoint saved as JSON mid-run and resumed continues exactly as the uninterrupted
/// run: the same bits at the end, with or without bounds, across a pending lazy
/// eigendecomposition.
#[test]
fn a_resumed_checkpoint_continues_the_run_bit_for_bit() {
    use cps_cmaes::{Bounds, Checkpoint, resume};
    let n = 12;
    let f = |x: &[f64]| functions::rosenbrock(x);
    for bounds in [
        None,
        Some(Bounds::new(vec![-3.0; n], vec![3.0; n]).unwrap()),
    ] {
        let config = CmaesConfig {
            bounds: bounds.clone(),
            ..CmaesConfig::new(0.5, 11)
        };
        let whole = minimize(
            &objective(&f),
            &vec![0.0; n],
            &config,
            &[StopRule::MaxGenerations(300)],
            &mut NoObserver,
        )
        .unwrap();
        // The same run in two halves, through JSON; 137 is not a multiple of the lazy gap.
        let x0 = vec![0.0; n];
        let start = match &bounds {
            Some(b) => {
                let mut z = vec![0.0; n];
                b.inverse(&x0, &mut z).unwrap();
                z
            }
            None => x0.clone(),
        };
        let mut es = Cmaes::new(&config, &start).unwrap();
        resume(
            &mut es,
            &objective(&f),
            &[StopRule::MaxGenerations(137)],
            &mut NoObserver,
        )
        .unwrap();
        let json = serde_json::to_string(&es.checkpoint()).unwrap();
        let saved: Checkpoint = serde_json::from_str(&json).unwrap();
        assert_eq!(saved.generation(), 137);
        let mut again = Cmaes::resume(&saved).unwrap();
        let rest = resume(
            &mut again,
            &objective(&f),
            &[StopRule::MaxGenerations(300)],
            &mut NoObserver,
        )
        .unwrap();
        assert_eq!(rest.generations, 300);
        assert_eq!(rest.evaluations, whole.evaluations);
        assert_eq!(rest.mean, whole.mean, "bounds: {}", bounds.is_some());
        assert_eq!(rest.sigma.to_bits(), whole.sigma.to_bits());
        assert_eq!(rest.best_cost.to_bits(), whole.best_cost.to_bits());
    }
    // A damaged checkpoint is refused, not resumed.
    let mut es = Cmaes::new(&CmaesConfig::new(0.5, 1), &[0.0; 3]).unwrap();
    resume(
        &mut es,
        &objective(&f),
        &[StopRule::MaxGenerations(5)],
        &mut NoObserver,
    )
    .unwrap();
    let json = serde_json::to_string(&es.checkpoint()).unwrap();
    let bad = json.replace("\"version\":2", "\"version\":7");
    let cp: cps_cmaes::Checkpoint = serde_json::from_str(&bad).unwrap();
    assert!(Cmaes::resume(&cp).is_err());
}

// The strategy's parameters against Hansen's tutorial formulas (moved from src/params.rs).

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1e-300)
}

#[test]
fn parameters_follow_the_tutorial_formulas() {
    for &n in &[2usize, 10, 75, 200] {
        let lambda = Parameters::default_lambda(n);
        let p = Parameters::new(n, lambda);
        let nf = n as f64;
        assert_eq!(p.lambda, 4 + (3.0 * nf.ln()) as usize);
        assert_eq!(p.mu, lambda / 2);
        let pos: Vec<f64> = p.weights[..p.mu].to_vec();
        assert!(close(pos.iter().sum::<f64>(), 1.0));
        let mu_eff = 1.0 / pos.iter().map(|w| w * w).sum::<f64>();
        assert!(close(p.mu_eff, mu_eff));
        // Weights are proportional to ln((λ+1)/2) − ln i within each sign group.
        for i in 1..p.mu {
            let r = ((lambda as f64 + 1.0) / 2.0).ln() - ((i + 1) as f64).ln();
            let r0 = ((lambda as f64 + 1.0) / 2.0).ln();
            assert!(close(p.weights[i] / p.weights[0], r / r0));
        }
        assert!(close(p.c_sigma, (mu_eff + 2.0) / (nf + mu_eff + 5.0)));
        let ds = 1.0 + 2.0 * f64::max(0.0, ((mu_eff - 1.0) / (nf + 1.0)).sqrt() - 1.0) + p.c_sigma;
        assert!(close(p.d_sigma, ds));
        assert!(close(
            p.c_c,
            (4.0 + mu_eff / nf) / (nf + 4.0 + 2.0 * mu_eff / nf)
        ));
        assert!(close(p.c1, 2.0 / ((nf + 1.3).powi(2) + mu_eff)));
        let cmu = f64::min(
            1.0 - p.c1,
            2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((nf + 2.0).powi(2) + mu_eff),
        );
        assert!(close(p.c_mu, cmu));
        let neg: Vec<f64> = p.weights[p.mu..]
            .iter()
            .copied()
            .filter(|w| *w < 0.0)
            .collect();
        let mu_eff_neg = neg.iter().sum::<f64>().powi(2) / neg.iter().map(|w| w * w).sum::<f64>();
        assert!(close(p.mu_eff_neg, mu_eff_neg));
        let total = f64::min(
            f64::min(1.0 + p.c1 / p.c_mu, 1.0 + 2.0 * mu_eff_neg / (mu_eff + 2.0)),
            (1.0 - p.c1 - p.c_mu) / (nf * p.c_mu),
        );
        assert!(close(p.negative_weight_total(), total));
        assert!(p.weights.windows(2).all(|w| w[0] >= w[1]));
    }
}

#[test]
fn known_values_at_n_10() {
    // λ = 10, μ = 5; reference values computed independently in Python.
    let p = Parameters::new(10, 10);
    assert_eq!((p.lambda, p.mu), (10, 5));
    assert!((p.mu_eff - 3.167_299_281_410_702_6).abs() < 1e-12);
    assert!((p.chi_n - 3.084_726_565_169_012_3).abs() < 1e-12);
    assert_eq!(Parameters::new(75, 16).default_eigen_gap(), 4);
}

#[test]
fn separable_rates_are_scaled_by_n_plus_2_over_3() {
    let (full, sep) = (Parameters::new(40, 15), Parameters::separable(40, 15));
    assert!(close(sep.c1, full.c1 * 14.0));
    assert!(close(sep.c_mu, full.c_mu * 14.0));
    assert_eq!(sep.c_sigma, full.c_sigma);
    // The negative weights follow the positive-definiteness bound of the new rates.
    let posdef = (1.0 - sep.c1 - sep.c_mu) / (40.0 * sep.c_mu);
    assert!(sep.negative_weight_total() <= posdef * (1.0 + 1e-12));
}

// The benchmark functions' seeds and runs (moved from src/functions.rs).

#[test]
fn seeds_are_read_and_bounded() {
    let seeds = |t: &str| t.parse::<Seeds>().map(|s| (s.first, s.last));
    assert_eq!(seeds("3..7").unwrap(), (3, 7));
    assert_eq!(seeds(" 5 ").unwrap(), (5, 5));
    assert!(seeds("7..3").is_err());
    assert!(seeds("0..20000").unwrap_err().contains("20001 seeds"));
}

#[test]
fn a_bench_runs_every_seed_and_refuses_a_dimension_out_of_range() {
    let mut b = Bench {
        function: TestFunction::Sphere,
        dim: 3,
        seeds: "4..6".parse().unwrap(),
        restarts: Restarts::None,
        separable: false,
    };
    let mut told = Vec::new();
    let s = bench(&b, |r| told.push(r.seed)).unwrap();
    assert_eq!(told, [4, 5, 6]);
    assert_eq!(s.successes(), 3);
    let mut e: Vec<u64> = s.runs.iter().map(|r| r.evaluations).collect();
    e.sort_unstable();
    assert_eq!(s.median_evaluations(), e[1] as f64);
    b.dim = 5001;
    assert!(matches!(
        bench(&b, |_| {}),
        Err(CmaesError::InvalidConfig { field: "dim", .. })
    ));
    b.separable = true;
    b.seeds = "1".parse().unwrap();
    b.dim = 0;
    assert!(bench(&b, |_| {}).is_err());
}
