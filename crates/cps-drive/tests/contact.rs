//! The contact task (`cps_drive::contact`) on franky-sim's FR3 with a table, MuJoCo's
//! contact force as the ground truth: a 10 N press while sliding 20 cm, at tables 2 cm
//! higher and lower than nominal; no table within reach; a force above the ceiling; the
//! simulator killed while pressing.
//!
//! Loopback addresses: 127.0.0.84–88.

use cps_testkit::franky_sim as sim;

use std::sync::atomic::AtomicBool;

use cps_drive::contact::{
    ContactEnding, ContactOutcome, ContactPlan, ContactWaypoint, ForcePrimitive, Stage, run_contact,
};
use cps_dynamics::Drive;
use cps_franka::control::{CartesianGains, SensingOptions, robot_dynamics};
use cps_franka::limits::{Arm, RateLimits};
use cps_franka::{Connection, LoopOptions, MotionEnd, Realtime};
use sim::{FrankySim, SimOptions, Truth};

fn plan() -> ContactPlan {
    let w = |t: f64, x: f64, force: f64| ContactWaypoint {
        t,
        offset: [x, 0.0, 0.0],
        force,
    };
    ContactPlan {
        above: [0.45, 0.0, 0.47],
        direction: [0.0, 0.0, -1.0],
        search: 0.15,
        speed: 0.03,
        detect: 3.0,
        ceiling: 30.0,
        retreat: 0.05,
        error_gain: 0.2,
        gains: CartesianGains {
            translation: [2000.0; 3],
            rotation: [150.0; 3],
            damping_ratio: 1.0,
            nullspace: 5.0,
        },
        force_gains: (0.2, 5.0, 30.0),
        sensing: SensingOptions::default(),
        primitive: ForcePrimitive::from_waypoints(&[
            w(0.0, 0.0, 0.0),
            w(1.0, 0.0, 10.0),
            w(5.0, 0.2, 10.0),
            w(6.0, 0.2, 0.0),
        ])
        .unwrap(),
    }
}

/// Runs `plan` on a simulator with a table at `table` (None: no table); `during` is called
/// with the simulator while the task runs.
fn run(
    host: &str,
    table: Option<f64>,
    plan: &ContactPlan,
    during: impl FnOnce(&FrankySim) + Send,
) -> Option<(ContactOutcome, Vec<Truth>)> {
    let sim = FrankySim::start_with(
        host,
        SimOptions {
            table,
            friction: Some(0.5),
            truth: true,
            ..Default::default()
        },
    )?;
    let mut conn = Connection::connect(&sim.host, Default::default()).unwrap();
    let (state, _) = conn
        .newest_state(std::time::Duration::from_secs(2))
        .unwrap();
    let mut plan = plan.clone();
    let (model, friction) = Drive::FrankySim
        .apply(robot_dynamics(&mut conn, &state).unwrap())
        .unwrap();
    plan.sensing.friction = friction;
    let stop = AtomicBool::new(false);
    // franky-sim is a Python process stepping MuJoCo: on a loaded CI machine it can pause
    // for longer than a robot's 100 ms without a state; half a second tells a pause from a
    // simulator that is gone. (The search without a table once ended interrupted in CI,
    // its cause unrecorded: the assertions now print the loop's ending and timing.)
    let options = LoopOptions {
        realtime: Realtime::Ignore,
        state_timeout: std::time::Duration::from_millis(500),
        ..Default::default()
    };
    let outcome = std::thread::scope(|scope| {
        scope.spawn(|| during(&sim));
        run_contact(
            &mut conn,
            &model,
            RateLimits::of(Arm::Fr3),
            &options,
            &plan,
            &stop,
        )
    })
    .unwrap();
    let truth = if outcome.report.ending.complete() {
        sim.truth()
    } else {
        Vec::new()
    };
    Some((outcome, truth))
}

/// MuJoCo's normal force averaged over the 10 steps up to `id`.
fn truth_force(
    truth: &[Truth],
    at: &std::collections::HashMap<u64, usize>,
    id: u64,
) -> Option<f64> {
    let i = *at.get(&id)?;
    let lo = i.saturating_sub(9);
    Some(truth[lo..=i].iter().map(|t| t.normal).sum::<f64>() / (i - lo + 1) as f64)
}

#[test]
fn presses_ten_newtons_along_the_profile_on_tables_at_two_heights() {
    // The highest and the lowest table of the plan's reach (a third, at 0.40 m, between
    // them, cost CI 20 s of real time and was dropped; contact_experiment.rs presses on it).
    for (host, top) in [("127.0.0.84", 0.42), ("127.0.0.85", 0.38)] {
        let Some((out, truth)) = run(host, Some(top), &plan(), |_| {}) else {
            return;
        };
        assert_eq!(
            out.ending,
            ContactEnding::Done,
            "{}",
            out.report.ending.sentence()
        );
        let at: std::collections::HashMap<u64, usize> =
            truth.iter().enumerate().map(|(i, t)| (t.id, i)).collect();
        // Contact where the table is, sensed within a few ms of MuJoCo's first contact.
        let (t_contact, p) = out.contact.unwrap();
        assert!(
            (p[2] - top).abs() < 0.01,
            "contact at z = {} on a table at {top}",
            p[2]
        );
        let onset = truth.iter().find(|t| t.normal > 0.0).unwrap().id;
        let flagged = out.ticks.iter().find(|k| k.t >= t_contact).unwrap().id;
        let latency = flagged as f64 - onset as f64;
        // While the profile holds 10 N (1 s to 5 s after contact): the truth against it.
        let mut err = Vec::new();
        let mut est = Vec::new();
        for k in out
            .ticks
            .iter()
            .filter(|k| k.stage == Stage::Press && k.t - t_contact > 1.0 && k.t - t_contact < 5.0)
        {
            if let Some(f) = truth_force(&truth, &at, k.id) {
                err.push(f - k.desired);
                est.push(k.pressing - f);
            }
        }
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        let (force_rms, peak, path_rms) = out.measures([0.0, 0.0, -1.0]);
        let onset_i = at[&onset];
        let truth_peak = (onset_i..onset_i + 500)
            .filter_map(|i| truth_force(&truth, &at, truth[i].id))
            .fold(0.0, f64::max);
        let end = out.ticks.last().unwrap();
        eprintln!(
            "table {top}: latency {latency} ms, truth − desired RMS {:.2} N (10 ms means), estimate − truth {:.2} N, estimate − desired {force_rms:.2} N, peak {peak:.1} N (estimate), {truth_peak:.1} N (MuJoCo, 10 ms, first 0.5 s), path RMS {:.1} mm, lifted to z = {:.3}",
            rms(&err),
            rms(&est),
            path_rms * 1e3,
            end.tool[2]
        );
        assert!(err.len() > 3000, "{} pressing ticks matched", err.len());
        assert!(latency < 40.0, "contact sensed {latency} ms late");
        assert!(
            rms(&err) < 8.0 && rms(&est) < 4.0 && force_rms < 3.0,
            "{} {}",
            rms(&err),
            rms(&est)
        );
        assert!(peak < 25.0 && path_rms < 0.02);
        // It lifted off: the tool ended above the table, no force asked for, none on it in
        // MuJoCo.
        assert!(end.tool[2] > top + 0.03 && end.desired == 0.0, "{end:?}");
        assert_eq!(truth.last().unwrap().normal, 0.0);
    }
}

#[test]
fn without_a_surface_within_reach_it_goes_back_up_without_pressing() {
    let Some((out, _)) = run("127.0.0.86", Some(0.20), &plan(), |_| {}) else {
        return;
    };
    assert!(
        matches!(out.ending, ContactEnding::NoContact { .. }),
        "{:?}: {} ({:?})",
        out.ending,
        out.report.ending.sentence(),
        out.report.timing
    );
    assert!(
        out.ending
            .sentence()
            .starts_with("no contact within the approach distance (150 mm searched)"),
        "{}",
        out.ending.sentence()
    );
    assert!(out.report.ending.complete());
    assert!(
        out.ticks
            .iter()
            .all(|k| k.stage != Stage::Press && k.desired == 0.0)
    );
    let last = out.ticks.last().unwrap();
    assert!(
        last.tool[2] > 0.47 - 0.15 + 0.04,
        "ended at z = {}",
        last.tool[2]
    );
}

#[test]
fn a_force_above_the_ceiling_drops_it_and_retreats() {
    // 8 s in (pressing), something pushes the hand up with 45 N: above the 30 N ceiling.
    let Some((out, _)) = run("127.0.0.87", Some(0.40), &plan(), |sim| {
        std::thread::sleep(std::time::Duration::from_secs(8));
        sim.send("push 0 0 45");
        std::thread::sleep(std::time::Duration::from_millis(300));
        sim.send("release");
    }) else {
        return;
    };
    let ContactEnding::Ceiling { force, t } = out.ending else {
        panic!(
            "{:?}: {} ({:?})",
            out.ending,
            out.report.ending.sentence(),
            out.report.timing
        );
    };
    assert!(force > 30.0);
    // From that tick on no force is asked for, and the tool retreats from the table.
    assert!(
        out.ticks
            .iter()
            .filter(|k| k.t > t)
            .all(|k| k.desired == 0.0)
    );
    assert!(
        out.ticks.last().unwrap().tool[2] > 0.43,
        "{:?}",
        out.ticks.last()
    );
    assert!(
        out.report.ending.complete(),
        "{}",
        out.report.ending.sentence()
    );
}

#[test]
fn the_simulator_killed_while_pressing_ends_lost_with_every_tick_kept() {
    let Some((out, _)) = run("127.0.0.88", Some(0.40), &plan(), |sim| {
        // Killed once it has pressed on the table for half a second of simulated time
        // (MuJoCo's own contact force, however slowly a loaded machine runs the simulator).
        let start = std::time::Instant::now();
        while start.elapsed() < std::time::Duration::from_secs(120) {
            std::thread::sleep(std::time::Duration::from_millis(250));
            if sim.truth().iter().filter(|t| t.normal > 5.0).count() > 500 {
                break;
            }
        }
        sim.kill();
    }) else {
        return;
    };
    assert!(
        matches!(out.report.ending, MotionEnd::Lost(_)),
        "{}",
        out.report.ending.sentence()
    );
    assert_eq!(out.ending, ContactEnding::Interrupted);
    assert!(out.ticks.iter().any(|k| k.stage == Stage::Press));
    // Every command sent is in the recording, with the controller's tick for the same
    // state; the controller's ticks without one are answers withheld as late and the one
    // the dead simulator did not take.
    let mut computed = out.ticks.iter().map(|k| k.id);
    assert!(
        out.report
            .samples
            .iter()
            .all(|s| computed.any(|id| id == s.id)),
        "a command sent without its tick"
    );
    let unsent = out.ticks.len() - out.report.samples.len();
    let withheld = out.report.timing.withheld as usize;
    assert!(
        unsent <= withheld + 1,
        "{unsent} ticks unsent, {withheld} withheld"
    );
}
