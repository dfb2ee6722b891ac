//! Robots from Python: `Robot("panda")`, a TOML or URDF file; forward kinematics, the
//! geometric Jacobian and inverse kinematics, each on one configuration or batched over
//! the rows of an array; the joint limits.

use cps_kinematics::{IkConfig, IkTarget, solve_ik};
use cps_movement::robot_file::{RobotModel, ik_target, load_robot};
use nalgebra::{IsometryMatrix3, Matrix3, Rotation3, Translation3};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use rayon::prelude::*;

use cps_movement::export::{ExportFormat, ExportOptions, export_samples};
use cps_movement::limits::{JointTrajectory, check_samples};
use cps_movement::retiming::{RetimeMode, retime_samples};
use cps_outcome::files::write_file;
use cps_outcome::outcome::Values;
use cps_outcome::results_dir::check_file_target;
use pyo3::types::PyDict;

use crate::arrays::{array1, array2, floats, matrix, shape_text, vector};
use crate::errors::{IntoPyErr, PyResultExt, choose, failure, file_error, value_error};
use crate::experiment::json_to_py;
use crate::interrupt::run;

/// Lower and upper joint limits.
type Limits<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// Joint values beyond this magnitude mean nothing (radians or metres).
const MAX_JOINT_VALUE: f64 = 1000.0;

/// A serial robot arm with its tool point: a built-in name (`panda`, `ur3`, `crx10ia`, `puma560`),
/// or a `.toml` / `.urdf` robot file.
#[pyclass(module = "cps._cps", frozen)]
pub struct Robot {
    model: RobotModel,
}

impl Robot {
    fn dof(&self) -> usize {
        self.model.chain.dof()
    }

    /// A joint trajectory from `t` (samples,) and `q` (samples, dof), checked as the
    /// command line checks a file, for a controller at `rate` Hz.
    fn trajectory(
        &self,
        t: &Bound<'_, PyAny>,
        q: &Bound<'_, PyAny>,
        rate: f64,
    ) -> PyResult<JointTrajectory> {
        let times = vector(t, "t", None)?;
        let m = matrix(q, "q", Some(self.dof()), false)?;
        if m.rows != times.len() || times.len() < 2 {
            return Err(value_error(format!(
                "q: {} rows for {} time stamps (at least 2 needed)",
                m.rows,
                times.len()
            )));
        }
        if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
            return Err(value_error(format!(
                "t: time stamps must increase strictly: t[{}] = {} follows {}",
                k + 1,
                times[k + 1],
                times[k]
            )));
        }
        if !(rate.is_finite() && (1.0..=100_000.0).contains(&rate)) {
            return Err(value_error(format!(
                "rate: give the control rate in Hz, between 1 and 100000 (got {rate})"
            )));
        }
        Ok(JointTrajectory {
            names: self.model.joint_names.clone(),
            times,
            q: m.rows_vec(),
        })
    }

    /// The link inertias and a batch of states for the dynamics: `q` as
    /// [`Self::configurations`] reads it and two more arrays of its shape (named).
    fn dynamics_state<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        a: (&Bound<'py, PyAny>, &str),
        b: (&Bound<'py, PyAny>, &str),
    ) -> PyResult<(&[cps_kinematics::LinkInertia], State)> {
        let Some(links) = &self.model.inertia else {
            return Err(value_error(format!(
                "{}: the robot's link inertias are not known, so its dynamics cannot be computed",
                self.model.name
            )));
        };
        let (q, m, batched) = self.configurations(q)?;
        let n = self.dof();
        let rows = |(x, name): (&Bound<'py, PyAny>, &str)| -> PyResult<Vec<f64>> {
            let f = floats(x, name)?;
            if f.values().len() != m * n {
                return Err(value_error(format!(
                    "{name}: expected the shape of q ({}), got {}",
                    if batched {
                        format!("({m}, {n})")
                    } else {
                        format!("({n},)")
                    },
                    shape_text(f.shape())
                )));
            }
            Ok(f.values().to_vec())
        };
        let (a, b) = (rows(a)?, rows(b)?);
        Ok((
            links,
            State {
                q,
                m,
                batched,
                a,
                b,
            },
        ))
    }

    /// `each` of `q`'s configurations (one (dof,), or the rows of (m, dof)), computed
    /// without the GIL, each appending `shape`'s count of values: an array of `shape`, or
    /// (m, ..shape) for rows.
    fn per_configuration<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        shape: Vec<usize>,
        each: impl Fn(
            &cps_kinematics::SerialChain,
            &[f64],
            &mut Vec<f64>,
        ) -> Result<(), cps_kinematics::KinematicsError>
        + Send
        + Sync,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (values, m, batched) = self.configurations(q)?;
        let n = self.dof();
        let chain = &self.model.chain;
        let size: usize = shape.iter().product();
        let out = py
            .detach(|| -> Result<Vec<f64>, cps_kinematics::KinematicsError> {
                let mut out = Vec::with_capacity(size * m);
                for c in values.chunks(n) {
                    each(chain, c, &mut out)?;
                }
                Ok(out)
            })
            .py()?;
        let dims = if batched {
            std::iter::once(m).chain(shape).collect()
        } else {
            shape
        };
        Ok(PyArray1::from_vec(py, out).reshape(dims)?.into_any())
    }

    /// Configurations from `q`: (dof,) → one, (m, dof) → m. Returns (values, m, batched).
    fn configurations(&self, q: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, usize, bool)> {
        let n = self.dof();
        let a = floats(q, "q")?;
        let (m, batched) = match *a.shape() {
            [k] if k == n => (1, false),
            [m, k] if k == n => (m, true),
            _ => {
                return Err(value_error(format!(
                    "q: expected {n} joint values, (dof,) or (m, {n}), got shape {}",
                    shape_text(a.shape())
                )));
            }
        };
        if let Some((i, v)) = a
            .values()
            .iter()
            .enumerate()
            .find(|(_, v)| v.abs() > MAX_JOINT_VALUE)
        {
            return Err(value_error(format!(
                "q: joint {} is {v}; joint values must be at most {MAX_JOINT_VALUE} in magnitude",
                i % n + 1
            )));
        }
        Ok((a.values().to_vec(), m, batched))
    }

    fn target(&self, values: &[f64], name: &str) -> PyResult<IkTarget> {
        ik_target(values).map_err(|e| value_error(e.0.replace("--target", name)))
    }

    /// The planner's settings with `seed`, `samples` and `share`, checked.
    fn settings(
        &self,
        seed: u64,
        samples: usize,
        share: f64,
    ) -> PyResult<cps_movement::planning::Settings> {
        let settings = cps_movement::planning::Settings {
            seed,
            samples,
            share,
            ..Default::default()
        };
        settings.check().map_err(|e| value_error(e.to_string()))?;
        Ok(settings)
    }

    /// A report's JSON as a dict, with its motion: `t` (samples,) and `q` (samples, dof).
    fn motion<'py>(
        &self,
        py: Python<'py>,
        json: &serde_json::Value,
        plan: &cps_robot::Plan,
    ) -> PyResult<Bound<'py, PyAny>> {
        let out = json_to_py(py, json)?;
        let times = (0..plan.points().len()).map(|k| plan.time(k)).collect();
        out.set_item("t", array1(py, times))?;
        let rows = plan.points().len();
        out.set_item("q", array2(py, plan.points().concat(), rows, self.dof())?)?;
        Ok(out)
    }

    /// One IK target: a position (3,), a pose (7,) or a 4×4 matrix.
    fn one_target(&self, obj: &Bound<'_, PyAny>, name: &str) -> PyResult<IkTarget> {
        let a = floats(obj, name)?;
        match a.shape() {
            [3] | [7] => self.target(a.values(), name),
            [4, 4] => matrix_target(a.values(), name),
            other => Err(value_error(format!(
                "{name}: expected a position (3,), a pose [x, y, z, qx, qy, qz, qw] (7,) or a 4×4 matrix, got shape {}",
                shape_text(other)
            ))),
        }
    }
}

/// A homogeneous 4×4 matrix as an IK target.
fn matrix_target(m: &[f64], name: &str) -> PyResult<IkTarget> {
    let r = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    let ortho = (r.transpose() * r - Matrix3::identity()).norm();
    if ortho > 1e-6 || r.determinant() < 0.0 || m[12..16] != [0.0, 0.0, 0.0, 1.0] {
        return Err(value_error(format!(
            "{name}: not a homogeneous transform (rotation part not orthonormal with determinant 1, or last row not [0, 0, 0, 1])"
        )));
    }
    Ok(IkTarget::Pose(IsometryMatrix3::from_parts(
        Translation3::new(m[3], m[7], m[11]),
        Rotation3::from_matrix_unchecked(r),
    )))
}

#[pymethods]
impl Robot {
    #[new]
    #[pyo3(signature = (robot=None, *, tool=None, tip=None, scene=None, margin=None))]
    fn new(
        robot: Option<&str>,
        tool: Option<&str>,
        tip: Option<&str>,
        scene: Option<std::path::PathBuf>,
        margin: Option<f64>,
    ) -> PyResult<Self> {
        let mut model = match scene {
            Some(path) => {
                if robot.is_some() || tool.is_some() || tip.is_some() {
                    return Err(value_error(
                        "scene: the scene names its robot and tool; give either scene or robot/tool/tip",
                    ));
                }
                cps_movement::scene::load_scene(&path)
                    .map_err(file_error)?
                    .robot
            }
            None => load_robot(robot.unwrap_or("panda"), tool, tip).map_err(|e| {
                value_error(
                    e.0.replace("--tool", "tool")
                        .replace("--tip", "tip")
                        .replace("--robot", "robot"),
                )
            })?,
        };
        if let Some(m) = margin {
            model = model
                .with_margin(m)
                .map_err(|e| value_error(format!("margin: {e}")))?;
        }
        Ok(Self { model })
    }

    /// The clearance (m) the guard keeps between the robot's shapes and its scene's, or
    /// None when the robot has no collision geometry (then nothing is checked for
    /// collisions).
    #[getter]
    fn margin(&self) -> Option<f64> {
        self.model.shapes.as_ref().map(|s| s.margin())
    }

    /// Every pair of the robot's links (and a link and an obstacle of its scene) closer
    /// than `within` metres at `q` (dof,), closest first: `(first, second, distance)` with
    /// links by their URDF names, obstacles by their scene names, the signed distance in
    /// metres (negative: overlapping, the depth).
    #[pyo3(signature = (q, *, within=0.1))]
    fn distances(&self, q: &Bound<'_, PyAny>, within: f64) -> PyResult<Vec<(String, String, f64)>> {
        let q = vector(q, "q", Some(self.dof()))?;
        if !(within.is_finite() && within > 0.0) {
            return Err(value_error(format!(
                "within: a distance > 0 in metres (got {within})"
            )));
        }
        let pairs = cps_movement::collide::distances(&self.model, &q, within)
            .map_err(|e| value_error(e.0))?;
        Ok(pairs
            .into_iter()
            .map(|p| (p.first, p.second, p.distance))
            .collect())
    }

    /// Checks a joint trajectory (`t` (samples,), `q` (samples, dof)) for collisions as the
    /// guard will before sending it at `rate` Hz — what `cps-cli collide --json` prints:
    /// `{"ok", "margin_m", "collision", "closest", "rows": [{"row", "time", "pairs"}], …}`.
    #[pyo3(signature = (t, q, *, rate=1000.0))]
    fn collide<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        rate: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let traj = self.trajectory(t, q, rate)?;
        let report = py
            .detach(|| cps_movement::collide::check_samples(&self.model, &traj, rate))
            .map_err(|e| value_error(e.0))?;
        json_to_py(py, &report.json())
    }

    /// A collision-free path from `start` to `goal` (dof,) around the robot itself and its
    /// scene at its margin — what `cps-cli plan --json` prints, with the timed motion `t`
    /// (samples,) and `q` (samples, dof) every millisecond: RRT-Connect seeded by `seed`
    /// (the same seed, the same path), at most `samples` random configurations, each
    /// segment timed at rest at its ends at `share` of the limits, the whole verified as the
    /// guard checks a plan. Instead of `goal`, `goal_pose` puts the tool there (a position
    /// (3,), a pose `[x, y, z, qx, qy, qz, qw]` (7,) or a 4×4 matrix, world frame): the
    /// clear inverse-kinematics solution nearest `start`, as `cps-cli plan --to-pose`.
    /// Raises `ValueError` for a bad end (naming the pair of one in collision, or a pose
    /// out of reach), `cps.CpsError` when no path is found.
    #[pyo3(signature = (start, goal=None, *, goal_pose=None, seed=1, samples=20_000, share=0.5))]
    #[allow(clippy::too_many_arguments)]
    fn plan<'py>(
        &self,
        py: Python<'py>,
        start: &Bound<'py, PyAny>,
        goal: Option<&Bound<'py, PyAny>>,
        goal_pose: Option<&Bound<'py, PyAny>>,
        seed: u64,
        samples: usize,
        share: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        use cps_movement::planning::{End, plan_report, reach};
        let settings = self.settings(seed, samples, share)?;
        let from = vector(start, "start", Some(self.dof()))?;
        let to = match (goal, goal_pose) {
            (Some(g), None) => vector(g, "goal", Some(self.dof()))?,
            (None, Some(p)) => {
                let target = self.one_target(p, "goal_pose")?;
                py.detach(|| reach(&self.model, &target, &from, 32, seed))
                    .map_err(|e| value_error(format!("goal_pose: {e}")))?
            }
            _ => {
                return Err(value_error(
                    "give the goal as joint angles (goal) or as the tool's pose (goal_pose), one of the two",
                ));
            }
        };
        let report = py
            .detach(|| plan_report(&self.model, &from, &to, &settings))
            .map_err(|e| match e.end() {
                Some(End::Start) => value_error(format!("start: {e}")),
                Some(End::Goal) => value_error(format!("goal: {e}")),
                None => failure(e.to_string()),
            })?;
        self.motion(py, &report.json(), &report.planned.plan)
    }

    /// Movements run one after another as one motion: each a pair `(t, q)` (`t` (samples,)
    /// in seconds, `q` (samples, dof)), resampled every millisecond; wherever the robot would
    /// stand elsewhere than the next movement's start — after the one before, or at `start`
    /// (default: the first movement's start) — a path planned as [`Robot::plan`] plans leads
    /// there, and the whole is verified as the guard checks a plan — what `cps-cli plan
    /// --join --json` prints (`stretches`, each movement or transition with its times),
    /// with the motion `t` and `q`. Raises `ValueError` naming the movement (`movements[k]`)
    /// for one that breaks a limit or comes within the margin, or an end in collision;
    /// `cps.CpsError` when no transition is found.
    #[pyo3(signature = (movements, *, start=None, seed=1, samples=20_000, share=0.5))]
    fn join<'py>(
        &self,
        py: Python<'py>,
        movements: Vec<(Bound<'py, PyAny>, Bound<'py, PyAny>)>,
        start: Option<&Bound<'py, PyAny>>,
        seed: u64,
        samples: usize,
        share: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        use cps_movement::planning::{join_movements, movement_of};
        let settings = self.settings(seed, samples, share)?;
        let from = start
            .map(|s| vector(s, "start", Some(self.dof())))
            .transpose()?;
        let named = movements
            .iter()
            .enumerate()
            .map(|(k, (t, q))| {
                let name = format!("movements[{k}]");
                let traj = self
                    .trajectory(t, q, 1000.0)
                    .map_err(|e| value_error(format!("{name}: {}", e.value(py))))?;
                let plan = movement_of(&traj, settings.dt)
                    .map_err(|e| value_error(format!("{name}: {e}")))?;
                Ok((name, plan))
            })
            .collect::<PyResult<Vec<_>>>()?;
        let report = py
            .detach(|| join_movements(&self.model, from.as_deref(), named, &settings))
            .map_err(|e| {
                if e.is_input() {
                    value_error(e.to_string())
                } else {
                    failure(e.to_string())
                }
            })?;
        self.motion(py, &report.json(), &report.joined.plan)
    }

    /// The robot's name.
    #[getter]
    fn name(&self) -> String {
        self.model.name.clone()
    }

    /// Degrees of freedom.
    #[getter]
    #[pyo3(name = "dof")]
    fn dof_py(&self) -> usize {
        self.dof()
    }

    /// Joint names.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.model.joint_names.clone()
    }

    /// The tool point, in words.
    #[getter]
    fn tool(&self) -> String {
        self.model.tool.clone()
    }

    /// The configuration inverse kinematics starts from by default.
    #[getter]
    fn ready<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.model.ready.clone())
    }

    /// Joint position limits `(lower, upper)` in radians, or None.
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> Option<Limits<'py>> {
        self.model
            .chain
            .limits()
            .map(|(l, u)| (array1(py, l.to_vec()), array1(py, u.to_vec())))
    }

    /// Joint speed limits in rad/s, or None.
    #[getter]
    fn velocity_limits<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.model
            .chain
            .velocity_limits()
            .map(|v| array1(py, v.to_vec()))
    }

    /// Whether `q` (dof,) lies within the joint limits; (m, dof) gives m booleans.
    fn within_limits<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (values, _, batched) = self.configurations(q)?;
        let n = self.dof();
        let inside: Vec<bool> = values
            .chunks(n)
            .map(|c| self.model.chain.within_limits(c))
            .collect();
        if batched {
            Ok(PyArray1::from_vec(py, inside).into_any())
        } else {
            Ok(inside[0].into_pyobject(py)?.to_owned().into_any())
        }
    }

    /// The tool pose as a 4×4 homogeneous matrix (world frame, metres) of `q` (dof,),
    /// or (m, 4, 4) for `q` (m, dof).
    fn fk<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        self.per_configuration(py, q, vec![4, 4], |chain, c, out| {
            let t = chain.fk_matrix(c)?;
            out.extend((0..16).map(|k| t[(k / 4, k % 4)]));
            Ok(())
        })
    }

    /// The tool pose as `[x, y, z, qx, qy, qz, qw]` (world frame, metres; the rotation's
    /// unit quaternion with `qw >= 0`) of `q` (dof,), or (m, 7) for `q` (m, dof).
    fn pose<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        self.per_configuration(py, q, vec![7], |chain, c, out| {
            let pose = chain.fk(c)?;
            let r = nalgebra::UnitQuaternion::from_rotation_matrix(&pose.rotation);
            let sign = if r.w < 0.0 { -1.0 } else { 1.0 };
            let p = pose.translation.vector;
            out.extend([p.x, p.y, p.z]);
            out.extend([r.i, r.j, r.k, r.w].map(|x| sign * x));
            Ok(())
        })
    }

    /// The geometric Jacobian (6, dof) in the world frame (rows: linear, then angular
    /// velocity of the tool point), or (m, 6, dof) for `q` (m, dof).
    fn jacobian<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let n = self.dof();
        self.per_configuration(py, q, vec![6, n], |chain, c, out| {
            let j = chain.jacobian(c)?;
            out.extend((0..6 * n).map(|k| j[(k / n, k % n)]));
            Ok(())
        })
    }

    /// Joint angles that put the tool at `target`: a position (3,), a pose [x, y, z, qx,
    /// qy, qz, qw] (7,) or a 4×4 matrix; batched as (m, 3), (m, 7) or (m, 4, 4), solved in
    /// parallel, each row from `q0` (default: the ready configuration), within the joint
    /// limits. Raises `cps.CpsError` naming the row when a target is out of reach.
    #[pyo3(signature = (target, q0=None, *, tolerance=1e-9, restarts=300, seed=0))]
    fn ik<'py>(
        &self,
        py: Python<'py>,
        target: &Bound<'py, PyAny>,
        q0: Option<&Bound<'py, PyAny>>,
        tolerance: f64,
        restarts: usize,
        seed: u64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n = self.dof();
        let a = floats(target, "target")?;
        let shape = a.shape().to_vec();
        let (rows, width, batched) = match shape.as_slice() {
            [w] if *w == 3 || *w == 7 => (1, *w, false),
            [4, 4] => (1, 16, false),
            [m, w] if *w == 3 || *w == 7 => (*m, *w, true),
            [m, 4, 4] => (*m, 16, true),
            _ => {
                return Err(value_error(format!(
                    "target: expected a position (3,), a pose [x, y, z, qx, qy, qz, qw] (7,) or a 4×4 matrix, or m of them, got shape {}",
                    shape_text(&shape)
                )));
            }
        };
        let targets = a
            .values()
            .chunks(width)
            .enumerate()
            .map(|(k, v)| {
                let name = if batched {
                    format!("target[{k}]")
                } else {
                    "target".into()
                };
                if width == 16 {
                    matrix_target(v, &name)
                } else {
                    self.target(v, &name)
                }
            })
            .collect::<PyResult<Vec<_>>>()?;
        let seed_q = match q0 {
            Some(q) if !q.is_none() => vector(q, "q0", Some(n))?,
            _ => self.model.ready.clone(),
        };
        self.model
            .chain
            .check_within_limits(&seed_q)
            .map_err(|e| value_error(format!("q0: {e}")))?;
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(value_error(format!(
                "tolerance: must be finite and > 0 (got {tolerance})"
            )));
        }
        let config = IkConfig {
            position_tolerance: tolerance,
            rotation_tolerance: tolerance,
            restarts,
            seed,
            ..IkConfig::default()
        };
        let chain = &self.model.chain;
        // A solve is microseconds to a few milliseconds (restarts): a handful inline, a
        // batch on the pool, stoppable by Ctrl-C.
        let solved = run(py, rows as f64 * 1e6, |_| {
            targets
                .par_iter()
                .map(|t| solve_ik(chain, t, &seed_q, &config))
                .collect::<Vec<_>>()
        })?;
        let mut out = Vec::with_capacity(rows * n);
        for (k, s) in solved.into_iter().enumerate() {
            match s {
                Ok(sol) => out.extend(sol.q),
                Err(e) => {
                    let err = e.py_err();
                    let msg = err.value(py).to_string();
                    return Err(if batched {
                        failure(format!("target[{k}]: {msg}"))
                    } else {
                        err
                    });
                }
            }
        }
        if batched {
            Ok(array2(py, out, rows, n)?.into_any())
        } else {
            Ok(array1(py, out).into_any())
        }
    }

    /// Joint torques (N m) of inverse dynamics (recursive Newton–Euler) at positions `q`,
    /// velocities `qd` and accelerations `qdd`, each (dof,) or (m, dof); gravity
    /// (0, 0, −9.81) m/s² unless given. Needs the robot's link inertias (the built-in
    /// Panda: Gaz et al. 2019); raises `ValueError` for a robot without them.
    #[pyo3(signature = (q, qd, qdd, *, gravity=None))]
    fn inverse_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        qdd: &Bound<'py, PyAny>,
        gravity: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (
            links,
            State {
                q,
                m,
                batched,
                a: qd,
                b: qdd,
            },
        ) = self.dynamics_state(q, (qd, "qd"), (qdd, "qdd"))?;
        let n = self.dof();
        let g = nalgebra::Vector3::from(gravity_of(gravity)?);
        let chain = &self.model.chain;
        let out = py
            .detach(|| -> Result<Vec<f64>, cps_kinematics::KinematicsError> {
                let mut out = Vec::with_capacity(m * n);
                for k in 0..m {
                    let s = k * n..(k + 1) * n;
                    out.extend(chain.inverse_dynamics(
                        links,
                        g,
                        &q[s.clone()],
                        &qd[s.clone()],
                        &qdd[s],
                    )?);
                }
                Ok(out)
            })
            .py()?;
        shaped(py, out, m, n, batched)
    }

    /// Joint accelerations (rad/s²) of forward dynamics (the articulated-body algorithm) at
    /// positions `q` and velocities `qd` under joint torques `tau` (N m), each (dof,) or
    /// (m, dof); gravity (0, 0, −9.81) m/s² unless given; `armature` the rotor inertia
    /// reflected to each joint (kg m², MuJoCo's and pinocchio's `armature`; default none).
    /// The inverse of `inverse_dynamics`. Needs the robot's link inertias.
    #[pyo3(signature = (q, qd, tau, *, gravity=None, armature=None))]
    fn forward_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        gravity: Option<&Bound<'py, PyAny>>,
        armature: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (
            links,
            State {
                q,
                m,
                batched,
                a: qd,
                b: tau,
            },
        ) = self.dynamics_state(q, (qd, "qd"), (tau, "tau"))?;
        let n = self.dof();
        let g = gravity_of(gravity)?.to_vec();
        let armature = match armature {
            Some(a) if !a.is_none() => vector(a, "armature", Some(n))?,
            _ => vec![0.0; n],
        };
        let chain = &self.model.chain;
        let out = py
            .detach(|| match n {
                2 => forward::<2>(chain, links, &g, &armature, &q, &qd, &tau),
                3 => forward::<3>(chain, links, &g, &armature, &q, &qd, &tau),
                4 => forward::<4>(chain, links, &g, &armature, &q, &qd, &tau),
                5 => forward::<5>(chain, links, &g, &armature, &q, &qd, &tau),
                6 => forward::<6>(chain, links, &g, &armature, &q, &qd, &tau),
                7 => forward::<7>(chain, links, &g, &armature, &q, &qd, &tau),
                8 => forward::<8>(chain, links, &g, &armature, &q, &qd, &tau),
                _ => Err(cps_kinematics::KinematicsError::InvalidModel(format!(
                    "forward dynamics is computed for arms of 2 to 8 joints; this one has {n}"
                ))),
            })
            .py()?;
        shaped(py, out, m, n, batched)
    }

    /// Checks a joint trajectory (`t` (samples,), `q` (samples, dof)) against every limit of
    /// the robot as its controller sees it at `rate` Hz — what `cps-cli limits check`
    /// prints as JSON: `{"ok", "peak_usage", "violations", "not_checked", …}`.
    #[pyo3(signature = (t, q, *, rate=1000.0))]
    fn check_limits<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        rate: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let traj = self.trajectory(t, q, rate)?;
        let report = py.detach(|| check_samples(&self.model, &traj, rate)).py()?;
        json_to_py(py, &report.json())
    }

    /// Retimes a joint trajectory (`t` (samples,), `q` (samples, dof)) within every limit:
    /// `mode="fastest"` (TOPP-RA, then jerk smoothing) or `"uniform"` (its own timing
    /// stretched by the smallest factor). Returns `cps-cli retime`'s JSON as a dict, with
    /// the result sampled at `rate` Hz under `"t"`, `"q"`, `"qd"`, `"qdd"` (arrays).
    #[pyo3(signature = (t, q, *, mode="fastest", rate=1000.0))]
    fn retime<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        mode: &str,
        rate: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mode = choose(
            "mode",
            mode,
            &[
                ("fastest", RetimeMode::Fastest),
                ("uniform", RetimeMode::Uniform),
            ],
        )?;
        let traj = self.trajectory(t, q, rate)?;
        let report = py
            .detach(|| retime_samples(&self.model, &traj, rate, mode))
            .py()?;
        let out = json_to_py(py, &report.json())?;
        let dict = out.cast::<PyDict>()?;
        let n = self.dof();
        let column = |name: String| -> Vec<f64> {
            match report.table.column(&name).map(|c| &c.values) {
                Some(Values::Numbers(v)) => v.clone(),
                _ => Vec::new(),
            }
        };
        dict.set_item("t", array1(py, column("t".into())))?;
        for (key, suffix) in [("q", ""), ("qd", "_vel"), ("qdd", "_acc")] {
            let cols: Vec<Vec<f64>> = traj
                .names
                .iter()
                .map(|name| column(format!("{name}{suffix}")))
                .collect();
            let rows = cols[0].len();
            let flat = (0..rows)
                .flat_map(|k| cols.iter().map(move |c| c[k]))
                .collect();
            dict.set_item(key, array2(py, flat, rows, n)?)?;
        }
        Ok(out)
    }

    /// Writes a joint trajectory (`t`, `q`) for ROS 2 and viewers, as `cps-cli export`:
    /// `format="ros2-yaml"` (trajectory_msgs/JointTrajectory), `"mcap"` (ROS 2 MCAP with the
    /// trajectory, /joint_states, /tf, /tf_static, /robot_description) or `"csv-1khz"`;
    /// points every `period` seconds. An existing file at `path` is replaced only with
    /// `force=True` and only if it is of that format. Returns the export's summary.
    #[pyo3(signature = (t, q, path, *, format, period=0.01, force=false))]
    #[allow(clippy::too_many_arguments)]
    fn export<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        path: std::path::PathBuf,
        format: &str,
        period: f64,
        force: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let format = choose("format", format, &ExportFormat::ALL.map(|f| (f.name(), f)))?;
        let traj = self.trajectory(t, q, 1000.0)?;
        check_file_target(&path, format.file_kind(), force).map_err(file_error)?;
        let options = ExportOptions { period };
        let exported = py
            .detach(|| export_samples(&self.model, &traj, format, &options))
            .map_err(|e| value_error(e.0.replace("--period", "period")))?;
        write_file(&path, &exported.bytes).map_err(|e| failure(e.to_string()))?;
        json_to_py(py, &exported.json)
    }

    /// The robot in words: its kinematic description, limits, base and tool.
    fn describe(&self) -> String {
        cps_movement::robot_file::Describe::describe(&self.model).join("\n")
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot(\"{}\", dof={}, tool=\"{}\")",
            self.model.name,
            self.dof(),
            self.model.tool
        )
    }
}

/// Forward dynamics of `N` joints for every row of `q`, `qd`, `tau` (flat, row-major).
fn forward<const N: usize>(
    chain: &cps_kinematics::SerialChain,
    links: &[cps_kinematics::LinkInertia],
    gravity: &[f64],
    armature: &[f64],
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Result<Vec<f64>, cps_kinematics::KinematicsError> {
    let model = cps_kinematics::ArmModel::<N>::new(chain, links)?
        .with_gravity([gravity[0], gravity[1], gravity[2]])
        .with_armature(std::array::from_fn(|i| armature[i]))?;
    let mut out = Vec::with_capacity(q.len());
    let row = |v: &[f64], k: usize| -> [f64; N] { std::array::from_fn(|i| v[k * N + i]) };
    for k in 0..q.len() / N {
        let f = model.frames(&row(q, k));
        out.extend(model.forward_dynamics(&f, &row(qd, k), &row(tau, k), None));
    }
    Ok(out)
}

/// A batch of dynamic states: positions and two more arrays of their shape, flat.
struct State {
    q: Vec<f64>,
    m: usize,
    batched: bool,
    a: Vec<f64>,
    b: Vec<f64>,
}

/// The `gravity` keyword of the dynamics methods: three numbers, (0, 0, −9.81) m/s² unless
/// given.
fn gravity_of(gravity: Option<&Bound<'_, PyAny>>) -> PyResult<[f64; 3]> {
    match gravity {
        Some(g) if !g.is_none() => {
            let v = vector(g, "gravity", Some(3))?;
            Ok([v[0], v[1], v[2]])
        }
        _ => Ok(cps_kinematics::GRAVITY),
    }
}

/// `m` rows of `n` values as the caller gave its states: (m, n), or (n,) for one state.
fn shaped(
    py: Python<'_>,
    out: Vec<f64>,
    m: usize,
    n: usize,
    batched: bool,
) -> PyResult<Bound<'_, PyAny>> {
    if batched {
        Ok(array2(py, out, m, n)?.into_any())
    } else {
        Ok(array1(py, out).into_any())
    }
}
