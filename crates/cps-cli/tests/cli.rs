//! End-to-end tests of the `cps-cli` binary: a small run with its files and numbers,
//! determinism across thread counts, and every kind of bad input.

mod common;

use std::process::{Command, Output};

use common::{cli, json, repo, write};

const SHIPPED: &str = include_str!("../../../experiments/viapoint.toml");

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The shipped experiment made quick: the exact optimum as a warm start and a short run.
fn small_experiment() -> String {
    SHIPPED
        .replace("warm_start = false", "warm_start = true")
        .replace("sigma0 = 0.5", "sigma0 = 0.001")
        .replace("generations = 3000", "generations = 40")
        .replace("repetitions = 1 ", "repetitions = 2 ")
}

#[test]
fn a_run_writes_every_result_with_the_promised_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let exp = write(dir.path(), "small.toml", &small_experiment());
    let out = dir.path().join("out");
    let o = cli(&[
        "run",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in [
        "summary.json",
        "cost_history.csv",
        "weights.csv",
        "trajectory.csv",
        "cost.png",
        "cost.svg",
        "coordinates.png",
        "coordinates.svg",
        "path3d.png",
        "path3d.svg",
        "velocity.svg",
        "acceleration.svg",
        "search.svg",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    // The report holds the six figures inline and the numbers of the summary.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 6);
    let s = json(&out.join("summary.json"));
    assert!(html.contains(&format!("{:.6e}", s["best_cost"].as_f64().unwrap())));
    assert_eq!(s["experiment"], "viapoint");
    assert_eq!(s["complete"], true);
    assert_eq!(s["repetitions"], 2);
    for v in s["via_errors_m"].as_array().unwrap() {
        assert!(v.as_f64().unwrap() < 1e-3);
    }
    assert!(s["goal_error_m"].as_f64().unwrap() < 1e-3);
    assert!(s["final_speed_m_s"].as_f64().unwrap() < 1e-3);
    let gap = s["gap_to_optimum"].as_f64().unwrap();
    assert!((0.0..0.01).contains(&gap), "gap {gap}");
    let best = s["best_cost"].as_f64().unwrap();
    let opt = s["optimum_cost"].as_f64().unwrap();
    assert!(((best - opt) / opt - gap).abs() < 1e-12);

    let traj = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    let mut lines = traj.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,x,y,z,x_vel,y_vel,z_vel,x_acc,y_acc,z_acc"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 1001);
    assert_eq!(rows[0][1..4], [0.75, 0.02, 1.87]);
    let last = &rows[1000];
    assert_eq!(last[0], 10.0);
    assert!(
        (last[1] - 0.55).abs() < 1e-3
            && (last[2] + 0.57).abs() < 1e-3
            && (last[3] - 1.45).abs() < 1e-3
    );
    // Velocities are physical: they match the positions' central differences.
    let k = 400;
    let dv = (rows[k + 1][1] - rows[k - 1][1]) / 0.02;
    assert!(
        (dv - rows[k][4]).abs() < 1e-3 * (1.0 + dv.abs()),
        "{dv} vs {}",
        rows[k][4]
    );

    let weights = std::fs::read_to_string(out.join("weights.csv")).unwrap();
    assert!(weights.starts_with(
        "Time,NrDmps,NrBfs,Scaling,Tau,NrIterations,Weights,Rewards,ComputeTime,NrWayPoints,WayPoints"
    ));
    assert_eq!(
        weights.lines().count(),
        3,
        "a header and one row per repetition"
    );
    let history = std::fs::read_to_string(out.join("cost_history.csv")).unwrap();
    assert!(history.starts_with("repetition,generation,best,median,best_so_far,sigma"));
    assert_eq!(history.lines().count(), 1 + 2 * 40);
}

#[test]
fn one_and_two_threads_give_identical_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let exp = write(
        dir.path(),
        "e.toml",
        &small_experiment()
            .replace("warm_start = true", "warm_start = false")
            .replace("sigma0 = 0.001", "sigma0 = 0.5"),
    );
    let mut summaries = Vec::new();
    for t in ["1", "2"] {
        let out = dir.path().join(format!("out{t}"));
        let o = cli(&[
            "run",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            t,
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let mut s = json(&out.join("summary.json"));
        let obj = s.as_object_mut().unwrap();
        obj.remove("wall_time_s");
        obj.remove("threads");
        for r in obj["runs"].as_array_mut().unwrap() {
            r.as_object_mut().unwrap().remove("seconds");
        }
        summaries.push(s);
    }
    assert_eq!(summaries[0], summaries[1]);
}

#[test]
fn the_default_experiment_is_valid_and_check_does_not_run() {
    let o = cli(&["default"]);
    assert!(o.status.success());
    let dir = tempfile::tempdir().unwrap();
    let exp = write(dir.path(), "d.toml", &String::from_utf8(o.stdout).unwrap());
    let o = cli(&["check", exp.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("ok"));
}

#[test]
fn existing_results_are_kept_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let exp = write(dir.path(), "e.toml", &small_experiment());
    let out = dir.path().join("out");
    let args = [
        "run",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ];
    assert!(cli(&args).status.success());
    let before = std::fs::read(out.join("summary.json")).unwrap();
    let o = cli(&args);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("already holds results"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(out.join("summary.json")).unwrap(), before);
    let mut forced = args.to_vec();
    forced.push("--force");
    assert!(cli(&forced).status.success());
    // No staging directories are left behind.
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(leftovers.is_empty());
}

/// Each bad input: exit code 2, a message with the file, the line and the rule, and
/// nothing written.
#[test]
fn bad_inputs_are_clear_errors_and_write_nothing() {
    let base = small_experiment();
    let line_of = |needle: &str| base.lines().position(|l| l.contains(needle)).unwrap() + 1;
    let cases: Vec<(&str, String, Option<usize>, &str)> = vec![
        (
            "unknown key",
            base.replace("tau = 10.0", "tau = 10.0\ntaux = 3"),
            Some(line_of("tau = 10.0") + 1),
            "unknown field",
        ),
        (
            "missing coordinate",
            base.replace("position = [0.78, 0.60, 1.70]", "position = [0.78, 0.60]"),
            Some(line_of("[0.78, 0.60, 1.70]")),
            "has 2 coordinates",
        ),
        (
            "extra coordinate",
            base.replace(
                "goal = [0.55, -0.57, 1.45]",
                "goal = [0.55, -0.57, 1.45, 2.0]",
            ),
            Some(line_of("goal = [0.55")),
            "has 4 coordinates",
        ),
        (
            "via time outside",
            base.replace("time = 8.0", "time = 12.0"),
            Some(line_of("time = 8.0")),
            "inside (0, tau",
        ),
        (
            "via time at zero",
            base.replace("time = 2.0", "time = 0.0"),
            Some(line_of("time = 2.0")),
            "inside (0, tau",
        ),
        (
            "via times not increasing",
            base.replace("time = 6.0", "time = 3.0"),
            Some(line_of("time = 6.0")),
            "later than the previous",
        ),
        (
            "tau <= 0",
            base.replace("tau = 10.0", "tau = 0.0"),
            Some(line_of("tau = 10.0")),
            "`tau` must be finite and > 0",
        ),
        (
            "dt <= 0",
            base.replace("dt = 0.01", "dt = -0.01"),
            Some(line_of("dt = 0.01")),
            "`dt` must be finite and > 0",
        ),
        (
            "dt >= tau",
            base.replace("dt = 0.01", "dt = 10.0"),
            Some(line_of("dt = 0.01")),
            "smaller than tau",
        ),
        (
            "NaN",
            base.replace("start = [0.75, 0.02, 1.87]", "start = [0.75, nan, 1.87]"),
            Some(line_of("start = [")),
            "must be finite",
        ),
        (
            "infinity",
            base.replace(
                "position = [1.12, 0.37, 1.45]",
                "position = [1.12, inf, 1.45]",
            ),
            Some(line_of("[1.12, 0.37, 1.45]")),
            "must be finite",
        ),
        (
            "zero basis functions",
            base.replace("basis_functions = 25", "basis_functions = 0"),
            Some(line_of("basis_functions = 25")),
            "at least 1",
        ),
        (
            "negative penalty",
            base.replace("via = 1e5", "via = -1e5"),
            None,
            "cost.via",
        ),
        (
            "population < 2",
            base.replace("population = 96", "population = 1"),
            Some(line_of("population = 96")),
            "between 2 and 100000",
        ),
        ("not TOML", "this is [not toml".to_string(), Some(1), "TOML"),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (what, text, line, rule) in cases {
        let exp = write(dir.path(), "bad.toml", &text);
        let out = dir.path().join("never");
        let o = cli(&[
            "run",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        let msg = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{what}: {msg}");
        assert!(msg.contains("bad.toml"), "{what}: {msg}");
        if let Some(line) = line {
            assert!(
                msg.contains(&format!("bad.toml:{line}:")),
                "{what}: expected line {line}: {msg}"
            );
        }
        assert!(msg.contains(rule), "{what}: expected `{rule}`: {msg}");
        assert!(!msg.contains("panicked"), "{what}: {msg}");
        assert!(!out.exists(), "{what}: wrote {}", out.display());
        // `check` agrees.
        assert_eq!(
            cli(&["check", exp.to_str().unwrap()]).status.code(),
            Some(2),
            "{what}"
        );
    }
    let o = cli(&[
        "run",
        dir.path().join("missing.toml").to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot read"));
}

/// Ctrl-C (SIGINT) and SIGTERM (what `timeout` and cluster schedulers send) stop at the
/// end of a generation and still write complete files, marked `"complete": false`, with
/// exit code 130.
#[cfg(unix)]
#[test]
fn an_interrupted_run_writes_what_it_learned_marked_incomplete() {
    let dir = tempfile::tempdir().unwrap();
    let exp = write(
        dir.path(),
        "long.toml",
        // No tolfun stop: the run must still be going when the signal comes, however fast
        // the build.
        &SHIPPED
            .replace("generations = 3000", "generations = 1000000")
            .replace("tol_fun = 1e-3", "tol_fun = 0.0"),
    );
    for signal in ["INT", "TERM"] {
        let out = dir.path().join(format!("out-{signal}"));
        assert_eq!(
            common::run_signalled(&exp, &out, signal),
            Some(130),
            "{signal}"
        );
        let s = json(&out.join("summary.json"));
        assert_eq!(s["complete"], false);
        assert_eq!(s["termination"], "interrupted");
        assert!(s["generations"].as_u64().unwrap() >= 1);
        assert!(out.join("trajectory.csv").is_file() && out.join("cost.png").is_file());
    }
}

fn stdout_json(o: &Output) -> serde_json::Value {
    serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&o.stdout)))
}

#[test]
fn fk_and_ik_from_the_command_line_round_trip() {
    // At q = 0 the Panda's flange is 0.088 m forward and 0.926 m up, pointing down.
    let o = cli(&[
        "fk",
        "--robot",
        "panda",
        "--q",
        "0,0,0,0,0,0,0",
        "--tool",
        "flange",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let fk = stdout_json(&o);
    assert!((fk["T"][0][3].as_f64().unwrap() - 0.088).abs() < 1e-12);
    assert!((fk["T"][2][3].as_f64().unwrap() - 0.926).abs() < 1e-12);
    assert!((fk["T"][2][2].as_f64().unwrap() + 1.0).abs() < 1e-12);
    assert_eq!(fk["quaternion_xyzw"].as_array().unwrap().len(), 4);

    // The Hand TCP pose at some configuration, then IK for that full pose.
    let q = "0.3,-0.5,0.2,-2.0,0.1,1.6,0.7";
    let fk = stdout_json(&cli(&["fk", "--q", q, "--json"]));
    let mut target: Vec<String> = fk["position"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.to_string())
        .collect();
    target.extend(
        fk["quaternion_xyzw"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.to_string()),
    );
    let o = cli(&["ik", "--target", &target.join(","), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ik = stdout_json(&o);
    assert!(ik["position_error"].as_f64().unwrap() <= 1e-9);
    assert!(ik["rotation_error"].as_f64().unwrap() <= 1e-9);
    let q_ik: Vec<String> = ik["q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.to_string())
        .collect();
    let again = stdout_json(&cli(&["fk", "--q", &q_ik.join(","), "--json"]));
    for k in 0..3 {
        let (a, b) = (
            again["position"][k].as_f64().unwrap(),
            fk["position"][k].as_f64().unwrap(),
        );
        assert!((a - b).abs() < 1e-9);
    }
}

#[test]
fn kinematics_bad_input_exits_2_with_a_clear_message() {
    for (args, expect) in [
        (vec!["fk", "--q", "0,0,0"], "expected 7 joint values, got 3"),
        (vec!["fk", "--robot", "r2d2", "--q", "0"], "unknown robot"),
        (vec!["ik", "--target", "3,0,0.5"], "target not reached"),
        (vec!["ik", "--target", "0.3,0.1"], "x,y,z"),
        (vec!["ik", "--target", "0.3,NaN,0.5"], "finite"),
        (
            vec![
                "ik",
                "--target",
                "0.3,0.1,0.5",
                "--seed-q",
                "0,0,0,0,0,1.57,0.78",
            ],
            "--seed-q: joint 4 = 0 is outside its limits [-3.0718, -0.0698]",
        ),
        (
            vec!["fk", "--within-limits", "--q", "0,0,0,0,0,1.57,0.78"],
            "--q: joint 4 = 0 is outside its limits",
        ),
    ] {
        let o = cli(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
    }
    let o = cli(&["robot", "show", "panda"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("modified (Craig) DH") && text.contains("-3.0718"),
        "{text}"
    );
}

/// The robot files in configs/robots/ describe the same robots as the built-in models:
/// the Panda as a TOML DH table and as URDF joints, the UR3 as a TOML DH table.
#[test]
fn robot_files_agree_with_the_built_in_models() {
    let q7 = "0.3,-0.5,0.2,-2.0,0.1,1.6,0.7";
    let fk = |robot: &str, q: &str, extra: &[&str]| {
        let mut args = vec!["fk", "--robot", robot, "--q", q, "--json"];
        args.extend_from_slice(extra);
        let o = cli(&args);
        assert!(o.status.success(), "{robot}: {}", stderr(&o));
        stdout_json(&o)["T"].clone()
    };
    let close = |a: &serde_json::Value, b: &serde_json::Value| {
        for r in 0..4 {
            for c in 0..4 {
                let d = a[r][c].as_f64().unwrap() - b[r][c].as_f64().unwrap();
                assert!(d.abs() < 1e-12, "T[{r}][{c}] differs by {d}");
            }
        }
    };
    let builtin = fk("panda", q7, &[]);
    close(&builtin, &fk(&repo("configs/robots/panda.toml"), q7, &[]));
    close(&builtin, &fk(&repo("configs/robots/panda.urdf"), q7, &[]));
    let flange = fk("panda", q7, &["--tool", "flange"]);
    close(
        &flange,
        &fk(
            &repo("configs/robots/panda.toml"),
            q7,
            &["--tool", "flange"],
        ),
    );
    close(
        &flange,
        &fk(
            &repo("configs/robots/panda.urdf"),
            q7,
            &["--tip", "panda_link8"],
        ),
    );
    let q6 = "0.3,-1.1,0.8,-0.4,1.2,0.5";
    close(
        &fk("ur3", q6, &[]),
        &fk(&repo("configs/robots/ur3.toml"), q6, &[]),
    );
    let o = cli(&["robot", "show", &repo("configs/robots/panda.urdf")]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("panda_joint7"));
}

#[test]
fn bad_robot_files_exit_2_naming_the_place() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(repo("configs/robots/panda.toml")).unwrap();
    let no_limit = good.replacen("q_max = 2.8973\n", "", 1);
    let unknown = good.replacen("dq_max = 2.175\n", "dq_max = 2.175\ndamping = 3.0\n", 1);
    let inverted = good.replacen("q_min = -1.7628", "q_min = 1.9", 1);
    let some_speeds = good.replacen("dq_max = 2.61\n", "", 1);
    let prismatic = std::fs::read_to_string(repo("configs/robots/panda.urdf"))
        .unwrap()
        .replace(
            "panda_joint4\" type=\"revolute",
            "panda_joint4\" type=\"prismatic",
        );
    for (name, text, expect) in [
        ("no_limit.toml", no_limit.as_str(), "missing field `q_max`"),
        ("unknown.toml", unknown.as_str(), "unknown field `damping`"),
        (
            "inverted.toml",
            inverted.as_str(),
            "joint 2: limits need finite `q_min` < `q_max`",
        ),
        (
            "speeds.toml",
            some_speeds.as_str(),
            "`dq_max` for every joint or for none",
        ),
        (
            "prismatic.urdf",
            prismatic.as_str(),
            "joint `panda_joint4` is prismatic",
        ),
        ("broken.urdf", "<robot name='x'><link", "URDF:"),
    ] {
        let p = write(dir.path(), name, text);
        let o = cli(&["fk", "--robot", p.to_str().unwrap(), "--q", "0,0,0,0,0,0,0"]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(expect) && err.contains(name), "{name}: {err}");
        assert!(!err.contains("panicked"));
    }
    // Line and column of the offending joint table.
    let p = dir.path().join("inverted.toml");
    let err = stderr(&cli(&["robot", "show", p.to_str().unwrap()]));
    assert!(err.contains("inverted.toml:") && err.contains(':'), "{err}");
    let urdf = repo("configs/robots/panda.urdf");
    for (args, expect) in [
        (
            vec!["fk", "--robot", urdf.as_str(), "--tool", "hand", "--q", "0"],
            "--tip",
        ),
        (
            vec!["fk", "--robot", "panda", "--tool", "gripper", "--q", "0"],
            "not `gripper`",
        ),
        (
            vec!["fk", "--robot", "/nowhere/arm.toml", "--q", "0"],
            "cannot read the robot file",
        ),
    ] {
        let o = cli(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{args:?}: {}", stderr(&o));
    }
}

/// The thesis's scene puts the Hand TCP at the experiment's start point at the initial
/// configuration, and every Table 3 point is reachable within the joint limits.
#[test]
fn the_thesis_scene_starts_at_p0_and_reaches_every_way_point() {
    let o = cli(&[
        "scene",
        "check",
        &repo("configs/scenes/thesis.toml"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v = stdout_json(&o);
    let tool: Vec<f64> = v["tool_at_initial_q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    for (a, b) in tool.iter().zip([0.75, 0.02, 1.87]) {
        assert!((a - b).abs() < 1e-12, "{tool:?}");
    }
    assert_eq!(v["initial_q_outside_limits"], serde_json::json!([4]));
    let objects = v["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 6);
    assert!(
        objects.iter().all(|o| o["reachable"] == true),
        "{objects:?}"
    );

    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo("configs/scenes/thesis.toml")).unwrap();
    let far = write(
        dir.path(),
        "far.toml",
        &text.replace("[0.55, -0.57, 1.45]", "[3.0, 0.0, 1.0]"),
    );
    let o = cli(&["scene", "check", far.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("pT   (3.000, 0.000, 1.000): NOT reachable")
    );
    let short = write(
        dir.path(),
        "short.toml",
        &text.replace("1.5707963267948966, 0.7853981633974483]", "1.57]"),
    );
    let o = cli(&["scene", "check", short.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("short.toml:16:")
            && stderr(&o).contains("expected 7 joint values, got 6"),
        "{}",
        stderr(&o)
    );
}

fn demo_csv(rows: usize) -> String {
    let mut s = String::from("time,x,y\n");
    for k in 0..rows {
        let t = 2.0 * k as f64 / (rows - 1) as f64;
        let u = t / 2.0;
        let mj = 10.0 * u.powi(3) - 15.0 * u.powi(4) + 6.0 * u.powi(5);
        s.push_str(&format!("{t},{},{}\n", 0.2 + 0.3 * mj, -0.1 + 0.05 * mj));
    }
    s
}

/// imitate → model.json → rollout: the trajectory reproduces the demonstration, a new
/// goal and τ are honoured, and the files have the promised shape.
#[test]
fn imitate_and_rollout_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let demo = write(dir.path(), "demo.csv", &demo_csv(201));
    let model = dir.path().join("model.json");
    let o = cli(&[
        "imitate",
        demo.to_str().unwrap(),
        "--bases",
        "20",
        "--out",
        model.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = stdout_json(&o);
    for d in 0..2 {
        assert!(report["rmse"][d].as_f64().unwrap() < 1e-4, "{report}");
    }
    let m = json(&model);
    assert_eq!(m["format"], "cps-dmp-model");
    assert_eq!(m["version"], 1);
    assert_eq!(m["names"], serde_json::json!(["x", "y"]));
    assert_eq!(m["weights"].as_array().unwrap().len(), 2);
    let traj = dir.path().join("traj.csv");
    let plot = dir.path().join("traj.png");
    let o = cli(&[
        "rollout",
        model.to_str().unwrap(),
        "--goal",
        "0.6,0.0",
        "--tau",
        "4",
        "--out",
        traj.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&traj).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "t,x,y,x_vel,y_vel,x_acc,y_acc");
    let last: Vec<f64> = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!((last[0] - 4.0).abs() < 1e-12);
    assert!(
        (last[1] - 0.6).abs() < 5e-3 && (last[2] - 0.0).abs() < 5e-3,
        "{last:?}"
    );
    assert!(std::fs::metadata(&plot).unwrap().len() > 1000);
}

#[test]
fn bad_demonstrations_and_models_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let good = demo_csv(50);
    let mut lines: Vec<String> = good.lines().map(str::to_string).collect();
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "short.csv",
            "time,x\n0,1\n1,2\n".into(),
            "at least 3 samples",
        ),
        (
            "dup.csv",
            "time,x\n0,1\n1,2\n1,3\n2,4\n".into(),
            "sample 2 at 1 s follows 1 s",
        ),
        (
            "nan.csv",
            "time,x\n0,1\n1,NaN\n2,3\n".into(),
            "line 3, column `x`: NaN is not finite",
        ),
        (
            "text.csv",
            "time,x\n0,1\n1,abc\n2,3\n".into(),
            "line 3, column `x`: `abc` is not a number",
        ),
        (
            "ragged.csv",
            "time,x,y\n0,1,2\n1,2\n2,3,4\n".into(),
            "line 3",
        ),
        (
            "noheader.csv",
            "0,1,2\n1,2,3\n2,3,4\n".into(),
            "no header row",
        ),
    ];
    for (name, text, expect) in cases {
        let p = write(dir.path(), name, &text);
        let out = dir.path().join(format!("{name}.json"));
        let o = cli(&[
            "imitate",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(expect) && stderr(&o).contains(name),
            "{name}: {}",
            stderr(&o)
        );
        assert!(!out.exists(), "{name}: a model was written");
    }
    // Mismatched dimensions between demonstrations; zero bases; τ ≤ 0.
    let a = write(dir.path(), "a.csv", &good);
    lines.iter_mut().for_each(|l| {
        let mut parts: Vec<&str> = l.split(',').collect();
        parts.pop();
        *l = parts.join(",");
    });
    let b = write(dir.path(), "b.csv", &(lines.join("\n") + "\n"));
    let out = dir.path().join("m.json");
    let outs = out.to_str().unwrap();
    for (args, expect) in [
        (
            vec![
                "imitate",
                a.to_str().unwrap(),
                b.to_str().unwrap(),
                "--out",
                outs,
            ],
            "1 dimensions",
        ),
        (
            vec![
                "imitate",
                a.to_str().unwrap(),
                "--bases",
                "0",
                "--out",
                outs,
            ],
            "--bases: must be at least 1",
        ),
        (
            vec!["imitate", a.to_str().unwrap(), "--tau", "-1", "--out", outs],
            "--tau: must be finite and > 0",
        ),
        (
            vec![
                "imitate",
                a.to_str().unwrap(),
                "--lambda",
                "lots",
                "--out",
                outs,
            ],
            "--lambda",
        ),
    ] {
        let o = cli(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{args:?}: {}", stderr(&o));
        assert!(!out.exists());
    }
    // Models of another version or formulation, and a goal of the wrong dimension.
    assert!(
        cli(&["imitate", a.to_str().unwrap(), "--out", outs])
            .status
            .success()
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let traj = dir.path().join("t.csv");
    let ts = traj.to_str().unwrap();
    for (name, body, expect) in [
        (
            "v2.json",
            text.replace("\"version\": 1", "\"version\": 2"),
            "version 2 is not supported",
        ),
        (
            "f.json",
            text.replace("ijspeert2013", "schaal"),
            "unknown formulation \"schaal\"",
        ),
    ] {
        let p = write(dir.path(), name, &body);
        let o = cli(&["rollout", p.to_str().unwrap(), "--out", ts]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{name}: {}", stderr(&o));
    }
    let o = cli(&["rollout", outs, "--goal", "1,2,3", "--out", ts]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--goal: 3 values for a 2-dimensional model (x, y)"),
        "{}",
        stderr(&o)
    );
    let o = cli(&["rollout", outs, "--tau", "0", "--out", ts]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--tau"), "{}", stderr(&o));
    assert!(!traj.exists());
}

#[test]
fn cmaes_bench_prints_per_seed_results() {
    let o = cli(&[
        "cmaes", "bench", "sphere", "--dim", "5", "--seeds", "1..3", "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v = stdout_json(&o);
    let rows = v.as_array().unwrap();
    assert_eq!(rows.len(), 3);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r["seed"], (i + 1) as u64);
        assert_eq!(r["success"], true);
        assert!(r["best"].as_f64().unwrap() <= 1e-8);
        assert!(r["evaluations"].as_u64().unwrap() > 100);
    }
    for (args, expect) in [
        (
            vec!["cmaes", "bench", "sphere", "--seeds", "5..2"],
            "--seeds",
        ),
        (vec!["cmaes", "bench", "sphere", "--dim", "0"], "--dim"),
    ] {
        let o = cli(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(stderr(&o).contains(expect), "{}", stderr(&o));
    }
}

/// The official CoppeliaSim Python client (`coppeliasim-zmqremoteapi-client` from PyPI)
/// drives `cps-cli sim serve` through a full session. The interpreter is `$CPS_PYTHON`
/// or `python3`; without the package the test is skipped, except under CI (`CI` set),
/// where `.ci/run` installs it and the test is required.
#[test]
fn the_official_python_client_runs_a_session_against_sim_serve() {
    use std::io::{BufRead, BufReader};
    let python = std::env::var("CPS_PYTHON").unwrap_or_else(|_| "python3".into());
    let has_client = Command::new(&python)
        .args(["-c", "import coppeliasim_zmqremoteapi_client"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_client {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must provide the official Python client (CPS_PYTHON={python})"
        );
        eprintln!("skipped: {python} has no coppeliasim_zmqremoteapi_client");
        return;
    }
    let mut server = Command::new(env!("CARGO_BIN_EXE_cps-cli"))
        .args(["sim", "serve", "--bind", "127.0.0.1:0"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(server.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let port = line
        .split("tcp://127.0.0.1:")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .unwrap_or_else(|| panic!("no endpoint in {line:?}"))
        .to_string();
    let script = format!(
        "{}/tests/data/python_session.py",
        env!("CARGO_MANIFEST_DIR")
    );
    let out = Command::new(&python)
        .args([&script, &port])
        .output()
        .unwrap();
    // CoppeliaSim's own first examples' calls (simpleTest.py and its asyncio twin).
    let examples = format!(
        "{}/tests/data/python_examples.py",
        env!("CARGO_MANIFEST_DIR")
    );
    let ex = Command::new(&python)
        .args([&examples, &port])
        .output()
        .unwrap();
    // Stopped as Ctrl-C stops it, so it prints what clients logged.
    let _ = Command::new("kill")
        .args(["-INT", &server.id().to_string()])
        .status();
    let mut logged = String::new();
    std::io::Read::read_to_string(&mut server.stderr.take().unwrap(), &mut logged).unwrap();
    let _ = server.wait();
    for (o, ok) in [(&out, "python session ok"), (&ex, "python examples ok")] {
        assert!(
            o.status.success() && String::from_utf8_lossy(&o.stdout).contains(ok),
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // sim.addLog's messages are printed by the server with their level.
    assert!(
        logged.contains("[sim.addLog script info] free t="),
        "{logged}"
    );
    assert!(
        logged.contains("[sim.addLog warning] stepped k=9"),
        "{logged}"
    );
    assert!(
        logged.contains("[sim.addLog script info] async t="),
        "{logged}"
    );
}

/// The shipped demonstration (experiments/demos) is learned within a millimetre.
#[test]
fn the_shipped_demonstration_is_learned_within_a_millimetre() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json");
    let o = cli(&[
        "imitate",
        &repo("experiments/demos/table3_min_jerk.csv"),
        "--out",
        model.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = stdout_json(&o);
    for d in 0..3 {
        assert!(report["rmse"][d].as_f64().unwrap() < 1e-3, "{report}");
    }
}

/// A file that asks for more memory or work than the ceilings is refused before any work,
/// naming the key with its place; raising the ceiling lets it through `check`.
#[test]
fn oversized_experiments_are_refused_by_their_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let shipped = std::fs::read_to_string(repo("experiments/viapoint.toml")).unwrap();
    let line = |needle: &str| shipped.lines().position(|l| l.starts_with(needle)).unwrap() + 1;
    for (name, from, to, flag) in [
        (
            "memory.toml",
            "basis_functions = 25 ",
            "basis_functions = 20000 ",
            "--max-memory",
        ),
        (
            "work.toml",
            "repetitions = 1 ",
            "repetitions = 10000 ",
            "--max-work",
        ),
    ] {
        let key = from.split(' ').next().unwrap();
        let f = write(dir.path(), name, &shipped.replace(from, to));
        let out = dir.path().join("never");
        let o = cli(&[
            "run",
            f.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(&format!("{name}:{}:", line(key))), "{err}");
        assert!(err.contains(key) && err.contains(flag), "{err}");
        assert!(!out.exists());
    }
    let f = write(
        dir.path(),
        "raised.toml",
        &shipped.replace("repetitions = 1 ", "repetitions = 10000 "),
    );
    let o = cli(&["check", f.to_str().unwrap(), "--max-work", "1e15"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("operations"));
}

/// `run --out` never touches what cps did not write: a foreign file blocks the run, with
/// or without --force, and stays as it was; a file added beside cps's results blocks
/// --force too; `imitate --force` will not replace a file that is not a cps model.
#[test]
fn files_cps_did_not_write_are_never_touched() {
    let dir = tempfile::tempdir().unwrap();
    let exp = write(dir.path(), "e.toml", &small_experiment());
    let run = |out: &std::path::Path, force: bool| {
        let mut args = vec!["run", exp.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.push("--quiet");
        if force {
            args.push("--force");
        }
        cli(&args)
    };
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("thesis.pdf"), b"precious").unwrap();
    for force in [false, true] {
        let o = run(&out, force);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("`thesis.pdf`"), "{}", stderr(&o));
    }
    let names: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["thesis.pdf"]);
    assert_eq!(std::fs::read(out.join("thesis.pdf")).unwrap(), b"precious");

    let ours = dir.path().join("ours");
    assert!(run(&ours, false).status.success());
    let manifest = json(&ours.join("cps-manifest.json"));
    let listed = manifest["files"].as_array().unwrap();
    assert!(listed.iter().any(|f| f == "summary.json"));
    assert!(
        run(&ours, true).status.success(),
        "--force replaces cps's own results"
    );
    std::fs::write(ours.join("notes.txt"), b"mine").unwrap();
    let o = run(&ours, true);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("`notes.txt`"), "{}", stderr(&o));
    assert_eq!(std::fs::read(ours.join("notes.txt")).unwrap(), b"mine");

    let model = dir.path().join("model.json");
    std::fs::write(&model, b"{\"mine\": true}").unwrap();
    let demo = repo("experiments/demos/table3_min_jerk.csv");
    let o = cli(&[
        "imitate",
        &demo,
        "--out",
        model.to_str().unwrap(),
        "--force",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(&model).unwrap(), b"{\"mine\": true}");
}

/// Reads the named columns of a CSV file.
fn csv_columns(path: &std::path::Path, names: &[&str]) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| {
            header
                .iter()
                .position(|h| h == n)
                .unwrap_or_else(|| panic!("{n}"))
        })
        .collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    idx.iter()
        .map(|&i| rows.iter().map(|r: &Vec<f64>| r[i]).collect())
        .collect()
}

/// One CSV dialect: a trajectory `run` writes is a demonstration `imitate` reads (its
/// positions, not its derivative columns), and `rollout` of the model gives the trajectory
/// back.
#[test]
fn a_run_trajectory_round_trips_through_imitate_and_rollout() {
    let dir = tempfile::tempdir().unwrap();
    let exp = write(
        dir.path(),
        "exact.toml",
        &SHIPPED.replace("method = \"cmaes\"", "method = \"exact\""),
    );
    let out = dir.path().join("run");
    let o = cli(&[
        "run",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let traj = out.join("trajectory.csv");
    let model = dir.path().join("model.json");
    let o = cli(&[
        "imitate",
        traj.to_str().unwrap(),
        "--out",
        model.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        stdout_json(&o)["dimensions"],
        serde_json::json!(["x", "y", "z"])
    );
    let back = dir.path().join("back.csv");
    let o = cli(&[
        "rollout",
        model.to_str().unwrap(),
        "--out",
        back.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (
        csv_columns(&traj, &["t", "x", "y", "z"]),
        csv_columns(&back, &["t", "x", "y", "z"]),
    );
    assert_eq!(a[0].len(), b[0].len());
    let mut sq = 0.0;
    for d in 1..4 {
        for k in 0..a[0].len() {
            sq += (a[d][k] - b[d][k]).powi(2);
        }
    }
    let rmse = (sq / a[0].len() as f64).sqrt();
    // 25 bases imitating a 25-basis DMP: micrometres (measured 2.4e-6 m).
    assert!(rmse < 2e-5, "round-trip RMSE {rmse} m");

    // Columns chosen by name; a wrong name is named with the columns there are.
    let o = cli(&[
        "imitate",
        traj.to_str().unwrap(),
        "--columns",
        "x,height",
        "--out",
        dir.path().join("m2.json").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("no column `height`") && err.contains("x_vel"),
        "{err}"
    );
}

/// `limits check`: a slow move holds every Panda limit (exit 0, usage as computed by
/// hand), a fast one breaks the speed limit of the joint that moves (exit 1, the violation
/// in the JSON), and a file with too few joints is bad input (exit 2).
#[test]
fn limits_check_reports_usage_and_violations_with_its_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let ready = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    // Joint 1 follows 3x² − 2x³ (rest to rest) over `duration` seconds, 1 kHz samples.
    let file = |name: &str, amplitude: f64, duration: f64| {
        let mut text = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
        let n = (duration * 1000.0).round() as usize;
        for k in 0..=n {
            let x = k as f64 / n as f64;
            let mut q = ready;
            q[0] = amplitude * (3.0 * x * x - 2.0 * x * x * x);
            let cells: Vec<String> = q.iter().map(|v| format!("{v:e}")).collect();
            text.push_str(&format!("{},{}\n", k as f64 * 0.001, cells.join(",")));
        }
        write(dir.path(), name, &text)
    };
    let slow = file("slow.csv", 1.0, 4.0);
    let o = cli(&[
        "limits",
        "check",
        slow.to_str().unwrap(),
        "--robot",
        "panda",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["ok"], true);
    // Peak speed 1.5 A / T = 0.375 rad/s of joint 1's 2.175: 17.2 %.
    let usage = v["peak_usage"]["velocity"][0].as_f64().unwrap();
    assert!((usage - 100.0 * 0.375 / 2.175).abs() < 0.1, "{usage}");
    assert!(v["peak_usage"]["torque"][1].as_f64().unwrap() > 1.0); // gravity on joint 2
    let fast = file("fast.csv", 2.5, 1.0);
    let o = cli(&[
        "limits",
        "check",
        fast.to_str().unwrap(),
        "--robot",
        "panda",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["ok"], false);
    let speed: Vec<&serde_json::Value> = v["violations"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|x| x["quantity"] == "velocity")
        .collect();
    assert_eq!(speed.len(), 1, "{speed:?}");
    assert_eq!(speed[0]["joint"], 1);
    assert!((speed[0]["value"].as_f64().unwrap() - 3.75).abs() < 1e-3); // 1.5 · 2.5 rad / 1 s
    assert!((speed[0]["time"].as_f64().unwrap() - 0.5).abs() < 2e-3); // the middle
    assert_eq!(speed[0]["limit"], 2.175);
    let o = cli(&[
        "limits",
        "check",
        fast.to_str().unwrap(),
        "--robot",
        "panda",
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("joint 1 velocity at 0.50"));
    let short = write(
        dir.path(),
        "short.csv",
        "t,q1,q2\n0,0,0\n0.1,0,0\n0.2,0,0\n",
    );
    let o = cli(&[
        "limits",
        "check",
        short.to_str().unwrap(),
        "--robot",
        "panda",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("a 7-joint robot needs the time and 7 joint positions"));
    let o = cli(&["limits", "check", slow.to_str().unwrap(), "--rate", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--rate 0"));
}

/// Robot files carry limits and inertias for every joint or for none; a tensor no rigid
/// body has is refused, naming the joint and the place.
#[test]
fn robot_file_limits_and_inertias_are_all_or_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let panda = std::fs::read_to_string(repo("configs/robots/panda.toml")).unwrap();
    let traj = write(
        dir.path(),
        "t.csv",
        "t,q1,q2,q3,q4,q5,q6,q7\n0,0,0,0,-1,0,1,0\n0.5,0,0,0,-1,0,1,0\n1,0,0,0,-1,0,1,0\n",
    );
    let cases = [
        (
            panda.replacen("tau_max = 12.0\n", "", 1),
            "give `tau_max` for every joint or for none",
        ),
        (
            panda.replacen("mass = 0.646926\n", "", 1),
            "joint 2: give `mass`, `com` and `inertia` together",
        ),
        (
            panda.replacen("inertia = [0.70337,", "inertia = [0.01,", 1),
            "joint 1: invalid robot model: link inertia has principal moments",
        ),
    ];
    for (i, (text, message)) in cases.iter().enumerate() {
        let robot = write(dir.path(), &format!("bad{i}.toml"), text);
        let o = cli(&[
            "limits",
            "check",
            traj.to_str().unwrap(),
            "--robot",
            robot.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(message), "{}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("bad{i}.toml:")),
            "{}",
            stderr(&o)
        );
    }
    let good = write(dir.path(), "good.toml", &panda);
    let o = cli(&[
        "limits",
        "check",
        traj.to_str().unwrap(),
        "--robot",
        good.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["not_checked"].as_object().unwrap().is_empty(), "{v}");
}

#[test]
fn retime_writes_a_trajectory_that_limits_check_accepts_and_never_overwrites_unasked() {
    let dir = tempfile::tempdir().unwrap();
    // A 0.5 s move of joint 1 by 2 rad from Franka's ready pose: far beyond its limits.
    let mut text = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
    for k in 0..=50 {
        let x = k as f64 / 50.0;
        let q1 = 2.0 * x * x * x * (10.0 - 15.0 * x + 6.0 * x * x);
        text.push_str(&format!("{},{q1},-0.785,0,-2.356,0,1.571,0.785\n", 0.5 * x));
    }
    let fast = write(dir.path(), "fast.csv", &text);
    let out = dir.path().join("retimed.csv");
    let args = |mode: &str| {
        vec![
            "retime".to_string(),
            fast.to_str().unwrap().into(),
            "--robot".into(),
            "panda".into(),
            "--mode".into(),
            mode.into(),
            "--out".into(),
            out.to_str().unwrap().into(),
            "--json".into(),
        ]
    };
    let run = |a: &[String]| cli(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let o = run(&args("fastest"));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["ok"], true);
    assert!(v["peak_usage_before"]["velocity"].as_f64().unwrap() > 100.0);
    // Joint 1's 2 rad at no more than 2.175 rad/s: at least 0.92 s.
    let fastest = v["duration_s"].as_f64().unwrap();
    assert!(fastest > 2.0 / 2.175 && fastest < 2.0, "{fastest}");
    let o = cli(&["limits", "check", out.to_str().unwrap(), "--robot", "panda"]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    // An existing output is kept unless --force; uniform slowing is slower than the fastest.
    let before = std::fs::read(&out).unwrap();
    let o = run(&args("uniform"));
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&out).unwrap(), before);
    let mut forced = args("uniform");
    forced.push("--force".into());
    let o = run(&forced);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["duration_s"].as_f64().unwrap() > fastest);
    let o = run(&{
        let mut a = args("quickest");
        a.push("--force".into());
        a
    });
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("`quickest`") && stderr(&o).contains("`uniform`"));
}

/// `cps-cli sim pool`: N stand-in servers on every second port from the base, each
/// accepting connections, all stopped by one Ctrl-C; bad pools exit 2 and leave nothing.
#[test]
fn sim_pool_starts_every_second_port_and_stops_them_all() {
    use std::io::{BufRead, BufReader};
    // A base port unlikely to be taken, different per test process; another on a clash.
    let (mut pool, mut out, lines, base) = (0..5u16)
        .find_map(|attempt| {
            let base = 30_000 + (std::process::id() % 2_000) as u16 * 2 + attempt * 4_000;
            let mut pool = Command::new(env!("CARGO_BIN_EXE_cps-cli"))
                .args(["sim", "pool", "--n", "3", "--base-port", &base.to_string()])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap();
            let mut out = BufReader::new(pool.stdout.take().unwrap());
            let mut lines = Vec::new();
            for _ in 0..4 {
                let mut line = String::new();
                out.read_line(&mut line).unwrap();
                lines.push(line);
            }
            if lines[0].is_empty() {
                let _ = pool.wait(); // a port was taken: it exited with 2
                return None;
            }
            Some((pool, out, lines, base))
        })
        .expect("a free range of ports");
    assert!(
        lines[0].starts_with("3 stand-in CoppeliaSim servers"),
        "{lines:?}"
    );
    for i in 0..3u16 {
        let port = base + 2 * i;
        assert_eq!(
            lines[1 + i as usize].trim(),
            format!("tcp://127.0.0.1:{port}")
        );
        assert!(std::net::TcpStream::connect(("127.0.0.1", port)).is_ok());
    }
    let _ = Command::new("kill")
        .args(["-INT", &pool.id().to_string()])
        .status();
    let status = pool.wait().unwrap();
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut out, &mut rest).unwrap();
    assert!(status.success());
    assert_eq!(rest.matches("stopped after").count(), 3, "{rest}");
    // Bad pools: none, past the last port, a port already taken (nothing stays up).
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    for (args, says) in [
        (vec!["--n", "0"], "--n 0".to_string()),
        (
            vec!["--n", "10", "--base-port", "65530"],
            "65548".to_string(),
        ),
        (
            vec!["--n", "1", "--base-port", &port.to_string()],
            format!("127.0.0.1:{port}"),
        ),
    ] {
        let mut full = vec!["sim", "pool"];
        full.extend(&args);
        let o = cli(&full);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(stderr(&o).contains(&says), "{args:?}: {}", stderr(&o));
    }
}
