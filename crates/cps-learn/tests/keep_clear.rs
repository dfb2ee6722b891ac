//! Keeping a task-space movement clear on the model ([`cps_learn::keep_clear`]): the
//! thesis task's learned movement, executed by the Panda's inverse controller, brings a
//! ball on the flange 2 cm into a ball standing beside its path. Judged by the analytic
//! distance between the two balls, `‖p_flange(q) − c‖ − 2 r`, at every executed sample:
//! below zero before, at least the clearance (less what the 40 ms between judged samples
//! can hide) after, the movement still near the one learned, and the same bits twice.

use std::sync::Arc;

use cps_geometry::{Body, Obstacle, Shape};
use cps_kinematics::robots::{PandaTool, panda};
use cps_learn::{
    Clearance, KeepClear, RobotSetup, Solver, ViaPointConfig, ViaPointTask, keep_clear,
    learn_via_points, targets_at,
};
use cps_robot::{ExecutionConfig, Shapes};
use nalgebra::{Isometry3, Vector3};

const R: f64 = 0.05;
const CLEAR: f64 = 0.02;
const DT: f64 = 0.01;

#[test]
fn a_movement_into_a_ball_is_bent_around_it_on_the_model() {
    let robot = RobotSetup {
        chain: panda(PandaTool::HandTcp).with_base(Isometry3::translation(0.5396, 0.02, 0.749)),
        initial_q: cps_kinematics::robots::PANDA_THESIS_START.to_vec(),
        execution: ExecutionConfig::default(),
    };
    let task = ViaPointTask::thesis();
    let mut config = ViaPointConfig::new(task.clone());
    config.solver = Solver::Exact;
    let learned = learn_via_points(&config, &|_, _| std::ops::ControlFlow::Continue(())).unwrap();
    let dmp = task.build_dmp().unwrap();
    let w0 = learned.best().weights.clone();
    let targets = |w: &[f64]| targets_at(&dmp.rollout(w), DT).1;
    let flange = |q: &[f64]| {
        let mut f = Vec::new();
        robot.chain.frames_into(q, &mut f).unwrap();
        f[7].translation.vector
    };
    // The ball: beside the flange where it is at t = 3 s, 8 cm off sideways (horizontal,
    // across the path): the two 5 cm balls overlap by 2 cm.
    let before = cps_learn::execute_on_model(&robot, DT, &targets(&w0)).unwrap();
    let (p, next) = (flange(&before.q[300]), flange(&before.q[301]));
    let across = (next - p).cross(&Vector3::z()).normalize();
    let centre = p + 0.08 * across;
    let gap = |q: &[f64]| (flange(q) - centre).norm() - 2.0 * R;
    let shapes = Shapes::new(
        vec![Body {
            link: "flange".into(),
            frame: 7,
            origin: Isometry3::identity(),
            shape: Shape::sphere(R, "flange ball").unwrap(),
        }],
        vec![],
    )
    .with_obstacles(
        vec![Obstacle {
            name: "ball".into(),
            pose: Isometry3::translation(centre.x, centre.y, centre.z),
            shape: Shape::sphere(R, "ball").unwrap(),
        }],
        vec![],
    )
    .unwrap();
    let clearance = Clearance {
        shapes: Arc::new(shapes),
        distance: CLEAR,
        weight: 1e6,
        stride: cps_learn::CLEARANCE_STRIDE,
    };
    let worst =
        |rec: &cps_robot::Recording| rec.q.iter().map(|q| gap(q)).fold(f64::INFINITY, f64::min);
    assert!(worst(&before) < -0.019, "{}", worst(&before));

    // The anchor: how far the tool path strays from the learned one, 1e2 per m² of mean
    // squared distance.
    let y0 = dmp.rollout(&w0);
    let n = y0.n_samples();
    let anchor = |w: &[f64], out: &mut Vec<f64>| {
        let y = dmp.rollout(w);
        let s = (1e2 / n as f64).sqrt();
        for k in 0..n {
            for d in 0..3 {
                out.push(s * (y.position(d)[k] - y0.position(d)[k]));
            }
        }
    };
    let keep = KeepClear {
        clearance: &clearance,
        robot: &robot,
        dt: DT,
        iterations: 50,
    };
    let started = std::time::Instant::now();
    let kept = keep_clear(&keep, w0.clone(), &anchor, &targets, &|_| {
        std::ops::ControlFlow::Continue(())
    })
    .unwrap();
    eprintln!(
        "kept clear in {:.2} s, {} iterations, {} evaluations ({}): clearance cost {:?}, anchor {:?}, worst {:.2} → {:.2} mm",
        started.elapsed().as_secs_f64(),
        kept.search.generations,
        kept.search.evaluations,
        kept.search.termination,
        kept.clearance,
        kept.anchor,
        worst(&before) * 1e3,
        worst(&kept.executed) * 1e3
    );
    assert!(
        worst(&kept.executed) > CLEAR - 2e-3,
        "{}",
        worst(&kept.executed)
    );
    let judged = (0..kept.executed.q.len()).step_by(cps_learn::CLEARANCE_STRIDE);
    let at_judged = judged
        .map(|k| gap(&kept.executed.q[k]))
        .fold(f64::INFINITY, f64::min);
    assert!(at_judged > CLEAR - 2e-4, "{at_judged}");
    // Bent where the ball is: the path stays within 6 cm of the learned one (the ball
    // asked for 4), and within a millimetre over the last second, far from it.
    let y = dmp.rollout(&kept.theta);
    let off = |k: usize| {
        (0..3)
            .map(|d| (y.position(d)[k] - y0.position(d)[k]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    assert!((0..n).map(off).fold(0.0, f64::max) < 0.06);
    assert!((n - 100..n).map(off).fold(0.0, f64::max) < 1e-3);
    let c = kept.closest[1].as_ref().unwrap();
    assert_eq!((c.first.as_str(), c.second.as_str()), ("flange", "ball"));
    assert!((c.distance - worst(&kept.executed)).abs() < 2e-3);
    // Deterministic.
    let again = keep_clear(&keep, w0.clone(), &anchor, &targets, &|_| {
        std::ops::ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(again.theta, kept.theta);
    // A movement that keeps clear is left as it is: the ball a metre higher.
    let far = Clearance {
        shapes: Arc::new(
            Shapes::new(clearance.shapes.bodies().to_vec(), vec![])
                .with_obstacles(
                    vec![Obstacle {
                        name: "ball".into(),
                        pose: Isometry3::translation(centre.x, centre.y, centre.z + 1.0),
                        shape: Shape::sphere(R, "ball").unwrap(),
                    }],
                    vec![],
                )
                .unwrap(),
        ),
        ..clearance.clone()
    };
    let left = keep_clear(
        &KeepClear {
            clearance: &far,
            ..keep
        },
        w0.clone(),
        &anchor,
        &targets,
        &|_| std::ops::ControlFlow::Continue(()),
    )
    .unwrap();
    assert_eq!(
        (left.theta, left.search.termination.as_str()),
        (w0, "clear")
    );
}
