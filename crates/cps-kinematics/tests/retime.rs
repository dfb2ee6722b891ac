//! Retiming against closed forms: time-optimal rest-to-rest motions along a straight line
//! in joint space (trapezoid and S-curve), limits between the commands, infeasibility.

use cps_kinematics::robots::{PandaTool, panda, panda_inertia, panda_limits};
use cps_kinematics::{
    GRAVITY, JointLimits, KinematicsError, LinkInertia, Quantity, RetimeOptions, RobotLimits,
    SerialChain, retime, retime::uniform,
};
use nalgebra::Vector3;

/// A straight joint-space segment from `a` to `b`, sampled at `n` points (its spline is
/// the straight line, traversed as 3σ² − 2σ³).
fn segment(a: &[f64], b: &[f64], n: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
    let t: Vec<f64> = (0..n).map(|k| k as f64 / (n - 1) as f64).collect();
    let q = t
        .iter()
        .map(|s| {
            let sigma = 3.0 * s * s - 2.0 * s * s * s;
            a.iter().zip(b).map(|(x, y)| x + (y - x) * sigma).collect()
        })
        .collect();
    (t, q)
}

/// The robot `arm` with `limits` (and torques with `inertia`), without Cartesian limits.
fn limited<'a>(
    arm: &'a SerialChain,
    limits: &'a JointLimits,
    inertia: Option<&'a [LinkInertia]>,
) -> RobotLimits<'a> {
    RobotLimits {
        chain: arm,
        limits,
        inertia,
        gravity: Vector3::from(GRAVITY),
        cartesian: None,
    }
}

/// The Panda's velocity and acceleration limits only (and jerk with `jerk`).
fn kinematic_limits(jerk: bool) -> JointLimits {
    let (full, _) = panda_limits();
    JointLimits {
        acceleration: full.acceleration,
        jerk: if jerk { full.jerk } else { None },
        torque: None,
        torque_rate: None,
    }
}

/// Rest-to-rest optimum along a line of joint displacements `d`: (vel/acc-only duration,
/// S-curve duration), from the tightest joint's path-speed, -acceleration and -jerk bounds.
fn closed_form(d: &[f64], v: &[f64], a: &[f64], j: &[f64]) -> (f64, f64) {
    let min = |lim: &[f64]| {
        lim.iter()
            .zip(d)
            .map(|(l, x)| l / x.abs())
            .fold(f64::INFINITY, f64::min)
    };
    let (vv, aa, jj) = (min(v), min(a), min(j));
    assert!(
        vv * vv / aa <= 1.0 && aa / jj <= vv / aa,
        "cruise phase expected"
    );
    (1.0 / vv + vv / aa, 1.0 / vv + vv / aa + aa / jj)
}

#[test]
fn a_straight_line_is_the_trapezoid_and_with_jerk_the_s_curve() {
    let arm = panda(PandaTool::Flange);
    let a = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7];
    let b = [1.5, 0.3, -0.8, -1.2, 0.6, 2.4, -0.5];
    let d: Vec<f64> = a.iter().zip(&b).map(|(x, y)| y - x).collect();
    let (path_t, path_q) = segment(&a, &b, 200);
    let (full, _) = panda_limits();
    let (vel, acc, jerk) = (
        arm.velocity_limits().unwrap(),
        full.acceleration.as_ref().unwrap(),
        full.jerk.as_ref().unwrap(),
    );
    let (trapezoid, s_curve) = closed_form(&d, vel, acc, jerk);
    for (with_jerk, expected) in [(false, trapezoid), (true, s_curve)] {
        let limits = kinematic_limits(with_jerk);
        let robot = limited(&arm, &limits, None);
        let r = retime(&robot, &path_t, &path_q, &RetimeOptions::default()).unwrap();
        assert!(r.check.ok(), "{:?}", r.check.joints.violations);
        // Within a control period and the grid's discretisation of the optimum, never below.
        assert!(
            r.duration >= expected - 1e-3 && r.duration <= expected * 1.002,
            "jerk {with_jerk}: {} s vs closed form {expected} s",
            r.duration
        );
        // Ten times finer than the commands, the exact derivatives keep the limits.
        for k in 0..=(r.duration * 10_000.0) as usize {
            let [q, v, a, j] = r.at(k as f64 * 1e-4);
            assert!(arm.within_limits(&q));
            for i in 0..7 {
                assert!(v[i].abs() <= vel[i] * (1.0 + 1e-9), "v{i} {}", v[i]);
                assert!(a[i].abs() <= acc[i] * (1.0 + 1e-9), "a{i} {}", a[i]);
                if with_jerk {
                    assert!(j[i].abs() <= jerk[i] * (1.0 + 1e-9), "j{i} {}", j[i]);
                }
            }
        }
        // Starts and ends at rest, at the path's ends.
        let [q0, v0, ..] = r.at(0.0);
        let [q1, v1, ..] = r.at(r.duration);
        for i in 0..7 {
            assert!((q0[i] - a[i]).abs() < 1e-12 && (q1[i] - b[i]).abs() < 1e-12);
            assert!(v0[i].abs() < 1e-9 && v1[i].abs() < 1e-9);
        }
        assert_eq!(r.q.len(), (r.duration * 1000.0 - 1e-6).ceil() as usize + 1);
    }
}

#[test]
fn torque_limits_slow_the_motion_and_hold() {
    let arm = panda(PandaTool::Flange);
    let (limits, _) = panda_limits();
    let inertia = panda_inertia();
    let robot = limited(&arm, &limits, Some(&inertia));
    let (t, q) = segment(
        &[0.0, -0.5, 0.0, -2.2, 0.0, 1.8, 0.8],
        &[0.4, 0.9, 0.3, -0.6, 0.2, 1.9, 0.8],
        300,
    );
    let r = retime(&robot, &t, &q, &RetimeOptions::default()).unwrap();
    assert!(r.check.ok(), "{:?}", r.check.joints.violations);
    let peak = |k: Quantity| {
        r.check
            .joints
            .peak_usage
            .iter()
            .find(|(q, _)| *q == k)
            .map(|(_, u)| u.iter().copied().fold(0.0, f64::max))
            .unwrap()
    };
    // Time-optimal: some limit is (nearly) reached.
    let top = Quantity::ALL
        .iter()
        .skip(1)
        .map(|k| peak(*k))
        .fold(0.0, f64::max);
    assert!(top > 90.0 && top <= 100.0, "highest usage {top}");
}

#[test]
fn a_path_held_against_gravity_beyond_the_torque_limit_is_named() {
    let arm = panda(PandaTool::Flange);
    let (mut limits, _) = panda_limits();
    limits.torque.as_mut().unwrap()[1] = 5.0;
    let inertia = panda_inertia();
    let robot = limited(&arm, &limits, Some(&inertia));
    let (t, q) = segment(
        &[0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0],
        &[0.0, 0.8, 0.0, -1.5, 0.0, 1.5, 0.0],
        50,
    );
    let e = retime(&robot, &t, &q, &RetimeOptions::default()).unwrap_err();
    assert!(matches!(e, KinematicsError::Infeasible { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("joint 2 needs") && msg.contains("against gravity"),
        "{msg}"
    );
    let e = uniform(&robot, &t, &q, 1000.0).unwrap_err();
    assert!(e.to_string().contains("joint 2 torque"), "{e}");
}

#[test]
fn uniform_slowing_finds_the_smallest_stretch() {
    let arm = panda(PandaTool::Flange);
    let limits = kinematic_limits(true);
    let robot = limited(&arm, &limits, None);
    // A 0.2 s move of 1 rad on joint 1 is far too fast; 5 s is slow enough. The move is
    // the quintic 10σ³ − 15σ⁴ + 6σ⁵ (at rest, without acceleration, at both ends).
    let (t, q): (Vec<f64>, Vec<Vec<f64>>) = (0..2001)
        .map(|k| {
            let s = k as f64 / 2000.0;
            let sigma = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
            (s, vec![sigma, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0])
        })
        .unzip();
    for span in [0.2, 5.0] {
        let t: Vec<f64> = t.iter().map(|x| x * span).collect();
        let r = uniform(&robot, &t, &q, 1000.0).unwrap();
        assert!(r.check.ok());
        // Over T: peak speed 1.875/T, acceleration 5.7735/T², jerk 60/T³: the binding
        // limit (here the speed) decides T.
        let needed = (1.875 / 2.175_f64)
            .max((10.0 / 3.0_f64.sqrt() / 15.0).sqrt())
            .max((60.0 / 7500.0_f64).cbrt());
        assert!(
            (r.duration - needed).abs() < 0.01 * needed,
            "span {span}: {} s vs {needed} s",
            r.duration
        );
        assert!((r.factor * span - r.duration).abs() < 1e-9);
    }
}

/// Cartesian jerk limits on a robot without joint jerk limits: the first rounds find the
/// tool's jerk over its limit and smoothing starts (it once stayed at zero width, and the
/// retiming gave up after its 40 rounds).
#[test]
fn cartesian_jerk_limits_alone_start_the_smoothing() {
    let arm = panda(PandaTool::HandTcp);
    let (_, cartesian) = panda_limits();
    let limits = kinematic_limits(false);
    let robot = RobotLimits {
        cartesian: Some(&cartesian),
        ..limited(&arm, &limits, None)
    };
    let a = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7];
    let b = [1.2, 0.2, -0.6, -1.4, 0.5, 2.2, -0.3];
    let (t, q) = segment(&a, &b, 50);
    let r = retime(&robot, &t, &q, &RetimeOptions::default()).unwrap();
    assert!(r.smoothing > 0.0, "no smoothing: {}", r.smoothing);
    let c = r.check.cartesian.as_ref().unwrap();
    for (name, usage) in &c.peak_usage {
        assert!(*usage <= 100.0 + 1e-6, "{name} at {usage} %");
    }
    assert!(c.violations.is_empty() && r.check.joints.violations.is_empty());
}
