//! `[robot] backend = "dynamics"`: the thesis's joint via-point experiment executed on the
//! Panda with dynamics under a joint-level controller, deterministic; the shipped dynamics
//! experiment learned on the executions, and its command streamed to franky-sim (a MuJoCo
//! FR3 behind the real protocol); bad robot sections named with their place.

mod common;
use cps_testkit::franky_sim as sim;

use common::{csv_columns, json, repo, run_quiet as run, write};

const SHIPPED: &str = include_str!("../../../experiments/viapoint_joint.toml");
const BACKEND: &str = "backend = \"kinematic\"   # or \"coppelia\"";

/// The shipped experiment on the dynamics robot with `extra` keys in `[robot]`, learned
/// on the model (what the controller does with a model-learned movement).
fn on_dynamics(extra: &str) -> String {
    let line = SHIPPED
        .lines()
        .find(|l| l.starts_with(BACKEND))
        .expect("the shipped experiment names its backend");
    SHIPPED
        .replace(line, &format!("backend = \"dynamics\"\n{extra}"))
        .replace("[joint]\n", "[joint]\nlearn_on = \"model\"\n")
}

/// The recorded tool's largest distance from the model's tool at the same time (m).
fn executed_gap(out: &std::path::Path) -> f64 {
    json(&out.join("summary.json"))["execution"]["max_tool_deviation_m"]
        .as_f64()
        .expect("the summary says how far the executed tool was from the model's")
}

#[test]
fn the_joint_experiment_runs_on_the_dynamics_robot_and_shows_its_controller() {
    let dir = tempfile::tempdir().unwrap();
    let go = |name: &str, extra: &str| {
        let file = write(dir.path(), &format!("{name}.toml"), &on_dynamics(extra));
        let out = dir.path().join(name);
        let (o, err) = run(&file, &out);
        assert!(o.status.success(), "{name}: {err}");
        out
    };
    let pd = go("pd", "");
    let summary = json(&pd.join("summary.json"));
    let backend = summary["backend"].as_str().unwrap();
    assert!(
        backend.starts_with("dynamics (in-process, joint_pd controller, franky-sim drive"),
        "{backend}"
    );
    // franky-sim's PD lags the movement by 0.1 s: centimetres at its speed.
    let pd_gap = executed_gap(&pd);
    assert!(pd_gap > 0.01, "{pd_gap} m");
    // Computed torque feeds the model's dynamics forward: within a millimetre while the
    // model is the arm (rigid drives); the joints' friction, which its model does not
    // know, leaves millimetres — still far closer than the PD.
    let ct = go("ct", "controller = \"computed_torque\"\ndrive = \"rigid\"");
    let ct_gap = executed_gap(&ct);
    assert!(ct_gap < 1e-3, "{ct_gap} m");
    let ct_friction = executed_gap(&go("ctf", "controller = \"computed_torque\""));
    assert!(
        ct_friction > ct_gap && ct_friction < pd_gap / 3.0,
        "{ct_friction} m"
    );
    // The same file, the same run, bit for bit (noise from its seed included).
    let noisy = "noise = 1e-4\nseed = 3";
    let (a, b) = (go("a", noisy), go("b", noisy));
    let joints: Vec<String> = (1..=7).map(|i| format!("q{i}")).collect();
    let names: Vec<&str> = joints.iter().map(String::as_str).collect();
    assert_eq!(
        csv_columns(&a.join("recording.csv"), &names),
        csv_columns(&b.join("recording.csv"), &names)
    );
}

#[test]
fn bad_dynamics_sections_are_named_with_their_place() {
    // What a good file does, in words: both stages of the search, and the robot.
    let o = common::cli(&["check", &repo("experiments/dynamics/viapoint_joint.toml")]);
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{said}");
    assert!(
        said.contains("then on the executions: Levenberg–Marquardt, up to 15 iterations")
            && said.contains("on the dynamics (in-process, joint_pd controller, franky-sim drive"),
        "{said}"
    );
    let dir = tempfile::tempdir().unwrap();
    let refused = |name: &str, toml: String, expected: &str| {
        let err = common::refused(dir.path(), name, &toml, expected);
        assert!(
            err.contains(&format!("{name}.toml:")),
            "{name}: no place in {err}"
        );
    };
    refused(
        "controller",
        on_dynamics("controller = \"pid\""),
        "[robot] `controller` = \"pid\" is not one of joint_pd, computed_torque, joint_impedance",
    );
    refused(
        "negative",
        on_dynamics("kp = [4500, 4500, 3500, -3500, 2000, 2000, 2000]"),
        "[robot] `kp[3]` is -3500: a gain must be finite and ≥ 0",
    );
    refused(
        "count",
        on_dynamics("kv = [450, 450, 350, 350, 200, 200]"),
        "[robot] `kv` has 6 values: one per joint of the panda (7)",
    );
    refused(
        "drive",
        on_dynamics("drive = \"hydraulic\""),
        "[robot] `drive` = \"hydraulic\" is not one of franky-sim",
    );
    refused(
        "integrator",
        on_dynamics("integrator = \"rk45\""),
        "[robot] `integrator` = \"rk45\" is not one of euler, rk4",
    );
    refused(
        "dt",
        on_dynamics("").replace(
            "dt = 0.01               # control period",
            "dt = 0.0125 # control period",
        ),
        "must be a whole number of milliseconds",
    );
    refused("noise", on_dynamics("noise = -1.0"), "[robot] `noise`");
    refused(
        "calibration_missing",
        on_dynamics("calibration = \"missing.toml\""),
        "[robot] `calibration`: ",
    );
    refused(
        "calibration_empty",
        on_dynamics("calibration = \"\""),
        "[robot] `calibration` is empty: give the path of a calibration file",
    );
    // A calibration's values are judged where they are read, at their line and column in
    // the calibration file (they ran, failing later without a place, or with the arm
    // standing).
    let calibration = |name: &str, key: &str, value: &str| {
        let good = "# A robot's calibration, identified by cps\n\n[calibration]\nrobot = \"panda\"\ncontroller = \"joint_pd\"\nkp = [4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0]\nkv = [450.0, 450.0, 350.0, 350.0, 200.0, 200.0, 200.0]\nlag_ms = 0\narmature = [0.2, 0.2, 0.2, 0.2, 0.07, 0.07, 0.07]\nviscous = [0.2, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2]\ncoulomb = [1.1, 1.1, 1.1, 1.1, 0.7, 0.4, 0.2]\ncoulomb_speed = 0.01\n";
        let line = good
            .lines()
            .find(|l| l.starts_with(&format!("{key} =")))
            .unwrap();
        let number = good.lines().position(|l| l == line).unwrap() + 1;
        let text = good.replace(line, &format!("{key} = {value}"));
        std::fs::write(dir.path().join(format!("{name}.calibration.toml")), text).unwrap();
        (
            on_dynamics(&format!("calibration = \"{name}.calibration.toml\"")),
            format!("{name}.calibration.toml:{number}:1"),
        )
    };
    for (name, key, value, says) in [
        (
            "kp_zero",
            "kp",
            "[0.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0]",
            "kp of joint 1 is 0: it must be finite and > 0",
        ),
        (
            "coulomb_huge",
            "coulomb",
            "[1e6, 1.1, 1.1, 1.1, 0.7, 0.4, 0.2]",
            "coulomb of joint 1 is 1000000 N m, at or above its drive's 87 N m",
        ),
    ] {
        let (toml, place) = calibration(name, key, value);
        let err = common::refused(dir.path(), name, &toml, says);
        assert!(err.contains(&place), "{name}: {err}");
    }
    refused(
        "calibration_and_gains",
        on_dynamics("calibration = \"missing.toml\"\nkp = [1, 1, 1, 1, 1, 1, 1]"),
        "[robot] `kp` and `calibration` both say how the robot is driven: give one",
    );
    refused(
        "learn_on",
        on_dynamics("").replace("learn_on = \"model\"", "learn_on = \"robot\""),
        "[joint] learn_on must be \"execution\" or \"model\" (got \"robot\")",
    );
    refused(
        "learn_on_kinematic",
        SHIPPED.replace("[joint]\n", "[joint]\nlearn_on = \"execution\"\n"),
        "[joint] learn_on = \"execution\" learns on what a simulated robot does",
    );
    refused(
        "kp_on_kinematic",
        SHIPPED.replace("[robot]", "[robot]\nkp = [1, 1, 1, 1, 1, 1, 1]"),
        "[robot] `kp` is read only with backend = \"dynamics\"",
    );
    refused(
        "controller_on_kinematic",
        SHIPPED.replace("[robot]", "[robot]\ncontroller = \"joint_pd\""),
        "[robot] `controller` is read only with backend = \"ros2\"",
    );
    // A bare FR3 flange carries no link inertias (with the hand it carries MuJoCo's).
    write(
        dir.path(),
        "bare_scene.toml",
        "[robot]\nmodel = \"fr3\"\ntool = \"flange\"\ninitial_q = [0.0, 0.0, 0.0, -0.3, 0.0, 1.87, 0.785]\n",
    );
    refused(
        "bare",
        on_dynamics("").replace("scene = \"thesis\"", "scene = \"bare_scene.toml\""),
        "the scene's robot fr3 has 7 joints and no link inertias",
    );
}

/// The shipped dynamics experiment: the FR3 under franky-sim's PD, learned on what the arm
/// does. The model-learned command passes the via points centimetres away as executed
/// (the controller lags); the command learned on the executions passes each within a
/// millimetre, ends at the goal, keeps every limit at 1 kHz (not slowed by the guard), and
/// the guarded execution recorded afterwards is the one it was judged on.
#[test]
fn the_shipped_dynamics_experiment_learns_what_the_robot_does() {
    let dir = tempfile::tempdir().unwrap();
    let file = std::path::PathBuf::from(repo("experiments/dynamics/viapoint_joint.toml"));
    let out = dir.path().join("out");
    let (o, err) = run(&file, &out);
    assert!(o.status.success(), "{err}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["complete"], true, "{s}");
    let l = &s["executed_learning"];
    let mm = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap() * 1e3)
            .collect()
    };
    let before = mm(&l["model_learned_via_errors_m"]);
    assert!(before.iter().all(|e| *e > 20.0), "{before:?} mm");
    let after = mm(&l["via_errors_m"]);
    assert_eq!(after.len(), 4);
    assert!(after.iter().all(|e| *e < 1.0), "{after:?} mm");
    assert!(l["goal_error_m"].as_f64().unwrap() < 1e-3, "{l}");
    // The command itself does not pass there: it leads the lagging arm.
    let commanded = mm(&l["commanded_via_errors_m"]);
    assert!(commanded.iter().all(|e| *e > 10.0), "{commanded:?} mm");
    // Executed through the guard: as planned (10 s, not slowed), every limit kept, and the
    // same motion the learner judged.
    assert_eq!(s["limit_usage"]["ok"], true, "{}", s["limit_usage"]);
    let e = &s["execution"];
    assert!(
        (e["duration_s"].as_f64().unwrap() - 10.0).abs() < 1e-9,
        "{e}"
    );
    let recorded = mm(&e["via_errors_m"]);
    for (a, b) in recorded.iter().zip(&after) {
        assert!((a - b).abs() < 1e-6, "{recorded:?} against {after:?} mm");
    }
    // The result is the command: t, q1..q7 every 10 ms from the start configuration.
    let q1 = csv_columns(&out.join("trajectory.csv"), &["t", "q1"]);
    assert_eq!(q1[0].len(), 1001);
    transfers_to_franky_sim(&out.join("trajectory.csv"), dir.path());
}

/// The learned command streamed unchanged to franky-sim at 1 kHz (`cps-cli franka
/// execute`, approaching its start first) passes each via point within 3 mm at its time,
/// in MuJoCo's own tool position. The model-learned command, streamed the same way,
/// passes them 24.5–40.7 mm away.
fn transfers_to_franky_sim(command: &std::path::Path, dir: &std::path::Path) {
    let Some(sim) = sim::FrankySim::start_with(
        "127.0.0.95",
        sim::SimOptions {
            truth: true,
            ..Default::default()
        },
    ) else {
        return;
    };
    let record = dir.join("franky.csv");
    let o = common::cli(&[
        "franka",
        "execute",
        command.to_str().unwrap(),
        "--host",
        &sim.host,
        "--record",
        record.to_str().unwrap(),
        "--realtime",
        "ignore",
        "--approach",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = json(&dir.join("franky.report.json"));
    assert_eq!(report["complete"], true, "{report}");
    // The plan's point at time t is due at robot time approach_s + t (the recording's `t`;
    // a state lost, it went with the next row).
    let start = report["approach_s"].as_f64().unwrap();
    let joints: Vec<String> = (1..=7).map(|i| format!("q{i}")).collect();
    let names: Vec<&str> = ["t"]
        .into_iter()
        .chain(joints.iter().map(String::as_str))
        .collect();
    let columns = csv_columns(&record, &names);
    let (time, q) = (&columns[0], &columns[1..]);
    // MuJoCo's tool at the step whose joints the robot reported (its world is the robot's
    // base frame; the fr3 scene puts the base at (0.42244, 0.02, 0.74177)).
    let truth = sim.truth();
    let base = [0.42244, 0.02, 0.74177];
    let vias = [
        (2.0, [0.78, 0.60, 1.70]),
        (4.0, [1.12, 0.37, 1.45]),
        (6.0, [1.15, -0.15, 1.20]),
        (8.0, [0.90, -0.53, 1.20]),
    ];
    let mut errors = Vec::new();
    for (t, p) in vias {
        let k = time.iter().position(|&r| r >= start + t - 1e-9).unwrap();
        let reported: Vec<f64> = (0..7).map(|j| q[j][k]).collect();
        let (gap, step) = truth
            .iter()
            .map(|s| {
                let d =
                    s.q.iter()
                        .zip(&reported)
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0, f64::max);
                (d, s)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap();
        assert!(
            gap < 1e-6,
            "no simulation step has the joints reported at {t} s"
        );
        let e = (0..3)
            .map(|d| (step.tcp[d] + base[d] - p[d]).powi(2))
            .sum::<f64>()
            .sqrt();
        errors.push(e * 1e3);
    }
    eprintln!("franky-sim passes the via points {errors:?} mm away");
    assert!(errors.iter().all(|e| *e < 3.0), "{errors:?} mm");
}

/// `cps-cli franka identify` on franky-sim: 9 s of chirps where the arm stands, its joint
/// controller recovered (franky-sim's kp, and kv = kp/10, within 5 %) and the calibrated
/// robot within 2 mrad RMS of the 3 s held back; the same from the recording
/// (`cps-cli identify`); an experiment run on the calibrated robot, and one of another
/// robot refused with its place.
#[test]
fn franky_sims_controller_is_identified_and_calibrates_the_dynamics_robot() {
    let Some(sim) = sim::FrankySim::start("127.0.0.96") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (out, rec) = (dir.path().join("robot.toml"), dir.path().join("rec.csv"));
    let o = common::cli(&[
        "franka",
        "identify",
        "--host",
        &sim.host,
        "--out",
        out.to_str().unwrap(),
        "--record",
        rec.to_str().unwrap(),
        "--realtime",
        "ignore",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    drop(sim);
    let franky_kp = [4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0];
    let judge = |answer: &serde_json::Value| {
        let list = |v: &serde_json::Value| -> Vec<f64> {
            v.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        };
        let c = &answer["calibration"];
        let (kp, kv) = (list(&c["kp"]), list(&c["kv"]));
        eprintln!("kp {kp:?}\nkv {kv:?}\nfit {}", answer["fit"]);
        for j in 0..7 {
            assert!((kp[j] / franky_kp[j] - 1.0).abs() < 0.05, "kp {kp:?}");
            assert!(
                (kv[j] / (franky_kp[j] / 10.0) - 1.0).abs() < 0.05,
                "kv {kv:?}"
            );
        }
        let held = list(&answer["fit"]["held_back_rms_mrad"]);
        assert!(held.iter().all(|e| *e <= 2.0), "{held:?} mrad");
    };
    judge(&serde_json::from_slice(&o.stdout).unwrap());
    // The same from the recording, for a robot cps does not drive.
    let again = dir.path().join("again.toml");
    let o = common::cli(&[
        "identify",
        rec.to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    judge(&serde_json::from_slice(&o.stdout).unwrap());
    // The shipped dynamics experiment on the calibrated robot (learned on the model: a
    // short run).
    let shipped =
        std::fs::read_to_string(repo("experiments/dynamics/viapoint_joint.toml")).unwrap();
    let drive = shipped.lines().find(|l| l.starts_with("drive = ")).unwrap();
    let calibrated = shipped
        .replace(drive, "calibration = \"robot.toml\"")
        .replace("learn_on = \"execution\"", "learn_on = \"model\"    ");
    assert!(calibrated.contains("learn_on = \"model\""));
    let file = write(dir.path(), "calibrated.toml", &calibrated);
    let (o, err) = run(&file, &dir.path().join("calibrated"));
    assert!(o.status.success(), "{err}");
    let s = json(&dir.path().join("calibrated/summary.json"));
    let backend = s["backend"].as_str().unwrap();
    assert!(backend.contains("calibrated (lag"), "{backend}");
    // The Panda's scene with the FR3's calibration.
    let wrong = on_dynamics("calibration = \"robot.toml\"");
    let err = common::refused(
        dir.path(),
        "panda_calibrated",
        &wrong,
        "it calibrates the robot fr3, not panda",
    );
    assert!(err.contains("panda_calibrated.toml:"), "{err}");
}
