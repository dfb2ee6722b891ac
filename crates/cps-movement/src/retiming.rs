//! Retiming a joint trajectory for a robot (`cps-cli retime`, and experiments' results):
//! the fastest timing of its path within every limit ([`cps_kinematics::retime()`]), or the
//! smallest uniform slowing of its own timing ([`cps_kinematics::retime::uniform`]).
//!
//! The result is a joint trajectory CSV in the input's form, sampled at the control rate:
//! `t`, one position column per joint (the input's names), then `<name>_vel` and
//! `<name>_acc`, the exact derivatives of the retimed motion.

use std::path::Path;

use cps_kinematics::retime::{RetimeOptions, uniform};
use cps_kinematics::{CommandCheck, JointSpline, retime};
use serde_json::{Value, json};

use crate::limits::{JointTrajectory, LimitsReport, check_samples, read_joint_trajectory};
use crate::robot_file::RobotModel;
use cps_outcome::InputError;
use cps_outcome::outcome::{Column, Format, Table};

/// How to retime.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RetimeMode {
    /// The fastest timing of the path (TOPP-RA, then jerk smoothing).
    Fastest,
    /// The trajectory's own timing stretched by the smallest factor that keeps every limit.
    Uniform,
}

impl RetimeMode {
    /// `fastest` or `uniform`.
    pub fn name(self) -> &'static str {
        match self {
            RetimeMode::Fastest => "fastest",
            RetimeMode::Uniform => "uniform",
        }
    }

    /// The mode of a name, with a sentence listing the choices otherwise.
    pub fn parse(name: &str) -> Result<Self, String> {
        match name {
            "fastest" => Ok(RetimeMode::Fastest),
            "uniform" => Ok(RetimeMode::Uniform),
            other => Err(format!(
                "retiming mode `{other}`: choose `fastest` (the time-optimal timing of the path) or `uniform` (the smallest slowing of its own timing)"
            )),
        }
    }
}

/// A retimed trajectory and what changed.
#[derive(Debug, Clone)]
pub struct RetimeReport {
    /// How it was retimed.
    pub mode: RetimeMode,
    /// The input checked at the same rate.
    pub before: LimitsReport,
    /// The result's check at the rate, joint and Cartesian.
    pub after: CommandCheck,
    /// Control rate (Hz).
    pub rate: f64,
    /// Duration of the input (s).
    pub original_duration: f64,
    /// Duration of the result's motion (s; its last sample is at the next multiple of the
    /// control period, holding the end).
    pub duration: f64,
    /// Uniform: the stretch factor (a DMP's τ is multiplied by it).
    pub factor: Option<f64>,
    /// Fastest: the TOPP-RA law's duration before jerk smoothing (s), the smoothing width
    /// (s) and the rounds of verification.
    pub fastest: Option<(f64, f64, usize)>,
    /// `t`, positions, `_vel`, `_acc` at the rate.
    pub table: Table,
    /// The retimed positions at the rate (the input's names, time from 0).
    pub trajectory: JointTrajectory,
}

says_itself_by_json_and_lines!(RetimeReport);

/// Retimes a trajectory in memory for `robot`.
pub fn retime_samples(
    robot: &RobotModel,
    traj: &JointTrajectory,
    rate: f64,
    mode: RetimeMode,
) -> Result<RetimeReport, InputError> {
    let kin = |e: cps_kinematics::KinematicsError| InputError(e.to_string());
    let limits = robot.robot_limits();
    let before = check_samples(robot, traj, rate)?;
    let original_duration = traj.times[traj.times.len() - 1] - traj.times[0];
    let (q, qd, qdd, dt, after, factor, fastest, duration) = match mode {
        RetimeMode::Fastest => {
            let r = retime(
                &limits,
                &traj.times,
                &traj.q,
                &RetimeOptions { rate, grid: 0 },
            )
            .map_err(kin)?;
            let (mut qd, mut qdd) = (Vec::new(), Vec::new());
            for t in r.times() {
                let [_, v, a, _] = r.at(t);
                qd.push(v);
                qdd.push(a);
            }
            let fastest = Some((r.topp_duration, r.smoothing, r.rounds));
            (r.q, qd, qdd, r.dt, r.check, None, fastest, r.duration)
        }
        RetimeMode::Uniform => {
            let r = uniform(&limits, &traj.times, &traj.q, rate).map_err(kin)?;
            let spline = JointSpline::new(&traj.times, &traj.q).map_err(kin)?;
            let k = r.factor;
            let (mut qd, mut qdd) = (Vec::new(), Vec::new());
            for i in 0..r.q.len() {
                let t = (i as f64 * r.dt).min(r.duration);
                let p = spline.point(traj.times[0] + t / k);
                qd.push(p.d1.iter().map(|v| v / k).collect());
                qdd.push(p.d2.iter().map(|a| a / (k * k)).collect());
            }
            (r.q, qd, qdd, r.dt, r.check, Some(k), None, r.duration)
        }
    };
    let times: Vec<f64> = (0..q.len()).map(|k| k as f64 * dt).collect();
    let mut table = Table::new("retimed").with(Column::numbers("t", times.clone(), Format::Plain));
    for (suffix, rows) in [("", &q), ("_vel", &qd), ("_acc", &qdd)] {
        for (j, name) in traj.names.iter().enumerate() {
            table.push(Column::numbers(
                format!("{name}{suffix}"),
                rows.iter().map(|r| r[j]).collect(),
                Format::Plain,
            ));
        }
    }
    let trajectory = JointTrajectory {
        names: traj.names.clone(),
        times,
        q,
    };
    Ok(RetimeReport {
        trajectory,
        mode,
        before,
        after,
        rate,
        original_duration,
        duration,
        factor,
        fastest,
        table,
    })
}

/// Reads a joint trajectory file and retimes it for `robot` at `rate` Hz.
pub fn retime_file(
    path: &Path,
    robot: &RobotModel,
    rate: f64,
    mode: RetimeMode,
) -> Result<RetimeReport, InputError> {
    crate::limits::check_rate(rate)?;
    let traj = read_joint_trajectory(path, robot.chain.dof())?;
    retime_samples(robot, &traj, rate, mode)
        .map_err(|e| InputError(format!("{}: {e}", path.display())))
}

/// The largest usage (percent) of each checked quantity over the joints, then the
/// Cartesian ones.
fn peaks(check: &CommandCheck) -> serde_json::Map<String, Value> {
    let mut out: serde_json::Map<String, Value> = check
        .joints
        .peak_usage
        .iter()
        .map(|(q, u)| {
            (
                q.name().to_string(),
                json!(u.iter().copied().fold(0.0, f64::max)),
            )
        })
        .collect();
    for (q, u) in check
        .cartesian
        .as_ref()
        .map_or(&[][..], |c| &c.peak_usage[..])
    {
        out.insert(q.to_string(), json!(u));
    }
    out
}

impl RetimeReport {
    /// Whether the result keeps every joint and Cartesian limit.
    pub fn ok(&self) -> bool {
        self.after.ok()
    }

    /// `{"mode", "rate_hz", "duration_s", "original_duration_s", "factor"?, "topp_duration_s"?,
    /// "smoothing_s"?, "rounds"?, "ok", "peak_usage_before", "peak_usage_after",
    /// "violations_before", "not_checked"}` (peak usage: the largest over the joints, in %).
    pub fn json(&self) -> Value {
        let mut out = json!({
            "mode": self.mode.name(),
            "rate_hz": self.rate,
            "duration_s": self.duration,
            "original_duration_s": self.original_duration,
        });
        let map = out.as_object_mut().expect("an object");
        if let Some(k) = self.factor {
            map.insert("factor".into(), json!(k));
        }
        if let Some((topp, w, rounds)) = self.fastest {
            map.insert("topp_duration_s".into(), json!(topp));
            map.insert("smoothing_s".into(), json!(w));
            map.insert("rounds".into(), json!(rounds));
        }
        map.insert("ok".into(), json!(self.ok()));
        map.insert(
            "peak_usage_before".into(),
            Value::Object(peaks(&self.before.check)),
        );
        map.insert("peak_usage_after".into(), Value::Object(peaks(&self.after)));
        map.insert(
            "violations_before".into(),
            json!(self.before.check.violation_count()),
        );
        map.insert(
            "not_checked".into(),
            self.after
                .joints
                .not_checked
                .iter()
                .map(|(q, why)| (q.name().to_string(), json!(why)))
                .collect::<serde_json::Map<_, _>>()
                .into(),
        );
        out
    }

    /// The report in words.
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![match (self.factor, self.fastest) {
            (Some(k), _) => format!(
                "uniform slowing by {k:.4} (a DMP's τ times {k:.4}): {:.3} s → {:.3} s",
                self.original_duration, self.duration
            ),
            (_, Some((topp, w, rounds))) => format!(
                "fastest timing: {:.3} s → {:.3} s (TOPP-RA {topp:.3} s + {:.1} ms jerk smoothing, {rounds} round(s))",
                self.original_duration,
                self.duration,
                1e3 * w
            ),
            _ => String::new(),
        }];
        out.push(format!(
            "peak usage in % before → after, the largest over the joints ({} Hz):",
            self.rate
        ));
        let before = peaks(&self.before.check);
        for (q, after) in peaks(&self.after) {
            let b = before.get(&q).and_then(Value::as_f64).unwrap_or(f64::NAN);
            out.push(format!(
                "  {q:<26}{b:7.1} → {:5.1}",
                after.as_f64().unwrap_or(f64::NAN)
            ));
        }
        for (q, why) in &self.after.joints.not_checked {
            out.push(format!("  {:<13}not checked: {why}", q.name()));
        }
        out
    }
}
