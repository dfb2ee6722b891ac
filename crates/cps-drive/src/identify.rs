//! Calibrating the dynamics robot to a real one: `cps-cli franka identify` excites a
//! Franka where it stands (a chirp on every joint, within 40 % of its limits, from rest to
//! rest), records it at 1 kHz and identifies its joint controller and drives
//! ([`cps_dynamics::identify()`]); `cps-cli identify` does the same from a recording already
//! made. Either way the calibration is judged on a part of the recording it was not
//! fitted to — the calibrated robot driven by that part's commands from its first state —
//! and written as a calibration file ([`cps_movement::calibration`]).

use std::path::{Path, PathBuf};

use cps_dynamics::{
    Calibration, Chirps, Identified, Recorded, excitation, identify, predict_until,
};
use cps_franka::Sample;
use cps_franka::limits::Arm;
use cps_franka::rt::Realtime;
use cps_kinematics::ArmModel;
use cps_movement::calibration::{Calibrated, CalibrationFile, FitRecord, calibration_text};
use cps_movement::robot_file::load_robot;
use cps_outcome::InputError;
use cps_outcome::results_dir::{FileKind, check_file_target};

use crate::error::DriveError;
use cps_robot::{RobotModel, StopToken};
use serde_json::json;

use crate::franka::{ExecuteSettings, FrankaCommands, execute, state, write_recording};
use crate::recording::{check_record_target, report_path};

/// The control period of a Franka (s).
const PERIOD: f64 = 0.001;

/// What `franka identify` does.
#[derive(Debug, Clone)]
pub struct IdentifySettings {
    /// The robot's address.
    pub host: String,
    /// Which arm.
    pub arm: Arm,
    /// Realtime scheduling of the loop.
    pub realtime: Realtime,
    /// The excitation fitted on.
    pub fit: Chirps,
    /// The excitation held back to judge the fit, right after it.
    pub check: Chirps,
    /// The world the chirps are checked in ([`ExecuteSettings::world`]); None: the arm
    /// and its hand alone.
    pub world: Option<std::sync::Arc<cps_robot::Shapes>>,
}

impl IdentifySettings {
    /// These settings with the chirps checked among the obstacles of the scene file at
    /// `scene` ([`crate::scene::scene_world`]); unchanged for None.
    pub fn in_scene(self, scene: Option<&Path>) -> Result<Self, DriveError> {
        Ok(IdentifySettings {
            world: scene
                .map(|s| crate::scene::scene_world(s, self.arm))
                .transpose()?,
            ..self
        })
    }

    /// Six seconds of chirps from 0.2 to 1.5 Hz to fit on, then three from 1.2 down to
    /// 0.3 Hz, the joints in other phases, held back.
    pub fn new(host: &str, arm: Arm, realtime: Realtime) -> Self {
        IdentifySettings {
            host: host.to_string(),
            arm,
            realtime,
            fit: Chirps::default(),
            check: Chirps {
                seconds: 3.0,
                from_hz: 1.2,
                to_hz: 0.3,
                phase: 2.1,
                ..Chirps::default()
            },
            world: None,
        }
    }
}

/// The arm as a dynamics model: its hand's inertias included (the robot carries it).
fn dynamics_model(arm: &str) -> Result<(RobotModel, ArmModel<7>), DriveError> {
    let model = load_robot(arm, Some("hand"), None)?;
    let links = model
        .inertia
        .clone()
        .ok_or_else(|| DriveError::Failed(format!("the {arm}'s link inertias are not known")))?;
    if model.chain.dof() != 7 {
        return Err(DriveError::Failed(format!(
            "{arm}: identification is for seven-joint arms"
        )));
    }
    let dynamics = ArmModel::<7>::new(&model.chain, &links)?;
    Ok((model, dynamics))
}

fn torque_limits(model: &RobotModel) -> Result<[f64; 7], DriveError> {
    let t = model.limits.torque.as_ref().ok_or_else(|| {
        DriveError::Failed(format!("the {}'s torque limits are not known", model.name))
    })?;
    Ok(std::array::from_fn(|j| t[j]))
}

/// Samples as a recording to identify from.
fn recorded(samples: &[Sample]) -> Recorded<7> {
    Recorded {
        period: PERIOD,
        time: samples.iter().map(|s| s.t).collect(),
        q: samples.iter().map(|s| s.q).collect(),
        dq: samples.iter().map(|s| s.dq).collect(),
        tau: samples.iter().map(|s| s.tau).collect(),
        q_c: samples.iter().map(|s| s.q_c).collect(),
    }
}

/// Fits on `fit`, predicts `held` from its first state under its commands, and returns the
/// identification with the prediction's RMS per joint (rad).
fn fit_and_judge(
    model: &RobotModel,
    dynamics: &ArmModel<7>,
    fit: &Recorded<7>,
    held: &Recorded<7>,
    stop: &StopToken,
) -> Result<(Identified<7>, [f64; 7]), DriveError> {
    let limits = torque_limits(model)?;
    let found = identify(dynamics, fit, &limits).map_err(DriveError::Failed)?;
    stopped(stop)?;
    if held.q.len() < 2 {
        return Err(DriveError::Failed(
            "nothing was held back to judge the calibration on".into(),
        ));
    }
    let predicted = predict_until(
        dynamics,
        model.clone(),
        &found.calibration,
        limits,
        held,
        stop,
    )
    .map_err(DriveError::Failed)?;
    stopped(stop)?;
    let n = predicted.len().min(held.q.len() - 1);
    let rms = std::array::from_fn(|j| {
        let sum: f64 = (0..n)
            .map(|k| (predicted[k][j] - held.q[k + 1][j]).powi(2))
            .sum();
        (sum / n.max(1) as f64).sqrt()
    });
    Ok((found, rms))
}

/// The calibration file of `found` on `robot`, judged at `held_back` (rad).
fn calibration_file(
    robot: &str,
    found: &Identified<7>,
    held_back: &[f64; 7],
    source: String,
    samples: usize,
) -> CalibrationFile {
    let c: &Calibration<7> = &found.calibration;
    let round = |v: &[f64], digits: i32| -> Vec<f64> {
        let s = 10f64.powi(digits);
        v.iter().map(|x| (x * s).round() / s).collect()
    };
    CalibrationFile {
        calibration: Calibrated {
            robot: robot.to_string(),
            controller: "joint_pd".into(),
            kp: round(&c.kp, 3),
            kv: round(&c.kv, 4),
            lag_ms: c.lag,
            armature: round(&c.armature, 5),
            viscous: round(&c.friction.viscous, 5),
            coulomb: round(&c.friction.coulomb, 5),
            coulomb_speed: c.friction.speed,
        },
        fit: Some(FitRecord {
            source,
            samples,
            controller_rms_nm: round(&found.controller_rms, 5),
            drive_rms_nm: round(&found.drive_rms, 5),
            held_back_rms_mrad: round(&held_back.map(|r| r * 1e3), 4),
        }),
    }
}

/// What an identification gives: the calibration file written at `out`.
#[derive(Debug, Clone)]
pub struct CalibrationWritten {
    /// The calibration and the record of its fit.
    pub file: CalibrationFile,
    /// Where it was written.
    pub out: PathBuf,
    /// `franka identify`: the robot's report of the excitation, whose loop timing is said
    /// too.
    pub excitation: Option<cps_franka::MotionReport>,
}

/// `{"out", "calibration", "fit"}`.
impl serde::Serialize for CalibrationWritten {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (c, fit) = (&self.file.calibration, &self.file.fit);
        let mut json =
            json!({ "out": self.out.display().to_string(), "calibration": c, "fit": fit });
        if let Some(r) = &self.excitation {
            json["complete"] = json!(true);
            json["timing"] = crate::franka::timing_json(r);
        }
        json.serialize(s)
    }
}

/// The gains, the lag and the drives, and how close the calibrated robot came to the
/// held-back recording.
impl std::fmt::Display for CalibrationWritten {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let c = &self.file.calibration;
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let held = self
            .file
            .fit
            .as_ref()
            .map_or(&[][..], |f| &f.held_back_rms_mrad[..]);
        let worst = held.iter().fold(0.0f64, |a, b| a.max(*b));
        writeln!(
            f,
            "{}: calibration written to {}",
            c.robot,
            self.out.display()
        )?;
        writeln!(f, "  kp [{}] N m/rad", list(&c.kp))?;
        writeln!(f, "  kv [{}] N m s/rad, lag {} ms", list(&c.kv), c.lag_ms)?;
        writeln!(
            f,
            "  rotor inertia [{}] kg m², viscous [{}] N m s/rad, Coulomb [{}] N m",
            list(&c.armature),
            list(&c.viscous),
            list(&c.coulomb)
        )?;
        write!(
            f,
            "  held back: the calibrated robot within {worst:.3} mrad RMS of the recording (worst joint)"
        )?;
        for line in self.excitation.iter().flat_map(crate::franka::timing_lines) {
            write!(f, "\n{line}")?;
        }
        Ok(())
    }
}

/// Whether two paths name one file: equal once their folders are resolved.
fn same_file(a: &Path, b: &Path) -> bool {
    let resolve = |p: &Path| {
        let dir = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::canonicalize(dir)
            .ok()
            .map(|d| d.join(p.file_name().unwrap_or_default()))
    };
    matches!((resolve(a), resolve(b)), (Some(x), Some(y)) if x == y)
}

/// The error of an identification stopped by Ctrl-C or SIGTERM, once `stop` says so.
fn stopped(stop: &StopToken) -> Result<(), DriveError> {
    if stop.is_stopped() {
        return Err(DriveError::Failed(
            "stopped before the calibration was complete; nothing was written".into(),
        ));
    }
    Ok(())
}

/// Where the calibration goes: its path, and whether a file (checked to be a calibration
/// cps wrote, and `--force` given) was there when the command began.
struct Target<'a> {
    path: &'a Path,
    existed: bool,
}

impl<'a> Target<'a> {
    /// Checks `path` before any work ([`check_file_target`]).
    fn check(path: &'a Path, force: bool) -> Result<Self, InputError> {
        check_file_target(path, FileKind::Calibration, force)?;
        Ok(Target {
            path,
            existed: std::fs::symlink_metadata(path).is_ok(),
        })
    }

    /// Writes the calibration; a file that appeared at the path meanwhile is left alone.
    fn write(&self, file: &CalibrationFile, comment: &[String]) -> Result<(), DriveError> {
        Ok(cps_outcome::files::write_file_unless_new_there(
            self.path,
            calibration_text(file, comment).as_bytes(),
            self.existed,
        )?)
    }
}

/// `cps-cli franka identify`: excites the robot where it stands, records it (into
/// `record` too, when given), identifies it and writes the calibration to `out` (both
/// checked before anything moves: new files, or `force`).
pub fn franka_identify(
    settings: &IdentifySettings,
    out: &Path,
    record: Option<&Path>,
    force: bool,
    stop: &StopToken,
) -> Result<CalibrationWritten, DriveError> {
    let target = Target::check(out, force)?;
    if let Some(r) = record {
        check_record_target(r, force)?;
        let same = |a: &Path, b: &Path| a == b || (same_file(a, b));
        for (what, path) in [
            ("the recording", r.to_path_buf()),
            ("its report", report_path(r)),
        ] {
            if same(out, &path) {
                return Err(InputError(format!(
                    "--out {} and --record {}: the calibration would be written over {what}; give two different files",
                    out.display(),
                    r.display()
                ))
                .into());
            }
        }
    }
    let (model, dynamics) = dynamics_model(settings.arm.name())?;
    let center = state(&settings.host)?.state.q.to_vec();
    let fit = excitation(&model, &center, &settings.fit, PERIOD)
        .map_err(|e| DriveError::Failed(format!("the excitation: {e}")))?;
    let check = excitation(&model, &center, &settings.check, PERIOD)
        .map_err(|e| DriveError::Failed(format!("the held-back excitation: {e}")))?;
    let split = fit.len();
    let commands: Vec<[f64; 7]> = fit
        .iter()
        .chain(check.iter().skip(1))
        .map(|q| std::array::from_fn(|j| q[j]))
        .collect();
    let prepared = FrankaCommands {
        source: "the excitation".into(),
        commands,
        how: "chirps on every joint",
    };
    let executed = execute(
        &prepared,
        &ExecuteSettings {
            host: settings.host.clone(),
            arm: settings.arm,
            retime: false,
            approach: false,
            realtime: settings.realtime,
            world: settings.world.clone(),
        },
        stop,
    )?;
    // The excitation's samples (those of the approach, and of the motion's opening at rest,
    // left out), and the first held back.
    let report = &executed.report;
    let clock = |k: usize| report.sample_at_clock(k as f64 * PERIOD);
    let first = clock(executed.approach).unwrap_or(report.samples.len());
    let samples = &report.samples[first..];
    let split = clock(executed.approach + split).map_or(samples.len(), |i| i - first);
    if let Some(r) = record {
        let report = json!({
            "complete": executed.complete(),
            "ending": executed.report.ending.sentence(),
            "host": settings.host,
            "samples": samples.len(),
            "what": "cps-cli franka identify's excitation",
            "timing": crate::franka::timing_json(&executed.report),
        });
        write_recording(r, samples, &report)?;
    }
    if !executed.complete() {
        return Err(DriveError::Failed(format!(
            "the excitation did not finish: {}; nothing was identified",
            executed.report.ending.sentence()
        )));
    }
    let whole = recorded(samples);
    let seconds = samples.len() as f64 * PERIOD;
    let mut answer = conclude(
        (&model, &dynamics),
        &whole,
        split,
        &target,
        stop,
        &|held| {
            format!(
                "cps-cli franka identify: {seconds:.1} s of chirps on the {} at {}, the last {held:.1} s held back",
                settings.arm.name(),
                settings.host,
            )
        },
        format!(
            "{}'s joint controller and drives; `[robot] calibration = \"{}\"` with backend = \"dynamics\" simulates them",
            settings.arm.name(),
            out.display()
        ),
    )?;
    // The excitation's loop: what it saw of the robot's cycles.
    answer.excitation = Some(executed.report);
    Ok(answer)
}

/// Splits `whole` at `split`, fits the arm (its model and dynamics) on the first part, judges on the rest, writes the
/// calibration to `out` (its source said by `source` of the seconds held back, a
/// `comment` on top) and answers.
fn conclude(
    (model, dynamics): (&RobotModel, &ArmModel<7>),
    whole: &Recorded<7>,
    split: usize,
    out: &Target<'_>,
    stop: &StopToken,
    source: &dyn Fn(f64) -> String,
    comment: String,
) -> Result<CalibrationWritten, DriveError> {
    let (fit_part, held) = split_at(whole, split);
    let (found, rms) = fit_and_judge(model, dynamics, &fit_part, &held, stop)?;
    let file = calibration_file(
        &model.name,
        &found,
        &rms,
        source(held.q.len() as f64 * PERIOD),
        fit_part.q.len(),
    );
    out.write(&file, &[comment])?;
    Ok(CalibrationWritten {
        file,
        out: out.path.to_path_buf(),
        excitation: None,
    })
}

/// The recording split at sample `at`: what is fitted on and what is held back.
fn split_at(rec: &Recorded<7>, at: usize) -> (Recorded<7>, Recorded<7>) {
    let part = |r: std::ops::Range<usize>| Recorded {
        period: rec.period,
        time: rec.time[r.clone()].to_vec(),
        q: rec.q[r.clone()].to_vec(),
        dq: rec.dq[r.clone()].to_vec(),
        tau: rec.tau[r.clone()].to_vec(),
        q_c: rec.q_c[r].to_vec(),
    };
    (part(0..at), part(at..rec.q.len()))
}

/// `cps-cli identify`: identifies the robot `arm` from a recording `cps-cli franka
/// execute`/`record` wrote (`t`, `q1..7`, `dq1..7`, `tau1..7`, `q_d1..7` at 1 kHz), its
/// last quarter held back, and writes the calibration to `out` (checked before any work: a
/// new file, or with `force` a calibration cps wrote; a file that appears there meanwhile
/// is left alone). Ends early, writing nothing, once `stop` is stopped.
pub fn identify_recording(
    recording: &Path,
    arm: &str,
    out: &Path,
    force: bool,
    stop: &StopToken,
) -> Result<CalibrationWritten, DriveError> {
    let target = Target::check(out, force)?;
    let (model, dynamics) = dynamics_model(arm)?;
    let text = cps_outcome::source::read_text(
        recording,
        cps_movement::movement::MAX_DEMO_BYTES,
        "recording",
    )?;
    let mut names = Vec::new();
    for prefix in ["q", "dq", "tau", "q_d"] {
        names.extend((1..=7).map(|j| format!("{prefix}{j}")));
    }
    let (_, demo) = cps_movement::movement::parse_demo_columns(recording, &text, Some(&names))
        .map_err(|e| {
            InputError(format!(
                "{} (a recording of `cps-cli franka execute` or `franka record` has t, q1..7, dq1..7, tau1..7, q_d1..7)",
                e.0
            ))
        })?;
    let times = demo.times();
    let row = |k: usize, block: usize| -> [f64; 7] {
        let s = demo.sample(k);
        std::array::from_fn(|j| s[7 * block + j])
    };
    let n = demo.len();
    let whole = Recorded {
        period: PERIOD,
        time: times.to_vec(),
        q: (0..n).map(|k| row(k, 0)).collect(),
        dq: (0..n).map(|k| row(k, 1)).collect(),
        tau: (0..n).map(|k| row(k, 2)).collect(),
        q_c: (0..n).map(|k| row(k, 3)).collect(),
    };
    whole
        .check_times()
        .map_err(|e| InputError(format!("{}: {e}", recording.display())))?;
    let seconds = n as f64 * PERIOD;
    stopped(stop)?;
    conclude(
        (&model, &dynamics),
        &whole,
        n * 3 / 4,
        &target,
        stop,
        &|held| {
            format!(
                "cps-cli identify {}: {seconds:.1} s, the last {held:.1} s held back",
                recording.display()
            )
        },
        format!(
            "{arm}'s joint controller and drives, identified from {}",
            recording.display()
        ),
    )
    .map_err(|e| match e {
        DriveError::Failed(m) => DriveError::Failed(format!("{}: {m}", recording.display())),
        other => other,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ctrl-C or SIGTERM ends `cps-cli identify` (it ran on, deaf to both): a stopped
    /// identification writes nothing and says so.
    #[test]
    fn a_stopped_identification_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("t");
        for prefix in ["q", "dq", "tau", "q_d"] {
            for j in 1..=7 {
                text.push_str(&format!(",{prefix}{j}"));
            }
        }
        for k in 0..3 {
            text.push_str(&format!("\n{}", k as f64 * 1e-3));
            text.push_str(&",0".repeat(28));
        }
        let rec = dir.path().join("rec.csv");
        std::fs::write(&rec, text).unwrap();
        let out = dir.path().join("robot.toml");
        let stop = StopToken::new();
        stop.stop();
        let e = identify_recording(&rec, "fr3", &out, false, &stop)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("stopped before the calibration was complete"),
            "{e}"
        );
        assert!(!out.exists());
        // Not stopped, the same recording is judged for what it is.
        let e = identify_recording(&rec, "fr3", &out, false, &StopToken::new())
            .unwrap_err()
            .to_string();
        assert!(e.contains("too few"), "{e}");
        assert!(!out.exists());
    }
}
