//! franky-sim (MuJoCo FR3 behind the real FCI protocol) started by the tests.
//!
//! The interpreter is `$CPS_FRANKA_PYTHON`, else `target/franka-venv/bin/python` of this
//! workspace (what `.ci/run` creates: franky-sim and pylibfranka, pinned). Without it the
//! tests skip with a sentence, except under CI, where they fail.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

/// Simulators running in this test program, and the turn of the next to start.
static RUNNING: (Mutex<usize>, Condvar) = (Mutex::new(0), Condvar::new());

/// How many simulators a test program runs at once: one per core. A franky-sim stepping
/// MuJoCo at 1 kHz takes a third of a core; two beside each other on two cores, with
/// cps's loops and another test program at a lower priority beside them, passed every
/// test (`test.sh`'s clock lane took 279 s instead of 358 s one at a time).
fn at_once() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

/// A simulator's places among those running (all of them for one that runs alone);
/// given back when dropped.
struct Turn(usize);

impl Turn {
    fn take(alone: bool) -> Turn {
        let places = if alone { at_once() } else { 1 };
        let (count, freed) = &RUNNING;
        let mut n = count.lock().unwrap_or_else(|e| e.into_inner());
        while *n + places > at_once() {
            n = freed.wait(n).unwrap_or_else(|e| e.into_inner());
        }
        *n += places;
        Turn(places)
    }
}

impl Drop for Turn {
    fn drop(&mut self) {
        let (count, freed) = &RUNNING;
        *count.lock().unwrap_or_else(|e| e.into_inner()) -= self.0;
        freed.notify_all();
    }
}

/// The workspace's root (this file is included by the tests of several crates).
fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// franky-sim's interpreter, or None (recorded as a skip; a failure under CI).
pub fn python() -> Option<PathBuf> {
    crate::interpreter(
        "CPS_FRANKA_PYTHON",
        "target/franka-venv/bin/python",
        "franky-sim and pylibfranka",
        "bash .ci/peers",
    )
}

/// franky-sim's interpreter and the folder of its robot model (`fr3.urdf`, `fr3.xml`,
/// `meshes/` with franka_description's collision meshes), or None (a skip; a failure
/// under CI).
pub fn assets() -> Option<(PathBuf, PathBuf)> {
    let python = python()?;
    let out = Command::new(&python)
        .args([
            "-c",
            "import franky_sim, os; print(os.path.dirname(franky_sim.__file__))",
        ])
        .output()
        .expect("run franky-sim's interpreter");
    assert!(
        out.status.success(),
        "franky_sim does not import: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()).join("assets");
    Some((python, dir))
}

/// A franky-sim server on its own loopback address, stopped when dropped; one per core
/// at a time in a test program.
pub struct FrankySim {
    child: std::sync::Arc<Mutex<Child>>,
    /// The address it serves on.
    pub host: String,
    /// The simulator's standard output, line by line (after `ready`).
    lines: Mutex<std::sync::mpsc::Receiver<String>>,
    /// Where MuJoCo's ground truth is written (with `SimOptions::truth`).
    truth: Option<PathBuf>,
    _turn: Turn,
}

/// What the simulated world holds beyond the arm.
#[derive(Debug, Clone, Copy, Default)]
pub struct SimOptions {
    /// A table under the hand with its top at this height (m): x in [0.35, 0.75],
    /// y in [-0.3, 0.3].
    pub table: Option<f64>,
    /// The table's sliding friction coefficient (None: MuJoCo's 1).
    pub friction: Option<f64>,
    /// Log MuJoCo's ground truth per step (contact force, tool centre point).
    pub truth: bool,
    /// A box (a shelf) centred at x, y, z in the base frame, sx × sy × sz metres, whose
    /// contacts with the robot are counted ([`FrankySim::box_contacts`]).
    pub shelf: Option<[f64; 6]>,
    /// The only simulator of its test program while it runs: for runs compared tick by
    /// tick with another client's (a tick that comes late to one run and not to the other
    /// parts them by a few milliradians).
    pub alone: bool,
}

/// One simulation step's ground truth (see sim_server.py).
#[derive(Debug, Clone, Copy)]
pub struct Truth {
    /// The message id of the robot state sent after the step.
    pub id: u64,
    /// The table's force on the robot, world axes (N).
    pub force: [f64; 3],
    /// The contacts' normal forces summed (N).
    pub normal: f64,
    /// The hand's tool centre point (m).
    pub tcp: [f64; 3],
    /// The joint positions (rad).
    pub q: [f64; 7],
}

impl FrankySim {
    /// Starts franky-sim on `host` (a loopback address of this test's own) and waits until it
    /// serves; None when franky-sim is not installed (outside CI).
    pub fn start(host: &str) -> Option<Self> {
        Self::start_with(host, SimOptions::default())
    }

    /// Starts franky-sim on `host` with a table or the ground truth logged.
    pub fn start_with(host: &str, options: SimOptions) -> Option<Self> {
        let python = python()?;
        let turn = Turn::take(options.alone);
        let script = workspace().join("crates/cps-franka/tests/sim_server.py");
        let mut command = Command::new(python);
        command.arg(script).args(["--host", host]);
        if let Some(top) = options.table {
            command.args(["--table", &top.to_string()]);
        }
        if let Some(mu) = options.friction {
            command.args(["--friction", &mu.to_string()]);
        }
        if let Some(b) = options.shelf {
            command.arg("--box").args(b.iter().map(|v| v.to_string()));
        }
        let truth = options.truth.then(|| {
            std::env::temp_dir().join(format!("cps-truth-{}-{host}.csv", std::process::id()))
        });
        if let Some(t) = &truth {
            command.arg("--truth").arg(t);
        }
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start the franky-sim server");
        let out = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let line = rx.recv_timeout(Duration::from_secs(60)).unwrap_or_default();
        assert!(
            line.starts_with("ready"),
            "franky-sim did not start on {host}: {line:?}"
        );
        Some(FrankySim {
            child: std::sync::Arc::new(Mutex::new(child)),
            host: host.to_string(),
            lines: Mutex::new(rx),
            truth,
            _turn: turn,
        })
    }

    /// Sends one line to the simulator (`push FX FY FZ`, `lead X Y Z S K D`, `release`).
    pub fn send(&self, line: &str) {
        use std::io::Write;
        let mut c = self.child.lock().unwrap_or_else(|e| e.into_inner());
        let stdin = c.stdin.as_mut().expect("the simulator's input");
        writeln!(stdin, "{line}")
            .and_then(|_| stdin.flush())
            .expect("write to the simulator");
    }

    /// MuJoCo's ground truth so far (the simulator writes it out first).
    pub fn truth(&self) -> Vec<Truth> {
        let path = self.truth.as_ref().expect("started with SimOptions::truth");
        self.send("flush");
        let rx = self.lines.lock().unwrap_or_else(|e| e.into_inner());
        let line = rx.recv_timeout(Duration::from_secs(10)).unwrap_or_default();
        assert_eq!(line, "flushed", "the simulator did not write its truth out");
        let text = std::fs::read_to_string(path).expect("read the truth file");
        text.lines()
            .skip(1)
            .filter_map(|l| {
                let v: Vec<f64> = l
                    .split(',')
                    .map(|x| x.parse().ok())
                    .collect::<Option<_>>()?;
                (v.len() == 15).then(|| Truth {
                    id: v[0] as u64,
                    force: [v[1], v[2], v[3]],
                    normal: v[4],
                    tcp: [v[5], v[6], v[7]],
                    q: std::array::from_fn(|i| v[8 + i]),
                })
            })
            .collect()
    }

    /// The box's contacts with the robot so far (MuJoCo's contact list, every step): how
    /// many steps had one, and the robot's geoms it touched.
    pub fn box_contacts(&self) -> (u64, Vec<String>) {
        self.send("contacts");
        let rx = self.lines.lock().unwrap_or_else(|e| e.into_inner());
        let line = rx.recv_timeout(Duration::from_secs(10)).unwrap_or_default();
        let mut words = line.split_whitespace();
        assert_eq!(
            words.next(),
            Some("contacts"),
            "the simulator said {line:?}"
        );
        let steps = words
            .next()
            .and_then(|w| w.parse().ok())
            .expect("a step count");
        let geoms = match words.next() {
            Some("-") | None => Vec::new(),
            Some(g) => g.split(',').map(str::to_string).collect(),
        };
        (steps, geoms)
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
        run_python(code, &self.host)
    }
}

/// Runs a Python snippet with franky-sim's interpreter (pylibfranka), `HOST` set to
/// `host`; returns its standard output (panics naming Python's error when it fails).
pub fn run_python(code: &str, host: &str) -> String {
    let out = Command::new(python().expect("franky-sim's interpreter"))
        .args(["-c", code])
        .env("HOST", host)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "python failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("UTF-8")
}

impl Drop for FrankySim {
    fn drop(&mut self) {
        self.kill();
        if let Some(t) = &self.truth {
            let _ = std::fs::remove_file(t);
        }
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
