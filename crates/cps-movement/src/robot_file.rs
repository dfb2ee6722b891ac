//! Robot models from the command line's `--robot` value: a built-in name, a TOML robot file
//! (schema below, examples in `configs/robots/`) or a URDF file.
//!
//! A TOML robot file names its DH convention and gives one `[[joint]]` table per joint
//! with its DH row and its limits; `[base]` places the robot in the world and `[tools.*]`
//! names tool points (`xyz` in metres, `rpy` in radians as URDF: roll about x, then pitch
//! about y, then yaw about z, all about fixed axes).

use std::path::Path;
use std::sync::Arc;

use cps_kinematics::robots::{
    PandaTool, fr3, fr3_inertia, fr3_limits, panda, panda_inertia, panda_limits, puma560, ur3,
    ur3_inertia, ur3_limits,
};
use cps_kinematics::{
    CartesianLimits, ChainGeometry, DhConvention, DhLink, IkTarget, JointLimits, LinkInertia,
    SerialChain, chain_from_urdf,
};
use nalgebra::{Isometry3, IsometryMatrix3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;
use toml::Spanned;

use cps_outcome::InputError;
use cps_outcome::source::location;

pub use cps_robot::RobotModel;

/// Words about a robot model.
pub trait Describe {
    /// The robot in words, one line each: its kinematic description (DH table or URDF
    /// joints) with the joint limits, then the base and the tool frame.
    fn describe(&self) -> Vec<String>;
}

impl Describe for RobotModel {
    fn describe(&self) -> Vec<String> {
        let mut out = Vec::new();
        macro_rules! put {
            ($($arg:tt)*) => { out.push(format!($($arg)*)) };
        }
        let arm = &self.chain;
        let limits = |i: usize| {
            let (lo, hi) = arm
                .limits()
                .map_or(("-".to_string(), "-".to_string()), |(lo, hi)| {
                    (format!("{:.4}", lo[i]), format!("{:.4}", hi[i]))
                });
            let dq = arm
                .velocity_limits()
                .map_or("-".to_string(), |v| format!("{:.4}", v[i]));
            format!("{lo:>10} {hi:>10} {dq:>9}")
        };
        let head = format!("{:>10} {:>10} {:>9}", "q_min", "q_max", "dq_max");
        match arm.geometry() {
            ChainGeometry::Dh { convention, links } => {
                let conv = match convention {
                    DhConvention::Standard => {
                        "standard DH: T_i = RotZ(θ_i) TransZ(d_i) TransX(a_i) RotX(α_i)"
                    }
                    DhConvention::Modified => {
                        "modified (Craig) DH: T_i = RotX(α_{i−1}) TransX(a_{i−1}) RotZ(θ_i) TransZ(d_i)"
                    }
                };
                put!("{}: {} revolute joints, {conv}", self.name, arm.dof());
                put!(
                    "{:>5} {:>9} {:>9} {:>10} {:>8} {head}",
                    "joint",
                    "a [m]",
                    "d [m]",
                    "α [rad]",
                    "offset"
                );
                for (i, l) in links.iter().enumerate() {
                    put!(
                        "{:>5} {:>9.4} {:>9.4} {:>10.4} {:>8.4} {}",
                        i + 1,
                        l.a,
                        l.d,
                        l.alpha,
                        l.offset,
                        limits(i)
                    );
                }
            }
            ChainGeometry::Joints(joints) => {
                put!(
                    "{}: {} revolute joints, URDF joints (origin xyz, rpy; axis)",
                    self.name,
                    arm.dof()
                );
                for (i, j) in joints.iter().enumerate() {
                    let t = j.origin.translation.vector;
                    let (r, p, y) = j.origin.rotation.euler_angles();
                    put!(
                        "{:>2} {:<14} xyz [{:.4} {:.4} {:.4}] rpy [{:.4} {:.4} {:.4}] axis [{:.3} {:.3} {:.3}] {}",
                        i + 1,
                        self.joint_names[i],
                        t.x,
                        t.y,
                        t.z,
                        r,
                        p,
                        y,
                        j.axis.x,
                        j.axis.y,
                        j.axis.z,
                        limits(i)
                    );
                }
                put!("   (limit columns: {head})");
            }
        }
        let frame = |iso: &nalgebra::Isometry3<f64>| {
            let t = iso.translation.vector;
            let (r, p, y) = iso.rotation.euler_angles();
            format!(
                "xyz [{:.4} {:.4} {:.4}] m, rpy [{:.4} {:.4} {:.4}] rad",
                t.x, t.y, t.z, r, p, y
            )
        };
        put!("base: {}", frame(&arm.base()));
        put!("tool ({}): {}", self.tool, frame(&arm.tool()));
        match &self.shapes {
            None => put!("collision shapes: none (nothing is checked for collisions)"),
            Some(shapes) => {
                let links = shapes.links();
                put!(
                    "collision shapes: {} bodies on {} links, {} pairs checked at a {:.1} mm margin",
                    shapes.bodies().len(),
                    links.len(),
                    shapes.model().pair_count(),
                    1e3 * shapes.margin()
                );
                let (skipped, checked): (Vec<_>, Vec<_>) = shapes
                    .left_out()
                    .iter()
                    .partition(|l| l.skipped_at(shapes.margin()));
                put!("pairs left out ({}):", skipped.len());
                for l in skipped {
                    put!("  {}", l.describe());
                }
                if !checked.is_empty() {
                    put!(
                        "pairs the description leaves out, checked ({}):",
                        checked.len()
                    );
                    for l in checked {
                        put!("  {}", l.describe());
                    }
                }
            }
        }
        out
    }
}

/// An inverse-kinematics target from `x,y,z` (metres, world frame) or a full pose
/// `x,y,z,qx,qy,qz,qw`; the sentence of an error names `--target`.
pub fn ik_target(values: &[f64]) -> Result<IkTarget, InputError> {
    if let Some(v) = values.iter().find(|v| !v.is_finite() || v.abs() > 1e6) {
        return Err(InputError(format!(
            "--target: values must be finite and at most 1e6 in magnitude (got {v:?})"
        )));
    }
    match values {
        [x, y, z] => Ok(IkTarget::Position(Vector3::new(*x, *y, *z))),
        [x, y, z, qx, qy, qz, qw] => {
            let quat = Quaternion::new(*qw, *qx, *qy, *qz);
            if quat.norm() < 1e-9 {
                return Err(InputError(
                    "--target: the quaternion has zero length".into(),
                ));
            }
            let rot = UnitQuaternion::from_quaternion(quat).to_rotation_matrix();
            Ok(IkTarget::Pose(IsometryMatrix3::from_parts(
                Translation3::new(*x, *y, *z),
                rot,
            )))
        }
        other => Err(InputError(format!(
            "--target: give x,y,z or x,y,z,qx,qy,qz,qw ({} values given)",
            other.len()
        ))),
    }
}

/// The largest joint value accepted (radians or metres): beyond it the angle means nothing.
pub const MAX_JOINT_VALUE: f64 = 1000.0;

/// A result and the file it was saved to (`imitate`, `promp fit`, `promp condition`), as
/// the command that saved it says it: `Serialize` for `--json`, `Display` for the text.
#[derive(Debug, Clone, Copy)]
pub struct Saved<'a, T> {
    /// The result.
    pub what: &'a T,
    /// The file it was saved to.
    pub out: &'a Path,
}

/// A result that says itself once saved: its JSON and its lines, naming the file.
pub trait SaysSaved {
    /// The JSON and the lines of `self` saved to `out`.
    fn said(&self, out: &Path) -> (serde_json::Value, Vec<String>);
}

impl<T: SaysSaved> serde::Serialize for Saved<'_, T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.what.said(self.out).0.serialize(s)
    }
}

impl<T: SaysSaved> std::fmt::Display for Saved<'_, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.what.said(self.out).1.join("\n"))
    }
}

/// The tool pose of `model` (named `robot` as the user gave it) at `q` (`cps-cli fk`): JSON
/// `{"robot", "q", "T", "position", "quaternion_xyzw"}`. `within_limits` refuses joint values
/// outside the limits.
pub fn tool_pose(
    model: &RobotModel,
    robot: &str,
    q: &[f64],
    within_limits: bool,
) -> Result<ToolPose, InputError> {
    let arm = &model.chain;
    if let Some((j, v)) = q
        .iter()
        .enumerate()
        .find(|(_, v)| v.abs() > MAX_JOINT_VALUE)
    {
        return Err(InputError(format!(
            "--q: joint {} is {v:?}; joint values must be at most {MAX_JOINT_VALUE} in magnitude",
            j + 1
        )));
    }
    if within_limits {
        arm.check_within_limits(q)
            .map_err(|e| InputError(format!("--q: {e}")))?;
    }
    let kin = |e: cps_kinematics::KinematicsError| InputError(e.to_string());
    let t = arm.fk_matrix(q).map_err(kin)?;
    let pose = arm.fk(q).map_err(kin)?;
    let quat = UnitQuaternion::from_rotation_matrix(&pose.rotation);
    let p = pose.translation.vector;
    Ok(ToolPose {
        robot: robot.to_string(),
        q: q.to_vec(),
        t: std::array::from_fn(|r| std::array::from_fn(|c| t[(r, c)])),
        position: [p.x, p.y, p.z],
        quaternion_xyzw: [quat.i, quat.j, quat.k, quat.w],
    })
}

/// `cps-cli fk`: the tool's pose at `q`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ToolPose {
    /// The robot, as the user named it.
    pub robot: String,
    /// The joint values.
    pub q: Vec<f64>,
    /// The pose as a homogeneous matrix, row by row.
    #[serde(rename = "T")]
    pub t: [[f64; 4]; 4],
    /// The tool point (world frame, m).
    pub position: [f64; 3],
    /// The orientation (x, y, z, w).
    pub quaternion_xyzw: [f64; 4],
}

/// The matrix, then the position and the quaternion.
impl std::fmt::Display for ToolPose {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "tool pose of {} (world frame, metres):", self.robot)?;
        for r in &self.t {
            writeln!(
                f,
                "  [{:>10.6} {:>10.6} {:>10.6} {:>10.6}]",
                r[0], r[1], r[2], r[3]
            )?;
        }
        let [x, y, z] = self.position;
        writeln!(f, "position   {x:.6} {y:.6} {z:.6}")?;
        let [qx, qy, qz, qw] = self.quaternion_xyzw;
        write!(f, "quaternion {qx:.6} {qy:.6} {qz:.6} {qw:.6} (x y z w)")
    }
}

/// `cps-cli ik`: joint values that reach the target, and how closely.
#[derive(Debug, Clone, serde::Serialize)]
pub struct JointSolution {
    /// The robot, as the user named it.
    pub robot: String,
    /// The joint values (rad, or m for a prismatic joint).
    pub q: Vec<f64>,
    /// The distance left to the target position (m).
    pub position_error: f64,
    /// The angle left to the target orientation (rad).
    pub rotation_error: f64,
    /// Iterations of the solver.
    pub iterations: usize,
    /// Restarts from other seeds.
    pub restarts: usize,
}

impl std::fmt::Display for JointSolution {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let q: Vec<String> = self.q.iter().map(|v| format!("{v:.6}")).collect();
        writeln!(f, "q = [{}] rad", q.join(", "))?;
        write!(
            f,
            "position error {:.3e} m, rotation error {:.3e} rad, {} iterations, {} restarts",
            self.position_error, self.rotation_error, self.iterations, self.restarts
        )
    }
}

/// Joint angles that put `model`'s tool (named `robot` as the user gave it) at `target`
/// (`x,y,z` or `x,y,z,qx,qy,qz,qw`) from `seed_q` (default: the ready configuration),
/// `cps-cli ik`: JSON `{"robot", "q", "position_error", "rotation_error", "iterations",
/// "restarts"}`.
pub fn joint_solution(
    model: &RobotModel,
    robot: &str,
    target: &[f64],
    seed_q: Option<&[f64]>,
) -> Result<JointSolution, InputError> {
    let arm = &model.chain;
    let target = ik_target(target)?;
    let seed = seed_q.unwrap_or(&model.ready);
    arm.check_within_limits(seed)
        .map_err(|e| InputError(format!("--seed-q: {e}")))?;
    let sol = cps_kinematics::solve_ik(arm, &target, seed, &cps_kinematics::IkConfig::default())
        .map_err(|e| InputError(e.to_string()))?;
    Ok(JointSolution {
        robot: robot.to_string(),
        q: sol.q,
        position_error: sol.position_error,
        rotation_error: sol.rotation_error,
        iterations: sol.iterations,
        restarts: sol.restarts,
    })
}

/// The built-in robot names.
pub const BUILT_IN: &str = "panda, fr3, ur3, crx10ia, puma560";

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    name: String,
    convention: Spanned<String>,
    #[serde(default)]
    ready: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    base: Option<Frame>,
    joint: Spanned<Vec<Spanned<Joint>>>,
    #[serde(default)]
    tools: std::collections::BTreeMap<String, Frame>,
    #[serde(default)]
    default_tool: Option<Spanned<String>>,
    #[serde(default)]
    cartesian: Option<Spanned<CartesianSection>>,
}

/// `[cartesian]`: `[velocity, acceleration, jerk]` limits of the tool point's translation
/// (m/s, m/s², m/s³), the tool's rotation (rad/s, rad/s², rad/s³) and the elbow (joint 3;
/// rad/s, rad/s², rad/s³).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CartesianSection {
    translation: [f64; 3],
    rotation: [f64; 3],
    elbow: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Joint {
    a: f64,
    d: f64,
    alpha: f64,
    #[serde(default)]
    offset: f64,
    q_min: f64,
    q_max: f64,
    dq_max: Option<f64>,
    /// Acceleration limit, rad/s².
    ddq_max: Option<f64>,
    /// Jerk limit, rad/s³.
    dddq_max: Option<f64>,
    /// Torque limit, N m.
    tau_max: Option<f64>,
    /// Torque-rate limit, N m/s.
    dtau_max: Option<f64>,
    /// The link's mass (kg), centre of mass in its frame (m) and inertia about it
    /// `[xx, xy, xz, yy, yz, zz]` (kg m²): all three or none.
    mass: Option<f64>,
    com: Option<[f64; 3]>,
    inertia: Option<[f64; 6]>,
}

/// A rigid transform in a robot or scene file.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Frame {
    #[serde(default)]
    xyz: [f64; 3],
    #[serde(default)]
    rpy: [f64; 3],
}

impl Frame {
    /// The transform, or a message if a value is not finite.
    pub fn isometry(&self) -> Result<Isometry3<f64>, String> {
        if !self.xyz.iter().chain(&self.rpy).all(|v| v.is_finite()) {
            return Err("`xyz` and `rpy` must be finite".into());
        }
        Ok(Isometry3::from_parts(
            Translation3::new(self.xyz[0], self.xyz[1], self.xyz[2]),
            UnitQuaternion::from_euler_angles(self.rpy[0], self.rpy[1], self.rpy[2]),
        ))
    }
}

/// A robot from URDF text: its joints' ranges, speeds and efforts (torque limits), and
/// its links' inertias when it gives them.
fn urdf_robot(
    text: &str,
    tip: Option<&str>,
) -> Result<(RobotModel, cps_kinematics::UrdfChain), cps_kinematics::KinematicsError> {
    let u = chain_from_urdf(text, tip)?;
    let model = RobotModel {
        name: u.name.clone(),
        ready: mid_range(&u.chain),
        tool: format!("link `{}`", u.tip_link),
        joint_names: u.joint_names.clone(),
        chain: u.chain.clone(),
        limits: JointLimits {
            torque: u.effort.clone(),
            ..JointLimits::default()
        },
        inertia: u.inertia.clone(),
        cartesian: None,
        shapes: None,
    };
    Ok((model, u))
}

/// The FANUC CRX-10iA (`crx10ia`): configs/robots/crx10ia.urdf, built in.
pub const CRX10IA_URDF: &str = include_str!("../../../configs/robots/crx10ia.urdf");

/// Its side file of limits, built in with it.
pub const CRX10IA_LIMITS: &str = include_str!("../../../configs/robots/crx10ia.limits.toml");

/// The limits a URDF has no tag for: `ROBOT.limits.toml` beside `ROBOT.urdf`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SideFile {
    ddq_max: Option<Spanned<Vec<f64>>>,
    dddq_max: Option<Spanned<Vec<f64>>>,
    tau_max: Option<Spanned<Vec<f64>>>,
    dtau_max: Option<Spanned<Vec<f64>>>,
    cartesian: Option<Spanned<CartesianSection>>,
}

/// The side file of a URDF robot at `path` (`text`): acceleration, jerk, torque (replacing
/// the URDF's efforts) and torque-rate limits per joint, and `[cartesian]`; each checked
/// with its place.
fn apply_side_file(model: &mut RobotModel, path: &Path, text: &str) -> Result<(), InputError> {
    let at = |span: std::ops::Range<usize>, m: String| {
        InputError(format!(
            "{}: {m}",
            cps_outcome::source::location(path, text, &span)
        ))
    };
    let file: SideFile = toml::from_str(text).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        at(span, e.message().to_string())
    })?;
    let n = model.chain.dof();
    let per_joint =
        |v: &Option<Spanned<Vec<f64>>>, key: &str| -> Result<Option<Vec<f64>>, InputError> {
            let Some(v) = v else { return Ok(None) };
            let values = v.get_ref();
            if values.len() != n || values.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
                return Err(at(
                    v.span(),
                    format!(
                        "`{key}` needs {n} finite values > 0, one per joint (got {})",
                        values.len()
                    ),
                ));
            }
            Ok(Some(values.clone()))
        };
    model.limits.acceleration = per_joint(&file.ddq_max, "ddq_max")?;
    model.limits.jerk = per_joint(&file.dddq_max, "dddq_max")?;
    if let Some(t) = per_joint(&file.tau_max, "tau_max")? {
        model.limits.torque = Some(t);
    }
    model.limits.torque_rate = per_joint(&file.dtau_max, "dtau_max")?;
    if let Some(c) = &file.cartesian {
        model.cartesian = Some(cartesian_limits(c).map_err(|m| at(c.span(), m))?);
    }
    Ok(())
}

/// `[cartesian]` checked: every value finite and > 0.
fn cartesian_limits(c: &Spanned<CartesianSection>) -> Result<CartesianLimits, String> {
    let v = c.get_ref();
    if v.translation
        .iter()
        .chain(&v.rotation)
        .chain(&v.elbow)
        .any(|x| !(x.is_finite() && *x > 0.0))
    {
        return Err("[cartesian] limits must be finite and > 0".into());
    }
    Ok(CartesianLimits {
        translation: v.translation,
        rotation: v.rotation,
        elbow: v.elbow,
    })
}

/// Loads `spec`: a built-in name, or a path ending in `.toml` or `.urdf`. `tool` picks a
/// tool point (built-in Panda: `hand` or `flange`; TOML: a `[tools.*]` name); `tip` picks
/// the URDF tip link.
pub fn load_robot(
    spec: &str,
    tool: Option<&str>,
    tip: Option<&str>,
) -> Result<RobotModel, InputError> {
    let lower = spec.to_ascii_lowercase();
    if lower.ends_with(".toml") || lower.ends_with(".urdf") {
        let path = Path::new(spec);
        let text = cps_outcome::source::read_text(
            path,
            cps_outcome::source::MAX_FILE_BYTES,
            "robot file",
        )?;
        if lower.ends_with(".urdf") {
            if tool.is_some() {
                return Err(InputError(
                    "--tool: a URDF robot ends at its tip link; choose it with --tip".into(),
                ));
            }
            let (mut model, urdf) = urdf_robot(&text, tip)
                .map_err(|e| InputError(format!("{}: {e}", path.display())))?;
            // Its links' shapes, from its `<collision>` elements (none: unchecked, said).
            if !urdf.collisions.is_empty() {
                let geometry = crate::collision::urdf_geometry(&urdf, path)?;
                model.shapes = Some(Arc::new(geometry.shapes()));
            }
            // The limits a URDF has no tag for, from `ROBOT.limits.toml` beside it.
            let side = path.with_extension("limits.toml");
            if side.is_file() {
                let text = cps_outcome::source::read_text(
                    &side,
                    cps_outcome::source::MAX_FILE_BYTES,
                    "limits file",
                )?;
                apply_side_file(&mut model, &side, &text)?;
            }
            return Ok(model);
        }
        if tip.is_some() {
            return Err(InputError("--tip applies to URDF robots only".into()));
        }
        return parse_robot_toml(path, &text, tool);
    }
    if tip.is_some() {
        return Err(InputError("--tip applies to URDF robots only".into()));
    }
    let names = |n: usize| (1..=n).map(|i| format!("joint{i}")).collect();
    match spec {
        "panda" | "fr3" => {
            let fr3_arm = spec == "fr3";
            let (t, words) = match tool.unwrap_or("hand") {
                "hand" => (PandaTool::HandTcp, "Franka Hand TCP"),
                "flange" => (PandaTool::Flange, "flange"),
                other => {
                    let arm = if fr3_arm { "FR3" } else { "Panda" };
                    return Err(InputError(format!(
                        "--tool: the {arm} has tools `hand` and `flange`, not `{other}`"
                    )));
                }
            };
            // Franka publishes no FR3 inertias or Cartesian limits of the same form: with
            // the hand, the FR3 carries MuJoCo Menagerie's inertias (franky-sim's model);
            // a bare flange carries none (the robot's own URDF has them).
            let (chain, limits, inertia, cartesian) = if fr3_arm {
                let inertia = (t == PandaTool::HandTcp).then(fr3_inertia);
                (fr3(t), fr3_limits(), inertia, None)
            } else {
                let (joint, cartesian) = panda_limits();
                (panda(t), joint, Some(panda_inertia()), Some(cartesian))
            };
            // franka_description's collision meshes, the hand's with the hand.
            let arm = if fr3_arm {
                crate::collision::FrankaArm::Fr3
            } else {
                crate::collision::FrankaArm::Panda
            };
            let geometry = crate::collision::franka_geometry(arm, t == PandaTool::HandTcp);
            Ok(RobotModel {
                name: spec.into(),
                chain,
                ready: cps_kinematics::robots::PANDA_READY.to_vec(),
                tool: words.into(),
                joint_names: names(7),
                limits,
                inertia,
                cartesian,
                shapes: Some(Arc::new(geometry.shapes())),
            })
        }
        "ur3" | "puma560" => {
            if let Some(t) = tool {
                return Err(InputError(format!(
                    "--tool: the built-in {spec} has only its flange, not `{t}`"
                )));
            }
            let ur = spec == "ur3";
            let chain = if ur { ur3() } else { puma560() };
            Ok(RobotModel {
                name: spec.into(),
                ready: vec![0.0; chain.dof()],
                joint_names: names(chain.dof()),
                chain,
                tool: "flange".into(),
                limits: if ur {
                    ur3_limits()
                } else {
                    JointLimits::default()
                },
                inertia: ur.then(ur3_inertia),
                cartesian: None,
                shapes: None,
            })
        }
        "crx10ia" => {
            if let Some(t) = tool {
                return Err(InputError(format!(
                    "--tool: the built-in crx10ia has only its flange, not `{t}`"
                )));
            }
            let (mut model, _) = urdf_robot(CRX10IA_URDF, None)
                .map_err(|e| InputError(format!("the built-in crx10ia: {e}")))?;
            apply_side_file(
                &mut model,
                Path::new("configs/robots/crx10ia.limits.toml"),
                CRX10IA_LIMITS,
            )?;
            model.ready = vec![0.0; 6];
            model.tool = "flange".into();
            Ok(model)
        }
        other => Err(InputError(format!(
            "--robot: unknown robot `{other}` (built in: {BUILT_IN}; or a .toml or .urdf file)"
        ))),
    }
}

/// The middle of each joint's range (0 without finite limits): a neutral IK seed.
fn mid_range(chain: &SerialChain) -> Vec<f64> {
    match chain.limits() {
        Some((lo, hi)) => lo
            .iter()
            .zip(hi)
            .map(|(l, h)| {
                if l.is_finite() && h.is_finite() {
                    0.5 * (l + h)
                } else {
                    0.0
                }
            })
            .collect(),
        None => vec![0.0; chain.dof()],
    }
}

/// The `[[joint]]`s' DH links, ranges, speed limits and inertias, each checked.
struct DhJoints {
    links: Vec<DhLink>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    dq: Vec<Option<f64>>,
    inertias: Vec<Option<LinkInertia>>,
}

fn dh_joints(
    joints: &[Spanned<Joint>],
    err: &dyn Fn(std::ops::Range<usize>, String) -> InputError,
) -> Result<DhJoints, InputError> {
    let mut links = Vec::new();
    let (mut lo, mut hi, mut dq) = (Vec::new(), Vec::new(), Vec::new());
    let mut inertias = Vec::new();
    for (i, j) in joints.iter().enumerate() {
        let v = j.get_ref();
        let bad = |m: String| err(j.span(), format!("joint {}: {m}", i + 1));
        if ![v.a, v.d, v.alpha, v.offset].iter().all(|x| x.is_finite()) {
            return Err(bad("`a`, `d`, `alpha` and `offset` must be finite".into()));
        }
        if !(v.q_min.is_finite() && v.q_max.is_finite() && v.q_min < v.q_max) {
            return Err(bad(format!(
                "limits need finite `q_min` < `q_max` (got {} .. {})",
                v.q_min, v.q_max
            )));
        }
        if let Some(s) = v.dq_max
            && !(s.is_finite() && s > 0.0)
        {
            return Err(bad(format!("`dq_max` must be finite and > 0 (got {s})")));
        }
        links.push(DhLink {
            a: v.a,
            d: v.d,
            alpha: v.alpha,
            offset: v.offset,
        });
        lo.push(v.q_min);
        hi.push(v.q_max);
        dq.push(v.dq_max);
        inertias.push(match (v.mass, v.com, v.inertia) {
            (None, None, None) => None,
            (Some(m), Some(c), Some(t)) => {
                Some(LinkInertia::new(m, c, t).map_err(|e| bad(format!("{e}")))?)
            }
            _ => {
                return Err(bad(
                    "give `mass`, `com` and `inertia` together, or none of them".into(),
                ));
            }
        });
    }
    Ok(DhJoints {
        links,
        lo,
        hi,
        dq,
        inertias,
    })
}

/// `chain` with the tool `tool` names, else the file's `default_tool`, else none (the
/// last joint's frame): the chain and the tool's name.
fn with_tool(
    mut chain: SerialChain,
    file: &File,
    tool: Option<&str>,
    path: &Path,
) -> Result<(SerialChain, String), InputError> {
    let wanted = tool
        .map(str::to_string)
        .or_else(|| file.default_tool.as_ref().map(|t| t.get_ref().clone()));
    let tool_name = match wanted {
        Some(name) => {
            let Some(frame) = file.tools.get(&name) else {
                let known: Vec<&str> = file.tools.keys().map(String::as_str).collect();
                return Err(InputError(format!(
                    "{}: no tool `{name}` (tools: {})",
                    path.display(),
                    if known.is_empty() {
                        "none".into()
                    } else {
                        known.join(", ")
                    }
                )));
            };
            let iso = frame
                .isometry()
                .map_err(|m| InputError(format!("{}: [tools.{name}] {m}", path.display())))?;
            chain = chain.with_tool(iso);
            name
        }
        None => "last joint frame".into(),
    };
    Ok((chain, tool_name))
}

/// Parses a TOML robot file (`path` only for messages); `tool` picks a `[tools.*]` entry.
pub fn parse_robot_toml(
    path: &Path,
    text: &str,
    tool: Option<&str>,
) -> Result<RobotModel, InputError> {
    let file: File = toml::from_str(text).map_err(|e| {
        let at = e
            .span()
            .map(|s| location(path, text, &s))
            .unwrap_or_else(|| path.display().to_string());
        InputError(format!("{at}: {}", e.message()))
    })?;
    let err = |span: std::ops::Range<usize>, msg: String| {
        InputError(format!("{}: {msg}", location(path, text, &span)))
    };
    let convention = match file.convention.get_ref().as_str() {
        "standard" => DhConvention::Standard,
        "modified" => DhConvention::Modified,
        other => {
            return Err(err(
                file.convention.span(),
                format!("`convention` must be \"standard\" or \"modified\", not \"{other}\""),
            ));
        }
    };
    let joints = file.joint.get_ref();
    if joints.is_empty() {
        return Err(err(
            file.joint.span(),
            "a robot needs at least one [[joint]]".into(),
        ));
    }
    let DhJoints {
        links,
        lo,
        hi,
        dq,
        inertias,
    } = dh_joints(joints, &err)?;
    // Every joint or none: a limit or an inertia given for some joints only is an error.
    let all_or_none = |what: &str, given: usize| -> Result<bool, InputError> {
        match given {
            0 => Ok(false),
            n if n == joints.len() => Ok(true),
            _ => Err(err(
                file.joint.span(),
                format!("give {what} for every joint or for none"),
            )),
        }
    };
    let per_joint =
        |what: &str, f: fn(&Joint) -> Option<f64>| -> Result<Option<Vec<f64>>, InputError> {
            let values: Vec<Option<f64>> = joints.iter().map(|j| f(j.get_ref())).collect();
            Ok(
                all_or_none(&format!("`{what}`"), values.iter().flatten().count())?
                    .then(|| values.into_iter().flatten().collect()),
            )
        };
    let limits = JointLimits {
        acceleration: per_joint("ddq_max", |j| j.ddq_max)?,
        jerk: per_joint("dddq_max", |j| j.dddq_max)?,
        torque: per_joint("tau_max", |j| j.tau_max)?,
        torque_rate: per_joint("dtau_max", |j| j.dtau_max)?,
    };
    limits
        .validate(joints.len())
        .map_err(|e| err(file.joint.span(), e.to_string()))?;
    let inertia = all_or_none(
        "`mass`, `com` and `inertia`",
        inertias.iter().flatten().count(),
    )?
    .then(|| inertias.into_iter().flatten().collect());
    let whole = 0..text.len();
    let in_file = |e: cps_kinematics::KinematicsError| err(whole.clone(), e.to_string());
    let mut chain = SerialChain::new(convention, links)
        .and_then(|c| c.with_limits(&lo, &hi))
        .map_err(in_file)?;
    match dq.iter().filter(|v| v.is_some()).count() {
        0 => {}
        n if n == dq.len() => {
            let dq: Vec<f64> = dq.iter().flatten().copied().collect();
            chain = chain.with_velocity_limits(&dq).map_err(in_file)?;
        }
        _ => {
            return Err(err(
                file.joint.span(),
                "give `dq_max` for every joint or for none".into(),
            ));
        }
    }
    if let Some(b) = &file.base {
        let iso = b
            .isometry()
            .map_err(|m| InputError(format!("{}: [base] {m}", path.display())))?;
        chain = chain.with_base(iso);
    }
    let (chain, tool_name) = with_tool(chain, &file, tool, path)?;
    let n = chain.dof();
    let ready = match &file.ready {
        Some(r) => {
            let q = r.get_ref();
            if q.len() != n || q.iter().any(|v| !v.is_finite()) {
                return Err(err(
                    r.span(),
                    format!("`ready` needs {n} finite joint values (got {})", q.len()),
                ));
            }
            q.clone()
        }
        None => mid_range(&chain),
    };
    let cartesian = match &file.cartesian {
        Some(c) => Some(cartesian_limits(c).map_err(|m| err(c.span(), m))?),
        None => None,
    };
    Ok(RobotModel {
        name: file.name,
        chain,
        ready,
        tool: tool_name,
        joint_names: (1..=n).map(|i| format!("joint{i}")).collect(),
        limits,
        inertia,
        cartesian,
        shapes: None,
    })
}
