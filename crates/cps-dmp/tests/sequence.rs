//! Sequences: C² at every junction. Checked twice: the acceleration each later segment's
//! own equation gives at the junction equals the one the previous segment arrived with
//! (to 1e-9); and on the grid, the positions' centred second difference across a junction
//! converges to the recorded acceleration as the step halves (its error is the jerk's
//! jump times h/6, so it halves), while chaining without the correction keeps an error of
//! half the acceleration's jump whatever the step.

use cps_dmp::{
    Combine, Demonstration, DiscreteDmp, DmpConfig, Formulation, Junction, OnlineDmp, Regression,
    Trajectory, imitate, sequence, sequence_with,
};

fn segments(dt: f64) -> Vec<(DiscreteDmp, Vec<f64>)> {
    // A: thesis form, B: goal-robust with another τ, C: a sampled curve (as a ProMP's
    // mean would be) imitated.
    let a = DiscreteDmp::new(DmpConfig::new(10, 1.0, dt), &[0.0, 0.0], &[1.0, 0.5]).unwrap();
    let wa: Vec<f64> = (0..20).map(|i| 40.0 * (i as f64 * 1.3).sin()).collect();
    let cb = DmpConfig {
        formulation: Formulation::GoalRobust,
        ..DmpConfig::new(8, 1.5, dt)
    };
    let b = DiscreteDmp::new(cb, &[0.0, 0.0], &[2.0, -0.5]).unwrap();
    let wb: Vec<f64> = (0..16).map(|i| 0.3 * (i as f64 * 0.7).cos()).collect();
    let t: Vec<f64> = (0..=400).map(|k| k as f64 / 200.0).collect();
    let rows: Vec<Vec<f64>> = t
        .iter()
        .map(|&s| vec![2.0 - 0.5 * s + 0.2 * (3.0 * s).sin(), -0.5 + 0.4 * s * s])
        .collect();
    let demo = Demonstration::new(t, &rows).unwrap();
    let cc = DmpConfig {
        formulation: Formulation::GoalRobust,
        ..DmpConfig::new(25, 2.0, dt)
    };
    let fit = imitate(&cc, &[demo], Regression::default(), Combine::Mean).unwrap();
    vec![(a, wa), (b, wb), (fit.dmp, fit.weights)]
}

/// The samples at the junctions.
fn junction_samples(s: &cps_dmp::Sequenced) -> Vec<usize> {
    let t = s.trajectory.times();
    s.junctions
        .iter()
        .map(|&j| t.iter().position(|&x| (x - j).abs() < 1e-9).unwrap())
        .collect()
}

/// The largest |centred second difference − recorded acceleration| at the samples `ks`.
fn fd_gap(traj: &Trajectory, ks: &[usize]) -> f64 {
    let t = traj.times();
    let mut worst = 0.0f64;
    for &k in ks {
        let h = t[k + 1] - t[k];
        for d in 0..traj.dims() {
            let y = traj.position(d);
            let fd = (y[k + 1] - 2.0 * y[k] + y[k - 1]) / (h * h);
            worst = worst.max((fd - traj.acceleration(d)[k]).abs());
        }
    }
    worst
}

#[test]
fn junctions_are_continuous_in_position_velocity_and_acceleration() {
    let segs = segments(0.005);
    let refs: Vec<(&DiscreteDmp, &[f64])> = segs.iter().map(|(d, w)| (d, w.as_slice())).collect();
    let s = sequence(&refs).unwrap();
    let traj = &s.trajectory;
    assert_eq!(s.junctions.len(), 2);
    assert!((s.junctions[0] - 1.0).abs() < 1e-12 && (s.junctions[1] - 2.5).abs() < 1e-12);
    for (j, &k) in junction_samples(&s).iter().enumerate() {
        let (dmp, w) = &s.segments[j + 1];
        let y: Vec<f64> = (0..2).map(|d| traj.position(d)[k]).collect();
        let v: Vec<f64> = (0..2).map(|d| traj.velocity(d)[k]).collect();
        assert_eq!(
            dmp.start(),
            y.as_slice(),
            "the next segment starts at the junction"
        );
        let next = OnlineDmp::new(dmp, w).with_velocity(&v).unwrap();
        for d in 0..2 {
            let (a, b) = (traj.acceleration(d)[k], next.acceleration()[d]);
            assert!(
                (a - b).abs() < 1e-9 * (1.0 + a.abs()),
                "junction {j}: {a} vs {b}"
            );
        }
    }
    // On the grid: halving the step halves the second difference's error across the
    // junctions (C²); without the correction the error stays (the acceleration jumps).
    let gap = |dt: f64, junction: Junction| {
        let segs = segments(dt);
        let refs: Vec<(&DiscreteDmp, &[f64])> =
            segs.iter().map(|(d, w)| (d, w.as_slice())).collect();
        let s = sequence_with(&refs, junction).unwrap();
        fd_gap(&s.trajectory, &junction_samples(&s))
    };
    let (c2, c2_half) = (gap(0.005, Junction::C2), gap(0.0025, Junction::C2));
    let (c1, c1_half) = (gap(0.005, Junction::C1), gap(0.0025, Junction::C1));
    eprintln!(
        "second-difference error at the junctions: C2 {c2:.3e} → {c2_half:.3e}, C1 {c1:.3e} → {c1_half:.3e}"
    );
    assert!((1.8..2.2).contains(&(c2 / c2_half)), "C2 {c2} → {c2_half}");
    assert!(
        (0.9..1.1).contains(&(c1 / c1_half)) && c1_half > 20.0 * c2_half,
        "C1 {c1} → {c1_half}"
    );
    // Every goal is reached, the last one at the end.
    let n = traj.n_samples() - 1;
    let goal = s.segments[2].0.goal();
    assert!(
        (traj.position(0)[n] - goal[0]).abs() < 1e-2
            && (traj.position(1)[n] - goal[1]).abs() < 1e-2
    );
}

#[test]
fn bad_sequences_are_refused() {
    assert!(sequence(&[]).is_err());
    let a = DiscreteDmp::new(DmpConfig::new(5, 1.0, 0.01), &[0.0], &[1.0]).unwrap();
    let b = DiscreteDmp::new(DmpConfig::new(5, 1.0, 0.01), &[0.0, 0.0], &[1.0, 1.0]).unwrap();
    let (wa, wb) = (vec![0.0; 5], vec![0.0; 10]);
    let e = sequence(&[(&a, &wa), (&b, &wb)]).unwrap_err().to_string();
    assert!(e.contains("has 2 values, expected 1"), "{e}");
    assert!(sequence(&[(&a, &wb)]).is_err());
}
