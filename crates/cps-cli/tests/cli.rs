//! End-to-end tests of the `cps-cli` binary: a small run with its files and numbers,
//! determinism across thread counts, and every kind of bad input.

mod common;

use std::process::Command;

use common::{cli, csv_columns, json, repo, stderr, stdout_json, write};

const SHIPPED: &str = include_str!("../../../experiments/viapoint.toml");

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
    assert_eq!(m["version"], 2); // version 2: the formulation named as everywhere
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

/// The default formulation keeps a shape from a new start; the thesis's, one word away,
/// says in a sentence when a new start mirrors or stretches its shape.
#[test]
fn imitate_keeps_a_shape_by_default_and_the_thesiss_form_warns_when_a_start_distorts_it() {
    let dir = tempfile::tempdir().unwrap();
    let demo = write(dir.path(), "demo.csv", &demo_csv(201));
    let learn = |name: &str, extra: &[&str]| {
        let model = dir.path().join(name);
        let mut args = vec![
            "imitate",
            demo.to_str().unwrap(),
            "--out",
            model.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = cli(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        model
    };
    let robust = learn("robust.json", &[]);
    // One vocabulary: the model file names the formulation as the option does.
    assert_eq!(json(&robust)["formulation"], "robust");
    let thesis = learn("thesis.json", &["--formulation", "ijspeert"]);
    assert_eq!(json(&thesis)["formulation"], "ijspeert");
    // x learned 0.2 → 0.5; from 0.7 to 0.5 it runs the other way.
    let roll = |model: &std::path::Path| {
        let out = dir.path().join("r.csv");
        let o = cli(&[
            "rollout",
            model.to_str().unwrap(),
            "--start",
            "0.7,-0.1",
            "--out",
            out.to_str().unwrap(),
            "--force",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let warned = roll(&thesis);
    assert!(
        warned.contains("warning: x: goal − start is -0.2000 where the model learned 0.3000, which mirrors it (×-0.67)")
            && warned.contains("--formulation robust"),
        "{warned}"
    );
    assert!(!warned.contains("warning: y"), "{warned}");
    assert!(!roll(&robust).contains("warning"));
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
            text.replace("\"version\": 2", "\"version\": 3"),
            "version 3 is not supported",
        ),
        (
            "f.json",
            text.replace("\"robust\"", "\"schaal\""),
            "formulation \"schaal\" is not one of \"ijspeert\", \"robust\"",
        ),
        (
            "former.json",
            text.replace("\"robust\"", "\"goal_robust\""),
            "\"goal_robust\" is now called \"robust\"",
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
    // What `.ci/peers` installs the client into, else the system's Python.
    let venv = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../target/ci-python/bin/python"
    );
    let python = std::env::var("CPS_PYTHON").unwrap_or_else(|_| {
        if std::path::Path::new(venv).exists() {
            venv.into()
        } else {
            "python3".into()
        }
    });
    let has_client = Command::new(&python)
        .args(["-c", "import coppeliasim_zmqremoteapi_client"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_client {
        cps_testkit::skip(&format!(
            "{python} has no coppeliasim_zmqremoteapi_client (the official CoppeliaSim client)"
        ));
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
    assert!(listed.iter().any(|f| f["path"] == "summary.json"));
    // Each file with the size and SHA-256 it was written with.
    let summary = std::fs::read(ours.join("summary.json")).unwrap();
    let entry = listed.iter().find(|f| f["path"] == "summary.json").unwrap();
    assert_eq!(entry["size"], summary.len());
    assert_eq!(entry["sha256"].as_str().unwrap().len(), 64);
    assert!(
        run(&ours, true).status.success(),
        "--force replaces cps's own results"
    );
    std::fs::write(ours.join("notes.txt"), b"mine").unwrap();
    let o = run(&ours, true);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("`notes.txt`"), "{}", stderr(&o));
    assert_eq!(std::fs::read(ours.join("notes.txt")).unwrap(), b"mine");
    std::fs::remove_file(ours.join("notes.txt")).unwrap();

    // A manifest entry `lnk/victim.txt` where `lnk` links to another directory: --force
    // deleted the file there. And a hand-made manifest naming a user's thesis.tex made
    // --force delete it. Both are refused now, and the files stay.
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    std::fs::write(elsewhere.join("victim.txt"), b"precious").unwrap();
    std::os::unix::fs::symlink(&elsewhere, ours.join("lnk")).unwrap();
    let mut m = json(&ours.join("cps-manifest.json"));
    let mut victim = m["files"][0].clone();
    victim["path"] = "lnk/victim.txt".into();
    m["files"].as_array_mut().unwrap().push(victim);
    std::fs::write(ours.join("cps-manifest.json"), m.to_string()).unwrap();
    let o = run(&ours, true);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("symbolic link"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(elsewhere.join("victim.txt")).unwrap(),
        b"precious"
    );
    let thesis = dir.path().join("thesis");
    std::fs::create_dir(&thesis).unwrap();
    std::fs::write(thesis.join("thesis.tex"), b"\\documentclass{book}").unwrap();
    std::fs::write(
        thesis.join("cps-manifest.json"),
        r#"{"files": ["thesis.tex"], "format": "cps-results", "version": 1}"#,
    )
    .unwrap();
    let o = run(&thesis, true);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("cannot verify"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(thesis.join("thesis.tex")).unwrap(),
        b"\\documentclass{book}"
    );

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

/// A demonstration that returns to its start along one axis cannot be learned in the
/// Ijspeert form; `imitate --formulation ijspeert` says so and names the flag that learns
/// it, which does (the default).
#[test]
fn imitate_names_the_formulation_that_learns_a_return_to_the_start() {
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("t,x,y\n");
    for k in 0..=200 {
        let t = k as f64 * 0.01;
        let x = (std::f64::consts::PI * t / 2.0).sin().powi(2) * 0.3;
        csv.push_str(&format!("{t},{x},{}\n", 0.2 * t));
    }
    let demo = dir.path().join("loop.csv");
    std::fs::write(&demo, csv).unwrap();
    let model = dir.path().join("m.json");
    let args = [
        "imitate",
        demo.to_str().unwrap(),
        "--out",
        model.to_str().unwrap(),
        "--formulation",
        "ijspeert",
    ];
    let o = cli(&args);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("pass --formulation robust"),
        "{}",
        stderr(&o)
    );
    assert!(!model.exists());
    let o = cli(&args[..4]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(model.is_file());
}
