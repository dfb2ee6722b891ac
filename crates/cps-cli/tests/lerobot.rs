//! LeRobot datasets on the command line: `lerobot show`, and a dataset's episodes as the
//! demonstrations of `imitate` and `promp fit` — on the dataset LeRobot 0.6.1's own writer
//! made (crates/cps-lerobot/tests/data), its joints matched to cps's robots by name, and
//! bad input refused in a sentence with exit 2 and nothing written.

mod common;

use common::{cli, repo};

fn fixture() -> String {
    repo("crates/cps-lerobot/tests/data/fr3_reach")
}

fn json(out: &std::process::Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// `cps-cli args`, which must succeed.
fn ok(args: &[&str]) -> std::process::Output {
    let o = cli(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn model(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The fixture's episode `e` ends at start + 0.1 (e + 1) * direction (make_fixture.py).
fn goal(e: usize) -> Vec<f64> {
    let start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let dir = [1.0, 0.5, -0.5, 0.8, 0.3, -0.4, 0.6];
    (0..7)
        .map(|j| start[j] + 0.1 * (e + 1) as f64 * dir[j])
        .collect()
}

#[test]
fn show_lists_episodes_tasks_and_features() {
    let text = cli(&["lerobot", "show", &fixture()]);
    let words = String::from_utf8_lossy(&text.stdout);
    assert!(
        words.contains("3 episodes, 127 frames at 30 frames/s, robot `panda`"),
        "{words}"
    );
    assert!(
        words.contains("1: 52 frames, 1.70 s, reach the right bin"),
        "{words}"
    );
    let j = json(&cli(&["lerobot", "show", &fixture(), "--json"]));
    assert_eq!(j["fps"], 30.0);
    assert_eq!(
        j["tasks"],
        serde_json::json!(["reach the left bin", "reach the right bin"])
    );
    let frames: Vec<u64> = j["episodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["frames"].as_u64().unwrap())
        .collect();
    assert_eq!(frames, [40, 52, 35]);
    let action = j["features"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["name"] == "action")
        .unwrap();
    assert_eq!(action["shape"], serde_json::json!([8]));
}

#[test]
fn episodes_of_a_dataset_are_imitated_as_demonstrations() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.json");
    ok(&[
        "imitate",
        &fixture(),
        "--episodes",
        "0,2",
        "--out",
        out.to_str().unwrap(),
    ]);
    let m = model(&out);
    let names: Vec<String> = serde_json::from_value(m["names"].clone()).unwrap();
    assert_eq!(
        names,
        (1..=7)
            .map(|i| format!("panda_joint{i}"))
            .collect::<Vec<_>>()
    );
    // Two episodes: their mean duration on the 30 frames/s grid, their mean goal.
    assert_eq!(
        m["config"]["tau"],
        serde_json::json!((39.0 / 30.0 + 34.0 / 30.0) / 2.0)
    );
    assert_eq!(m["config"]["dt"], serde_json::json!(1.0 / 30.0));
    let g: Vec<f64> = serde_json::from_value(m["goal"].clone()).unwrap();
    for (j, (g, (a, b))) in g.iter().zip(goal(0).iter().zip(goal(2))).enumerate() {
        assert!((g - (a + b) / 2.0).abs() < 1e-6, "joint {j}");
    }

    // The action has a gripper after the joints: matched to the dataset's robot (panda),
    // the seven joints are imitated; --columns takes entries by name.
    let a = dir.path().join("a.json");
    ok(&[
        "imitate",
        &fixture(),
        "--feature",
        "action",
        "--out",
        a.to_str().unwrap(),
    ]);
    assert_eq!(model(&a)["names"].as_array().unwrap().len(), 7);
    let c = dir.path().join("c.json");
    ok(&[
        "imitate",
        &fixture(),
        "--feature",
        "action",
        "--columns",
        "panda_joint4,gripper",
        "--out",
        c.to_str().unwrap(),
    ]);
    assert_eq!(
        model(&c)["names"],
        serde_json::json!(["panda_joint4", "gripper"])
    );

    let p = dir.path().join("p.json");
    let o = ok(&["promp", "fit", &fixture(), "--out", p.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("3 demonstrations, 7 dimension(s)"));
}

#[test]
fn what_is_not_a_robots_joint_space_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.json");
    let o = out.to_str().unwrap();
    let f = fixture();
    for (args, words) in [
        (
            vec![
                "--feature",
                "observation.environment_state",
                "--robot",
                "panda",
            ],
            "`observation.environment_state`'s entries (x, y, z) do not name `panda_joint1`",
        ),
        (vec!["--robot", "fr3"], "do not name `fr3_joint1`"),
        (
            vec!["--episodes", "3"],
            "has no episode 3: its episodes are 0 to 2",
        ),
        (
            vec!["--feature", "observation.images.wrist"],
            "has no feature `observation.images.wrist`",
        ),
    ] {
        let mut a = vec!["imitate", f.as_str(), "--out", o];
        a.extend(args);
        let r = cli(&a);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{err}");
        assert!(err.contains(words), "{err}");
        assert!(!out.exists());
    }
    let r = cli(&["imitate", dir.path().to_str().unwrap(), "--out", o]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        err.contains("meta/info.json") && err.contains("not a LeRobot dataset"),
        "{err}"
    );
    let r = cli(&["lerobot", "show", "/no/such/dataset"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("no such folder"));
}

/// A joint CSV as `ros2 record` writes it: `t`, the joints by name, their `_vel`, at
/// irregular arrival times.
fn joint_csv(path: &std::path::Path, seconds: f64) {
    let mut text = String::from("t");
    for j in 1..=7 {
        text += &format!(",panda_joint{j}");
    }
    for j in 1..=7 {
        text += &format!(",panda_joint{j}_vel");
    }
    text.push('\n');
    let mut times = Vec::new();
    let mut t = 0.0;
    while t < seconds {
        times.push(t);
        // 9–11 ms apart, as messages arrive.
        t += 0.009 + 0.002 * ((t * 1000.0) as usize % 3) as f64 / 2.0;
    }
    times.push(seconds);
    for t in times {
        text += &format!("{t}");
        for j in 0..7 {
            text += &format!(",{}", 0.1 * j as f64 + t);
        }
        for _ in 0..7 {
            text += ",1.0";
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn recordings_written_as_a_dataset_learn_again() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
    joint_csv(&a, 1.0);
    joint_csv(&b, 0.6);
    let out = dir.path().join("ds");
    let o = out.to_str().unwrap();
    let j = json(&cli(&[
        "lerobot",
        "write",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out",
        o,
        "--robot",
        "panda",
        "--task",
        "reach",
        "--fps",
        "50",
        "--json",
    ]));
    assert_eq!(j["episodes"], serde_json::json!([51, 31]));
    assert_eq!(j["action"], "next state");
    assert_eq!(
        j["features"],
        serde_json::json!(["observation.state", "observation.velocity", "action"])
    );
    let shown = json(&cli(&["lerobot", "show", o, "--json"]));
    assert_eq!(shown["robot_type"], "panda");
    assert_eq!(shown["tasks"], serde_json::json!(["reach"]));
    // The written episodes learn again: joint j rises 1 rad/s from 0.1 j.
    let m = dir.path().join("m.json");
    ok(&[
        "imitate",
        o,
        "--episodes",
        "0",
        "--out",
        m.to_str().unwrap(),
    ]);
    let model = model(&m);
    assert_eq!(model["config"]["tau"], serde_json::json!(1.0));
    let goal: Vec<f64> = serde_json::from_value(model["goal"].clone()).unwrap();
    for (j, g) in goal.iter().enumerate() {
        assert!((g - (0.1 * j as f64 + 1.0)).abs() < 1e-6, "joint {j}: {g}");
    }
    // Written again: refused, then replaced with --force.
    let again = cli(&[
        "lerobot",
        "write",
        a.to_str().unwrap(),
        "--out",
        o,
        "--robot",
        "panda",
        "--task",
        "reach",
    ]);
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force replaces it"));
    ok(&[
        "lerobot",
        "write",
        a.to_str().unwrap(),
        "--out",
        o,
        "--robot",
        "panda",
        "--task",
        "reach",
        "--fps",
        "10",
        "--force",
    ]);
    assert_eq!(json(&cli(&["lerobot", "show", o, "--json"]))["frames"], 11);
}

#[test]
fn recordings_that_do_not_fit_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.csv");
    joint_csv(&a, 0.5);
    let out = dir.path().join("ds");
    let o = out.to_str().unwrap();
    for (args, words) in [
        (vec!["--robot", "fr3"], "no column names joint `fr3_joint1`"),
        (vec!["--robot", "panda", "--fps", "0"], "--fps"),
    ] {
        let mut all = vec![
            "lerobot",
            "write",
            a.to_str().unwrap(),
            "--out",
            o,
            "--task",
            "x",
        ];
        all.extend(args);
        let r = cli(&all);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{err}");
        assert!(err.contains(words), "{err}");
        assert!(!out.exists());
    }
    let mine = dir.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    let r = cli(&[
        "lerobot",
        "write",
        a.to_str().unwrap(),
        "--out",
        mine.to_str().unwrap(),
        "--robot",
        "panda",
        "--task",
        "x",
        "--force",
    ]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("not a LeRobot dataset cps would replace"));
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 2, "{left:?}");
}

/// The tool position `cps-cli fk --robot panda` gives at `q` (the robot's base frame; the
/// Panda's default tool is its hand).
fn tool(q: &[f64]) -> [f64; 3] {
    common::hand_at("panda", q)
}

#[test]
fn an_imitation_experiment_learns_from_a_datasets_episodes() {
    let dir = tempfile::tempdir().unwrap();
    // The thesis's scene with the Panda starting where the episodes start: from the
    // thesis's stretched arm, the inverse kinematics reaches them folded, link7 within
    // the guard's margin of link5.
    let scene = common::write(dir.path(), "home.toml", &common::thesis_scene_at_home());
    let file = common::write(
        dir.path(),
        "lerobot.toml",
        &format!(
            r#"[experiment]
kind = "imitation"
name = "lerobot"
seed = 1

[robot]
scene = {:?}
backend = "kinematic"
dt = 0.01

[demonstrations]
lerobot = {:?}
episodes = [0, 2]

[imitation]
basis_functions = 25
ridge_lambda = 1e-12
jerk_lambda = "auto"

[dmp]
basis_functions = 25
tau = 10.0
dt = 0.01

[task]
start = [0.75, 0.02, 1.87]
goal = [0.55, -0.57, 1.45]

[output]
plots = false

[optimizer]
method = "exact"
generations = 1
"#,
            scene,
            fixture()
        ),
    );
    let out = dir.path().join("out");
    ok(&[
        "run",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["demonstrations"]["kept"], 2);
    assert_eq!(summary["demonstrations"]["executed"], 2);
    let runs = summary["runs"].as_array().unwrap();
    assert!(
        runs[1]["take"]
            .as_str()
            .unwrap()
            .ends_with("fr3_reach episode 2")
    );
    // Each episode's tool path, in the world frame, spans what the robot's kinematics
    // says its joint path does: start to end as far apart as cps-cli fk's two poses.
    let rows = std::fs::read_to_string(out.join("recordings.csv")).unwrap();
    let start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let dir7 = [1.0, 0.5, -0.5, 0.8, 0.3, -0.4, 0.6];
    for (index, e) in [(0, 0usize), (1, 2)] {
        let path: Vec<[f64; 3]> = rows
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<_>>())
            .filter(|c| c[0] == "learned" && c[1] == index.to_string())
            .map(|c| {
                [
                    c[3].parse().unwrap(),
                    c[4].parse().unwrap(),
                    c[5].parse().unwrap(),
                ]
            })
            .collect();
        let end: Vec<f64> = (0..7)
            .map(|j| start[j] + 0.1 * (e + 1) as f64 * dir7[j])
            .collect();
        let (a, b) = (tool(&start), tool(&end));
        let want = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        let (p, q) = (path[0], path[path.len() - 1]);
        let got = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
        assert!(
            (got - want).abs() < 1e-5,
            "episode {e}: {got} m, fk says {want} m"
        );
    }
}
