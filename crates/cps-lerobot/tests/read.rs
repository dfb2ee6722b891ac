//! The reader against a dataset written by LeRobot 0.6.1's own `LeRobotDataset.create` /
//! `add_frame` / `save_episode` / `finalize` (tests/data/make_fixture.py made it, once),
//! and against that dataset broken in the ways a user's copy breaks.

use std::path::{Path, PathBuf};

use cps_lerobot::Dataset;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fr3_reach")
}

/// The fixture's episodes, as make_fixture.py computes them.
fn reach(episode: usize, n: usize) -> Vec<Vec<f64>> {
    let start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let dir = [1.0, 0.5, -0.5, 0.8, 0.3, -0.4, 0.6];
    (0..n)
        .map(|k| {
            let s = k as f64 / (n - 1) as f64;
            let b = 10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5);
            (0..7)
                .map(|j| start[j] + b * 0.1 * (episode + 1) as f64 * dir[j])
                .collect()
        })
        .collect()
}

fn copy_of_fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    fn copy(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap() {
            let e = e.unwrap();
            let target = to.join(e.file_name());
            if e.path().is_dir() {
                copy(&e.path(), &target);
            } else {
                std::fs::copy(e.path(), target).unwrap();
            }
        }
    }
    copy(&fixture(), dir.path());
    dir
}

#[test]
fn lerobots_own_dataset_reads_back_every_value() {
    let ds = Dataset::open(&fixture()).unwrap();
    let info = ds.info();
    assert_eq!(info.codebase_version, "v3.0");
    assert_eq!(info.fps, 30.0);
    assert_eq!(info.robot_type.as_deref(), Some("panda"));
    assert_eq!(
        (info.total_episodes, info.total_frames, info.total_tasks),
        (3, 127, 2)
    );
    assert_eq!(ds.tasks(), ["reach the left bin", "reach the right bin"]);
    let lengths: Vec<usize> = ds.episodes().iter().map(|e| e.length).collect();
    assert_eq!(lengths, [40, 52, 35]);
    assert_eq!(ds.episodes()[1].tasks, ["reach the right bin"]);
    assert_eq!(ds.episodes()[2].frames, 92..127);
    for (e, n) in [(0, 40), (1, 52), (2, 35)] {
        let f = ds.frames(e, "observation.state").unwrap();
        assert_eq!(f.names[0], "panda_joint1");
        assert_eq!(f.names.len(), 7);
        let q = reach(e, n);
        assert_eq!(f.values.len(), n);
        for (k, row) in f.values.iter().enumerate() {
            // Stored as float32 by LeRobot.
            assert!(
                (f.t[k] - k as f64 / 30.0).abs() < 1e-6,
                "t[{k}] = {}",
                f.t[k]
            );
            for j in 0..7 {
                assert!(
                    (row[j] - q[k][j]).abs() < 1e-6,
                    "episode {e} frame {k} joint {j}"
                );
            }
        }
    }
    let a = ds.frames(1, "action").unwrap();
    assert_eq!(a.names.last().map(String::as_str), Some("gripper"));
    assert_eq!(a.values[0].len(), 8);
    assert_eq!(a.values[0][7], 0.04f32 as f64);
    assert_eq!(a.values[51][7], 0.0);
}

#[test]
fn bad_datasets_are_refused_naming_the_file_and_the_fault() {
    let missing = tempfile::tempdir().unwrap();
    let e = Dataset::open(missing.path()).unwrap_err().to_string();
    assert!(
        e.contains("meta/info.json") && e.contains("not a LeRobot dataset"),
        "{e}"
    );

    let e = Dataset::open(Path::new("/no/such/dataset"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/no/such/dataset") && e.contains("no such folder"),
        "{e}"
    );

    let ds = Dataset::open(&fixture()).unwrap();
    let e = ds.frames(3, "observation.state").unwrap_err().to_string();
    assert!(e.contains("no episode 3") && e.contains("0 to 2"), "{e}");
    let e = ds.frames(0, "observation.nope").unwrap_err().to_string();
    assert!(
        e.contains("info.json") && e.contains("`observation.nope`") && e.contains("action"),
        "{e}"
    );

    // A truncated frames file.
    let copy = copy_of_fixture();
    let data = copy.path().join("data/chunk-000/file-000.parquet");
    let bytes = std::fs::read(&data).unwrap();
    std::fs::write(&data, &bytes[..bytes.len() / 2]).unwrap();
    let ds = Dataset::open(copy.path()).unwrap();
    let e = ds.frames(0, "observation.state").unwrap_err().to_string();
    assert!(
        e.contains("file-000.parquet") && e.contains("truncated"),
        "{e}"
    );

    // A truncated episode index.
    let copy = copy_of_fixture();
    let index = copy.path().join("meta/episodes/chunk-000/file-000.parquet");
    std::fs::write(&index, b"PAR1 and nothing more").unwrap();
    let e = Dataset::open(copy.path()).unwrap_err().to_string();
    assert!(
        e.contains("meta/episodes/chunk-000/file-000.parquet") && e.contains("parquet"),
        "{e}"
    );

    // An older format, and a feature that is not a vector of numbers.
    let copy = copy_of_fixture();
    let info = copy.path().join("meta/info.json");
    let text = std::fs::read_to_string(&info).unwrap();
    std::fs::write(&info, text.replace("\"v3.0\"", "\"v2.1\"")).unwrap();
    let e = Dataset::open(copy.path()).unwrap_err().to_string();
    assert!(e.contains("info.json") && e.contains("v2.1"), "{e}");
    std::fs::write(
        &info,
        text.replacen("\"dtype\": \"float32\"", "\"dtype\": \"video\"", 1),
    )
    .unwrap();
    let ds = Dataset::open(copy.path()).unwrap();
    let e = ds.frames(0, "observation.state").unwrap_err().to_string();
    assert!(
        e.contains("video") && e.contains("not a vector of numbers"),
        "{e}"
    );
    std::fs::write(&info, "{\"codebase_version\": ").unwrap();
    let e = Dataset::open(copy.path()).unwrap_err().to_string();
    assert!(e.contains("info.json") && e.contains("not JSON"), "{e}");
}

/// The hostile sweep's datasets: a description sending cps outside the dataset, a path
/// template padding to 70 000 digits, and frames files with bytes changed (12 of 300 made
/// the parquet crate panic). Each is a sentence naming the file, never a panic.
#[test]
fn hostile_descriptions_and_mutated_frames_are_sentences() {
    let copy = copy_of_fixture();
    let info = copy.path().join("meta/info.json");
    let original = std::fs::read_to_string(&info).unwrap();
    let data = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet";
    assert!(original.contains(data));
    let outside = copy.path().parent().unwrap().join("outside.parquet");
    for (template, fault) in [
        ("../outside.parquet", "inside its folder"),
        (outside.to_str().unwrap(), "inside its folder"),
        (
            "data/chunk-{chunk_index:070000d}/file-000.parquet",
            "70000 digits",
        ),
    ] {
        std::fs::write(&info, original.replace(data, template)).unwrap();
        let ds = Dataset::open(copy.path()).unwrap();
        let e = ds.frames(0, "action").unwrap_err().to_string();
        assert!(
            e.contains("info.json") && e.contains(fault),
            "{template}: {e}"
        );
    }
    std::fs::write(&info, &original).unwrap();
    let file = copy.path().join("data/chunk-000/file-000.parquet");
    let pristine = std::fs::read(&file).unwrap();
    let hook = std::panic::take_hook();
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let (mut refused, mut read, mut inside) = (0, 0, 0);
    std::panic::set_hook(Box::new(|_| {}));
    for _ in 0..300 {
        let mut bytes = pristine.clone();
        for _ in 0..1 + next() % 4 {
            let at = (next() % bytes.len() as u64) as usize;
            bytes[at] = next() as u8;
        }
        std::fs::write(&file, &bytes).unwrap();
        // A panic anywhere fails this test: the reader must have caught it.
        let out = std::panic::catch_unwind(|| {
            Dataset::open(copy.path()).and_then(|ds| ds.frames(0, "action"))
        });
        match out.expect("no panic reaches the caller") {
            Ok(_) => read += 1,
            Err(e) => {
                let e = e.to_string();
                assert!(e.contains("file-000.parquet"), "{e}");
                inside += usize::from(e.contains("the reader failed inside"));
                refused += 1;
            }
        }
    }
    std::panic::set_hook(hook);
    assert_eq!(refused + read, 300);
    // The parquet crate's own panics are among them (12 of 300 in the sweep).
    assert!(
        refused > 100 && inside > 0,
        "{refused} refused ({inside} inside the reader), {read} read"
    );
}
