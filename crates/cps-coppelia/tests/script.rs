//! cps's scene script (`/Panda/cpsExecutor`) on the stand-in server: a trajectory executed
//! in a few calls records exactly what stepping records call by call; its wall time
//! follows the simulator's step cost; bad sequences, a stopped simulation, a missing
//! script and a simulation held by another client are clear errors.

use std::time::{Duration, Instant};

use cps_coppelia::codec::{self, Value};
use cps_coppelia::{Client, ClientConfig, FrankaScene, SceneSetup, ServerConfig, StandInServer};
use cps_kinematics::robots::{PandaTool, panda};
use cps_kinematics::{IkTarget, SerialChain};
use cps_robot::{ExecutionConfig, RobotModel, StopToken, execute};
use nalgebra::{Isometry3, Vector3};

const READY: [f64; 7] = cps_kinematics::robots::PANDA_READY;

fn model() -> SerialChain {
    panda(PandaTool::HandTcp).with_base(Isometry3::translation(0.5396, 0.02, 0.749))
}

fn server(script: bool, step_cost: Duration) -> StandInServer {
    let scene = SceneSetup {
        robot_name: "Panda".into(),
        chain: model(),
        initial_q: READY.to_vec(),
        dummies: vec![],
        dt: 0.01,
        ik_following: false,
        step_cost,
        script,
    };
    StandInServer::start(ServerConfig::new("127.0.0.1:0", scene)).unwrap()
}

fn client(endpoint: &str, timeout: Duration) -> Client {
    Client::connect(ClientConfig {
        endpoint: endpoint.into(),
        connect_timeout: timeout,
        call_timeout: timeout,
        ..ClientConfig::default()
    })
    .unwrap()
}

/// A circle of radius 5 cm in `n` samples around the ready pose's tool.
fn circle(n: usize) -> Vec<IkTarget> {
    let c = model().fk(&READY).unwrap().translation.vector;
    (0..=n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            IkTarget::Position(c + Vector3::new(0.05 * (a.cos() - 1.0), 0.05 * a.sin(), 0.0))
        })
        .collect()
}

fn run(scene: &mut FrankaScene, targets: &[IkTarget]) -> cps_robot::Recording {
    scene.reset(&READY).unwrap();
    execute(
        scene,
        &model(),
        targets,
        &ExecutionConfig::default(),
        &StopToken::new(),
    )
    .unwrap()
}

#[test]
fn the_script_records_bit_for_bit_what_stepping_records_in_a_few_calls() {
    let srv = server(true, Duration::ZERO);
    let mut scene = FrankaScene::open(
        client(srv.endpoint(), Duration::from_secs(5)),
        "Panda",
        RobotModel::of_chain("Panda", model()),
        0.01,
    )
    .unwrap();
    assert!(scene.has_script() && scene.runs_sequences());
    let targets = circle(300);
    let before = srv.requests();
    let batched = run(&mut scene, &targets);
    let batched_calls = srv.requests() - before;
    scene.without_script();
    assert!(!scene.runs_sequences());
    let before = srv.requests();
    let stepped = run(&mut scene, &targets);
    let stepped_calls = srv.requests() - before;
    assert_eq!(batched, stepped);
    assert!(batched.steps >= 301 && batched.max_position_error() < 1e-4);
    // Reset (stop, wait, seven joints, start, hold), the clock, the joints, then load,
    // release, one poll, hold: a few dozen calls against several per step.
    assert!(batched_calls <= 30, "{batched_calls} calls with the script");
    assert!(
        stepped_calls >= 3 * batched.steps as u64,
        "{stepped_calls} calls stepping"
    );
}

#[test]
fn a_scene_without_the_script_is_stepped_call_by_call() {
    let srv = server(false, Duration::ZERO);
    let mut scene = FrankaScene::open(
        client(srv.endpoint(), Duration::from_secs(5)),
        "Panda",
        RobotModel::of_chain("Panda", model()),
        0.01,
    )
    .unwrap();
    assert!(!scene.has_script());
    let rec = run(&mut scene, &circle(50));
    assert_eq!(rec.time.len(), 51);
    assert!(rec.max_position_error() < 1e-4);
}

/// The run's wall time is the steps' cost (the stand-in advances a free-running
/// simulation by the steps its wall time allows), and the client's polls, paced by the
/// progress they read, stay few: at most one every `STOP_POLL` (so a stop is seen within
/// it), and a handful besides.
#[test]
fn a_run_takes_the_simulators_time_and_a_few_polls() {
    let srv = server(true, Duration::from_millis(2));
    let mut scene = FrankaScene::open(
        client(srv.endpoint(), Duration::from_secs(5)),
        "Panda",
        RobotModel::of_chain("Panda", model()),
        0.01,
    )
    .unwrap();
    scene.reset(&READY).unwrap();
    let rows: Vec<Vec<f64>> = (0..300)
        .map(|k| {
            let mut q = READY.to_vec();
            q[0] = 1e-3 * k as f64;
            q
        })
        .collect();
    let before = srv.requests();
    let started = Instant::now();
    let rec = scene.run_joint_targets(&rows).unwrap();
    let took = started.elapsed();
    assert!(took >= Duration::from_millis(600), "{took:?}");
    let polls = (took.as_secs_f64() / cps_coppelia::STOP_POLL).ceil() as u64;
    assert!(
        srv.requests() - before <= 10 + polls,
        "{} calls in {took:?}",
        srv.requests() - before
    );
    assert_eq!(rec.q, rows);
    // One step of dt each (the clock may have moved between the start and the hold).
    for (k, t) in rec.time.iter().enumerate() {
        assert!((t - rec.time[0] - 0.01 * k as f64).abs() < 1e-12, "{t}");
    }
    let fk = model().fk(&rows[299]).unwrap();
    assert!((rec.tool[299].translation.vector - fk.translation.vector).norm() < 1e-12);
}

fn script_call(sim: &mut Client, name: &str, args: Vec<Value>) -> Result<Vec<Value>, String> {
    let h = sim.get_object("/Panda/cpsExecutor").unwrap();
    sim.call_script_function(name, h, args)
        .map_err(|e| e.to_string())
}

#[test]
fn bad_sequences_and_calls_are_refused_with_the_reason() {
    let srv = server(true, Duration::ZERO);
    let mut sim = client(srv.endpoint(), Duration::from_secs(5));
    // Simulation scripts run only while the simulation runs.
    let e = script_call(&mut sim, "cpsLoad", vec![codec::floats(&READY)]).unwrap_err();
    assert!(e.contains("only while the simulation runs"), "{e}");
    sim.start_simulation().unwrap();
    let e = script_call(&mut sim, "cpsResult", vec![]).unwrap_err();
    assert!(e.contains("no sequence loaded"), "{e}");
    let e = script_call(&mut sim, "cpsLoad", vec![codec::floats(&[0.0; 10])]).unwrap_err();
    assert!(e.contains("not whole rows of 7"), "{e}");
    let mut rows = [0.0; 14];
    rows[9] = f64::NAN;
    let e = script_call(&mut sim, "cpsLoad", vec![codec::floats(&rows)]).unwrap_err();
    assert!(e.contains("row 2, joint 3"), "{e}");
    let e = script_call(&mut sim, "cpsLoad", vec![codec::text("q")]).unwrap_err();
    assert!(e.contains("argument 1 must be a table"), "{e}");
    let e = script_call(
        &mut sim,
        "cpsLoad",
        vec![codec::floats(&vec![0.0; 7 * 50_001])],
    )
    .unwrap_err();
    assert!(e.contains("at most 50000"), "{e}");
    let e = script_call(&mut sim, "cpsRm", vec![]).unwrap_err();
    assert!(e.contains("cpsRm does not exist"), "{e}");
    let joint = sim.get_object("/Panda_joint1").unwrap();
    let e = sim
        .call_script_function("cpsResult", joint, vec![])
        .unwrap_err()
        .to_string();
    assert!(e.contains("Invalid script handle"), "{e}");
    // A good run, then stopping the simulation forgets it.
    assert_eq!(
        script_call(&mut sim, "cpsLoad", vec![codec::floats(&READY)]).unwrap()[0],
        codec::int(1)
    );
    sim.stop_simulation().unwrap();
    sim.start_simulation().unwrap();
    assert!(script_call(&mut sim, "cpsResult", vec![]).is_err());
}

/// Another client holding the simulation in stepping mode stops the run; the client
/// says so within its timeout instead of waiting for ever.
#[test]
fn a_simulation_held_by_another_client_is_a_timeout_naming_it() {
    let srv = server(true, Duration::ZERO);
    let mut scene = FrankaScene::open(
        client(srv.endpoint(), Duration::from_millis(500)),
        "Panda",
        RobotModel::of_chain("Panda", model()),
        0.01,
    )
    .unwrap();
    scene.reset(&READY).unwrap();
    let mut other = client(srv.endpoint(), Duration::from_secs(5));
    other.set_stepping(true).unwrap();
    let started = Instant::now();
    let e = scene
        .run_joint_targets(&vec![READY.to_vec(); 20])
        .unwrap_err()
        .to_string();
    assert!(
        started.elapsed() < Duration::from_secs(3),
        "{:?}",
        started.elapsed()
    );
    assert!(e.contains("stood still at step 0 of 20"), "{e}");
    // Once the other client lets go, the scene runs again.
    other.set_stepping(false).unwrap();
    scene.reset(&READY).unwrap();
    assert_eq!(
        scene
            .run_joint_targets(&vec![READY.to_vec(); 20])
            .unwrap()
            .q
            .len(),
        20
    );
}

/// The script shipped for CoppeliaSim (`configs/coppeliasim/cpsExecutor.lua`) keeps the
/// same protocol, run by a Lua interpreter against a mock `sim` module
/// (`tests/lua/harness.lua`). Without `lua5.4` the test is skipped ([`cps_testkit::skip`]):
/// a failure under CI, which installs Lua.
#[test]
fn the_coppeliasim_script_keeps_the_protocol() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let harness = dir.join("tests/lua/harness.lua");
    let script = dir.join("../../configs/coppeliasim/cpsExecutor.lua");
    let out = match std::process::Command::new("lua5.4")
        .arg(&harness)
        .arg(&script)
        .output()
    {
        Ok(out) => out,
        Err(e) => {
            cps_testkit::skip(&format!("no lua5.4 to run the scene script ({e})"));
            return;
        }
    };
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
