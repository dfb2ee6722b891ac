//! The experiments library as a Rust user meets it: read a file, run it with an observer,
//! look at the outcome's numbers, write it as files.

use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use cps_experiment::budget::Ceilings;
use cps_experiment::{Event, Experiment, ExperimentError, Observer, Outcome, RunOptions, run};
use cps_outcome::files::table_csv;
use cps_outcome::outcome::{Column, Format, Table};
use cps_report::write::{WriteOptions, save};

/// The thesis's via-point task, small enough for a test: `generations` of CMA-ES with a
/// population of 16, `repetitions` runs.
fn viapoint(generations: u64, repetitions: usize, method: &str) -> Experiment {
    let text = format!(
        r#"
[experiment]
name = "small"
seed = 7
repetitions = {repetitions}
[dmp]
basis_functions = 10
tau = 10.0
dt = 0.01
[task]
start = [0.75, 0.02, 1.87]
goal = [0.55, -0.57, 1.45]
[[task.via]]
time = 4.0
position = [1.12, 0.37, 1.45]
[optimizer]
method = "{method}"
sigma0 = 0.5
population = 16
generations = {generations}
"#
    );
    Experiment::from_text(Path::new("small.toml"), &text, &Ceilings::default())
        .expect("a valid experiment")
}

fn run_quiet(exp: &Experiment, threads: usize) -> Outcome {
    run(
        exp,
        &RunOptions {
            threads: Some(threads),
            ..RunOptions::default()
        },
        &(),
    )
    .expect("the run succeeds")
}

fn number(outcome: &Outcome, key: &str) -> f64 {
    outcome.summary[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} is a number"))
}

#[test]
fn the_exact_solver_reaches_the_optimum_that_cma_es_is_measured_against() {
    let exact = run_quiet(&viapoint(10, 1, "exact"), 2);
    assert!(exact.complete());
    // The exact solver's cost is the optimum itself.
    let (best, optimum) = (number(&exact, "best_cost"), number(&exact, "optimum_cost"));
    assert!(
        (best - optimum).abs() <= 1e-9 * optimum,
        "{best} vs {optimum}"
    );
    // CMA-ES from the same file ends above it, never below (the optimum is exact).
    let learned = run_quiet(&viapoint(150, 1, "cmaes"), 2);
    assert!(number(&learned, "best_cost") >= optimum * (1.0 - 1e-9));
    assert_eq!(number(&learned, "optimum_cost"), optimum);
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let exp = viapoint(60, 3, "cmaes");
    let (one, two) = (run_quiet(&exp, 1), run_quiet(&exp, 2));
    let strip = |o: &Outcome| {
        let mut s = o.summary.clone();
        for run in s["runs"].as_array_mut().unwrap() {
            run.as_object_mut().unwrap().remove("seconds");
        }
        s
    };
    assert_eq!(strip(&one), strip(&two));
    for name in ["trajectory", "cost_history"] {
        assert_eq!(one.table(name), two.table(name), "table {name}");
    }
    assert_eq!(one.header.threads, 1);
    assert_eq!(two.header.threads, 2);
}

/// Counts generations and stops the run after `stop_after`.
struct Stopper {
    stop_after: u64,
    seen: AtomicU64,
    planned: AtomicU64,
    finished: Mutex<bool>,
}

impl Observer for Stopper {
    fn started(&self, generations: u64) {
        self.planned.store(generations, Ordering::SeqCst);
    }
    fn event(&self, event: Event<'_>) -> ControlFlow<()> {
        if let Event::Generation { best_so_far, .. } = event {
            assert!(best_so_far.is_finite());
            if self.seen.fetch_add(1, Ordering::SeqCst) + 1 >= self.stop_after {
                return ControlFlow::Break(());
            }
        }
        ControlFlow::Continue(())
    }
    fn finished(&self) {
        *self.finished.lock().unwrap() = true;
    }
}

#[test]
fn an_observer_sees_every_generation_and_can_stop_the_run() {
    let exp = viapoint(400, 1, "cmaes");
    let watcher = Stopper {
        stop_after: u64::MAX,
        seen: AtomicU64::new(0),
        planned: AtomicU64::new(0),
        finished: Mutex::new(false),
    };
    let full = run(&exp, &RunOptions::default(), &watcher).unwrap();
    assert_eq!(watcher.planned.load(Ordering::SeqCst), 400);
    assert_eq!(
        watcher.seen.load(Ordering::SeqCst),
        full.summary["generations"].as_u64().unwrap(),
        "one event per generation"
    );
    assert!(*watcher.finished.lock().unwrap());

    let stopper = Stopper {
        stop_after: 20,
        ..watcher
    };
    stopper.seen.store(0, Ordering::SeqCst);
    let part = run(&exp, &RunOptions::default(), &stopper).unwrap();
    assert!(!part.complete(), "a stopped run is marked incomplete");
    assert_eq!(part.summary["generations"].as_u64(), Some(20));
    assert_eq!(part.table("cost_history").unwrap().rows(), 20);
    // The finished part is a result like any other: its summary says so.
    assert_eq!(part.summary_json()["complete"], false);
}

#[test]
fn an_outcome_is_written_as_the_files_it_declares() {
    let outcome = run_quiet(&viapoint(30, 2, "cmaes"), 2);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("results");
    save(&outcome, &out, false, &WriteOptions { figures: false }).unwrap();
    // summary.json is the header, then the kind's fields, in order.
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let keys: Vec<&str> = json
        .as_object()
        .unwrap()
        .keys()
        .map(|k| k.as_str())
        .collect();
    assert_eq!(&keys[..3], ["experiment", "kind", "complete"]);
    assert_eq!(json, outcome.summary_json());
    // Each table is its CSV, row for row.
    for table in &outcome.tables {
        let csv = std::fs::read_to_string(out.join(format!("{}.csv", table.name))).unwrap();
        assert_eq!(csv.lines().count(), table.rows() + 1, "{}", table.name);
        assert_eq!(csv.as_bytes(), table_csv(table).unwrap());
    }
    // Without figures nothing is drawn, and the report is written only with them.
    assert!(!out.join("coordinates.png").exists());
    let manifest = std::fs::read_to_string(out.join("cps-manifest.json")).unwrap();
    assert!(manifest.contains("trajectory.csv"));
    // The same directory again is refused without force, kept with force.
    let again = save(&outcome, &out, false, &WriteOptions { figures: false });
    assert!(matches!(again, Err(ExperimentError::Input(_))), "{again:?}");
    save(&outcome, &out, true, &WriteOptions { figures: false }).unwrap();
}

#[test]
fn table_cells_follow_their_column_format() {
    let table = Table::new("t")
        .with(Column::numbers("fixed", vec![1.0, 0.5], Format::Fixed(3)))
        .with(Column::numbers(
            "sci",
            vec![1234.5, f64::NAN],
            Format::Sci(2),
        ))
        .with(Column::numbers("gap", vec![f64::NAN, 2.0], Format::ShortestSci).nan_as_empty())
        .with(Column::integers("n", vec![3, 4]))
        .with(Column::texts("name", vec!["a, b".into(), "c".into()]));
    let csv = String::from_utf8(table_csv(&table).unwrap()).unwrap();
    assert_eq!(
        csv,
        "fixed,sci,gap,n,name\n1.000,1.23e3,,3,\"a, b\"\n0.500,NaN,2e0,4,c\n"
    );
    let short = Table::new("bad")
        .with(Column::integers("a", vec![1, 2]))
        .with(Column::integers("b", vec![1]));
    let err = table_csv(&short).unwrap_err().to_string();
    assert!(err.contains("table bad: column b has 1 rows"), "{err}");
}

#[test]
fn a_way_point_out_of_reach_is_an_input_error_of_the_run() {
    // Via points are checked against the robot when the run opens it.
    let path = Path::new("../../experiments/viapoint_joint.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let far = text.replacen("[1.12, 0.37, 1.45]", "[3.5, 0.37, 1.45]", 1);
    assert_ne!(
        far, text,
        "the shipped file has the thesis's second via point"
    );
    let exp = Experiment::from_text(path, &far, &Ceilings::default()).unwrap();
    match run(&exp, &RunOptions::default(), &()) {
        Err(ExperimentError::Input(e)) => assert!(e.0.contains("reach"), "{e}"),
        other => panic!("expected an input error, got {other:?}"),
    }
}
