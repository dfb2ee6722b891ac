//! The Rust client against the stand-in server on a free loopback port: a full session,
//! errors from the server, two clients with separate stepping, and a dead server.

use std::time::{Duration, Instant};

use cps_coppelia::sim::HANDLE_WORLD;
use cps_coppelia::{Client, ClientConfig, CoppeliaError, SceneSetup, ServerConfig, StandInServer};
use cps_kinematics::robots::{PandaTool, panda};
use nalgebra::Isometry3;

const THESIS_Q0: [f64; 7] = [
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    std::f64::consts::FRAC_PI_2,
    std::f64::consts::FRAC_PI_4,
];

fn server() -> StandInServer {
    let chain = panda(PandaTool::HandTcp).with_base(Isometry3::translation(0.5396, 0.02, 0.749));
    StandInServer::start(ServerConfig {
        bind: "127.0.0.1:0".into(),
        scene: SceneSetup {
            robot_name: "Panda".into(),
            chain,
            initial_q: THESIS_Q0.to_vec(),
            dummies: vec![
                ("p0".into(), [0.75, 0.02, 1.87]),
                ("p1".into(), [0.78, 0.60, 1.70]),
            ],
            dt: 0.05,
            ik_following: false,
            step_cost: std::time::Duration::ZERO,
            script: true,
        },
        limits: cps_coppelia::ServerLimits::default(),
    })
    .unwrap()
}

fn client(endpoint: &str) -> Client {
    Client::connect(ClientConfig {
        endpoint: endpoint.into(),
        connect_timeout: Duration::from_secs(2),
        call_timeout: Duration::from_secs(2),
        ..ClientConfig::default()
    })
    .unwrap()
}

#[test]
fn a_full_session() {
    let srv = server();
    let mut sim = client(srv.endpoint());
    // The seven joints and the tip: the thesis's start point at the initial configuration.
    let joints: Vec<i64> = (1..=7)
        .map(|i| sim.get_object(&format!("/Panda_joint{i}")).unwrap())
        .collect();
    for (h, q) in joints.iter().zip(THESIS_Q0) {
        assert!((sim.get_joint_position(*h).unwrap() - q).abs() < 1e-15);
    }
    let tip = sim.get_object("/Panda_tip").unwrap();
    let p = sim.get_object_position(tip, HANDLE_WORLD).unwrap();
    for (a, b) in p.iter().zip([0.75, 0.02, 1.87]) {
        assert!((a - b).abs() < 1e-12, "{p:?}");
    }
    // Moving joint 1 turns the tip about the base's z axis.
    sim.set_joint_position(joints[0], 0.5).unwrap();
    let moved = sim.get_object_position(tip, HANDLE_WORLD).unwrap();
    assert!((moved[2] - 1.87).abs() < 1e-12 && (moved[0] - 0.75).abs() > 0.01);
    // A dummy: create, alias, move, colour, find by its alias, remove.
    let d = sim.create_dummy(0.04).unwrap();
    sim.set_object_alias(d, "pT").unwrap();
    sim.set_object_position(d, [0.55, -0.57, 1.45], HANDLE_WORLD)
        .unwrap();
    sim.set_object_color(d, [0.0, 1.0, 0.0]).unwrap();
    assert_eq!(sim.get_object("/pT").unwrap(), d);
    assert_eq!(
        sim.get_object_position(d, HANDLE_WORLD).unwrap(),
        [0.55, -0.57, 1.45]
    );
    let m = sim.get_object_matrix(d, HANDLE_WORLD).unwrap();
    assert_eq!([m[3], m[7], m[11]], [0.55, -0.57, 1.45]);
    // A quarter turn about z, set as a matrix, comes back as a pose.
    let quarter = [0.0, -1.0, 0.0, 0.1, 1.0, 0.0, 0.0, 0.2, 0.0, 0.0, 1.0, 0.3];
    sim.set_object_matrix(d, quarter, HANDLE_WORLD).unwrap();
    let back = sim.get_object_matrix(d, HANDLE_WORLD).unwrap();
    for (a, b) in back.iter().zip(quarter) {
        assert!((a - b).abs() < 1e-12, "{back:?}");
    }
    let p1 = sim.get_object("/p1").unwrap();
    let pose = sim.get_object_pose(p1, HANDLE_WORLD).unwrap();
    assert!((pose.translation.vector - nalgebra::Vector3::new(0.78, 0.60, 1.70)).norm() < 1e-15);
    sim.remove_objects(&[d]).unwrap();
    assert!(matches!(
        sim.get_object("/pT"),
        Err(CoppeliaError::Remote { .. })
    ));
    // Start, stepping, several steps with time advancing by dt, stop.
    sim.start_simulation().unwrap();
    assert_eq!(sim.get_simulation_state().unwrap(), 17);
    assert_eq!(sim.set_stepping(true).unwrap(), 0);
    let t0 = sim.get_simulation_time().unwrap();
    for k in 1..=5 {
        sim.step().unwrap();
        let t = sim.get_simulation_time().unwrap();
        assert!((t - t0 - 0.05 * k as f64).abs() < 1e-12, "t {t}");
    }
    sim.stop_simulation().unwrap();
    assert_eq!(sim.get_simulation_state().unwrap(), 0);
    assert_eq!(sim.get_simulation_time().unwrap(), 0.0);
    // An error raised on the server names the function.
    match sim.get_object("/NoSuchThing") {
        Err(CoppeliaError::Remote {
            function, message, ..
        }) => {
            assert_eq!(function, "sim.getObject");
            assert!(message.contains("Object does not exist"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    match sim.call("sim.noSuchFunction", vec![]) {
        Err(CoppeliaError::Remote { message, .. }) => {
            assert!(message.contains("No such function: sim.noSuchFunction"))
        }
        other => panic!("{other:?}"),
    }
    match sim.call(
        "sim.setJointPosition",
        vec![
            cps_coppelia::codec::text("j"),
            cps_coppelia::codec::text("x"),
        ],
    ) {
        Err(CoppeliaError::Remote { message, .. }) => assert!(
            message.contains("argument 1 must be an integer"),
            "{message}"
        ),
        other => panic!("{other:?}"),
    }
}

#[test]
fn two_clients_keep_separate_stepping_state() {
    let srv = server();
    let (mut a, mut b) = (client(srv.endpoint()), client(srv.endpoint()));
    a.start_simulation().unwrap();
    assert_eq!(a.set_stepping(true).unwrap(), 0);
    assert_eq!(a.set_stepping(true).unwrap(), 1);
    assert_eq!(b.set_stepping(true).unwrap(), 0, "b has its own level");
    assert_eq!(b.set_stepping(false).unwrap(), 1);
    // Only a steps now: each of its steps advances the clock by dt, b's requests do not.
    let t0 = b.get_simulation_time().unwrap();
    a.step().unwrap();
    assert!((b.get_simulation_time().unwrap() - t0 - 0.05).abs() < 1e-12);
    // Stopping the simulation ends every client's stepping.
    a.stop_simulation().unwrap();
    assert_eq!(a.set_stepping(true).unwrap(), 0);
}

#[test]
fn a_dead_server_is_a_timely_error_and_a_restarted_one_is_reached_again() {
    let srv = server();
    let endpoint = srv.endpoint().to_string();
    let mut sim = client(&endpoint);
    assert!(sim.get_simulation_time().is_ok());
    drop(srv);
    let start = Instant::now();
    let e = sim.get_simulation_time().unwrap_err();
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "took {:?}",
        start.elapsed()
    );
    assert!(
        matches!(
            e,
            CoppeliaError::Timeout { .. } | CoppeliaError::Connection { .. }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains(&endpoint));
    // The server comes back on the same port: the next call reconnects by itself
    // (a server restart forgets `require`, which the stand-in does not enforce).
    let again = StandInServer::start(ServerConfig {
        bind: endpoint.trim_start_matches("tcp://").into(),
        scene: SceneSetup {
            robot_name: "Panda".into(),
            chain: panda(PandaTool::HandTcp),
            initial_q: THESIS_Q0.to_vec(),
            dummies: vec![],
            dt: 0.05,
            ik_following: false,
            step_cost: std::time::Duration::ZERO,
            script: true,
        },
        limits: cps_coppelia::ServerLimits::default(),
    })
    .unwrap();
    assert_eq!(sim.get_simulation_time().unwrap(), 0.0);
    drop(again);
    // Nothing listening at all: connect fails within its timeout.
    let start = Instant::now();
    let e = Client::connect(ClientConfig {
        endpoint: endpoint.clone(),
        connect_timeout: Duration::from_millis(300),
        call_timeout: Duration::from_millis(300),
        ..ClientConfig::default()
    })
    .unwrap_err();
    assert!(start.elapsed() < Duration::from_secs(3), "{e}");
}

/// The same trajectory executed on the in-process robot and, through the remote API, on
/// the stand-in server gives the same recording.
#[test]
fn execution_on_the_server_matches_the_in_process_robot() {
    use cps_coppelia::FrankaScene;
    use cps_kinematics::IkTarget;
    use cps_robot::{ExecutionConfig, KinematicRobot, Stepped, StopToken, execute};
    let srv = server();
    let mut scene = FrankaScene::open(
        client(srv.endpoint()),
        "Panda",
        cps_robot::RobotModel::of_chain("Panda", panda(PandaTool::HandTcp)),
        0.05,
    )
    .unwrap();
    let names: Vec<String> = scene
        .way_points()
        .unwrap()
        .into_iter()
        .map(|w| w.0)
        .collect();
    assert!(names.is_empty() || names.iter().all(|n| n.starts_with('p')));
    let model = panda(PandaTool::HandTcp).with_base(Isometry3::translation(0.5396, 0.02, 0.749));
    let ready = cps_kinematics::robots::PANDA_READY;
    scene.command_joint_positions(&ready).unwrap();
    scene.start_stepping().unwrap();
    scene.step().unwrap();
    let c = model.fk(&ready).unwrap().translation.vector;
    let targets: Vec<IkTarget> = (0..=40)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / 40.0;
            IkTarget::Position(
                c + nalgebra::Vector3::new(0.02 * (a.cos() - 1.0), 0.02 * a.sin(), 0.0),
            )
        })
        .collect();
    let cfg = ExecutionConfig {
        max_iterations_per_sample: 1,
        ..ExecutionConfig::default()
    };
    let remote = execute(&mut scene, &model, &targets, &cfg, &StopToken::new()).unwrap();
    let mut local_robot = KinematicRobot::new(model.clone(), &ready, 0.05).unwrap();
    let local = execute(&mut local_robot, &model, &targets, &cfg, &StopToken::new()).unwrap();
    assert_eq!(remote.q.len(), local.q.len());
    for (a, b) in remote.q.iter().zip(&local.q) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() < 1e-12, "{x} vs {y}");
        }
    }
    for (a, b) in remote.position.iter().zip(&local.position) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-12);
        }
    }
    // Both recordings count time from the start of the execution, dt per step (the remote
    // clock was one step ahead when the execution began).
    assert!((remote.time[1] - remote.time[0] - 0.05).abs() < 1e-12);
    for (a, b) in remote.time.iter().zip(&local.time) {
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }
    assert!(
        remote.max_position_error() < 1e-4,
        "{}",
        remote.max_position_error()
    );
    scene.stop().unwrap();
}

/// An endpoint that is not a ZMQ server (a plain TCP listener that sends garbage) gives a
/// clear error within the timeout, never a hang.
#[test]
fn an_endpoint_that_is_not_a_zmq_server_is_an_error() {
    use std::io::Write;
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let garbage = std::thread::spawn(move || {
        if let Ok((mut s, _)) = listener.accept() {
            let _ = s.write_all(b"HTTP/1.1 400 Bad Request\r\n\r\n");
            std::thread::sleep(Duration::from_millis(500));
        }
    });
    let start = Instant::now();
    let e = Client::connect(ClientConfig {
        endpoint: format!("tcp://127.0.0.1:{port}"),
        connect_timeout: Duration::from_millis(500),
        call_timeout: Duration::from_millis(500),
        ..ClientConfig::default()
    })
    .unwrap_err();
    assert!(
        start.elapsed() < Duration::from_secs(3),
        "took {:?}",
        start.elapsed()
    );
    assert!(e.to_string().contains(&format!("127.0.0.1:{port}")), "{e}");
    let _ = garbage.join();
    // Settings that cannot work are refused before any I/O.
    let bad = Client::connect(ClientConfig {
        endpoint: "localhost:23000".into(),
        ..ClientConfig::default()
    });
    assert!(matches!(bad, Err(CoppeliaError::InvalidConfig(_))));
}

/// A CoppeliaSim 4.3–4.5 server (protocol v1) does not know `zmqRemoteApi.require`: the
/// client notices and speaks v1 (`{func, args}` only) from then on.
#[test]
fn a_v1_server_is_detected() {
    use cps_coppelia::codec::{self, Value};
    use zeromq::{RepSocket, Socket, SocketRecv, SocketSend, ZmqMessage};
    let (tx, rx) = std::sync::mpsc::channel();
    let server = std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async move {
            let mut rep = RepSocket::new();
            let ep = rep.bind("tcp://127.0.0.1:0").await.unwrap();
            tx.send(ep.to_string()).unwrap();
            let mut seen = Vec::new();
            for _ in 0..2 {
                let m = rep.recv().await.unwrap();
                let bytes: Vec<u8> = m.into_vec().into_iter().flat_map(|b| b.to_vec()).collect();
                let req = codec::decode(&bytes).unwrap();
                let func = codec::get(&req, "func").and_then(codec::as_text).unwrap();
                seen.push((func.clone(), codec::get(&req, "uuid").is_some()));
                let reply = if func == "zmqRemoteApi.require" {
                    codec::map([
                        ("success", Value::Bool(false)),
                        (
                            "error",
                            codec::text("No such function: zmqRemoteApi.require"),
                        ),
                    ])
                } else {
                    codec::map([
                        ("success", Value::Bool(true)),
                        ("ret", Value::Array(vec![Value::Float(1.25)])),
                    ])
                };
                rep.send(ZmqMessage::from(codec::encode(&reply)))
                    .await
                    .unwrap();
            }
            seen
        })
    });
    let endpoint = rx.recv().unwrap();
    let mut sim = client(&endpoint);
    assert_eq!(sim.protocol(), cps_coppelia::Protocol::V1);
    assert_eq!(sim.get_simulation_time().unwrap(), 1.25);
    drop(sim);
    let seen = server.join().unwrap();
    assert_eq!(
        seen[1],
        ("sim.getSimulationTime".to_string(), false),
        "v1 requests carry no uuid"
    );
}

/// Against a protocol-v1 server (CoppeliaSim 4.3–4.5, faked here from the protocol notes):
/// stepping goes through the global `setStepping`/`step` and waits for the step counter
/// published on the next port; setters send `(handle, relativeTo, value)`.
#[test]
fn a_v1_server_steps_through_its_step_counter_and_takes_v1_setters() {
    use cps_coppelia::codec::{self, Value};
    use zeromq::{PubSocket, RepSocket, Socket, SocketRecv, SocketSend, ZmqMessage};
    // Two free consecutive ports: request port p, step counter p + 1.
    let port = (0..50)
        .find_map(|_| {
            let a = std::net::TcpListener::bind("127.0.0.1:0").ok()?;
            let p = a.local_addr().ok()?.port();
            let b = std::net::TcpListener::bind(("127.0.0.1", p.checked_add(1)?)).ok()?;
            drop((a, b));
            Some(p)
        })
        .expect("two consecutive free ports");
    let (tx, rx) = std::sync::mpsc::channel();
    let server = std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async move {
            let mut rep = RepSocket::new();
            rep.bind(&format!("tcp://127.0.0.1:{port}")).await.unwrap();
            let mut publisher = PubSocket::new();
            publisher
                .bind(&format!("tcp://127.0.0.1:{}", port + 1))
                .await
                .unwrap();
            tx.send(()).unwrap();
            // The simulation advances 30 ms after a `step` request was answered, then
            // publishes the counter; meanwhile requests are served. A client that did not
            // wait for the counter would read the old time.
            let steps = std::sync::Arc::new(std::sync::atomic::AtomicU32::new(0));
            let (step_tx, mut step_rx) = tokio::sync::mpsc::unbounded_channel::<()>();
            let counter = steps.clone();
            tokio::spawn(async move {
                while step_rx.recv().await.is_some() {
                    tokio::time::sleep(Duration::from_millis(30)).await;
                    let n = counter.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1;
                    publisher
                        .send(ZmqMessage::from(n.to_le_bytes().to_vec()))
                        .await
                        .unwrap();
                }
            });
            let mut stepping = false;
            let mut seen = Vec::new();
            loop {
                let m = rep.recv().await.unwrap();
                let bytes: Vec<u8> = m.into_vec().into_iter().flat_map(|b| b.to_vec()).collect();
                let req = codec::decode(&bytes).unwrap();
                let func = codec::get(&req, "func").and_then(codec::as_text).unwrap();
                let args = codec::as_list(codec::get(&req, "args")).unwrap();
                seen.push((func.clone(), args.clone()));
                let ok = |ret: Vec<Value>| {
                    codec::map([("success", Value::Bool(true)), ("ret", Value::Array(ret))])
                };
                let now = steps.load(std::sync::atomic::Ordering::SeqCst);
                let reply = match func.as_str() {
                    "zmqRemoteApi.require" => codec::map([
                        ("success", Value::Bool(false)),
                        (
                            "error",
                            codec::text("No such function: zmqRemoteApi.require"),
                        ),
                    ]),
                    "setStepping" => {
                        stepping = codec::as_bool(&args[0]).unwrap();
                        ok(vec![codec::int(0)])
                    }
                    "sim.getSimulationTime" => ok(vec![Value::Float(f64::from(now) * 0.05)]),
                    _ => ok(vec![]),
                };
                rep.send(ZmqMessage::from(codec::encode(&reply)))
                    .await
                    .unwrap();
                if func == "step" && stepping {
                    step_tx.send(()).unwrap();
                }
                if func == "sim.setObjectPosition" {
                    return (seen, steps.load(std::sync::atomic::Ordering::SeqCst));
                }
            }
        })
    });
    rx.recv().unwrap();
    let mut sim = client(&format!("tcp://127.0.0.1:{port}"));
    assert_eq!(sim.protocol(), cps_coppelia::Protocol::V1);
    sim.set_stepping(true).unwrap();
    for k in 1..=3 {
        // `step` returns only once the counter arrived, i.e. after the step happened.
        sim.step().unwrap();
        assert!((sim.get_simulation_time().unwrap() - 0.05 * f64::from(k)).abs() < 1e-12);
    }
    sim.set_object_position(17, [0.1, 0.2, 0.3], HANDLE_WORLD)
        .unwrap();
    let (seen, steps) = server.join().unwrap();
    assert_eq!(steps, 3);
    let stepping = seen.iter().find(|(f, _)| f == "setStepping").unwrap();
    assert_eq!(stepping.1[0], Value::Bool(true));
    assert!(
        matches!(stepping.1.get(1), Some(Value::Text(_))),
        "the uuid follows"
    );
    let setter = &seen.last().unwrap().1;
    assert_eq!(setter[0], codec::int(17));
    assert_eq!(
        setter[1],
        codec::int(HANDLE_WORLD),
        "v1 takes relativeTo second"
    );
    assert_eq!(setter[2], codec::floats(&[0.1, 0.2, 0.3]));
}

/// CoppeliaSim's IK as the backend: the trajectory moves `/Panda_target`, the scene's IK
/// (emulated by the stand-in with `ik_following`) moves the joints, and the tip follows.
#[test]
fn the_scene_s_own_ik_follows_the_target() {
    use cps_coppelia::FrankaScene;
    use cps_kinematics::IkTarget;
    use cps_robot::{ExecutionConfig, Robot, Stepped, Stepping, StopToken, execute};
    let model = panda(PandaTool::HandTcp).with_base(Isometry3::translation(0.5396, 0.02, 0.749));
    let srv = StandInServer::start(ServerConfig {
        bind: "127.0.0.1:0".into(),
        scene: SceneSetup {
            robot_name: "Panda".into(),
            chain: model.clone(),
            initial_q: THESIS_Q0.to_vec(),
            dummies: vec![],
            dt: 0.05,
            ik_following: true,
            step_cost: std::time::Duration::ZERO,
            script: true,
        },
        limits: cps_coppelia::ServerLimits::default(),
    })
    .unwrap();
    let mut scene = FrankaScene::open(
        client(srv.endpoint()),
        "Panda",
        cps_robot::RobotModel::of_chain("Panda", panda(PandaTool::HandTcp)),
        0.05,
    )
    .unwrap();
    assert!(!matches!(scene.stepping(), Stepping::Targets { .. }));
    scene.follow_ik_target(true).unwrap();
    assert!(matches!(scene.stepping(), Stepping::Targets { .. }));
    let ready = cps_kinematics::robots::PANDA_READY;
    scene.reset(&ready).unwrap();
    // Reset put the target on the tip: a step does not move the robot.
    scene.step().unwrap();
    let q = scene.joint_positions().unwrap();
    assert!(
        q.iter().zip(&ready).all(|(a, b)| (a - b).abs() < 1e-9),
        "{q:?}"
    );
    let c = model.fk(&ready).unwrap().translation.vector;
    let targets: Vec<IkTarget> = (0..=40)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / 40.0;
            IkTarget::Position(
                c + nalgebra::Vector3::new(0.0, 0.03 * a.sin(), 0.03 * (1.0 - a.cos())),
            )
        })
        .collect();
    let rec = execute(
        &mut scene,
        &model,
        &targets,
        &ExecutionConfig::default(),
        &StopToken::new(),
    )
    .unwrap();
    assert!(
        rec.max_position_error() < 1e-4,
        "{}",
        rec.max_position_error()
    );
    assert_eq!(rec.unconverged, 0);
    // The joints really moved (the circle's top is 6 cm above the start).
    let top = &rec.q[20];
    assert!(top.iter().zip(&ready).any(|(a, b)| (a - b).abs() > 0.01));
    scene.stop().unwrap();
}

/// Callbacks: the server calls a registered Rust function during a request (CoppeliaSim's
/// `sim.testCB(a, cb, b, iterations)` calls `cb(a, b)` iterations + 1 times) and gets its
/// results back.
#[test]
fn a_registered_callback_is_called_by_the_server() {
    use cps_coppelia::codec::{self, Value};
    let srv = server();
    let mut sim = client(srv.endpoint());
    let calls = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let seen = calls.clone();
    let cb = sim.register_callback("multiply", move |args| {
        seen.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        let a = codec::as_f64(&args[0]).unwrap();
        let b = codec::as_f64(&args[1]).unwrap();
        vec![Value::Float(a * b)]
    });
    let ret = sim
        .call(
            "sim.testCB",
            vec![codec::int(21), cb, codec::int(2), codec::int(3)],
        )
        .unwrap();
    assert_eq!(codec::as_f64(&ret[0]), Some(42.0));
    assert_eq!(calls.load(std::sync::atomic::Ordering::SeqCst), 4);
    // A plain call afterwards is unaffected.
    assert_eq!(sim.get_simulation_time().unwrap(), 0.0);
}

// ---- Hostile peers ----------------------------------------------------------------------

fn server_with(limits: cps_coppelia::ServerLimits) -> StandInServer {
    let chain = panda(PandaTool::HandTcp);
    StandInServer::start(ServerConfig {
        limits,
        ..ServerConfig::new(
            "127.0.0.1:0",
            SceneSetup {
                robot_name: "Panda".into(),
                chain,
                initial_q: THESIS_Q0.to_vec(),
                dummies: vec![("p0".into(), [0.75, 0.02, 1.87])],
                dt: 0.05,
                ik_following: false,
                step_cost: std::time::Duration::ZERO,
                script: true,
            },
        )
    })
    .unwrap()
}

/// A ZMTP 3.0 greeting (NULL mechanism) and READY command for `kind`, written by hand.
fn handshake_bytes(kind: &[u8; 3]) -> Vec<u8> {
    let mut g = vec![0u8; 64];
    g[0] = 0xff;
    g[9] = 0x7f;
    g[10] = 3;
    g[12..16].copy_from_slice(b"NULL");
    let mut ready = vec![5u8];
    ready.extend_from_slice(b"READY");
    ready.push(11);
    ready.extend_from_slice(b"Socket-Type");
    ready.extend_from_slice(&3u32.to_be_bytes());
    ready.extend_from_slice(kind);
    g.extend_from_slice(&[0x04, ready.len() as u8]);
    g.extend_from_slice(&ready);
    g
}

/// A raw ZMTP 3.0 REQ peer over TCP.
fn raw_peer(endpoint: &str) -> std::net::TcpStream {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(endpoint.trim_start_matches("tcp://")).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.write_all(&handshake_bytes(b"REQ")).unwrap();
    let mut theirs = [0u8; 64];
    s.read_exact(&mut theirs).unwrap();
    let mut head = [0u8; 2];
    s.read_exact(&mut head).unwrap();
    let mut body = vec![0; head[1] as usize];
    s.read_exact(&mut body).unwrap();
    s
}

/// A v2 request as CBOR, framed for REQ (empty delimiter, then the body).
fn framed_request(func: &str) -> Vec<u8> {
    use cps_coppelia::codec;
    let body = codec::encode(&codec::map([
        ("func", codec::text(func)),
        ("args", codec::Value::Array(vec![])),
        ("uuid", codec::text("flood")),
    ]));
    let mut out = vec![0x01, 0x00, 0x00, body.len() as u8];
    out.extend_from_slice(&body);
    out
}

#[test]
fn a_peer_declaring_a_huge_frame_is_dropped_and_the_others_are_served() {
    use std::io::{Read, Write};
    let srv = server_with(cps_coppelia::ServerLimits::default());
    let mut sim = client(srv.endpoint());
    for declared in [64u64 << 30, u64::MAX, (16 << 20) + 1] {
        let mut peer = raw_peer(srv.endpoint());
        let mut head = vec![0x02u8];
        head.extend_from_slice(&declared.to_be_bytes());
        peer.write_all(&head).unwrap();
        // The server closes the connection instead of waiting for (or allocating) the body.
        let mut buf = [0u8; 16];
        assert!(matches!(peer.read(&mut buf), Ok(0) | Err(_)));
        assert!(sim.get_simulation_time_step().is_ok());
    }
    assert!(srv.dropped_peers() >= 3, "{}", srv.dropped_peers());
}

#[test]
fn a_flooding_client_does_not_starve_another() {
    use std::io::Write;
    let srv = server_with(cps_coppelia::ServerLimits::default());
    // The flooder pipelines requests and never reads a reply.
    let mut flood = raw_peer(srv.endpoint());
    flood.set_nonblocking(true).unwrap();
    let request = framed_request("sim.getSimulationTime");
    let stop = Instant::now() + Duration::from_secs(3);
    let mut sim = client(srv.endpoint());
    let mut answered = 0;
    while Instant::now() < stop && answered < 20 {
        for _ in 0..200 {
            let _ = flood.write_all(&request);
        }
        // Every call of the well-behaved client is answered within its 2 s timeout.
        sim.get_simulation_time().unwrap();
        answered += 1;
    }
    assert_eq!(answered, 20);
}

#[test]
fn degenerate_poses_and_values_get_error_replies() {
    let srv = server_with(cps_coppelia::ServerLimits::default());
    let mut sim = client(srv.endpoint());
    let d = sim.get_object("/p0").unwrap();
    let j = sim.get_object("/Panda_joint1").unwrap();
    let bad_matrices: [[f64; 12]; 6] = [
        [-1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0], // reflection
        [0.0; 12],                                                     // zeros
        [2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0],  // scaling
        [
            1e300, 0.0, 0.0, 0.0, 0.0, 1e300, 0.0, 0.0, 0.0, 0.0, 1e300, 0.0,
        ],
        [
            f64::NAN,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
        ],
        [1.0, 0.0, 0.0, 1e300, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0], // huge translation
    ];
    for m in bad_matrices {
        let e = sim.set_object_matrix(d, m, HANDLE_WORLD).unwrap_err();
        assert!(matches!(e, CoppeliaError::Remote { .. }), "{e}");
    }
    let bad_poses: [[f64; 7]; 3] = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1e200, 1e200, 0.0, 0.0],
        [f64::INFINITY, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
    ];
    for p in bad_poses {
        use cps_coppelia::codec;
        let args = vec![codec::int(d), codec::floats(&p), codec::int(HANDLE_WORLD)];
        assert!(sim.call("sim.setObjectPose", args).is_err());
    }
    for v in [f64::NAN, f64::INFINITY, 1e300] {
        assert!(sim.set_joint_position(j, v).is_err());
    }
    assert!(sim.get_joint_position(1 << 60).is_err());
    // A slightly off rotation (as a client's rounding leaves it) is accepted, and the
    // server is still answering.
    let c = 0.5f64.cos();
    let s = 0.5f64.sin();
    let m = [c, -s, 0.0, 0.1, s, c, 0.0, 0.2, 0.0, 0.0, 1.0 + 1e-9, 0.3];
    sim.set_object_matrix(d, m, HANDLE_WORLD).unwrap();
    let p = sim.get_object_position(d, HANDLE_WORLD).unwrap();
    assert!((p[0] - 0.1).abs() < 1e-12 && (p[2] - 0.3).abs() < 1e-12);
}

#[test]
fn a_silent_stepping_client_loses_its_hold_after_its_lease() {
    let srv = server_with(cps_coppelia::ServerLimits {
        client_lease: Duration::from_millis(300),
        ..cps_coppelia::ServerLimits::default()
    });
    let mut dead = client(srv.endpoint());
    dead.set_stepping(true).unwrap();
    dead.start_simulation().unwrap();
    // It dies without saying goodbye: the connection stays, the client says nothing more.
    std::mem::forget(dead);
    let mut other = client(srv.endpoint());
    let t0 = other.get_simulation_time().unwrap();
    let t1 = other.get_simulation_time().unwrap();
    assert_eq!(
        t0, t1,
        "the stepping client holds the simulation while its lease runs"
    );
    std::thread::sleep(Duration::from_millis(400));
    let t2 = other.get_simulation_time().unwrap();
    let t3 = other.get_simulation_time().unwrap();
    assert!(
        t3 > t2,
        "after the lease the simulation runs on ({t2} → {t3})"
    );
}

/// A hostile server: after a correct handshake it answers with a 64 GiB frame header,
/// with bytes that are not CBOR, with CBOR of the wrong shape, or not at all. The client
/// returns an error each time (within its timeout), allocates nothing for the huge frame,
/// and never panics.
#[test]
fn the_client_survives_a_hostile_server() {
    use std::io::{Read, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let endpoint = format!("tcp://{}", listener.local_addr().unwrap());
    let replies: Vec<Option<Vec<u8>>> = vec![
        Some({
            let mut f = vec![0x01, 0x00, 0x02];
            f.extend_from_slice(&(64u64 << 30).to_be_bytes());
            f
        }),
        Some(vec![0x01, 0x00, 0x00, 0x03, 0xff, 0x00, 0x13]),
        Some({
            // A CBOR text where a map is expected.
            vec![0x01, 0x00, 0x00, 0x04, 0x63, b'a', b'b', b'c']
        }),
        None,
    ];
    let server = std::thread::spawn(move || {
        for reply in replies {
            let Ok((mut s, _)) = listener.accept() else {
                return;
            };
            let _ = s.write_all(&handshake_bytes(b"REP"));
            // Take the client's greeting, READY and first request (all short).
            s.set_read_timeout(Some(Duration::from_millis(200)))
                .unwrap();
            let mut buf = [0u8; 4096];
            let mut got = 0;
            while got < 64 + 2 + 20 + 2 + 30 {
                match s.read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(k) => got += k,
                }
            }
            if let Some(r) = reply {
                let _ = s.write_all(&r);
            }
            // Hold the connection until the client gives up on it.
            s.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
            while let Ok(k) = s.read(&mut buf) {
                if k == 0 {
                    break;
                }
            }
        }
    });
    for _ in 0..4 {
        let start = Instant::now();
        let e = Client::connect(ClientConfig {
            endpoint: endpoint.clone(),
            connect_timeout: Duration::from_millis(600),
            call_timeout: Duration::from_millis(600),
            ..ClientConfig::default()
        })
        .unwrap_err();
        assert!(start.elapsed() < Duration::from_secs(3), "{e}");
        let text = e.to_string();
        assert!(text.contains(&endpoint), "{text}");
    }
    server.join().unwrap();
}

/// `step_cost` stands in for a simulator's physics: each step takes at least that long
/// (the server sleeps it; a lower bound only, which no machine load can break), and the
/// simulation time still advances by dt a step.
#[test]
fn every_step_takes_the_step_cost() {
    let scene = SceneSetup {
        step_cost: Duration::from_millis(20),
        script: true,
        ..server_scene(panda(PandaTool::HandTcp))
    };
    let srv = StandInServer::start(ServerConfig::new("127.0.0.1:0", scene)).unwrap();
    let mut sim = client(srv.endpoint());
    sim.start_simulation().unwrap();
    assert_eq!(sim.set_stepping(true).unwrap(), 0);
    let t0 = sim.get_simulation_time().unwrap();
    let started = std::time::Instant::now();
    for _ in 0..10 {
        sim.step().unwrap();
    }
    assert!(
        started.elapsed() >= Duration::from_millis(200),
        "{:?}",
        started.elapsed()
    );
    let t1 = sim.get_simulation_time().unwrap();
    assert!((t1 - t0 - 0.5).abs() < 1e-9, "{t0} → {t1}");
    sim.stop_simulation().unwrap();
}

/// The test scene: the Panda with no dummies, dt 0.05, no IK, no step cost.
fn server_scene(chain: cps_kinematics::SerialChain) -> SceneSetup {
    SceneSetup {
        robot_name: "Panda".into(),
        chain,
        initial_q: THESIS_Q0.to_vec(),
        dummies: vec![],
        dt: 0.05,
        ik_following: false,
        step_cost: Duration::ZERO,
        script: true,
    }
}

/// A stop reaches a plan the scene script is running: cps tells the script to stop where
/// it is (`cpsStop`), and the run ends Stopped with what was recorded, the points not
/// reached left out, no time twice, and the robot holding where it stopped (the script ran
/// every plan to its end, blind to the stop).
#[test]
fn a_stop_reaches_a_plan_the_scene_script_runs() {
    use cps_coppelia::FrankaScene;
    use cps_robot::{Ending, Plan, Robot, Stepped, StopToken};
    // Each step costs a millisecond: the 4 s plan below takes 4 s of wall time.
    let srv = StandInServer::start(ServerConfig::new(
        "127.0.0.1:0",
        SceneSetup {
            robot_name: "Panda".into(),
            chain: panda(PandaTool::HandTcp),
            initial_q: THESIS_Q0.to_vec(),
            dummies: vec![],
            dt: 0.001,
            ik_following: false,
            step_cost: Duration::from_millis(1),
            script: true,
        },
    ))
    .unwrap();
    let mut scene = FrankaScene::open(
        client(srv.endpoint()),
        "Panda",
        cps_robot::RobotModel::of_chain("Panda", panda(PandaTool::HandTcp)),
        0.001,
    )
    .unwrap();
    assert!(scene.has_script());
    let ready = cps_kinematics::robots::PANDA_READY;
    scene.reset(&ready).unwrap();
    let points: Vec<Vec<f64>> = (0..=400)
        .map(|k| {
            let mut q = ready.to_vec();
            q[0] += 0.2 * (1.0 - (std::f64::consts::PI * k as f64 / 400.0).cos()) / 2.0;
            q
        })
        .collect();
    let plan = Plan::new(0.01, points).unwrap();
    let stop = StopToken::new();
    let stopper = stop.clone();
    let t = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(300));
        stopper.stop();
    });
    let run = scene.run(&plan, &stop).unwrap();
    t.join().unwrap();
    assert_eq!(run.ending, Ending::Stopped);
    assert!(
        run.len() > 1 && run.len() < plan.points().len(),
        "{} of {} points",
        run.len(),
        plan.points().len()
    );
    assert!(run.time.windows(2).all(|w| w[1] > w[0]));
    // Nothing more is commanded: the robot holds where the recording ends.
    let held = Robot::joint_positions(&mut scene).unwrap();
    Stepped::step(&mut scene).unwrap();
    assert_eq!(Robot::joint_positions(&mut scene).unwrap(), held);
    let last = run.q.last().unwrap();
    assert!((held[0] - last[0]).abs() < 0.01, "{held:?} vs {last:?}");
}
