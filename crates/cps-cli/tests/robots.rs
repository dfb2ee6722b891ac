//! End-to-end tests of `cps-cli`'s robot commands without a robot: forward and inverse
//! kinematics, robot files against the built-in models, the thesis scene, `limits check`,
//! `retime` and `collide`; an experiment's obstacles and clearance.

mod common;

use common::{cli, repo, stderr, stdout_json, write};

#[test]
fn fk_and_ik_from_the_command_line_round_trip() {
    // At q = 0 the Panda's flange is 0.088 m forward and 0.926 m up, pointing down.
    let o = cli(&[
        "fk",
        "--robot",
        "panda",
        "--q",
        "0,0,0,0,0,0,0",
        "--tool",
        "flange",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let fk = stdout_json(&o);
    assert!((fk["T"][0][3].as_f64().unwrap() - 0.088).abs() < 1e-12);
    assert!((fk["T"][2][3].as_f64().unwrap() - 0.926).abs() < 1e-12);
    assert!((fk["T"][2][2].as_f64().unwrap() + 1.0).abs() < 1e-12);
    assert_eq!(fk["quaternion_xyzw"].as_array().unwrap().len(), 4);

    // The Hand TCP pose at some configuration, then IK for that full pose.
    let q = "0.3,-0.5,0.2,-2.0,0.1,1.6,0.7";
    let fk = stdout_json(&cli(&["fk", "--q", q, "--json"]));
    let mut target: Vec<String> = fk["position"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.to_string())
        .collect();
    target.extend(
        fk["quaternion_xyzw"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.to_string()),
    );
    let o = cli(&["ik", "--target", &target.join(","), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ik = stdout_json(&o);
    assert!(ik["position_error"].as_f64().unwrap() <= 1e-9);
    assert!(ik["rotation_error"].as_f64().unwrap() <= 1e-9);
    let q_ik: Vec<String> = ik["q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.to_string())
        .collect();
    let again = stdout_json(&cli(&["fk", "--q", &q_ik.join(","), "--json"]));
    for k in 0..3 {
        let (a, b) = (
            again["position"][k].as_f64().unwrap(),
            fk["position"][k].as_f64().unwrap(),
        );
        assert!((a - b).abs() < 1e-9);
    }
}

#[test]
fn kinematics_bad_input_exits_2_with_a_clear_message() {
    for (args, expect) in [
        (vec!["fk", "--q", "0,0,0"], "expected 7 joint values, got 3"),
        (vec!["fk", "--robot", "r2d2", "--q", "0"], "unknown robot"),
        (vec!["ik", "--target", "3,0,0.5"], "target not reached"),
        (vec!["ik", "--target", "0.3,0.1"], "x,y,z"),
        (vec!["ik", "--target", "0.3,NaN,0.5"], "finite"),
        (
            vec![
                "ik",
                "--target",
                "0.3,0.1,0.5",
                "--seed-q",
                "0,0,0,0,0,1.57,0.78",
            ],
            "--seed-q: joint 4 = 0 is outside its limits [-3.0718, -0.0698]",
        ),
        (
            vec!["fk", "--within-limits", "--q", "0,0,0,0,0,1.57,0.78"],
            "--q: joint 4 = 0 is outside its limits",
        ),
    ] {
        let o = cli(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
    }
    let o = cli(&["robot", "show", "panda"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("modified (Craig) DH") && text.contains("-3.0718"),
        "{text}"
    );
}

/// The robot files in configs/robots/ describe the same robots as the built-in models:
/// the Panda as a TOML DH table and as URDF joints, the UR3 as a TOML DH table.
#[test]
fn robot_files_agree_with_the_built_in_models() {
    let q7 = "0.3,-0.5,0.2,-2.0,0.1,1.6,0.7";
    let fk = |robot: &str, q: &str, extra: &[&str]| {
        let mut args = vec!["fk", "--robot", robot, "--q", q, "--json"];
        args.extend_from_slice(extra);
        let o = cli(&args);
        assert!(o.status.success(), "{robot}: {}", stderr(&o));
        stdout_json(&o)["T"].clone()
    };
    let close = |a: &serde_json::Value, b: &serde_json::Value| {
        for r in 0..4 {
            for c in 0..4 {
                let d = a[r][c].as_f64().unwrap() - b[r][c].as_f64().unwrap();
                assert!(d.abs() < 1e-12, "T[{r}][{c}] differs by {d}");
            }
        }
    };
    let builtin = fk("panda", q7, &[]);
    close(&builtin, &fk(&repo("configs/robots/panda.toml"), q7, &[]));
    close(&builtin, &fk(&repo("configs/robots/panda.urdf"), q7, &[]));
    let flange = fk("panda", q7, &["--tool", "flange"]);
    close(
        &flange,
        &fk(
            &repo("configs/robots/panda.toml"),
            q7,
            &["--tool", "flange"],
        ),
    );
    close(
        &flange,
        &fk(
            &repo("configs/robots/panda.urdf"),
            q7,
            &["--tip", "panda_link8"],
        ),
    );
    let q6 = "0.3,-1.1,0.8,-0.4,1.2,0.5";
    close(
        &fk("ur3", q6, &[]),
        &fk(&repo("configs/robots/ur3.toml"), q6, &[]),
    );
    let o = cli(&["robot", "show", &repo("configs/robots/panda.urdf")]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("panda_joint7"));
}

#[test]
fn bad_robot_files_exit_2_naming_the_place() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(repo("configs/robots/panda.toml")).unwrap();
    let no_limit = good.replacen("q_max = 2.8973\n", "", 1);
    let unknown = good.replacen("dq_max = 2.175\n", "dq_max = 2.175\ndamping = 3.0\n", 1);
    let inverted = good.replacen("q_min = -1.7628", "q_min = 1.9", 1);
    let some_speeds = good.replacen("dq_max = 2.61\n", "", 1);
    let prismatic = std::fs::read_to_string(repo("configs/robots/panda.urdf"))
        .unwrap()
        .replace(
            "panda_joint4\" type=\"revolute",
            "panda_joint4\" type=\"prismatic",
        );
    for (name, text, expect) in [
        ("no_limit.toml", no_limit.as_str(), "missing field `q_max`"),
        ("unknown.toml", unknown.as_str(), "unknown field `damping`"),
        (
            "inverted.toml",
            inverted.as_str(),
            "joint 2: limits need finite `q_min` < `q_max`",
        ),
        (
            "speeds.toml",
            some_speeds.as_str(),
            "`dq_max` for every joint or for none",
        ),
        (
            "prismatic.urdf",
            prismatic.as_str(),
            "joint `panda_joint4` is prismatic",
        ),
        ("broken.urdf", "<robot name='x'><link", "URDF:"),
    ] {
        let p = write(dir.path(), name, text);
        let o = cli(&["fk", "--robot", p.to_str().unwrap(), "--q", "0,0,0,0,0,0,0"]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(expect) && err.contains(name), "{name}: {err}");
        assert!(!err.contains("panicked"));
    }
    // Line and column of the offending joint table.
    let p = dir.path().join("inverted.toml");
    let err = stderr(&cli(&["robot", "show", p.to_str().unwrap()]));
    assert!(err.contains("inverted.toml:") && err.contains(':'), "{err}");
    let urdf = repo("configs/robots/panda.urdf");
    for (args, expect) in [
        (
            vec!["fk", "--robot", urdf.as_str(), "--tool", "hand", "--q", "0"],
            "--tip",
        ),
        (
            vec!["fk", "--robot", "panda", "--tool", "gripper", "--q", "0"],
            "not `gripper`",
        ),
        (
            vec!["fk", "--robot", "/nowhere/arm.toml", "--q", "0"],
            "cannot read the robot file",
        ),
    ] {
        let o = cli(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{args:?}: {}", stderr(&o));
    }
}

/// The thesis's scene puts the Hand TCP at the experiment's start point at the initial
/// configuration, and every Table 3 point is reachable within the joint limits.
#[test]
fn the_thesis_scene_starts_at_p0_and_reaches_every_way_point() {
    let o = cli(&[
        "scene",
        "check",
        &repo("configs/scenes/thesis.toml"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v = stdout_json(&o);
    let tool: Vec<f64> = v["tool_at_initial_q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    for (a, b) in tool.iter().zip([0.75, 0.02, 1.87]) {
        assert!((a - b).abs() < 1e-12, "{tool:?}");
    }
    assert_eq!(v["initial_q_outside_limits"], serde_json::json!([4]));
    let objects = v["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 6);
    assert!(
        objects.iter().all(|o| o["reachable"] == true),
        "{objects:?}"
    );

    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo("configs/scenes/thesis.toml")).unwrap();
    let far = write(
        dir.path(),
        "far.toml",
        &text.replace("[0.55, -0.57, 1.45]", "[3.0, 0.0, 1.0]"),
    );
    let o = cli(&["scene", "check", far.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("pT   (3.000, 0.000, 1.000): NOT reachable")
    );
    let short = write(
        dir.path(),
        "short.toml",
        &text.replace("1.5707963267948966, 0.7853981633974483]", "1.57]"),
    );
    let o = cli(&["scene", "check", short.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("short.toml:16:")
            && stderr(&o).contains("expected 7 joint values, got 6"),
        "{}",
        stderr(&o)
    );
}

/// `limits check`: a slow move holds every Panda limit (exit 0, usage as computed by
/// hand), a fast one breaks the speed limit of the joint that moves (exit 1, the violation
/// in the JSON), and a file with too few joints is bad input (exit 2).
#[test]
fn limits_check_reports_usage_and_violations_with_its_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let ready = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    // Joint 1 follows 3x² − 2x³ (rest to rest) over `duration` seconds, 1 kHz samples.
    let file = |name: &str, amplitude: f64, duration: f64| {
        let mut text = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
        let n = (duration * 1000.0).round() as usize;
        for k in 0..=n {
            let x = k as f64 / n as f64;
            let mut q = ready;
            q[0] = amplitude * (3.0 * x * x - 2.0 * x * x * x);
            let cells: Vec<String> = q.iter().map(|v| format!("{v:e}")).collect();
            text.push_str(&format!("{},{}\n", k as f64 * 0.001, cells.join(",")));
        }
        write(dir.path(), name, &text)
    };
    let slow = file("slow.csv", 1.0, 4.0);
    let o = cli(&[
        "limits",
        "check",
        slow.to_str().unwrap(),
        "--robot",
        "panda",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["ok"], true);
    // Peak speed 1.5 A / T = 0.375 rad/s of joint 1's 2.175: 17.2 %.
    let usage = v["peak_usage"]["velocity"][0].as_f64().unwrap();
    assert!((usage - 100.0 * 0.375 / 2.175).abs() < 0.1, "{usage}");
    assert!(v["peak_usage"]["torque"][1].as_f64().unwrap() > 1.0); // gravity on joint 2
    let fast = file("fast.csv", 2.5, 1.0);
    let o = cli(&[
        "limits",
        "check",
        fast.to_str().unwrap(),
        "--robot",
        "panda",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["ok"], false);
    let speed: Vec<&serde_json::Value> = v["violations"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|x| x["quantity"] == "velocity")
        .collect();
    assert_eq!(speed.len(), 1, "{speed:?}");
    assert_eq!(speed[0]["joint"], 1);
    assert!((speed[0]["value"].as_f64().unwrap() - 3.75).abs() < 1e-3); // 1.5 · 2.5 rad / 1 s
    assert!((speed[0]["time"].as_f64().unwrap() - 0.5).abs() < 2e-3); // the middle
    assert_eq!(speed[0]["limit"], 2.175);
    let o = cli(&[
        "limits",
        "check",
        fast.to_str().unwrap(),
        "--robot",
        "panda",
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("joint 1 velocity at 0.50"));
    let short = write(
        dir.path(),
        "short.csv",
        "t,q1,q2\n0,0,0\n0.1,0,0\n0.2,0,0\n",
    );
    let o = cli(&[
        "limits",
        "check",
        short.to_str().unwrap(),
        "--robot",
        "panda",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("a 7-joint robot needs the time and 7 joint positions"));
    let o = cli(&["limits", "check", slow.to_str().unwrap(), "--rate", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--rate 0"));
}

/// Robot files carry limits and inertias for every joint or for none; a tensor no rigid
/// body has is refused, naming the joint and the place.
#[test]
fn robot_file_limits_and_inertias_are_all_or_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let panda = std::fs::read_to_string(repo("configs/robots/panda.toml")).unwrap();
    let traj = write(
        dir.path(),
        "t.csv",
        "t,q1,q2,q3,q4,q5,q6,q7\n0,0,0,0,-1,0,1,0\n0.5,0,0,0,-1,0,1,0\n1,0,0,0,-1,0,1,0\n",
    );
    let cases = [
        (
            panda.replacen("tau_max = 12.0\n", "", 1),
            "give `tau_max` for every joint or for none",
        ),
        (
            panda.replacen("mass = 0.646926\n", "", 1),
            "joint 2: give `mass`, `com` and `inertia` together",
        ),
        (
            panda.replacen("inertia = [0.70337,", "inertia = [0.01,", 1),
            "joint 1: invalid robot model: link inertia has principal moments",
        ),
    ];
    for (i, (text, message)) in cases.iter().enumerate() {
        let robot = write(dir.path(), &format!("bad{i}.toml"), text);
        let o = cli(&[
            "limits",
            "check",
            traj.to_str().unwrap(),
            "--robot",
            robot.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(message), "{}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("bad{i}.toml:")),
            "{}",
            stderr(&o)
        );
    }
    let good = write(dir.path(), "good.toml", &panda);
    let o = cli(&[
        "limits",
        "check",
        traj.to_str().unwrap(),
        "--robot",
        good.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["not_checked"].as_object().unwrap().is_empty(), "{v}");
}

#[test]
fn retime_writes_a_trajectory_that_limits_check_accepts_and_never_overwrites_unasked() {
    let dir = tempfile::tempdir().unwrap();
    // A 0.5 s move of joint 1 by 2 rad from Franka's ready pose: far beyond its limits.
    let mut text = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
    for k in 0..=50 {
        let x = k as f64 / 50.0;
        let q1 = 2.0 * x * x * x * (10.0 - 15.0 * x + 6.0 * x * x);
        text.push_str(&format!("{},{q1},-0.785,0,-2.356,0,1.571,0.785\n", 0.5 * x));
    }
    let fast = write(dir.path(), "fast.csv", &text);
    let out = dir.path().join("retimed.csv");
    let args = |mode: &str| {
        vec![
            "retime".to_string(),
            fast.to_str().unwrap().into(),
            "--robot".into(),
            "panda".into(),
            "--mode".into(),
            mode.into(),
            "--out".into(),
            out.to_str().unwrap().into(),
            "--json".into(),
        ]
    };
    let run = |a: &[String]| cli(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let o = run(&args("fastest"));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["ok"], true);
    assert!(v["peak_usage_before"]["velocity"].as_f64().unwrap() > 100.0);
    // Joint 1's 2 rad at no more than 2.175 rad/s: at least 0.92 s.
    let fastest = v["duration_s"].as_f64().unwrap();
    assert!(fastest > 2.0 / 2.175 && fastest < 2.0, "{fastest}");
    let o = cli(&["limits", "check", out.to_str().unwrap(), "--robot", "panda"]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    // An existing output is kept unless --force; uniform slowing is slower than the fastest.
    let before = std::fs::read(&out).unwrap();
    let o = run(&args("uniform"));
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&out).unwrap(), before);
    let mut forced = args("uniform");
    forced.push("--force".into());
    let o = run(&forced);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["duration_s"].as_f64().unwrap() > fastest);
    let o = run(&{
        let mut a = args("quickest");
        a.push("--force".into());
        a
    });
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("`quickest`") && stderr(&o).contains("`uniform`"));
}

/// Careless or hostile arguments are refused before anything connects, with exit 2 and a
/// sentence that states the rule (each was accepted, exited 1, or stated a wrong range).
#[test]
fn hostile_arguments_exit_2_stating_the_rule() {
    let dir = tempfile::tempdir().unwrap();
    let mut seven = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
    for k in 0..3 {
        seven.push_str(&format!("{},0,-0.3,0,-2.2,0,2.0,0.8\n", k as f64 * 0.5));
    }
    let file = write(dir.path(), "seven.csv", &seven);
    let file = file.to_str().unwrap();
    let refused = |args: &[&str], says: &str| {
        let o = cli(args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    };
    let range = "a whole number from 0 to 232";
    refused(&["ros2", "graph", "--domain", "-1"], range);
    refused(&["ros2", "graph", "--domain", "99999"], range);
    refused(
        &["ros2", "graph", "--seconds", "0"],
        "--seconds 0: give a time above 0 and at most 600 s",
    );
    refused(
        &["ros2", "send", file, "--controller", ""],
        "--controller ``: give the controller's name",
    );
    refused(
        &["ros2", "send", file, "--controller", "/arm controller!"],
        "--controller `/arm controller!`",
    );
    refused(
        &["franka", "state", "--host", "not a host!"],
        "--host `not a host!`: not an address",
    );
    // A 6-joint file with velocities given for the 7-joint Panda: its `q1_vel` was read as
    // joint 7, and `limits check` said it was within the limits.
    let six = write(
        dir.path(),
        "six.csv",
        "t,q1,q2,q3,q4,q5,q6,q1_vel,q2_vel,q3_vel,q4_vel,q5_vel,q6_vel\n0,0,-0.3,0,-2.2,0,2.0,0,0,0,0,0,0\n1,0,-0.3,0,-2.2,0,2.0,0,0,0,0,0,0\n",
    );
    for args in [
        vec!["limits", "check", six.to_str().unwrap(), "--robot", "panda"],
        vec![
            "ros2",
            "send",
            six.to_str().unwrap(),
            "--controller",
            "/arm",
        ],
    ] {
        refused(
            &args,
            "6 joint position column(s) (q1, q2, q3, q4, q5, q6) for a 7-joint robot",
        );
    }
    // `franka identify`'s calibration over its own recording: refused before connecting.
    let same = dir.path().join("same.csv");
    refused(
        &[
            "franka",
            "identify",
            "--host",
            "127.0.0.1",
            "--out",
            same.to_str().unwrap(),
            "--record",
            same.to_str().unwrap(),
        ],
        "the calibration would be written over the recording",
    );
}

/// `collide`: a swing of joint 1 through a shelf placed on the tool's way is a collision
/// (exit 1), named with the two bodies and its time, each row's near pairs listed in JSON
/// with signed distances; the same swing without the shelf, or stopped before it, passes;
/// a robot without shapes and a negative margin are refused (exit 2).
#[test]
fn collide_finds_the_shelf_on_the_way_and_lists_each_rows_near_pairs() {
    let dir = tempfile::tempdir().unwrap();
    let fr3 = std::fs::read_to_string(repo("configs/scenes/fr3.toml")).unwrap();
    let scene = cps_movement::scene::parse_scene(std::path::Path::new("fr3.toml"), &fr3).unwrap();
    let q0 = scene.initial_q.clone();
    // The tool's place with joint 1 turned 0.8 rad: a 10 cm cube centred there.
    let mut at = q0.clone();
    at[0] += 0.8;
    let p = scene.robot.chain.fk(&at).unwrap().translation.vector;
    let shelf = format!(
        "\n[[obstacle]]\nname = \"shelf\"\nshape = \"box\"\nxyz = [{}, {}, {}]\nsize = [0.1, 0.1, 0.1]\n",
        p.x, p.y, p.z
    );
    let with_shelf = write(dir.path(), "shelf.toml", &(fr3.clone() + &shelf));
    let plain = write(dir.path(), "plain.toml", &fr3);
    // Joint 1 from the start by `to` rad in 3 s, a row every 10 ms.
    let swing = |name: &str, to: f64| {
        let mut csv = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
        for k in 0..=300 {
            let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 300.0).cos();
            let mut q = q0.clone();
            q[0] += to * s;
            let cells: Vec<String> = q.iter().map(|v| v.to_string()).collect();
            csv += &format!("{},{}\n", k as f64 * 0.01, cells.join(","));
        }
        write(dir.path(), name, &csv)
    };
    let through = swing("through.csv", 1.2);
    let short = swing("short.csv", 0.3);
    let args = |csv: &std::path::Path, scene: &std::path::Path| {
        vec![
            "collide".to_string(),
            csv.display().to_string(),
            "--scene".into(),
            scene.display().to_string(),
        ]
    };
    let run = |a: Vec<String>| cli(&a.iter().map(String::as_str).collect::<Vec<_>>());

    let o = run(args(&through, &with_shelf));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(out.contains("COLLISION: `fr3_"), "{out}");
    assert!(out.contains("and `shelf` at t = "), "{out}");
    let mut a = args(&through, &with_shelf);
    a.push("--json".into());
    let j = stdout_json(&run(a));
    assert_eq!(j["ok"], false);
    assert_eq!(j["obstacles"], 2, "the table and the shelf");
    assert_eq!(j["collision"]["second"], "shelf");
    let rows = j["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 301);
    // The row at the tool's place: the hand or a finger inside the shelf (negative), and
    // every pair listed within 10 cm.
    let shelf_pairs = |row: &serde_json::Value| -> Vec<f64> {
        row["pairs"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| p["second"] == "shelf")
            .map(|p| p["distance"].as_f64().unwrap())
            .collect()
    };
    let deepest = rows
        .iter()
        .flat_map(shelf_pairs)
        .fold(f64::INFINITY, f64::min);
    assert!(deepest < -0.02, "{deepest}");
    assert!(
        rows.iter()
            .flat_map(|r| r["pairs"].as_array().unwrap().clone())
            .all(|p| p["distance"].as_f64().unwrap() < 0.1)
    );
    assert!(
        shelf_pairs(&rows[0]).iter().all(|d| *d > 0.005),
        "the start keeps clear of the shelf"
    );
    assert!(j["closest"]["distance"].as_f64().unwrap() <= deepest + 1e-12);
    // The collision comes before the rows reach the tool's place (joint 1 at 0.8 rad: row
    // 177 of the cosine swing), at or after the first row the shelf is within the margin.
    let t = j["collision"]["time"].as_f64().unwrap();
    let first_near = rows
        .iter()
        .position(|r| shelf_pairs(r).iter().any(|d| *d < 0.005))
        .unwrap();
    assert!(
        t <= 1.77 && t > (first_near as f64 - 1.0) * 0.01,
        "{t} {first_near}"
    );

    // Without the shelf, or stopped before it: ok.
    for (csv, scene) in [(&through, &plain), (&short, &with_shelf)] {
        let o = run(args(csv, scene));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stdout));
        assert!(String::from_utf8_lossy(&o.stdout).contains("ok: every pair keeps 5.0 mm"));
    }
    // A robot without shapes, a negative margin, --robot beside --scene: exit 2.
    let toml_robot = repo("configs/robots/panda.toml");
    let o = cli(&["collide", through.to_str().unwrap(), "--robot", &toml_robot]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("has no collision geometry: there is nothing to check"),
        "{}",
        stderr(&o)
    );
    let mut a = args(&through, &with_shelf);
    a.extend(["--margin".into(), "-0.01".into()]);
    let o = run(a);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--margin: the clearance margin must be a finite distance ≥ 0 m"));
    let mut a = args(&through, &with_shelf);
    a.extend(["--robot".into(), "ur3".into()]);
    assert_eq!(run(a).status.code(), Some(2));
}

const JOINT: &str = include_str!("../../../experiments/viapoint_joint.toml");

/// `[[obstacle]]` in an experiment file, in the scene files' form: a shelf on the joint
/// movement's way makes its execution a collision the guard refuses (a failed run naming
/// the shelf); one around the robot's start, one without a robot and one with a name the
/// scene already has are refused before anything runs, with their place.
#[test]
fn an_experiments_obstacles_join_its_scenes_world() {
    let dir = tempfile::tempdir().unwrap();
    let fast = JOINT.replace("generations = 15 ", "generations = 3  ");
    let ball = |name: &str, at: [f64; 3], radius: f64| {
        format!(
            "\n[[obstacle]]\nname = \"{name}\"\nshape = \"sphere\"\nxyz = [{}, {}, {}]\nradius = {radius}\n",
            at[0], at[1], at[2]
        )
    };
    // A ball on via point p2, which the tool passes.
    let file = write(
        dir.path(),
        "shelf.toml",
        &(fast.clone() + &ball("shelf", [1.12, 0.37, 1.45], 0.05)),
    );
    let out = dir.path().join("shelf");
    let (o, err) = common::run_quiet(&file, &out);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let s = common::json(&out.join("summary.json"));
    let failure = s["failure"].as_str().unwrap();
    assert!(failure.contains("and `shelf` at t = "), "{failure}");
    // Around the start (the tool at p0): refused where it stands in the file.
    common::refused(
        dir.path(),
        "start",
        &(fast.clone() + &ball("cup", [0.75, 0.02, 1.87], 0.06)),
        "[[obstacle]]: at the scene's start, `panda_",
    );
    // The scene's table is taken.
    common::refused(
        dir.path(),
        "taken",
        &(fast.clone() + &ball("table", [2.0, 0.0, 1.0], 0.1)),
        "not an object's or another obstacle's (got `table`)",
    );
    // Without a robot there is no world to put it in.
    let plain = std::fs::read_to_string(repo("experiments/viapoint.toml")).unwrap();
    common::refused(
        dir.path(),
        "no_robot",
        &(plain + &ball("shelf", [1.12, 0.37, 1.45], 0.05)),
        "[[obstacle]] places things in the robot's world, and this experiment has no [robot]",
    );
}

/// `[clearance]` needs shapes to keep apart and a kind that learns a robot's movement:
/// without a robot, with a robot that has none, or with a bad distance, weight or budget,
/// the file is refused with its place; `[joint] clearance` (where it was) names where it
/// went.
#[test]
fn a_clearance_is_refused_where_nothing_can_keep_it() {
    let dir = tempfile::tempdir().unwrap();
    let with = |extra: &str| format!("{JOINT}\n[clearance]\n{extra}");
    common::refused(
        dir.path(),
        "negative",
        &with("distance = -0.01\n"),
        "[clearance] `distance` must be finite, ≥ 0",
    );
    common::refused(
        dir.path(),
        "weight",
        &with("distance = 0.02\nweight = -1.0\n"),
        "[clearance] `weight` must be finite, ≥ 0",
    );
    common::refused(
        dir.path(),
        "iterations",
        &with("distance = 0.02\niterations = 0\n"),
        "[clearance] `iterations` must be in [1, 10000] (got 0)",
    );
    common::refused(
        dir.path(),
        "moved",
        &JOINT.replace("[joint]\n", "[joint]\nclearance = 0.02\n"),
        "[joint] `clearance` is `[clearance] distance` (every kind that learns a robot's movement keeps it): move it there",
    );
    // A kind without a robot has nothing to keep clear.
    let plain = std::fs::read_to_string(repo("experiments/viapoint.toml")).unwrap();
    common::refused(
        dir.path(),
        "no_robot",
        &format!("{plain}\n[clearance]\ndistance = 0.02\n"),
        "[clearance] keeps a robot's collision shapes apart while it learns, and kind = \"viapoint\" learns no robot's movement here",
    );
    // A robot without collision geometry (a TOML robot file) cannot keep one.
    let scene = std::fs::read_to_string(repo("configs/scenes/thesis.toml"))
        .unwrap()
        .replace(
            "model = \"panda\"",
            &format!("model = \"{}\"", repo("configs/robots/panda.toml")),
        );
    let scene = scene[..scene.find("# The table the robot stands on").unwrap()].to_string();
    std::fs::write(dir.path().join("toml_robot.toml"), scene).unwrap();
    common::refused(
        dir.path(),
        "shapeless",
        &with("distance = 0.02\n").replace("scene = \"thesis\"", "scene = \"toml_robot.toml\""),
        "[clearance]: the robot `panda` has no collision geometry to keep clear with",
    );
}

/// The FR3's scene with a 10 × 10 × 62 cm post on the table half a metre in front of the
/// arm, where its hand sweeps from one side to the other.
fn post_scene(dir: &std::path::Path) -> String {
    let scene = std::fs::read_to_string(repo("configs/scenes/fr3.toml")).unwrap()
        + "\n[[obstacle]]\nname = \"post\"\nshape = \"box\"\nxyz = [0.97, 0.02, 1.05]\nsize = [0.1, 0.1, 0.62]\n";
    write(dir, "post.toml", &scene)
        .to_str()
        .unwrap()
        .to_string()
}

const LEFT: &str = "-1.0,0.5,0,-1.5,0,2.0,0.785";
const RIGHT: &str = "1.0,0.5,0,-1.5,0,2.0,0.785";

/// `plan`: the straight way from one side of the post to the other goes through it
/// (`collide` says so); the planned way goes around, and the file it writes passes
/// `collide` and `limits check` — every pair kept 5 mm apart and every limit kept at 1 kHz —
/// from the start to the goal exactly. The same seed gives the same file, byte for byte.
#[test]
fn plan_goes_around_a_post_the_straight_way_hits() {
    let dir = tempfile::tempdir().unwrap();
    let scene = post_scene(dir.path());
    let straight = write(
        dir.path(),
        "straight.csv",
        &format!("t,q1,q2,q3,q4,q5,q6,q7\n0,{LEFT}\n2,0,0.5,0,-1.5,0,2.0,0.785\n4,{RIGHT}\n"),
    );
    let o = cli(&["collide", "--scene", &scene, straight.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("`post`"));
    let out = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let plan = |file: &str, seed: &str| {
        let o = cli(&[
            "plan", "--scene", &scene, "--from", LEFT, "--to", RIGHT, "--out", file, "--seed",
            seed, "--json",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        stdout_json(&o)
    };
    let j = plan(&out("p.csv"), "1");
    let points = j["waypoints"].as_array().unwrap();
    assert!(points.len() >= 3, "{j}");
    let q = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let parse = |s: &str| -> Vec<f64> { s.split(',').map(|x| x.parse().unwrap()).collect() };
    assert_eq!(q(&points[0]), parse(LEFT));
    assert_eq!(q(&points[points.len() - 1]), parse(RIGHT));
    assert!(j["clearance_m"].as_f64().unwrap() >= 0.005, "{j}");
    let o = cli(&["collide", "--scene", &scene, &out("p.csv")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stdout));
    let o = cli(&["limits", "check", "--robot", "fr3", &out("p.csv")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stdout));
    let text = std::fs::read_to_string(out("p.csv")).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(
        rows[1]
            .split(',')
            .skip(1)
            .map(|x| x.parse::<f64>().unwrap())
            .collect::<Vec<_>>(),
        parse(LEFT)
    );
    plan(&out("again.csv"), "1");
    assert_eq!(std::fs::read(out("again.csv")).unwrap(), text.as_bytes());
    // Another seed finds a way too.
    let j = plan(&out("other.csv"), "7");
    assert!(
        cli(&["collide", "--scene", &scene, &out("other.csv")])
            .status
            .success(),
        "{j}"
    );
}

/// `plan`'s bad ends are named by their flag (exit 2): a start inside the post, naming the
/// pair; a goal out of its range; a value that is not a number; a joint too few; a goal
/// pose out of reach or inside the post. A goal pose within reach is where the path's last
/// configuration puts the hand. No way within the samples is exit 1, saying what was tried.
#[test]
fn plan_names_bad_ends_and_says_what_it_tried() {
    let dir = tempfile::tempdir().unwrap();
    let scene = post_scene(dir.path());
    for (from, to, wanted) in [
        (
            "0,0.5,0,-1.5,0,2.0,0.785",
            RIGHT,
            "--from: the start is in collision: `fr3_link5` and `post` are",
        ),
        (
            LEFT,
            "1.0,0.5,0,0.5,0,2.0,0.785",
            "--to: the goal's joint 4 = 0.5000 rad is outside its range [-3.0421, -0.1518]",
        ),
        (
            "-1.0,NaN,0,-1.5,0,2.0,0.785",
            RIGHT,
            "--from: the start's joint 2 is not a finite number",
        ),
        (
            LEFT,
            "1.0,0.5,0,-1.5,0,2.0",
            "--to: the goal has 6 joint values; the robot has 7 joints",
        ),
    ] {
        let o = cli(&["plan", "--scene", &scene, "--from", from, "--to", to]);
        assert_eq!(o.status.code(), Some(2), "{wanted}: {}", stderr(&o));
        assert!(stderr(&o).contains(wanted), "{}", stderr(&o));
    }
    // A goal pose: out of reach, or inside the post.
    let base = [0.42244, 0.02, 0.74177];
    let hand = common::hand_at("fr3", &[1.0, 0.5, 0.0, -1.5, 0.0, 2.0, 0.785]);
    let world = |p: [f64; 3]| format!("{},{},{}", p[0] + base[0], p[1] + base[1], p[2] + base[2]);
    for (pose, wanted) in [
        (
            "3,0,1".to_string(),
            "--to-pose: the goal pose is out of reach",
        ),
        (
            world([0.55, 0.0, 0.35]),
            "--to-pose: the goal is in collision: `fr3_",
        ),
    ] {
        let o = cli(&[
            "plan",
            "--scene",
            &scene,
            "--from",
            LEFT,
            "--to-pose",
            &pose,
        ]);
        assert_eq!(o.status.code(), Some(2), "{wanted}: {}", stderr(&o));
        assert!(stderr(&o).contains(wanted), "{}", stderr(&o));
    }
    // A reachable one: the path ends where the tool is there.
    let o = cli(&[
        "plan",
        "--scene",
        &scene,
        "--from",
        LEFT,
        "--to-pose",
        &world(hand),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j = stdout_json(&o);
    let end: Vec<f64> =
        serde_json::from_value(j["waypoints"].as_array().unwrap().last().unwrap().clone()).unwrap();
    let there = common::hand_at("fr3", &end);
    for k in 0..3 {
        assert!(
            (there[k] - hand[k]).abs() < 1e-6,
            "{there:?} against {hand:?}"
        );
    }
    let o = cli(&[
        "plan",
        "--scene",
        &scene,
        "--from",
        LEFT,
        "--to",
        RIGHT,
        "--samples",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no collision-free path found within 1 random configurations"),
        "{}",
        stderr(&o)
    );
}

/// A movement CSV at 1 kHz: joint 7 of `q` turned by 0.3 rad in a second, at rest at both
/// ends (the quintic smoothstep).
fn wrist_turn(q: &str) -> String {
    let q: Vec<f64> = q.split(',').map(|x| x.parse().unwrap()).collect();
    let mut csv = String::from("t,q1,q2,q3,q4,q5,q6,q7\n");
    for k in 0..=1000 {
        let s = k as f64 / 1000.0;
        let mut p = q.clone();
        p[6] += 0.3 * (10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5));
        let row: Vec<String> = p.iter().map(|x| x.to_string()).collect();
        csv += &format!("{},{}\n", k as f64 / 1000.0, row.join(","));
    }
    csv
}

/// `plan --join`: a movement on each side of the post, joined by a transition that goes
/// around it; the file passes `collide` and `limits check`, and the movements' rows are in
/// it unchanged where the report puts them. A movement that itself sweeps through the post
/// is exit 2 naming it, its file and the pair; a missing file is exit 2 naming it.
#[test]
fn plan_joins_movements_around_the_post_between_them() {
    let dir = tempfile::tempdir().unwrap();
    let scene = post_scene(dir.path());
    let left = write(dir.path(), "left.csv", &wrist_turn(LEFT));
    let right = write(dir.path(), "right.csv", &wrist_turn(RIGHT));
    let out = dir.path().join("task.csv");
    let (l, r, o) = (
        left.to_str().unwrap(),
        right.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let run = cli(&[
        "plan", "--scene", &scene, "--join", l, r, "--out", o, "--json",
    ]);
    assert!(run.status.success(), "{}", stderr(&run));
    let j = stdout_json(&run);
    let stretches = j["stretches"].as_array().unwrap();
    let parts: Vec<&str> = stretches
        .iter()
        .map(|s| s["part"].as_str().unwrap())
        .collect();
    assert_eq!(parts, ["movement", "transition", "movement"], "{j}");
    assert!(
        stretches[1]["waypoints"].as_array().unwrap().len() >= 3,
        "{j}"
    );
    for args in [
        vec!["collide", "--scene", &scene, o],
        vec!["limits", "check", "--robot", "fr3", o],
    ] {
        let c = cli(&args);
        assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stdout));
    }
    let joined = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<f64>> = joined
        .lines()
        .skip(1)
        .map(|l| l.split(',').skip(1).map(|x| x.parse().unwrap()).collect())
        .collect();
    for (stretch, file) in [(&stretches[0], &left), (&stretches[2], &right)] {
        let first = (stretch["start_s"].as_f64().unwrap() * 1000.0).round() as usize;
        let text = std::fs::read_to_string(file).unwrap();
        for (k, line) in text.lines().skip(1).enumerate() {
            let given: Vec<f64> = line
                .split(',')
                .skip(1)
                .map(|x| x.parse().unwrap())
                .collect();
            for (a, b) in given.iter().zip(&rows[first + k]) {
                assert!((a - b).abs() < 1e-9, "row {k} of {}", file.display());
            }
        }
    }
    // A movement through the post; a file that is not there.
    let sweep = write(
        dir.path(),
        "sweep.csv",
        &format!("t,q1,q2,q3,q4,q5,q6,q7\n0,{LEFT}\n2,0,0.5,0,-1.5,0,2.0,0.785\n4,{RIGHT}\n"),
    );
    let bad = cli(&[
        "plan",
        "--scene",
        &scene,
        "--join",
        r,
        sweep.to_str().unwrap(),
    ]);
    assert_eq!(bad.status.code(), Some(2), "{}", stderr(&bad));
    let text = stderr(&bad);
    assert!(
        text.contains("--join: movement 2, ") && text.contains("`post`"),
        "{text}"
    );
    assert!(
        text.contains("(movement 2 is ") && text.contains("sweep.csv)"),
        "{text}"
    );
    let missing = dir.path().join("missing.csv");
    let bad = cli(&[
        "plan",
        "--scene",
        &scene,
        "--join",
        l,
        missing.to_str().unwrap(),
    ]);
    assert_eq!(bad.status.code(), Some(2), "{}", stderr(&bad));
    assert!(stderr(&bad).contains("missing.csv"), "{}", stderr(&bad));
}
