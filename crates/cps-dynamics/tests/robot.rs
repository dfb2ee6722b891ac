//! The dynamics robot against what control theory says its controllers do, and as a cps
//! robot: determinism, stopping, the stepped and streaming interfaces.

use cps_dynamics::{Arm, Controller, DynamicsRobot, DynamicsSettings, Integrator};
use cps_kinematics::ArmModel;
use cps_kinematics::contact::JointFriction;
use cps_kinematics::robots::{PandaTool, panda, panda_inertia};
use cps_robot::{Ending, Plan, Robot, RobotModel, StopToken};

const START: [f64; 7] = cps_kinematics::robots::PANDA_READY;

fn robot(controller: Controller<7>, noise: f64, seed: u64) -> DynamicsRobot<7> {
    robot_with(controller, noise, seed, Integrator::SemiImplicitEuler, true)
}

/// The Panda (Gaz et al.'s inertias) with franky-sim's rotor inertia, no friction.
fn robot_with(
    controller: Controller<7>,
    noise: f64,
    seed: u64,
    integrator: Integrator,
    reflexes: bool,
) -> DynamicsRobot<7> {
    let chain = panda(PandaTool::HandTcp);
    let dynamics = ArmModel::<7>::new(&chain, &panda_inertia())
        .unwrap()
        .with_armature([0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074])
        .unwrap();
    let mut arm = Arm::at_rest(
        dynamics,
        JointFriction::none(),
        [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0],
        START,
    );
    arm.integrator = integrator;
    DynamicsRobot::new(
        RobotModel::of_chain("panda", chain),
        arm,
        DynamicsSettings {
            controller,
            control_period: 0.001,
            dt: 0.01,
            noise,
            seed,
            reflexes,
            lag: 0,
        },
    )
    .unwrap()
}

/// `seconds` of joint `j` following `f(t)` (added to the start), every 10 ms.
fn plan(seconds: f64, j: usize, f: impl Fn(f64) -> f64) -> Plan {
    let n = (seconds / 0.01).round() as usize;
    Plan::new(
        0.01,
        (0..=n)
            .map(|k| {
                let mut q = START.to_vec();
                q[j] += f(k as f64 * 0.01);
                q
            })
            .collect(),
    )
    .unwrap()
}

#[test]
fn franky_sim_s_pd_lags_a_steady_motion_by_kv_over_kp() {
    // Joint 1 speeds up to 0.3 rad/s within a few tenths of a second and keeps it: with
    // Coriolis and gravity compensated and no feed-forward, kp·e = kv·q̇ once the
    // acceleration is gone, so the joint trails its target by kv/kp = 0.1 s.
    let speed = 0.3;
    let tau = 0.2;
    let p = plan(3.0, 0, |t| speed * (t - tau * (t / tau).tanh()));
    let mut r = robot(Controller::franky_sim(), 0.0, 0);
    let run = r.run(&p, &StopToken::new()).unwrap();
    assert_eq!(run.ending, Ending::Finished);
    assert_eq!(run.q.len(), 301);
    for k in [120, 150, 180] {
        let target = p.points()[k][0];
        let lag = (target - run.q[k][0]) / speed;
        assert!(
            (lag - 0.1).abs() < 0.002,
            "at {} s: lag {lag} s",
            k as f64 * 0.01
        );
    }
    assert!(r.report().unwrap().contains("3000 control periods"));
}

#[test]
fn computed_torque_follows_the_plan_while_the_model_is_the_robot() {
    // The arm is the controller's model: the error starts at zero and stays there
    // (ë + kv ė + kp e = 0), up to integration error.
    let p = plan(2.0, 3, |t| {
        0.4 * (std::f64::consts::PI * t / 2.0).sin().powi(2)
    });
    let ct = Controller::ComputedTorque {
        kp: [400.0; 7],
        kv: [40.0; 7],
    };
    let run = robot(ct, 0.0, 0).run(&p, &StopToken::new()).unwrap();
    let worst = run
        .q
        .iter()
        .zip(p.points())
        .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
        .fold(0.0, f64::max);
    assert!(worst < 1e-4, "{worst} rad");
    // franky-sim's PD on the same plan is far behind.
    let pd = robot(Controller::franky_sim(), 0.0, 0)
        .run(&p, &StopToken::new())
        .unwrap();
    let pd_worst =
        pd.q.iter()
            .zip(p.points())
            .map(|(a, b)| (a[3] - b[3]).abs())
            .fold(0.0, f64::max);
    assert!(pd_worst > 100.0 * worst, "{pd_worst} vs {worst}");
}

#[test]
fn the_same_seed_gives_the_same_run_and_noise_is_felt() {
    let p = plan(1.0, 1, |t| 0.1 * t * t);
    let go = |noise, seed| {
        robot(Controller::franky_sim(), noise, seed)
            .run(&p, &StopToken::new())
            .unwrap()
            .q
    };
    let quiet = go(0.0, 0);
    assert_eq!(go(1e-4, 7), go(1e-4, 7));
    assert_ne!(go(1e-4, 7), go(1e-4, 8));
    let noisy = go(1e-4, 7);
    let off = noisy
        .iter()
        .zip(&quiet)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
        .fold(0.0, f64::max);
    // A stiff controller turns 0.1 mrad of reading noise into motion of about as much.
    assert!(off > 1e-6 && off < 1e-3, "{off}");
    // A robot that ran once runs the same plan the same way again from the same start.
    let mut r = robot(Controller::franky_sim(), 1e-4, 7);
    let first = r.run(&p, &StopToken::new()).unwrap().q;
    assert!(r.teleport(&START).unwrap());
    assert_eq!(r.run(&p, &StopToken::new()).unwrap().q, first);
}

#[test]
fn a_stop_brings_the_arm_to_rest_and_keeps_what_was_recorded() {
    let p = plan(2.0, 0, |t| 0.5 * t);
    let stop = StopToken::new();
    stop.stop();
    let mut r = robot(Controller::franky_sim(), 0.0, 0);
    let run = r.run(&p, &stop).unwrap();
    assert_eq!(run.ending, Ending::Stopped);
    // The start, once: a stop before moving records no second entry at the same time.
    assert_eq!(run.q.len(), 1);
    assert!(r.arm().dq.iter().all(|v| v.abs() <= 1e-3));
}

#[test]
fn a_joint_leaving_its_range_stops_the_arm_as_a_reflex_does() {
    // Joint 4 driven 3 rad up in 2 s: its range ends at −0.0698 rad, 2.29 rad away.
    let p = plan(2.0, 3, |t| 1.5 * t);
    let mut r = robot(Controller::franky_sim(), 0.0, 0);
    let run = r.run(&p, &StopToken::new()).unwrap();
    let Ending::Failed(why) = &run.ending else {
        panic!("{:?}", run.ending)
    };
    assert!(
        why.contains("reflex: joint 4") && why.contains("beyond its range"),
        "{why}"
    );
    // What was recorded before is kept; the arm has braked just past the limit (its
    // wrist keeps chattering at franky-sim's gains, < 0.1 rad/s, see docs/robots.md).
    assert!(run.q.len() > 150 && run.q.len() < 201, "{}", run.q.len());
    let hi = panda(PandaTool::HandTcp).limits().unwrap().1[3];
    let q4 = r.arm().q[3];
    assert!(
        q4 > hi + cps_dynamics::REFLEX_MARGIN && q4 < hi + 0.05,
        "{q4}"
    );
    let dq = r.arm().dq;
    assert!(dq[..4].iter().all(|v| v.abs() <= 0.02), "{dq:?}");
    assert!(dq.iter().all(|v| v.abs() <= 0.1), "{dq:?}");
    // Where it came to rest is recorded after the braking, never at a time already held.
    let increasing = |t: &[f64]| t.windows(2).all(|w| w[1] > w[0]);
    assert!(
        increasing(&run.time),
        "{:?}",
        &run.time[run.time.len() - 3..]
    );
    // The same when streamed: the reflex's entry comes after the braking.
    let mut r = robot(Controller::franky_sim(), 0.0, 0);
    let streamed = r
        .streaming()
        .unwrap()
        .stream(
            &mut |_q, t, cmd| {
                cmd.copy_from_slice(&START);
                cmd[3] = START[3] + 1.5 * t;
                t >= 2.0
            },
            3000,
            &StopToken::new(),
        )
        .unwrap();
    assert!(
        matches!(streamed.ending, Ending::Failed(_)),
        "{:?}",
        streamed.ending
    );
    assert!(
        increasing(&streamed.time),
        "{:?}",
        &streamed.time[streamed.time.len() - 3..]
    );
    // Nor can the arm be put where a real one cannot be (the thesis's Panda start has
    // joint 4 at 0 rad, beyond its range).
    let mut outside = START;
    outside[3] = 0.0;
    let e = robot(Controller::franky_sim(), 0.0, 0)
        .teleport(&outside)
        .unwrap_err()
        .to_string();
    assert!(e.contains("joint 4 at 0.0000 rad, beyond its range"), "{e}");
    // Without reflexes the same plan runs to its end.
    let mut free = robot_with(
        Controller::franky_sim(),
        0.0,
        0,
        Integrator::SemiImplicitEuler,
        false,
    );
    let run = free.run(&p, &StopToken::new()).unwrap();
    assert_eq!(run.ending, Ending::Finished);
    assert_eq!(run.q.len(), 201);
}

#[test]
fn the_stepped_and_streaming_interfaces_move_the_arm_where_commanded() {
    let mut r = robot(Controller::franky_sim(), 0.0, 0);
    let stepped = r.stepped().unwrap();
    let mut target = START.to_vec();
    for k in 1..=100 {
        target[4] = START[4] + 0.002 * k as f64;
        stepped.command_joint_positions(&target).unwrap();
        stepped.step().unwrap();
    }
    for _ in 0..50 {
        stepped.step().unwrap();
    }
    let q = stepped.joint_positions().unwrap();
    assert!((q[4] - (START[4] + 0.2)).abs() < 1e-3, "{}", q[4]);
    assert!((stepped.time().unwrap() - 1.5).abs() < 1e-9);
    let streaming = r.streaming().unwrap();
    let goal = START[4];
    let run = streaming
        .stream(
            &mut |_q, t, cmd| {
                cmd.copy_from_slice(&START);
                cmd[4] = goal + 0.2 * (1.0 - (t / 0.5).min(1.0));
                t >= 1.0
            },
            5000,
            &StopToken::new(),
        )
        .unwrap();
    assert_eq!(run.ending, Ending::Finished);
    assert!((run.q.last().unwrap()[4] - goal).abs() < 1e-3);
    assert!(
        robot(Controller::franky_sim(), 0.0, 0)
            .stepped()
            .unwrap()
            .command_joint_positions(&[0.0; 6])
            .unwrap_err()
            .to_string()
            .contains("6 joint positions commanded, the arm has 7")
    );
}

#[test]
fn rk4_and_euler_agree_on_a_controlled_motion() {
    let p = plan(1.0, 1, |t| 0.2 * (std::f64::consts::PI * t).sin().powi(2));
    let go = |integrator| {
        robot_with(Controller::franky_sim(), 0.0, 0, integrator, true)
            .run(&p, &StopToken::new())
            .unwrap()
            .q
    };
    let (euler, rk4) = (go(Integrator::SemiImplicitEuler), go(Integrator::Rk4));
    let gap = euler
        .iter()
        .zip(&rk4)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
        .fold(0.0, f64::max);
    // franky-sim's stiff PD is close to explicit Euler's stability edge at 1 ms on the
    // light wrist joints (kv·h/I ≈ 2), where Euler's error is millirads — as it is in
    // MuJoCo, which steps franky-sim's PD the same way. RK4 is the accurate one.
    assert!(gap > 1e-5 && gap < 5e-3, "{gap}");
}
