//! Action chunks followed on the in-process FR3 at 1 kHz behind the guard: a recorded
//! stand-in stream replayed (checked whole first), a live feed with bad chunks among good
//! ones, a stall, a stop — every command within the limits the executor keeps, the log
//! and the report true to what happened.

use cps_chunks::{
    Chunk, ChunkVerdict, FollowReport, FollowSettings, Followed, Replay, StandIn, follow, live,
    replay_plan,
};
use cps_kinematics::robots::{PANDA_READY, PandaTool, fr3, fr3_limits};
use cps_robot::{Guarded, KinematicRobot, Policy, Robot, RobotModel, StopToken};

const DT: f64 = 1e-3;

fn model() -> RobotModel {
    let mut m = RobotModel::of_chain("fr3", fr3(PandaTool::HandTcp));
    m.limits = fr3_limits();
    m
}

fn robot() -> Guarded<KinematicRobot> {
    Guarded::new(
        KinematicRobot::of_model(model(), &PANDA_READY, DT).unwrap(),
        Policy::STRICT,
    )
}

/// The demonstration: every joint swings about the ready pose, 0.25 Hz, from rest.
fn demo(t: f64) -> Vec<f64> {
    let s = 0.5 - 0.5 * (std::f64::consts::FRAC_PI_2 * t.max(0.0)).cos();
    PANDA_READY
        .iter()
        .enumerate()
        .map(|(j, q)| q + 0.3 * s * if j % 2 == 0 { 1.0 } else { -0.5 })
        .collect()
}

/// Backward differences of the commands (from the start at rest) within the limits the
/// run kept, at every millisecond.
fn within_limits(run: &Followed) {
    let q0 = &run.run.q[0];
    for (j, l) in run.limits.iter().enumerate() {
        let (mut prev, mut v0, mut a0) = (q0[j], 0.0, 0.0);
        for (k, c) in run.commands.iter().enumerate() {
            let v = (c[j] - prev) / DT;
            let a = (v - v0) / DT;
            let jk = (a - a0) / DT;
            let tol = 1.0 + 1e-6;
            assert!(
                v.abs() <= l.velocity * tol
                    && a.abs() <= l.acceleration * tol
                    && jk.abs() <= l.jerk * tol,
                "joint {} command {k}: v {v} a {a} j {jk}",
                j + 1
            );
            (prev, v0, a0) = (c[j], v, a);
        }
    }
}

#[test]
fn a_delayed_noisy_stream_is_followed_on_the_robot_within_every_limit() {
    for hz in [10.0, 30.0] {
        let stand_in = StandIn {
            horizon: 50,
            target_hz: 50.0,
            chunk_hz: hz,
            delay_s: (0.05, 0.15),
            noise_rad: 0.002,
            seed: 11,
        };
        let chunks = stand_in.chunks(&demo, 0.0, 6.0);
        let settings = FollowSettings::default();
        let mut r = robot();
        let plan = replay_plan(r.model(), &PANDA_READY, DT, &chunks, &settings).unwrap();
        let mut source = Replay::new(chunks.clone());
        let run = follow(
            &mut r,
            &mut source,
            Some(&plan),
            &settings,
            &StopToken::new(),
        )
        .unwrap();
        assert!(run.run.ending.complete(), "{:?}", run.run.ending);
        // The robot was sent exactly the plan the guard checked.
        assert_eq!(run.commands.len() + 1, plan.points().len());
        for (c, p) in run.commands.iter().zip(&plan.points()[1..]) {
            assert_eq!(c, p);
        }
        within_limits(&run);
        let log = source.into_log();
        assert_eq!(
            log.entries.len(),
            chunks.len(),
            "every chunk back in the log"
        );
        assert!(
            log.entries
                .iter()
                .all(|(_, v)| matches!(v, Some(ChunkVerdict::Taken { .. })))
        );
        let report = FollowReport::new(&run, &log);
        eprintln!("{hz} Hz:\n  {}", report.lines().join("\n  "));
        assert_eq!((report.taken, report.refused), (chunks.len(), 0));
        assert!(report.skipped > 0, "delayed chunks start in the past");
        assert!(
            report.usage.iter().all(|u| *u <= 1.0 + 1e-6),
            "{:?}",
            report.usage
        );
        assert!(
            (0.05..=0.15).contains(&report.delay.min) && report.delay.max <= 0.15,
            "{:?}",
            report.delay
        );
        // After the first second the commands are within 10 mrad of the demonstration.
        let worst = (1000..6000)
            .map(|k| {
                let d = demo((k + 1) as f64 * DT);
                (0..7)
                    .map(|j| (run.commands[k][j] - d[j]).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        assert!(worst < 0.01, "{hz} Hz: {worst} rad from the demonstration");
        // The stream is over: its last chunk is followed to its end, the arm comes to
        // rest, the run ends (no stall: the stream ended, it did not stop coming).
        assert!(report.stalls.is_empty(), "{:?}", report.stalls);
        let end = demo(chunks.last().unwrap().time_of(49));
        let last = run.commands.last().unwrap();
        assert!(
            (0..7).all(|j| (last[j] - end[j]).abs() < 0.005),
            "{last:?} vs {end:?}"
        );
        assert_eq!(&run.commands[run.commands.len() - 2], last, "at rest");
    }
}

#[test]
fn a_live_feed_refuses_bad_chunks_and_brakes_to_rest_when_it_closes() {
    let (mut feed, source) = live(7);
    let here = PANDA_READY.to_vec();
    let moved = |dq: f64| {
        let mut q = here.clone();
        q[0] += dq;
        q
    };
    // A chunk far from the arm, one outside the range, then a good one moving joint 1
    // by 0.1 rad; then the policy closes the stream.
    let far = Chunk::new(0.0, 0.0, 50.0, vec![moved(0.5); 10], None, 7).unwrap();
    let mut out_of_range = vec![here.clone(); 10];
    out_of_range[9][3] = 0.5;
    let range = Chunk::new(0.0, 0.0, 50.0, out_of_range, None, 7).unwrap();
    let good = Chunk::new(
        0.0,
        0.0,
        50.0,
        (0..25).map(|k| moved(0.1 * k as f64 / 24.0)).collect(),
        None,
        7,
    )
    .unwrap();
    for c in [far, range, good] {
        feed.push(c).unwrap();
    }
    feed.close();
    let mut r = robot();
    let mut source = source;
    let run = follow(
        &mut r,
        &mut source,
        None,
        &FollowSettings::default(),
        &StopToken::new(),
    )
    .unwrap();
    assert!(run.run.ending.complete(), "{:?}", run.run.ending);
    within_limits(&run);
    assert!(!feed.running());
    let log = feed.into_log(source);
    let report = FollowReport::new(&run, &log);
    eprintln!("{}", report.lines().join("\n"));
    assert_eq!((report.chunks, report.taken, report.refused), (3, 1, 2));
    assert!(
        report.refusals[0]
            .1
            .starts_with("the chunk wants joint 1 0.500 rad from where the arm is commanded"),
        "{:?}",
        report.refusals
    );
    assert!(
        report.refusals[1]
            .1
            .starts_with("target 9 puts joint 4 at 0.5 rad, outside its range"),
        "{:?}",
        report.refusals
    );
    // The arm moved to the good chunk's end and stands there at rest.
    let end = run.commands.last().unwrap();
    assert!((end[0] - (here[0] + 0.1)).abs() < 1e-3, "{end:?}");
    assert_eq!(&run.commands[run.commands.len() - 2], end);
}

/// The sweep's poisoned streams, replayed: a chunk observed before the one followed
/// (inference servers in parallel), replayed, and a chunk stamped 1 000 s ahead of the
/// robot's clock, live, are each refused while the arm goes on, and every honest chunk
/// after them is taken;
/// chunks after a pause longer than the idle end are said to have never reached the arm.
#[test]
fn stale_and_future_chunks_are_refused_alone_and_a_long_pause_is_said() {
    let stand_in = StandIn {
        horizon: 50,
        target_hz: 50.0,
        chunk_hz: 30.0,
        delay_s: (0.07, 0.13),
        noise_rad: 0.0,
        seed: 5,
    };
    let mut chunks = stand_in.chunks(&demo, 0.0, 3.0);
    let n = chunks.len();
    // Chunk 20 observed before chunk 19 (its server was slower), arriving after it.
    let (o19, a19) = (chunks[19].observed_s, chunks[19].arrived_s);
    chunks[20] = Chunk::new(
        o19 - 0.03,
        a19 + 0.001,
        50.0,
        chunks[20].targets.clone(),
        None,
        7,
    )
    .unwrap();
    let settings = FollowSettings::default();
    let mut r = robot();
    let mut source = Replay::new(chunks.clone());
    let plan = replay_plan(r.model(), &PANDA_READY, DT, &chunks, &settings).unwrap();
    let run = follow(
        &mut r,
        &mut source,
        Some(&plan),
        &settings,
        &StopToken::new(),
    )
    .unwrap();
    assert!(run.run.ending.complete(), "{:?}", run.run.ending);
    within_limits(&run);
    let log = source.into_log();
    let report = FollowReport::new(&run, &log);
    assert_eq!(
        (report.taken, report.refused),
        (n - 1, 1),
        "{:?}",
        report.refusals
    );
    assert_eq!(report.refusals[0].0, 20);
    assert!(
        report.refusals[0].1.contains("observation time"),
        "{:?}",
        report.refusals
    );
    // The future chunk, live: refused, and the honest chunks after it are taken.
    let (mut feed, source) = live(7);
    let here = PANDA_READY.to_vec();
    let hold = |observed: f64| {
        Chunk::new(observed, observed, 50.0, vec![here.clone(); 25], None, 7).unwrap()
    };
    feed.push(hold(1000.0)).unwrap();
    for k in 0..3 {
        feed.push(hold(0.0 + k as f64 * 1e-3)).unwrap();
    }
    feed.close();
    let mut r = robot();
    let mut source = source;
    let run = follow(&mut r, &mut source, None, &settings, &StopToken::new()).unwrap();
    let log = feed.into_log(source);
    let report = FollowReport::new(&run, &log);
    assert_eq!(
        (report.chunks, report.taken, report.refused),
        (4, 3, 1),
        "{:?}",
        report.refusals
    );
    assert!(
        report.refusals[0]
            .1
            .contains("later than the robot's clock now"),
        "{:?}",
        report.refusals
    );
    // A pause longer than the idle end: the chunks after it never reach the arm, and the
    // report says so.
    let short = FollowSettings {
        idle_end_s: 0.5,
        ..FollowSettings::default()
    };
    let mut late = stand_in.chunks(&demo, 0.0, 1.0);
    let k = late.len();
    let mut after = stand_in.chunks(&demo, 0.0, 1.0);
    for c in &mut after {
        *c = Chunk::new(
            c.observed_s + 3.0,
            c.arrived_s + 3.0,
            50.0,
            c.targets.clone(),
            None,
            7,
        )
        .unwrap();
    }
    late.extend(after);
    let mut r = robot();
    let mut source = Replay::new(late.clone());
    let run = follow(&mut r, &mut source, None, &short, &StopToken::new()).unwrap();
    let report = FollowReport::new(&run, &source.into_log());
    let (unplayed, pause) = report.unplayed.expect("the later chunks are counted");
    assert_eq!(unplayed, late.len() - k);
    assert!(pause > 1.5, "{pause}");
    assert!(
        report
            .lines()
            .iter()
            .any(|l| l.contains("never reached the arm"))
    );
    // No chunk at all: the report says so, and no statistic of nothing (NaN) is printed.
    let mut source = Replay::new(Vec::new());
    let run = follow(&mut robot(), &mut source, None, &short, &StopToken::new()).unwrap();
    let lines = FollowReport::new(&run, &source.into_log()).lines();
    assert!(
        lines.iter().any(|l| l.starts_with("no chunk came")),
        "{lines:?}"
    );
    assert!(lines.iter().all(|l| !l.contains("NaN")), "{lines:?}");
}

#[test]
fn a_stop_brakes_a_live_run_and_keeps_what_was_recorded() {
    let (mut feed, source) = live(7);
    // A long chunk joint 1 follows at speed; the stop comes while it moves.
    let chunk = Chunk::new(
        0.0,
        0.0,
        50.0,
        (0..200)
            .map(|k| {
                let mut q = PANDA_READY.to_vec();
                q[0] += 0.01 * k as f64;
                q
            })
            .collect(),
        None,
        7,
    )
    .unwrap();
    feed.push(chunk).unwrap();
    let stop = StopToken::new();
    let mut r = robot();
    let mut source = source.paced();
    // Stop from inside: after 500 periods the state the feed reads says t ≥ 0.5 s.
    let stopper = stop.clone();
    let watcher = std::thread::spawn(move || {
        loop {
            if let Some((t, _)) = feed.state()
                && t >= 0.5
            {
                stopper.stop();
                return (feed, t);
            }
            std::thread::yield_now();
        }
    });
    let run = follow(&mut r, &mut source, None, &FollowSettings::default(), &stop);
    let (feed, t) = watcher.join().unwrap();
    let run = run.unwrap();
    let seen = run.commands.len();
    assert!(t >= 0.5 && seen >= 500, "{t} {seen}");
    assert_eq!(run.run.ending, cps_robot::Ending::Stopped);
    within_limits(&run);
    drop(feed);
}
