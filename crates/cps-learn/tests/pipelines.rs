//! The robot pipelines on the in-process robot: the thesis's imitation experiment end to
//! end, way-point reachability, and joint-space via-point learning.

use std::ops::ControlFlow;

use cps_kinematics::robots::{PandaTool, panda};
use cps_learn::{
    ImitationConfig, LearnError, RobotSetup, Solver, ViaPointConfig, ViaPointTask,
    check_way_points, run_imitation,
};
use cps_robot::{ExecutionConfig, KinematicRobot, StopToken};
use nalgebra::Isometry3;

const THESIS_Q0: [f64; 7] = cps_kinematics::robots::PANDA_THESIS_START;

fn thesis_robot() -> RobotSetup {
    RobotSetup {
        chain: panda(PandaTool::HandTcp).with_base(Isometry3::translation(0.5396, 0.02, 0.749)),
        initial_q: THESIS_Q0.to_vec(),
        execution: ExecutionConfig::default(),
    }
}

fn config(demos: usize) -> ImitationConfig {
    let mut learner = ViaPointConfig::new(ViaPointTask::thesis());
    learner.solver = Solver::Exact;
    let mut c = ImitationConfig::thesis(learner, thesis_robot());
    c.demonstrations = demos;
    c
}

#[test]
fn the_thesis_pipeline_imitates_the_mean_within_a_millimetre() {
    let c = config(20);
    let mut robot = KinematicRobot::new(c.robot.chain.clone(), &THESIS_Q0, 0.01).unwrap();
    let out = run_imitation(
        &c,
        &mut robot,
        &|_, _, _| ControlFlow::Continue(()),
        &StopToken::new(),
    )
    .unwrap();
    assert!(out.complete);
    assert_eq!(out.demonstrations.len(), 20);
    let kept = out.kept().count();
    let dropped: Vec<_> = out
        .demonstrations
        .iter()
        .filter_map(|d| d.dropped.as_ref())
        .collect();
    assert!(kept >= 5, "{kept} kept");
    assert_eq!(kept + dropped.len(), 20);
    // Every executed demonstration is tracked within 1 mm.
    for d in out.kept() {
        let r = d.recording.as_ref().unwrap();
        assert!(
            r.max_position_error() < 1e-3,
            "demo {}: {}",
            d.index,
            r.max_position_error()
        );
    }
    assert_eq!(out.fits.len(), 2);
    let (ridge, jerk) = (&out.fits[0], &out.fits[1]);
    for f in &out.fits {
        assert!(f.rmse() < 1e-3, "{} rmse {}", f.method, f.rmse());
        assert!(f.recording.as_ref().unwrap().max_position_error() < 1e-3);
    }
    assert!(jerk.integrated_squared_jerk() < ridge.integrated_squared_jerk());
}

#[test]
fn an_unreachable_via_point_is_named_with_its_distance() {
    let mut task = ViaPointTask::thesis();
    task.via[2].position = vec![3.0, 0.0, 1.2];
    let err = check_way_points(&task, &thesis_robot()).unwrap_err();
    match &err {
        LearnError::Unreachable {
            point, distance, ..
        } => {
            assert_eq!(point, "via[2]");
            // The Panda reaches ~0.855 m from its shoulder (at 0.5396 + 0, 0.02, 0.749 + 0.333):
            // the point is ~1.6 m beyond that.
            assert!(*distance > 1.4 && *distance < 1.8, "{distance}");
        }
        other => panic!("{other}"),
    }
    assert!(err.to_string().contains("via[2]"), "{err}");
}

#[test]
fn joint_space_learning_reaches_the_points_within_limits() {
    use cps_learn::{JointSpaceConfig, execute_joint_trajectory, learn_joint_space};
    let mut learner = ViaPointConfig::new(ViaPointTask::thesis());
    learner.warm_start = true;
    learner.sigma0 = 0.01;
    learner.population = Some(32);
    learner.generations = 300;
    let c = JointSpaceConfig::new(learner, thesis_robot());
    let out = learn_joint_space(&c, &|_| ControlFlow::Continue(())).unwrap();
    // Task-space errors through forward kinematics, within a millimetre; never worse than
    // the warm start; the IK configurations are the way points, within the limits.
    assert!(out.breakdown.total() <= out.warm_start.total());
    assert_eq!(out.search.generations, 300);
    for (q, p) in out.way_configurations.iter().zip(
        std::iter::once(&c.learner.task.start)
            .chain(c.learner.task.via.iter().map(|v| &v.position))
            .chain(std::iter::once(&c.learner.task.goal)),
    ) {
        let x = c.robot.chain.fk(q).unwrap().translation.vector;
        assert!((x - nalgebra::Vector3::new(p[0], p[1], p[2])).norm() < 1e-6);
        assert!(c.robot.chain.within_limits(q));
    }
    assert!(out.errors.max_position_error() < 1e-3);
    assert!(out.limits.within());
    let mut robot = KinematicRobot::new(c.robot.chain.clone(), &THESIS_Q0, 0.01).unwrap();
    let rec =
        execute_joint_trajectory(&mut robot, &c.robot, &out.trajectory, &StopToken::new()).unwrap();
    assert!(
        rec.max_position_error() < 1e-9,
        "{}",
        rec.max_position_error()
    );
}

/// The plant's closed loop against its analytic response: a critically damped PD loop
/// tracking a constant reference from rest at 1 m below it follows
/// `e(t) = (1 + ω t) e^(−ω t)`.
#[test]
fn the_plant_tracks_a_step_as_the_critically_damped_solution() {
    use cps_learn::{PlantTrajectory, PointMassPlant};
    let plant = PointMassPlant {
        substeps: 100,
        ..PointMassPlant::default()
    };
    let times: Vec<f64> = (0..=200).map(|k| k as f64 * 0.01).collect();
    // The reference: 0 at t = 0 (the plant starts there), then 1 m from the next sample.
    let mut y = vec![1.0; times.len()];
    y[0] = 0.0;
    let zero = vec![0.0; times.len()];
    let traj = cps_dmp::Trajectory::from_parts(times.clone(), &[y], &[zero.to_vec()], &[zero]);
    let mut out = PlantTrajectory::default();
    plant.simulate(&traj, &mut out);
    let omega = (plant.kp / plant.mass).sqrt();
    // The step is ramped over the first sample: compare from 0.2 s on, shifted by half a
    // sample, to 2e-3 of the step.
    for (t, y) in times.iter().zip(&out.position[0]).skip(20) {
        let s = t - 0.005;
        let expected = 1.0 - (1.0 + omega * s) * (-omega * s).exp();
        assert!((y - expected).abs() < 2e-3, "t = {t}: {y} vs {expected}");
    }
}

/// Learning through the plant with the effort term improves on its warm start, gives the
/// same bits on one and on two threads, and the same search whether candidates are
/// simulated or evaluated by the cost's quadratic form; it ends no lower than the exact
/// optimum.
#[test]
fn effort_learning_improves_and_is_the_same_on_any_thread_count() {
    use cps_learn::{EffortConfig, Evaluation, PointMassPlant, learn_with_effort};
    let mut learner = ViaPointConfig::new(ViaPointTask::thesis());
    learner.warm_start = true;
    learner.sigma0 = 0.005;
    learner.population = Some(32);
    learner.generations = 150;
    learner.evaluation = Evaluation::Rollout;
    let c = EffortConfig {
        learner,
        plant: PointMassPlant::default(),
        effort_weight: 1e-2,
    };
    let run = |threads, c: &EffortConfig| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| learn_with_effort(c, &|_| ControlFlow::Continue(())))
            .unwrap()
    };
    let (one, two) = (run(1, &c), run(2, &c));
    assert_eq!(one.weights, two.weights);
    assert_eq!(one.evaluation, Evaluation::Rollout);
    assert!(
        one.breakdown.total() < 0.97 * one.start.total(),
        "{:?} vs {:?}",
        one.breakdown,
        one.start
    );
    assert!(one.breakdown.effort > 0.0);
    // The plant lags behind the DMP: the learned reference leads it.
    assert!(one.errors.max_position_error() < 2e-3, "{:?}", one.errors);
    assert!(one.breakdown.total() >= one.optimum.total());
    // The quadratic form: the same generations, the same cost to rounding.
    let mut q = c.clone();
    q.learner.evaluation = Evaluation::Auto;
    let by_form = run(2, &q);
    assert_eq!(by_form.evaluation, Evaluation::Quadratic);
    assert_eq!(by_form.search.generations, one.search.generations);
    let (a, b) = (one.breakdown.total(), by_form.breakdown.total());
    assert!((a - b).abs() < 1e-9 * a, "{a} vs {b}");
}

/// The effort cost is quadratic in the weights (the plant is linear): the exact solve is
/// its minimum, checked by simulations of the plant: every perturbation costs more, by
/// the quadratic's own amount (its third difference vanishes).
#[test]
fn the_exact_effort_optimum_is_the_minimum_through_the_plant() {
    use cps_learn::{EffortConfig, PointMassPlant, SearchSpace, Solver, learn_with_effort};
    let mut learner = ViaPointConfig::new(ViaPointTask::thesis());
    learner.solver = Solver::Exact;
    let c = EffortConfig {
        learner,
        plant: PointMassPlant::default(),
        effort_weight: 1e-2,
    };
    let exact = learn_with_effort(&c, &|_| ControlFlow::Continue(())).unwrap();
    assert_eq!(exact.search.termination, "exact");
    let best = exact.breakdown.total();
    assert!((best - exact.optimum.total()).abs() < 1e-12 * best);
    // The plain via-point optimum (the DMP alone) is worse through the plant.
    let plain = cps_learn::exact_optimum(
        &c.learner.task,
        &exact.dmp,
        &SearchSpace::new(c.learner.parametrisation, &exact.dmp),
    )
    .unwrap();
    let mut plant = cps_learn::PlantTrajectory::default();
    let cost_of = |w: &[f64], plant: &mut cps_learn::PlantTrajectory| {
        cps_learn::effort_cost(&c, &exact.dmp.rollout(w), plant).total()
    };
    assert!(cost_of(&plain.weights, &mut plant) > 1.01 * best);
    // Perturbed weights, by simulations: higher, and quadratic along a line.
    let n = exact.weights.len();
    for seed in 1..4u64 {
        let d: Vec<f64> = (0..n)
            .map(|i| ((((i as u64 + 7) * 0x9E37_79B9) ^ seed) % 1000) as f64 / 500.0 - 1.0)
            .collect();
        let at = |s: f64, plant: &mut cps_learn::PlantTrajectory| {
            let w: Vec<f64> = exact
                .weights
                .iter()
                .zip(&d)
                .map(|(w, d)| w + s * d)
                .collect();
            cost_of(&w, plant)
        };
        let (c1, c2, c3) = (
            at(1.0, &mut plant),
            at(2.0, &mut plant),
            at(3.0, &mut plant),
        );
        assert!(c1 > best && at(-1.0, &mut plant) > best, "seed {seed}");
        let third = c3 - 3.0 * c2 + 3.0 * c1 - best;
        assert!(
            third.abs() < 1e-9 * c3,
            "third difference {third} of costs up to {c3}"
        );
    }
}

/// Pose learning: the position part is the via-point learner's; the orientation part,
/// from a start about a radian off at the via points, gets within 2° of every target in
/// a short run (the shipped experiment runs longer).
#[test]
fn pose_learning_meets_the_orientation_targets() {
    use cps_learn::{PoseConfig, learn_pose};
    use nalgebra::{Quaternion, UnitQuaternion, Vector3};
    let mut learner = ViaPointConfig::new(ViaPointTask::thesis());
    learner.solver = Solver::Exact;
    learner.population = Some(24);
    learner.generations = 300;
    // The Hand's orientation at the thesis's start, then turned about the world's z axis.
    let start = UnitQuaternion::from_quaternion(Quaternion::new(
        0.0,
        std::f64::consts::FRAC_1_SQRT_2,
        0.0,
        std::f64::consts::FRAC_1_SQRT_2,
    ));
    let yaw =
        |deg: f64| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg.to_radians()) * start;
    let c = PoseConfig {
        learner,
        start_orientation: start,
        goal_orientation: yaw(-45.0),
        via_orientations: vec![Some(yaw(40.0)), None, Some(yaw(-15.0)), Some(yaw(-40.0))],
        orientation_sigma0: 0.3,
        orientation_solver: cps_learn::Solver::Cmaes,
    };
    let out = learn_pose(&c, &|_, _| ControlFlow::Continue(())).unwrap();
    let o = &out.orientation;
    assert_eq!(out.position.best().termination, "exact");
    assert!(
        o.breakdown.total() < 1e-3 * o.start.total(),
        "{:?} vs {:?}",
        o.breakdown,
        o.start
    );
    assert!(o.errors.via[1].is_none());
    assert!(o.errors.max_angle() < 2f64.to_radians(), "{:?}", o.errors);
    // Every sample is a unit quaternion.
    for q in &o.trajectory.orientation {
        assert!((q.coords.norm() - 1.0).abs() < 1e-12);
    }
    // Levenberg–Marquardt on the orientation residuals: converged, far lower than
    // CMA-ES's 300 generations, every target within a hundredth of a degree.
    let lm = PoseConfig {
        orientation_solver: Solver::LeastSquares,
        ..c.clone()
    };
    let out = learn_pose(&lm, &|_, _| ControlFlow::Continue(())).unwrap();
    let l = &out.orientation;
    assert_eq!(l.search.termination, "converged");
    assert!(l.search.generations < 50, "{}", l.search.generations);
    assert!(
        l.breakdown.total() < 0.5 * o.breakdown.total(),
        "LM {} vs CMA-ES {}",
        l.breakdown.total(),
        o.breakdown.total()
    );
    assert!(
        l.errors.max_angle() < 0.01f64.to_radians(),
        "{:?}",
        l.errors
    );
    // The exact solver is refused for the orientation, naming the field.
    let exact = PoseConfig {
        orientation_solver: Solver::Exact,
        ..c
    };
    let err = learn_pose(&exact, &|_, _| ControlFlow::Continue(()))
        .unwrap_err()
        .to_string();
    assert!(err.contains("orientation.method"), "{err}");
}

/// Levenberg–Marquardt in joint space from the surrogate's optimum: every iteration lowers
/// the cost, and 15 of them end lower than 300 CMA-ES generations (the arm's redundancy
/// is a smooth valley), within the limits.
#[test]
fn joint_space_least_squares_beats_cma_es_within_limits() {
    use cps_learn::{JointSpaceConfig, learn_joint_space};
    let mut learner = ViaPointConfig::new(ViaPointTask::thesis());
    learner.warm_start = true;
    learner.sigma0 = 0.002;
    learner.population = Some(32);
    learner.generations = 300;
    let cmaes = JointSpaceConfig::new(learner.clone(), thesis_robot());
    learner.solver = Solver::LeastSquares;
    learner.generations = 15;
    let lm = JointSpaceConfig::new(learner, thesis_robot());
    let run = |c: &JointSpaceConfig| learn_joint_space(c, &|_| ControlFlow::Continue(())).unwrap();
    let (a, b) = (run(&cmaes), run(&lm));
    assert_eq!(b.search.generations, 15);
    assert!(
        b.search.history.windows(2).all(|w| w[1].best < w[0].best)
            && b.search.history[0].best < b.warm_start.total()
    );
    assert!(
        b.breakdown.total() < a.breakdown.total(),
        "LM {} vs CMA-ES {}",
        b.breakdown.total(),
        a.breakdown.total()
    );
    assert!(b.search.evaluations < a.search.evaluations / 2);
    assert!(b.limits.within(), "{:?}", b.limits);
    assert!(b.errors.max_position_error() < 1e-3);
}

/// Around an obstacle: CMA-ES finds the way, the polish (Levenberg–Marquardt from CMA-ES's
/// best) goes to the bottom of that basin: lower than CMA-ES alone, and clear of the
/// obstacle but for a penalty's hair.
#[test]
fn polishing_cma_es_lowers_its_cost_around_an_obstacle() {
    let mut task = ViaPointTask::thesis();
    task.obstacles.push(cps_learn::PointObstacle {
        position: vec![1.18, 0.10, 1.31],
        clearance: 0.08,
    });
    task.weights.obstacle = 1e6;
    let config = ViaPointConfig {
        warm_start: true,
        sigma0: 0.05,
        population: Some(48),
        generations: 100,
        ..ViaPointConfig::new(task)
    };
    let polished = ViaPointConfig {
        polish: true,
        ..config.clone()
    };
    let quiet = |_: usize, _: &cps_cmaes::GenerationReport<'_>| ControlFlow::Continue(());
    let (a, b) = (
        cps_learn::learn_via_points(&config, &quiet).unwrap(),
        cps_learn::learn_via_points(&polished, &quiet).unwrap(),
    );
    let (a, b_run) = (a.best(), b.best());
    assert_eq!(b_run.termination, format!("{}+polished", a.termination));
    assert!(b_run.generations > a.generations);
    assert!(
        b_run.cost < 0.95 * a.cost,
        "polished {} vs CMA-ES {}",
        b_run.cost,
        a.cost
    );
    let d = polished.task.obstacle_distances(&b.best_trajectory())[0];
    assert!(d > 0.0799, "{d}");
    assert!(b_run.errors.max_position_error() < 1e-4);
}
