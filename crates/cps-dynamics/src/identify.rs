//! Calibration to a robot: the joint-level controller's gains and lag, and the drives'
//! rotor inertia and friction, identified from a recording made at the control rate — so
//! that the dynamics robot behaves like that robot.
//!
//! The robot runs a position controller of franky-sim's form, `τ = kp·(q_c − q) −
//! kv·q̇ + C(q, q̇)q̇ + g(q)` (gravity and Coriolis cancelled with the arm's model), and
//! reports the torque it applied. Per joint, with the arm's rigid-body model known:
//!
//! 1. **the controller**: `τ − g(q) − C(q, q̇)q̇ = kp·(q_c − q) − kv·q̇` is linear in
//!    `kp` and `kv`: least squares over the samples whose torque was not clipped, for each
//!    alignment of torque, state and command (the command `lag` control periods old); the
//!    alignment with the smallest residual wins;
//! 2. **the drive**: what the applied torque does beyond the rigid bodies, `τ − RNEA(q, q̇,
//!    q̈) = J_rotor·q̈ + b·q̇ + c·tanh(q̇/s)`, with `q̈` from consecutive velocities: least
//!    squares for the rotor inertia `J_rotor`, viscous `b` and Coulomb `c` friction
//!    (`s` = [`FRANKY_SIM_COULOMB_SPEED`], the speed franky-sim's
//!    friction rises over).
//!
//! [`excitation`] makes the commands to record from (a chirp on every joint, within a
//! share of the limits, starting and ending at rest); [`predict`] runs a calibrated robot
//! on recorded commands, to judge a calibration on a recording it was not fitted to.

#![allow(clippy::needless_range_loop)] // small dense systems and joint-indexed arrays, read side by side

use cps_kinematics::ArmModel;
use cps_kinematics::contact::JointFriction;
use cps_robot::{Generator, RobotModel, StopToken, Streaming};

use crate::arm::{Arm, FRANKY_SIM_COULOMB_SPEED};
use crate::controller::Controller;
use crate::robot::{DynamicsRobot, DynamicsSettings, MAX_LAG};

/// The longest run of missed periods a recording may hold (0.1 s at 1 kHz): a robot that
/// reports no state for longer has lost its connection, and what it did meanwhile is not
/// in the recording. Bounding it bounds the work and memory of [`predict`] by the
/// recording's length, whatever its clock says.
pub const MAX_MISSED_PERIODS: usize = 100;

/// How far each joint's command must range over a recording (rad) for its controller to be
/// identified: a robot standing still, its sensors' noise aside, determines no gains.
pub const MIN_EXCITATION: f64 = 0.02;

/// A robot's joint-level controller and drives, as identified ([`identify`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration<const N: usize> {
    /// Position gain per joint (N m/rad).
    pub kp: [f64; N],
    /// Velocity gain per joint (N m s/rad).
    pub kv: [f64; N],
    /// How many control periods old the command the controller acts on is.
    pub lag: usize,
    /// Rotor inertia per joint (kg m²).
    pub armature: [f64; N],
    /// The joints' friction.
    pub friction: JointFriction<N>,
}

/// A recording at the control rate: per period the measured joints, their velocities,
/// the torques the robot applied (gravity included), and the command it was sent. A
/// robot under load misses periods now and then: `time` says which ones each sample is.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recorded<const N: usize> {
    /// The control period (s).
    pub period: f64,
    /// The robot's clock at each sample (s; empty: one period apart).
    pub time: Vec<f64>,
    /// Measured positions (rad).
    pub q: Vec<[f64; N]>,
    /// Measured velocities (rad/s).
    pub dq: Vec<[f64; N]>,
    /// Applied torques (N m, gravity included).
    pub tau: Vec<[f64; N]>,
    /// Commanded positions (rad).
    pub q_c: Vec<[f64; N]>,
}

/// What [`identify`] found and how well it fits.
#[derive(Debug, Clone, PartialEq)]
pub struct Identified<const N: usize> {
    /// The calibration.
    pub calibration: Calibration<N>,
    /// RMS of the controller model's torque residual per joint (N m).
    pub controller_rms: [f64; N],
    /// RMS of the drive model's torque residual per joint (N m).
    pub drive_rms: [f64; N],
    /// Samples per joint the controller was fitted on (those not clipped).
    pub samples: [usize; N],
    /// The applied torque of sample k was computed from the state of sample k − this.
    pub torque_delay: usize,
}

impl<const N: usize> Recorded<N> {
    /// Sample `k`'s control period, counted from the first sample's.
    pub fn period_index(&self, k: usize) -> usize {
        match self.time.get(k) {
            Some(t) => ((t - self.time[0]) / self.period).round() as usize,
            None => k,
        }
    }

    /// Checks the period (finite, > 0) and the clock: one time a sample, each a whole
    /// number of periods after the one before, no gap of more than
    /// [`MAX_MISSED_PERIODS`] — a recording's own fault, for a reader to report as input.
    pub fn check_times(&self) -> Result<(), String> {
        let num = |x: f64| cps_files::number(x, 4);
        if !(self.period.is_finite() && self.period > 0.0) {
            return Err(format!(
                "the control period must be finite and > 0 (got {})",
                self.period
            ));
        }
        if !self.time.is_empty() && self.time.len() != self.q.len() {
            return Err(format!(
                "the recording has {} times for {} samples",
                self.time.len(),
                self.q.len()
            ));
        }
        if let Some(k) = (0..self.time.len()).find(|&k| !self.time[k].is_finite()) {
            return Err(format!("sample {}: its time is not finite", k + 1));
        }
        let mut missed_pairs = 0;
        for k in 1..self.time.len() {
            let gap = self.time[k] - self.time[k - 1];
            let steps = gap / self.period;
            if !(steps.is_finite() && steps > 0.5 && (steps - steps.round()).abs() < 0.25) {
                return Err(format!(
                    "samples {k} and {} are {} s apart: not a whole number of control periods ({} s, {:.0} Hz)",
                    k + 1,
                    num(gap),
                    self.period,
                    1.0 / self.period
                ));
            }
            if steps.round() > (MAX_MISSED_PERIODS + 1) as f64 {
                return Err(format!(
                    "samples {k} and {} are {} s apart: the robot reported nothing for more than {MAX_MISSED_PERIODS} control periods ({:.3} s), so the recording does not say what it did; identify from a recording without such a gap (or from each part of it)",
                    k + 1,
                    num(gap),
                    MAX_MISSED_PERIODS as f64 * self.period
                ));
            }
            if steps.round() >= 2.0 {
                missed_pairs += 1;
            }
        }
        // A robot under load misses a period now and then; a recording that misses most is
        // one made at another rate.
        if self.time.len() > 2 && 2 * missed_pairs > self.time.len() - 1 {
            let mut gaps: Vec<f64> = self.time.windows(2).map(|w| w[1] - w[0]).collect();
            gaps.sort_by(f64::total_cmp);
            let typical = gaps[gaps.len() / 2];
            return Err(format!(
                "its samples are typically {} s apart ({} Hz): identification needs a recording at the control rate, one sample every {} s ({:.0} Hz)",
                num(typical),
                num(1.0 / typical),
                self.period,
                1.0 / self.period
            ));
        }
        Ok(())
    }

    /// For each sample, the first sample of the run of consecutive periods holding it.
    fn runs(&self) -> Vec<usize> {
        let mut start = vec![0; self.q.len()];
        for k in 1..self.q.len() {
            start[k] = if self.period_index(k) == self.period_index(k - 1) + 1 {
                start[k - 1]
            } else {
                k
            };
        }
        start
    }
}

/// Solves the normal equations `A x = b` of a small least-squares problem (Gaussian
/// elimination with partial pivoting); `None` when they are singular.
fn solve<const M: usize>(mut a: [[f64; M]; M], mut b: [f64; M]) -> Option<[f64; M]> {
    for c in 0..M {
        let p = (c..M).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-300 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..M {
            let f = a[r][c] / a[c][c];
            for k in c..M {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; M];
    for c in (0..M).rev() {
        let s: f64 = (c + 1..M).map(|k| a[c][k] * x[k]).sum();
        x[c] = (b[c] - s) / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Least squares `y ≈ Σ x_m·r_m` over rows; returns the coefficients and the residual's
/// RMS.
fn least_squares<const M: usize>(rows: &[([f64; M], f64)]) -> Option<([f64; M], f64)> {
    let mut a = [[0.0; M]; M];
    let mut b = [0.0; M];
    for (r, y) in rows {
        for i in 0..M {
            b[i] += r[i] * y;
            for j in 0..M {
                a[i][j] += r[i] * r[j];
            }
        }
    }
    let x = solve(a, b)?;
    let sum: f64 = rows
        .iter()
        .map(|(r, y)| (y - (0..M).map(|i| x[i] * r[i]).sum::<f64>()).powi(2))
        .sum();
    Some((x, (sum / rows.len().max(1) as f64).sqrt()))
}

/// Identifies the controller and drives of the robot `model` (its rigid bodies, without
/// rotor inertia) from `rec`; `torque_limit` per joint says which samples were clipped.
/// Errors, each a sentence: a recording too short, of unequal columns or a period that
/// is not positive, a joint whose torque was clipped throughout or whose motion does not
/// determine its gains.
pub fn identify<const N: usize>(
    model: &ArmModel<N>,
    rec: &Recorded<N>,
    torque_limit: &[f64; N],
) -> Result<Identified<N>, String> {
    check_recording(rec)?;
    let n = rec.q.len();
    // The torque the controller asked for, gravity and Coriolis taken out, per sample and
    // torque-to-state delay (0: the state of the same sample, 1: the one before).
    let mut gravity = Vec::with_capacity(n);
    let mut coriolis = Vec::with_capacity(n);
    for k in 0..n {
        let f = model.frames(&rec.q[k]);
        gravity.push(model.gravity(&f));
        coriolis.push(model.coriolis(&f, &rec.dq[k]));
    }
    // A sample is used when it, and the samples it is paired with, lie in one run of
    // consecutive periods (a missed period breaks the pairing of torque, state and command).
    let runs = rec.runs();
    let clipped = |k: usize, j: usize| rec.tau[k][j].abs() >= 0.995 * torque_limit[j];
    let skipped = |k: usize, back: usize| k < runs[k] + back;
    let mut best: Option<(f64, usize, usize)> = None;
    for delay in 0..=1 {
        for age in delay..=delay + MAX_LAG {
            let mut total = 0.0;
            for j in 0..N {
                let rows = controller_rows(rec, &gravity, &coriolis, j, delay, age, &|k, j| {
                    clipped(k, j) || skipped(k, age)
                });
                let Some((_, rms)) = least_squares(&rows) else {
                    continue;
                };
                total += rms * rms;
            }
            if best.is_none_or(|b| total < b.0) {
                best = Some((total, delay, age));
            }
        }
    }
    let (_, delay, age) = best.expect("at least one alignment");
    let mut kp = [0.0; N];
    let mut kv = [0.0; N];
    let mut controller_rms = [0.0; N];
    let mut samples = [0; N];
    for j in 0..N {
        let rows = controller_rows(rec, &gravity, &coriolis, j, delay, age, &|k, j| {
            clipped(k, j) || skipped(k, age)
        });
        samples[j] = rows.len();
        if rows.len() < 100 {
            return Err(format!(
                "joint {}: its torque was at the drive's limit ({} N m) in all but {} samples: record a gentler motion",
                j + 1,
                torque_limit[j],
                rows.len()
            ));
        }
        let ([p, v], rms) = least_squares(&rows).ok_or_else(|| {
            format!(
                "joint {}: the recording does not determine its gains (did it move?)",
                j + 1
            )
        })?;
        if !(p > 0.0 && v >= 0.0) {
            return Err(format!(
                "joint {}: the fit gives kp = {p:.4} N m/rad and kv = {v:.4} N m s/rad, which no stable position controller has (kp > 0, kv ≥ 0): the recording does not determine its gains",
                j + 1
            ));
        }
        kp[j] = p;
        kv[j] = v;
        controller_rms[j] = rms;
    }
    let (armature, friction, drive_rms) = fit_drives(model, rec, delay, &clipped, &skipped)?;
    Ok(Identified {
        calibration: Calibration {
            kp,
            kv,
            lag: age - delay,
            armature,
            friction,
        },
        controller_rms,
        drive_rms,
        samples,
        torque_delay: delay,
    })
}

/// A recording identification can use: columns of one length, times that advance, at
/// least a second of motion, every joint excited.
fn check_recording<const N: usize>(rec: &Recorded<N>) -> Result<(), String> {
    let n = rec.q.len();
    if [rec.dq.len(), rec.tau.len(), rec.q_c.len()]
        .iter()
        .any(|&l| l != n)
    {
        return Err(format!(
            "the recording's columns differ in length: {} positions, {} velocities, {} torques, {} commands",
            n,
            rec.dq.len(),
            rec.tau.len(),
            rec.q_c.len()
        ));
    }
    rec.check_times()?;
    let skip = MAX_LAG + 2;
    if n < 200 + 2 * skip {
        return Err(format!(
            "{n} samples are too few to identify from: record at least a second of motion"
        ));
    }
    for j in 0..N {
        let (lo, hi) = rec
            .q_c
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                (lo.min(c[j]), hi.max(c[j]))
            });
        let span = hi - lo;
        if span.is_nan() || span < MIN_EXCITATION {
            return Err(format!(
                "joint {}: its command ranges over {:.2} mrad only: the recording does not excite it, so its controller cannot be identified (record a motion of every joint of at least {} mrad; `cps-cli franka identify` makes one)",
                j + 1,
                span * 1e3,
                MIN_EXCITATION * 1e3
            ));
        }
    }
    Ok(())
}

/// The drives: the applied torque beyond the rigid bodies, from the state it acted on
/// and the acceleration it produced (the torque `delay` samples after its state; clipped
/// and skipped samples left out): armature, friction, and each fit's RMS.
fn fit_drives<const N: usize>(
    model: &ArmModel<N>,
    rec: &Recorded<N>,
    delay: usize,
    clipped: &dyn Fn(usize, usize) -> bool,
    skipped: &dyn Fn(usize, usize) -> bool,
) -> Result<([f64; N], JointFriction<N>, [f64; N]), String> {
    let n = rec.q.len();
    let skip = MAX_LAG + 2;
    let runs = rec.runs();
    let h = rec.period;
    let mut drive_rows: Vec<Vec<([f64; 3], f64)>> = vec![Vec::new(); N];
    for k in skip..n - 1 {
        // The state before the torque and the one after it, consecutive.
        if skipped(k, delay) || runs[k - delay + 1] != runs[k - delay] {
            continue;
        }
        let s = k - delay;
        let ddq: [f64; N] = std::array::from_fn(|j| (rec.dq[s + 1][j] - rec.dq[s][j]) / h);
        let f = model.frames(&rec.q[s]);
        let rigid = model.inverse_dynamics(&f, &rec.dq[s], &ddq, true);
        for j in 0..N {
            if clipped(k, j) {
                continue;
            }
            let v = rec.dq[s][j];
            drive_rows[j].push((
                [ddq[j], v, (v / FRANKY_SIM_COULOMB_SPEED).tanh()],
                rec.tau[k][j] - rigid[j],
            ));
        }
    }
    let mut armature = [0.0; N];
    let mut friction = JointFriction::none();
    friction.speed = FRANKY_SIM_COULOMB_SPEED;
    let mut drive_rms = [0.0; N];
    for j in 0..N {
        let ([a, b, c], rms) = least_squares(&drive_rows[j]).ok_or_else(|| {
            format!(
                "joint {}: the recording does not determine its drive (did it move?)",
                j + 1
            )
        })?;
        // A negative coefficient is noise about zero: none.
        armature[j] = a.max(0.0);
        friction.viscous[j] = b.max(0.0);
        friction.coulomb[j] = c.max(0.0);
        drive_rms[j] = rms;
    }
    Ok((armature, friction, drive_rms))
}

/// Joint `j`'s controller rows `([q_c − q, −q̇], τ − g − C q̇)`: torque of sample k, state
/// of k − `delay`, command of k − `age`; clipped samples left out.
fn controller_rows<const N: usize>(
    rec: &Recorded<N>,
    gravity: &[nalgebra::SVector<f64, N>],
    coriolis: &[nalgebra::SVector<f64, N>],
    j: usize,
    delay: usize,
    age: usize,
    clipped: &dyn Fn(usize, usize) -> bool,
) -> Vec<([f64; 2], f64)> {
    let skip = MAX_LAG + 2;
    (skip..rec.q.len())
        .filter(|&k| !clipped(k, j))
        .map(|k| {
            let s = k - delay;
            (
                [rec.q_c[k - age][j] - rec.q[s][j], -rec.dq[s][j]],
                rec.tau[k][j] - gravity[s][j] - coriolis[s][j],
            )
        })
        .collect()
}

/// How [`excitation`] moves the joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chirps {
    /// Duration (s).
    pub seconds: f64,
    /// The frequency at the start (Hz).
    pub from_hz: f64,
    /// The frequency at the end (Hz).
    pub to_hz: f64,
    /// The largest amplitude of a joint (rad).
    pub amplitude: f64,
    /// The share of each speed, acceleration and jerk limit the chirps may use at their
    /// highest frequency.
    pub share: f64,
    /// Each joint's phase offset is this times its index (rad), so that joints move apart.
    pub phase: f64,
}

impl Default for Chirps {
    /// Six seconds from 0.2 to 1.5 Hz, at most 0.1 rad, within 40 % of the limits.
    fn default() -> Self {
        Chirps {
            seconds: 6.0,
            from_hz: 0.2,
            to_hz: 1.5,
            amplitude: 0.1,
            share: 0.4,
            phase: 0.9,
        }
    }
}

/// Commands every `period` from rest at `center` back to rest at `center`: every joint a
/// chirp sweeping as `chirps` says, faded in and out over half a second, its amplitude the
/// largest within `chirps.share` of the robot's speed, acceleration and jerk limits and
/// 0.05 rad inside its range. Errors: a centre outside the range or too near it to move.
pub fn excitation(
    model: &RobotModel,
    center: &[f64],
    chirps: &Chirps,
    period: f64,
) -> Result<Vec<Vec<f64>>, String> {
    let n = model.chain.dof();
    if center.len() != n {
        return Err(format!(
            "{} centre positions for a {n}-joint robot",
            center.len()
        ));
    }
    let omega = 2.0 * std::f64::consts::PI * chirps.to_hz.max(chirps.from_hz);
    let bound = |limits: Option<&Vec<f64>>, j: usize, power: i32| {
        limits.map_or(f64::INFINITY, |l| chirps.share * l[j] / omega.powi(power))
    };
    let speeds = model.chain.velocity_limits().map(<[f64]>::to_vec);
    let mut amplitude = vec![0.0; n];
    for j in 0..n {
        let room = match model.chain.limits() {
            Some((lo, hi)) => (center[j] - lo[j]).min(hi[j] - center[j]) - 0.05,
            None => f64::INFINITY,
        };
        if room <= 0.0 {
            return Err(format!(
                "joint {} is within 0.05 rad of its range at the centre ({:.4} rad): move the robot away from its limits first",
                j + 1,
                center[j]
            ));
        }
        amplitude[j] = chirps
            .amplitude
            .min(room)
            .min(bound(speeds.as_ref(), j, 1))
            .min(bound(model.limits.acceleration.as_ref(), j, 2))
            .min(bound(model.limits.jerk.as_ref(), j, 3));
    }
    let samples = (chirps.seconds / period).round() as usize + 1;
    let fade = 0.5_f64.min(chirps.seconds / 4.0);
    let (f0, f1, t_end) = (chirps.from_hz, chirps.to_hz, chirps.seconds);
    Ok((0..samples)
        .map(|k| {
            let t = k as f64 * period;
            // A quintic smoothstep in and out: at rest, without a jump of acceleration.
            let smooth = |x: f64| {
                let x = x.clamp(0.0, 1.0);
                x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)
            };
            let w = smooth(t / fade) * smooth((t_end - t) / fade);
            let phi = 2.0 * std::f64::consts::PI * (f0 * t + (f1 - f0) * t * t / (2.0 * t_end));
            (0..n)
                .map(|j| center[j] + amplitude[j] * w * (phi + chirps.phase * j as f64).sin())
                .collect()
        })
        .collect())
}

/// What the robot `model` (its rigid bodies, without rotor inertia) calibrated as
/// `calibration` does with the commands of the recording `held`, from its first state: its
/// joints at each later sample (a missed period holds the last command, as a robot does).
/// `torque_limit` per joint.
pub fn predict<const N: usize>(
    model: &ArmModel<N>,
    robot: RobotModel,
    calibration: &Calibration<N>,
    torque_limit: [f64; N],
    held: &Recorded<N>,
) -> Result<Vec<[f64; N]>, String> {
    predict_until(
        model,
        robot,
        calibration,
        torque_limit,
        held,
        &StopToken::new(),
    )
}

/// [`predict`], ending early (with an error saying so) once `stop` is stopped.
pub fn predict_until<const N: usize>(
    model: &ArmModel<N>,
    robot: RobotModel,
    calibration: &Calibration<N>,
    torque_limit: [f64; N],
    held: &Recorded<N>,
    stop: &StopToken,
) -> Result<Vec<[f64; N]>, String> {
    let n = held.q.len();
    if n < 2 || held.dq.len() != n || held.q_c.len() != n {
        return Err(format!(
            "a recording of {n} samples (with {} velocities, {} commands) has nothing to predict",
            held.dq.len(),
            held.q_c.len()
        ));
    }
    held.check_times()?;
    let dynamics = model
        .clone()
        .with_armature(calibration.armature)
        .map_err(|e| e.to_string())?;
    let mut arm = Arm::at_rest(dynamics, calibration.friction, torque_limit, held.q[0]);
    arm.dq = held.dq[0];
    let period = held.period;
    let mut sim = DynamicsRobot::new(
        robot,
        arm,
        DynamicsSettings {
            controller: Controller::JointPd {
                kp: calibration.kp,
                kv: calibration.kv,
            },
            control_period: period,
            dt: period,
            noise: 0.0,
            seed: 0,
            reflexes: false,
            lag: calibration.lag,
        },
    )
    .map_err(|e| e.to_string())?;
    // The command of every period: the last one sent by then.
    let periods = held.period_index(n - 1);
    let mut commands = Vec::with_capacity(periods);
    let mut k = 0;
    for p in 0..periods {
        while k + 1 < n && held.period_index(k + 1) <= p {
            k += 1;
        }
        commands.push(held.q_c[k]);
    }
    let mut next: Box<Generator<'_>> = Box::new(|_q, t, command| {
        let p = ((t / period).round() as usize).min(periods - 1);
        command.copy_from_slice(&commands[p]);
        p + 1 >= periods
    });
    let run =
        Streaming::stream(&mut sim, &mut next, periods + 1, stop).map_err(|e| e.to_string())?;
    if stop.is_stopped() {
        return Err("stopped before the prediction was complete".into());
    }
    (1..n)
        .map(|k| {
            let q = run
                .q
                .get(held.period_index(k))
                .ok_or_else(|| "the prediction ended early".to_string())?;
            Ok(std::array::from_fn(|j| q[j]))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use cps_kinematics::robots::{PandaTool, fr3, fr3_inertia, fr3_limits};
    use cps_robot::Robot;

    const START: [f64; 7] = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.785];

    /// A robot of known gains, lag, rotor inertia and friction, driven by `commands` one
    /// control period each; recorded as a Franka reports: each state with the torque that
    /// produced it and the command sent after it.
    fn record(truth: &Calibration<7>, commands: &[Vec<f64>]) -> Recorded<7> {
        let chain = fr3(PandaTool::HandTcp);
        let model = ArmModel::<7>::new(&chain, &fr3_inertia())
            .unwrap()
            .with_armature(truth.armature)
            .unwrap();
        let limits = [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0];
        let arm = Arm::at_rest(model, truth.friction, limits, START);
        let mut robot = DynamicsRobot::new(
            RobotModel::of_chain("fr3", chain),
            arm,
            DynamicsSettings {
                controller: Controller::JointPd {
                    kp: truth.kp,
                    kv: truth.kv,
                },
                control_period: 0.001,
                dt: 0.001,
                noise: 0.0,
                seed: 0,
                reflexes: true,
                lag: truth.lag,
            },
        )
        .unwrap();
        let mut rec = Recorded {
            period: 0.001,
            ..Recorded::default()
        };
        let mut tau = robot.applied_torques();
        for c in commands {
            rec.q.push(robot.arm().q);
            rec.dq.push(robot.arm().dq);
            rec.tau.push(tau);
            rec.q_c.push(std::array::from_fn(|j| c[j]));
            let stepped = robot.stepped().unwrap();
            stepped.command_joint_positions(c).unwrap();
            stepped.step().unwrap();
            tau = robot.applied_torques();
        }
        rec
    }

    fn truth() -> Calibration<7> {
        Calibration {
            kp: [4000.0, 4400.0, 3000.0, 3600.0, 1500.0, 1200.0, 600.0],
            kv: [380.0, 420.0, 300.0, 330.0, 120.0, 90.0, 40.0],
            lag: 2,
            armature: [0.2, 0.18, 0.19, 0.2, 0.07, 0.075, 0.07],
            friction: JointFriction {
                viscous: [0.2, 0.25, 0.18, 0.2, 0.1, 0.12, 0.05],
                coulomb: [1.1, 1.2, 1.0, 1.1, 0.7, 0.4, 0.25],
                speed: FRANKY_SIM_COULOMB_SPEED,
            },
        }
    }

    #[test]
    fn a_known_robot_is_identified_and_predicted() {
        let truth = truth();
        let chain = fr3(PandaTool::HandTcp);
        let model = fr3_model();
        let commands = excitation(&model, &START, &Chirps::default(), 0.001).unwrap();
        let rec = record(&truth, &commands);
        let rigid = ArmModel::<7>::new(&chain, &fr3_inertia()).unwrap();
        let limits = [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0];
        let found = identify(&rigid, &rec, &limits).unwrap();
        let c = &found.calibration;
        assert_eq!(c.lag, truth.lag);
        assert_eq!(found.torque_delay, 1);
        for j in 0..7 {
            assert!(
                (c.kp[j] / truth.kp[j] - 1.0).abs() < 1e-6,
                "kp {j}: {}",
                c.kp[j]
            );
            assert!(
                (c.kv[j] / truth.kv[j] - 1.0).abs() < 1e-6,
                "kv {j}: {}",
                c.kv[j]
            );
            // The drive from differenced velocities: within a few per cent.
            assert!(
                (c.armature[j] - truth.armature[j]).abs() < 0.01,
                "armature {j}: {}",
                c.armature[j]
            );
            assert!(
                (c.friction.coulomb[j] - truth.friction.coulomb[j]).abs() < 0.05,
                "coulomb {j}: {}",
                c.friction.coulomb[j]
            );
        }
        // A motion it was not fitted to, predicted from its first state.
        let other = Chirps {
            seconds: 3.0,
            from_hz: 1.2,
            to_hz: 0.3,
            phase: 2.1,
            ..Chirps::default()
        };
        let held = record(&truth, &excitation(&model, &START, &other, 0.001).unwrap());
        let predicted =
            predict(&rigid, RobotModel::of_chain("fr3", chain), c, limits, &held).unwrap();
        let worst = |predicted: &[[f64; 7]], held: &Recorded<7>| {
            (0..predicted.len())
                .flat_map(|k| (0..7).map(move |j| (k, j)))
                .map(|(k, j)| (predicted[k][j] - held.q[k + 1][j]).abs())
                .fold(0.0, f64::max)
        };
        assert!(
            worst(&predicted, &held) < 1e-4,
            "{} rad",
            worst(&predicted, &held)
        );
        // A robot under load misses periods: samples lost here and there (the robot held
        // its last command meanwhile) change neither the fit nor the prediction.
        let mut lossy = rec.clone();
        lossy.time = (0..lossy.q.len()).map(|k| k as f64 * 0.001).collect();
        for k in (1500..lossy.q.len()).step_by(997).rev() {
            for column in [&mut lossy.q, &mut lossy.dq, &mut lossy.tau] {
                column.remove(k);
            }
            lossy.q_c.remove(k);
            lossy.time.remove(k);
        }
        let again = identify(&rigid, &lossy, &limits).unwrap();
        assert_eq!(again.calibration.lag, truth.lag);
        for j in 0..7 {
            assert!((again.calibration.kp[j] / truth.kp[j] - 1.0).abs() < 1e-6);
        }
    }

    /// The FR3 with its limits (acceleration and jerk included).
    fn fr3_model() -> RobotModel {
        let mut m = RobotModel::of_chain("fr3", fr3(PandaTool::HandTcp));
        m.limits = fr3_limits();
        m
    }

    #[test]
    fn bad_recordings_are_named() {
        let rigid = ArmModel::<7>::new(&fr3(PandaTool::HandTcp), &fr3_inertia()).unwrap();
        let short = Recorded::<7> {
            period: 0.001,
            time: Vec::new(),
            q: vec![START; 10],
            dq: vec![[0.0; 7]; 10],
            tau: vec![[0.0; 7]; 10],
            q_c: vec![START; 10],
        };
        let e = identify(&rigid, &short, &[87.0; 7]).unwrap_err();
        assert!(e.contains("10 samples are too few"), "{e}");
        let mut uneven = short.clone();
        uneven.tau.pop();
        assert!(
            identify(&rigid, &uneven, &[87.0; 7])
                .unwrap_err()
                .contains("differ in length")
        );
        let still = Recorded::<7> {
            period: 0.001,
            time: Vec::new(),
            q: vec![START; 1000],
            dq: vec![[0.0; 7]; 1000],
            tau: vec![[0.0; 7]; 1000],
            q_c: vec![START; 1000],
        };
        let e = identify(&rigid, &still, &[87.0; 7]).unwrap_err();
        assert!(e.contains("does not excite it"), "{e}");
    }

    /// Recordings a careless user or a broken logger makes: refused with a sentence, never
    /// a panic, negative gains, or memory that grows with a gap in the clock.
    #[test]
    fn hostile_recordings_are_refused() {
        let rigid = ArmModel::<7>::new(&fr3(PandaTool::HandTcp), &fr3_inertia()).unwrap();
        let model = fr3_model();
        let commands = excitation(&model, &START, &Chirps::default(), 0.001).unwrap();
        let rec = record(&truth(), &commands);
        let n = rec.q.len();
        let clock = |rec: &Recorded<7>, f: &dyn Fn(usize) -> f64| Recorded {
            time: (0..rec.q.len()).map(f).collect(),
            ..rec.clone()
        };
        // A last time stamp of 1e300 (it panicked on a capacity overflow).
        let far = clock(&rec, &|k| if k + 1 == n { 1e300 } else { k as f64 * 1e-3 });
        let e = identify(&rigid, &far, &[87.0; 7]).unwrap_err();
        assert!(e.contains("reported nothing for more than 100"), "{e}");
        let e = predict(&rigid, model.clone(), &truth(), [87.0; 7], &far).unwrap_err();
        assert!(e.contains("reported nothing"), "{e}");
        // A gap of 10 000 s (it took 2.4 GB): refused before anything is allocated for it.
        let gap = clock(&rec, &|k| {
            k as f64 * 1e-3 + if k > n / 2 { 1e4 } else { 0.0 }
        });
        let e = predict(&rigid, model.clone(), &truth(), [87.0; 7], &gap).unwrap_err();
        assert!(
            e.contains(&format!("samples {} and {}", n / 2 + 1, n / 2 + 2)),
            "{e}"
        );
        // A recording at 500 Hz is named as such (it was refused for clipped torques).
        let slow = clock(&rec, &|k| k as f64 * 2e-3);
        let e = identify(&rigid, &slow, &[87.0; 7]).unwrap_err();
        assert!(e.contains("(500 Hz)") && e.contains("(1000 Hz)"), "{e}");
        // A still robot with sensor noise (it got negative gains).
        let mut rng = 12345u64;
        let mut noise = |scale: f64| {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * scale
        };
        let mut still = Recorded::<7> {
            period: 0.001,
            ..Recorded::default()
        };
        for _ in 0..3000 {
            still
                .q
                .push(std::array::from_fn(|j| START[j] + noise(1e-4)));
            still.dq.push(std::array::from_fn(|_| noise(1e-3)));
            still.tau.push(std::array::from_fn(|_| noise(0.1)));
            still
                .q_c
                .push(std::array::from_fn(|j| START[j] + noise(1e-5)));
        }
        let e = identify(&rigid, &still, &[87.0; 7]).unwrap_err();
        assert!(
            e.contains("joint 1") && e.contains("does not excite it"),
            "{e}"
        );
        // Torques that push away from the command (a sign flipped in a logger): no stable
        // controller fits.
        let mut deaf = rec.clone();
        for k in 0..n {
            let f = rigid.frames(&rec.q[k]);
            let (g, c) = (rigid.gravity(&f), rigid.coriolis(&f, &rec.dq[k]));
            deaf.tau[k] = std::array::from_fn(|j| 2.0 * (g[j] + c[j]) - rec.tau[k][j]);
        }
        let e = identify(&rigid, &deaf, &[87.0; 7]).unwrap_err();
        assert!(e.contains("no stable position controller"), "{e}");
    }
}
