//! `FrankaRobot` — the arm as a robot of cps's execution contract — against franky-sim (a
//! MuJoCo FR3 behind the real protocol): the robot's own URDF and end effector checked
//! against the scene's model at opening, a planned sequence streamed and recorded point by
//! point, a sequence too sharp for the arm slowed by the guard. (Moved here from
//! cps-experiment's `FrankaBackend` tests with the code.)

use cps_testkit::franky_sim as common;

use common::FrankySim;
use cps_franka::limits::Arm;
use cps_franka::{FrankaRobot, FrankaSettings, Realtime};
use cps_kinematics::robots::{PandaTool, fr3, fr3_limits};
use cps_robot::{Guarded, Plan, Policy, Robot, RobotModel, StopToken};
use nalgebra::Isometry3;

/// The FR3 with the Franka Hand placed as `configs/scenes/fr3.toml` places it.
fn scene_model(tool: PandaTool) -> RobotModel {
    let chain = fr3(tool).with_base(Isometry3::translation(0.42244, 0.02, 0.74177));
    let mut model = RobotModel::of_chain("fr3", chain);
    model.limits = fr3_limits();
    model
}

#[test]
fn the_robot_checks_the_model_and_records_every_planned_point() {
    let Some(sim) = FrankySim::start("127.0.0.74") else {
        return;
    };
    let settings = FrankaSettings {
        host: sim.host.clone(),
        arm: Arm::Fr3,
        realtime: Realtime::Ignore,
        dt: 0.01,
    };
    let stop = StopToken::new();
    // The scene's FR3 with the hand is the simulator's arm: its URDF agrees to far less
    // than a millimetre (the same published kinematics), its end effector to 5 mm.
    let robot = FrankaRobot::open(&settings, scene_model(PandaTool::HandTcp)).unwrap();
    let gap = robot.model_gap().unwrap();
    assert!(gap < 1e-6, "{gap}");
    // A model whose tool is the flange, not the hand the robot reports: named.
    drop(robot);
    let e = FrankaRobot::open(&settings, scene_model(PandaTool::Flange))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the scene's tool is not the end effector"),
        "{e}"
    );
    // A planned sequence: 0.5 s moving joint 7 by 0.2 rad from where the arm stands,
    // planned every 10 ms; recorded point by point at the points' times.
    let robot = FrankaRobot::open(&settings, scene_model(PandaTool::HandTcp)).unwrap();
    let mut robot = Guarded::new(robot, Policy::EXPERIMENT);
    let q0 = robot.joint_positions().unwrap();
    robot.move_to(&q0, &stop).unwrap();
    let rows: Vec<Vec<f64>> = (0..=50)
        .map(|k| {
            let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 50.0).cos();
            let mut q = q0.clone();
            q[6] += 0.2 * s;
            q
        })
        .collect();
    let rec = robot.run(&Plan::new(0.01, rows).unwrap(), &stop).unwrap();
    assert_eq!(rec.q.len(), 51);
    // Point k is at k·dt from the plan's start (its first point the robot's start).
    assert!((rec.time[50] - 0.50).abs() < 1e-9, "{}", rec.time[50]);
    // The measured joint 7 follows, 100 ms late (franky-sim's PD), and the tool poses are
    // the scene model's at the measured joints.
    let moved = rec.q[50][6] - q0[6];
    assert!(moved > 0.1 && moved < 0.21, "joint 7 moved {moved}");
    let fk = scene_model(PandaTool::HandTcp)
        .chain
        .fk(&rec.q[30])
        .unwrap();
    assert!((fk.translation.vector - rec.tool[30].translation.vector).norm() < 1e-12);
    let reports = robot.inner().reports();
    let last = reports.last().unwrap();
    assert!(last.ending.complete(), "{}", last.ending.sentence());
    assert!(
        last.peak_usage.iter().flatten().all(|&u| u <= 1.0),
        "{:?}",
        last.peak_usage
    );
    assert_eq!(
        robot.slowest(),
        1.0,
        "a gentle sequence runs at its planned timing"
    );
    // A sequence too sharp for the arm at its planned timing (joint 7 by 0.2 rad in 0.1 s,
    // 99 rad/s² at its peak, ten times the FR3's limit): slowed as far as the limits
    // need, nothing sent beyond them.
    let q1 = rec.q[50].clone();
    robot.move_to(&q1, &stop).unwrap();
    let sharp: Vec<Vec<f64>> = (0..=10)
        .map(|k| {
            let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 10.0).cos();
            let mut q = q1.clone();
            q[6] -= 0.2 * s;
            q
        })
        .collect();
    let rec = robot.run(&Plan::new(0.01, sharp).unwrap(), &stop).unwrap();
    assert!(robot.slowest() > 1.5, "slowed {}x", robot.slowest());
    let last = robot.inner().reports().last().unwrap();
    assert!(last.ending.complete(), "{}", last.ending.sentence());
    assert!(
        last.peak_usage.iter().flatten().all(|&u| u <= 1.0),
        "{:?}",
        last.peak_usage
    );
    let planned = 0.11;
    let took = rec.time[10] - rec.time[0] + 0.01 * robot.slowest();
    assert!(took > 1.5 * planned, "{took} s");
    // Stepping one command at a time is not how a Franka is driven: it offers no stepped
    // interface at all.
    assert!(robot.stepped().is_none());
}
