//! A joint trajectory file against a robot's limits (`cps-cli limits check`).
//!
//! A joint trajectory CSV has a header, the time in seconds first, then one position column
//! per joint in radians; further columns (velocities `q1_vel`, …, or anything named) are
//! allowed and not read. The controller receives positions at its control rate: a file
//! sampled at that rate is taken command by command; any other file is resampled at the
//! rate by a cubic spline per joint that starts and ends at rest (zero end velocities, as
//! the controller requires), the last position held once the file's time is over. The
//! derivatives and torques are then those of [`cps_kinematics::check_joint_trajectory`].

use std::path::Path;

use cps_kinematics::{LimitCheck, Quantity, check_joint_trajectory};
use nalgebra::Vector3;
use serde_json::{Map, Value, json};

use crate::InputError;
use crate::robot_file::RobotModel;

/// Positions of a joint trajectory file.
#[derive(Debug, Clone)]
pub struct JointTrajectory {
    /// The position columns' names.
    pub names: Vec<String>,
    /// Sample times (s), strictly increasing.
    pub times: Vec<f64>,
    /// One row of joint positions per sample (rad).
    pub q: Vec<Vec<f64>>,
}

/// Reads a joint trajectory CSV for a robot of `dof` joints (at most 256 MiB): the time
/// column and the first `dof` columns after it. Errors name the file and the line.
pub fn read_joint_trajectory(path: &Path, dof: usize) -> Result<JointTrajectory, InputError> {
    let text = crate::source::read_text(path, crate::movement::MAX_DEMO_BYTES, "trajectory")?;
    let header: Vec<String> = text
        .lines()
        .next()
        .unwrap_or("")
        .split(',')
        .map(|h| h.trim().to_string())
        .collect();
    if header.len() < dof + 1 {
        return Err(InputError(format!(
            "{}: the header has {} column(s); a {dof}-joint robot needs the time and {dof} joint positions (radians)",
            path.display(),
            header.len()
        )));
    }
    let names = header[1..=dof].to_vec();
    let (names, demo) = crate::movement::parse_demo_columns(path, &text, Some(&names))?;
    let q = (0..demo.len()).map(|k| demo.sample(k).to_vec()).collect();
    Ok(JointTrajectory {
        names,
        times: demo.times().to_vec(),
        q,
    })
}

/// Second derivatives of the cubic spline through `(t, y)` with zero slope at both ends.
fn clamped_spline(t: &[f64], y: &[f64]) -> Vec<f64> {
    let n = t.len();
    let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    // Tridiagonal system for the second derivatives m (Thomas algorithm).
    let (mut diag, mut upper, mut rhs) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut lower = vec![0.0; n];
    diag[0] = 2.0 * h[0];
    upper[0] = h[0];
    rhs[0] = 6.0 * ((y[1] - y[0]) / h[0]);
    for i in 1..n - 1 {
        lower[i] = h[i - 1];
        diag[i] = 2.0 * (h[i - 1] + h[i]);
        upper[i] = h[i];
        rhs[i] = 6.0 * ((y[i + 1] - y[i]) / h[i] - (y[i] - y[i - 1]) / h[i - 1]);
    }
    lower[n - 1] = h[n - 2];
    diag[n - 1] = 2.0 * h[n - 2];
    rhs[n - 1] = -6.0 * ((y[n - 1] - y[n - 2]) / h[n - 2]);
    for i in 1..n {
        let w = lower[i] / diag[i - 1];
        diag[i] -= w * upper[i - 1];
        rhs[i] -= w * rhs[i - 1];
    }
    let mut m = vec![0.0; n];
    m[n - 1] = rhs[n - 1] / diag[n - 1];
    for i in (0..n - 1).rev() {
        m[i] = (rhs[i] - upper[i] * m[i + 1]) / diag[i];
    }
    m
}

/// The spline with second derivatives `m` at time `x` (clamped to the knots' range).
fn spline_at(t: &[f64], y: &[f64], m: &[f64], x: f64) -> f64 {
    let x = x.clamp(t[0], t[t.len() - 1]);
    let i = match t.partition_point(|&ti| ti <= x) {
        0 => 0,
        k => (k - 1).min(t.len() - 2),
    };
    let h = t[i + 1] - t[i];
    let (a, b) = ((t[i + 1] - x) / h, (x - t[i]) / h);
    a * y[i] + b * y[i + 1] + ((a * a * a - a) * m[i] + (b * b * b - b) * m[i + 1]) * h * h / 6.0
}

/// The commands the controller receives at `rate` Hz: `(t0, dt, rows, resampled)`.
pub fn at_rate(traj: &JointTrajectory, rate: f64) -> (f64, f64, Vec<Vec<f64>>, bool) {
    let dt = 1.0 / rate;
    let t0 = traj.times[0];
    let on_rate = traj
        .times
        .windows(2)
        .all(|w| ((w[1] - w[0]) - dt).abs() <= 1e-9 * dt);
    if on_rate {
        return (t0, dt, traj.q.clone(), false);
    }
    let dof = traj.q[0].len();
    let splines: Vec<(Vec<f64>, Vec<f64>)> = (0..dof)
        .map(|j| {
            let y: Vec<f64> = traj.q.iter().map(|r| r[j]).collect();
            let m = clamped_spline(&traj.times, &y);
            (y, m)
        })
        .collect();
    let span = traj.times[traj.times.len() - 1] - t0;
    let steps = (span / dt - 1e-9).ceil().max(0.0) as usize;
    let rows = (0..=steps)
        .map(|k| {
            let x = t0 + k as f64 * dt;
            splines
                .iter()
                .map(|(y, m)| spline_at(&traj.times, y, m, x))
                .collect()
        })
        .collect();
    (t0, dt, rows, true)
}

/// A checked trajectory file.
#[derive(Debug, Clone)]
pub struct LimitsReport {
    /// Per-quantity peak usage, violations and what could not be checked.
    pub check: LimitCheck,
    /// The control rate (Hz).
    pub rate: f64,
    /// Whether the file was resampled at the rate (else taken command by command).
    pub resampled: bool,
    /// Commands checked (the held ones after the end included).
    pub commands: usize,
    /// The trajectory's duration (s).
    pub duration: f64,
}

/// Checks a joint trajectory in memory (times and one row of positions each) against a
/// chain's limits at `rate` Hz, resampled as a file would be.
pub fn check_samples(
    chain: &cps_kinematics::SerialChain,
    limits: &cps_kinematics::JointLimits,
    inertia: Option<&[cps_kinematics::LinkInertia]>,
    traj: &JointTrajectory,
    rate: f64,
) -> Result<LimitsReport, cps_kinematics::KinematicsError> {
    let (t0, dt, rows, resampled) = at_rate(traj, rate);
    let check = check_joint_trajectory(
        chain,
        limits,
        inertia,
        Vector3::from(cps_kinematics::GRAVITY),
        t0,
        dt,
        &rows,
    )?;
    Ok(LimitsReport {
        check,
        rate,
        resampled,
        commands: rows.len() + 3,
        duration: traj.times[traj.times.len() - 1] - t0,
    })
}

/// Checks a joint trajectory file against `robot`'s limits at `rate` Hz.
pub fn check_file(path: &Path, robot: &RobotModel, rate: f64) -> Result<LimitsReport, InputError> {
    if !(rate.is_finite() && (1.0..=100_000.0).contains(&rate)) {
        return Err(InputError(format!(
            "--rate {rate}: give the control rate in Hz, between 1 and 100000"
        )));
    }
    let traj = read_joint_trajectory(path, robot.chain.dof())?;
    check_samples(
        &robot.chain,
        &robot.limits,
        robot.inertia.as_deref(),
        &traj,
        rate,
    )
    .map_err(|e| InputError(format!("{}: {e}", path.display())))
}

impl LimitsReport {
    /// `{"ok", "peak_usage": {quantity: [percent per joint]}, "violations": [{"joint",
    /// "quantity", "time", "value", "limit"}], "not_checked": {quantity: reason}, "rate_hz",
    /// "resampled", "duration_s"}`.
    pub fn json(&self) -> Value {
        let peak: Map<String, Value> = self
            .check
            .peak_usage
            .iter()
            .map(|(q, u)| (q.name().to_string(), json!(u)))
            .collect();
        let skipped: Map<String, Value> = self
            .check
            .not_checked
            .iter()
            .map(|(q, why)| (q.name().to_string(), json!(why)))
            .collect();
        let violations: Vec<Value> = self
            .check
            .violations
            .iter()
            .map(|v| {
                json!({"joint": v.joint, "quantity": v.quantity.name(), "time": v.time,
                       "value": v.value, "limit": v.limit})
            })
            .collect();
        json!({
            "ok": self.check.ok(),
            "peak_usage": peak,
            "violations": violations,
            "not_checked": skipped,
            "rate_hz": self.rate,
            "resampled": self.resampled,
            "duration_s": self.duration,
        })
    }

    /// The report in words, a line each.
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![format!(
            "{:.3} s, {} commands at {} Hz{}",
            self.duration,
            self.commands,
            self.rate,
            if self.resampled {
                " (resampled by a cubic spline that starts and ends at rest)"
            } else {
                ""
            }
        )];
        out.push("peak usage in % of each limit, joints 1, 2, …:".into());
        for (q, usage) in &self.check.peak_usage {
            let cells: Vec<String> = usage.iter().map(|u| format!("{u:6.1}")).collect();
            out.push(format!("  {:<13}{}", q.name(), cells.join(" ")));
        }
        for (q, why) in &self.check.not_checked {
            out.push(format!("  {:<13}not checked: {why}", q.name()));
        }
        if self.check.ok() {
            out.push("every checked limit holds".into());
        } else {
            out.push(format!("{} violation(s):", self.check.violations.len()));
            for v in &self.check.violations {
                let unit = v.quantity.unit();
                let relation = if v.quantity == Quantity::Position {
                    "beyond its bound"
                } else {
                    "above"
                };
                out.push(format!(
                    "  joint {} {} at {:.3} s: {:.6} {unit}, {relation} {:.6} {unit}",
                    v.joint,
                    v.quantity.name(),
                    v.time,
                    v.value,
                    v.limit
                ));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spline_interpolates_and_starts_and_ends_at_rest() {
        let t: Vec<f64> = (0..11).map(|k| k as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|x| (3.0 * x).sin()).collect();
        let m = clamped_spline(&t, &y);
        for (ti, yi) in t.iter().zip(&y) {
            assert!((spline_at(&t, &y, &m, *ti) - yi).abs() < 1e-12);
        }
        let h = 1e-7;
        let slope0 = (spline_at(&t, &y, &m, h) - y[0]) / h;
        let slope1 = (y[10] - spline_at(&t, &y, &m, 1.0 - h)) / h;
        assert!(
            slope0.abs() < 1e-5 && slope1.abs() < 1e-5,
            "{slope0} {slope1}"
        );
        // A cubic with zero end slopes is reproduced exactly: y = 3x² − 2x³.
        let y: Vec<f64> = t.iter().map(|x| 3.0 * x * x - 2.0 * x * x * x).collect();
        let m = clamped_spline(&t, &y);
        for k in 0..100 {
            let x = k as f64 * 0.0101;
            assert!((spline_at(&t, &y, &m, x) - (3.0 * x * x - 2.0 * x * x * x)).abs() < 1e-12);
        }
    }
}
