//! Learning that keeps clear, kind by kind (`[clearance]`), on the thesis's Panda with a
//! ball where the learned movement's hand goes. Without `[clearance]` the guard refuses
//! the movement by name and nothing is executed past it; with it the run completes —
//! every command the in-process robot got was judged by the guard at 1 kHz, 5 mm margin,
//! the check tested against MuJoCo's distances — with the closest pair where the
//! clearance asks and the kind's own targets still met.

mod common;

use common::{json, repo, run_quiet, write};

/// `file` with a ball of `radius` at `xyz` in its world, and `extra` appended.
fn with_ball(file: &str, xyz: [f64; 3], radius: f64, extra: &str) -> String {
    let text = std::fs::read_to_string(repo(file)).unwrap();
    format!(
        "{text}\n[[obstacle]]\nname = \"ball\"\nshape = \"sphere\"\nxyz = [{}, {}, {}]\nradius = {radius}\n{extra}",
        xyz[0], xyz[1], xyz[2]
    )
}

const CLEARANCE: &str = "\n[clearance]\ndistance = 0.02\n";

/// The executed kind: its warm start (the analytic optimum) puts the right finger into a
/// ball beside the path at t ≈ 5 s; with `[clearance]` it is first kept clear on the
/// model and every execution's cost keeps it.
#[test]
fn the_executed_kind_learns_around_a_ball() {
    let dir = tempfile::tempdir().unwrap();
    let ball = [1.122, 0.104, 1.314];
    let plain = write(
        dir.path(),
        "plain.toml",
        &with_ball("experiments/viapoint_executed.toml", ball, 0.05, ""),
    );
    let (o, err) = run_quiet(&plain, &dir.path().join("plain"));
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("the guard refused it: `panda_rightfinger` and `ball`")
            && err.contains("[clearance] (a distance) learns a movement that keeps clear"),
        "{err}"
    );

    let kept = write(
        dir.path(),
        "kept.toml",
        &with_ball("experiments/viapoint_executed.toml", ball, 0.05, CLEARANCE),
    );
    let out = dir.path().join("kept");
    let (o, err) = run_quiet(&kept, &out);
    assert!(o.status.success(), "{err}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["complete"], true);
    let before = s["warm_start_kept_clear"]["closest"][0]["distance_m"]
        .as_f64()
        .unwrap();
    let after = s["clearance"]["closest"]["distance_m"].as_f64().unwrap();
    assert!(before < 0.0, "the optimum was in the ball: {before}");
    assert!(after > 0.0195, "kept clear as executed: {after}");
    assert_eq!(s["clearance"]["closest"]["second"], "ball");
    for e in s["via_errors_m"].as_array().unwrap() {
        assert!(e.as_f64().unwrap() < 1e-3, "{s}");
    }
    assert_eq!(s["refused_candidates"], 0);
}

/// The ProMP kind: the conditioned mean passes a small ball at t ≈ 7 s; with
/// `[clearance]` the most likely movement of the conditioned ProMP that keeps it is
/// executed instead — still through the via point it was conditioned on (pinned by the
/// conditioned covariance), within a millimetre.
#[test]
fn the_promp_kind_executes_its_most_likely_clear_movement() {
    let dir = tempfile::tempdir().unwrap();
    let ball = [1.0133, -0.3193, 1.1417];
    let plain = write(
        dir.path(),
        "plain.toml",
        &with_ball("experiments/promp.toml", ball, 0.02, ""),
    );
    let (o, err) = run_quiet(&plain, &dir.path().join("plain"));
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("executing the conditioned ProMP") && err.contains("and `ball` at t = 6."),
        "{err}"
    );

    let kept = write(
        dir.path(),
        "kept.toml",
        &with_ball("experiments/promp.toml", ball, 0.02, CLEARANCE),
    );
    let out = dir.path().join("kept");
    let (o, err) = run_quiet(&kept, &out);
    assert!(o.status.success(), "{err}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["complete"], true);
    let k = &s["promp"]["kept_clear"];
    let (before, after) = (
        k["closest"][0]["distance_m"].as_f64().unwrap(),
        k["closest"][1]["distance_m"].as_f64().unwrap(),
    );
    assert!(before < 0.005, "within the guard's margin before: {before}");
    assert!(after > 0.0195, "{after}");
    let via = s["promp"]["executed"]["via_error_m"].as_f64().unwrap();
    assert!(via < 1e-3, "through the via point: {via}");
}

/// The sweep: an imitation with `[clearance] distance = 0.05` bent its movement into a
/// jump at the start (velocity 111 %, acceleration 2 118 %, torque rate 8 911 % of the
/// limits), `"ok": false` in the summary, and the run exited 0. The bend is judged at the
/// control rate: a run whose bend breaks a limit fails (exit 1), `limits = "report"` or not
/// (it keeps reporting the thesis's start beyond joint 4's range, a fact of the scene).
#[test]
fn an_imitation_bent_into_a_jump_fails_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let ball = [0.82, 0.10, 1.86];
    let bent = write(
        dir.path(),
        "bent.toml",
        &with_ball(
            "experiments/imitation.toml",
            ball,
            0.03,
            "\n[clearance]\ndistance = 0.05\n",
        ),
    );
    let out = dir.path().join("bent");
    let (o, err) = run_quiet(&bent, &out);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("[clearance] bent the imitation by ridge into a movement that breaks joint")
            && err.contains("lower `[clearance] distance`"),
        "{err}"
    );
    let s = json(&out.join("summary.json"));
    assert_eq!(s["imitations"][0]["limit_usage"]["ok"], false);
    // The shipped imitation itself, unbent, reports and completes.
    let plain = write(
        dir.path(),
        "plain.toml",
        &std::fs::read_to_string(repo("experiments/imitation.toml")).unwrap(),
    );
    let (o, err) = run_quiet(&plain, &dir.path().join("plain"));
    assert!(o.status.success(), "{err}");
}
