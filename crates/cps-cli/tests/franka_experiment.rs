//! `[robot] backend = "franka"`: the shipped experiment learned on the FR3's model and
//! executed on franky-sim (a MuJoCo FR3 behind the real protocol); a plan that leaves the
//! FR3's range refused before the robot moves; bad robot sections named.

mod common;
use cps_testkit::franky_sim as sim;

use common::{cli, json, run_quiet as run, write};
use sim::FrankySim;

const SHIPPED: &str = include_str!("../../../experiments/franka/viapoint_joint.toml");

/// The shipped Franka experiment pointed at `host`, with a short search (the warm start
/// is already within a millimetre) and realtime scheduling not required.
fn on(host: &str) -> String {
    let text = SHIPPED
        .replace(
            "host = \"172.16.0.2\"",
            &format!("host = \"{host}\"\nrealtime = \"ignore\""),
        )
        .replace("generations = 15 ", "generations = 5  ");
    assert!(text.contains(host) && text.contains("generations = 5  "));
    text
}

fn state_q(host: &str) -> Vec<f64> {
    let o = cli(&["franka", "state", "--host", host, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    serde_json::from_value(v["q"].clone()).unwrap()
}

/// The learned movement runs on the simulated FR3: every row recorded, and the measured
/// tool passes each via point and reaches the goal. franky-sim's joint PD damps the
/// absolute velocity (kv/kp = 0.1 s), so the arm runs about 100 ms behind its commands: at
/// the via-point times the tool is centimetres short, but its path goes through every via
/// point within millimetres.
#[test]
fn the_shipped_experiment_is_executed_on_the_simulated_fr3() {
    let Some(sim) = FrankySim::start("127.0.0.63") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "fr3.toml", &on(&sim.host));
    let out = dir.path().join("out");
    let (o, err) = run(&file, &out);
    assert!(o.status.success(), "{err}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["complete"], true, "{s}");
    assert!(
        s["backend"]
            .as_str()
            .unwrap()
            .starts_with("franka (fr3 at 127.0.0.63"),
        "{s}"
    );
    // What was sent: every stream within the limits, the loop's timing.
    let backend = s["backend"].as_str().unwrap();
    assert!(
        backend.contains("motions sent at 1 kHz, at most") && backend.contains("ticks missed"),
        "{backend}"
    );
    let e = &s["execution"];
    assert_eq!(e["samples"], 1001, "{e}");
    assert_eq!(e["within_position_limits"], true, "{e}");
    // The recording: the measured tool every 10 ms.
    let text = std::fs::read_to_string(out.join("recording.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (x, y, z) = (col("tool_x"), col("tool_y"), col("tool_z"));
    let tool: Vec<[f64; 3]> = lines
        .map(|l| {
            let c: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            [c[x], c[y], c[z]]
        })
        .collect();
    assert_eq!(tool.len(), 1001);
    let points = [
        [0.78, 0.60, 1.70],
        [1.12, 0.37, 1.45],
        [1.15, -0.15, 1.20],
        [0.90, -0.53, 1.20],
        [0.55, -0.57, 1.45],
    ];
    for p in points {
        let closest = tool
            .iter()
            .map(|t| ((t[0] - p[0]).powi(2) + (t[1] - p[1]).powi(2) + (t[2] - p[2]).powi(2)).sqrt())
            .fold(f64::INFINITY, f64::min);
        assert!(closest < 0.01, "the tool passes {p:?} at {closest} m");
    }
    // The robot stays where the movement ended: at the goal configuration, within the
    // simulator's lag at the end of the motion.
    let q = state_q(&sim.host);
    let goal: Vec<f64> = serde_json::from_value(s["way_configurations_rad"][5].clone()).unwrap();
    let far = q
        .iter()
        .zip(&goal)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        far < 0.02,
        "the robot ended {far} rad from the goal configuration"
    );
}

/// The thesis's Panda scene planned and checked against the FR3: its start has joint 4
/// beyond the FR3's range, so nothing is sent, the robot stays, the learned result is kept
/// with the reason, and the exit code is 1.
#[test]
fn a_plan_outside_the_fr3s_range_is_refused_before_the_robot_moves() {
    let Some(sim) = FrankySim::start("127.0.0.64") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let text = on(&sim.host).replace(
        "scene = \"fr3\"           # the thesis's scene with an FR3 (built in)",
        "scene = \"thesis\"\narm = \"fr3\"",
    );
    assert!(text.contains("scene = \"thesis\""));
    let file = write(dir.path(), "panda.toml", &text);
    let before = state_q(&sim.host);
    let out = dir.path().join("out");
    let (o, err) = run(&file, &out);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("refused before sending anything: joint 4")
            && err.contains("beyond the limit -0.151800 rad"),
        "{err}"
    );
    let s = json(&out.join("summary.json"));
    assert_eq!(s["complete"], false);
    assert!(s["failure"].as_str().unwrap().contains("joint 4"), "{s}");
    let after = state_q(&sim.host);
    let moved = before
        .iter()
        .zip(&after)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(moved < 1e-3, "the robot moved by {moved} rad");
}

/// Bad `[robot]` sections for the Franka, each named with its place, exit 2, nothing
/// written; no robot needed.
#[test]
fn bad_franka_sections_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let refused = |name: &str, toml: String, expected: &str| {
        common::refused(dir.path(), name, &toml, expected);
    };
    let host_line = "host = \"172.16.0.2\"     # the robot's address (`ip` or `ip:port`)";
    assert!(SHIPPED.contains(host_line));
    refused(
        "no_host",
        SHIPPED.replace(host_line, ""),
        "backend = \"franka\" needs `host`, the robot's address",
    );
    refused(
        "url",
        SHIPPED.replace(host_line, "host = \"tcp://10.0.0.2:1337\""),
        "[robot] `host` must be the robot's address, `ip` or `ip:port`",
    );
    refused(
        "pool",
        SHIPPED.replace(host_line, "hosts = [\"10.0.0.2\", \"10.0.0.3\"]"),
        "`hosts` (a pool of robots) is read only by kind = \"viapoint_executed\"",
    );
    refused(
        "arm",
        SHIPPED.replace(host_line, "host = \"10.0.0.2\"\narm = \"ur5\""),
        "[robot] `arm` must be fr3 or panda (got `ur5`)",
    );
    refused(
        "dt",
        SHIPPED.replace(
            "dt = 0.01               # the movement",
            "dt = 0.0125 # the movement",
        ),
        "`dt` must be a whole number of milliseconds",
    );
    refused(
        "endpoint",
        SHIPPED.replace(
            host_line,
            "host = \"10.0.0.2\"\nendpoint = \"tcp://127.0.0.1:23000\"",
        ),
        "[robot] `endpoint` is read only with backend = \"coppelia\"",
    );
    let kinematic = SHIPPED.replace("backend = \"franka\"", "backend = \"kinematic\"");
    refused(
        "host_on_kinematic",
        kinematic,
        "[robot] `host` is read only with backend = \"franka\"",
    );
    // A robot that is not there: named, within the connect timeout, before any learning.
    let started = std::time::Instant::now();
    let file = write(
        dir.path(),
        "absent.toml",
        &SHIPPED.replace(host_line, "host = \"127.0.0.65\""),
    );
    let out = dir.path().join("absent");
    let (o, err) = run(&file, &out);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("127.0.0.65"), "{err}");
    assert!(started.elapsed().as_secs() < 30, "{:?}", started.elapsed());
}

const SHELF: &str = include_str!("../../../experiments/franka/shelf.toml");

/// The shipped shelf experiment: learned to keep 2.5 cm from the shelf (the warm start,
/// blind to it, goes through it), executed on franky-sim with the same shelf in its MuJoCo
/// world: no contact between the arm and the shelf in MuJoCo's contact list at any step,
/// and the measured tool's path through every via point within 3 mm.
#[test]
fn the_shelf_experiment_keeps_clear_of_the_shelf_on_the_simulated_fr3() {
    // The scene's world frame is the base's moved by the scene's placement.
    let base = [0.42244, 0.02, 0.74177];
    let shelf = [
        1.26 - base[0],
        0.07 - base[1],
        1.30 - base[2],
        0.16,
        0.12,
        0.12,
    ];
    assert!(SHELF.contains("xyz = [1.26, 0.07, 1.30]\nsize = [0.16, 0.12, 0.12]"));
    let Some(sim) = FrankySim::start_with(
        "127.0.0.65",
        sim::SimOptions {
            shelf: Some(shelf),
            truth: true,
            ..Default::default()
        },
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let text = SHELF.replace(
        "host = \"172.16.0.2\"",
        &format!("host = \"{}\"\nrealtime = \"ignore\"", sim.host),
    );
    assert!(text.contains(&sim.host));
    let file = write(dir.path(), "shelf.toml", &text);
    let out = dir.path().join("out");
    let (o, err) = run(&file, &out);
    assert!(o.status.success(), "{err}");
    let s = json(&out.join("summary.json"));
    let c = &s["clearance"];
    assert_eq!(c["kept_m"], 0.025, "{c}");
    // Blind to the shelf, the warm start goes into it; learned, the arm keeps 2 cm.
    assert_eq!(c["warm_start_closest"]["second"], "shelf", "{c}");
    assert!(
        c["warm_start_closest"]["distance_m"].as_f64().unwrap() < 0.0,
        "{c}"
    );
    assert!(
        c["closest_to_world"]["distance_m"].as_f64().unwrap() >= 0.02,
        "{c}"
    );
    // The arm keeps its own shapes (link5–link7 among them, which franka_description's
    // SRDF leaves out) its 1 cm apart.
    assert_eq!(c["kept_self_m"], 0.01, "{c}");
    assert!(c["closest"]["distance_m"].as_f64().unwrap() >= 0.009, "{c}");
    let via = s["via_errors_m"].as_array().unwrap();
    assert!(via.iter().all(|e| e.as_f64().unwrap() < 1e-3), "{via:?}");
    // MuJoCo: no step with a contact between the shelf and the robot.
    let (steps, geoms) = sim.box_contacts();
    assert_eq!(steps, 0, "the arm touched the shelf: {geoms:?}");
    // MuJoCo's tool passes every via point within 3 mm.
    let truth = sim.truth();
    assert!(truth.len() > 10_000, "{} steps", truth.len());
    let world = |t: &sim::Truth| [t.tcp[0] + base[0], t.tcp[1] + base[1], t.tcp[2] + base[2]];
    for p in [
        [0.78, 0.60, 1.70],
        [1.12, 0.37, 1.45],
        [1.15, -0.15, 1.20],
        [0.90, -0.53, 1.20],
    ] {
        let closest = truth
            .iter()
            .map(|t| {
                let w = world(t);
                ((w[0] - p[0]).powi(2) + (w[1] - p[1]).powi(2) + (w[2] - p[2]).powi(2)).sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        println!("MuJoCo's tool passes {p:?} at {:.2} mm", closest * 1e3);
        assert!(closest < 0.003, "MuJoCo's tool passes {p:?} at {closest} m");
    }
}
