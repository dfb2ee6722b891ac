//! The hostile sweep of 2026-12-05, case by case, as a user meets it: each hostile file
//! or flag is refused in one sentence naming its place, exit 2, within seconds, without
//! a panic, an abort, a hang or a number hundreds of digits long.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs `cps-cli args` in `dir`, killed after 60 s (a hang fails the test): its exit code
/// and standard error.
fn run_in(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_cps-cli"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            child.kill().ok();
            panic!("cps-cli {args:?} still runs after 60 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Asserts a refusal: exit 2, one sentence holding `needle`, no panic, no long number.
fn refused(dir: &Path, args: &[&str], needle: &str) {
    let (code, err) = run_in(dir, args);
    assert_eq!(code, Some(2), "cps-cli {args:?}: {err}");
    assert!(err.contains(needle), "cps-cli {args:?}: {err}");
    assert!(!err.contains("panicked"), "cps-cli {args:?}: {err}");
    let longest = err
        .split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0);
    assert!(longest < 20, "a number of {longest} digits: {err}");
}

const HEADER: &str = "t,q1,q2,q3,q4,q5,q6,q7\n";
const HOME: &str = "0,-0.785,0,-2.356,0,1.571,0.785";

fn trajectory(dir: &Path, name: &str, last: &str) -> String {
    let text = format!("{HEADER}0,{HOME}\n1,{HOME}\n{last},{HOME}\n");
    std::fs::write(dir.join(name), text).unwrap();
    name.to_string()
}

#[test]
fn trajectories_spanning_years_are_refused_before_they_are_resampled() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 1e7 s at 1 kHz was a 240 GB allocation and an abort; 1e300 s a panic.
    for last in ["10000000", "1e300"] {
        let f = trajectory(d, &format!("t{last}.csv"), last);
        for args in [
            vec!["limits", "check", &f],
            vec!["collide", &f],
            vec!["retime", &f, "--out", "r.csv"],
            vec!["export", &f, "--out", "e.csv", "--format", "csv-1khz"],
        ] {
            refused(
                d,
                &args,
                "a trajectory cps checks or sends is at most 10 million commands",
            );
        }
    }
    assert!(!d.join("r.csv").exists() && !d.join("e.csv").exists());
}

#[test]
fn a_frame_rate_of_billions_is_refused_before_the_frames_are_made() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let f = trajectory(d, "rec.csv", "2");
    // 288 GB, then an abort.
    refused(
        d,
        &[
            "lerobot",
            "write",
            &f,
            "--out",
            "ds",
            "--task",
            "t",
            "--fps",
            "4000000000",
        ],
        "--fps 4000000000: the episodes' frames: 8e9 would be held in memory",
    );
    let huge = trajectory(d, "huge.csv", "1e300");
    // Printed as 300 digits.
    refused(
        d,
        &["lerobot", "write", &huge, "--out", "ds", "--task", "t"],
        "its samples are 1e300 s apart",
    );
    assert!(!d.join("ds").exists());
}

#[test]
fn a_recording_with_a_time_of_1e300_is_bad_input_said_briefly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut text = String::from("t");
    for p in ["q", "dq", "tau", "q_d"] {
        for j in 1..=7 {
            text += &format!(",{p}{j}");
        }
    }
    text.push('\n');
    for k in 0..2000 {
        let t = if k == 1999 { 1e300 } else { k as f64 * 1e-3 };
        let q: Vec<String> = (0..7)
            .map(|j| format!("{}", 0.1 * (t * 3.0 + j as f64).sin()))
            .collect();
        let q = q.join(",");
        text += &format!("{t},{q},0,0,0,0,0,0,0,0.1,0.1,0.1,0.1,0.1,0.1,0.1,{q}\n");
    }
    std::fs::write(d.join("rec.csv"), text).unwrap();
    // Exit 1 and a number of 300 digits before.
    refused(
        d,
        &["identify", "rec.csv", "--out", "c.toml"],
        "samples 1999 and 2000 are 1e300 s apart",
    );
    assert!(!d.join("c.toml").exists());
}

/// A scene of the FR3 at the origin with one box `size` at `xyz`.
fn scene_with_box(dir: &Path, name: &str, size: &str, xyz: &str) -> String {
    let text = format!(
        "[robot]\nmodel = \"fr3\"\ninitial_q = [0, -0.785, 0, -2.356, 0, 1.571, 0.785]\n\n[[obstacle]]\nname = \"plate\"\nshape = \"box\"\nsize = {size}\nxyz = {xyz}\n"
    );
    std::fs::write(dir.join(name), text).unwrap();
    name.to_string()
}

#[test]
fn shapes_of_absurd_size_are_refused_and_the_largest_accepted_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let f = trajectory(d, "still.csv", "2");
    // A 1e15 m plate through the arm, a 1e154 m box: "ok: every pair keeps 5.0 mm", exit 0.
    for (size, shown) in [("[1e15, 1e15, 0.01]", "1e15"), ("[1e154, 1, 1]", "1e154")] {
        let s = scene_with_box(d, "big.toml", size, "[0, 0, 0.5]");
        refused(
            d,
            &["collide", &f, "--scene", &s],
            &format!("the size {shown} m is larger than the 100 m of a robot's cell"),
        );
    }
    let s = scene_with_box(d, "far.toml", "[1, 1, 1]", "[1e160, 0, 0]");
    refused(
        d,
        &["collide", &f, "--scene", &s],
        "`xyz` places it 1e160 m away",
    );
    // The largest plate accepted, through the arm at 0.5 m, is found as deep in it as a
    // plate of 1 m: the distances hold at every size accepted.
    let depth = |size: &str| {
        let s = scene_with_box(d, "floor.toml", size, "[0, 0, 0.5]");
        let (code, err) = run_in(d, &["collide", &f, "--scene", &s]);
        assert_eq!(code, Some(2), "{err}");
        let at = err.find("`plate` are ").expect("the plate named") + 12;
        err[at..].split(" mm").next().unwrap().to_string()
    };
    let small = depth("[1, 1, 0.01]");
    assert_eq!(depth("[100, 100, 0.01]"), small);
    assert!(small.parse::<f64>().unwrap() > 10.0, "{small}");
}
