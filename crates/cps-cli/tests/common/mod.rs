//! Helpers shared by the CLI's end-to-end tests.
// Each test file uses a different subset.
#![allow(dead_code)]

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
