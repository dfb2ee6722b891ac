//! cps-franka against franka-sim 1.1.7 with its reflexes on (the FCI's limits and
//! discontinuities, the communication constraints) on a loaded machine: a CPU hog on
//! every core but one beside it and cps's loop at normal priority, so the robot loses cycles, and the
//! link dropping 2 % of the commands on purpose (seeded), so it surely does. franka-sim
//! extrapolates every lost cycle as a real FR3 does and judges the next command against
//! that. Every motion must end as planned with no reflex, the robot's extrapolated cycles
//! and dropped commands in the report; pylibfranka, the official client, replays a
//! trajectory on the same load beside it as the reference.

// Joint-indexed arrays are read side by side.
#![allow(clippy::needless_range_loop)]

use std::sync::atomic::AtomicBool;

use cps_franka::limits::{Arm, DT, RateLimits};
use cps_franka::reference::Reference;
use cps_franka::rt::start_position;
use cps_franka::{
    Connection, JointVelocities, LoopOptions, MotionEnd, MotionReport, Realtime, Start, Torques,
    check_trajectory, execute_stream, run_joint_velocities, run_torques,
};
use cps_testkit::franka_sim::{self, FrankaSim};

fn options() -> LoopOptions {
    LoopOptions {
        realtime: Realtime::Off,
        ..LoopOptions::default()
    }
}

/// S-curves at 95 % of the FR3's jerk limit and 60 % of its acceleration limit, joint by
/// joint scaled, out and back three times: the jerk jumps between zero and ±95 % of the
/// limit every millisecond or two. (franka-sim applies a command that comes late, over the
/// run of cycles it ends, where a real robot drops it; its history's acceleration is then
/// an average, and a stream at more than two thirds of the acceleration limit is judged a
/// jump there, never by a real robot: the limiter's tests in cps-robot hold streams at
/// 95 % of both limits to a real robot's rule.)
fn s_curves(from: [f64; 7]) -> Vec<[f64; 7]> {
    let limits = RateLimits::of(Arm::Fr3);
    let w = (0.6 * limits.ddq_max[0] / (0.95 * limits.dddq_max[0]) / DT).round() as usize;
    let mut jerks = Vec::new();
    for sign in [1.0, -1.0, 1.0, -1.0, 1.0, -1.0] {
        for (j, len) in [
            (1.0, w),
            (0.0, 100),
            (-1.0, w),
            (0.0, 150),
            (-1.0, w),
            (0.0, 100),
            (1.0, w),
            (0.0, 20),
        ] {
            jerks.extend(std::iter::repeat_n(sign * j, len));
        }
    }
    let mut r = Reference::at_rest(from);
    let mut s = vec![from];
    for j in jerks {
        let mut next = r;
        for i in 0..7 {
            let scale = 0.95 * (1.0 - 0.05 * i as f64);
            next.a[i] = r.a[i] + scale * j * limits.dddq_max[i] * DT;
            next.v[i] = r.v[i] + next.a[i] * DT;
            next.q[i] = r.q[i] + next.v[i] * DT;
        }
        r = next;
        s.push(r.q);
    }
    s
}

/// A gentle 4 s quintic (0.19 rad/s at most), the issue's example.
fn quintic(from: [f64; 7]) -> Vec<[f64; 7]> {
    let d = [0.4, 0.2, -0.3, 0.3, 0.2, -0.2, 0.3];
    (0..=4000)
        .map(|k| {
            let s = k as f64 / 4000.0;
            let p = 10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5);
            std::array::from_fn(|i| from[i] + d[i] * p)
        })
        .collect()
}

fn finished(what: &str, r: &MotionReport) {
    assert_eq!(
        r.ending,
        MotionEnd::Finished,
        "{what}: {} ({})",
        r.ending.sentence(),
        r.cycles().sentence()
    );
    eprintln!(
        "{what}: {} ticks; {}; loop p99 {:.1} us",
        r.timing.ticks,
        r.cycles().sentence(),
        r.timing.p99_us
    );
}

#[test]
fn on_franka_sim_with_its_reflexes_on_a_loaded_machine_no_motion_trips_a_reflex() {
    if !franka_sim::inside(
        "on_franka_sim_with_its_reflexes_on_a_loaded_machine_no_motion_trips_a_reflex",
    ) {
        return;
    }
    let Some(sim) = FrankaSim::start(true) else {
        return;
    };
    let limits = RateLimits::of(Arm::Fr3);
    let stop = AtomicBool::new(false);
    let mut all = cps_franka::Cycles::default();
    {
        let mut robot = Connection::connect(&sim.host, Default::default()).unwrap();
        robot.lose_commands(0.02, 61).unwrap();

        // S-curves at 95 % of the jerk limit, then the gentle quintic.
        for (what, make) in [
            ("S-curves", s_curves as fn([f64; 7]) -> Vec<[f64; 7]>),
            ("quintic", quintic),
        ] {
            let from = start_position(&robot.read_state().unwrap());
            let stream = check_trajectory(&limits, from, &make(from), Start::Refuse).unwrap();
            let r = execute_stream(&mut robot, limits, &stream, &options(), &stop).unwrap();
            finished(what, &r);
            // Ends where the stream ends: whatever was limited on the way was rejoined.
            let end = r.samples.last().unwrap().q_c;
            assert_eq!(end, *stream.commands.last().unwrap(), "{what}");
            all.add(&r.cycles());
        }

        // Joint velocities: a smooth bump on joint 5.
        let r = run_joint_velocities(&mut robot, limits, &options(), &stop, |_, t| {
            let s = (t / 2.0).min(1.0);
            let mut dq = [0.0; 7];
            dq[4] = 0.3 * (std::f64::consts::PI * s).sin().powi(2);
            JointVelocities {
                dq,
                finished: t >= 2.0,
            }
        })
        .unwrap();
        finished("joint velocities", &r);
        all.add(&r.cycles());

        // Torques: a joint-space spring and damper to a point 0.2 rad away on joint 1.
        let q0 = start_position(&robot.read_state().unwrap());
        let (k, d) = (
            [60.0, 60.0, 60.0, 60.0, 15.0, 15.0, 5.0],
            [8.0, 8.0, 8.0, 8.0, 2.0, 2.0, 1.0],
        );
        let r = run_torques(&mut robot, limits, &options(), &stop, |state, t| {
            let mut target = q0;
            target[0] += 0.2 * (t / 2.0).min(1.0);
            let mut tau = [0.0; 7];
            for i in 0..7 {
                tau[i] = k[i] * (target[i] - state.q[i]) - d[i] * state.dq[i];
            }
            Torques {
                tau,
                finished: t >= 3.0,
            }
        })
        .unwrap();
        finished("torques", &r);
        all.add(&r.cycles());
        assert!(robot.commands_lost() > 0);
    }
    assert!(
        all.extrapolated > 0 && all.dropped > 0,
        "the robot lost no cycle: {}",
        all.sentence()
    );
    let violations = sim.violations();
    assert!(violations.is_empty(), "franka-sim reports: {violations:#?}");

    // The official client on the same load: the quintic replayed as libfranka's examples
    // do (the trajectory's clock advanced by each state's period).
    let theirs = sim.pylibfranka(
        r#"
import json, os, pylibfranka as p
robot = p.Robot(os.environ["HOST"], p.RealtimeConfig.kIgnore)
q0 = list(robot.read_once().q_d)
d = [0.4, 0.2, -0.3, 0.3, 0.2, -0.2, 0.3]
ctl = robot.start_joint_position_control(p.ControllerMode.JointImpedance)
t, long_periods = 0.0, 0
while True:
    state, period = ctl.readOnce()
    t += period.to_sec()
    long_periods += period.to_sec() > 0.0015
    s = min(t / 4.0, 1.0)
    pp = 10 * s**3 - 15 * s**4 + 6 * s**5
    cmd = p.JointPositions([a + b * pp for a, b in zip(q0, d)])
    cmd.motion_finished = t >= 4.0
    ctl.writeOnce(cmd)
    if t >= 4.0:
        break
print(json.dumps({"long_periods": long_periods}))
"#,
    );
    eprintln!("pylibfranka on the same load: {}", theirs.trim());
    let violations = sim.violations();
    assert!(
        violations.is_empty(),
        "franka-sim reports (pylibfranka): {violations:#?}"
    );
}

/// The error flags' names by their place in the state, as franka-sim (which reports every
/// reflex by setting them) numbers them: its table is libfranka's `research_interface`
/// enum. (cps once named them in the order of libfranka's public `Errors` fields, which
/// differs from the 24th on: a lost-cycles abort was reported as a Cartesian generator's
/// discontinuity.)
#[test]
fn every_error_flag_franka_sim_sets_has_franka_sim_s_name() {
    let Some(python) = franka_sim::python() else {
        return;
    };
    let out = std::process::Command::new(python)
        .args([
            "-c",
            "import json; from franka_sim.limits.tables import ERROR_NAMES as n; \
             from franka_sim.comm_constraints import COMMUNICATION_CONSTRAINTS_VIOLATION_INDEX as c; \
             t = dict(n); t[c] = 'communication_constraints_violation'; \
             print(json.dumps({str(k): v for k, v in t.items()}))",
        ])
        .output()
        .expect("franka-sim's Python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let theirs: std::collections::BTreeMap<String, String> =
        serde_json::from_slice(&out.stdout).expect("franka-sim's table as JSON");
    assert!(theirs.len() >= 20, "{theirs:?}");
    for (index, name) in &theirs {
        let i: usize = index.parse().unwrap();
        // franka-sim spells the invalid frame's flag with the word `flag` after it, and
        // `tau_J` as libfranka's member, where its error name has `tau_j`.
        let name = name.to_lowercase();
        let name = name.trim_end_matches("_flag");
        assert_eq!(cps_franka::wire::ERROR_NAMES[i], name, "flag {i}");
    }
}
