//! Criterion benchmarks of the hot paths, named by size.
//!
//! Run with `cargo bench --bench core`; figures go to BENCHMARKS.md.

use std::hint::black_box;
use std::ops::ControlFlow;

use cps::cmaes::{Cmaes, CmaesConfig, functions};
use cps::dmp::{DiscreteDmp, DmpConfig};
use cps::learn::{Parametrisation, SearchSpace, ViaPointConfig, ViaPointTask, learn_via_points};
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn thesis_dmp() -> DiscreteDmp {
    DiscreteDmp::new(
        DmpConfig::new(25, 10.0, 0.01),
        &[0.75, 0.02, 1.87],
        &[0.55, -0.57, 1.45],
    )
    .unwrap()
}

fn random_weights(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| rng.random_range(-1e3..1e3)).collect()
}

fn rollout(c: &mut Criterion) {
    let dmp = thesis_dmp();
    let w = random_weights(dmp.n_weights(), 1);
    let mut traj = dmp.new_trajectory();
    c.bench_function("rollout/3x25x1000", |b| {
        b.iter(|| dmp.rollout_into(black_box(&w), &mut traj))
    });
    let pop = random_weights(16 * dmp.n_weights(), 2);
    let mut out: Vec<_> = (0..16).map(|_| dmp.new_trajectory()).collect();
    c.bench_function("rollout_batch/16x3x25x1000", |b| {
        b.iter(|| dmp.rollout_batch(black_box(&pop), &mut out))
    });
}

fn cmaes_overhead(c: &mut Criterion) {
    for n in [75usize, 200] {
        c.bench_function(&format!("cmaes_overhead/n={n}"), |b| {
            b.iter_batched_ref(
                || Cmaes::new(&CmaesConfig::new(1.0, 3), &vec![1.0; n]).unwrap(),
                |es| {
                    // Several generations per sample so the lazy decomposition is amortised
                    // as in a real run.
                    for _ in 0..8 {
                        let costs: Vec<f64> = es.ask().chunks(n).map(functions::sphere).collect();
                        es.tell(&costs).unwrap();
                    }
                },
                BatchSize::LargeInput,
            )
        });
    }
}

fn cmaes_generation(c: &mut Criterion) {
    // One generation at n = 75, λ = 16, including its 16 via-point rollouts and costs,
    // on one thread.
    let task = ViaPointTask::thesis();
    let dmp = task.build_dmp().unwrap();
    let space = SearchSpace::new(Parametrisation::AnchorOffset, &dmp);
    let n = space.len();
    let mut w = vec![0.0; n];
    let mut traj = dmp.new_trajectory();
    c.bench_function("cmaes_generation/n=75", |b| {
        b.iter_batched_ref(
            || Cmaes::new(&CmaesConfig::new(0.5, 3), &vec![0.0; n]).unwrap(),
            |es| {
                for _ in 0..8 {
                    let xs = es.ask().to_vec();
                    let costs: Vec<f64> = xs
                        .chunks(n)
                        .map(|x| {
                            space.to_weights(x, &mut w);
                            dmp.rollout_into(&w, &mut traj);
                            task.cost(&traj)
                        })
                        .collect();
                    es.tell(&costs).unwrap();
                }
            },
            BatchSize::LargeInput,
        )
    });
}

fn viapoint_run(c: &mut Criterion) {
    let mut config = ViaPointConfig::new(ViaPointTask::thesis());
    config.generations = 200;
    config.tol_fun = None;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut group = c.benchmark_group("viapoint");
    group.sample_size(20);
    group.bench_function("200_generations", |b| {
        b.iter(|| {
            pool.install(|| learn_via_points(&config, &|_, _| ControlFlow::Continue(())).unwrap())
        })
    });
    group.finish();
}

criterion_group!(
    benches,
    rollout,
    cmaes_overhead,
    cmaes_generation,
    viapoint_run
);
criterion_main!(benches);
