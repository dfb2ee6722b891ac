//! `cps-cli promp`: fit, condition, sample and stats from the command line, checked
//! against the demonstrations' own sample statistics, the via points, seeded
//! reproducibility, and bad input (exit 2, nothing written).

mod common;

use std::path::{Path, PathBuf};

use common::cli;
use cps_promp::ProMp;

/// `n` demonstrations drawn from a known 2-D ProMP with 8 bases, written as CSVs with
/// different durations (1.5 … 2.5 s) and sampling rates; returns their paths and, per
/// demonstration, its values on the normalised grid `s_k = k / 100`.
fn demos(dir: &Path, n: usize) -> (Vec<PathBuf>, Vec<Vec<[f64; 2]>>) {
    let b = 8;
    let mean: Vec<f64> = (0..2 * b)
        .map(|i| {
            if i < b {
                i as f64 / 7.0
            } else {
                (i as f64).sin()
            }
        })
        .collect();
    let cov: Vec<f64> = (0..4 * b * b)
        .map(|k| {
            let (i, j) = (k / (2 * b), k % (2 * b));
            let d = (i as f64 - j as f64).abs();
            0.01 * (-d * d / 4.0).exp()
        })
        .collect();
    let truth = ProMp::new(2, b, 1.0, mean, cov).unwrap();
    let weights = truth.sample(n, 11).unwrap();
    let grid: Vec<f64> = (0..=100).map(|k| k as f64 / 100.0).collect();
    let mut paths = Vec::new();
    let mut on_grid = Vec::new();
    for (i, w) in weights.iter().enumerate() {
        let (duration, samples) = (1.5 + i as f64 / n as f64, 150 + 7 * i);
        let s: Vec<f64> = (0..samples)
            .map(|k| k as f64 / (samples - 1) as f64)
            .collect();
        let rows = truth.trajectory(w, &s);
        let mut text = String::from("t,x,y\n");
        for (sk, r) in s.iter().zip(&rows) {
            text += &format!("{},{},{}\n", sk * duration, r[0], r[1]);
        }
        let p = dir.join(format!("demo{i:02}.csv"));
        std::fs::write(&p, text).unwrap();
        paths.push(p);
        on_grid.push(
            truth
                .trajectory(w, &grid)
                .iter()
                .map(|r| [r[0], r[1]])
                .collect(),
        );
    }
    (paths, on_grid)
}

fn ok(args: &[&str]) -> String {
    let o = cli(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The columns of a CSV by name.
fn columns(path: &Path) -> Vec<(String, Vec<f64>)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let names: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for l in lines {
        for (c, v) in l.split(',').enumerate() {
            cols[c].push(v.parse().unwrap());
        }
    }
    names.into_iter().zip(cols).collect()
}

#[test]
fn fit_and_stats_reproduce_the_demonstrations_sample_mean_and_std() {
    let dir = tempfile::tempdir().unwrap();
    let (paths, on_grid) = demos(dir.path(), 25);
    let p = dir.path().join("p.json");
    let mut args = vec!["promp", "fit", "--bases", "8", "--duration", "2"];
    let names: Vec<&str> = paths.iter().map(|p| p.to_str().unwrap()).collect();
    args.extend(&names);
    args.extend(["--out", p.to_str().unwrap(), "--json"]);
    let answer: serde_json::Value = serde_json::from_str(&ok(&args)).unwrap();
    assert_eq!(answer["demonstrations"], 25);
    assert_eq!(answer["dimensions"], serde_json::json!(["x", "y"]));
    let stats = dir.path().join("stats.csv");
    ok(&[
        "promp",
        "stats",
        p.to_str().unwrap(),
        "--dt",
        "0.02",
        "--out",
        stats.to_str().unwrap(),
    ]);
    let cols = columns(&stats);
    let heads: Vec<&str> = cols.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(heads, ["t", "x", "y", "x_std", "y_std"]);
    assert_eq!(cols[0].1.len(), 101);
    assert!((cols[0].1[100] - 2.0).abs() < 1e-12);
    // The demonstrations lie in the basis's span, so the ProMP's mean and σ at each time
    // are the demonstrations' own sample mean and standard deviation (N − 1).
    let n = on_grid.len() as f64;
    let mut worst = 0.0f64;
    for k in 0..=100 {
        for d in 0..2 {
            let m = on_grid.iter().map(|g| g[k][d]).sum::<f64>() / n;
            let v = on_grid.iter().map(|g| (g[k][d] - m).powi(2)).sum::<f64>() / (n - 1.0);
            worst = worst
                .max((cols[1 + d].1[k] - m).abs())
                .max((cols[3 + d].1[k] - v.sqrt()).abs());
        }
    }
    assert!(worst < 1e-6, "largest difference {worst}");
}

#[test]
fn conditioning_meets_the_via_points_and_seeded_samples_repeat() {
    let dir = tempfile::tempdir().unwrap();
    let (paths, _) = demos(dir.path(), 25);
    let d = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
    let mut args = vec!["promp", "fit", "--bases", "8", "--duration", "2"];
    let names: Vec<&str> = paths.iter().map(|p| p.to_str().unwrap()).collect();
    args.extend(&names);
    let p = d("p.json");
    args.extend(["--out", &p]);
    ok(&args);
    let q = d("q.json");
    let plot = d("q.svg");
    let text = ok(&[
        "promp",
        "condition",
        &p,
        "--at",
        "0.5",
        "--position",
        "0.3,0.6",
        "--at",
        "1.0",
        "--position",
        "0.6,0.4",
        "--std",
        "0",
        "--out",
        &q,
        "--plot",
        &plot,
        "--json",
    ]);
    let answer: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mean = &answer["via_points"][1]["mean"];
    assert!((mean[0].as_f64().unwrap() - 0.6).abs() < 1e-6, "{mean}");
    assert!(std::fs::read_to_string(&plot).unwrap().contains("<svg"));
    // Every sample passes through both via points.
    let (s1, s2, s3) = (d("s1"), d("s2"), d("s3"));
    for (out, seed) in [(&s1, "5"), (&s2, "5"), (&s3, "6")] {
        ok(&[
            "promp", "sample", &q, "--n", "4", "--seed", seed, "--dt", "0.25", "--out", out,
        ]);
    }
    for k in 1..=4 {
        let f = format!("sample_{k:03}.csv");
        let a = std::fs::read(Path::new(&s1).join(&f)).unwrap();
        assert_eq!(a, std::fs::read(Path::new(&s2).join(&f)).unwrap());
        assert_ne!(a, std::fs::read(Path::new(&s3).join(&f)).unwrap());
        let cols = columns(&Path::new(&s1).join(&f));
        let at = |t: f64| {
            cols[0]
                .1
                .iter()
                .position(|&x| (x - t).abs() < 1e-9)
                .unwrap()
        };
        for (t, x, y) in [(0.5, 0.3, 0.6), (1.0, 0.6, 0.4)] {
            let i = at(t);
            assert!((cols[1].1[i] - x).abs() < 1e-5 && (cols[2].1[i] - y).abs() < 1e-5);
        }
    }
}

#[test]
fn bad_input_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (paths, _) = demos(dir.path(), 3);
    let d = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
    let (a, b) = (paths[0].to_str().unwrap(), paths[1].to_str().unwrap());
    let one = d("one.csv");
    std::fs::write(&one, "t,x\n0,0\n1,1\n2,1\n").unwrap();
    let p = d("p.json");
    ok(&["promp", "fit", a, b, "--bases", "6", "--out", &p]);
    let out = d("out.json");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["fit", a, "--out", &out], "at least 2 files"),
        (
            vec!["fit", a, &one, "--out", &out],
            "must have the same dimensions",
        ),
        (
            vec!["fit", a, b, "--bases", "1", "--out", &out],
            "--bases 1",
        ),
        (
            vec![
                "condition",
                &p,
                "--at",
                "9",
                "--position",
                "1,1",
                "--out",
                &out,
            ],
            "outside the demonstrated movement",
        ),
        (
            vec![
                "condition",
                &p,
                "--at",
                "1",
                "--position",
                "1",
                "--out",
                &out,
            ],
            "the ProMP has 2 dimensions",
        ),
        (
            vec![
                "condition",
                &p,
                "--at",
                "1",
                "--position",
                "1,1",
                "--at",
                "1",
                "--position",
                "0,0",
                "--out",
                &out,
            ],
            "contradict each other",
        ),
        (
            vec![
                "condition",
                &p,
                "--at",
                "1",
                "--position",
                "1,1",
                "--std",
                "-1",
                "--out",
                &out,
            ],
            "finite and ≥ 0",
        ),
        (vec!["stats", a, "--out", &out], "not JSON"),
        (vec!["sample", &p, "--n", "0", "--out", &out], "--n 0"),
        (vec!["sample", &p, "--dt", "0", "--out", &out], "--dt 0"),
    ];
    for (args, says) in cases {
        let mut full = vec!["promp"];
        full.extend(&args);
        let o = cli(&full);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!Path::new(&out).exists(), "{args:?} wrote {out}");
    }
    // An existing file is not replaced without --force, and a file that is not a ProMP
    // is not replaced even with it.
    let o = cli(&[
        "promp",
        "condition",
        &p,
        "--at",
        "1",
        "--position",
        "1,1",
        "--std",
        "1",
        "--out",
        a,
        "--force",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(std::fs::read_to_string(a).unwrap().starts_with("t,x,y"));
}
