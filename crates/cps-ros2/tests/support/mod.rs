//! Test data both ROS 2 test binaries use: a smooth 7-joint trajectory and the check
//! that a peer's JSON of it is the same, number for number.

#![allow(dead_code)]

use cps_ros2_msg::msg::{JointTrajectory, JointTrajectoryPoint, Time};
use serde_json::Value;

pub fn joints() -> Vec<String> {
    (1..=7).map(|i| format!("panda_joint{i}")).collect()
}

/// `seconds` of a smooth movement at `rate` Hz: positions, velocities, accelerations.
pub fn trajectory(seconds: f64, rate: f64) -> JointTrajectory {
    let n = (seconds * rate).round() as u64;
    let points = (0..=n)
        .map(|k| {
            let t = k as f64 / rate;
            JointTrajectoryPoint {
                positions: (0..7)
                    .map(|i| 0.1 * i as f64 + 0.3 * (t + i as f64).sin())
                    .collect(),
                velocities: (0..7).map(|i| 0.3 * (t + i as f64).cos()).collect(),
                accelerations: (0..7).map(|i| -0.3 * (t + i as f64).sin()).collect(),
                effort: vec![],
                time_from_start: Time::from_nanos(k * (1e9 / rate).round() as u64),
            }
        })
        .collect();
    JointTrajectory {
        joint_names: joints(),
        points,
        ..JointTrajectory::default()
    }
}

pub fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The peer's JSON of a trajectory equals `t`, number for number.
pub fn assert_same_trajectory(got: &Value, t: &JointTrajectory) {
    let names: Vec<&str> = got["joint_names"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap())
        .collect();
    assert_eq!(names, t.joint_names);
    let points = got["points"].as_array().unwrap();
    assert_eq!(points.len(), t.points.len());
    for (g, p) in points.iter().zip(&t.points) {
        assert_eq!(floats(&g["positions"]), p.positions);
        assert_eq!(floats(&g["velocities"]), p.velocities);
        assert_eq!(floats(&g["accelerations"]), p.accelerations);
        assert!(g["effort"].as_array().unwrap().is_empty());
        let tfs = g["time_from_start"].as_array().unwrap();
        assert_eq!(
            (tfs[0].as_i64().unwrap(), tfs[1].as_u64().unwrap()),
            (
                p.time_from_start.sec as i64,
                p.time_from_start.nanosec as u64
            )
        );
    }
}
