//! A dataset cps writes, read back by cps's reader and laid out as LeRobot's own writer
//! laid out the fixture (tests/data/fr3_reach): the same files, the same column types.
//! (`python/tests/test_lerobot.py` opens it with pyarrow and pandas; LeRobot's own loader
//! opened one when this was written — docs/datasets.md.)

use std::path::Path;

use cps_lerobot::{Dataset, NewDataset, NewEpisode, NewFeature, write};
use parquet::file::reader::{FileReader, SerializedFileReader};

fn joints() -> Vec<String> {
    (1..=7).map(|i| format!("fr3_joint{i}")).collect()
}

fn episode(task: &str, n: usize, offset: f64) -> NewEpisode {
    let q: Vec<Vec<f64>> = (0..n)
        .map(|k| {
            (0..7)
                .map(|j| offset + 0.01 * k as f64 + 0.1 * j as f64)
                .collect()
        })
        .collect();
    let action = q.iter().skip(1).chain(q.last()).cloned().collect();
    NewEpisode {
        task: task.into(),
        values: vec![q, action],
    }
}

fn spec() -> NewDataset {
    NewDataset {
        fps: 50,
        robot_type: Some("fr3".into()),
        features: vec![
            NewFeature {
                name: "observation.state".into(),
                names: joints(),
            },
            NewFeature {
                name: "action".into(),
                names: joints(),
            },
        ],
    }
}

/// `(column path, physical type)` of a parquet file's leaves.
fn leaves(path: &Path) -> Vec<(String, String)> {
    let r = SerializedFileReader::new(std::fs::File::open(path).unwrap()).unwrap();
    r.metadata()
        .file_metadata()
        .schema_descr()
        .columns()
        .iter()
        .map(|c| (c.path().string(), format!("{:?}", c.physical_type())))
        .collect()
}

#[test]
fn written_then_read_back_frame_by_frame() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("out");
    let eps = vec![
        episode("pour", 30, 0.0),
        episode("stir", 12, 1.0),
        episode("pour", 20, 2.0),
    ];
    write(&root, &spec(), &eps, false).unwrap();
    let ds = Dataset::open(&root).unwrap();
    assert_eq!(ds.info().fps, 50.0);
    assert_eq!(ds.info().robot_type.as_deref(), Some("fr3"));
    assert_eq!(
        (
            ds.info().total_episodes,
            ds.info().total_frames,
            ds.info().total_tasks
        ),
        (3, 62, 2)
    );
    assert_eq!(ds.tasks(), ["pour", "stir"]);
    assert_eq!(ds.episodes()[2].tasks, ["pour"]);
    assert_eq!(ds.episodes()[2].frames, 42..62);
    for (e, ep) in eps.iter().enumerate() {
        for (f, name) in ["observation.state", "action"].iter().enumerate() {
            let frames = ds.frames(e, name).unwrap();
            assert_eq!(frames.names, joints());
            assert_eq!(frames.values.len(), ep.len());
            for (k, row) in frames.values.iter().enumerate() {
                assert!((frames.t[k] - k as f64 / 50.0).abs() < 1e-6);
                for (got, want) in row.iter().zip(&ep.values[f][k]) {
                    assert_eq!(*got, *want as f32 as f64, "episode {e} {name} frame {k}");
                }
            }
        }
    }
    // No staging folder is left behind.
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["out"]);
}

#[test]
fn the_files_are_laid_out_as_lerobots_own() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("out");
    write(&root, &spec(), &[episode("pour", 10, 0.0)], false).unwrap();
    let lerobot = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fr3_reach");
    for file in [
        "meta/info.json",
        "meta/stats.json",
        "meta/tasks.parquet",
        "data/chunk-000/file-000.parquet",
        "meta/episodes/chunk-000/file-000.parquet",
    ] {
        assert!(root.join(file).is_file(), "{file}");
        assert!(lerobot.join(file).is_file(), "{file}");
    }
    // The frames: the same leaves as LeRobot's for the features both have.
    let ours = leaves(&root.join("data/chunk-000/file-000.parquet"));
    let theirs = leaves(&lerobot.join("data/chunk-000/file-000.parquet"));
    let common: Vec<_> = theirs
        .iter()
        .filter(|(p, _)| !p.starts_with("observation.environment_state"))
        .cloned()
        .collect();
    assert_eq!(ours, common);
    assert_eq!(
        leaves(&root.join("meta/tasks.parquet")),
        leaves(&lerobot.join("meta/tasks.parquet"))
    );
    // The episode index: LeRobot's columns without its per-episode statistics.
    let theirs: Vec<_> = leaves(&lerobot.join("meta/episodes/chunk-000/file-000.parquet"))
        .into_iter()
        .filter(|(p, _)| !p.starts_with("stats/"))
        .collect();
    assert_eq!(
        leaves(&root.join("meta/episodes/chunk-000/file-000.parquet")),
        theirs
    );
    // info.json: the same keys.
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (a, b) = (
        read(&root.join("meta/info.json")),
        read(&lerobot.join("meta/info.json")),
    );
    let keys = |v: &serde_json::Value| -> Vec<String> {
        let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        k.sort();
        k
    };
    assert_eq!(keys(&a), keys(&b));
    let (a, b) = (
        read(&root.join("meta/stats.json")),
        read(&lerobot.join("meta/stats.json")),
    );
    assert_eq!(keys(&a["action"]), keys(&b["action"]));
}

#[test]
fn bad_episodes_and_an_existing_folder_are_refused_and_nothing_is_left() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("out");
    let mut bad = episode("pour", 5, 0.0);
    bad.values[1][3] = vec![0.0; 6];
    let e = write(&root, &spec(), &[bad], false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("episode 0, frame 3") && e.contains("`action` needs 7"),
        "{e}"
    );
    let mut nan = episode("pour", 5, 0.0);
    nan.values[0][2][4] = f64::NAN;
    assert!(write(&root, &spec(), &[nan], false).is_err());
    assert!(
        write(&root, &spec(), &[], false)
            .unwrap_err()
            .to_string()
            .contains("needs an episode")
    );
    assert!(!root.exists());
    std::fs::create_dir(&root).unwrap();
    let e = write(&root, &spec(), &[episode("pour", 5, 0.0)], false)
        .unwrap_err()
        .to_string();
    assert!(e.contains("exists already"), "{e}");
}

#[test]
fn only_a_dataset_of_cps_files_is_replaced_and_nothing_else_is_ever_removed() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("out");
    write(&root, &spec(), &[episode("pour", 10, 0.0)], false).unwrap();
    // Without replace: refused, saying how.
    let e = write(&root, &spec(), &[episode("stir", 4, 0.0)], false)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--force replaces it"), "{e}");
    // With it: the new dataset in place of the old.
    write(&root, &spec(), &[episode("stir", 4, 0.0)], true).unwrap();
    let ds = Dataset::open(&root).unwrap();
    assert_eq!(
        (ds.tasks(), ds.info().total_frames),
        (&["stir".to_string()][..], 4)
    );
    // A file cps did not write (a video, a note) makes the folder the user's: refused even
    // with replace, and every file stays.
    let video = root.join("videos/observation.images.wrist/chunk-000/file-000.mp4");
    std::fs::create_dir_all(video.parent().unwrap()).unwrap();
    std::fs::write(&video, b"not cps's").unwrap();
    let e = write(&root, &spec(), &[episode("pour", 3, 0.0)], true)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not a LeRobot dataset cps would replace") && e.contains("file-000.mp4"),
        "{e}"
    );
    assert_eq!(std::fs::read(&video).unwrap(), b"not cps's");
    assert_eq!(Dataset::open(&root).unwrap().info().total_frames, 4);
    // A folder beside it that looks like an old staging folder is never touched: cps
    // stages under a fresh name.
    let other = dir.path().join("other");
    let staging = dir.path().join(".other.cps-staging");
    std::fs::create_dir(&staging).unwrap();
    std::fs::write(staging.join("mine.txt"), b"mine").unwrap();
    write(&other, &spec(), &[episode("pour", 3, 0.0)], false).unwrap();
    assert_eq!(std::fs::read(staging.join("mine.txt")).unwrap(), b"mine");
    assert_eq!(Dataset::open(&other).unwrap().info().total_frames, 3);
}

/// The sweep's two data losses: `--force` onto a link to another dataset removed that
/// dataset's files through the link; onto a dataset holding an empty `videos/` it removed
/// the five files, failed, and left no dataset at all.
#[test]
fn force_through_a_link_or_onto_a_folder_with_more_loses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let theirs = dir.path().join("theirs");
    write(&theirs, &spec(), &[episode("pour", 10, 0.0)], false).unwrap();
    let before: Vec<Vec<u8>> = cps_lerobot::write::FILES
        .iter()
        .map(|f| std::fs::read(theirs.join(f)).unwrap())
        .collect();
    let link = dir.path().join("mine");
    std::os::unix::fs::symlink(&theirs, &link).unwrap();
    let e = write(&link, &spec(), &[episode("stir", 4, 0.0)], true)
        .unwrap_err()
        .to_string();
    assert!(e.contains("symbolic link"), "{e}");
    for (f, b) in cps_lerobot::write::FILES.iter().zip(&before) {
        assert_eq!(&std::fs::read(theirs.join(f)).unwrap(), b, "{f}");
    }
    std::fs::create_dir(theirs.join("videos")).unwrap();
    let e = write(&theirs, &spec(), &[episode("stir", 4, 0.0)], true)
        .unwrap_err()
        .to_string();
    assert!(e.contains("videos"), "{e}");
    assert_eq!(Dataset::open(&theirs).unwrap().info().total_frames, 10);
    let mut names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert_eq!(names, ["mine", "theirs"]);
}
