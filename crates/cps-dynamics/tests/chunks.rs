//! A policy stand-in's chunks followed on the FR3 with dynamics (franky-sim's PD and
//! drives): every command within the limits, no reflex, the arm close to the
//! demonstration — where naive execution of the same chunks (each a new trajectory from
//! its first point, linearly interpolated) breaks the velocity and jerk limits many times
//! over.

use cps_chunks::{Chunk, FollowReport, FollowSettings, Replay, StandIn, follow, replay_plan};
use cps_dynamics::DynamicsOptions;
use cps_kinematics::robots::{PANDA_READY, PandaTool, fr3, fr3_inertia, fr3_limits};
use cps_robot::{Guarded, Policy, Robot, RobotModel, StopToken};

const DT: f64 = 1e-3;

fn model() -> RobotModel {
    let mut m = RobotModel::of_chain("fr3", fr3(PandaTool::HandTcp));
    m.limits = fr3_limits();
    m.inertia = Some(fr3_inertia());
    m
}

/// The demonstration: every joint swings about the ready pose at 0.25 Hz, from rest.
fn demo(t: f64) -> Vec<f64> {
    let s = 0.5 - 0.5 * (std::f64::consts::FRAC_PI_2 * t.max(0.0)).cos();
    PANDA_READY
        .iter()
        .enumerate()
        .map(|(j, q)| q + 0.3 * s * if j % 2 == 0 { 1.0 } else { -0.5 })
        .collect()
}

/// Naive execution: from its arrival, each chunk's targets in order from its first,
/// linearly interpolated every millisecond; the commands for `n` periods from `q0`.
fn naive(chunks: &[Chunk], q0: &[f64], n: usize) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(n);
    let mut current: Option<&Chunk> = None;
    let mut next = 0;
    for k in 1..=n {
        let t = k as f64 * DT;
        while next < chunks.len() && chunks[next].arrived_s <= t {
            current = Some(&chunks[next]);
            next += 1;
        }
        out.push(match current {
            None => q0.to_vec(),
            Some(c) => {
                let s = ((t - c.arrived_s) * c.rate_hz).min((c.targets.len() - 1) as f64);
                let (i, u) = (s.floor() as usize, s.fract());
                let j = (i + 1).min(c.targets.len() - 1);
                (0..q0.len())
                    .map(|d| c.targets[i][d] * (1.0 - u) + c.targets[j][d] * u)
                    .collect()
            }
        });
    }
    out
}

/// Largest |velocity| and |jerk| of commands from rest at `q0`, as shares of the limits.
fn peak_shares(commands: &[Vec<f64>], q0: &[f64]) -> (f64, f64) {
    let m = model();
    let (vmax, jmax) = (
        m.chain.velocity_limits().unwrap().to_vec(),
        fr3_limits().jerk.unwrap(),
    );
    let (mut pv, mut pj) = (0.0_f64, 0.0_f64);
    for j in 0..q0.len() {
        let (mut prev, mut v0, mut a0) = (q0[j], 0.0, 0.0);
        for c in commands {
            let v = (c[j] - prev) / DT;
            let a = (v - v0) / DT;
            pv = pv.max(v.abs() / vmax[j]);
            pj = pj.max(((a - a0) / DT).abs() / jmax[j]);
            (prev, v0, a0) = (c[j], v, a);
        }
    }
    (pv, pj)
}

#[test]
fn chunks_at_10_and_30_hz_are_followed_on_the_dynamics_robot_without_a_reflex() {
    for hz in [10.0, 30.0] {
        let chunks = StandIn {
            horizon: 50,
            target_hz: 50.0,
            chunk_hz: hz,
            delay_s: (0.05, 0.15),
            noise_rad: 0.002,
            seed: 5,
        }
        .chunks(&demo, 0.0, 6.0);
        let robot = cps_dynamics::open(model(), &PANDA_READY, &DynamicsOptions::default()).unwrap();
        let mut robot = Guarded::new(robot, Policy::STRICT);
        let settings = FollowSettings::default();
        let plan = replay_plan(robot.model(), &PANDA_READY, DT, &chunks, &settings).unwrap();
        let mut source = Replay::new(chunks.clone());
        let run = follow(
            &mut robot,
            &mut source,
            Some(&plan),
            &settings,
            &StopToken::new(),
        )
        .unwrap();
        assert!(run.run.ending.complete(), "{hz} Hz: {:?}", run.run.ending);
        let report = FollowReport::new(&run, &source.into_log());
        eprintln!("{hz} Hz:\n  {}", report.lines().join("\n  "));
        assert!(
            report.usage.iter().all(|u| *u <= 1.0 + 1e-6),
            "{:?}",
            report.usage
        );
        // The arm itself, after the first second, as close to the demonstration as the
        // arm driven by the demonstration itself (its controller's own lag) within 5 mrad.
        let worst = |run: &cps_robot::Run| {
            (1000..6000)
                .map(|k| {
                    let d = demo(run.time[k]);
                    (0..7)
                        .map(|j| (run.q[k][j] - d[j]).abs())
                        .fold(0.0, f64::max)
                })
                .fold(0.0, f64::max)
        };
        let mut by_itself = Guarded::new(
            cps_dynamics::open(model(), &PANDA_READY, &DynamicsOptions::default()).unwrap(),
            Policy::STRICT,
        );
        let demo_plan =
            cps_robot::Plan::new(DT, (0..=6000).map(|k| demo(k as f64 * DT)).collect()).unwrap();
        let itself = worst(&by_itself.run(&demo_plan, &StopToken::new()).unwrap());
        let followed = worst(&run.run);
        eprintln!(
            "  the arm within {:.2} mrad of the demonstration (driven by the demonstration itself: {:.2} mrad)",
            1e3 * followed,
            1e3 * itself
        );
        assert!(
            followed < itself + 0.005,
            "{hz} Hz: {followed} rad from the demonstration"
        );
        // Naive execution of the same chunks breaks the limits many times over.
        let (v, j) = peak_shares(&naive(&chunks, &PANDA_READY, 6000), &PANDA_READY);
        let (cv, cj) = peak_shares(&run.commands, &PANDA_READY);
        eprintln!(
            "  naive: {v:.1}× the velocity and {j:.0}× the jerk limit; cps {cv:.2}× and {cj:.2}×"
        );
        assert!(v > 2.0 && j > 100.0, "naive {v} {j}");
        assert!(cv <= 1.0 && cj <= 1.0 + 1e-6);
    }
}
