//! The fuzz targets: each takes bytes, feeds them to one of cps's parsers (and, when it
//! accepts them, one step further: building, rolling out, resuming), and must return
//! without a panic, an abort or a hang, whatever the bytes.

use std::path::{Path, PathBuf};
use std::time::Duration;

/// One parser under test.
pub struct Target {
    /// Its name on the command line.
    pub name: &'static str,
    /// Valid inputs to mutate.
    pub seeds: Vec<Vec<u8>>,
    /// Whether grammar-aware (text) mutations apply.
    pub text: bool,
    /// Feeds one input; true when the parser accepted it.
    pub run: fn(&[u8]) -> bool,
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn text(b: &[u8]) -> Option<&str> {
    std::str::from_utf8(b).ok()
}

fn experiment(b: &[u8]) -> bool {
    let Some(t) = text(b) else { return false };
    // The path only places relative scene files (next to the shipped experiments).
    let path = repo().join("experiments/fuzz.toml");
    cps_experiment::experiment::parse(&path, t, None, &cps_experiment::budget::Ceilings::default())
        .is_ok()
}

/// One step past a robot parser: FK and the Jacobian of what it accepted.
fn exercise(chain: &cps_kinematics::SerialChain) -> bool {
    let q = vec![0.1; chain.dof()];
    let _ = chain.fk(&q);
    let _ = chain.jacobian(&q);
    true
}

fn robot_toml(b: &[u8]) -> bool {
    let Some(t) = text(b) else { return false };
    match cps_movement::robot_file::parse_robot_toml(Path::new("fuzz.toml"), t, None) {
        Ok(m) => exercise(&m.chain),
        Err(_) => false,
    }
}

fn urdf(b: &[u8]) -> bool {
    let Some(t) = text(b) else { return false };
    match cps_kinematics::chain_from_urdf(t, None) {
        Ok(u) => exercise(&u.chain),
        Err(_) => false,
    }
}

fn scene(b: &[u8]) -> bool {
    let Some(t) = text(b) else { return false };
    cps_movement::scene::parse_scene(&repo().join("configs/scenes/fuzz.toml"), t).is_ok()
}

fn demo_csv(b: &[u8]) -> bool {
    let Some(t) = text(b) else { return false };
    let Ok((_, demo)) = cps_movement::movement::parse_demo(Path::new("fuzz.csv"), t) else {
        return false;
    };
    {
        // One step further: a small imitation of what was accepted.
        let duration = demo.duration();
        if duration.is_finite() && duration > 0.0 && demo.len() <= 20_000 {
            let config = cps_dmp::DmpConfig::new(5, duration, duration / 50.0);
            let _ = cps_dmp::imitate(
                &config,
                &[demo],
                cps_dmp::Regression::Ridge {
                    lambda: cps_dmp::Lambda::Auto,
                },
                cps_dmp::Combine::Mean,
            );
        }
    }
    true
}

fn model_json(b: &[u8]) -> bool {
    let Some(t) = text(b) else { return false };
    let Ok(m) = cps_dmp::DmpModel::from_json(t) else {
        return false;
    };
    match m.to_dmp() {
        Ok((dmp, w)) => {
            if dmp.n_samples() <= 100_000 {
                let _ = dmp.rollout(&w);
            }
            true
        }
        Err(_) => false,
    }
}

fn checkpoint_json(b: &[u8]) -> bool {
    let Some(t) = text(b) else { return false };
    let Ok(cp) = serde_json::from_str::<cps_cmaes::Checkpoint>(t) else {
        return false;
    };
    let Ok(mut es) = cps_cmaes::Cmaes::resume(&cp) else {
        return false;
    };
    {
        let n = es.population().len();
        if n <= 100_000 {
            let x = es.ask().to_vec();
            let dims = serde_json::from_str::<serde_json::Value>(t)
                .ok()
                .and_then(|v| v.get("mean").and_then(|m| m.as_array()).map(Vec::len))
                .unwrap_or(1);
            let lambda = x.len() / dims.max(1);
            let costs: Vec<f64> = (0..lambda).map(|i| i as f64).collect();
            let _ = es.tell(&costs);
        }
    }
    true
}

thread_local! {
    static HANDLER: std::cell::RefCell<cps_coppelia::RequestHandler> =
        std::cell::RefCell::new(cps_coppelia::RequestHandler::new(
            cps_coppelia::SceneSetup {
                robot_name: "Panda".into(),
                chain: cps_kinematics::robots::panda(cps_kinematics::robots::PandaTool::HandTcp),
                initial_q: cps_kinematics::robots::PANDA_READY.to_vec(),
                dummies: vec![("p0".into(), [0.75, 0.02, 1.87])],
                dt: 0.05,
                ik_following: true,
                step_cost: std::time::Duration::ZERO,
                script: true,
            },
            Duration::from_secs(60),
        ));
}

fn cbor_request(b: &[u8]) -> bool {
    // The codec alone, then the server's handler (state kept across inputs, as a server
    // keeps it across requests).
    let decoded = cps_coppelia::codec::decode(b).is_ok();
    HANDLER.with(|h| {
        let reply = h.borrow_mut().handle(b);
        let reply = cps_coppelia::codec::decode(&reply).expect("the reply is CBOR");
        decoded && cps_coppelia::codec::get(&reply, "err").is_none()
    })
}

/// A DDS sample as a ROS 2 peer could send it: every message cps reads, either byte
/// order, service replies with Cyclone's 16-byte header and without it (Fast DDS's), and
/// the graph's `ros_discovery_info` in both GID layouts; true if one of them reads it
/// whole.
fn ros2_sample(b: &[u8]) -> bool {
    use cps_ros2::discovery::ParticipantEntities;
    use cps_ros2_msg::cdr::{CdrError, CdrReader};
    use cps_ros2_msg::msg::{
        Action, CancelAnswer, Feedback, FollowJointTrajectory, GoalAnswer, GoalId, GoalResult,
        JointState, JointTrajectory, MarkerArray, Message,
    };
    type Decoder = fn(&mut CdrReader) -> Result<(), CdrError>;
    let replies: [Decoder; 4] = [
        |r| GoalAnswer::decode(r).map(drop),
        |r| GoalResult::decode(r, FollowJointTrajectory::decode_result).map(drop),
        |r| CancelAnswer::decode(r).map(drop),
        |r| {
            let _: GoalId = GoalId(r.array("goal_id")?);
            Feedback::decode(r).map(drop)
        },
    ];
    let mut any = false;
    for little in [true, false] {
        let r = || CdrReader::new(b, little);
        any |= JointState::decode(&mut r()).is_ok();
        any |= JointTrajectory::decode(&mut r()).is_ok();
        any |= MarkerArray::decode(&mut r()).is_ok();
        any |= ParticipantEntities::decode_any(b, little).is_ok();
        for decode in replies {
            any |= decode(&mut r()).is_ok();
            let mut with_header = r();
            any |= with_header.u64("client").is_ok()
                && with_header.i64("sequence").is_ok()
                && decode(&mut with_header).is_ok();
        }
    }
    any
}

/// A motion-capture take as a file could hold it: C3D (and, as text, a Motive CSV
/// export); true if it reads. A take that reads is also made a demonstration of its first
/// three markers (refusals are fine, panics are not).
fn c3d_take(b: &[u8]) -> bool {
    take_of(cps_mocap::c3d::parse(b, "fuzz.c3d"))
}

fn motive_csv(b: &[u8]) -> bool {
    take_of(cps_mocap::motive::parse(b, "fuzz.csv"))
}

fn take_of(t: Result<cps_mocap::Take, cps_mocap::MocapError>) -> bool {
    let Ok(take) = t else { return false };
    if take.markers() >= 3 && take.frames <= 20_000 {
        let settings = cps_mocap::demo::Settings {
            markers: take.labels[..3].to_vec(),
            ..cps_mocap::demo::Settings::default()
        };
        let _ = cps_mocap::demo::demonstrate(&take, &settings);
    }
    true
}

fn take_seeds() -> Vec<Vec<u8>> {
    let mut spec = cps_mocap::synthetic::Spec::tool(4);
    spec.frames = 40;
    spec.gaps = vec![(1, 10, 3)];
    let (take, _) = cps_mocap::synthetic::take(&spec);
    let mut out = vec![
        cps_mocap::c3d::write(&take, cps_mocap::c3d::Format::Float).expect("a take"),
        cps_mocap::c3d::write(&take, cps_mocap::c3d::Format::Integer { scale: 0.5 })
            .expect("a take"),
    ];
    out.push(file("experiments/demos/takes/pour_2.c3d"));
    out
}

fn motive_seeds() -> Vec<Vec<u8>> {
    let mut text = String::from(
        "Format Version,1.23,Take Name,t,Capture Frame Rate,120.000000,Export Frame Rate,120.000000,Rotation Type,Quaternion,Length Units,Millimeters\n\n,Type,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker\n,Name,T,T,T,T,T,T,T,a,a,a,b,b,b,c,c,c\n,ID,1,1,1,1,1,1,1,2,2,2,3,3,3,4,4,4\n,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Position,Position,Position,Position,Position,Position,Position,Position,Position\nFrame,Time (Seconds),X,Y,Z,W,X,Y,Z,X,Y,Z,X,Y,Z,X,Y,Z\n",
    );
    for f in 0..30 {
        let x = f as f64;
        text.push_str(&format!(
            "{f},{:.6},0,0,0,1,{x},1,2,{x},0,0,{},100,0,{x},0,{},\n",
            x / 120.0,
            x + 100.0,
            if f == 7 { String::new() } else { "90".into() }
        ));
    }
    vec![text.into_bytes()]
}

fn ros2_seeds() -> Vec<Vec<u8>> {
    use cps_ros2_msg::msg::{JointState, JointTrajectory, JointTrajectoryPoint, Message, Time};
    let names: Vec<String> = (1..=7).map(|i| format!("panda_joint{i}")).collect();
    let state = JointState {
        name: names.clone(),
        position: vec![0.1; 7],
        velocity: vec![0.0; 7],
        ..JointState::default()
    };
    let trajectory = JointTrajectory {
        joint_names: names,
        points: (0..3)
            .map(|k| JointTrajectoryPoint {
                positions: vec![k as f64; 7],
                velocities: vec![0.0; 7],
                time_from_start: Time::from_secs(k as f64),
                ..JointTrajectoryPoint::default()
            })
            .collect(),
        ..JointTrajectory::default()
    };
    // The bodies, without the encapsulation header (as DDS hands them over).
    vec![
        state.to_cdr()[4..].to_vec(),
        trajectory.to_cdr()[4..].to_vec(),
    ]
}

fn file(rel: &str) -> Vec<u8> {
    std::fs::read(repo().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn cbor_seeds() -> Vec<Vec<u8>> {
    use cps_coppelia::codec::{self, Value};
    let req = |func: &str, args: Vec<Value>| {
        codec::encode(&codec::map([
            ("func", codec::text(func)),
            ("args", Value::Array(args)),
            ("uuid", codec::text("fuzz")),
            ("ver", codec::int(2)),
        ]))
    };
    vec![
        req("zmqRemoteApi.require", vec![codec::text("sim")]),
        req("sim.getObject", vec![codec::text("/Panda_joint3")]),
        req(
            "sim.setJointPosition",
            vec![codec::int(19), Value::Float(0.3)],
        ),
        req(
            "sim.setObjectMatrix",
            vec![
                codec::int(100),
                codec::floats(&[1.0, 0.0, 0.0, 0.1, 0.0, 1.0, 0.0, 0.2, 0.0, 0.0, 1.0, 0.3]),
                codec::int(-1),
            ],
        ),
        req(
            "sim.setObjectPose",
            vec![
                codec::int(25),
                codec::floats(&[0.1, 0.2, 0.3, 0.0, 0.0, 0.0, 1.0]),
                codec::int(-1),
            ],
        ),
        req(
            "sim.getObjectPosition",
            vec![codec::int(24), codec::int(16)],
        ),
        req("sim.createDummy", vec![Value::Float(0.01)]),
        req(
            "sim.removeObjects",
            vec![Value::Array(vec![codec::int(100)])],
        ),
        req("sim.setStepping", vec![Value::Bool(true)]),
        req("sim.startSimulation", vec![]),
        req("sim.step", vec![]),
        req("_*executed*_", vec![]),
        req(
            "sim.testCB",
            vec![
                codec::int(1),
                codec::text("cb@func"),
                codec::int(2),
                codec::int(3),
            ],
        ),
        req("sim.stopSimulation", vec![]),
    ]
}

fn checkpoint_seeds() -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for (n, separable, bounds) in [(3usize, false, false), (5, true, false), (4, false, true)] {
        let mut config = cps_cmaes::CmaesConfig::new(0.5, 7);
        config.separable = separable;
        if bounds {
            config.bounds = cps_cmaes::Bounds::new(vec![-1.0; n], vec![1.0; n]).ok();
        }
        let mut es = cps_cmaes::Cmaes::new(&config, &vec![0.2; n]).expect("valid");
        for _ in 0..3 {
            let x = es.ask().to_vec();
            let costs: Vec<f64> = x.chunks(n).map(|c| c.iter().map(|v| v * v).sum()).collect();
            es.tell(&costs).expect("tell");
        }
        out.push(serde_json::to_vec_pretty(&es.checkpoint()).expect("a checkpoint serialises"));
    }
    out
}

fn model_seeds() -> Vec<Vec<u8>> {
    let t: Vec<f64> = (0..101).map(|k| k as f64 * 0.02).collect();
    let rows: Vec<Vec<f64>> = t
        .iter()
        .map(|&s| vec![s.sin(), (2.0 * s).cos(), s * s])
        .collect();
    let demo = cps_dmp::Demonstration::new(t, &rows).expect("valid demonstration");
    let config = cps_dmp::DmpConfig::new(10, 2.0, 0.02);
    let fit = cps_dmp::imitate(
        &config,
        &[demo],
        cps_dmp::Regression::Ridge {
            lambda: cps_dmp::Lambda::Fixed(1e-9),
        },
        cps_dmp::Combine::Mean,
    )
    .expect("imitation");
    let model = cps_dmp::DmpModel::new(
        &fit.dmp,
        &fit.weights,
        vec!["a".into(), "b".into(), "c".into()],
    );
    vec![model.to_json().into_bytes()]
}

/// Every target with its seeds (the shipped files where there are some).
pub fn all() -> Vec<Target> {
    let shipped = |names: &[&str]| names.iter().map(|n| file(n)).collect::<Vec<_>>();
    let demo = {
        // The shipped demonstration's first 200 lines keep each input small.
        let full = String::from_utf8(file("experiments/demos/table3_min_jerk.csv")).expect("UTF-8");
        full.lines()
            .take(200)
            .collect::<Vec<_>>()
            .join("\n")
            .into_bytes()
    };
    vec![
        Target {
            name: "experiment",
            seeds: shipped(&[
                "experiments/viapoint.toml",
                "experiments/imitation.toml",
                "experiments/scaling.toml",
                "experiments/viapoint_joint.toml",
                "experiments/viapoint_energy.toml",
                "experiments/viapoint_pose.toml",
                "experiments/viapoint_executed.toml",
            ]),
            text: true,
            run: experiment,
        },
        Target {
            name: "robot-toml",
            seeds: shipped(&["configs/robots/panda.toml", "configs/robots/ur3.toml"]),
            text: true,
            run: robot_toml,
        },
        Target {
            name: "urdf",
            seeds: shipped(&["configs/robots/panda.urdf"]),
            text: true,
            run: urdf,
        },
        Target {
            name: "scene",
            seeds: shipped(&["configs/scenes/thesis.toml"]),
            text: true,
            run: scene,
        },
        Target {
            name: "demo-csv",
            seeds: vec![demo],
            text: true,
            run: demo_csv,
        },
        Target {
            name: "model-json",
            seeds: model_seeds(),
            text: true,
            run: model_json,
        },
        Target {
            name: "checkpoint-json",
            seeds: checkpoint_seeds(),
            text: true,
            run: checkpoint_json,
        },
        Target {
            name: "cbor-request",
            seeds: cbor_seeds(),
            text: false,
            run: cbor_request,
        },
        Target {
            name: "ros2-sample",
            seeds: ros2_seeds(),
            text: false,
            run: ros2_sample,
        },
        Target {
            name: "c3d",
            seeds: take_seeds(),
            text: false,
            run: c3d_take,
        },
        Target {
            name: "motive-csv",
            seeds: motive_seeds(),
            text: true,
            run: motive_csv,
        },
    ]
}
