//! A joint trajectory file against a robot's limits (`cps-cli limits check`).
//!
//! A joint trajectory CSV has a header, the time in seconds first, then one position column
//! per joint in radians, read by their names: in cps's dialect (derivative columns
//! `q1_vel`, `q1_acc`, … present) the positions are the columns with a `_vel` column beside
//! them, otherwise every column after the time. Their count must be the robot's joint
//! count, and where their names number the joints (`q1`, `joint3`, `panda_joint7`, from 1
//! or from 0) the numbers must be the robot's joints — they are read in that order. A file
//! of another robot is refused, never read with a velocity as a position. The controller receives positions at its control rate: a file
//! sampled at that rate is taken command by command; any other file is resampled at the
//! rate by a cubic spline per joint that starts and ends at rest (zero end velocities, as
//! the controller requires), the last position held once the file's time is over. The
//! derivatives and torques are then those of [`cps_kinematics::check_joint_trajectory`].

use std::path::Path;

use cps_kinematics::{CommandCheck, Quantity, check_commands};
use serde_json::{Map, Value, json};

use crate::robot_file::RobotModel;
use cps_outcome::InputError;

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
/// column and the position columns, chosen by name (see the module docs). Errors name the
/// file, the columns and the line.
pub fn read_joint_trajectory(path: &Path, dof: usize) -> Result<JointTrajectory, InputError> {
    let text = cps_outcome::source::read_text(path, crate::movement::MAX_DEMO_BYTES, "trajectory")?;
    let header: Vec<String> = text
        .lines()
        .next()
        .unwrap_or("")
        .split(',')
        .map(|h| h.trim().to_string())
        .collect();
    if header.len() < 2 {
        return Err(InputError(format!(
            "{}: the header has {} column(s); a {dof}-joint robot needs the time and {dof} joint positions (radians)",
            path.display(),
            header.len()
        )));
    }
    let positions = crate::movement::pick_columns(&header, None)
        .map_err(|m| InputError(format!("{}: {m}", path.display())))?;
    let names: Vec<String> = positions.iter().map(|&c| header[c].clone()).collect();
    let names = joint_columns(&names, dof).map_err(|m| {
        InputError(format!(
            "{}: {m} (the columns after the time `{}`: {})",
            path.display(),
            header[0],
            header[1..].join(", ")
        ))
    })?;
    let (names, demo) = crate::movement::parse_demo_columns(path, &text, Some(&names))?;
    let times = demo.times();
    commands_over(times[times.len() - 1] - times[0], 1000.0)
        .map_err(|e| InputError(format!("{}: {e}", path.display())))?;
    let q = (0..demo.len()).map(|k| demo.sample(k).to_vec()).collect();
    Ok(JointTrajectory {
        names,
        times: demo.times().to_vec(),
        q,
    })
}

/// The position columns `found` in a file, in the order of a `dof`-joint robot's joints:
/// as many as it has joints, and where the names number the joints, exactly its joints.
fn joint_columns(found: &[String], dof: usize) -> Result<Vec<String>, String> {
    let listed = |v: &[String]| v.join(", ");
    if found.len() != dof {
        return Err(format!(
            "{} joint position column(s) ({}) for a {dof}-joint robot; a {dof}-joint robot needs the time and {dof} joint positions (radians), optionally followed by their `_vel` and `_acc` columns",
            found.len(),
            listed(found)
        ));
    }
    let numbers: Option<Vec<usize>> = found
        .iter()
        .map(|name| {
            let digits = name.len() - name.trim_end_matches(|c: char| c.is_ascii_digit()).len();
            (digits > 0)
                .then(|| name[name.len() - digits..].parse().ok())
                .flatten()
        })
        .collect();
    let Some(numbers) = numbers else {
        return Ok(found.to_vec()); // names that do not number joints: taken in order
    };
    let base = *numbers.iter().min().unwrap_or(&0);
    let mut sorted = numbers.clone();
    sorted.sort_unstable();
    if base > 1 || sorted.iter().enumerate().any(|(i, &k)| k != base + i) {
        return Err(format!(
            "the position columns ({}) do not name the joints of a {dof}-joint robot (1..{dof}, or 0..{})",
            listed(found),
            dof - 1
        ));
    }
    let mut ordered: Vec<(usize, &String)> = numbers.into_iter().zip(found).collect();
    ordered.sort_by_key(|(k, _)| *k);
    Ok(ordered.into_iter().map(|(_, n)| n.clone()).collect())
}

/// A trajectory at a controller's rate: `(t0, dt, rows, resampled)`.
pub type AtRate = (f64, f64, Vec<Vec<f64>>, bool);

/// The commands the controller receives at `rate` Hz: `(t0, dt, rows, resampled)`. The
/// rows are counted before they are made: a span of more than [`cps_files::count::MAX_ROWS`]
/// commands is refused.
pub fn at_rate(traj: &JointTrajectory, rate: f64) -> Result<AtRate, InputError> {
    let dt = 1.0 / rate;
    let t0 = traj.times[0];
    let span = traj.times[traj.times.len() - 1] - t0;
    commands_over(span, rate)?;
    let on_rate = traj
        .times
        .windows(2)
        .all(|w| ((w[1] - w[0]) - dt).abs() <= 1e-9 * dt);
    if on_rate {
        return Ok((t0, dt, traj.q.clone(), false));
    }
    let spline = cps_kinematics::JointSpline::new(&traj.times, &traj.q)
        .map_err(|e| InputError(format!("the trajectory cannot be interpolated: {e}")))?;
    let steps = (span / dt - 1e-9).ceil().max(0.0) as usize;
    let rows = (0..=steps)
        .map(|k| spline.positions(t0 + k as f64 * dt))
        .collect();
    Ok((t0, dt, rows, true))
}

/// The commands a span of `span` s makes at `rate` Hz, refused past
/// [`cps_files::count::MAX_ROWS`] (2 h 46 min at 1 kHz).
pub fn commands_over(span: f64, rate: f64) -> Result<usize, InputError> {
    cps_files::count::rows(
        span,
        1.0 / rate,
        &format!(
            "the trajectory lasts {} s: its commands at {} Hz",
            cps_files::number(span, 6),
            cps_files::number(rate, 6)
        ),
        "a trajectory cps checks or sends is at most 10 million commands; split it, or check its times",
    )
    .map_err(InputError::from)
}

/// A checked trajectory file.
#[derive(Debug, Clone)]
pub struct LimitsReport {
    /// Per-quantity peak usage, violations and what could not be checked, joint and
    /// Cartesian.
    pub check: CommandCheck,
    /// The control rate (Hz).
    pub rate: f64,
    /// Whether the file was resampled at the rate (else taken command by command).
    pub resampled: bool,
    /// Commands checked (the held ones after the end included).
    pub commands: usize,
    /// The trajectory's duration (s).
    pub duration: f64,
}

/// Checks a joint trajectory in memory (times and one row of positions each) against
/// `robot`'s limits at `rate` Hz, resampled as a file would be: every joint limit, and the
/// Cartesian limits where the robot has them.
pub fn check_samples(
    robot: &RobotModel,
    traj: &JointTrajectory,
    rate: f64,
) -> Result<LimitsReport, InputError> {
    let (t0, dt, rows, resampled) = at_rate(traj, rate)?;
    let check = check_commands(&robot.robot_limits(), t0, dt, &rows)
        .map_err(|e| InputError(e.to_string()))?;
    Ok(LimitsReport {
        check,
        rate,
        resampled,
        commands: rows.len() + 3,
        duration: traj.times[traj.times.len() - 1] - t0,
    })
}

/// Checks that a control rate is in 1 … 100 000 Hz.
pub fn check_rate(rate: f64) -> Result<(), InputError> {
    if rate.is_finite() && (1.0..=100_000.0).contains(&rate) {
        Ok(())
    } else {
        Err(InputError(format!(
            "--rate {rate}: give the control rate in Hz, between 1 and 100000"
        )))
    }
}

/// Checks a joint trajectory file against `robot`'s limits at `rate` Hz.
pub fn check_file(path: &Path, robot: &RobotModel, rate: f64) -> Result<LimitsReport, InputError> {
    check_rate(rate)?;
    let traj = read_joint_trajectory(path, robot.chain.dof())?;
    check_samples(robot, &traj, rate).map_err(|e| InputError(format!("{}: {e}", path.display())))
}

says_itself_by_json_and_lines!(LimitsReport);

impl LimitsReport {
    /// Whether every checked limit, joint and Cartesian, holds.
    pub fn ok(&self) -> bool {
        self.check.ok()
    }

    /// `{"ok", "peak_usage": {quantity: [percent per joint]}, "violations": [{"joint",
    /// "quantity", "time", "value", "limit"}], "not_checked": {quantity: reason}, "rate_hz",
    /// "resampled", "duration_s"}`.
    pub fn json(&self) -> Value {
        let peak: Map<String, Value> = self
            .check
            .joints
            .peak_usage
            .iter()
            .map(|(q, u)| (q.name().to_string(), json!(u)))
            .collect();
        let skipped: Map<String, Value> = self
            .check
            .joints
            .not_checked
            .iter()
            .map(|(q, why)| (q.name().to_string(), json!(why)))
            .collect();
        let violations: Vec<Value> = self
            .check
            .joints
            .violations
            .iter()
            .map(|v| {
                json!({"joint": v.joint, "quantity": v.quantity.name(), "time": v.time,
                       "value": v.value, "limit": v.limit})
            })
            .collect();
        let mut out = json!({
            "ok": self.ok(),
            "peak_usage": peak,
            "violations": violations,
            "not_checked": skipped,
            "rate_hz": self.rate,
            "resampled": self.resampled,
            "duration_s": self.duration,
        });
        if let Some(c) = &self.check.cartesian {
            out["cartesian"] = json!({
                "peak_usage": c.peak_usage.iter().map(|(q, u)| (q.to_string(), json!(u))).collect::<Map<_, _>>(),
                "violations": c.violations.iter().map(|v| json!({"quantity": v.quantity, "time": v.time, "value": v.value, "limit": v.limit})).collect::<Vec<_>>(),
            });
        }
        out
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
        for (q, usage) in &self.check.joints.peak_usage {
            let cells: Vec<String> = usage.iter().map(|u| format!("{u:6.1}")).collect();
            out.push(format!("  {:<13}{}", q.name(), cells.join(" ")));
        }
        for (q, why) in &self.check.joints.not_checked {
            out.push(format!("  {:<13}not checked: {why}", q.name()));
        }
        if let Some(c) = &self.check.cartesian {
            let cells: Vec<String> = c
                .peak_usage
                .iter()
                .map(|(q, u)| format!("{} {u:.1}", q.replace('_', " ")))
                .collect();
            out.push(format!("  Cartesian: {}", cells.join(", ")));
        }
        let cartesian = self
            .check
            .cartesian
            .as_ref()
            .map_or(&[][..], |c| &c.violations[..]);
        if self.ok() {
            out.push("every checked limit holds".into());
        } else {
            out.push(format!(
                "{} violation(s):",
                self.check.joints.violations.len() + cartesian.len()
            ));
            for v in &self.check.joints.violations {
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
            for v in cartesian {
                out.push(format!(
                    "  tool {} at {:.3} s: {:.6}, above {}",
                    v.quantity.replace('_', " "),
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

    fn read(header: &str, row: &str, dof: usize) -> Result<JointTrajectory, InputError> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("joints.csv");
        // The row at three times (its first value is the time).
        let (one, two) = (row.replacen('0', "1", 1), row.replacen('0', "2", 1));
        std::fs::write(&p, format!("{header}\n{row}\n{one}\n{two}\n")).unwrap();
        read_joint_trajectory(&p, dof)
    }

    /// A joint file is read by its column names: a 6-joint file with velocities is not a
    /// 7-joint one (its `q1_vel` was read as joint 7's position), and named joints are
    /// read in their robot's order.
    #[test]
    fn joint_files_are_read_by_their_names() {
        let six = "t,q1,q2,q3,q4,q5,q6,q1_vel,q2_vel,q3_vel,q4_vel,q5_vel,q6_vel";
        let e = read(six, "0,1,2,3,4,5,6,0,0,0,0,0,0", 7).unwrap_err().0;
        assert!(
            e.contains("6 joint position column(s) (q1, q2, q3, q4, q5, q6) for a 7-joint robot"),
            "{e}"
        );
        assert_eq!(
            read(six, "0,1,2,3,4,5,6,0,0,0,0,0,0", 6).unwrap().q[0],
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
        );
        // Too many positions, or names of joints the robot does not have.
        let e = read("t,a,b,c", "0,1,2,3", 2).unwrap_err().0;
        assert!(e.contains("3 joint position column(s)"), "{e}");
        let e = read("t,q1,q2,q9", "0,1,2,3", 3).unwrap_err().0;
        assert!(e.contains("do not name the joints"), "{e}");
        // Names read in the joints' order, from 1 or from 0; other names in file order.
        let t = read("t,panda_joint2,panda_joint1", "0,2,1", 2).unwrap();
        assert_eq!(
            (t.q[0].clone(), t.names),
            (
                vec![1.0, 2.0],
                vec!["panda_joint1".to_string(), "panda_joint2".into()]
            )
        );
        assert_eq!(read("t,q0,q1", "0,1,2", 2).unwrap().q[0], [1.0, 2.0]);
        assert_eq!(
            read("t,shoulder,elbow", "0,1,2", 2).unwrap().q[0],
            [1.0, 2.0]
        );
    }
}
