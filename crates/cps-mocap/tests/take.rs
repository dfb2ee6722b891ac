//! Takes written as C3D and read back, and the tool's pose recovered from their markers
//! against the known motion.

use cps_mocap::c3d::{self, Format};
use cps_mocap::demo::{Origin, Settings, Up, demonstrate};
use cps_mocap::fit::{angle_between, norm, rotation_of, sub};
use cps_mocap::register::Calibration;
use cps_mocap::synthetic::{Spec, take};

fn worst(
    demo: &cps_mocap::demo::Demonstration,
    truth: &[cps_mocap::fit::Rigid],
    offset: usize,
) -> (f64, f64) {
    let mut e = (0.0f64, 0.0f64);
    for (i, (p, q)) in demo.position.iter().zip(&demo.quaternion).enumerate() {
        let t = &truth[i + offset];
        e.0 = e.0.max(norm(sub(*p, t.translation)));
        e.1 = e.1.max(angle_between(&rotation_of(*q), &t.rotation));
    }
    e
}

#[test]
fn noise_free_markers_give_the_pose_within_a_micrometre_and_a_microradian() {
    for n in [3, 4] {
        let spec = Spec::tool(n);
        let (t, truth) = take(&spec);
        let bytes = c3d::write(&t, Format::Float).unwrap();
        let back = c3d::parse(&bytes, "tool.c3d").unwrap();
        assert_eq!(back.frames, spec.frames);
        assert_eq!(back.labels, spec.labels);
        assert_eq!(back.xyz, t.xyz);
        // The body is defined at frame 0 (the take's axes there): compare orientations
        // relative to frame 0 and positions of the markers' centroid.
        let demo = demonstrate(
            &back,
            &Settings {
                markers: spec.labels.clone(),
                cutoff_hz: None,
                ..Settings::default()
            },
        )
        .unwrap();
        assert_eq!(demo.t.len(), spec.frames);
        let c: [f64; 3] =
            std::array::from_fn(|k| spec.markers.iter().map(|m| m[k]).sum::<f64>() / n as f64);
        let r0 = truth[0].rotation;
        let mut ep = 0.0f64;
        let mut er = 0.0f64;
        for (i, (p, q)) in demo.position.iter().zip(&demo.quaternion).enumerate() {
            let want = truth[i].apply(c);
            ep = ep.max(norm(sub(*p, want)));
            let rel = cps_mocap::fit::matmul(&truth[i].rotation, &cps_mocap::fit::transpose(&r0));
            er = er.max(angle_between(&rotation_of(*q), &rel));
        }
        // Float C3D holds millimetres to 7 digits: ≈ 1e-7 m.
        assert!(ep < 1e-6 && er < 1e-6, "{n} markers: {ep} m, {er} rad");
    }
}

#[test]
fn axes_from_markers_and_an_origin_marker_give_the_tool_frame_itself() {
    // Markers 1 at the origin, 2 on x, 3 in the x-y plane: the body frame is the tool's.
    let mut spec = Spec::tool(4);
    spec.markers = vec![
        [0.0, 0.0, 0.0],
        [0.16, 0.0, 0.0],
        [0.04, 0.1, 0.0],
        [0.0, 0.0, 0.08],
    ];
    let (t, truth) = take(&spec);
    let demo = demonstrate(
        &t,
        &Settings {
            markers: spec.labels.clone(),
            origin: Origin::Marker("tool1".into()),
            axes: Some(["tool1".into(), "tool2".into(), "tool3".into()]),
            cutoff_hz: None,
            ..Settings::default()
        },
    )
    .unwrap();
    let (ep, er) = worst(&demo, &truth, 0);
    assert!(ep < 1e-6 && er < 1e-6, "{ep} m, {er} rad");
}

#[test]
fn gaps_are_filled_outliers_rejected_and_noise_smoothed() {
    let mut spec = Spec::tool(4);
    spec.markers = vec![
        [0.0, 0.0, 0.0],
        [0.16, 0.0, 0.0],
        [0.04, 0.1, 0.0],
        [0.0, 0.0, 0.08],
    ];
    spec.noise_m = 0.0005;
    spec.gaps = vec![(1, 300, 8), (2, 1000, 40), (0, 2395, 5)];
    let (mut t, truth) = take(&spec);
    // Two spikes (a reflection picked up for one frame).
    t.xyz[500 * 4 + 3][1] += 60.0;
    t.xyz[1500 * 4][2] -= 45.0;
    let s = Settings {
        markers: spec.labels.clone(),
        origin: Origin::Marker("tool1".into()),
        axes: Some(["tool1".into(), "tool2".into(), "tool3".into()]),
        max_gap: 10,
        ..Settings::default()
    };
    let demo = demonstrate(&t, &s).unwrap();
    let r = &demo.report;
    assert_eq!(r.markers[1].gaps_filled, 1);
    assert_eq!(r.markers[1].frames_filled, 8);
    assert_eq!(r.markers[2].open_gaps, vec![[1001, 1040]]);
    assert!(
        r.markers[3].outliers >= 1 && r.markers[0].outliers >= 1,
        "{:?}",
        r.markers
    );
    assert!(r.frames_with_fewer_markers >= 40);
    let (ep, er) = worst(&demo, &truth, 0);
    let rms = (demo
        .position
        .iter()
        .zip(&truth)
        .map(|(p, t)| norm(sub(*p, t.translation)).powi(2))
        .sum::<f64>()
        / demo.t.len() as f64)
        .sqrt();
    // 0.5 mm noise per coordinate (0.87 mm in 3-D), smoothed at 10 Hz: under 0.5 mm RMS; within
    // 1.5 mm and a degree (the worst at the last frames, where the origin marker is lost
    // and the filter has only one side).
    assert!(
        rms < 5e-4 && ep < 1.5e-3 && er < 0.0175,
        "{rms} m RMS, {ep} m, {er} rad"
    );
    // Without smoothing the noise comes through larger.
    let raw = demonstrate(
        &t,
        &Settings {
            cutoff_hz: None,
            ..s.clone()
        },
    )
    .unwrap();
    let (rp, _) = worst(&raw, &truth, 0);
    assert!(rp > ep, "{rp} vs {ep}");
}

#[test]
fn a_long_gap_that_leaves_two_markers_is_refused_naming_the_frames() {
    let mut spec = Spec::tool(3);
    spec.gaps = vec![(2, 500, 30)];
    let (t, _) = take(&spec);
    let e = demonstrate(
        &t,
        &Settings {
            markers: spec.labels.clone(),
            ..Settings::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("frames 501–530") && e.contains("tool3"), "{e}");
    // A gap at the start is cut instead.
    spec.gaps = vec![(2, 0, 30)];
    let (t, _) = take(&spec);
    let d = demonstrate(
        &t,
        &Settings {
            markers: spec.labels.clone(),
            ..Settings::default()
        },
    )
    .unwrap();
    assert_eq!(d.report.cut, [30, 0]);
    assert_eq!(d.report.kept_frames, [31, 2400]);
    assert_eq!(d.t[0], 0.0);
}

#[test]
fn unknown_labels_and_collinear_markers_are_named() {
    let spec = Spec::tool(3);
    let (t, _) = take(&spec);
    let e = demonstrate(
        &t,
        &Settings {
            markers: vec!["tool1".into(), "tool2".into(), "wrist".into()],
            ..Settings::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("\"wrist\"") && e.contains("tool1, tool2, tool3"),
        "{e}"
    );
    let mut line = Spec::tool(3);
    line.markers = vec![[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.1, 0.0, 0.0]];
    let (t, _) = take(&line);
    let e = demonstrate(
        &t,
        &Settings {
            markers: line.labels.clone(),
            ..Settings::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("one line"), "{e}");
}

#[test]
fn a_registration_carries_the_pose_into_the_robot_frame() {
    // The robot's base sits at (0.5, 0.2, 0) m in a Y-up lab, its z along the lab's y.
    let lab_to_robot = cps_mocap::fit::Rigid {
        rotation: [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
        translation: [-0.5, 0.0, -0.2],
    };
    let pts = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.3, 0.2, 1.0],
    ];
    let mut toml = String::from("mocap_units = \"mm\"\n");
    for p in pts {
        let r = lab_to_robot.apply(p);
        toml.push_str(&format!(
            "[[points]]\nmocap = [{}, {}, {}]\nrobot = [{}, {}, {}]\n",
            p[0] * 1e3,
            p[1] * 1e3,
            p[2] * 1e3,
            r[0],
            r[1],
            r[2]
        ));
    }
    let calib = Calibration::parse(&toml, "lab.toml").unwrap();
    let reg = calib.register().unwrap();
    assert!(reg.rms_m < 1e-12);
    let mut spec = Spec::tool(3);
    spec.markers = vec![[0.0, 0.0, 0.0], [0.16, 0.0, 0.0], [0.04, 0.1, 0.0]];
    let (t, truth) = take(&spec);
    let s = Settings {
        markers: spec.labels.clone(),
        origin: Origin::Marker("tool1".into()),
        axes: Some(["tool1".into(), "tool2".into(), "tool3".into()]),
        cutoff_hz: None,
        calibration: Some(calib),
        ..Settings::default()
    };
    let demo = demonstrate(&t, &s).unwrap();
    let in_robot: Vec<_> = truth.iter().map(|p| lab_to_robot.then_after(p)).collect();
    let (ep, er) = worst(&demo, &in_robot, 0);
    assert!(ep < 1e-6 && er < 1e-6, "{ep} m, {er} rad");
    // The same rotation as --up y (without the offset).
    let up = demonstrate(
        &t,
        &Settings {
            calibration: None,
            up: Up::Y,
            ..s.clone()
        },
    )
    .unwrap();
    let d = sub(up.position[0], demo.position[0]);
    assert!(norm(sub(d, [0.5, 0.0, 0.2])) < 1e-9, "{d:?}");
    // Collinear points and a bad point are refused.
    let bad = Calibration::parse(
        "[[points]]\nmocap=[0,0,0]\nrobot=[0,0,0]\n[[points]]\nmocap=[1,1,1]\nrobot=[1,1,1]\n[[points]]\nmocap=[2,2,2]\nrobot=[2,2,2]\n",
        "line.toml",
    )
    .unwrap();
    assert!(
        bad.register()
            .unwrap_err()
            .to_string()
            .contains("collinear")
    );
    let off = Calibration::parse(
        &toml
            .replacen("robot = [", "robot = [0.05 + ", 0)
            .replace("mocap = [1000,", "mocap = [1030,"),
        "off.toml",
    )
    .unwrap();
    let e = off.register().unwrap_err().to_string();
    assert!(e.contains("mm RMS"), "{e}");
}

#[test]
fn integer_files_hold_the_scale_and_long_takes_their_length() {
    let mut spec = Spec::tool(3);
    spec.frames = 70_000;
    spec.rate = 100.0;
    let (t, _) = take(&spec);
    let bytes = c3d::write(&t, Format::Integer { scale: 0.1 }).unwrap();
    let back = c3d::parse(&bytes, "long.c3d").unwrap();
    assert_eq!(back.frames, 70_000);
    for (a, b) in back.xyz.iter().zip(&t.xyz) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() <= 0.05 + 1e-3, "{a:?} {b:?}");
        }
    }
    assert!(back.notes.is_empty(), "{:?}", back.notes);
    // Without the TRIAL parameters the length comes from the file's size (the block
    // padding after the last frame left out), and the take says so.
    let mut blind = bytes.clone();
    for name in [&b"ACTUAL_END_FIELD"[..], b"ACTUAL_START_FIELD"] {
        let at = blind.windows(name.len()).position(|w| w == name).unwrap();
        blind[at] = b'X';
    }
    let counted = c3d::parse(&blind, "long.c3d").unwrap();
    assert_eq!(counted.frames, 70_000);
    assert!(
        counted.notes[0].contains("counted from the file's length"),
        "{:?}",
        counted.notes
    );
    assert_eq!(counted.xyz, back.xyz);
}

#[test]
fn truncated_and_lying_files_are_named_not_panicked_on() {
    let spec = Spec::tool(3);
    let (t, _) = take(&spec);
    let bytes = c3d::write(&t, Format::Float).unwrap();
    let e = c3d::parse(&bytes[..bytes.len() / 2], "cut.c3d")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("cut.c3d: truncated"), "{e}");
    let e = c3d::parse(&bytes[..300], "tiny.c3d")
        .unwrap_err()
        .to_string();
    assert!(e.contains("truncated") && e.contains("header"), "{e}");
    let mut lie = bytes.clone();
    lie[1] = 0x51;
    assert!(
        c3d::parse(&lie, "x.c3d")
            .unwrap_err()
            .to_string()
            .contains("not a C3D file")
    );
    // Every single-byte corruption of the header and parameters is an error or a take,
    // never a panic.
    for i in 0..1536 {
        for v in [0u8, 1, 0x7f, 0x80, 0xff] {
            let mut b = bytes.clone();
            b[i] = v;
            let _ = c3d::parse(&b, "fuzz.c3d");
        }
    }
}

#[test]
fn a_motive_rigid_body_with_euler_angles_is_refused_with_the_setting_to_change() {
    let text = "Format Version,1.23,Capture Frame Rate,120.000000,Rotation Type,XYZ,Length Units,Millimeters\n\n,Type,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body\n,Name,Tool,Tool,Tool,Tool,Tool,Tool\n,ID,1,1,1,1,1,1\n,,Rotation,Rotation,Rotation,Position,Position,Position\nFrame,Time (Seconds),X,Y,Z,X,Y,Z\n0,0,10,20,30,1,2,3\n";
    let t = cps_mocap::motive::parse(text.as_bytes(), "euler.csv").unwrap();
    let e = demonstrate(
        &t,
        &Settings {
            rigid_body: Some("Tool".into()),
            ..Settings::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("euler.csv") && e.contains("Rotation Type Quaternion"),
        "{e}"
    );
}
