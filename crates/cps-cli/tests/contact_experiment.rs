//! `kind = "contact"` end to end: the shipped experiments/contact.toml run on franky-sim
//! with the test fixture's table (MuJoCo's contact force logged as the truth), and bad
//! `[contact]` sections named with their place in the file.

mod common;
use cps_testkit::franky_sim as sim;

use common::{run_quiet as run, write};
use sim::{FrankySim, SimOptions};

const SHIPPED: &str = include_str!("../../../experiments/contact.toml");

fn on(host: &str) -> String {
    let text = SHIPPED.replace("host = \"127.0.0.1\"", &format!("host = \"{host}\""));
    assert!(text.contains(host));
    text
}

#[test]
fn the_shipped_contact_experiment_presses_the_simulated_table() {
    let Some(sim) = FrankySim::start_with(
        "127.0.0.90",
        SimOptions {
            table: Some(0.40),
            friction: Some(0.5),
            truth: true,
            ..Default::default()
        },
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "contact.toml", &on(&sim.host));
    let out = dir.path().join("out");
    let (o, err) = run(&file, &out);
    assert!(o.status.success(), "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["complete"], true, "{summary}");
    let c = &summary["contact"];
    assert!(
        c["ending"]
            .as_str()
            .unwrap()
            .starts_with("pressed along the profile and lifted off")
    );
    // Contact on the table's top (the fingertips sink 1 mm into MuJoCo's soft contact... and
    // the tool centre point sits a little above the pads).
    let z = c["contact_point_m"][2].as_f64().unwrap();
    assert!((z - 0.40).abs() < 0.015, "contact at z = {z}");
    assert!(c["force_rms_error_n"].as_f64().unwrap() < 3.0, "{c}");
    for f in [
        "contact.csv",
        "force.png",
        "force.svg",
        "path.png",
        "report.html",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    // The estimated force in the table of results agrees with MuJoCo's while the profile
    // holds 10 N (rows matched to MuJoCo's steps by the robot state's message id).
    let truth = sim.truth();
    let text = std::fs::read_to_string(out.join("contact.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    let pressing: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r[col("stage")] == "press" && r[col("desired")].parse::<f64>().unwrap() > 9.9)
        .map(|r| {
            (
                r[col("t")].parse().unwrap(),
                r[col("pressing")].parse().unwrap(),
            )
        })
        .collect();
    assert!(pressing.len() > 2000, "{} rows at 10 N", pressing.len());
    let mean_truth = truth
        .iter()
        .filter(|t| t.normal > 0.0)
        .map(|t| t.normal)
        .sum::<f64>()
        / truth.iter().filter(|t| t.normal > 0.0).count() as f64;
    let mean_est = pressing.iter().map(|p| p.1).sum::<f64>() / pressing.len() as f64;
    eprintln!(
        "mean estimate at 10 N: {mean_est:.2} N; MuJoCo's mean force in contact {mean_truth:.2} N"
    );
    assert!((mean_est - 10.0).abs() < 1.0 && (mean_truth - 10.0).abs() < 1.5);
    // A lamp hanging where the approach starts (`above`, in the world: the scene's base at
    // (0.42244, 0.02, 0.74177) plus (0.45, 0, 0.47)): the free motion there is refused by
    // the guard, naming it, and the arm does not move.
    let lamp = "\n[[obstacle]]\nname = \"lamp\"\nshape = \"sphere\"\nxyz = [0.87244, 0.02, 1.21177]\nradius = 0.06\n";
    let file = write(dir.path(), "lamp.toml", &(on(&sim.host) + lamp));
    let (o, err) = run(&file, &dir.path().join("lamp"));
    assert_ne!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("the free motion above the surface") && err.contains("and `lamp` at t = "),
        "{err}"
    );
}

#[test]
fn bad_contact_sections_are_named_with_their_place() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let cases = [
        (
            SHIPPED.replace("stiffness = [2000.0, 150.0]", "stiffness = [9000.0, 150.0]"),
            "contact.toml:37:13: [contact] `stiffness`: translational stiffness along x 9000 N/m is out of range",
        ),
        (
            SHIPPED.replace("speed = 0.03 ", "speed = 3.0  "),
            "contact.toml:32:9: [contact] `speed` must be between 0.001 and 0.1 (got 3.0)",
        ),
        (
            SHIPPED.replace(
                "force = 10.0\n\n[[contact.waypoints]]\nt = 5.0",
                "force = 500.0\n\n[[contact.waypoints]]\nt = 5.0",
            ),
            "[[contact.waypoints]] waypoints[1]: force 500 N is out of range: it must lie in [0, 100]",
        ),
        (
            SHIPPED.replace("ceiling = 30.0", "ceiling = 8.0 "),
            "at or above the ceiling of 8 N",
        ),
        (
            SHIPPED.replace("drive = \"franky-sim\"", "drive = \"mujoco\"    "),
            "[contact] drive: `mujoco` is not one of franky-sim (franky-sim's FR3: rotor inertia and joint friction), rigid (or link: a Franka's torque sensors, after the gears)",
        ),
        (
            SHIPPED
                .replace("backend = \"franka\"", "backend = \"kinematic\"")
                .replace("host = \"127.0.0.1\"", "")
                .replace("realtime = \"ignore\"", ""),
            "kind = \"contact\" drives a Franka in torque mode",
        ),
        (
            format!("{SHIPPED}\n[dmp]\nbasis_functions = 5\n"),
            "unknown field `dmp`",
        ),
        (
            SHIPPED.replace("[contact]", "[contact]\ndemonstration = \"p.csv\""),
            "give either `demonstration` (a profile file) or [[contact.waypoints]], not both",
        ),
    ];
    for (text, expected) in cases {
        let file = write(dir.path(), "contact.toml", &text);
        let (o, err) = run(&file, &out);
        assert_eq!(o.status.code(), Some(2), "{expected}: {err}");
        assert!(err.contains(expected), "expected `{expected}` in: {err}");
    }
    // A demonstrated profile from a file: read, and its missing column named.
    let profile = dir.path().join("p.csv");
    std::fs::write(&profile, "t,dx,dy,force\n0,0,0,0\n1,0,0,5\n").unwrap();
    let text = SHIPPED.replace("[contact]", "[contact]\ndemonstration = \"p.csv\"");
    let cut = text.find("[[contact.waypoints]]").unwrap();
    let end = text.find("[output]").unwrap();
    let text = format!("{}{}", &text[..cut], &text[end..]);
    let file = write(dir.path(), "contact.toml", &text);
    let (o, err) = run(&file, &out);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("the header has no `dz` column"), "{err}");
}
