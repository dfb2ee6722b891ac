//! `FrankaBackend` against franky-sim (a MuJoCo FR3 behind the real protocol): the robot's
//! own URDF and end effector checked against the scene's model at opening, a planned
//! sequence streamed and recorded row by row.

#[path = "../../cps-franka/tests/common/mod.rs"]
mod sim;

use cps_experiment::franka_backend::{FrankaBackend, FrankaSettings};
use cps_experiment::scene::{FR3_SCENE, parse_scene};
use cps_franka::Realtime;
use cps_franka::limits::Arm;
use cps_kinematics::RobotBackend;
use cps_kinematics::robots::{PandaTool, fr3};
use sim::FrankySim;

#[test]
fn the_backend_checks_the_model_and_records_every_planned_row() {
    let Some(sim) = FrankySim::start("127.0.0.74") else {
        return;
    };
    let scene = parse_scene(std::path::Path::new("fr3.toml"), FR3_SCENE).unwrap();
    let settings = FrankaSettings {
        host: sim.host.clone(),
        arm: Arm::Fr3,
        realtime: Realtime::Ignore,
        dt: 0.01,
    };
    // The scene's FR3 with the hand is the simulator's arm: its URDF agrees to far less
    // than a millimetre (the same published kinematics), its end effector to 5 mm.
    let robot = FrankaBackend::open(&settings, &scene.robot.chain).unwrap();
    assert!(robot.model_gap() < 1e-6, "{}", robot.model_gap());
    // A model whose tool is the flange, not the hand the robot reports: named.
    let flange = fr3(PandaTool::Flange);
    drop(robot);
    let e = FrankaBackend::open(&settings, &flange).unwrap_err();
    assert!(
        e.contains("the scene's tool is not the end effector"),
        "{e}"
    );
    // A planned sequence: 0.5 s moving joint 7 by 0.2 rad from where the arm stands,
    // planned every 10 ms; recorded row by row, the clock one period per row.
    let mut robot = FrankaBackend::open(&settings, &scene.robot.chain).unwrap();
    let q0 = robot.joint_positions().unwrap();
    robot.reset(&q0).unwrap();
    let rows: Vec<Vec<f64>> = (0..=50)
        .map(|k| {
            let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 50.0).cos();
            let mut q = q0.clone();
            q[6] += 0.2 * s;
            q
        })
        .collect();
    let rec = robot.run_joint_targets(&rows).unwrap();
    assert_eq!(rec.q.len(), 51);
    assert!((rec.time[50] - 0.51).abs() < 1e-9, "{}", rec.time[50]);
    // The measured joint 7 follows, 100 ms late (franky-sim's PD), and the tool poses are
    // the scene model's at the measured joints.
    let moved = rec.q[50][6] - q0[6];
    assert!(moved > 0.1 && moved < 0.21, "joint 7 moved {moved}");
    let fk = scene.robot.chain.fk(&rec.q[30]).unwrap();
    assert!((fk.translation.vector - rec.tool[30].translation.vector).norm() < 1e-12);
    let reports = robot.reports();
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
    robot.reset(&q1).unwrap();
    let sharp: Vec<Vec<f64>> = (0..=10)
        .map(|k| {
            let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 10.0).cos();
            let mut q = q1.clone();
            q[6] -= 0.2 * s;
            q
        })
        .collect();
    let rec = robot.run_joint_targets(&sharp).unwrap();
    assert!(robot.slowest() > 1.5, "slowed {}x", robot.slowest());
    let last = robot.reports().last().unwrap();
    assert!(last.ending.complete(), "{}", last.ending.sentence());
    assert!(
        last.peak_usage.iter().flatten().all(|&u| u <= 1.0),
        "{:?}",
        last.peak_usage
    );
    let planned = 0.11;
    let took = rec.time[10] - rec.time[0] + 0.01 * robot.slowest();
    assert!(took > 1.5 * planned, "{took} s");
    // Stepping one command at a time is not how a Franka is driven: named.
    let e = robot.step().unwrap_err().to_string();
    assert!(e.contains("streams whole planned sequences"), "{e}");
}
