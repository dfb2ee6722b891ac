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
    let o = cli(&[
        "imitate",
        &fixture(),
        "--episodes",
        "0,2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
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
    let o = cli(&[
        "imitate",
        &fixture(),
        "--feature",
        "action",
        "--out",
        a.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(model(&a)["names"].as_array().unwrap().len(), 7);
    let c = dir.path().join("c.json");
    let o = cli(&[
        "imitate",
        &fixture(),
        "--feature",
        "action",
        "--columns",
        "panda_joint4,gripper",
        "--out",
        c.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        model(&c)["names"],
        serde_json::json!(["panda_joint4", "gripper"])
    );

    let p = dir.path().join("p.json");
    let o = cli(&["promp", "fit", &fixture(), "--out", p.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
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
