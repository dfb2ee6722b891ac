//! One plan, every robot: the same refused, stopped-before-moving, slowed, approached,
//! stopped-mid-plan and failed-mid-plan plans run through the guard on each robot cps
//! drives — the in-process robot, CoppeliaSim's stand-in server (through cps's scene
//! script), a Franka (franky-sim: MuJoCo behind the real protocol), a ROS 2 controller (a
//! CycloneDDS FollowJointTrajectory server) and the robot with dynamics (computed torque
//! on the FR3's inertias) — and what each says, sends and records is compared: the same
//! refusal in the same words, the same slowing, the same approach, the same plan sent, a
//! stop or a failure mid-plan ending the run with its recording kept.
//!
//! The whole test runs in a network namespace of its own (DDS discovery never leaves it);
//! franky-sim listens on 127.0.0.91 inside it. A second test streams one motion to every
//! robot that streams while it loses control periods (the in-process robots told to, the
//! Franka's link dropping commands): each survives them as a Franka must.

use cps_testkit::franky_sim as sim;
use cps_testkit::ros2_graph as graph;

use std::time::Duration;

use cps_coppelia::{Client, ClientConfig, FrankaScene, SceneSetup, ServerConfig, StandInServer};
use cps_dynamics::{Arm as DynamicArm, Controller, DynamicsRobot, DynamicsSettings};
use cps_franka::limits::Arm;
use cps_franka::{FrankaRobot, FrankaSettings, Realtime};
use cps_kinematics::ArmModel;
use cps_kinematics::contact::JointFriction;
use cps_kinematics::robots::{PandaTool, fr3, fr3_inertia, fr3_limits};
use cps_movement::collision::FrankaArm;
use cps_robot::{
    Guarded, KinematicRobot, Plan, Policy, Refusal, Robot, RobotError, RobotModel, StopToken,
};
use cps_ros2::robot::{Ros2Robot, Ros2Settings};

/// The FR3 with its hand, in its base frame, with the arm's own limits and shapes, and a
/// post standing beside it: 0.3 m from the base's axis, 0.9 rad clockwise of the arm at
/// rest (every case below but the collision's stays clear of it).
fn model() -> RobotModel {
    let mut m = RobotModel::of_chain("fr3", fr3(PandaTool::HandTcp));
    m.limits = fr3_limits();
    let shapes = cps_movement::collision::franka_geometry(FrankaArm::Fr3, true).shapes();
    let (angle, radius) = (-0.9f64, 0.3);
    let post = cps_geometry::Obstacle {
        name: "post".into(),
        pose: nalgebra::Isometry3::translation(radius * angle.cos(), radius * angle.sin(), 0.5),
        shape: cps_geometry::Shape::cylinder(0.04, 0.6, "the post").unwrap(),
    };
    let shapes = shapes.with_obstacles(vec![post], vec![]).unwrap();
    m.shapes = Some(std::sync::Arc::new(shapes));
    m
}

/// The Franka at `host` (franky-sim), its loop at whatever priority it may have.
fn franka_at(host: &str) -> FrankaRobot {
    let settings = FrankaSettings {
        host: host.to_string(),
        arm: Arm::Fr3,
        realtime: Realtime::Ignore,
        dt: 0.001,
    };
    FrankaRobot::connect(&settings, model()).unwrap()
}

/// The FR3 with its inertias under computed torque, at rest at `at` (the model is the
/// robot: it tracks).
fn dynamics_at(at: [f64; 7]) -> Result<DynamicsRobot<7>, RobotError> {
    DynamicsRobot::new(
        model(),
        DynamicArm::at_rest(
            ArmModel::<7>::new(&model().chain, &fr3_inertia()).unwrap(),
            JointFriction::none(),
            [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0],
            at,
        ),
        DynamicsSettings {
            controller: Controller::ComputedTorque {
                kp: [900.0; 7],
                kv: [60.0; 7],
            },
            control_period: 0.001,
            dt: 0.001,
            noise: 0.0,
            seed: 0,
            reflexes: true,
            lag: 0,
        },
    )
}

/// Joint `j` swings by `amplitude` and back to rest in `seconds` from `q0`, every 10 ms.
fn swing(q0: &[f64], j: usize, amplitude: f64, seconds: f64) -> Plan {
    swing_every(q0, j, amplitude, seconds, 0.01)
}

/// [`swing`] with its points every `dt`.
fn swing_every(q0: &[f64], j: usize, amplitude: f64, seconds: f64, dt: f64) -> Plan {
    let n = (seconds / dt).round() as usize;
    let points = (0..=n)
        .map(|k| {
            let s = 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / n as f64).cos();
            let mut q = q0.to_vec();
            q[j] += amplitude * s;
            q
        })
        .collect();
    Plan::new(dt, points).unwrap()
}

/// A 0.05 rad step of joint 2 at 0.5 s, commanded every millisecond.
fn step(q0: &[f64]) -> Plan {
    let points = (0..=1000)
        .map(|k| {
            let mut q = q0.to_vec();
            if k >= 500 {
                q[1] += 0.05;
            }
            q
        })
        .collect();
    Plan::new(1e-3, points).unwrap()
}

/// Waits until a robot holding `token` says it moves (at most 30 s).
fn once_moving(token: &StopToken) {
    let begun = std::time::Instant::now();
    while !token.is_moving() && begun.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_micros(100));
    }
}

/// Runs `plan` on `r` through a strict guard, doing `then` `after` the robot starts
/// moving (stopping the run, killing its far end).
fn run_and_then(
    r: &mut dyn Robot,
    plan: &Plan,
    after: Duration,
    then: impl FnOnce(&StopToken) + Send,
) -> Result<cps_robot::Run, RobotError> {
    let token = StopToken::new();
    std::thread::scope(|s| {
        let watcher = token.clone();
        s.spawn(move || {
            once_moving(&watcher);
            std::thread::sleep(after);
            then(&watcher);
        });
        Guarded::new(r, Policy::STRICT).run(plan, &token)
    })
}

/// What ends a robot's far end (its server, its simulator).
type Kill = Box<dyn FnOnce() + Send>;

/// Every robot still stands within 1 mrad of `q0`.
fn all_still(robots: &mut [(&str, &mut dyn Robot)], q0: &[f64]) {
    for (name, r) in robots {
        let q = r.joint_positions().unwrap();
        let moved = q
            .iter()
            .zip(q0)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(moved < 1e-3, "{name} moved {moved} rad");
    }
}

fn reason(e: RobotError) -> Refusal {
    match e {
        RobotError::Refused { reason, .. } => reason,
        other => panic!("not a refusal: {other}"),
    }
}

#[test]
fn the_same_plan_is_judged_and_sent_the_same_on_every_robot() {
    if !graph::inside("the_same_plan_is_judged_and_sent_the_same_on_every_robot") {
        return;
    }
    let Some(franky) = sim::FrankySim::start("127.0.0.91") else {
        return;
    };
    let stop = StopToken::new();
    let mut franka = franka_at(&franky.host);
    // Every robot starts where the simulated arm holds.
    let q0 = franka.joint_positions().unwrap();
    let start = q0
        .iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(",");
    let names: Vec<String> = (1..=7).map(|i| format!("fr3_joint{i}")).collect();
    let seen = graph::temp("server.json");
    let peer = graph::Peer::start(&[
        "serve",
        "/fr3_arm_controller/follow_joint_trajectory",
        seen.to_str().unwrap(),
        "--joint-states",
        "/joint_states",
        "--rate",
        "250",
        "--joints",
        &names.join(","),
        "--start",
        &start,
        "--linger",
        "15",
    ]);
    let ros = Ros2Robot::open(
        &Ros2Settings {
            controller: "/fr3_arm_controller".into(),
            joint_states: "/joint_states".into(),
            domain: None,
            service_mapping: Default::default(),
            dt: 0.001,
            goal_period: None,
            wait: Duration::from_secs(20),
            joint_names: None,
            read_start: true,
        },
        model(),
    )
    .unwrap();
    let server = StandInServer::start(ServerConfig::new(
        "127.0.0.1:0",
        SceneSetup {
            robot_name: "FR3".into(),
            chain: model().chain,
            initial_q: q0.clone(),
            dummies: vec![],
            dt: 0.001,
            ik_following: false,
            // A simulator 200 times faster than time (a zero cost runs a loaded sequence
            // at once, before a stop can reach it).
            step_cost: Duration::from_micros(5),
            script: true,
        },
    ))
    .unwrap();
    let client = Client::connect(ClientConfig {
        endpoint: server.endpoint().into(),
        ..ClientConfig::default()
    })
    .unwrap();
    let mut scene = FrankaScene::open(client, "FR3", model(), 0.001).unwrap();
    scene.reset(&q0).unwrap();
    let mut kinematic = KinematicRobot::of_model(model(), &q0, 0.001).unwrap();
    let at: [f64; 7] = q0.as_slice().try_into().unwrap();
    let mut dynamics = dynamics_at(at).unwrap();
    let mut ros = ros;
    let mut robots: Vec<(&str, &mut dyn Robot)> = vec![
        ("in-process", &mut kinematic),
        ("coppelia", &mut scene),
        ("franka", &mut franka),
        ("ros2", &mut ros),
        ("dynamics", &mut dynamics),
    ];

    // Refused: the same sentence from every robot, and nothing moves.
    for plan in [step(&q0), {
        let mut far = swing(&q0, 1, 0.1, 1.0).points().to_vec();
        for q in &mut far {
            q[1] += 0.2;
        }
        Plan::new(0.01, far).unwrap()
    }] {
        let said: Vec<String> = robots
            .iter_mut()
            .map(|(_, r)| {
                let mut guarded = Guarded::new(&mut **r, Policy::STRICT);
                reason(guarded.run(&plan, &stop).unwrap_err()).to_string()
            })
            .collect();
        println!("refused: {}", said[0]);
        assert!(said.iter().all(|s| *s == said[0]), "{said:#?}");
        all_still(&mut robots, &q0);
    }
    // Into the post: joint 1 swung 1.2 rad clockwise sweeps the arm through it. Every
    // robot refuses it with the same sentence, naming a link and the post, before moving;
    // slowing cannot help, so the experiments' policy refuses it too.
    let into_post = swing_every(&q0, 0, -1.2, 4.0, 0.001);
    let said: Vec<String> = robots
        .iter_mut()
        .map(|(_, r)| {
            let mut guarded = Guarded::new(&mut **r, Policy::EXPERIMENT);
            match reason(guarded.run(&into_post, &stop).unwrap_err()) {
                Refusal::Collision(c) => {
                    assert_eq!(c.second, "post");
                    assert!(c.first.starts_with("fr3_") && c.distance < 0.005, "{c}");
                    c.to_string()
                }
                other => panic!("not a collision: {other}"),
            }
        })
        .collect();
    println!("refused: {}", said[0]);
    assert!(said.iter().all(|s| *s == said[0]), "{said:#?}");
    all_still(&mut robots, &q0);
    // Stopped before moving: every robot reports it one way (it was an error on the
    // Franka): a run that ends Stopped with where the robot stands, nothing sent.
    let stopped = StopToken::new();
    stopped.stop();
    for (name, r) in &mut robots {
        let mut guarded = Guarded::new(&mut **r, Policy::STRICT);
        let run = guarded
            .run(&swing(&q0, 0, 0.05, 1.0), &stopped)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(run.ending, cps_robot::Ending::Stopped, "{name}");
        assert_eq!(run.len(), 1, "{name}");
        let off = run.q[0]
            .iter()
            .zip(&q0)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(off < 1e-3, "{name} stands {off} rad from where it stood");
    }
    assert!(
        format!("{}", reason(Guarded::new(&mut *robots[0].1, Policy::STRICT).run(&step(&q0), &stop).unwrap_err()))
            .starts_with("joint 2 at t = 0.500 s (command 500): velocity 50.000000 rad/s beyond the limit 2.620000 rad/s")
    );

    // Slowed: joint 1 by 0.4 rad and back in 0.5 s is too fast for the FR3 (its
    // acceleration peaks at 2π²·0.4/0.25 = 31.6 rad/s²); every robot slows it by the same
    // factor, is sent the same plan, and runs it to its end.
    let fast = swing(&q0, 0, 0.4, 0.5);
    let mut slowings = Vec::new();
    for (name, r) in &mut robots {
        let mut guarded = Guarded::new(&mut **r, Policy::EXPERIMENT);
        let prepared = guarded.prepare(&fast).unwrap();
        assert_eq!(prepared.approach_points, 0, "{name}");
        let slowing = prepared.slowing;
        let sent = prepared.plan.clone();
        let run = guarded.run_prepared(prepared, &stop).unwrap();
        assert!(run.ending.complete(), "{name}: {:?}", run.ending);
        assert_eq!(run.len(), fast.points().len(), "{name}");
        assert!((sent.dt() - 0.01 * slowing).abs() < 1e-12 && sent.points() == fast.points());
        // Where the robot holds now (a Franka: its last command) is the plan's end.
        let end = r.joint_positions().unwrap();
        let off = end
            .iter()
            .zip(fast.end())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(off < 1e-3, "{name} holds {off} rad from the plan's end");
        slowings.push((*name, slowing));
    }
    println!("slowed: {slowings:?}");
    assert!(slowings[0].1 > 1.7 && slowings[0].1 < 2.5, "{slowings:?}");
    assert!(
        slowings.iter().all(|(_, s)| *s == slowings[0].1),
        "{slowings:?}"
    );
    // What the Franka streamed is the slowed plan's motion every millisecond (after its
    // blend into the start); what the ROS 2 controller was sent is the plan's points at the
    // slowed times.
    drop(robots);
    let slowed = fast.slowed(slowings[0].1);
    let stream = franka.last_stream().unwrap();
    let motion = slowed.samples(1e-3);
    assert_eq!(stream.commands.len() - stream.approach, motion.len());
    for (c, m) in stream.commands[stream.approach..].iter().zip(&motion) {
        assert!(c.iter().zip(m).all(|(a, b)| (a - b).abs() < 1e-12));
    }
    let goal = &ros.last_goal().unwrap().message;
    assert_eq!(goal.points.len(), slowed.points().len());
    for (k, p) in goal.points.iter().enumerate() {
        assert_eq!(p.positions, slowed.points()[k]);
        assert!((p.time_from_start.secs() - slowed.time(k)).abs() < 1e-9);
    }
    let mut robots: Vec<(&str, &mut dyn Robot)> = vec![
        ("in-process", &mut kinematic),
        ("coppelia", &mut scene),
        ("franka", &mut franka),
        ("ros2", &mut ros),
        ("dynamics", &mut dynamics),
    ];

    // Approached: a plan 0.2 rad away on joint 2 is approached from where each robot
    // stands, in about the same time, then run.
    let mut far = swing(&q0, 1, 0.1, 1.0).points().to_vec();
    for q in &mut far {
        q[1] -= 0.2;
    }
    let far = Plan::new(0.01, far).unwrap();
    let mut approaches = Vec::new();
    for (name, r) in &mut robots {
        let mut guarded = Guarded::new(&mut **r, Policy::EXPERIMENT);
        let run = guarded.run(&far, &stop).unwrap();
        assert!(run.ending.complete(), "{name}: {:?}", run.ending);
        assert_eq!(run.len(), far.points().len(), "{name}");
        approaches.push((*name, run.approach_s));
    }
    println!("approached: {approaches:?}");
    let a0 = approaches[0].1;
    assert!(a0 > 0.5, "{approaches:?}");
    assert!(
        approaches.iter().all(|(_, a)| (a - a0).abs() < 0.05),
        "{approaches:?}"
    );

    // Stopped mid-plan: a slow 200 s swing of joint 1, stopped while it runs — after 1 s
    // on the robots that run in real time (the Franka, the ROS 2 controller), right after
    // they start on those that run faster than time (in process, the stand-in's script,
    // dynamics).
    // Every one ends Stopped with what it did recorded (times strictly increasing, no
    // duplicate), moved and then stands still within its limits.
    // Every robot stands where the approached plan ended.
    let here = far.end().to_vec();
    let long = swing_every(&here, 0, 0.2, 200.0, 0.05);
    let mut stops = Vec::new();
    for (name, r) in &mut robots {
        let long = &long;
        // A robot faster than time is stopped soon after it starts moving: the in-process
        // robot moves through the swing's 200 000 steps for about 70 ms (stopped after
        // 10 ms); the dynamics robot, which integrates its arm every millisecond, for
        // seconds of wall time at least (stopped after 0.3 s: its generic code is
        // instantiated in this test, unoptimised in the checked build, about a quarter of
        // real time, tens of times faster than time optimised); the stand-in's script,
        // which takes the plan first and then steps about 3 000 rows a second on a quiet
        // machine (900 of the 4 001 at 0.3 s), is stopped after 0.6 s: a loaded machine
        // once kept it from its first step for 0.3 s. A stop a loaded machine delays by tens
        // of milliseconds still lands mid-plan, and a loaded machine moves them slower.
        let after = match *name {
            "franka" | "ros2" => Duration::from_secs(1),
            "coppelia" => Duration::from_millis(600),
            "dynamics" => Duration::from_millis(300),
            _ => Duration::from_millis(10),
        };
        let run = run_and_then(&mut **r, long, after, |token| token.stop())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(run.ending, cps_robot::Ending::Stopped, "{name}");
        assert!(
            run.len() > 1 && run.len() < long.points().len(),
            "{name}: {} entries of a {}-point plan (stopped {after:?} after it moved), ending at {:?} s",
            run.len(),
            long.points().len(),
            run.time.last()
        );
        assert!(
            run.time.windows(2).all(|w| w[1] > w[0]),
            "{name}: its recording's times do not increase"
        );
        let moved = run
            .q
            .iter()
            .map(|q| (q[0] - here[0]).abs())
            .fold(0.0, f64::max);
        assert!(moved > 0.0, "{name} did not move before the stop");
        let now = r.joint_positions().unwrap();
        std::thread::sleep(Duration::from_millis(200));
        let later = r.joint_positions().unwrap();
        let drift = now
            .iter()
            .zip(&later)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            drift < 1e-4,
            "{name} still moves {drift} rad after its stop"
        );
        let fr3 = model();
        let (lo, hi) = fr3.chain.limits().unwrap();
        assert!(
            later
                .iter()
                .enumerate()
                .all(|(j, q)| *q >= lo[j] && *q <= hi[j]),
            "{name} stands outside its range: {later:?}"
        );
        stops.push((*name, after, run.len(), *run.time.last().unwrap()));
    }
    println!("stopped mid-plan (robot, stopped after, entries, last time s): {stops:?}");
    for (name, _, _, last) in &stops {
        if matches!(*name, "franka" | "ros2") {
            assert!(*last > 0.5 && *last < 3.0, "{name} recorded up to {last} s");
        }
    }
    drop(robots);
    // The controller got the three goals the plans made (the last one stopped), point for
    // point.
    peer.finish(Duration::from_secs(60));
    let seen: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&seen).unwrap()).unwrap();
    let goals = seen["goals"].as_array().unwrap();
    assert_eq!(goals.len(), 3, "{seen}");
    assert_eq!(
        goals[0]["trajectory"]["points"].as_array().unwrap().len(),
        fast.points().len()
    );

    // Failed mid-plan: the far end dies while the robot runs a plan — the stand-in server
    // stopped after 0.6 s of motion (its script runs 50 000 steps a part, 0.25 s each),
    // franky-sim killed after 1 s. The run is not an error:
    // it ends Failed, saying why, with what was recorded up to then. (The in-process and
    // dynamics robots have no far end to lose; the ROS 2 controller's loss is
    // crates/cps-ros2/tests/graph.rs's.)
    let kill_server: Kill = Box::new(move || drop(server));
    let kill_franky: Kill = Box::new(franky.killer());
    let dying: Vec<(&str, &mut dyn Robot, Kill, Duration)> = vec![
        (
            "coppelia",
            &mut scene,
            kill_server,
            Duration::from_millis(600),
        ),
        ("franka", &mut franka, kill_franky, Duration::from_secs(1)),
    ];
    let mut failures = Vec::new();
    for (name, r, kill, after) in dying {
        let at = r.joint_positions().unwrap();
        let plan = swing_every(&at, 0, 0.2, 200.0, 0.05);
        let run = run_and_then(r, &plan, after, |_| kill()).unwrap_or_else(|e| {
            panic!("{name}: an error, not a failed run with its recording: {e}")
        });
        let why = match &run.ending {
            cps_robot::Ending::Failed(why) => why.clone(),
            other => panic!("{name}: {other:?}"),
        };
        // The Franka's every millisecond is recorded; the scene script's part under way
        // when its simulator went away is lost with it (the parts before are kept).
        let least = if name == "franka" { 2 } else { 1 };
        assert!(
            run.len() >= least && run.len() < plan.points().len(),
            "{name}: {} entries",
            run.len()
        );
        assert!(
            run.time.windows(2).all(|w| w[1] > w[0]),
            "{name}: its recording's times do not increase"
        );
        failures.push((name, run.len(), why));
    }
    println!("failed mid-plan (robot, entries, why): {failures:#?}");
}

/// Time-optimal S-curves at 95 % of the FR3's acceleration and jerk limits on joints 1 and
/// 4 from `q0`, out and back, every millisecond: where a lost period leaves the least room.
fn s_curves(q0: &[f64]) -> Vec<Vec<f64>> {
    let (a, j): (f64, f64) = (0.95 * 10.0, 0.95 * 5000.0);
    let w = (a / j / 0.001).round() as usize;
    let mut jerks = Vec::new();
    for sign in [1.0, -1.0] {
        for (s, len) in [
            (1.0, w),
            (0.0, 60),
            (-1.0, w),
            (0.0, 80),
            (-1.0, w),
            (0.0, 60),
            (1.0, w),
        ] {
            jerks.extend(std::iter::repeat_n(sign * s * j, len));
        }
    }
    jerks.extend([0.0; 50]);
    let (mut q, mut v, mut acc) = (q0.to_vec(), [0.0; 7], [0.0; 7]);
    let mut out = vec![q.clone()];
    for jerk in jerks {
        for i in [0, 3] {
            acc[i] += jerk * 0.001;
            v[i] += acc[i] * 0.001;
            q[i] += v[i] * 0.001;
        }
        out.push(q.clone());
    }
    out
}

/// Every robot that streams survives lost periods as a Franka must: the in-process robot
/// and the robot with dynamics told to lose 15 % of their periods (each then extrapolates
/// its reference through a lost period and judges the next command against it, as a
/// Franka does), and the Franka (franky-sim) behind a link that drops 15 % of the commands;
/// a stream at 95 % of the acceleration and jerk limits ends where it should on each, with
/// no reflex, the lost periods counted. (Without cps's limiter the in-process robots' own
/// judgement of the stream's next command after a lost period fails the run.)
#[test]
fn every_streaming_robot_survives_lost_periods_as_a_franka_must() {
    let Some(franky) = sim::FrankySim::start("127.0.0.93") else {
        return;
    };
    let stop = StopToken::new();
    let mut franka = franka_at(&franky.host);
    franka.connection().lose_commands(0.15, 61).unwrap();
    let q0 = franka.joint_positions().unwrap();
    let mut kinematic = KinematicRobot::of_model(model(), &q0, 0.001).unwrap();
    kinematic.lose_cycles(0.15, 61).unwrap();
    let at: [f64; 7] = q0.as_slice().try_into().unwrap();
    let mut dynamics = dynamics_at(at).unwrap();
    dynamics.lose_cycles(0.15, 61).unwrap();
    let stream = s_curves(&q0);
    let n = stream.len();
    let robots: Vec<(&str, &mut dyn Robot, f64)> = vec![
        ("in-process", &mut kinematic, 1e-12),
        ("dynamics", &mut dynamics, 2e-3),
        ("franka", &mut franka, 0.05),
    ];
    for (name, robot, tolerance) in robots {
        let mut k = 0;
        let mut next = |_: &cps_robot::Measured<'_>, _: f64, out: &mut [f64]| -> bool {
            out.copy_from_slice(&stream[k.min(n - 1)]);
            k += 1;
            k >= n
        };
        let run = robot
            .streaming()
            .expect("it streams")
            .stream(&mut next, n + 100, &stop)
            .unwrap();
        assert_eq!(run.ending, cps_robot::Ending::Finished, "{name}");
        let end = run.q.last().unwrap();
        for (i, (a, b)) in end.iter().zip(stream.last().unwrap()).enumerate() {
            assert!(
                (a - b).abs() <= tolerance,
                "{name}: joint {} ends at {a}, the stream at {b}",
                i + 1
            );
        }
        let report = robot.report().unwrap_or_default();
        println!("{name}: {report}");
        if name != "franka" {
            // Periods lost, and commands limited after one (the stream's own would have
            // broken the jerk limit against the robot's extrapolation).
            let count = |what: &str| -> u64 {
                report
                    .split(what)
                    .next()
                    .and_then(|s| s.rsplit(' ').next())
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(0)
            };
            assert!(count(" periods lost on purpose") > 30, "{name}: {report}");
            assert!(count(" commands limited after one") > 0, "{name}: {report}");
        }
    }
    assert!(franka.connection().commands_lost() > 30);
}
