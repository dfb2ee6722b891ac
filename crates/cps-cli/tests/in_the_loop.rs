//! Learning with the simulator in the loop (`kind = "viapoint_executed"`) on pools of
//! stand-in simulators started as processes: the same summary for one simulator, four,
//! and four of which one is killed mid-run; a pool that dies entirely keeps what was
//! learned; bad pools are refused with the place named; the in-process robot, one per
//! worker thread, gives the same summary on any thread count.

mod common;

use std::path::Path;
use std::process::Child;

use common::{cli, json, run_interrupted, serve, write};

const EXECUTED: &str = include_str!("../../../experiments/viapoint_executed.toml");

/// The shipped file on `endpoints`, with a short budget and a 1 s timeout.
fn on_pool(endpoints: &[String]) -> String {
    let list: Vec<String> = endpoints.iter().map(|e| format!("\"{e}\"")).collect();
    EXECUTED
        .replace("backend = \"kinematic\"", "backend = \"coppelia\"")
        .replace(
            "# endpoints = [\"tcp://127.0.0.1:23000\", \"tcp://127.0.0.1:23002\",\n#              \"tcp://127.0.0.1:23004\", \"tcp://127.0.0.1:23006\"]",
            &format!("endpoints = [{}]", list.join(", ")),
        )
        .replace("# timeout = 5.0", "timeout = 1.0")
        .replace("generations = 30", "generations = 8")
}

fn servers(n: usize, extra: &[&str]) -> (Vec<Child>, Vec<String>) {
    (0..n)
        .map(|_| {
            let (child, port) = serve("0.01", extra);
            (child, format!("tcp://127.0.0.1:{port}"))
        })
        .unzip()
}

fn stop(children: Vec<Child>) {
    for mut c in children {
        let _ = c.kill();
        let _ = c.wait();
    }
}

fn run(dir: &Path, name: &str, toml: &str) -> (std::process::Output, serde_json::Value) {
    let file = write(dir, &format!("{name}.toml"), toml);
    let out = dir.join(name);
    let o = cli(&[
        "run",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let s = json(&out.join("summary.json"));
    (o, s)
}

/// The summary without what depends on the pool or the clock.
fn comparable(mut s: serde_json::Value) -> serde_json::Value {
    let m = s.as_object_mut().unwrap();
    m.remove("simulators");
    m.remove("wall_time_s");
    s
}

#[test]
fn one_simulator_four_and_four_with_one_killed_give_the_same_summary() {
    let dir = tempfile::tempdir().unwrap();
    let (one, e1) = servers(1, &[]);
    let (o, s1) = run(dir.path(), "one", &on_pool(&e1));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    stop(one);
    assert_eq!(s1["complete"], true);
    assert_eq!(s1["evaluations"], 1 + 16 * 8);
    assert_eq!(s1["peak_speed_usage"].as_array().unwrap().len(), 7);
    assert!(
        s1["limit_usage"]["peak_usage"]["velocity"].is_array(),
        "{s1}"
    );
    assert_eq!(s1["simulators"]["evaluations"][0], s1["evaluations"]);

    let (four, e4) = servers(4, &[]);
    let (o, s4) = run(dir.path(), "four", &on_pool(&e4));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    stop(four);
    let total = s1["evaluations"].as_u64().unwrap();
    let used = s4["simulators"]["evaluations"].as_array().unwrap();
    assert_eq!(used.len(), 4);
    assert_eq!(used.iter().map(|v| v.as_u64().unwrap()).sum::<u64>(), total);

    // Three healthy simulators and one that dies after 400 requests (≈ 15 executions).
    let (mut killed, mut ek) = servers(3, &[]);
    let (dying, e) = servers(1, &["--crash-after", "400"]);
    killed.extend(dying);
    ek.insert(1, e[0].clone());
    let (o, sk) = run(dir.path(), "killed", &on_pool(&ek));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    stop(killed);
    let dropped = sk["simulators"]["dropped"].as_array().unwrap();
    assert_eq!(dropped.len(), 1, "{sk}");
    assert_eq!(dropped[0]["endpoint"], e[0].as_str());
    let done = sk["simulators"]["evaluations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .sum::<u64>()
        + dropped[0]["evaluations"].as_u64().unwrap();
    assert_eq!(done, total, "no evaluation lost or counted twice");

    assert_eq!(comparable(s1.clone()), comparable(s4));
    assert_eq!(comparable(s1), comparable(sk));
}

/// The in-process robot runs one copy per worker thread: one thread and two give the same
/// summary, and two threads execute on two robots, sharing the executions.
#[test]
fn the_in_process_robot_gives_the_same_summary_on_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(
        dir.path(),
        "k.toml",
        &EXECUTED.replace("generations = 30", "generations = 4"),
    );
    let mut summaries = Vec::new();
    for t in ["1", "2"] {
        let out = dir.path().join(format!("out{t}"));
        let o = cli(&[
            "run",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            t,
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        summaries.push(json(&out.join("summary.json")));
    }
    let robots = &summaries[1]["simulators"]["endpoints"];
    assert_eq!(robots.as_array().unwrap().len(), 2, "{robots}");
    let per_robot = summaries[1]["simulators"]["evaluations"]
        .as_array()
        .unwrap();
    let total: u64 = per_robot.iter().map(|v| v.as_u64().unwrap()).sum();
    assert_eq!(total, 1 + 16 * 4);
    assert_eq!(
        summaries[0]["simulators"]["endpoints"]
            .as_array()
            .unwrap()
            .len(),
        1
    );
    let strip = |s: &serde_json::Value| {
        let mut s = comparable(s.clone());
        s.as_object_mut().unwrap().remove("threads");
        s
    };
    assert_eq!(strip(&summaries[0]), strip(&summaries[1]));
}

/// Every simulator gone: exit 1, what was learned kept with "complete": false and the
/// reason naming the simulator.
#[test]
fn a_pool_that_dies_entirely_keeps_what_was_learned() {
    let dir = tempfile::tempdir().unwrap();
    let (dying, e) = servers(1, &["--crash-after", "700"]);
    let (o, s) = run(dir.path(), "dies", &on_pool(&e));
    stop(dying);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(s["complete"], false);
    let failure = s["failure"].as_str().unwrap();
    assert!(
        failure.contains("every simulator of the pool is gone") && failure.contains(&e[0]),
        "{failure}"
    );
    assert!(s["generations"].as_u64().unwrap() >= 1, "{s}");
    assert!(s["best_cost"].as_f64().unwrap().is_finite());
    assert!(dir.path().join("dies/executed.csv").is_file());
}

#[test]
fn bad_pools_are_refused_naming_the_place() {
    let dir = tempfile::tempdir().unwrap();
    let refused = |name: &str, toml: &str, expected: &str| {
        let file = write(dir.path(), &format!("{name}.toml"), toml);
        let o = cli(&[
            "run",
            file.to_str().unwrap(),
            "--out",
            dir.path().join(name).to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(expected), "{name}: {err}");
        assert!(!dir.path().join(name).join("summary.json").exists());
    };
    let twice = on_pool(&[
        "tcp://localhost:23300".into(),
        "tcp://127.0.0.1:23300".into(),
    ]);
    refused(
        "twice",
        &twice,
        "`endpoints[1]` and `endpoints[0]` name the same simulator",
    );
    refused(
        "empty",
        &on_pool(&[]),
        "`endpoints` must name 1 to 256 simulators",
    );
    refused(
        "port",
        &on_pool(&["tcp://127.0.0.1:0".into()]),
        "`endpoints[0]` must look like tcp://host:port",
    );
    let other = include_str!("../../../experiments/imitation.toml")
        .replace("backend = \"kinematic\"", "backend = \"coppelia\"")
        .replace(
            "# endpoint = \"tcp://127.0.0.1:23000\"",
            "endpoints = [\"tcp://127.0.0.1:23000\"]",
        )
        .replace("dt = 0.01               #", "# dt = 0.01             #");
    refused(
        "other",
        &other,
        "`endpoints` (a pool of simulators) is read only by kind = \"viapoint_executed\"",
    );
    let ik = on_pool(&["tcp://127.0.0.1:23300".into()])
        .replace("# timeout = 1.0", "")
        .replace(
            "dt = 0.01               #",
            "control = \"simulator_ik\"\ndt = 0.01 #",
        );
    refused(
        "ik",
        &ik,
        "control = \"simulator_ik\" moves the IK target one step at a time",
    );
    let negative = EXECUTED.replace("tracking = 1e5 ", "tracking = -1.0 ");
    refused(
        "negative",
        &negative,
        "[executed] `tracking` must be finite, ≥ 0",
    );
    let misplaced = include_str!("../../../experiments/viapoint.toml")
        .replace("[output]", "[executed]\ntracking = 1.0\n\n[output]");
    refused(
        "misplaced",
        &misplaced,
        "[executed] is read only by kind = \"viapoint_executed\"",
    );
    let exact = EXECUTED.replace("method = \"cmaes\"", "method = \"exact\"");
    refused(
        "exact",
        &exact,
        "the exact solver only knows the analytic cost",
    );
}

/// A simulator whose scene lacks cps's script, or an endpoint that is no simulator: an
/// error naming it, before anything is learned.
#[test]
fn a_scene_without_the_script_or_a_foreign_endpoint_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let (plain, e) = servers(1, &["--without-script"]);
    let (healthy, h) = servers(1, &[]);
    let file = write(
        dir.path(),
        "plain.toml",
        &on_pool(&[h[0].clone(), e[0].clone()]),
    );
    let o = cli(&[
        "run",
        file.to_str().unwrap(),
        "--out",
        dir.path().join("plain").to_str().unwrap(),
    ]);
    stop(plain);
    stop(healthy);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_ne!(o.status.code(), Some(0));
    assert!(
        err.contains(&e[0]) && err.contains("has no /Panda/cpsExecutor script"),
        "{err}"
    );
    // A listener that speaks no ZMQ.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let foreign = format!("tcp://{}", listener.local_addr().unwrap());
    let file = write(
        dir.path(),
        "foreign.toml",
        &on_pool(std::slice::from_ref(&foreign)),
    );
    let started = std::time::Instant::now();
    let o = cli(&[
        "run",
        file.to_str().unwrap(),
        "--out",
        dir.path().join("foreign").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_ne!(o.status.code(), Some(0));
    assert!(err.contains(&foreign), "{err}");
    assert!(started.elapsed() < std::time::Duration::from_secs(20));
}

/// Ctrl-C while the simulators work (each execution takes 2 s of simulated physics):
/// exit 130 within a few seconds, what was learned kept, marked incomplete.
#[test]
fn ctrl_c_stops_a_pool_between_candidates() {
    let dir = tempfile::tempdir().unwrap();
    let (slow, e) = servers(2, &["--step-cost", "2"]);
    let file = write(dir.path(), "slow.toml", &on_pool(&e));
    let out = dir.path().join("slow");
    let started = std::time::Instant::now();
    assert_eq!(run_interrupted(&file, &out), Some(130));
    stop(slow);
    assert!(started.elapsed() < std::time::Duration::from_secs(10));
    let s = json(&out.join("summary.json"));
    assert_eq!(s["complete"], false);
    assert_eq!(s["termination"], "interrupted");
    assert!(out.join("executed.csv").is_file());
}
