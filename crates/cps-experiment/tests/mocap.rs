//! Motion-capture takes as an experiment's demonstrations: the shipped example
//! (experiments/mocap_imitation.toml) runs, its demonstrations follow the path the takes
//! were recorded along, and a bad `[demonstrations]` is named with its place.

use std::path::Path;

use cps_experiment::budget::Ceilings;
use cps_experiment::{Experiment, RunOptions, run};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .and_then(Path::parent)
        .expect("the repository")
}

#[test]
fn the_shipped_takes_are_imitated_along_the_path_they_were_recorded_on() {
    let path = repo().join("experiments/mocap_imitation.toml");
    let exp = cps_experiment::experiment::load(&path, None, &Ceilings::default()).expect("loads");
    let out = run(
        &exp,
        &RunOptions {
            threads: Some(2),
            ..RunOptions::default()
        },
        &(),
    )
    .expect("runs");
    assert!(out.header.complete);
    let s = &out.summary;
    assert_eq!(s["demonstrations"]["kept"], 3, "{}", s["dropped"]);
    let takes: Vec<&str> = s["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["take"].as_str().unwrap())
        .collect();
    assert_eq!(
        takes,
        [
            "demos/takes/pour_1.c3d",
            "demos/takes/pour_2.c3d",
            "demos/takes/pour_3.c3d"
        ]
    );
    // The takes are the thesis's way-point path, each within a centimetre: the executed
    // imitation starts and ends at its start and goal within 1.5 cm (0.3 mm noise, a
    // registration 0.3 mm off).
    let rec = out
        .tables
        .iter()
        .find(|t| t.name == "recordings")
        .expect("recordings");
    let col = |n: &str| match &rec.column(n).unwrap().values {
        cps_outcome::outcome::Values::Numbers(v) => v.clone(),
        _ => panic!("{n} numbers"),
    };
    let kinds = match &rec.column("type").unwrap().values {
        cps_outcome::outcome::Values::Texts(v) => v.clone(),
        _ => panic!("types"),
    };
    let (x, y, z) = (col("x"), col("y"), col("z"));
    let rows: Vec<usize> = (0..kinds.len())
        .filter(|&i| kinds[i].contains("ridge"))
        .collect();
    let (first, last) = (rows[0], *rows.last().unwrap());
    let d = |i: usize, p: [f64; 3]| {
        ((x[i] - p[0]).powi(2) + (y[i] - p[1]).powi(2) + (z[i] - p[2]).powi(2)).sqrt()
    };
    assert!(
        d(first, [0.75, 0.02, 1.87]) < 0.015,
        "start {}",
        d(first, [0.75, 0.02, 1.87])
    );
    assert!(
        d(last, [0.55, -0.57, 1.45]) < 0.015,
        "goal {}",
        d(last, [0.55, -0.57, 1.45])
    );
    // Every imitation tracked on the robot within a millimetre.
    for f in s["imitations"].as_array().unwrap() {
        assert!(
            f["tracking"]["max_position_error_m"].as_f64().unwrap() < 1e-3,
            "{f}"
        );
    }
}

#[test]
fn a_bad_demonstrations_section_is_named_with_its_place() {
    let text = std::fs::read_to_string(repo().join("experiments/mocap_imitation.toml")).unwrap();
    let at = repo().join("experiments/bad.toml");
    let load = |t: &str| {
        Experiment::from_text(&at, t, &Ceilings::default())
            .map(|_| ())
            .unwrap_err()
            .to_string()
    };
    let e = load(&text.replace("[demonstrations]\n", "[demonstrations]\ncount = 5\n"));
    assert!(
        e.contains("bad.toml:") && e.contains("`count`") && e.contains("takes"),
        "{e}"
    );
    let e = load(&text.replace("\"m4\"]", "\"wrist\"]"));
    assert!(
        e.contains("pour_1.c3d") && e.contains("\"wrist\"") && e.contains("Tool:tip"),
        "{e}"
    );
    let e = load(&text.replace("markers = [\"tip\", \"m2\", \"m3\", \"m4\"]", ""));
    assert!(e.contains("`markers") || e.contains("markers ="), "{e}");
    let e = load(&text.replace("lab.toml", "missing.toml"));
    assert!(
        e.contains("missing.toml") && e.contains("cannot read the calibration"),
        "{e}"
    );
}
