//! Torque control on franky-sim's MuJoCo FR3 behind the real protocol: the robot's
//! dynamic model against pinocchio's (the simulator's own), joint impedance, and the arm
//! guided by a simulated hand with MuJoCo's hand position as the truth. (Pressing on a
//! table, with MuJoCo's contact force as the truth, is `cps-experiment`'s contact task:
//! `crates/cps-experiment/tests/contact.rs`.)
//!
//! Loopback addresses: 127.0.0.75, .79, .80.
#![allow(clippy::needless_range_loop)]

use cps_testkit::franky_sim as common;

use std::sync::atomic::AtomicBool;

use common::{FrankySim, SimOptions, Truth};
use cps_franka::control::{JointImpedance, robot_dynamics};
use cps_franka::guide::{Guiding, run_guiding};
use cps_franka::limits::{Arm, RateLimits};
use cps_franka::{Connection, LoopOptions, Realtime, Torques, run_torques};

fn options() -> LoopOptions {
    LoopOptions {
        realtime: Realtime::Ignore,
        ..Default::default()
    }
}

/// A connection to `sim`, its current state and the robot's own dynamic model.
fn connected(
    sim: &FrankySim,
) -> (
    Connection,
    cps_franka::RobotState,
    cps_kinematics::ArmModel<7>,
) {
    let mut conn = Connection::connect(&sim.host, Default::default()).unwrap();
    let (state, _) = conn
        .newest_state(std::time::Duration::from_secs(2))
        .unwrap();
    let model = robot_dynamics(&mut conn, &state).unwrap();
    (conn, state, model)
}

#[test]
fn the_robot_s_model_agrees_with_pinocchio_s() {
    let Some(sim) = FrankySim::start("127.0.0.75") else {
        return;
    };
    let (_conn, _, model) = connected(&sim);
    // franky-sim adds gravity with pinocchio on its URDF plus the hand's inertia: the same
    // model read independently.
    let configurations = [
        cps_kinematics::robots::PANDA_READY,
        [0.5, 0.3, -0.4, -1.8, 0.7, 2.2, -0.3],
        [-1.2, -0.9, 1.1, -0.9, -1.5, 0.9, 1.9],
    ];
    let reference = sim.python(&format!(
        r#"
import numpy as np, pinocchio as pin
from franky_sim.mujoco_simulator import FrankaMujocoRobot
r = FrankaMujocoRobot()
m = r._BaseRobot__model
d = m.createData()
for q in {configurations:?}:
    q = np.array(q)
    g = pin.computeGeneralizedGravity(m, d, q)
    M = pin.crba(m, d, q); M = np.triu(M) + np.triu(M, 1).T
    print(" ".join(f"{{x:.12e}}" for x in list(g) + list(M.flatten())))
"#
    ));
    for (q, line) in configurations.iter().zip(reference.lines()) {
        let v: Vec<f64> = line.split(' ').map(|x| x.parse().unwrap()).collect();
        let f = model.frames(q);
        let g = model.gravity(&f);
        let m = model.mass_matrix(&f);
        for i in 0..7 {
            assert!(
                (g[i] - v[i]).abs() < 1e-6,
                "gravity joint {}: {} vs {}",
                i + 1,
                g[i],
                v[i]
            );
            for j in 0..7 {
                assert!((m[(i, j)] - v[7 + 7 * i + j]).abs() < 1e-6, "M[{i},{j}]");
            }
        }
    }
}

#[test]
fn joint_impedance_settles_on_its_target() {
    let Some(sim) = FrankySim::start("127.0.0.79") else {
        return;
    };
    let (mut conn, state, model) = connected(&sim);
    let law = JointImpedance::new(
        [600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0],
        [50.0, 50.0, 50.0, 20.0, 20.0, 20.0, 10.0],
    )
    .unwrap();
    let mut goal = state.q;
    goal[0] += 0.2;
    goal[3] -= 0.2;
    let stop = AtomicBool::new(false);
    let report = run_torques(
        &mut conn,
        RateLimits::of(Arm::Fr3),
        &options(),
        &stop,
        |s, t| {
            let frames = model.frames(&s.q);
            // The goal approached along a 1 s min-jerk, then held for 1.5 s.
            let x = (t / 1.0).clamp(0.0, 1.0);
            let share = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x);
            let mut q_d = state.q;
            for i in 0..7 {
                q_d[i] += (goal[i] - state.q[i]) * share;
            }
            Torques {
                tau: law.torques(&model, &frames, s, &q_d, &[0.0; 7]),
                finished: t > 2.5,
            }
        },
    )
    .unwrap();
    assert!(report.ending.complete(), "{}", report.ending.sentence());
    let last = report.samples.last().unwrap();
    // Within the joints' friction over the stiffness (1.137 N m / 600 N m/rad ≈ 2 mrad)
    // and the hand's fingers the model does not carry.
    for i in 0..7 {
        assert!(
            (last.q[i] - goal[i]).abs() < 0.005,
            "joint {}: {} vs {}",
            i + 1,
            last.q[i],
            goal[i]
        );
    }
    assert_eq!(report.limited.commands, 0);
}

#[test]
fn a_hand_guides_the_floating_arm_and_the_recording_follows_it() {
    let Some(sim) = FrankySim::start_with(
        "127.0.0.80",
        SimOptions {
            truth: true,
            ..Default::default()
        },
    ) else {
        return;
    };
    let mut conn = Connection::connect(&sim.host, Default::default()).unwrap();
    let start = conn
        .newest_state(std::time::Duration::from_secs(2))
        .unwrap()
        .0
        .tool_position();
    let goal = [0.45, 0.15, 0.45];
    let guiding = Guiding {
        duration: 4.0,
        ..Default::default()
    };
    let stop = AtomicBool::new(false);
    // A hand pulls the tool centre point along a straight line for 2 s, 0.5 s after the
    // arm starts floating: a spring of 400 N/m to an anchor moving to `goal`.
    let report = std::thread::scope(|scope| {
        scope.spawn(|| {
            std::thread::sleep(std::time::Duration::from_millis(500));
            sim.send(&format!(
                "lead {} {} {} 2.0 400 20",
                goal[0], goal[1], goal[2]
            ));
        });
        run_guiding(
            &mut conn,
            RateLimits::of(Arm::Fr3),
            &options(),
            &stop,
            &guiding,
        )
        .unwrap()
    });
    sim.send("release");
    assert!(report.ending.complete(), "{}", report.ending.sentence());
    assert!((report.samples.last().unwrap().t - 4.0).abs() < 0.01);
    let truth = sim.truth();
    let by_id: std::collections::HashMap<u64, &Truth> = truth.iter().map(|t| (t.id, t)).collect();
    // The recording (the robot's O_T_EE) is where MuJoCo had the hand.
    let mut worst: f64 = 0.0;
    let mut matched = 0;
    for s in &report.samples {
        if let Some(t) = by_id.get(&s.id) {
            let d = (0..3)
                .map(|k| (s.tool[k] - t.tcp[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            worst = worst.max(d);
            matched += 1;
        }
    }
    assert!(matched > 3500, "{matched} samples matched MuJoCo's steps");
    // The recording and MuJoCo's hand are one step apart at most (state after the step).
    assert!(
        worst < 1e-3,
        "the recording is {:.2} mm from MuJoCo's hand",
        worst * 1e3
    );
    // The arm went where the hand pulled it, along the line.
    let end = report.samples.last().unwrap().tool;
    let gap = (0..3)
        .map(|k| (end[k] - goal[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    let line: Vec<f64> = (0..3).map(|k| goal[k] - start[k]).collect();
    let length = line.iter().map(|x| x * x).sum::<f64>().sqrt();
    let off_line = report
        .samples
        .iter()
        .map(|s| {
            let r: Vec<f64> = (0..3).map(|k| s.tool[k] - start[k]).collect();
            let along = (0..3).map(|k| r[k] * line[k]).sum::<f64>() / length;
            ((0..3).map(|k| r[k] * r[k]).sum::<f64>() - along * along)
                .max(0.0)
                .sqrt()
        })
        .fold(0.0, f64::max);
    eprintln!(
        "guided {:.0} mm: ended {:.1} mm from the goal, at most {:.1} mm off the line; recording vs MuJoCo {:.2} mm",
        length * 1e3,
        gap * 1e3,
        off_line * 1e3,
        worst * 1e3
    );
    assert!(
        gap < 0.01,
        "ended {:.1} mm from where the hand pulled it",
        gap * 1e3
    );
    assert!(off_line < 0.012, "{:.1} mm off the line", off_line * 1e3);
    assert_eq!(report.limited.commands, 0);
}
