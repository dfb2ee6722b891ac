//! The one limit checker, `StreamCheck`: its two ways (refusing a command, measuring a
//! plan) agree, and what it refuses that the guard's earlier copy let through.

use cps_kinematics::robots::{PandaTool, fr3, fr3_limits};
use cps_kinematics::{Held, JointBounds, OUTSIDE_SLACK, Quantity, StreamCheck};
use rand::{Rng, SeedableRng};

/// The two ways of the one checker agree: the command `admit` refuses first is the
/// first sample of the earliest run a plan's check reports, with the same value and
/// bound, on random streams that break a limit somewhere.
#[test]
fn admit_refuses_where_the_plan_check_reports_first() {
    let chain = fr3(PandaTool::HandTcp);
    let limits = fr3_limits();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let dt = 1e-3;
    let (mut refused, mut kinds) = (0, std::collections::BTreeSet::new());
    for case in 0..200 {
        let q0 = cps_kinematics::robots::PANDA_READY.to_vec();
        // A smooth motion with one kick of random size at a random command.
        let (kick_at, joint) = (rng.random_range(1..300), rng.random_range(0..7));
        let kick = 10f64.powf(rng.random_range(-7.0..-1.0));
        let stream: Vec<Vec<f64>> = (0..300)
            .map(|k| {
                let mut q = q0.clone();
                let s = (k as f64 * dt * 2.0).sin().powi(2);
                q[joint] += 0.05 * s + if k >= kick_at { kick } else { 0.0 };
                q
            })
            .collect();
        let batch = cps_kinematics::check_joint_trajectory(
            &chain,
            &limits,
            None,
            cps_kinematics::GRAVITY.into(),
            0.0,
            dt,
            &stream,
        )
        .unwrap();
        let bounds = JointBounds::of(&chain, &limits, &q0);
        let mut check = StreamCheck::at_rest(bounds, stream[0].clone(), dt);
        // The plan's check holds the last command three periods: so does this stream.
        let held = std::iter::repeat_n(&stream[299], 3);
        let first = stream
            .iter()
            .chain(held)
            .try_for_each(|q| check.admit(q))
            .err();
        let earliest = batch.violations.first();
        match (first, earliest) {
            (None, None) => {}
            (Some(e), Some(v)) => {
                refused += 1;
                let Held::Quantity(quantity) = e.judged.held else {
                    panic!("case {case}: a rule without one")
                };
                kinds.insert(quantity);
                // The run's worst sample may come later than its first.
                assert!(e.time <= v.time + 1e-12, "case {case}: {e:?} vs {v:?}");
                let same_time: Vec<_> = batch
                    .violations
                    .iter()
                    .filter(|w| (w.time - v.time).abs() < 1e-12)
                    .collect();
                if (e.time - v.time).abs() < 1e-12 {
                    assert!(
                        same_time.iter().any(|w| w.joint == e.judged.joint
                            && w.quantity == quantity
                            && w.value == e.judged.value
                            && w.limit == e.judged.bound),
                        "case {case}: {e:?} vs {same_time:?}"
                    );
                }
            }
            (a, b) => panic!("case {case}: admit {a:?}, plan check {b:?}"),
        }
    }
    // The kicks reach the acceleration and jerk limits, some the velocity limit too.
    assert!(refused > 100, "{refused}");
    assert!(kinds.contains(&Quantity::Jerk) && kinds.contains(&Quantity::Acceleration));
}

/// A value that is not a number breaks every limit it is held to, and a joint that
/// starts beyond its range may come back but not go further out.
#[test]
fn not_a_number_is_refused_and_a_start_outside_may_only_come_back() {
    let chain = fr3(PandaTool::HandTcp);
    let limits = fr3_limits();
    let q0 = cps_kinematics::robots::PANDA_READY.to_vec();
    let bounds = JointBounds::of(&chain, &limits, &q0);
    let mut check = StreamCheck::at_rest(bounds.clone(), q0.clone(), 1e-3);
    let mut nan = q0.clone();
    nan[4] = f64::NAN;
    let e = check.admit(&nan).unwrap_err();
    assert_eq!(
        (e.judged.joint, e.judged.held, e.command),
        (5, Held::Quantity(Quantity::Position), 0)
    );
    assert_eq!(check.taken(), 0);
    // Joint 4 starts 1 mrad above its upper bound.
    let (_, hi) = chain.limits().unwrap();
    let mut out = q0.clone();
    out[3] = hi[3] + 1e-3;
    let mut check = StreamCheck::at_rest(bounds, out.clone(), 1e-3).numbered_from(1);
    let mut back = out.clone();
    back[3] -= 1e-7;
    check.admit(&back).unwrap();
    let mut further = back.clone();
    further[3] += 2e-4;
    let e = check.admit(&further);
    // Refused, for its position or for how fast it got there, as command 2.
    assert_eq!(e.map_err(|e| e.command), Err(2));
    let mut just = back;
    just[3] = hi[3] + 1e-3 + OUTSIDE_SLACK * 2.0;
    let mut slow = StreamCheck::at_rest(
        JointBounds {
            velocity: vec![f64::INFINITY; 7],
            acceleration: vec![f64::INFINITY; 7],
            jerk: vec![f64::INFINITY; 7],
            ..JointBounds::of(&chain, &limits, &q0)
        },
        out,
        1e-3,
    );
    let e = slow.admit(&just).unwrap_err();
    assert_eq!(
        (e.judged.held, e.judged.bound),
        (Held::Quantity(Quantity::Position), hi[3])
    );
}
