//! franka-sim 1.1.7 started by the tests: a second, independent simulator of the FCI v10
//! protocol that judges every command as the real Control does — the joint and Cartesian
//! limits and discontinuities (`--enforce-motion-limits`), and the lost cycles
//! (`--enforce-comm-constraints`): a cycle without a command in time is
//! extrapolated at constant acceleration, and the next command judged against that, as a
//! real FR3 does. franky-sim does neither, so the tests of cps's 1 kHz loop against the
//! robot's own rules run here.
//!
//! franka-sim binds 0.0.0.0:1337 (no address of its own per robot), so a test runs in a
//! network namespace of its own: it calls [`inside`] first (outside, the test re-runs
//! itself under `unshare -n` and returns false), then [`FrankaSim::start`], which starts
//! the server with both enforcements on franky-sim's FR3 model (offline: the wheel's MJCF
//! with its meshes; no download) and, with `load`, a CPU hog on every core but one, so
//! that the loop under test waits for a core and the robot loses cycles — the condition a
//! client of a real FR3 on a normal kernel meets. (One core is left to the simulator: on
//! two cores a second hog made the loop later, p99 1.0 ms against 0.5 ms, but not its
//! answers withheld as late, its dropped commands or the cycles the robot extrapolated,
//! in three runs of each of `crates/cps-franka/tests/franka_sim.rs`'s motions; it cost
//! 37 s of CPU in the tests, BENCHMARKS › Where a cold CI's time goes.) The simulator itself runs at
//! a realtime priority where that is permitted (`chrt -f 20`): it stands for the robot's
//! Control, a realtime machine of its own that no load on the client's reaches. The server's interpreter is
//! `$CPS_FRANKA_SIM_PYTHON`, else `target/franka-sim-venv/bin/python` (what `.ci/peers`
//! makes, versions pinned in `crates/cps-franka/tests/franka-sim-requirements.txt`: it
//! needs MuJoCo 3.2, franky-sim's venv has MuJoCo 4); pylibfranka, the reference client,
//! runs from franky-sim's venv ([`crate::franky_sim::python`]).

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// franka-sim's interpreter, or None (recorded as a skip; a failure under CI).
pub fn python() -> Option<PathBuf> {
    crate::interpreter(
        "CPS_FRANKA_SIM_PYTHON",
        "target/franka-sim-venv/bin/python",
        "franka-sim",
        "python3 -m venv target/franka-sim-venv && target/franka-sim-venv/bin/pip install -r crates/cps-franka/tests/franka-sim-requirements.txt",
    )
}

/// Whether this process is the test's run inside its network namespace. Outside, runs
/// `test` (this test binary's test of that name) in a new namespace with its loopback up
/// and checks that it passed; returns false.
pub fn inside(test: &str) -> bool {
    if std::env::var_os(crate::IN_NETNS).is_some() {
        return true;
    }
    if python().is_none() || crate::franky_sim::assets().is_none() {
        return false;
    }
    crate::rerun_in_namespace(test, "ip link set lo up", "the franka-sim tests");
    false
}

/// A franka-sim server with the robot's reflexes on (in this test's network namespace, on
/// 127.0.0.1), and the CPU hogs beside it; all stopped when dropped.
pub struct FrankaSim {
    server: Child,
    hogs: Vec<Child>,
    log: PathBuf,
    dir: PathBuf,
    /// The address it serves on.
    pub host: String,
}

impl FrankaSim {
    /// Starts the server (only [`inside`] a namespace) and waits until it serves; with
    /// `load`, a CPU hog on every core but one beside it. None when franka-sim or franky-sim's model
    /// is not installed (outside CI).
    pub fn start(load: bool) -> Option<Self> {
        assert!(
            std::env::var_os(crate::IN_NETNS).is_some(),
            "franka-sim binds 0.0.0.0:1337: start it inside the test's own network namespace (franka_sim::inside)"
        );
        let python = python()?;
        let (_, assets) = crate::franky_sim::assets()?;
        // A folder this harness creates (never one that was there: it is removed whole on
        // drop).
        let dir = (0u32..)
            .map(|k| {
                std::env::temp_dir().join(format!("cps-franka-sim-{}-{k}", std::process::id()))
            })
            .find(|d| match std::fs::create_dir(d) {
                Ok(()) => true,
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => false,
                Err(e) => panic!("a temporary folder {}: {e}", d.display()),
            })
            .expect("a free temporary folder name");
        // franky-sim's FR3 with its meshes where the model can find them.
        let xml = std::fs::read_to_string(assets.join("fr3.xml")).expect("franky-sim's fr3.xml");
        let meshes = assets.join("meshes");
        let xml = xml.replace(
            "meshdir=\"assets\"",
            &format!("meshdir=\"{}\"", meshes.display()),
        );
        let model = dir.join("fr3.xml");
        std::fs::write(&model, xml).expect("write the model");
        let log = dir.join("server.log");
        // The simulator stands for the robot's Control, a realtime machine of its own: it
        // runs at a realtime priority (where permitted), so the load falls on the client's
        // side, as it does beside a real arm.
        let realtime = Command::new("chrt")
            .args(["-f", "20", "true"])
            .status()
            .is_ok_and(|s| s.success());
        let mut server = if realtime {
            let mut c = Command::new("chrt");
            c.args(["-f", "20"]).arg(python);
            c
        } else {
            Command::new(python)
        };
        let server = server
            .args([
                "-m",
                "franka_sim.run_server",
                "--no-gripper",
                "--enforce-motion-limits",
                "--enforce-comm-constraints",
            ])
            .env("FR3_MJCF", &model)
            .stdin(Stdio::null())
            .stdout(Stdio::from(
                std::fs::File::create(&log).expect("the server's log"),
            ))
            .stderr(Stdio::from(
                std::fs::OpenOptions::new()
                    .append(true)
                    .open(&log)
                    .expect("the server's log"),
            ))
            .spawn()
            .expect("start franka-sim");
        let mut sim = FrankaSim {
            server,
            hogs: Vec::new(),
            log,
            dir,
            host: "127.0.0.1".into(),
        };
        let start = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", 1337)).is_err() {
            if let Ok(Some(status)) = sim.server.try_wait() {
                panic!("franka-sim exited ({status}):\n{}", sim.log_text());
            }
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "franka-sim did not serve within 60 s:\n{}",
                sim.log_text()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        if load {
            let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
            for _ in 0..cores.saturating_sub(1).max(1) {
                sim.hogs.push(
                    Command::new("sh")
                        .args(["-c", "while :; do :; done"])
                        .stdin(Stdio::null())
                        .stdout(Stdio::null())
                        .spawn()
                        .expect("a CPU hog"),
                );
            }
        }
        Some(sim)
    }

    /// The server's log so far.
    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// The server's lines naming a violated limit, a reflex or an aborted motion (none for
    /// a client that keeps the robot's rules).
    pub fn violations(&self) -> Vec<String> {
        self.log_text()
            .lines()
            .filter(|l| {
                l.contains("violated")
                    || l.contains("aborting the motion")
                    || l.contains("communication_constraints_violation")
                    || l.contains("kReflexAborted")
            })
            .map(str::to_string)
            .collect()
    }

    /// Runs a Python snippet with franky-sim's interpreter (pylibfranka, the official
    /// client), with `HOST` set; returns its standard output.
    pub fn pylibfranka(&self, code: &str) -> String {
        crate::franky_sim::run_python(code, &self.host)
    }
}

impl Drop for FrankaSim {
    fn drop(&mut self) {
        if std::thread::panicking() {
            // A failing test shows what the simulator said last.
            let log = self.log_text();
            let tail: Vec<&str> = log.lines().rev().take(40).collect();
            eprintln!("franka-sim's log, its end:");
            for line in tail.iter().rev() {
                eprintln!("  {line}");
            }
        }
        for hog in &mut self.hogs {
            let _ = hog.kill();
            let _ = hog.wait();
        }
        let _ = self.server.kill();
        let _ = self.server.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
