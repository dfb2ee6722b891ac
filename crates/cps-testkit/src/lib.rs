//! Support for cps's own tests (a dev-dependency, never shipped): [`skip`], how a test
//! whose peer is missing says so; [`franky_sim`], franky-sim started for a test;
//! [`franka_sim`], franka-sim (the robot's reflexes and packet-loss behaviour) in a
//! network namespace of the test's own, on a loaded machine; and [`ros2_graph`], a test in
//! a network namespace of its own with a DDS or ROS 2 peer.
//!
//! Many of cps's tests meet a real peer: franky-sim behind the Franka protocol, CycloneDDS
//! and rclpy in a network namespace, MuJoCo, a headless Chromium, the official CoppeliaSim
//! client. `.ci/peers` installs them all; a fresh clone has none. A test whose peer is
//! missing calls [`skip`]:
//!
//! - under CI (`CI` set) that is a failure: CI must run every test;
//! - elsewhere the test returns having checked nothing, and says so: a sentence on its
//!   standard error, and a line in the file `$CPS_SKIP_LOG` names, so that the test command
//!   of the README (`bash test.sh`, which sets it) counts the test as skipped, not passed,
//!   and closes with how many were skipped and the command that installs their peers.
//!
//! ```no_run
//! fn franky_sim_python() -> Option<std::path::PathBuf> {
//!     let p = std::path::PathBuf::from("target/franka-venv/bin/python");
//!     if p.exists() {
//!         return Some(p);
//!     }
//!     // Outside CI: recorded as skipped; under CI: a failure naming what is missing.
//!     cps_testkit::skip(&format!("no franky-sim ({} missing)", p.display()));
//!     None
//! }
//! # let _ = franky_sim_python();
//! ```

use std::io::Write;
use std::path::PathBuf;
use std::process::Command;

pub mod franka_sim;
pub mod franky_sim;
pub mod ros2_graph;

/// Set in a test's run inside its network namespace ([`rerun_in_namespace`]).
pub const IN_NETNS: &str = "CPS_IN_NETNS";

/// The environment variable naming the file skips are recorded in.
pub const SKIP_LOG: &str = "CPS_SKIP_LOG";

/// The command that installs every peer the tests meet.
pub const INSTALL_PEERS: &str = "bash .ci/peers";

/// Says that the running test could not meet its peer (`why`, a sentence naming what is
/// missing): a failure under CI; elsewhere a line on standard error and in `$CPS_SKIP_LOG`
/// (the test's name, then `why`). The caller then returns without checking anything.
///
/// # Panics
/// Under CI (`CI` set), always: a missing peer there is a broken install.
pub fn skip(why: &str) {
    if std::env::var_os("CI").is_some() {
        panic!("CI must run this test, but {why} (`{INSTALL_PEERS}` installs every peer)");
    }
    let test = std::thread::current()
        .name()
        .unwrap_or("a test")
        .to_string();
    eprintln!("skipped: {why} (`{INSTALL_PEERS}` installs every peer)");
    if let Some(path) = std::env::var_os(SKIP_LOG) {
        // One short line, appended: concurrent tests do not interleave within it.
        if let Ok(mut f) = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
        {
            let _ = writeln!(f, "{test}: {why}");
        }
    }
}

/// A peer's interpreter: `$var`, else `default` under this workspace, if it exists; None
/// otherwise (a skip naming `what` and how to install it, `install`; a failure under CI).
pub fn interpreter(var: &str, default: &str, what: &str, install: &str) -> Option<PathBuf> {
    let p = std::env::var_os(var).map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../..")
            .join(default)
    });
    if p.exists() {
        return Some(p);
    }
    skip(&format!("no {what} ({} missing; {install})", p.display()));
    None
}

/// Runs `test` (this test binary's test of that name) again in a network namespace of its
/// own (`unshare -n`, then `setup`, a shell command bringing its interfaces up), with
/// [`IN_NETNS`] set, and checks that it passed there. Without the right to make a
/// namespace (root is needed) the test is skipped (a failure under CI), `what` naming the
/// tests that need it.
pub fn rerun_in_namespace(test: &str, setup: &str, what: &str) {
    let exe = std::env::current_exe().expect("the test binary's path");
    let out = Command::new("unshare")
        .args(["-n", "sh", "-c", &format!("{setup} && exec \"$0\" \"$@\"")])
        .arg(&exe)
        .args([
            test,
            "--exact",
            "--nocapture",
            "--test-threads=1",
            "--include-ignored",
        ])
        .env(IN_NETNS, "1")
        .output();
    let out = match out {
        Ok(o) => o,
        Err(e) => {
            skip(&format!("cannot run unshare for a network namespace: {e}"));
            return;
        }
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() && stderr.contains("unshare failed") {
        skip(&format!(
            "no network namespace for {what} (root is needed): {stderr}"
        ));
        return;
    }
    print!("{stdout}");
    eprint!("{stderr}");
    assert!(
        out.status.success(),
        "{test} failed inside its network namespace"
    );
    assert!(
        stdout.contains("1 passed"),
        "{test} did not run inside its namespace:\n{stdout}"
    );
}
