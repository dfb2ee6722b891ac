//! `[robot] backend = "dynamics"`: the thesis's joint via-point experiment executed on the
//! Panda with dynamics under a joint-level controller, deterministic, and bad robot
//! sections named with their place.

mod common;

use common::{csv_columns, json, run_quiet as run, write};

const SHIPPED: &str = include_str!("../../../experiments/viapoint_joint.toml");
const BACKEND: &str = "backend = \"kinematic\"   # or \"coppelia\"";

/// The shipped experiment on the dynamics robot with `extra` keys in `[robot]`.
fn on_dynamics(extra: &str) -> String {
    let line = SHIPPED
        .lines()
        .find(|l| l.starts_with(BACKEND))
        .expect("the shipped experiment names its backend");
    SHIPPED.replace(line, &format!("backend = \"dynamics\"\n{extra}"))
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
