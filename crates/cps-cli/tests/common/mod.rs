//! Helpers shared by the CLI's end-to-end tests.
// Each test file uses a different subset.
#![allow(dead_code)]

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

/// Runs `cps-cli` with `args` to the end.
pub fn cli(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cps-cli"))
        .args(args)
        .output()
        .expect("run cps-cli")
}

/// A path in the repository.
pub fn repo(path: &str) -> String {
    format!("{}/../../{path}", env!("CARGO_MANIFEST_DIR"))
}

/// Writes an experiment file into `dir`; a scene path relative to `experiments/` is
/// pointed at the repository's scene.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    let scene = repo("configs/scenes/thesis.toml");
    std::fs::write(
        &p,
        text.replace("\"../configs/scenes/thesis.toml\"", &format!("{scene:?}")),
    )
    .unwrap();
    p
}

/// A JSON file.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Starts `cps-cli run file --out out --quiet`, sends it SIGINT (Ctrl-C) after 1.5 s
/// and returns its exit code.
/// `cps-cli run FILE --out OUT --quiet`: its output and its standard error.
pub fn run_quiet(file: &Path, out: &Path) -> (Output, String) {
    let o = cli(&[
        "run",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    (o, err)
}

pub fn run_interrupted(file: &Path, out: &Path) -> Option<i32> {
    run_signalled(file, out, "INT")
}

/// Runs `cps-cli run` and sends it `signal` (`INT`, `TERM`) after 1.5 s; its exit code.
#[allow(dead_code)]
pub fn run_signalled(file: &Path, out: &Path, signal: &str) -> Option<i32> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_cps-cli"))
        .args([
            "run",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let killed = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    child.wait().unwrap().code()
}

/// Starts `cps-cli sim serve` on a free port with time step `dt` and `extra` options;
/// returns it and its port.
pub fn serve(dt: &str, extra: &[&str]) -> (std::process::Child, String) {
    let mut server = std::process::Command::new(env!("CARGO_BIN_EXE_cps-cli"))
        .args(["sim", "serve", "--bind", "127.0.0.1:0", "--dt", dt])
        .args(extra)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(server.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    if extra.contains(&"--ik-following") {
        assert!(line.contains("followed by the tip"), "{line}");
    }
    let port = line
        .split("tcp://127.0.0.1:")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .unwrap_or_else(|| panic!("no endpoint in {line:?}"))
        .to_string();
    (server, port)
}

/// A command's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A command's standard output parsed as JSON.
pub fn stdout_json(o: &Output) -> serde_json::Value {
    serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&o.stdout)))
}

/// Reads the named columns of a CSV file.
pub fn csv_columns(path: &std::path::Path, names: &[&str]) -> Vec<Vec<f64>> {
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

/// Runs `toml` (written as `NAME.toml` in `dir`) and checks it is refused as bad input:
/// exit 2, `expected` in the error, nothing written.
pub fn refused(dir: &Path, name: &str, toml: &str, expected: &str) -> String {
    let file = write(dir, &format!("{name}.toml"), toml);
    let out = dir.join(name);
    let (o, err) = run_quiet(&file, &out);
    assert_eq!(o.status.code(), Some(2), "{name}: {err}");
    assert!(err.contains(expected), "{name}: {err}");
    assert!(!out.join("summary.json").exists(), "{name}");
    err
}

/// A Franka's joint positions from `cps-cli franka state`, checked idle and without
/// errors.
pub fn state_q(host: &str) -> Vec<f64> {
    let o = cli(&["franka", "state", "--host", host, "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["robot_mode"], "idle");
    assert_eq!(v["errors"].as_array().unwrap().len(), 0);
    v["q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The tool position `cps-cli fk --robot ROBOT --tool hand` gives at `q` (the robot's base
/// frame, m).
pub fn hand_at(robot: &str, q: &[f64]) -> [f64; 3] {
    let q: Vec<String> = q.iter().map(f64::to_string).collect();
    let fk = stdout_json(&cli(&[
        "fk",
        "--robot",
        robot,
        "--tool",
        "hand",
        "--q",
        &q.join(","),
        "--json",
    ]));
    let p: Vec<f64> = serde_json::from_value(fk["position"].clone()).unwrap();
    [p[0], p[1], p[2]]
}

/// A scene of `model` (its base the world's origin, its hand the tool, standing at
/// `initial_q`) with one obstacle, `post`: a box of `size` centred at `at`; written as
/// `NAME.toml` in `dir`.
pub fn post_scene(
    dir: &Path,
    name: &str,
    model: &str,
    initial_q: &[f64],
    at: [f64; 3],
    size: [f64; 3],
) -> PathBuf {
    let q: Vec<String> = initial_q.iter().map(f64::to_string).collect();
    let text = format!(
        "[robot]\nmodel = \"{model}\"\ntool = \"hand\"\ninitial_q = [{}]\n\n[[obstacle]]\nname = \"post\"\nshape = \"box\"\nxyz = [{}, {}, {}]\nsize = [{}, {}, {}]\n",
        q.join(", "),
        at[0],
        at[1],
        at[2],
        size[0],
        size[1],
        size[2]
    );
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

/// The thesis's scene with its Panda starting at Franka's home pose, not the thesis's
/// stretched arm (from which inverse kinematics folds the wrist, link7 into link5's hull).
pub fn thesis_scene_at_home() -> String {
    let thesis = std::fs::read_to_string(repo("configs/scenes/thesis.toml")).unwrap();
    let stretched = "initial_q = [0.0, 0.0, 0.0, 0.0, 0.0, 1.5707963267948966, 0.7853981633974483]";
    assert!(thesis.contains(stretched));
    thesis.replace(
        stretched,
        "initial_q = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]",
    )
}
