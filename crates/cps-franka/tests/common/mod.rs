//! franky-sim (MuJoCo FR3 behind the real FCI protocol) started by the tests.
//!
//! The interpreter is `$CPS_FRANKA_PYTHON`, else `target/franka-venv/bin/python` of this
//! workspace (what `.ci/run` creates: franky-sim and pylibfranka, pinned). Without it the
//! tests skip with a sentence, except under CI, where they fail.

#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// One simulator at a time: two MuJoCo loops on two cores would starve each other.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// The workspace's root (this file is included by the tests of several crates).
fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

pub fn python() -> Option<PathBuf> {
    let p = std::env::var_os("CPS_FRANKA_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("target/franka-venv/bin/python"));
    if p.exists() {
        return Some(p);
    }
    if std::env::var_os("CI").is_some() {
        panic!(
            "CI must provide franky-sim and pylibfranka: {} does not exist (.ci/run creates it)",
            p.display()
        );
    }
    eprintln!(
        "skipped: no franky-sim ({} missing; python3 -m venv target/franka-venv && target/franka-venv/bin/pip install franky-sim==1.0.4 pylibfranka==0.21.3)",
        p.display()
    );
    None
}

pub struct FrankySim {
    child: std::sync::Arc<Mutex<Child>>,
    pub host: String,
    _turn: MutexGuard<'static, ()>,
}

impl FrankySim {
    /// Starts franky-sim on `host` (a loopback address of this test's own) and waits until it
    /// serves; None when franky-sim is not installed (outside CI).
    pub fn start(host: &str) -> Option<Self> {
        let python = python()?;
        let turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        let script = workspace().join("crates/cps-franka/tests/sim_server.py");
        let mut child = Command::new(python)
            .arg(script)
            .args(["--host", host])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start the franky-sim server");
        let out = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = BufReader::new(out).read_line(&mut line);
            let _ = tx.send(line);
        });
        let line = rx.recv_timeout(Duration::from_secs(60)).unwrap_or_default();
        assert!(
            line.starts_with("ready"),
            "franky-sim did not start on {host}: {line:?}"
        );
        Some(FrankySim {
            child: std::sync::Arc::new(Mutex::new(child)),
            host: host.to_string(),
            _turn: turn,
        })
    }

    /// Kills the simulator (a robot that vanishes mid-motion).
    pub fn kill(&self) {
        let mut c = self.child.lock().unwrap_or_else(|e| e.into_inner());
        let _ = c.kill();
        let _ = c.wait();
    }

    /// A handle that kills the simulator from another thread.
    pub fn killer(&self) -> impl FnOnce() + Send + 'static {
        let child = self.child.clone();
        move || {
            let mut c = child.lock().unwrap_or_else(|e| e.into_inner());
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    /// Runs a Python snippet with this simulator's interpreter (pylibfranka), with `HOST`
    /// set; returns its standard output.
    pub fn python(&self, code: &str) -> String {
        let out = Command::new(python().unwrap())
            .args(["-c", code])
            .env("HOST", &self.host)
            .output()
            .expect("run python");
        assert!(
            out.status.success(),
            "python failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    }
}

impl Drop for FrankySim {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Waits until `f` holds, at most `timeout`.
pub fn eventually(timeout: Duration, mut f: impl FnMut() -> bool) -> bool {
    let start = Instant::now();
    while start.elapsed() < timeout {
        if f() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}
