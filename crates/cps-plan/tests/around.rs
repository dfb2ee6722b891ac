//! The guard's approach goes around (`Guarded::going_around(cps_plan::around)`): where the
//! straight approach to a plan's start would sweep the arm through a post, the guard
//! without a way around refuses it naming the pair, and with one the in-process robot gets
//! there — every configuration it passed keeping the margin.

use std::sync::Arc;

use cps_geometry::{Body, Obstacle, Shape};
use cps_kinematics::robots::{PandaTool, fr3};
use cps_robot::{
    Guarded, KinematicRobot, Plan, Policy, Refusal, Robot, RobotError, RobotModel, Shapes,
    StopToken,
};
use nalgebra::Isometry3;

const LEFT: [f64; 7] = [-1.0, 0.5, 0.0, -1.5, 0.0, 2.0, 0.785];
const RIGHT: [f64; 7] = [1.0, 0.5, 0.0, -1.5, 0.0, 2.0, 0.785];

/// An FR3 of balls on its forearm, wrist and flange, a post 10 cm square and a metre tall
/// 55 cm in front of its base.
fn robot() -> RobotModel {
    let mut model = RobotModel::of_chain("balls", fr3(PandaTool::Flange));
    let bodies = (3..=7)
        .map(|frame| Body {
            link: format!("link{frame}"),
            frame,
            origin: Isometry3::identity(),
            shape: Shape::sphere(0.06, "ball").unwrap(),
        })
        .collect();
    // Balls two joints apart or less overlap where the chain's frames meet.
    let joined = (3..7)
        .flat_map(|k| [1, 2].map(|d| (format!("link{k}"), format!("link{}", (k + d).min(7)))))
        .collect();
    let post = Obstacle {
        name: "post".into(),
        pose: Isometry3::translation(0.55, 0.0, 0.5),
        shape: Shape::cuboid([0.1, 0.1, 1.0], "post").unwrap(),
    };
    let shapes = Shapes::new(bodies, joined)
        .with_obstacles(vec![post], Vec::new())
        .unwrap();
    model.shapes = Some(Arc::new(shapes));
    model
}

#[test]
fn the_guards_approach_goes_around_a_post_the_straight_one_hits() {
    let model = robot();
    // A plan that holds at RIGHT for a second; the robot stands at LEFT.
    let plan = Plan::new(0.01, vec![RIGHT.to_vec(); 101]).unwrap();
    let stop = StopToken::new();
    let at_left = || KinematicRobot::of_model(model.clone(), &LEFT, 0.001).unwrap();
    let mut straight = Guarded::new(at_left(), Policy::EXPERIMENT);
    match straight.run(&plan, &stop) {
        Err(RobotError::Refused {
            reason: Refusal::Collision(c),
            ..
        }) => assert_eq!(c.second, "post", "{c:?}"),
        other => panic!("the straight approach: {other:?}"),
    }
    let mut around = Guarded::new(at_left(), Policy::EXPERIMENT).going_around(cps_plan::around);
    let run = around.run(&plan, &stop).unwrap();
    assert!(run.ending.complete(), "{:?}", run.ending);
    assert!(run.approach_s > 0.0);
    let last = run.q.last().unwrap();
    for (a, b) in last.iter().zip(RIGHT) {
        assert!((a - b).abs() < 1e-9, "{last:?}");
    }
    // Every configuration the robot passed keeps the margin.
    let shapes = model.shapes.as_ref().unwrap();
    let mut frames = Vec::new();
    let mut closest = f64::INFINITY;
    for q in &run.q {
        model.chain.frames_into(q, &mut frames).unwrap();
        for c in shapes.model().within(&frames, 0.1) {
            closest = closest.min(c.separation.distance);
        }
    }
    assert!(closest >= shapes.margin(), "{closest}");
}
