//! cps's scene script, `/<robot>/cpsExecutor`: a whole joint-target sequence executed
//! inside the simulator, so that a trajectory costs a handful of remote calls instead of
//! several per control step.
//!
//! The script lives in the scene as a simulation script object named `cpsExecutor`, a
//! child of the robot (for CoppeliaSim 4.8+: `configs/coppeliasim/cpsExecutor.lua`; the
//! stand-in server has it built in). Two functions, called with
//! `sim.callScriptFunction(name, scriptHandle, ...)`:
//!
//! - `cpsLoad(targets)`: `targets` is a flat table of `n · dof` joint positions, one row
//!   per simulation step. The script keeps them and, from the next step on, commands row
//!   k before step k (actuation) and records the joints, the tip's pose and the clock
//!   after it (sensing), then holds the last row. Returns `n`.
//! - `cpsResult()`: a map `{done, total}` while the run goes on; once `done == total` also
//!   `time` (n numbers), `q` (n · dof) and `pose` (n · 7: x y z qx qy qz qw, world frame).
//! - `cpsStop()`: ends the sequence where it is — no further row is commanded, the last
//!   one commanded is held — and answers as `cpsResult` does once a run is over, with
//!   `total = done` (a stop asked of cps, seen at the client's next poll).
//!
//! The client loads the sequence, lets the simulation run freely (it releases its
//! stepping hold), polls `cpsResult` a few times, paced by the progress it reads, and
//! takes its hold again. Stopping the simulation forgets the run, as CoppeliaSim
//! re-initialises simulation scripts.
//!
//! This module holds the protocol both sides share: the names, the limits, the run state
//! the stand-in keeps and the client's reading of the result.

use cps_robot::RobotError;
use nalgebra::{IsometryMatrix3, Quaternion, Translation3, UnitQuaternion};

use crate::codec::{self, Value};

/// The script object's alias (`/<robot>/cpsExecutor`).
pub const SCRIPT_ALIAS: &str = "cpsExecutor";
/// The function that loads a sequence.
pub const LOAD: &str = "cpsLoad";
/// The function that reports progress and, at the end, the recording.
pub const RESULT: &str = "cpsResult";
/// The function that ends a sequence where it is and returns what it recorded.
pub const STOP: &str = "cpsStop";
/// The most steps one `cpsLoad` takes. A recording of that many steps of a 7-joint robot
/// is ≈ 7 MB of CBOR, within the remote API's message ceiling; the client sends longer
/// sequences in parts.
pub const MAX_STEPS: usize = 50_000;

/// A sequence being executed by the stand-in's script.
#[derive(Debug, Clone, Default)]
pub(crate) struct Run {
    dof: usize,
    targets: Vec<f64>,
    time: Vec<f64>,
    q: Vec<f64>,
    pose: Vec<f64>,
}

impl Run {
    /// `cpsLoad`'s checks: a flat table of finite numbers, whole rows, not too many.
    pub(crate) fn load(dof: usize, args: &[Value], max_coordinate: f64) -> Result<Self, String> {
        let targets = args
            .first()
            .and_then(codec::as_f64_vec)
            .ok_or("cpsLoad(targets): argument 1 must be a table of joint positions")?;
        if dof == 0 || targets.is_empty() || !targets.len().is_multiple_of(dof) {
            return Err(format!(
                "cpsLoad(targets): {} numbers are not whole rows of {dof} joint positions",
                targets.len()
            ));
        }
        let n = targets.len() / dof;
        if n > MAX_STEPS {
            return Err(format!(
                "cpsLoad(targets): {n} steps, at most {MAX_STEPS} at once"
            ));
        }
        if let Some(i) = targets
            .iter()
            .position(|v| !(v.is_finite() && v.abs() <= max_coordinate))
        {
            return Err(format!(
                "cpsLoad(targets): row {}, joint {}: {} is not a finite joint value of magnitude at most {max_coordinate:e}",
                i / dof + 1,
                i % dof + 1,
                targets[i]
            ));
        }
        Ok(Self {
            dof,
            targets,
            time: Vec::with_capacity(n),
            q: Vec::with_capacity(n * dof),
            pose: Vec::with_capacity(n * 7),
        })
    }

    /// Steps in the sequence.
    pub(crate) fn total(&self) -> usize {
        self.targets.len() / self.dof
    }

    /// Steps executed so far.
    pub(crate) fn done(&self) -> usize {
        self.time.len()
    }

    /// The row to command before the next step, or `None` once the run is over.
    pub(crate) fn next_target(&self) -> Option<&[f64]> {
        let k = self.done();
        (k < self.total()).then(|| &self.targets[k * self.dof..(k + 1) * self.dof])
    }

    /// Ends the sequence where it is (`cpsStop`): no further row will be commanded.
    pub(crate) fn stop(&mut self) {
        let done = self.done();
        self.targets.truncate(done * self.dof);
    }

    /// Records the state after a step.
    pub(crate) fn record(&mut self, time: f64, q: &[f64], pose: &nalgebra::Isometry3<f64>) {
        self.time.push(time);
        self.q.extend_from_slice(q);
        let (t, r) = (pose.translation.vector, pose.rotation);
        self.pose
            .extend_from_slice(&[t.x, t.y, t.z, r.i, r.j, r.k, r.w]);
    }

    /// `cpsResult`'s answer.
    pub(crate) fn result(&self) -> Value {
        let mut entries = vec![
            ("done", codec::int(self.done() as i64)),
            ("total", codec::int(self.total() as i64)),
        ];
        if self.done() == self.total() {
            entries.push(("time", codec::floats(&self.time)));
            entries.push(("q", codec::floats(&self.q)));
            entries.push(("pose", codec::floats(&self.pose)));
        }
        codec::map(entries)
    }
}

/// What a `cpsResult` answer says.
#[derive(Debug)]
pub(crate) enum Progress {
    /// Steps done so far.
    Running(usize),
    /// The whole recording.
    Done(StepRecording),
}

/// Reads a `cpsResult` answer for a sequence of `total` steps of `dof` joints; a wrong
/// shape is a sentence saying what was wrong.
pub(crate) fn read_result(v: &Value, total: usize, dof: usize) -> Result<Progress, String> {
    let (done, reported) = (count(v, "done")?, count(v, "total")?);
    if reported != total || done > total {
        return Err(format!(
            "the script reports {done} of {reported} steps for a sequence of {total}"
        ));
    }
    if done < total {
        return Ok(Progress::Running(done));
    }
    let column = |key: &str, width: usize| {
        codec::get(v, key)
            .and_then(codec::as_f64_vec)
            .filter(|c| c.len() == total * width)
            .ok_or(format!("`{key}` must hold {} numbers", total * width))
    };
    let (time, q, pose) = (column("time", 1)?, column("q", dof)?, column("pose", 7)?);
    let mut rec = StepRecording {
        time,
        q: q.chunks(dof).map(<[f64]>::to_vec).collect(),
        tool: Vec::with_capacity(total),
    };
    for p in pose.chunks(7) {
        let r = UnitQuaternion::from_quaternion(Quaternion::new(p[6], p[3], p[4], p[5]));
        if !p.iter().all(|x| x.is_finite()) {
            return Err("`pose` holds a number that is not finite".into());
        }
        rec.tool.push(IsometryMatrix3::from_parts(
            Translation3::new(p[0], p[1], p[2]),
            r.to_rotation_matrix(),
        ));
    }
    Ok(Progress::Done(rec))
}

/// A count in an answer of the script.
fn count(v: &Value, key: &str) -> Result<usize, String> {
    codec::get(v, key)
        .and_then(codec::as_i64)
        .and_then(|n| usize::try_from(n).ok())
        .ok_or(format!("`{key}` must be a count"))
}

/// Reads a `cpsStop` answer for a sequence of at most `total` steps: the recording up to
/// where the sequence was stopped.
pub(crate) fn read_stopped(v: &Value, total: usize, dof: usize) -> Result<StepRecording, String> {
    let reported = count(v, "total")?;
    if reported > total {
        return Err(format!(
            "the script reports {reported} steps for a sequence of {total}"
        ));
    }
    match read_result(v, reported, dof)? {
        Progress::Done(rec) => Ok(rec),
        Progress::Running(_) => Err("the sequence is still running".into()),
    }
}

/// A script failure as the robot error the pipelines report.
pub(crate) fn backend_error(endpoint: &str, message: String) -> RobotError {
    RobotError::Robot {
        robot: format!("CoppeliaSim at {endpoint} ({SCRIPT_ALIAS})"),
        message,
    }
}

/// What the scene script recorded: one entry per step, after the step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepRecording {
    /// The simulation's clock (s).
    pub time: Vec<f64>,
    /// Measured joint positions.
    pub q: Vec<Vec<f64>>,
    /// Measured tool pose in the world frame.
    pub tool: Vec<IsometryMatrix3<f64>>,
}
