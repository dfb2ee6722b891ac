//! The guard's collision check against an analytic reference: a ball carried by the
//! Panda's first link at 0.5 m from its axis swings towards a ball standing in the world at
//! the same height and radius, so their distance at joint 1's angle `φ` is `2 R sin(|φ −
//! φ₀| / 2) − r₁ − r₂`. The plan is refused at the first millisecond where that is below
//! the margin — not before, not after — with the two names and the distance; commands sent
//! one at a time are refused at the same place; a streamed movement is braked there; a
//! simulator is not put inside the ball.

use std::sync::Arc;

use cps_geometry::{Body, Obstacle, Shape};
use cps_kinematics::robots::{PandaTool, panda};
use cps_robot::{
    Guarded, KinematicRobot, Plan, Policy, Refusal, Robot, RobotError, RobotModel, Shapes,
    StopToken,
};
use nalgebra::{Isometry3, Vector3};

const REACH: f64 = 0.5;
const GOAL_ANGLE: f64 = 1.0;
const BALL: f64 = 0.05;
const MARGIN: f64 = 0.01;

/// The Panda with one ball on link 1 and one in the world, `GOAL_ANGLE` round from it.
fn model() -> RobotModel {
    let chain = panda(PandaTool::HandTcp);
    let mut model = RobotModel::of_chain("panda", chain.clone());
    // Link 1's frame at q = 0 is the base's turned by nothing, at height 0.333 m; joint 1
    // turns it about the base's z.
    let mut frames = Vec::new();
    chain.frames_into(&[0.0; 7], &mut frames).unwrap();
    let link1 = frames[1];
    let at = |angle: f64| Vector3::new(REACH * angle.cos(), REACH * angle.sin(), 0.333);
    let body = Body {
        link: "panda_link1".into(),
        frame: 1,
        origin: Isometry3::from_parts(
            (link1.inverse() * nalgebra::Point3::from(at(0.0))).into(),
            nalgebra::UnitQuaternion::identity(),
        ),
        shape: Shape::sphere(BALL, "a ball").unwrap(),
    };
    let obstacle = Obstacle {
        name: "ball".into(),
        pose: Isometry3::translation(at(GOAL_ANGLE).x, at(GOAL_ANGLE).y, at(GOAL_ANGLE).z),
        shape: Shape::sphere(BALL, "the ball").unwrap(),
    };
    let shapes = Shapes::new(vec![body], vec![])
        .with_obstacles(vec![obstacle], vec![])
        .unwrap()
        .with_margin(MARGIN)
        .unwrap();
    model.shapes = Some(Arc::new(shapes));
    model
}

/// The two balls' distance with joint 1 at `phi`.
fn analytic(phi: f64) -> f64 {
    2.0 * REACH * ((phi - GOAL_ANGLE).abs() / 2.0).sin() - 2.0 * BALL
}

/// Joint 1 from 0 to `to` in `seconds`, a point every millisecond (cosine profile).
fn swing(to: f64, seconds: f64) -> Plan {
    let n = (seconds * 1000.0).round() as usize;
    let points = (0..=n)
        .map(|k| {
            let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / n as f64).cos();
            let mut q = vec![0.0; 7];
            q[0] = to * s;
            q
        })
        .collect();
    Plan::new(1e-3, points).unwrap()
}

/// The plan's first point within the margin, analytically.
fn first_within(plan: &Plan) -> usize {
    plan.points()
        .iter()
        .position(|q| analytic(q[0]) < MARGIN)
        .unwrap()
}

fn robot() -> Guarded<KinematicRobot> {
    let r = KinematicRobot::of_model(model(), &[0.0; 7], 1e-3).unwrap();
    Guarded::new(r, Policy::EXPERIMENT)
}

#[test]
fn a_plan_into_an_obstacle_is_refused_at_the_first_millisecond_within_the_margin() {
    let plan = swing(1.5, 3.0);
    let first = first_within(&plan);
    let mut r = robot();
    let e = r.run(&plan, &StopToken::new()).unwrap_err();
    let RobotError::Refused {
        reason: Refusal::Collision(c),
        ..
    } = e
    else {
        panic!("not a collision: {e}");
    };
    assert_eq!(
        (c.first.as_str(), c.second.as_str()),
        ("panda_link1", "ball")
    );
    assert_eq!(c.command, first, "{c}");
    assert!((c.time - first as f64 * 1e-3).abs() < 1e-9, "{c}");
    assert!(
        (c.distance - analytic(plan.points()[first][0])).abs() < 1e-7,
        "{c}"
    );
    assert_eq!(
        c.to_string(),
        format!(
            "`panda_link1` and `ball` at t = {:.3} s (command {first}) come {:.1} mm apart, within the clearance margin of 10.0 mm",
            c.time,
            1e3 * c.distance
        )
    );
    // Nothing moved, nothing recorded.
    assert_eq!(r.joint_positions().unwrap(), vec![0.0; 7]);
    // Stopping short of the margin is run to its end.
    let stop_short = (1..1000)
        .map(|k| k as f64 * 1e-3)
        .take_while(|&phi| analytic(phi) > MARGIN + 1e-4)
        .last()
        .unwrap();
    let run = r.run(&swing(stop_short, 3.0), &StopToken::new()).unwrap();
    assert!(run.ending.complete());
    // A plan that goes through the ball says how deep it would be, whatever slowing.
    let e = robot()
        .run(&swing(2.0, 0.5), &StopToken::new())
        .unwrap_err();
    assert!(e.to_string().contains("`panda_link1` and `ball`"), "{e}");
}

#[test]
fn commands_sent_one_at_a_time_are_refused_where_the_plan_would_be() {
    let plan = swing(1.5, 3.0);
    let first = first_within(&plan);
    let mut r = robot();
    let stepped = r.stepped().unwrap();
    for (k, q) in plan.points().iter().enumerate().skip(1) {
        match stepped.command_joint_positions(q) {
            Ok(()) => stepped.step().unwrap(),
            Err(e) => {
                assert_eq!(k, first, "{e}");
                let said = e.to_string();
                assert!(
                    said.contains("a command breaks a limit, so it was not sent")
                        && said.contains(&format!(
                            "`panda_link1` and `ball` at t = {:.3} s (command {first})",
                            first as f64 * 1e-3
                        )),
                    "{said}"
                );
                // The robot holds the last command sent.
                let q = r.joint_positions().unwrap();
                assert!((q[0] - plan.points()[first - 1][0]).abs() < 1e-12);
                return;
            }
        }
    }
    panic!("no command was refused");
}

#[test]
fn a_streamed_movement_is_braked_where_it_comes_within_the_margin() {
    let plan = swing(1.5, 3.0);
    let mut r = robot();
    // The nominal plan stops short; the commands made online run on past it.
    let nominal = swing(0.2, 3.0);
    let points = plan.points().to_vec();
    let mut next = |_: &cps_robot::Measured<'_>, t: f64, out: &mut [f64]| {
        let k = ((t * 1000.0).round() as usize + 1).min(points.len() - 1);
        out.copy_from_slice(&points[k]);
        k == points.len() - 1
    };
    let run = r
        .stream(&nominal, &mut next, 10_000, &StopToken::new())
        .unwrap();
    let cps_robot::Ending::Failed(why) = &run.ending else {
        panic!("{:?}", run.ending);
    };
    assert!(
        why.starts_with("a command came within the clearance margin, so the robot braked: `panda_link1` and `ball`"),
        "{why}"
    );
    // It ended before the balls met: the last configuration recorded keeps them apart.
    let last = run.q.last().unwrap()[0];
    assert!(analytic(last) > 0.0, "{last}");
    assert!(analytic(last) < MARGIN + 0.01, "{last}");
}

#[test]
fn a_simulator_is_not_put_inside_an_obstacle() {
    let mut r = robot();
    let e = r
        .teleport(&[GOAL_ANGLE, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        .unwrap_err();
    assert!(
        e.to_string()
            .contains("`panda_link1` and `ball` at t = 0.000 s (command 0) collide: 100.0 mm deep"),
        "{e}"
    );
    assert_eq!(r.joint_positions().unwrap(), vec![0.0; 7]);
    assert!(r.teleport(&[0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap());
}

#[test]
fn a_scene_s_obstacles_moved_into_the_base_frame_collide_where_they_did_in_the_world() {
    // The robot placed in a world (turned and shifted), the ball placed with it: the
    // same collision as unplaced. Then the world's ball moved into the base's frame
    // (`Shapes::moved`, as a Franka's commands are checked) for the unplaced robot: the
    // same again, at the same millisecond, the same distance.
    let plain = model();
    let plan = swing(1.2, 1.2);
    let base = Isometry3::new(Vector3::new(0.3, -0.2, 0.74), Vector3::new(0.0, 0.0, 0.5));
    let shapes = plain.shapes.clone().unwrap();
    let ball = &shapes.obstacles()[0];
    let in_world = shapes
        .with_obstacles(
            vec![Obstacle {
                pose: base * ball.pose,
                ..ball.clone()
            }],
            vec![],
        )
        .unwrap();
    let placed = plain.chain.clone().with_base(base);
    let reference = cps_robot::check_shapes(&shapes, &plain.chain, &plan, 1e-3)
        .unwrap()
        .expect("the swing reaches the ball");
    let in_world = Arc::new(in_world);
    let world = cps_robot::check_shapes(&in_world, &placed, &plan, 1e-3)
        .unwrap()
        .unwrap();
    let moved = Arc::new(in_world.moved(&base.inverse()));
    let in_base = cps_robot::check_shapes(&moved, &plain.chain, &plan, 1e-3)
        .unwrap()
        .unwrap();
    for c in [&world, &in_base] {
        assert_eq!(c.command, reference.command);
        assert_eq!((&c.first, &c.second), (&reference.first, &reference.second));
        assert!((c.distance - reference.distance).abs() < 1e-9, "{c:?}");
    }
    assert_eq!(reference.command, first_within(&plan));
}
