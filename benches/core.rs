//! Criterion benchmarks of the hot paths, named by size.
//!
//! Run with `cargo bench --bench core`; figures go to BENCHMARKS.md.

use std::hint::black_box;
use std::ops::ControlFlow;

use cps::cmaes::{Cmaes, CmaesConfig, Objective};
use cps::dmp::{DiscreteDmp, DmpConfig};
use cps::learn::{
    EffortConfig, Evaluation, Parametrisation, PointMassPlant, QuadraticCost, SearchSpace,
    ViaPointConfig, ViaPointObjective, ViaPointTask, exact_optimum, learn_via_points,
    learn_with_effort,
};
use criterion::{Criterion, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A rayon pool whose only worker is the benchmark's own thread, so `install` runs in
/// place and no iteration pays for a hand-off between threads.
fn one_thread_pool() -> &'static rayon::ThreadPool {
    static POOL: std::sync::OnceLock<rayon::ThreadPool> = std::sync::OnceLock::new();
    POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .use_current_thread()
            .build()
            .unwrap()
    })
}

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

fn kinematics(c: &mut Criterion) {
    use cps::kinematics::robots::{PandaTool, panda};
    let arm = panda(PandaTool::HandTcp);
    let q = [0.3, -0.5, 0.2, -2.0, 0.1, 1.6, 0.7];
    c.bench_function("fk/panda", |b| b.iter(|| arm.fk(black_box(&q)).unwrap()));
    c.bench_function("jacobian/panda", |b| {
        b.iter(|| arm.jacobian(black_box(&q)).unwrap())
    });
    // Inverse dynamics (recursive Newton–Euler) with Gaz et al.'s inertias, gravity on.
    let links = cps::kinematics::robots::panda_inertia();
    let gravity = nalgebra::Vector3::from(cps::kinematics::GRAVITY);
    let (qd, qdd) = (
        [0.3, -0.2, 0.5, 0.1, -0.4, 0.2, 0.6],
        [1.0, -0.5, 0.8, 0.3, -1.2, 0.7, 0.4],
    );
    c.bench_function("rnea/panda", |b| {
        b.iter(|| {
            arm.inverse_dynamics(&links, gravity, black_box(&q), &qd, &qdd)
                .unwrap()
        })
    });
    // Forward dynamics (q̈ from τ) of the same arm with franky-sim's armature and friction,
    // the frames included: the articulated-body algorithm, and the mass matrix by the
    // composite-rigid-body algorithm with a Cholesky solve.
    let (model, friction) = franky_sim_panda();
    let tau = [5.0, -3.0, 2.0, 1.0, 0.5, -0.2, 0.1];
    c.bench_function("forward_dynamics/aba_panda", |b| {
        b.iter(|| {
            let f = model.frames(black_box(&q));
            model.forward_dynamics(&f, &qd, &tau, Some(&friction))
        })
    });
    c.bench_function("forward_dynamics/crba_cholesky_panda", |b| {
        b.iter(|| {
            let f = model.frames(black_box(&q));
            model.forward_dynamics_crba(&f, &qd, &tau, Some(&friction))
        })
    });
    dynamics_robot(c);
    retiming(c);
    ik(c);
}

/// The Panda with its hand (Gaz et al.'s inertias) and franky-sim's rotor inertia and
/// joint friction.
fn franky_sim_panda() -> (
    cps::kinematics::ArmModel<7>,
    cps::kinematics::contact::JointFriction<7>,
) {
    use cps::kinematics::robots::{PandaTool, panda, panda_inertia};
    let model = cps::kinematics::ArmModel::<7>::new(&panda(PandaTool::HandTcp), &panda_inertia())
        .unwrap()
        .with_armature([0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074])
        .unwrap();
    let friction = cps::kinematics::contact::JointFriction {
        viscous: [0.21; 7],
        coulomb: [1.137, 1.137, 1.137, 1.137, 0.763, 0.44, 0.248],
        speed: 0.01,
    };
    (model, friction)
}

/// A 10 s movement of every joint run on the dynamics robot (the Panda with franky-sim's
/// rotor inertia and friction, franky-sim's PD, 1 kHz): 10 000 control periods, each the
/// controller's Coriolis and gravity torques and one forward-dynamics step. Ten simulated
/// seconds over the time measured is the real-time factor (BENCHMARKS.md › Dynamics).
fn dynamics_robot(c: &mut Criterion) {
    use cps::dynamics::{Arm, Controller, DynamicsRobot, DynamicsSettings, Integrator};
    use cps::kinematics::robots::{PandaTool, panda};
    use cps::robot::{Plan, Robot, RobotModel, StopToken};
    let chain = panda(PandaTool::HandTcp);
    let (model, friction) = franky_sim_panda();
    let start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let points = (0..=1000)
        .map(|k| {
            let s = (std::f64::consts::PI * k as f64 / 1000.0).sin().powi(2);
            start.iter().map(|q| q + 0.3 * s).collect()
        })
        .collect();
    let plan = Plan::new(0.01, points).unwrap();
    for integrator in [Integrator::SemiImplicitEuler, Integrator::Rk4] {
        let mut arm = Arm::at_rest(
            model.clone(),
            friction,
            [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0],
            start,
        );
        arm.integrator = integrator;
        let mut robot = DynamicsRobot::new(
            RobotModel::of_chain("panda", chain.clone()),
            arm,
            DynamicsSettings {
                controller: Controller::franky_sim(),
                control_period: 0.001,
                dt: 0.01,
                noise: 0.0,
                seed: 0,
                reflexes: true,
                lag: 0,
            },
        )
        .unwrap();
        let stop = StopToken::new();
        c.bench_function(&format!("dynamics/run_10s_pd_{}", integrator.name()), |b| {
            b.iter(|| {
                robot.teleport(&start).unwrap();
                robot.run(black_box(&plan), &stop).unwrap()
            })
        });
    }
}

/// A smooth random 7-joint path of 1000 samples inside the Panda's range (the path of
/// python/benchmarks/retime_vs_toppra.py, seed 1).
fn retime_path() -> (Vec<f64>, Vec<Vec<f64>>) {
    let amp = [0.25, 0.5, 0.35, 0.3, 0.45, 0.4, 0.55];
    let freq = [0.7, 1.2, 0.9, 1.4, 0.6, 1.1, 0.8];
    let mid = [0.0, 0.0, 0.0, -1.5, 0.0, 1.8, 0.0];
    (0..1000)
        .map(|k| {
            let s = k as f64 / 999.0;
            let q = (0..7)
                .map(|j| mid[j] + amp[j] * (std::f64::consts::TAU * freq[j] * s + j as f64).sin())
                .collect();
            (2.0 * s, q)
        })
        .unzip()
}

/// Retiming a 1000-sample 7-joint path: TOPP-RA on 1000 grid intervals with velocity and
/// acceleration limits (what toppra is compared on), and with every Panda limit (torques by
/// RNEA at each grid point, Cartesian limits, jerk smoothing, verification at 1 kHz).
fn retiming(c: &mut Criterion) {
    use cps::kinematics::retime::{RetimeOptions, RobotLimits, retime};
    use cps::kinematics::robots::{PandaTool, panda, panda_inertia, panda_limits};
    let arm = panda(PandaTool::HandTcp);
    let (t, q) = retime_path();
    let (full, cartesian) = panda_limits();
    let va = cps::kinematics::JointLimits {
        acceleration: full.acceleration.clone(),
        ..Default::default()
    };
    let links = panda_inertia();
    let gravity = nalgebra::Vector3::from(cps::kinematics::GRAVITY);
    let options = RetimeOptions::default();
    let velocity_acceleration = RobotLimits {
        chain: &arm,
        limits: &va,
        inertia: None,
        gravity,
        cartesian: None,
    };
    c.bench_function("retime/panda_1000_vel_acc", |b| {
        b.iter(|| retime(&velocity_acceleration, black_box(&t), &q, &options).unwrap())
    });
    let every = RobotLimits {
        chain: &arm,
        limits: &full,
        inertia: Some(&links),
        gravity,
        cartesian: Some(&cartesian),
    };
    c.bench_function("retime/panda_1000_every_limit", |b| {
        b.iter(|| retime(&every, black_box(&t), &q, &options).unwrap())
    });
}

/// IK for full poses of 1000 random in-limit configurations, from the ready pose, with
/// seeded restarts. Criterion times the mean per target; the median, p90 and success rate
/// over the same targets are printed once (the figures).
fn ik(c: &mut Criterion) {
    use cps::kinematics::robots::{PandaTool, panda};
    use cps::kinematics::{IkConfig, IkTarget, solve_ik};
    let arm = panda(PandaTool::HandTcp);
    let ready = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let targets: Vec<IkTarget> = (0..1000)
        .map(|_| IkTarget::Pose(arm.fk(&arm.random_configuration(&mut rng)).unwrap()))
        .collect();
    let config = IkConfig::default();
    // Each target's time is the best of three solves (the same work each time), which
    // removes most of a shared machine's scheduling noise from the distribution.
    let mut times = vec![f64::INFINITY; targets.len()];
    let mut solved = 0;
    for round in 0..3 {
        for (t, best) in targets.iter().zip(&mut times) {
            let start = std::time::Instant::now();
            let r = solve_ik(&arm, t, &ready, &config);
            *best = best.min(start.elapsed().as_secs_f64() * 1e6);
            if round == 0 {
                solved += usize::from(r.is_ok());
            }
        }
    }
    times.sort_by(f64::total_cmp);
    eprintln!(
        "ik/panda_pose_1000: {solved}/1000 solved, median {:.1} µs, p90 {:.1} µs, max {:.0} µs",
        times[500], times[900], times[999]
    );
    let mut k = 0;
    c.bench_function("ik/panda_pose", |b| {
        b.iter(|| {
            k = (k + 1) % targets.len();
            solve_ik(&arm, black_box(&targets[k]), &ready, &config)
        })
    });
}

/// DMP imitation and online stepping (issue 3's figures).
fn dmp_extras(c: &mut Criterion) {
    use cps::dmp::{Combine, Demonstration, Imitator, OnlineDmp, Regression};
    // A smooth 3-D demonstration: 10 s, 1000 samples.
    let times: Vec<f64> = (0..1000).map(|k| 10.0 * k as f64 / 999.0).collect();
    let rows: Vec<Vec<f64>> = times
        .iter()
        .map(|&t| {
            let s = t / 10.0;
            let mj = 10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5);
            let bump = (std::f64::consts::PI * s).sin().powi(2);
            vec![
                0.75 - 0.2 * mj + 0.1 * bump,
                0.02 - 0.59 * mj,
                1.87 - 0.42 * mj,
            ]
        })
        .collect();
    let demo = [Demonstration::new(times, &rows).unwrap()];
    let imitator = Imitator::new(thesis_dmp());
    c.bench_function("imitate/ridge_3x1000x25", |b| {
        b.iter(|| {
            imitator
                .imitate(black_box(&demo), Regression::default(), Combine::Mean)
                .unwrap()
        })
    });
    c.bench_function("imitate/ridge_weights_only_3x1000x25", |b| {
        b.iter(|| {
            imitator
                .weights(black_box(&demo), Regression::default(), Combine::Mean)
                .unwrap()
        })
    });
    let dmp = thesis_dmp();
    let w = random_weights(dmp.n_weights(), 3);
    let mut online = OnlineDmp::new(&dmp, &w);
    let h = dmp.config().step();
    c.bench_function("online_step/3d", |b| {
        b.iter(|| {
            online.step(black_box(h)).unwrap();
            if online.phase() < 1e-3 {
                online = OnlineDmp::new(&dmp, &w);
            }
        })
    });
}

/// Remote-API round trips: the Rust client against the stand-in server on loopback.
fn coppelia(c: &mut Criterion) {
    use cps::coppelia::{Client, ClientConfig, SceneSetup, ServerConfig, StandInServer};
    use cps::kinematics::robots::{PandaTool, panda};
    let server = StandInServer::start(ServerConfig {
        bind: "127.0.0.1:0".into(),
        scene: SceneSetup {
            robot_name: "Panda".into(),
            chain: panda(PandaTool::HandTcp),
            initial_q: vec![0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
            dummies: vec![],
            dt: 0.05,
            ik_following: false,
            step_cost: std::time::Duration::ZERO,
            script: true,
        },
        limits: cps::coppelia::ServerLimits::default(),
    })
    .unwrap();
    let mut sim = Client::connect(ClientConfig {
        endpoint: server.endpoint().into(),
        ..ClientConfig::default()
    })
    .unwrap();
    let joints: Vec<i64> = (1..=7)
        .map(|i| sim.get_object(&format!("/Panda_joint{i}")).unwrap())
        .collect();
    let tip = sim.get_object("/Panda_tip").unwrap();
    c.bench_function("coppelia/get_joint_position", |b| {
        b.iter(|| sim.get_joint_position(black_box(joints[0])).unwrap())
    });
    c.bench_function("coppelia/read_7_joints_and_tip", |b| {
        b.iter(|| {
            let q: Vec<f64> = joints
                .iter()
                .map(|&j| sim.get_joint_position(j).unwrap())
                .collect();
            (q, sim.get_object_position(tip, -1).unwrap())
        })
    });
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
    // ask + tell with a trivial objective on one thread, in steady state: a persistent
    // optimiser, so the periodic diagnostic eigendecomposition is amortised as in a real
    // run. Then the separable variant at n = 1000 (λ = 24): O(n λ), no matrix.
    let separable = CmaesConfig {
        separable: true,
        ..CmaesConfig::new(1.0, 3)
    };
    for (name, n, config) in [
        ("cmaes_overhead/n=75", 75, CmaesConfig::new(1.0, 3)),
        ("cmaes_overhead/n=200", 200, CmaesConfig::new(1.0, 3)),
        ("cmaes_overhead_separable/n=1000", 1000, separable),
    ] {
        let mut es = Cmaes::new(&config, &vec![1.0; n]).unwrap();
        let mut g = 0u64;
        c.bench_function(name, |b| {
            b.iter(|| {
                // Costs independent of x (a random ranking): the distribution neither
                // collapses nor diverges however many generations criterion runs.
                g += 1;
                let lambda = es.parameters().lambda;
                let costs: Vec<f64> = (0..lambda as u64)
                    .map(|i| ((i * 7919 + g * 104729) % 1009) as f64)
                    .collect();
                es.ask();
                es.tell(&costs).unwrap();
            })
        });
    }
}

fn cmaes_generation(c: &mut Criterion) {
    // One generation of the thesis task at n = 75, λ = 16: ask, the 16 via-point rollouts
    // and costs (batch rollouts), tell; one thread.
    let task = ViaPointTask::thesis();
    let dmp = task.build_dmp().unwrap();
    let space = SearchSpace::new(Parametrisation::AnchorOffset, &dmp);
    let objective = ViaPointObjective::new(&task, &dmp, &space);
    let n = space.len();
    let pool = one_thread_pool();
    let mut es = Cmaes::new(&CmaesConfig::new(0.5, 3), &vec![0.0; n]).unwrap();
    let mut costs = vec![0.0; es.parameters().lambda];
    c.bench_function("cmaes_generation/n=75", |b| {
        b.iter(|| {
            pool.install(|| {
                let xs = es.ask().to_vec();
                objective.evaluate_batch(&xs, n, &mut costs).unwrap();
                es.tell(&costs).unwrap();
            })
        })
    });
    let mut out = vec![0.0; 16];
    let xs: Vec<f64> = (0..16 * n)
        .map(|i| ((i % 13) as f64 - 6.0) * 0.05)
        .collect();
    c.bench_function("viapoint_costs/16x75", |b| {
        b.iter(|| {
            pool.install(|| {
                objective
                    .evaluate_batch(black_box(&xs), n, &mut out)
                    .unwrap()
            })
        })
    });
    c.bench_function("exact_optimum/thesis", |b| {
        b.iter(|| exact_optimum(&task, &dmp, &space).unwrap())
    });
    // The same 16 costs by the cost's exact quadratic form (what CMA-ES evaluates when
    // the cost is quadratic), one thread.
    let quadratic = QuadraticCost::of_task(&task, &dmp, &space).unwrap();
    let mut scratch = Vec::new();
    c.bench_function("quadratic_costs/16x75", |b| {
        b.iter(|| {
            for (x, o) in black_box(&xs).chunks_exact(n).zip(out.iter_mut()) {
                *o = quadratic.cost(x, &mut scratch);
            }
        })
    });
}

fn viapoint_run(c: &mut Criterion) {
    let mut config = ViaPointConfig::new(ViaPointTask::thesis());
    config.generations = 200;
    config.tol_fun = None;
    let pool = one_thread_pool();
    let mut group = c.benchmark_group("viapoint");
    group.sample_size(20);
    group.bench_function("200_generations", |b| {
        b.iter(|| {
            pool.install(|| learn_via_points(&config, &|_, _| ControlFlow::Continue(())).unwrap())
        })
    });
    // The same run with the machine's default pool (every core), as the CLI runs it.
    group.bench_function("200_generations_all_cores", |b| {
        b.iter(|| learn_via_points(&config, &|_, _| ControlFlow::Continue(())).unwrap())
    });
    // Every candidate rolled out instead of the quadratic form (the same search).
    let mut rollouts = config.clone();
    rollouts.evaluation = Evaluation::Rollout;
    group.bench_function("200_generations_rollouts", |b| {
        b.iter(|| {
            pool.install(|| learn_via_points(&rollouts, &|_, _| ControlFlow::Continue(())).unwrap())
        })
    });
    group.finish();
}

/// The parallel speed-up of the effort task (thesis eq. 53/54) when every candidate is
/// simulated: 10 generations of λ = 96 (each candidate a 1 kHz simulation of three
/// PD-controlled masses) on one thread and on two. (This was the shipped experiment's
/// `[speedup]` section; a timing belongs here.) Same seed, same bits on both: tested in
/// crates/cps-learn/tests/pipelines.rs.
fn energy_population(c: &mut Criterion) {
    let mut learner = ViaPointConfig::new(ViaPointTask::thesis());
    learner.warm_start = true;
    learner.sigma0 = 0.05;
    learner.population = Some(96);
    learner.generations = 10;
    learner.tol_fun = None;
    learner.evaluation = Evaluation::Rollout;
    let config = EffortConfig {
        learner,
        plant: PointMassPlant::default(),
        effort_weight: 1e-2,
    };
    let mut group = c.benchmark_group("energy_population");
    group.sample_size(10);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        group.bench_function(format!("10_generations_96/threads={threads}"), |b| {
            b.iter(|| {
                pool.install(|| learn_with_effort(&config, &|_| ControlFlow::Continue(())).unwrap())
            })
        });
    }
    group.finish();
}

/// 20 demonstrations × 1000 samples × 3 dimensions, as `python/benchmarks/beyond.py`
/// builds them for movement_primitives (a sine, a cosine and a parabola with seeded
/// offsets and gains).
fn promp_demos() -> Vec<(Vec<f64>, Vec<Vec<f64>>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let t: Vec<f64> = (0..1000).map(|k| k as f64 / 999.0).collect();
    (0..20)
        .map(|_| {
            let (a, b, c, d): (f64, f64, f64, f64) = (
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.05..0.05),
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.05..0.05),
            );
            let y = t
                .iter()
                .map(|&s| {
                    vec![
                        (std::f64::consts::TAU * s + a).sin() + b,
                        (std::f64::consts::PI * s).cos() * (1.0 + c),
                        s * s + d,
                    ]
                })
                .collect();
            (t.clone(), y)
        })
        .collect()
}

fn promp(c: &mut Criterion) {
    use cps::promp::{Observation, ProMp};
    let demos = promp_demos();
    c.bench_function("promp/fit_20x1000x3_25", |b| {
        b.iter(|| ProMp::fit(black_box(&demos), 25, 1.0).unwrap())
    });
    let p = ProMp::fit(&demos, 25, 1.0).unwrap();
    let via = [Observation::position(0.5, vec![0.5, 0.2, 0.3], 0.0)];
    c.bench_function("promp/condition_1_via", |b| {
        b.iter(|| p.condition(black_box(&via)).unwrap())
    });
    let t: Vec<f64> = (0..1000).map(|k| k as f64 / 999.0).collect();
    c.bench_function("promp/sample_1000x1000x3", |b| {
        b.iter(|| p.sample_trajectories(1000, 1, black_box(&t)).unwrap())
    });
}

fn obstacles(c: &mut Criterion) {
    use cps::dmp::SteeringAngle;
    let dmp = DiscreteDmp::new(DmpConfig::new(10, 1.0, 0.001), &[0.0; 3], &[1.0; 3]).unwrap();
    let w = random_weights(dmp.n_weights(), 5);
    let steer = SteeringAngle::new(&[0.5; 3]).unwrap();
    c.bench_function("obstacle/rollout_3x10x1000_plain", |b| {
        b.iter(|| dmp.rollout(black_box(&w)))
    });
    c.bench_function("obstacle/rollout_3x10x1000_steering", |b| {
        b.iter(|| dmp.rollout_coupled(black_box(&w), &steer))
    });
}

/// The chunk executor's work per 1 ms period on the FR3: a 30 Hz stand-in's chunks of
/// 50 targets pushed as they arrive, one command out per period (1000 periods per
/// iteration: the time per period is the reported time / 1000).
fn chunk_executor(c: &mut Criterion) {
    use cps::kinematics::robots::{PANDA_READY, PandaTool, fr3, fr3_limits};
    let mut model = cps::robot::RobotModel::of_chain("fr3", fr3(PandaTool::HandTcp));
    model.limits = fr3_limits();
    let demo = |t: f64| -> Vec<f64> {
        PANDA_READY
            .iter()
            .map(|q| q + 0.3 * (0.5 - 0.5 * (std::f64::consts::FRAC_PI_2 * t).cos()))
            .collect()
    };
    // The stand-in's chunks at 30 Hz for `seconds`.
    let stand_in = |seed: u64, seconds: f64| {
        cps::chunks::StandIn {
            horizon: 50,
            target_hz: 50.0,
            chunk_hz: 30.0,
            delay_s: (0.05, 0.15),
            noise_rad: 0.002,
            seed,
        }
        .chunks(&demo, 0.0, seconds)
    };
    let chunks = stand_in(1, 1.0);
    let settings = cps::chunks::FollowSettings::default();
    // Each period timed on its own over 20 s of chunks, for its median and p99 (what a
    // 1 kHz loop must fit): printed beside criterion's mean.
    {
        let long = stand_in(2, 20.0);
        let mut ex = cps::chunks::executor_for(&model, &PANDA_READY, 1e-3, &settings).unwrap();
        let mut it = long.into_iter().peekable();
        let mut ns = Vec::with_capacity(20_000);
        let mut kept = Vec::with_capacity(1_000);
        for k in 0..20_000 {
            let t = k as f64 * 1e-3;
            let start = std::time::Instant::now();
            while let Some(c) = it.next_if(|c| c.arrived_s <= t) {
                if let cps::chunks::Offer::Taken { replaced, .. } = ex.offer(c, t) {
                    // Kept, as the loop hands chunks back to be freed elsewhere.
                    kept.push(replaced);
                }
            }
            black_box(ex.tick(t + 1e-3));
            ns.push(start.elapsed().as_nanos() as u64);
        }
        ns.sort_unstable();
        eprintln!(
            "chunks/executor_period_fr3_30hz: median {} ns, p99 {} ns, max {} ns over 20 000 periods",
            ns[10_000], ns[19_800], ns[19_999]
        );
    }
    c.bench_function("chunks/executor_1000_periods_fr3_30hz", |b| {
        b.iter_batched(
            || {
                (
                    cps::chunks::executor_for(&model, &PANDA_READY, 1e-3, &settings).unwrap(),
                    chunks.clone(),
                )
            },
            |(mut ex, chunks)| {
                let mut it = chunks.into_iter().peekable();
                for k in 0..1000 {
                    let t = k as f64 * 1e-3;
                    while let Some(c) = it.next_if(|c| c.arrived_s <= t) {
                        black_box(ex.offer(c, t));
                    }
                    black_box(ex.tick(t + 1e-3));
                }
            },
            criterion::BatchSize::SmallInput,
        )
    });
}

/// A 10 s movement of every joint at 1 kHz (10 000 commands), judged against every limit:
/// a plan's check on the Panda with its inertias (torques by inverse dynamics at every
/// command, and the tool's Cartesian limits), and the Franka's per-millisecond check of
/// the same commands (BENCHMARKS.md › Limits).
fn limits(c: &mut Criterion) {
    use cps::kinematics::robots::{PandaTool, panda, panda_inertia, panda_limits};
    use cps::kinematics::{GRAVITY, RobotLimits, check_commands};
    let chain = panda(PandaTool::HandTcp);
    let (joint_limits, cartesian) = panda_limits();
    let inertia = panda_inertia();
    let start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let commands: Vec<Vec<f64>> = (0..10_000)
        .map(|k| {
            let s = (std::f64::consts::PI * k as f64 / 10_000.0).sin().powi(2);
            start.iter().map(|q| q + 0.3 * s).collect()
        })
        .collect();
    let robot = RobotLimits {
        chain: &chain,
        limits: &joint_limits,
        inertia: Some(&inertia),
        gravity: nalgebra::Vector3::from(GRAVITY),
        cartesian: Some(&cartesian),
    };
    c.bench_function("limits/plan_10k_commands", |b| {
        b.iter(|| check_commands(black_box(&robot), 0.0, 1e-3, &commands).unwrap())
    });
    let stream: Vec<[f64; 7]> = commands
        .iter()
        .map(|q| std::array::from_fn(|i| q[i]))
        .collect();
    let fr3 = cps::franka::limits::RateLimits::of(cps::franka::limits::Arm::Panda);
    c.bench_function("limits/franka_stream_10k_commands", |b| {
        b.iter(|| cps::franka::limits::check_stream(fr3, start, black_box(&stream)).unwrap())
    });
}

criterion_group!(dmp_benches, dmp_extras, coppelia, chunk_executor);
criterion_group!(beyond, promp, obstacles, limits);
criterion_group!(
    benches,
    kinematics,
    rollout,
    cmaes_overhead,
    cmaes_generation,
    viapoint_run,
    energy_population
);
criterion_main!(dmp_benches, beyond, benches);
