//! `cps-cli franka` end to end against franky-sim (a MuJoCo FR3 behind the real protocol):
//! state, an execution recorded, refusals before anything moves, bad input, a host that is
//! not there, Ctrl-C mid-motion, a recording without motion, a guided demonstration
//! imitated and replayed; a scene's obstacle in the way refused, with MuJoCo's contact
//! list as the judge.

mod common;
use cps_testkit::franky_sim as sim;

use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

use common::{cli, json, state_q};
use sim::FrankySim;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A 3 s joint trajectory from the simulator's start pose, its joint 1 by `swing` rad and
/// back, sampled every 10 ms (so cps resamples it).
fn trajectory(dir: &Path, from: &[f64], swing: f64) -> String {
    let mut text = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
    for k in 0..=300 {
        let t = k as f64 * 0.01;
        let s = 0.5 - 0.5 * (std::f64::consts::TAU * t / 3.0).cos();
        let mut q = from.to_vec();
        q[0] += swing * s;
        q[3] += 0.3 * s;
        let cells: Vec<String> = q.iter().map(|v| format!("{v:.9}")).collect();
        text.push_str(&format!("{t:.2},{}\n", cells.join(",")));
    }
    let p = dir.join("traj.csv");
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

#[test]
fn execute_records_every_tick_and_reports_timing_tracking_and_usage() {
    let Some(sim) = FrankySim::start("127.0.0.41") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let q = state_q(&sim.host);
    assert_eq!(q.len(), 7);
    let file = trajectory(dir.path(), &q, 0.5);
    let rec = dir.path().join("rec.csv");
    let o = cli(&[
        "franka",
        "execute",
        &file,
        "--host",
        &sim.host,
        "--record",
        rec.to_str().unwrap(),
        "--realtime",
        "ignore",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["complete"], true);
    assert_eq!(report["trajectory"], "resampled at 1 kHz");
    for k in ["velocity", "acceleration", "jerk"] {
        for u in report["limit_usage_percent"][k].as_array().unwrap() {
            assert!(u.as_f64().unwrap() <= 100.0, "{k}: {u}");
        }
    }
    assert!(
        report["limit_usage_percent"]["velocity"][0]
            .as_f64()
            .unwrap()
            > 5.0
    );
    assert!(report["timing"]["p99_us"].as_f64().unwrap() > 0.0);
    // The recording: the promised columns, one row per tick of the 3 s motion.
    let text = std::fs::read_to_string(&rec).unwrap();
    let mut lines = text.lines();
    let mut header = vec!["t".to_string()];
    for g in ["q", "dq", "tau", "q_d"] {
        header.extend((1..=7).map(|j| format!("{g}{j}")));
    }
    header.extend(["tool_x", "tool_y", "tool_z"].map(String::from));
    assert_eq!(lines.next().unwrap(), header.join(","));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    // (the file starts at the measured position, a hair from the desired one the robot
    // holds: a few milliseconds of approach blend the two; `approach_s` is the robot time
    // the file's first command was due, after them and the motion's opening.)
    let approach = (report["approach_s"].as_f64().unwrap() * 1e3).round() as usize;
    assert!(approach < 50, "{approach} ms of approach");
    // One row per state cps answered, stamped with the robot's time: the rows span the
    // motion's ticks, and a tick without a row is one the robot extrapolated (its state
    // missed, or superseded before cps read it, or answered late: counted in the report).
    // On a quiet machine that is none; on a loaded one franky-sim bunches its states.
    let ticks = ((rows.last().unwrap()[0] - rows[0][0]) * 1e3).round() as usize + 1;
    assert!(
        (3001 + approach..=3004 + approach).contains(&ticks),
        "{ticks} ticks ({} rows)",
        rows.len()
    );
    let extrapolated = report["timing"]["extrapolated_cycles"].as_u64().unwrap() as usize;
    assert!(
        rows.len() <= ticks && ticks - rows.len() <= extrapolated,
        "{} rows over {ticks} ticks, {extrapolated} cycles extrapolated",
        rows.len()
    );
    assert_eq!(report["samples"], rows.len());
    // Commanded joint 1 peaks at the swing half way; the measured one follows within 0.05.
    let start = report["approach_s"].as_f64().unwrap();
    let mid = rows.iter().find(|r| r[0] >= start + 1.5 - 1e-9).unwrap();
    assert!((mid[22] - (q[0] + 0.5)).abs() < 1e-3, "q_d1 {}", mid[22]);
    assert!(
        (mid[1] - mid[22]).abs() < 0.05,
        "q1 {} vs q_d1 {}",
        mid[1],
        mid[22]
    );
    let side = json(&dir.path().join("rec.report.json"));
    assert_eq!(side["complete"], true);
    // Again, in words. franky-sim holds where its PD lagged when a motion ends (its q_d
    // becomes the measured q, ~10 mrad from the last command), so the start needs an
    // approach now.
    let o = cli(&[
        "franka",
        "execute",
        &file,
        "--host",
        &sim.host,
        "--record",
        rec.to_str().unwrap(),
        "--realtime",
        "ignore",
        "--force",
        "--approach",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("the motion finished") && out.contains("p99"),
        "{out}"
    );
}

#[test]
fn refusals_come_before_anything_moves() {
    let Some(sim) = FrankySim::start("127.0.0.42") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let q = state_q(&sim.host);
    let rec = dir.path().join("rec.csv");
    let run = |file: &str, extra: &[&str]| {
        let mut args = vec![
            "franka",
            "execute",
            file,
            "--host",
            &sim.host,
            "--record",
            rec.to_str().unwrap(),
        ];
        args.extend_from_slice(&["--realtime", "ignore"]);
        args.extend_from_slice(extra);
        cli(&args)
    };
    // Not where the robot is: refused (1), naming the joint, with the way out.
    let mut far = q.clone();
    far[1] += 0.3;
    let file = trajectory(dir.path(), &far, 0.2);
    let o = run(&file, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("at joint 2") && stderr(&o).contains("--approach"),
        "{}",
        stderr(&o)
    );
    // Too fast for the FR3 (a 1.5 rad swing and back in 3 s): refused naming joint, time
    // and quantity; with --retime it is slowed to the limits instead (checked only: the
    // robot is elsewhere, so it is refused for its start).
    let fast = trajectory(dir.path(), &q, 3.0);
    let o = run(&fast, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("joint 1 at t =") && stderr(&o).contains("beyond the limit"),
        "{}",
        stderr(&o)
    );
    assert!(!rec.exists(), "nothing recorded when nothing moved");
    let after = state_q(&sim.host);
    assert!(
        q.iter().zip(&after).all(|(a, b)| (a - b).abs() < 1e-3),
        "the robot did not move"
    );
    // Planned for the Panda (its joint 4 reaches -0.0698): outside the FR3's range.
    let mut panda = q.clone();
    panda[3] = -0.0698;
    let file = trajectory(dir.path(), &panda, 0.1);
    let o = run(&file, &["--approach"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("leaves the fr3's joint range"),
        "{}",
        stderr(&o)
    );
    // Bad input: exit 2.
    let nan = dir.path().join("nan.csv");
    std::fs::write(
        &nan,
        "t,q1,q2,q3,q4,q5,q6,q7\n0,0,0,0,-1.5,0,1.5,0\n0.1,0,NaN,0,-1.5,0,1.5,0\n",
    )
    .unwrap();
    let o = run(nan.to_str().unwrap(), &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let six = dir.path().join("six.csv");
    std::fs::write(&six, "t,q1,q2,q3,q4,q5,q6\n0,0,0,0,-1.5,0,1.5\n").unwrap();
    let o = run(six.to_str().unwrap(), &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("7-joint robot"), "{}", stderr(&o));
    let o = run(&file, &["--arm", "ur5"]);
    assert_eq!(o.status.code(), Some(2));
    let o = run(&file, &["--realtime", "sometimes"]);
    assert_eq!(o.status.code(), Some(2));
}

/// franky-sim's start (franky_sim.constants.DEFAULT_INITIAL_JOINT_POS).
const FRANKY_START: [f64; 7] = [0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785];

/// `franka execute --scene`: a swing whose hand passes through a post of the scene is
/// refused before the robot moves, the hand and the post named; the same post stands in
/// franky-sim's MuJoCo world, whose contact list says the swing would have hit it (sent
/// without the scene, it does) and that the refused one never touched it; the swing the
/// other way, clear of the post, runs with the scene.
#[test]
fn with_a_scene_a_swing_into_its_obstacle_is_refused_before_the_robot_moves() {
    // The post stands where the hand's centre point is at the swing's peak (joint 1 by
    // 0.5 rad, joint 4 by 0.3, `trajectory`), 30 cm tall.
    let mut peak = FRANKY_START;
    peak[0] += 0.5;
    peak[3] += 0.3;
    let (at, size) = (common::hand_at("fr3", &peak), [0.05, 0.05, 0.3]);
    let Some(sim) = FrankySim::start_with(
        "127.0.0.60",
        sim::SimOptions {
            shelf: Some([at[0], at[1], at[2], size[0], size[1], size[2]]),
            ..Default::default()
        },
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let q0 = state_q(&sim.host);
    assert!(
        q0.iter()
            .zip(FRANKY_START)
            .all(|(a, b)| (a - b).abs() < 0.02),
        "franky-sim starts elsewhere: {q0:?}"
    );
    let scene = common::post_scene(dir.path(), "scene", "fr3", &FRANKY_START, at, size);
    let scene = scene.to_str().unwrap();
    let (into, away) = (dir.path().join("into"), dir.path().join("away"));
    std::fs::create_dir_all(&into).unwrap();
    std::fs::create_dir_all(&away).unwrap();
    let into = trajectory(&into, &q0, 0.5);
    let away = trajectory(&away, &q0, -0.5);
    let rec = dir.path().join("rec.csv");
    let execute = |file: &str, extra: &[&str]| {
        let mut a = vec![
            "franka",
            "execute",
            file,
            "--host",
            &sim.host,
            "--record",
            rec.to_str().unwrap(),
            "--realtime",
            "ignore",
            "--force",
            "--approach",
        ];
        a.extend_from_slice(extra);
        cli(&a)
    };
    let o = execute(&into, &["--scene", scene]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("refused before sending anything") && err.contains("`post`"),
        "{err}"
    );
    assert!(err.contains("`fr3_"), "{err}");
    let still = state_q(&sim.host);
    assert!(
        still.iter().zip(&q0).all(|(a, b)| (a - b).abs() < 1e-3),
        "the robot moved: {q0:?} -> {still:?}"
    );
    assert_eq!(
        sim.box_contacts().0,
        0,
        "the refused swing touched the post"
    );
    // The other way, clear of the post: executed, checked against the same scene.
    let o = execute(&away, &["--scene", scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (steps, geoms) = sim.box_contacts();
    assert_eq!(steps, 0, "the clear swing touched the post: {geoms:?}");
    // Without the scene the guard knows no post, and MuJoCo says the swing hits it.
    // (How that run ends is franky-sim's: the arm pushing on a fixed box.)
    execute(&into, &[]);
    let (steps, geoms) = sim.box_contacts();
    assert!(
        steps > 0,
        "MuJoCo saw no contact: the post is not in the way"
    );
    assert!(
        geoms
            .iter()
            .any(|g| g.contains("hand") || g.contains("finger") || g.contains("link")),
        "{geoms:?}"
    );
    // A scene for another arm is named.
    let panda = std::fs::read_to_string(scene)
        .unwrap()
        .replace("\"fr3\"", "\"panda\"");
    std::fs::write(scene, panda).unwrap();
    let o = execute(&away, &["--scene", scene]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("the scene's robot is `panda`, not the fr3"),
        "{err}"
    );
}

#[test]
fn a_host_without_a_robot_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let o = cli(&["franka", "state", "--host", "127.0.0.49"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("127.0.0.49: cannot reach the robot"),
        "{}",
        stderr(&o)
    );
    let rec = dir.path().join("rec.csv");
    let file = trajectory(dir.path(), &[0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785], 0.1);
    let o = cli(&[
        "franka",
        "execute",
        &file,
        "--host",
        "127.0.0.49",
        "--record",
        rec.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!rec.exists());
}

#[test]
fn ctrl_c_brakes_to_rest_and_keeps_the_recording_marked_incomplete() {
    let Some(sim) = FrankySim::start("127.0.0.43") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let q = state_q(&sim.host);
    let file = trajectory(dir.path(), &q, 0.8);
    let rec = dir.path().join("rec.csv");
    let child = Command::new(env!("CARGO_BIN_EXE_cps-cli"))
        .args([
            "franka",
            "execute",
            &file,
            "--host",
            &sim.host,
            "--record",
            rec.to_str().unwrap(),
            "--realtime",
            "ignore",
            "--json",
        ])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["complete"], false);
    assert!(
        report["ending"]
            .as_str()
            .unwrap()
            .contains("braked to rest"),
        "{report}"
    );
    assert!(report["brake_ticks"].as_u64().unwrap() > 0);
    let side = json(&dir.path().join("rec.report.json"));
    assert_eq!(side["complete"], false);
    let rows = std::fs::read_to_string(&rec).unwrap().lines().count() - 1;
    assert!(rows > 200 && rows < 3000, "{rows} rows");
    assert_eq!(report["samples"], rows);
}

#[test]
fn record_writes_the_state_at_the_robots_rate() {
    let Some(sim) = FrankySim::start("127.0.0.44") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("still.csv");
    let o = cli(&[
        "franka",
        "record",
        "--host",
        &sim.host,
        "--duration",
        "0.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = text.lines().skip(1).collect();
    // One row per robot tick (the message ids count milliseconds), t from 0 to 0.5 s.
    assert!((400..=501).contains(&rows.len()), "{} rows", rows.len());
    let last_t: f64 = rows
        .last()
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((0.49..=0.5).contains(&last_t), "{last_t}");
    let o = cli(&[
        "franka",
        "record",
        "--host",
        &sim.host,
        "--duration",
        "0",
        "--out",
        out.to_str().unwrap(),
        "--force",
    ]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn the_gripper_from_the_command_line() {
    let Some(sim) = FrankySim::start("127.0.0.45") else {
        return;
    };
    let o = cli(&["franka", "gripper", "home", "--host", &sim.host]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = cli(&[
        "franka", "gripper", "move", "0.03", "--host", &sim.host, "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["width"].as_f64().unwrap() - 0.03).abs() < 5e-3, "{v}");
    let o = cli(&[
        "franka", "gripper", "grasp", "0.01", "--force", "500", "--host", &sim.host,
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--force: 500 N is not in (0, 140] N"),
        "{}",
        stderr(&o)
    );
    let o = cli(&["franka", "gripper", "move", "--host", &sim.host]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("give the width"), "{}", stderr(&o));
    let o = cli(&["franka", "gripper", "wiggle", "--host", &sim.host]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn a_dmp_model_is_stepped_online_and_its_phase_waits_for_a_lagging_robot() {
    let Some(sim) = FrankySim::start("127.0.0.46") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let q = state_q(&sim.host);
    let file = trajectory(dir.path(), &q, 0.5);
    let model = dir.path().join("swing.json");
    let o = cli(&[
        "imitate",
        &file,
        "--columns",
        "q1,q2,q3,q4,q5,q6,q7",
        "--formulation",
        "robust",
        "--out",
        model.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rec = dir.path().join("rec.csv");
    let run = |gain: &str| {
        let o = cli(&[
            "franka",
            "execute",
            model.to_str().unwrap(),
            "--host",
            &sim.host,
            "--record",
            rec.to_str().unwrap(),
            "--realtime",
            "ignore",
            "--force",
            "--json",
            "--error-gain",
            gain,
        ]);
        assert!(
            o.status.success(),
            "{:?} {} {}",
            o.status,
            stderr(&o),
            String::from_utf8_lossy(&o.stdout)
        );
        let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(r["complete"], true, "{r}");
        assert_eq!(r["trajectory"], "a DMP stepped online with phase stopping");
        r
    };
    // Without phase stopping: the model's 3 s, and the swing back to where it started.
    let free = run("0");
    let d0 = free["duration_s"].as_f64().unwrap();
    assert!((3.0..3.8).contains(&d0), "{d0} s");
    let text = std::fs::read_to_string(&rec).unwrap();
    let last: Vec<f64> = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|c| c.parse().unwrap())
        .collect();
    assert!(
        (last[22] - q[0]).abs() < 2e-3,
        "q_d1 ends at {} for a start of {}",
        last[22],
        q[0]
    );
    // With a strong gain the simulator's PD lag (~0.03 rad at speed) slows the phase.
    let slowed = run("100");
    let d1 = slowed["duration_s"].as_f64().unwrap();
    assert!(
        d1 > 1.3 * d0,
        "{d1} s with phase stopping against {d0} s without"
    );
    for k in ["velocity", "acceleration", "jerk"] {
        for u in slowed["limit_usage_percent"][k].as_array().unwrap() {
            assert!(u.as_f64().unwrap() <= 100.0);
        }
    }
    // A task-space model is refused (2), and so are model options on a trajectory.
    let xyz = dir.path().join("xyz.csv");
    std::fs::write(&xyz, "t,x,y,z\n0,0,0,0\n0.5,0.1,0,0\n1,0.2,0,0\n").unwrap();
    let m3 = dir.path().join("xyz.json");
    assert!(
        cli(&[
            "imitate",
            xyz.to_str().unwrap(),
            "--formulation",
            "robust",
            "--out",
            m3.to_str().unwrap()
        ])
        .status
        .success()
    );
    let o = cli(&[
        "franka",
        "execute",
        m3.to_str().unwrap(),
        "--host",
        &sim.host,
        "--record",
        rec.to_str().unwrap(),
        "--force",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("3-dimensional model"), "{}", stderr(&o));
    let o = cli(&[
        "franka",
        "execute",
        &file,
        "--host",
        &sim.host,
        "--record",
        rec.to_str().unwrap(),
        "--force",
        "--tau",
        "5",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// The tool's path (columns tool_x, tool_y, tool_z) of a recording.
fn tool_path(file: &Path) -> Vec<[f64; 3]> {
    let text = std::fs::read_to_string(file).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let at = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (x, y, z) = (at("tool_x"), at("tool_y"), at("tool_z"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|c| c.parse().unwrap()).collect();
            [v[x], v[y], v[z]]
        })
        .collect()
}

#[test]
fn a_guided_demonstration_is_imitated_and_replayed() {
    let Some(sim) = FrankySim::start("127.0.0.82") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let demo = dir.path().join("demo.csv");
    // A hand pulls the tool 0.5 s after the arm floats: 15 cm sideways and down over 2 s.
    let o = std::thread::scope(|scope| {
        scope.spawn(|| {
            std::thread::sleep(Duration::from_millis(700));
            sim.send("lead 0.50 0.15 0.45 2.0 400 20");
        });
        cli(&[
            "franka",
            "guide",
            "--host",
            &sim.host,
            "--duration",
            "3.5",
            "--out",
            demo.to_str().unwrap(),
            "--realtime",
            "ignore",
            "--json",
        ])
    });
    sim.send("release");
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["complete"], true, "{report}");
    // The recording has the columns of `franka execute --record`.
    let header = std::fs::read_to_string(&demo)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_string();
    assert!(
        header.starts_with("t,q1,") && header.ends_with("tool_x,tool_y,tool_z"),
        "{header}"
    );
    let shown = tool_path(&demo);
    let moved = shown
        .last()
        .unwrap()
        .iter()
        .zip(&shown[0])
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(moved > 0.15, "the hand moved the tool {moved} m");
    // Imitated (a joint-space DMP) and replayed from where the arm stands.
    let model = dir.path().join("model.json");
    let o = cli(&[
        "imitate",
        demo.to_str().unwrap(),
        "--columns",
        "q1,q2,q3,q4,q5,q6,q7",
        // The thesis's formulation scales the shape to where franky-sim holds (~10 mrad
        // off the demonstration's start): the path replayed within 5 mm. The default,
        // robust, corrects that offset smoothly along the movement instead (6.4 mm).
        "--formulation",
        "ijspeert",
        "--out",
        model.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let replay = dir.path().join("replay.csv");
    // --approach: first back to the demonstration's start, where the model begins.
    let o = cli(&[
        "franka",
        "execute",
        model.to_str().unwrap(),
        "--host",
        &sim.host,
        "--record",
        replay.to_str().unwrap(),
        "--approach",
        "--realtime",
        "ignore",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let replayed = tool_path(&replay);
    // Every point of the replay lies near the demonstrated path, and it ends where the
    // demonstration did.
    let near = |p: &[f64; 3]| {
        shown
            .iter()
            .map(|q| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt())
            .fold(f64::INFINITY, f64::min)
    };
    let worst = replayed.iter().map(near).fold(0.0, f64::max);
    let end = replayed.last().unwrap();
    let end_gap = (0..3)
        .map(|k| (end[k] - shown.last().unwrap()[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    eprintln!(
        "guided {:.0} mm; replay at most {:.3} mm from the demonstrated path, ends {:.3} mm from its end; {} rows replayed",
        moved * 1e3,
        worst * 1e3,
        end_gap * 1e3,
        replayed.len()
    );
    assert!(worst < 0.005 && end_gap < 0.005, "{worst} {end_gap}");
}
