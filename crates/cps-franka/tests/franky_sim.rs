//! cps-franka against a physically simulated FR3 (franky-sim, MuJoCo) behind the real
//! protocol, with the official client pylibfranka as the second opinion. Each test has a
//! loopback address of its own; the simulators run one at a time.

// Joint-indexed arrays (commands, states, limits) are read side by side.
#![allow(clippy::needless_range_loop)]

use cps_testkit::franky_sim as common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use common::{FrankySim, SimOptions};
use cps_franka::limits::{Arm, RateLimits, check_stream, joint_limit};
use cps_franka::{
    Connection, FrankaError, LoopOptions, MotionEnd, Realtime, RobotMode, Start, approach,
    check_trajectory, execute_stream,
};
use cps_kinematics::Quantity;

/// For the runs compared tick by tick with pylibfranka's: no other simulator beside them.
const ALONE: SimOptions = SimOptions {
    table: None,
    friction: None,
    truth: false,
    shelf: None,
    alone: true,
};

fn options() -> LoopOptions {
    LoopOptions {
        realtime: Realtime::Ignore,
        ..LoopOptions::default()
    }
}

#[test]
fn the_state_decodes_as_pylibfranka_decodes_it() {
    let Some(sim) = FrankySim::start("127.0.0.21") else {
        return;
    };
    // pylibfranka first (one client at a time), then cps; the arm rests between the two.
    let theirs: serde_json::Value = serde_json::from_str(&sim.python(
        r#"
import json, os, pylibfranka
s = pylibfranka.Robot(os.environ["HOST"], pylibfranka.RealtimeConfig.kIgnore).read_once()
f = {k: list(getattr(s, k)) for k in ["q", "q_d", "dq", "O_T_EE", "O_T_EE_d", "F_T_EE", "EE_T_K", "F_T_NE", "NE_T_EE",
     "elbow", "elbow_d", "tau_J", "tau_J_d", "theta", "joint_contact", "O_F_ext_hat_K", "I_ee", "F_x_Cee"]}
f["m_ee"] = s.m_ee
f["robot_mode"] = str(s.robot_mode)
f["success"] = s.control_command_success_rate
f["errors"] = str(s.current_errors)
print(json.dumps(f))
"#,
    ))
    .unwrap();
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let s = robot.read_state().unwrap();
    let ours: Vec<(&str, Vec<f64>, f64)> = vec![
        // field, cps's values, tolerance (the arm rests; torques jitter in the PD)
        ("q", s.q.to_vec(), 1e-4),
        ("q_d", s.q_d.to_vec(), 1e-4),
        ("dq", s.dq.to_vec(), 5e-3),
        ("O_T_EE", s.o_t_ee.to_vec(), 1e-4),
        ("O_T_EE_d", s.o_t_ee_d.to_vec(), 1e-4),
        ("F_T_EE", s.f_t_ee.to_vec(), 1e-7),
        ("EE_T_K", s.ee_t_k.to_vec(), 1e-7),
        ("F_T_NE", s.f_t_ne.to_vec(), 1e-7),
        ("NE_T_EE", s.ne_t_ee.to_vec(), 1e-7),
        ("elbow", s.elbow.to_vec(), 1e-4),
        ("elbow_d", s.elbow_d.to_vec(), 1e-4),
        ("tau_J", s.tau_j.to_vec(), 1.0),
        ("tau_J_d", s.tau_j_d.to_vec(), 1.0),
        ("theta", s.theta.to_vec(), 1e-4),
        ("joint_contact", s.joint_contact.to_vec(), 0.0),
        ("O_F_ext_hat_K", s.o_f_ext_hat_k.to_vec(), 0.0),
        ("I_ee", s.i_ee.to_vec(), 1e-7),
        ("F_x_Cee", s.f_x_cee.to_vec(), 1e-7),
        ("m_ee", vec![s.m_ee], 1e-7),
        ("success", vec![s.control_command_success_rate], 0.0),
    ];
    for (name, values, tol) in ours {
        let theirs: Vec<f64> = match &theirs[name] {
            serde_json::Value::Array(a) => a.iter().map(|x| x.as_f64().unwrap()).collect(),
            x => vec![x.as_f64().unwrap()],
        };
        assert_eq!(theirs.len(), values.len(), "{name}");
        for (i, (a, b)) in values.iter().zip(&theirs).enumerate() {
            assert!(
                (a - b).abs() <= tol,
                "{name}[{i}]: cps {a}, pylibfranka {b}"
            );
        }
    }
    // Not all zeros: the decoding found real data (the tool hangs in front of the base).
    assert!(
        s.o_t_ee[12] > 0.3 && s.o_t_ee[14] > 0.3,
        "{:?}",
        s.tool_position()
    );
    assert_eq!(theirs["robot_mode"], "RobotMode.Idle");
    assert_eq!(s.robot_mode, RobotMode::Idle);
    assert!(!s.errors.any());
    assert!(robot.robot_model().unwrap().contains("<robot"));
}

#[test]
fn a_trajectory_is_executed_within_the_limits_and_tracked() {
    let Some(sim) = FrankySim::start("127.0.0.22") else {
        return;
    };
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let limits = RateLimits::of(Arm::Fr3);
    let start = robot.read_state().unwrap();
    let from = cps_franka::rt::start_position(&start);
    let mut goal = from;
    goal[0] += 0.4;
    goal[3] += 0.3;
    goal[6] -= 0.5;
    let trajectory = approach(&limits, from, goal, 0.4);
    let stream = check_trajectory(&limits, from, &trajectory, Start::Refuse).unwrap();
    let stop = AtomicBool::new(false);
    let report = execute_stream(&mut robot, limits, &stream, &options(), &stop).unwrap();
    assert_eq!(
        report.ending,
        MotionEnd::Finished,
        "{}",
        report.ending.sentence()
    );
    // The stream's command of each tick of the robot's clock (a state cps did not answer
    // advances it too), all of the stream, then its last one held until the commanded
    // motion is at rest (at most the three periods a jerk needs).
    let n = stream.commands.len();
    let id0 = report.samples[0].id;
    let ticks = report.samples.last().unwrap().id - id0 + 1;
    assert!(
        (n as u64..=n as u64 + 3).contains(&ticks),
        "{ticks} ticks for {n} commands"
    );
    assert_eq!(report.limited.commands, 0, "{}", report.cycles().sentence());
    for s in &report.samples {
        let k = ((s.id - id0) as usize).min(n - 1);
        assert_eq!(s.q_c, stream.commands[k], "command {k}");
    }
    // What was sent keeps every limit (the robot's own differences, on its clock).
    check_stream(limits, from, &cps_franka::rt::as_held(&report.samples)).unwrap();
    assert!(report.peak_usage.iter().flatten().all(|&u| u <= 1.0));
    // Robot time runs forward in whole milliseconds.
    assert!(report.samples.windows(2).all(|w| w[1].t > w[0].t));
    // The robot took the last command as its desired position (to f32 precision), and the
    // simulated arm followed it: franky-sim's joint PD lags ≈ 10 mrad at the end of this
    // motion and settles slowly, so the measured position is held to 10 mrad after 0.5 s.
    std::thread::sleep(Duration::from_millis(500));
    let end = robot.read_state().unwrap();
    for (i, g) in goal.iter().enumerate() {
        let (q_d, q) = (end.q_d[i], end.q[i]);
        assert!((q_d - g).abs() < 1e-6, "q_d {}: {q_d} vs {g}", i + 1);
        assert!((q - g).abs() < 1e-2, "joint {}: {q} vs {g}", i + 1);
    }
    let moved: f64 = (0..3)
        .map(|k| (end.tool_position()[k] - start.tool_position()[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(moved > 0.05, "the tool moved {moved} m");
    assert!(report.timing.ticks == report.samples.len() && report.timing.median_us > 0.0);
    assert_eq!(end.robot_mode, RobotMode::Idle);
}

#[test]
fn a_step_is_refused_before_anything_is_sent_and_the_robot_stays() {
    let Some(sim) = FrankySim::start("127.0.0.23") else {
        return;
    };
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let limits = RateLimits::of(Arm::Fr3);
    let before = robot.read_state().unwrap();
    let from = cps_franka::rt::start_position(&before);
    let mut trajectory = vec![from; 500];
    for q in &mut trajectory[250..] {
        q[2] += 0.05;
    }
    match check_trajectory(&limits, from, &trajectory, Start::Refuse) {
        Err(FrankaError::Limit(b)) => {
            assert_eq!(
                (b.limit, b.command),
                (joint_limit(3, Quantity::Velocity), 250)
            );
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
    std::thread::sleep(Duration::from_millis(200));
    let after = robot.read_state().unwrap();
    for i in 0..7 {
        assert!((after.q[i] - before.q[i]).abs() < 1e-4);
    }
}

#[test]
fn a_stop_request_brakes_within_the_limits_and_keeps_the_recording() {
    let Some(sim) = FrankySim::start("127.0.0.24") else {
        return;
    };
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let limits = RateLimits::of(Arm::Fr3);
    let from = cps_franka::rt::start_position(&robot.read_state().unwrap());
    let mut goal = from;
    goal[0] += 1.2;
    let stream = check_trajectory(
        &limits,
        from,
        &approach(&limits, from, goal, 0.8),
        Start::Refuse,
    )
    .unwrap();
    let stop = AtomicBool::new(false);
    let report = std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(400));
            stop.store(true, Ordering::Relaxed);
        });
        execute_stream(&mut robot, limits, &stream, &options(), &stop).unwrap()
    });
    assert_eq!(report.ending, MotionEnd::Stopped);
    assert!(report.brake_ticks > 0 && report.samples.len() < stream.commands.len());
    let sent = cps_franka::rt::as_held(&report.samples);
    let check = check_stream(limits, from, &sent).unwrap();
    assert!(check.at_rest_now(), "the last command is at rest");
    // Stopped short of the goal, and the robot is idle again (states already queued when
    // the motion ended may still say "move").
    assert!(sent.last().unwrap()[0] < goal[0] - 0.05);
    assert!(common::eventually(Duration::from_secs(2), || {
        robot.read_state().unwrap().robot_mode == RobotMode::Idle
    }));
}

#[test]
fn a_simulator_killed_mid_motion_ends_as_lost_with_the_recording_kept() {
    let Some(sim) = FrankySim::start("127.0.0.25") else {
        return;
    };
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let limits = RateLimits::of(Arm::Fr3);
    let from = cps_franka::rt::start_position(&robot.read_state().unwrap());
    let mut goal = from;
    goal[1] += 0.6;
    let stream = check_trajectory(
        &limits,
        from,
        &approach(&limits, from, goal, 0.1),
        Start::Refuse,
    )
    .unwrap();
    let stop = AtomicBool::new(false);
    let report = std::thread::scope(|s| {
        let kill = sim.killer();
        let killer = s.spawn(move || {
            std::thread::sleep(Duration::from_millis(700));
            kill();
        });
        let r = execute_stream(&mut robot, limits, &stream, &options(), &stop).unwrap();
        killer.join().unwrap();
        r
    });
    match &report.ending {
        MotionEnd::Lost(reason) => assert!(reason.contains("127.0.0.25"), "{reason}"),
        other => panic!("expected a lost connection, got {other:?}"),
    }
    assert!(
        report.samples.len() > 100,
        "{} samples kept",
        report.samples.len()
    );
    assert!(report.samples.len() < stream.commands.len());
}

/// The commands of a 4 s swing of joints 1, 4 and 6 from `from` and back, one per ms.
fn swing(from: [f64; 7]) -> Vec<[f64; 7]> {
    (0..=4000)
        .map(|k| {
            let s = 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / 4000.0).cos();
            let mut q = from;
            q[0] += 0.5 * s;
            q[3] += 0.4 * s;
            q[5] -= 0.3 * s;
            q
        })
        .collect()
}

#[test]
fn the_same_stream_from_cps_and_from_pylibfranka_moves_the_arm_alike() {
    // pylibfranka's loop on one simulator ...
    let theirs: serde_json::Value = {
        let Some(sim) = FrankySim::start_with("127.0.0.26", ALONE) else {
            return;
        };
        serde_json::from_str(&sim.python(
            r#"
import json, math, os, time, pylibfranka as p
robot = p.Robot(os.environ["HOST"], p.RealtimeConfig.kIgnore)
q0 = list(robot.read_once().q_d)
ctl = robot.start_joint_position_control(p.ControllerMode.JointImpedance)
rec, lat = [], []
for k in range(4001):
    state, _ = ctl.readOnce()
    t0 = time.perf_counter()
    s = 0.5 - 0.5 * math.cos(2 * math.pi * k / 4000)
    q = list(q0)
    q[0] += 0.5 * s; q[3] += 0.4 * s; q[5] -= 0.3 * s
    cmd = p.JointPositions(q)
    if k == 4000:
        cmd.motion_finished = True
    ctl.writeOnce(cmd)
    lat.append(time.perf_counter() - t0)
    rec.append(list(state.q))
lat.sort()
print(json.dumps({"q": rec, "median_us": lat[len(lat) // 2] * 1e6, "p99_us": lat[int(len(lat) * 0.99)] * 1e6}))
"#,
        ))
        .unwrap()
    };
    // ... and cps's on another, started alike.
    let Some(sim) = FrankySim::start_with("127.0.0.27", ALONE) else {
        return;
    };
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let limits = RateLimits::of(Arm::Fr3);
    let from = cps_franka::rt::start_position(&robot.read_state().unwrap());
    let stream = check_trajectory(&limits, from, &swing(from), Start::Refuse).unwrap();
    let stop = AtomicBool::new(false);
    let ours = execute_stream(&mut robot, limits, &stream, &options(), &stop).unwrap();
    assert_eq!(ours.ending, MotionEnd::Finished);
    let theirs_q: Vec<Vec<f64>> = serde_json::from_value(theirs["q"].clone()).unwrap();
    // Tick by tick, the measured joints agree to the simulator's own spread (commands that
    // reach it a tick late are re-applied, so the two runs differ by a tick here and there).
    let mut worst: f64 = 0.0;
    for (s, q) in ours.samples.iter().zip(&theirs_q) {
        for (a, b) in s.q.iter().zip(q) {
            worst = worst.max((a - b).abs());
        }
    }
    eprintln!(
        "cps vs pylibfranka: largest joint difference {worst:.2e} rad over 4 s; loop p99 cps {:.1} us, pylibfranka {:.1} us",
        ours.timing.p99_us,
        theirs["p99_us"].as_f64().unwrap()
    );
    assert!(worst < 5e-3, "the two runs differ by {worst} rad");
    // And both moved: joint 1 half-way is 0.5 rad out.
    assert!((ours.samples[2000].q[0] - from[0] - 0.5).abs() < 0.05);
    assert!((theirs_q[2000][0] - from[0] - 0.5).abs() < 0.05);
}

#[test]
fn the_gripper_homes_moves_and_grasps() {
    use cps_franka::{Gripper, GripperCommand};
    let Some(sim) = FrankySim::start("127.0.0.28") else {
        return;
    };
    let mut hand = Gripper::connect(&sim.host, Duration::from_secs(3)).unwrap();
    assert!(hand.run(GripperCommand::Homing).unwrap());
    // franky-sim calls a finger motion done once the width changes by less than 10 um per
    // simulation step for 100 steps, so the fingers may stop a few millimetres short of
    // their goal (78.4 mm of 80 seen under load): the widths are checked to 5 mm, which
    // still tells every commanded width here from the others.
    let s = hand.state(Duration::from_secs(1)).unwrap();
    assert!(
        s.max_width > 0.075 && s.max_width <= 0.0805,
        "homing measured {s:?}"
    );
    assert!(
        hand.run(GripperCommand::Move {
            width: 0.03,
            speed: 0.05
        })
        .unwrap()
    );
    let s = hand.state(Duration::from_secs(1)).unwrap();
    assert!((s.width - 0.03).abs() < 5e-3, "{s:?}");
    let grasp = GripperCommand::Grasp {
        width: 0.01,
        epsilon_inner: 0.005,
        epsilon_outer: 0.005,
        speed: 0.05,
        force: 20.0,
    };
    // franky-sim's fingers close on nothing to about the commanded width, which it calls
    // held: a grasp holds when the fingers stop within the tolerances (here 5 mm).
    assert!(hand.run(grasp).unwrap());
    let w = hand.state(Duration::from_secs(1)).unwrap().width;
    assert!((w - 0.01).abs() <= 0.005, "width {w} after the grasp");
    // Out of range: refused before anything is sent.
    let e = hand
        .run(GripperCommand::Move {
            width: 0.5,
            speed: 0.05,
        })
        .unwrap_err();
    assert!(e.to_string().contains("width 0.5 m is not in [0,"), "{e}");
}

#[test]
fn the_robots_own_urdf_agrees_with_the_fr3_model_cps_plans_on() {
    use cps_kinematics::robots::{PandaTool, fr3};
    use rand::SeedableRng;
    let Some(sim) = FrankySim::start("127.0.0.29") else {
        return;
    };
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let xml = robot.robot_model().unwrap();
    // Read by cps's URDF loader, up to the flange (link8): seven joints with inertias.
    let urdf = cps_kinematics::chain_from_urdf(&xml, Some("link8")).unwrap();
    assert_eq!(urdf.chain.dof(), 7);
    let inertia = urdf
        .inertia
        .expect("the FR3's URDF carries <inertial> elements");
    assert!(
        inertia.iter().all(|l| l.mass > 0.1 && l.mass < 10.0),
        "{inertia:?}"
    );
    assert_eq!(
        urdf.effort.unwrap(),
        vec![87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]
    );
    // The same kinematics as cps's FR3 (the published modified-DH table) everywhere.
    let ours = fr3(PandaTool::Flange);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200 {
        let q = ours.random_configuration(&mut rng);
        let (a, b) = (ours.fk(&q).unwrap(), urdf.chain.fk(&q).unwrap());
        let dp = (a.translation.vector - b.translation.vector).norm();
        let dr = (a.rotation.matrix() - b.rotation.matrix()).norm();
        assert!(dp < 1e-9 && dr < 1e-9, "at {q:?}: {dp} m, {dr} rad");
    }
    // cps plans within Franka's published FR3 ranges, which lie inside the robot's own
    // (its URDF allows e.g. joint 1 to ±2.9007 where the datasheet says ±2.7437).
    let (lo_u, hi_u) = urdf.chain.limits().unwrap();
    let (lo, hi) = ours.limits().unwrap();
    for j in 0..7 {
        assert!(
            lo_u[j] <= lo[j] && hi[j] <= hi_u[j],
            "joint {}: [{}, {}] not inside [{}, {}]",
            j + 1,
            lo[j],
            hi[j],
            lo_u[j],
            hi_u[j]
        );
    }
    assert_eq!(
        urdf.chain.velocity_limits().unwrap(),
        ours.velocity_limits().unwrap()
    );
}

/// The velocities of a 3 s rest-to-rest swing: joints 1 and 4 move 0.3 and −0.2 rad.
fn swing_velocities(k: usize) -> [f64; 7] {
    let s = 1.0 - (std::f64::consts::TAU * k as f64 / 3000.0).cos();
    let mut dq = [0.0; 7];
    dq[0] = 0.1 * s; // ∫ over 3 s = 0.3 rad
    dq[3] = -0.2 / 3.0 * s;
    dq
}

#[test]
fn joint_velocities_move_the_arm_as_pylibfranka_does() {
    // pylibfranka's joint velocity loop on one simulator ...
    let theirs: Vec<Vec<f64>> = {
        let Some(sim) = FrankySim::start_with("127.0.0.71", ALONE) else {
            return;
        };
        let out = sim.python(
            r#"
import json, math, os, pylibfranka as p
robot = p.Robot(os.environ["HOST"], p.RealtimeConfig.kIgnore)
ctl = robot.start_joint_velocity_control(p.ControllerMode.JointImpedance)
rec = []
for k in range(3001):
    state, _ = ctl.readOnce()
    s = 1.0 - math.cos(2 * math.pi * k / 3000)
    cmd = p.JointVelocities([0.1 * s, 0, 0, -0.2 / 3 * s, 0, 0, 0])
    if k == 3000:
        cmd.motion_finished = True
    ctl.writeOnce(cmd)
    rec.append(list(state.q))
print(json.dumps(rec))
"#,
        );
        serde_json::from_str(&out).unwrap()
    };
    // ... and cps's on another, the same velocities per answered tick.
    let Some(sim) = FrankySim::start_with("127.0.0.72", ALONE) else {
        return;
    };
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let limits = RateLimits::of(Arm::Fr3);
    let from = cps_franka::rt::start_position(&robot.read_state().unwrap());
    let stop = AtomicBool::new(false);
    let mut k = 0;
    let report = cps_franka::run_joint_velocities(&mut robot, limits, &options(), &stop, |_, _| {
        let v = cps_franka::JointVelocities {
            dq: swing_velocities(k),
            finished: k >= 3000,
        };
        k += 1;
        v
    })
    .unwrap();
    assert_eq!(
        report.ending,
        MotionEnd::Finished,
        "{}",
        report.ending.sentence()
    );
    // What was sent (as the positions it integrates to) keeps every limit, and ends
    // 0.3 rad and -0.2 rad out on joints 1 and 4.
    let sent = cps_franka::rt::as_held(&report.samples);
    check_stream(limits, from, &sent).unwrap();
    let last = sent.last().unwrap();
    assert!((last[0] - from[0] - 0.3).abs() < 1e-3, "{last:?}");
    assert!((last[3] - from[3] + 0.2).abs() < 1e-3, "{last:?}");
    // Tick by tick, the arm moved as under pylibfranka.
    let mut worst: f64 = 0.0;
    for (s, q) in report.samples.iter().zip(&theirs) {
        for (a, b) in s.q.iter().zip(q) {
            worst = worst.max((a - b).abs());
        }
    }
    eprintln!("joint velocities, cps vs pylibfranka: largest joint difference {worst:.2e} rad");
    assert!(worst < 5e-3, "the two runs differ by {worst} rad");
    assert!((report.samples[1500].q[0] - from[0] - 0.15).abs() < 0.03);
}

/// A joint impedance law computed by cps at 1 kHz (the robot adds gravity): the arm
/// follows a swing of joint 1, every torque sent within the torque and torque-rate limits.
#[test]
fn torques_from_cps_move_the_arm_and_stay_within_the_torque_limits() {
    let Some(sim) = FrankySim::start("127.0.0.73") else {
        return;
    };
    let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
    let limits = RateLimits::of(Arm::Fr3);
    let q0 = robot.read_state().unwrap().q;
    let stiffness = [600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0];
    let damping = [50.0, 50.0, 50.0, 50.0, 20.0, 20.0, 10.0];
    let target = |t: f64| {
        let s = if t < 3.0 {
            0.5 - 0.5 * (std::f64::consts::PI * t / 3.0).cos()
        } else {
            1.0
        };
        let mut q = q0;
        q[0] += 0.3 * s;
        q
    };
    let stop = AtomicBool::new(false);
    let report = cps_franka::run_torques(&mut robot, limits, &options(), &stop, |state, t| {
        let q_d = target(t);
        let mut tau = [0.0; 7];
        for i in 0..7 {
            tau[i] = stiffness[i] * (q_d[i] - state.q[i]) - damping[i] * state.dq[i];
        }
        cps_franka::Torques {
            tau,
            finished: t >= 4.0,
        }
    })
    .unwrap();
    assert_eq!(
        report.ending,
        MotionEnd::Finished,
        "{}",
        report.ending.sentence()
    );
    let mut last = [0.0; 7];
    for s in &report.samples {
        for i in 0..7 {
            assert!(s.tau_c[i].abs() <= limits.tau_max[i] + 1e-9);
            assert!((s.tau_c[i] - last[i]).abs() <= limits.dtau_max[i] * 1e-3 + 1e-9);
        }
        last = s.tau_c;
    }
    let end = report.samples.last().unwrap();
    assert!(
        (end.q[0] - q0[0] - 0.3).abs() < 0.03,
        "joint 1 ended at {:?}",
        end.q[0] - q0[0]
    );
    for i in 1..7 {
        assert!(
            (end.q[i] - q0[i]).abs() < 0.03,
            "joint {} drifted {}",
            i + 1,
            end.q[i] - q0[i]
        );
    }
    eprintln!(
        "torque control: joint 1 at {:.4} rad of 0.3, {} commands limited, peak torque use {:.0} %",
        end.q[0] - q0[0],
        report.limited.commands,
        report.peak_usage[0].iter().fold(0.0f64, |a, &b| a.max(b)) * 100.0
    );

    // A step of 5 N m on joint 7 is sent as a ramp of 0.95 N m per tick (95 % of the rate
    // limit, from the torques the robot reports applied), each limited command counted.
    let report = cps_franka::run_torques(&mut robot, limits, &options(), &stop, |state, t| {
        let mut tau = [0.0; 7];
        for i in 0..7 {
            tau[i] = -damping[i] * state.dq[i];
        }
        if t < 0.05 {
            tau[6] += 5.0;
        }
        cps_franka::Torques {
            tau,
            finished: t >= 0.3,
        }
    })
    .unwrap();
    assert_eq!(
        report.ending,
        MotionEnd::Finished,
        "{}",
        report.ending.sentence()
    );
    let ramp: Vec<f64> = report.samples.iter().take(6).map(|s| s.tau_c[6]).collect();
    assert!(
        report.limited.commands >= 4,
        "{} limited, ramp {ramp:?}",
        report.limited.commands
    );
    // Each step at most 0.95 N m from the torques the robot reported applied, which
    // franky-sim, on a loaded machine, sometimes reports a tick late (the ramp then waits
    // that tick, from the torques it reported before: within a millinewton metre of those
    // sent, its torques at rest before the ramp included).
    assert!((ramp[0] - 0.95).abs() < 0.05, "{ramp:?}");
    assert!(
        ramp[..4]
            .windows(2)
            .all(|w| (-1e-3..=0.95 + 1e-4).contains(&(w[1] - w[0]))),
        "{ramp:?}"
    );
    assert!(ramp[3] > 2.8, "{ramp:?}");

    // A controller that answers NaN: never sent; the arm is damped to rest and the motion
    // ends naming the joint.
    let report = cps_franka::run_torques(&mut robot, limits, &options(), &stop, |state, t| {
        let mut tau = [0.0; 7];
        tau[2] = if t > 0.5 {
            f64::NAN
        } else {
            -2.0 * state.dq[2]
        };
        cps_franka::Torques {
            tau,
            finished: false,
        }
    })
    .unwrap();
    match &report.ending {
        MotionEnd::LimitBrake(b) => {
            assert_eq!(
                (b.limit, b.value.is_nan()),
                (joint_limit(3, Quantity::Torque), true),
                "{b}"
            )
        }
        other => panic!("{}", other.sentence()),
    }
    assert!(
        report
            .samples
            .iter()
            .all(|s| s.tau_c.iter().all(|x| x.is_finite()))
    );
    let end = report.samples.last().unwrap();
    assert!(end.dq.iter().all(|v| v.abs() < 0.05), "{:?}", end.dq);
}
