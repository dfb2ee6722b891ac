//! The guard on the in-process robot: plans refused, slowed and approached as the policy
//! says, in the words every robot uses; a joint that starts outside its range may move
//! back; a movement generated online is checked on its nominal plan first.

use cps_kinematics::Quantity;
use cps_kinematics::robots::{FR3_DQ_MAX, PandaTool, fr3, fr3_limits};
use cps_robot::{
    APPROACH_SHARE, Guarded, KinematicRobot, Limit, MAX_SLOWING, OnBreach, OnStart, Plan, Policy,
    Refusal, Robot, RobotError, RobotModel, StopToken,
};

const HOME: [f64; 7] = cps_kinematics::robots::PANDA_READY;

fn fr3_model() -> RobotModel {
    let mut m = RobotModel::of_chain("fr3", fr3(PandaTool::HandTcp));
    m.limits = fr3_limits();
    m
}

fn robot(policy: Policy, dt: f64) -> Guarded<KinematicRobot> {
    Guarded::new(
        KinematicRobot::of_model(fr3_model(), &HOME, dt).unwrap(),
        policy,
    )
}

/// Joint `j` swings by `amplitude` and back to rest in `seconds`, points every `dt`.
fn swing(j: usize, amplitude: f64, seconds: f64, dt: f64) -> Plan {
    let n = (seconds / dt).round() as usize;
    let points = (0..=n)
        .map(|k| {
            let s = 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / n as f64).cos();
            let mut q = HOME.to_vec();
            q[j] += amplitude * s;
            q
        })
        .collect();
    Plan::new(dt, points).unwrap()
}

#[test]
fn a_step_is_refused_in_words_before_anything_moves() {
    // A 0.05 rad step of joint 2 at t = 1 s, commanded every millisecond: 50 rad/s.
    let points: Vec<Vec<f64>> = (0..=2000)
        .map(|k| {
            let mut q = HOME.to_vec();
            if k >= 1000 {
                q[1] += 0.05;
            }
            q
        })
        .collect();
    let plan = Plan::new(1e-3, points).unwrap();
    let mut r = robot(Policy::STRICT, 1e-3);
    let e = r.run(&plan, &StopToken::new()).unwrap_err();
    let RobotError::Refused {
        reason: Refusal::Limit(b),
        ..
    } = &e
    else {
        panic!("{e}")
    };
    assert_eq!(
        b.limit,
        Limit::Joint {
            joint: 2,
            quantity: Quantity::Velocity
        }
    );
    assert_eq!(
        b.to_string(),
        "joint 2 at t = 1.000 s (command 1000): velocity 50.000000 rad/s beyond the limit 2.620000 rad/s"
    );
    assert_eq!(
        e.to_string(),
        format!("the in-process robot: refused before sending anything: {b}")
    );
    // Nothing moved.
    assert_eq!(r.joint_positions().unwrap(), HOME.to_vec());
}

#[test]
fn a_plan_too_fast_is_slowed_as_little_as_the_limits_need() {
    // Joint 1 by 1.5 rad and back in 1 s: its peak speed π·1.5 = 4.71 rad/s is 1.8 times
    // the FR3's 2.62; its acceleration 2π²·1.5 = 29.6 rad/s² three times its 10.
    let plan = swing(0, 1.5, 1.0, 0.01);
    let mut strict = robot(Policy::STRICT, 0.01);
    assert!(matches!(
        strict.run(&plan, &StopToken::new()),
        Err(RobotError::Refused {
            reason: Refusal::Limit(_),
            ..
        })
    ));
    let mut r = robot(Policy::EXPERIMENT, 0.01);
    let run = r.run(&plan, &StopToken::new()).unwrap();
    assert!(run.ending.complete());
    // At least √(29.6/10) = 1.72 times slower, and not much more.
    assert!(
        run.slowing >= 1.72 && run.slowing < 2.2,
        "slowed {}",
        run.slowing
    );
    assert_eq!(r.slowest(), run.slowing);
    // Every point reached at its slowed time, the whole movement within every limit.
    assert_eq!(run.len(), plan.points().len());
    let last = run.len() - 1;
    assert!((run.time[last] - plan.duration() * run.slowing).abs() < 0.011);
    let usage = r.last_verdict().unwrap().peak_joint_usage();
    assert!(usage.iter().all(|&u| u <= 100.0), "{usage:?}");
    assert!(r.report().unwrap().contains("slowed up to"));
    // Ten times faster than that cannot be slowed enough within 10x.
    let mut r = robot(Policy::EXPERIMENT, 0.01);
    match r.run(&swing(0, 1.5, 0.05, 0.001), &StopToken::new()) {
        Err(RobotError::Refused {
            reason: Refusal::EvenSlowed { max, .. },
            ..
        }) => assert_eq!(max, MAX_SLOWING),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_plan_that_starts_elsewhere_is_refused_or_approached() {
    let mut far = swing(1, 0.1, 2.0, 0.01);
    let shifted: Vec<Vec<f64>> = far
        .points()
        .iter()
        .map(|q| {
            let mut q = q.clone();
            q[1] += 0.3;
            q
        })
        .collect();
    far = Plan::new(0.01, shifted).unwrap();
    let mut r = robot(Policy::STRICT, 0.01);
    let e = r.run(&far, &StopToken::new()).unwrap_err().to_string();
    assert!(
        e.contains("the plan starts 0.3000 rad from where the robot stands at joint 2"),
        "{e}"
    );
    let policy = Policy {
        on_breach: OnBreach::Refuse,
        on_start: OnStart::Approach,
    };
    let mut r = robot(policy, 0.01);
    let run = r.run(&far, &StopToken::new()).unwrap();
    // The approach: a septic profile at 20 % of the limits; for 0.3 rad on joint 2 its
    // duration is set by the speed (2.1875·0.3 / (0.2·2.62) = 1.25 s).
    let expected = 2.1875 * 0.3 / (APPROACH_SHARE * FR3_DQ_MAX[1]);
    assert!(
        (run.approach_s - expected).abs() < 0.011,
        "approach {} s, expected {expected}",
        run.approach_s
    );
    // The run's entries are the plan's own, from its start.
    assert_eq!(run.len(), far.points().len());
    assert!(run.time[0].abs() < 1e-12);
    assert!((run.q[0][1] - far.start()[1]).abs() < 1e-12);
    assert!((run.q[run.len() - 1][1] - far.end()[1]).abs() < 1e-12);
}

#[test]
fn a_joint_outside_its_range_may_move_back_but_not_further_out() {
    // The thesis's start has joint 4 at 0, above the Panda's (and the FR3's) upper bound.
    let mut start = HOME.to_vec();
    start[3] = 0.0;
    let mk = |to: f64| {
        let points = (0..=100)
            .map(|k| {
                let s = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 100.0).cos();
                let mut q = start.clone();
                q[3] = to * s;
                q
            })
            .collect();
        Plan::new(0.01, points).unwrap()
    };
    let mut r = Guarded::new(
        KinematicRobot::of_model(fr3_model(), &start, 0.01).unwrap(),
        Policy::STRICT,
    );
    assert!(r.run(&mk(-0.2), &StopToken::new()).is_ok());
    r.move_to(&start, &StopToken::new()).unwrap();
    let e = r.run(&mk(0.05), &StopToken::new()).unwrap_err().to_string();
    assert!(
        e.contains("joint 4 at t =") && e.contains("position"),
        "{e}"
    );
}

#[test]
fn a_movement_generated_online_is_checked_on_its_nominal_plan_then_streamed() {
    // Joint 7 swung online along its nominal plan, one command per step, slowed (phase
    // stopping's way) to 0.9 of the plan's pace: within every limit, streamed whole.
    let mut r = robot(Policy::STRICT, 0.01);
    let nominal = swing(6, 0.15, 2.0, 0.01);
    let points = nominal.points().to_vec();
    let mut k = 0;
    let mut next = |_measured: &cps_robot::Measured<'_>, _t: f64, out: &mut [f64]| {
        k += 1;
        let s = (k as f64 * 0.9).min(200.0);
        let (i, f) = (s.floor() as usize, s.fract());
        let b = &points[(i + 1).min(200)];
        for j in 0..7 {
            out[j] = points[i][j] + f * (b[j] - points[i][j]);
        }
        s >= 200.0
    };
    let run = r
        .stream(&nominal, &mut next, 1000, &StopToken::new())
        .unwrap();
    assert!(run.ending.complete(), "{:?}", run.ending);
    assert_eq!(run.len(), 224);
    assert!((run.q[223][6] - HOME[6]).abs() < 1e-9);
    // The sweep: an online movement that leaves its nominal plan was held to the
    // collisions only. Joint 7 towards +0.3 rad by a first-order lag jumps to 1.5 rad/s
    // from rest: the first command breaks the acceleration limit, is not sent, and the
    // robot stops where it stood.
    let mut target = HOME[6];
    let mut lag = |_measured: &cps_robot::Measured<'_>, _t: f64, out: &mut [f64]| {
        target += (HOME[6] + 0.3 - target) * 0.05;
        out.copy_from_slice(&HOME);
        out[6] = target;
        false
    };
    let run = r
        .stream(&nominal, &mut lag, 1000, &StopToken::new())
        .unwrap();
    let cps_robot::Ending::Failed(why) = &run.ending else {
        panic!("{:?}", run.ending);
    };
    assert!(
        why.contains("broke a limit, so it was not sent") && why.contains("joint 7"),
        "{why}"
    );
    assert!(
        run.q.iter().all(|q| q[6] == HOME[6]),
        "nothing of it was sent"
    );
    // A nominal movement that breaks a limit is refused before anything is sent.
    let mut never =
        |_: &cps_robot::Measured<'_>, _: f64, _: &mut [f64]| -> bool { panic!("nothing is sent") };
    let e = r
        .stream(
            &swing(6, 3.0, 0.2, 0.01),
            &mut never,
            1000,
            &StopToken::new(),
        )
        .unwrap_err();
    assert!(matches!(e, RobotError::Refused { .. }), "{e}");
    // No way around that check: the guarded robot hands out no streaming interface (it
    // handed out the inner robot's, which streamed whatever it was given).
    assert!(Robot::streaming(&mut r).is_none());
}

#[test]
fn a_stop_ends_a_run_where_it_is_with_the_recording_kept() {
    let stop = StopToken::new();
    let mut r = robot(Policy::STRICT, 0.01);
    let plan = swing(0, 0.2, 2.0, 0.01);
    stop.stop();
    let run = r.run(&plan, &stop).unwrap();
    assert_eq!(run.ending, cps_robot::Ending::Stopped);
    assert_eq!(run.len(), 1, "only where it stood");
}

/// A guarded robot's stepped interface is the guard's own: each joint command is judged
/// as a plan's commands are (a command clamped to a limit is at it, not beyond), and one
/// that breaks a limit is refused and not sent (the
/// inner robot's interface was handed out, and the closed-loop executor's commands went
/// unchecked beyond speed and range).
#[test]
fn stepping_a_guarded_robot_judges_every_command() {
    let swing = swing(0, 0.2, 2.0, 0.01);
    // The plan's points, commanded one step at a time: every one accepted.
    let mut r = robot(Policy::STRICT, 0.01);
    {
        let stepped = Robot::stepped(&mut r).expect("the in-process robot steps");
        for q in &swing.points()[1..] {
            stepped.command_joint_positions(q).unwrap();
            stepped.step().unwrap();
        }
        let end = stepped.joint_positions().unwrap();
        assert!((end[0] - HOME[0]).abs() < 1e-9, "{end:?}");
    }
    // A jump: its acceleration (0.01 rad in one step from rest: 100 rad/s²) is refused in
    // the words a plan's is, and the robot does not move.
    let mut r = robot(Policy::STRICT, 0.01);
    let stepped = Robot::stepped(&mut r).unwrap();
    let mut jump = HOME.to_vec();
    jump[0] += 0.01;
    let e = stepped
        .command_joint_positions(&jump)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not sent") && e.contains("joint 1 at t = 0.010 s (command 1): acceleration"),
        "{e}"
    );
    stepped.step().unwrap();
    assert_eq!(stepped.joint_positions().unwrap(), HOME.to_vec());
    // Stopping dead from speed is refused too: a step without a new command holds the
    // last one.
    let mut r = robot(Policy::STRICT, 0.01);
    let stepped = Robot::stepped(&mut r).unwrap();
    let mut moving = false;
    for q in &swing.points()[1..60] {
        stepped.command_joint_positions(q).unwrap();
        stepped.step().unwrap();
        moving = true;
    }
    assert!(moving);
    let e = stepped.step().unwrap_err().to_string();
    assert!(e.contains("not sent") && e.contains("acceleration"), "{e}");
    // A command that is not a number is refused in words (the guard's own differences
    // of it compared as false with every limit, and passed).
    let mut r = robot(Policy::STRICT, 0.01);
    let stepped = Robot::stepped(&mut r).unwrap();
    let mut nan = HOME.to_vec();
    nan[2] = f64::NAN;
    let e = stepped
        .command_joint_positions(&nan)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not sent") && e.contains("joint 3") && e.contains("is not a number"),
        "{e}"
    );
    stepped.step().unwrap();
    assert_eq!(stepped.joint_positions().unwrap(), HOME.to_vec());
}
