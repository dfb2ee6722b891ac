//! Every command that drives a Franka, against franka-sim 1.1.7 with the robot's reflexes
//! on (its limits and discontinuities, its communication constraints) on a loaded machine:
//! a CPU hog on every core but one beside it and cps's loop at normal priority (`--realtime off`, how a
//! researcher without a realtime kernel runs), so the robot loses cycles and extrapolates
//! them, as a real FR3 does. `franka execute` (a trajectory out and back, a DMP stepped
//! online), `franka follow` (a chunk file, a live policy over UDP),
//! `franka identify`'s chirps and `franka guide`'s torques: each ends complete, with no
//! reflex, and the robot's extrapolated cycles in its report.

mod common;
use cps_testkit::franka_sim::{self, FrankaSim};
use cps_testkit::franky_sim as franky;

use std::path::Path;
use std::process::Command;

use common::{cli, state_q, stderr};
use cps_chunks::StandIn;

/// A command's report, after checking it ended complete (else what franka-sim said).
fn complete(sim: &FrankaSim, what: &str, o: &std::process::Output) -> serde_json::Value {
    assert!(
        o.status.success(),
        "{what}: {} {}{}\nfranka-sim: {:#?}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        stderr(o),
        sim.violations()
    );
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["complete"], true, "{what}: {r}");
    eprintln!("{what}: {}", r["timing"]);
    r
}

/// A CSV trajectory (t, q1..q7) from `from`: a quintic of `seconds` by `d`.
fn quintic(dir: &Path, name: &str, from: &[f64], d: [f64; 7], seconds: f64) -> String {
    let mut text = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
    let n = (seconds * 100.0) as usize;
    for k in 0..=n {
        let s = k as f64 / n as f64;
        let p = 10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5);
        let q: Vec<String> = (0..7)
            .map(|i| format!("{:.9}", from[i] + d[i] * p))
            .collect();
        text.push_str(&format!("{:.3},{}\n", s * seconds, q.join(",")));
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

#[test]
fn every_franka_command_runs_on_franka_sim_with_its_reflexes_on_a_loaded_machine() {
    if !franka_sim::inside(
        "every_franka_command_runs_on_franka_sim_with_its_reflexes_on_a_loaded_machine",
    ) {
        return;
    }
    let Some(python) = franky::python() else {
        return;
    };
    let Some(sim) = FrankaSim::start(true) else {
        return;
    };
    let host = sim.host.clone();
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.csv");
    let rec = rec.to_str().unwrap();
    let on = |args: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        a.extend(
            ["--host", &host, "--realtime", "off", "--json"]
                .iter()
                .map(|s| s.to_string()),
        );
        a
    };
    let run = |args: Vec<String>| {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        cli(&a)
    };
    let mut extrapolated = 0;
    let mut add = |timing: &serde_json::Value| {
        extrapolated += timing["extrapolated_cycles"].as_u64().unwrap();
    };

    // A gentle 4 s quintic (the example), out and back. (`--retime`, at 95 % of
    // every limit, is left to python/benchmarks/franka_lost_cycles.py: franka-sim applies a
    // command that comes late, over the run of cycles it ends, where a real robot drops it;
    // its history's acceleration is then an average, and a stream above two thirds of the
    // acceleration limit can be judged a jump there, never by a real robot.)
    let q0 = state_q(&host);
    let out = quintic(
        dir.path(),
        "out.csv",
        &q0,
        [0.4, 0.2, -0.3, 0.3, 0.2, -0.2, 0.3],
        4.0,
    );
    let r = complete(
        &sim,
        "execute",
        &run(on(&["franka", "execute", &out, "--record", rec, "--force"])),
    );
    add(&r["timing"]);
    let q1 = state_q(&host);
    let back: [f64; 7] = std::array::from_fn(|i| q0[i] - q1[i]);
    let back = quintic(dir.path(), "back.csv", &q1, back, 4.0);
    let r = complete(
        &sim,
        "execute back",
        &run(on(&[
            "franka", "execute", &back, "--record", rec, "--force",
        ])),
    );
    add(&r["timing"]);

    // A DMP imitating a swing, stepped online with phase stopping.
    let q = state_q(&host);
    let swing = quintic(
        dir.path(),
        "swing.csv",
        &q,
        [0.3, 0.0, 0.0, 0.2, 0.0, 0.0, 0.0],
        3.0,
    );
    let model = dir.path().join("swing.json");
    let o = cli(&[
        "imitate",
        &swing,
        "--columns",
        "q1,q2,q3,q4,q5,q6,q7",
        "--out",
        model.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r = complete(
        &sim,
        "execute a DMP online",
        &run(on(&[
            "franka",
            "execute",
            model.to_str().unwrap(),
            "--record",
            rec,
            "--force",
        ])),
    );
    add(&r["timing"]);

    // A policy stand-in's chunks at 30 Hz from a file ...
    let q = state_q(&host);
    let chunks = StandIn {
        horizon: 50,
        target_hz: 50.0,
        chunk_hz: 30.0,
        delay_s: (0.05, 0.15),
        noise_rad: 0.002,
        seed: 61,
    }
    .chunks(
        &|t: f64| {
            let s = 0.5 - 0.5 * (std::f64::consts::FRAC_PI_2 * t.max(0.0)).cos();
            let mut x = q.clone();
            x[0] += 0.3 * s;
            x[3] += 0.2 * s;
            x
        },
        0.0,
        3.0,
    );
    let file = dir.path().join("chunks.csv");
    std::fs::write(&file, cps_movement::chunks::write_chunks(&chunks, 7)).unwrap();
    let r = complete(
        &sim,
        "follow a chunk file",
        &run(on(&[
            "franka",
            "follow",
            file.to_str().unwrap(),
            "--rate",
            "50",
            "--record",
            rec,
            "--force",
        ])),
    );
    add(&r["timing"]);

    // ... and live from another process over UDP (the example client: 80 ms of inference
    // per chunk at 10 Hz).
    let follow = Command::new(env!("CARGO_BIN_EXE_cps-cli"))
        .args(on(&[
            "franka",
            "follow",
            "--listen",
            "127.0.0.1:7771",
            "--record",
            &dir.path().join("live.csv").to_string_lossy(),
        ]))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let client = Command::new(&python)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../python/examples/chunk_client.py"))
        .args(["--to", "127.0.0.1:7771", "--hz", "10", "--seconds", "3"])
        .output()
        .unwrap();
    assert!(client.status.success(), "client: {}", stderr(&client));
    let r = complete(&sim, "follow --listen", &follow.wait_with_output().unwrap());
    assert!(r["chunks"]["taken"].as_u64().unwrap() >= 10, "{r}");
    add(&r["timing"]);

    // identify's 9 s of chirps on every joint. What it fits from them is franka-sim's
    // controller, which need not be a PD one (it is not: the fit is refused); the
    // excitation itself must run to its end, its report beside the recording.
    let calibration = dir.path().join("calibration.toml");
    let excitation = dir.path().join("chirps.csv");
    let o = run(on(&[
        "franka",
        "identify",
        "--out",
        calibration.to_str().unwrap(),
        "--record",
        excitation.to_str().unwrap(),
    ]));
    let r = common::json(&dir.path().join("chirps.report.json"));
    assert_eq!(r["complete"], true, "identify: {r} ({})", stderr(&o));
    eprintln!("identify: {}", r["timing"]);
    add(&r["timing"]);

    // guide: the arm floats under cps's torques for a second.
    let guided = dir.path().join("guided.csv");
    let o = run(on(&[
        "franka",
        "guide",
        "--duration",
        "1",
        "--out",
        guided.to_str().unwrap(),
    ]));
    let r = complete(&sim, "guide", &o);
    add(&r["timing"]);

    assert!(extrapolated > 0, "the loaded machine lost no cycle");
    let violations = sim.violations();
    assert!(violations.is_empty(), "franka-sim reports: {violations:#?}");
}
