//! Scene files (`configs/scenes/`): a robot placed in the world with its initial
//! configuration, named objects (way-point dummies), and obstacles: points with the
//! clearance a movement must keep, or shapes the robot must not touch.
//!
//! An `[[obstacle]]` is a point (`name`, `position`, `clearance`) or a shape: `name`,
//! `shape = "box" | "sphere" | "cylinder" | "capsule" | "mesh"`, `xyz` and `rpy` (its pose
//! in the world frame: metres, and radians as URDF's roll, pitch, yaw), `size = [sx, sy,
//! sz]` (a box's full edge lengths), `radius`, `length` (a cylinder's or a capsule's, about
//! its z axis), `file` (a mesh, STL, OBJ or COLLADA, relative to the scene file; collided
//! as its convex hull), `touch` (the links that may touch it: the link a robot stands on, the
//! fingers that press a table).
//!
//! The robot's own shapes and the shaped obstacles are what the guard checks every plan
//! against; `[robot] margin` (m) sets the clearance every other pair keeps. A scene whose
//! robot already touches an obstacle at its start (beyond what `touch` allows) is refused.

use std::path::Path;

use cps_kinematics::{IkConfig, IkSolution, IkTarget, KinematicsError, solve_ik};
use nalgebra::Vector3;
use serde::Deserialize;
use toml::Spanned;

use crate::robot_file::{Frame, RobotModel, load_robot};
use cps_outcome::InputError;
use cps_outcome::source::location;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    robot: RobotSection,
    #[serde(default)]
    object: Vec<Spanned<Object>>,
    #[serde(default)]
    obstacle: Vec<Spanned<ObstacleEntry>>,
}

/// One `[[obstacle]]` as a file gives it (see the module's text), read by
/// [`parse_obstacles`].
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleEntry {
    name: String,
    position: Option<[f64; 3]>,
    clearance: Option<f64>,
    shape: Option<String>,
    xyz: Option<[f64; 3]>,
    rpy: Option<[f64; 3]>,
    size: Option<[f64; 3]>,
    radius: Option<f64>,
    length: Option<f64>,
    file: Option<String>,
    #[serde(default)]
    touch: Vec<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotSection {
    model: String,
    tool: Option<String>,
    tip: Option<String>,
    initial_q: Spanned<Vec<f64>>,
    base: Option<Frame>,
    margin: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Object {
    name: String,
    position: [f64; 3],
}

/// A point obstacle of a scene (`[[obstacle]]`): movements learned in the scene keep
/// `clearance` from `position` (world frame, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstacle {
    /// Where it is.
    pub position: [f64; 3],
    /// The distance to keep (> 0).
    pub clearance: f64,
}

/// A loaded scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The robot, placed at the scene's base.
    pub robot: RobotModel,
    /// The initial joint configuration.
    pub initial_q: Vec<f64>,
    /// Named objects and their world positions, in file order.
    pub objects: Vec<(String, Vector3<f64>)>,
    /// Named point obstacles (`[[obstacle]]` with a `position`), in file order: movements
    /// learned in this scene keep their clearance.
    pub obstacles: Vec<(String, Obstacle)>,
    /// Obstacles with a shape (`[[obstacle]]` with a `shape`), in file order, world frame.
    pub shapes: Vec<cps_geometry::Obstacle>,
}

/// Reads a scene file; a relative robot file path is resolved against the scene's folder.
pub fn load_scene(path: &Path) -> Result<Scene, InputError> {
    let text =
        cps_outcome::source::read_text(path, cps_outcome::source::MAX_FILE_BYTES, "scene file")?;
    parse_scene(path, &text)
}

/// The thesis's scene, built in (the text of `configs/scenes/thesis.toml`).
pub const THESIS_SCENE: &str = include_str!("../../../configs/scenes/thesis.toml");

/// The thesis's scene with a Franka Research 3 (the text of `configs/scenes/fr3.toml`):
/// the same table, way points and tool, the base placed so the FR3's start configuration
/// (inside its range, unlike the thesis's) puts the tool at the same start point.
pub const FR3_SCENE: &str = include_str!("../../../configs/scenes/fr3.toml");

/// Parses scene text (`path` names it in messages and resolves relative robot files).
pub fn parse_scene(path: &Path, text: &str) -> Result<Scene, InputError> {
    let text = text.to_string();
    let file: File = toml::from_str(&text).map_err(|e| {
        let at = e
            .span()
            .map(|s| location(path, &text, &s))
            .unwrap_or_else(|| path.display().to_string());
        InputError(format!("{at}: {}", e.message()))
    })?;
    let r = &file.robot;
    let model = if r.model.contains('.') {
        let p = path.parent().unwrap_or(Path::new(".")).join(&r.model);
        p.to_string_lossy().into_owned()
    } else {
        r.model.clone()
    };
    let mut robot = load_robot(&model, r.tool.as_deref(), r.tip.as_deref())
        .map_err(|e| InputError(format!("{}: [robot] {e}", path.display())))?;
    if let Some(b) = &r.base {
        let iso = b
            .isometry()
            .map_err(|m| InputError(format!("{}: [robot.base] {m}", path.display())))?;
        robot.chain = robot.chain.clone().with_base(iso);
    }
    let q = r.initial_q.get_ref();
    robot.chain.check(q).map_err(|e| {
        InputError(format!(
            "{}: [robot] `initial_q`: {e}",
            location(path, &text, &r.initial_q.span())
        ))
    })?;
    let mut objects = Vec::new();
    for o in &file.object {
        let v = o.get_ref();
        let at = || location(path, &text, &o.span());
        if v.name.is_empty() || v.name.contains('/') {
            return Err(InputError(format!(
                "{}: object names are non-empty and without `/` (got `{}`)",
                at(),
                v.name
            )));
        }
        if objects.iter().any(|(n, _)| n == &v.name) {
            return Err(InputError(format!(
                "{}: a second object named `{}`",
                at(),
                v.name
            )));
        }
        if !v.position.iter().all(|x| x.is_finite()) {
            return Err(InputError(format!("{}: `position` must be finite", at())));
        }
        objects.push((v.name.clone(), Vector3::from(v.position)));
    }
    let taken: Vec<String> = objects.iter().map(|(n, _)| n.clone()).collect();
    let Obstacles {
        points: obstacles,
        shapes,
        allowed,
    } = parse_obstacles(path, &text, &file.obstacle, &taken)?;
    let margin = r.margin.as_ref().map(|m| *m.get_ref());
    let at_margin = || {
        r.margin.as_ref().map_or_else(
            || path.display().to_string(),
            |m| location(path, &text, &m.span()),
        )
    };
    if robot.shapes.is_none() && (!shapes.is_empty() || margin.is_some()) {
        return Err(InputError(format!(
            "{}: the robot `{}` has no collision geometry, so the scene's shaped obstacles and margin could not be checked (give a robot whose URDF has <collision> elements, or a built-in Franka)",
            at_margin(),
            robot.name
        )));
    }
    robot = robot
        .in_scene(shapes.clone(), allowed, margin)
        .map_err(|m| InputError(format!("{}: {m}", at_margin())))?;
    start_clear(&robot, q).map_err(|m| {
        InputError(format!(
            "{}: at the robot's `initial_q`, {m}",
            location(path, &text, &r.initial_q.span())
        ))
    })?;
    Ok(Scene {
        robot,
        initial_q: q.clone(),
        objects,
        obstacles,
        shapes,
    })
}

/// A file's `[[obstacle]]`s read: points, shapes, and the contacts their `touch` allows.
#[derive(Debug, Clone, Default)]
pub struct Obstacles {
    /// Point obstacles (`position`, `clearance`), in file order.
    pub points: Vec<(String, Obstacle)>,
    /// Shaped obstacles, in file order, world frame.
    pub shapes: Vec<cps_geometry::Obstacle>,
    /// (link, obstacle) pairs that may touch.
    pub allowed: Vec<(String, String)>,
}

/// Reads the `[[obstacle]]` entries of the file at `path` (its `text`, for places), whose
/// names must differ from each other and from `taken` (its objects'). Mesh files are
/// relative to `path`'s folder. Scene files and experiment files read them alike.
pub fn parse_obstacles(
    path: &Path,
    text: &str,
    entries: &[Spanned<ObstacleEntry>],
    taken: &[String],
) -> Result<Obstacles, InputError> {
    let mut obstacles: Vec<(String, Obstacle)> = Vec::new();
    let mut shapes: Vec<cps_geometry::Obstacle> = Vec::new();
    for o in entries {
        let v = o.get_ref();
        let at = || location(path, text, &o.span());
        if v.name.is_empty()
            || v.name.contains('/')
            || taken.contains(&v.name)
            || obstacles.iter().any(|(n, _)| n == &v.name)
            || shapes.iter().any(|s| s.name == v.name)
        {
            return Err(InputError(format!(
                "{}: obstacle names are non-empty, without `/`, and not an object's or another obstacle's (got `{}`)",
                at(),
                v.name
            )));
        }
        if v.shape.is_some() {
            shapes
                .push(shaped_obstacle(v, path).map_err(|m| InputError(format!("{}: {m}", at())))?);
            continue;
        }
        let (Some(position), Some(clearance)) = (v.position, v.clearance) else {
            return Err(InputError(format!(
                "{}: obstacle `{}` needs a `position` and a `clearance` (a point), or a `shape`",
                at(),
                v.name
            )));
        };
        if let Some(extra) = [
            ("xyz", v.xyz.is_some()),
            ("rpy", v.rpy.is_some()),
            ("size", v.size.is_some()),
            ("radius", v.radius.is_some()),
            ("length", v.length.is_some()),
            ("file", v.file.is_some()),
        ]
        .iter()
        .find(|(_, given)| *given)
        {
            return Err(InputError(format!(
                "{}: obstacle `{}` is a point (`position`): `{}` belongs to an obstacle with a `shape`",
                at(),
                v.name,
                extra.0
            )));
        }
        if !position.iter().all(|x| x.is_finite()) {
            return Err(InputError(format!("{}: `position` must be finite", at())));
        }
        if !(clearance.is_finite() && clearance > 0.0) {
            return Err(InputError(format!(
                "{}: `clearance` must be finite and > 0 (got {})",
                at(),
                clearance
            )));
        }
        obstacles.push((
            v.name.clone(),
            Obstacle {
                position,
                clearance,
            },
        ));
    }
    // The robot among the shaped obstacles, each with the links that may touch it.
    let mut allowed = Vec::new();
    for o in entries {
        let v = o.get_ref();
        if !v.touch.is_empty() && v.shape.is_none() {
            return Err(InputError(format!(
                "{}: obstacle `{}` is a point: only an obstacle with a `shape` can be touched",
                location(path, text, &o.span()),
                v.name
            )));
        }
        allowed.extend(v.touch.iter().map(|l| (l.clone(), v.name.clone())));
    }
    Ok(Obstacles {
        points: obstacles,
        shapes,
        allowed,
    })
}

/// Whether `robot` at `q` keeps every pair of its shapes its margin apart: the pair that
/// does not, in words, otherwise (a robot without shapes is clear).
pub fn start_clear(robot: &RobotModel, q: &[f64]) -> Result<(), String> {
    let Some(s) = &robot.shapes else {
        return Ok(());
    };
    let mut watch = cps_robot::ShapeWatch::new(s.clone(), robot.chain.dof());
    match watch.judge(&robot.chain, q, 0.0, 0) {
        Ok(None) => Ok(()),
        Ok(Some(c)) => Err(start_words(&c)),
        Err(e) => Err(e.to_string()),
    }
}

/// A collision at a scene's start, in words (no time: it is where the robot stands).
fn start_words(c: &cps_robot::Collision) -> String {
    if c.distance < 0.0 {
        format!(
            "`{}` and `{}` are {:.1} mm deep in each other: move the obstacle, or name the link in its `touch` if it stands on it",
            c.first,
            c.second,
            -1e3 * c.distance
        )
    } else {
        format!(
            "`{}` and `{}` are {:.1} mm apart, within the clearance margin of {:.1} mm",
            c.first,
            c.second,
            1e3 * c.distance,
            1e3 * c.margin
        )
    }
}

/// An `[[obstacle]]` with a `shape`: the keys its shape needs, and no others.
fn shaped_obstacle(v: &ObstacleEntry, path: &Path) -> Result<cps_geometry::Obstacle, String> {
    use cps_geometry::Shape;
    let shape = v.shape.as_deref().unwrap_or_default();
    let what = format!("obstacle `{}`", v.name);
    if v.position.is_some() || v.clearance.is_some() {
        return Err(format!(
            "{what} has a `shape`: give its place as `xyz` (and `rpy`), not `position` and `clearance`"
        ));
    }
    let needs: &[&str] = match shape {
        "box" => &["size"],
        "sphere" => &["radius"],
        "cylinder" | "capsule" => &["radius", "length"],
        "mesh" => &["file"],
        other => {
            return Err(format!(
                "{what}: shape `{other}` is not one of box, sphere, cylinder, capsule, mesh"
            ));
        }
    };
    let given = [
        ("size", v.size.is_some()),
        ("radius", v.radius.is_some()),
        ("length", v.length.is_some()),
        ("file", v.file.is_some()),
    ];
    if let Some((key, _)) = given.iter().find(|(k, g)| needs.contains(k) && !g) {
        return Err(format!("{what}: a {shape} needs `{key}`"));
    }
    if let Some((key, _)) = given.iter().find(|(k, g)| !needs.contains(k) && *g) {
        return Err(format!("{what}: a {shape} has no `{key}`"));
    }
    let xyz = v
        .xyz
        .ok_or_else(|| format!("{what} needs `xyz`, where it is"))?;
    let rpy = v.rpy.unwrap_or([0.0; 3]);
    if !xyz.iter().chain(&rpy).all(|x| x.is_finite()) {
        return Err(format!("{what}: `xyz` and `rpy` must be finite"));
    }
    if !xyz.iter().all(|x| x.abs() <= cps_geometry::MAX_EXTENT) {
        return Err(format!(
            "{what}: `xyz` places it {} m away; a scene lies within {} m of the robot's base",
            cps_files::number(xyz.iter().fold(0.0, |a: f64, x| a.max(x.abs())), 6),
            cps_geometry::MAX_EXTENT
        ));
    }
    let pose = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(xyz[0], xyz[1], xyz[2]),
        nalgebra::UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    );
    let geometry = match shape {
        "box" => Shape::cuboid(v.size.unwrap_or_default(), &what),
        "sphere" => Shape::sphere(v.radius.unwrap_or_default(), &what),
        "cylinder" => Shape::cylinder(
            v.radius.unwrap_or_default(),
            v.length.unwrap_or_default(),
            &what,
        ),
        "capsule" => Shape::capsule(
            v.radius.unwrap_or_default(),
            v.length.unwrap_or_default(),
            &what,
        ),
        _ => {
            let file = path
                .parent()
                .unwrap_or(Path::new("."))
                .join(v.file.as_deref().unwrap_or_default());
            let name = file.display().to_string();
            let hull = crate::collision::read_mesh(&file, [1.0; 3])
                .and_then(|(m, _)| m.hull(&name).map_err(|e| e.to_string()))?;
            Ok(Shape::Convex(std::sync::Arc::new(hull)))
        }
    }
    .map_err(|e| e.to_string())?;
    Ok(cps_geometry::Obstacle {
        name: v.name.clone(),
        pose,
        shape: geometry,
    })
}

/// Where a scene's tool starts and which of its objects the tool can reach
/// ([`Scene::reach`]).
#[derive(Debug)]
pub struct Reach {
    /// The robot's name.
    pub robot: String,
    /// Its tool point's name.
    pub tool_name: String,
    /// The tool position at the initial configuration, world frame.
    pub tool: Vector3<f64>,
    /// Initial joints outside their limits: (1-based joint, value, lower, upper).
    pub outside_limits: Vec<(usize, f64, f64, f64)>,
    /// Per object in file order: its name, position and the IK solution within the joint
    /// limits, or why there is none.
    pub objects: Vec<(String, Vector3<f64>, Result<IkSolution, KinematicsError>)>,
}

impl Reach {
    /// Whether every object is reachable.
    pub fn all_reachable(&self) -> bool {
        self.objects.iter().all(|o| o.2.is_ok())
    }
}

/// `{"robot", "tool_at_initial_q", "initial_q_outside_limits", "objects": [{"name",
/// "position", "reachable", "q" and "position_error", or "error"}]}`.
impl serde::Serialize for Reach {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let objects: Vec<_> = self
            .objects
            .iter()
            .map(|(name, p, r)| match r {
                Ok(q) => serde_json::json!({"name": name, "position": [p.x, p.y, p.z],
                    "reachable": true, "q": q.q, "position_error": q.position_error}),
                Err(e) => serde_json::json!({"name": name, "position": [p.x, p.y, p.z],
                    "reachable": false, "error": e.to_string()}),
            })
            .collect();
        let t = &self.tool;
        serde_json::json!({
            "robot": self.robot,
            "tool_at_initial_q": [t.x, t.y, t.z],
            "initial_q_outside_limits": self.outside_limits.iter().map(|o| o.0).collect::<Vec<_>>(),
            "objects": objects,
        })
        .serialize(s)
    }
}

/// The tool at the initial configuration, a note per joint outside its limits, then a line
/// per object: reachable (with the solution) or why not.
impl std::fmt::Display for Reach {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let t = &self.tool;
        write!(
            f,
            "{} ({}): tool at the initial configuration ({:.4}, {:.4}, {:.4}) m",
            self.robot, self.tool_name, t.x, t.y, t.z
        )?;
        for (j, v, lo, hi) in &self.outside_limits {
            write!(
                f,
                "\nnote: initial joint {j} = {v} lies outside its limits [{lo}, {hi}]; accepted as a start state"
            )?;
        }
        for (name, p, r) in &self.objects {
            write!(f, "\n{name:<4} ({:.3}, {:.3}, {:.3}): ", p.x, p.y, p.z)?;
            match r {
                Ok(s) => {
                    let q: Vec<_> = s.q.iter().map(|v| format!("{v:.3}")).collect();
                    let e = s.position_error;
                    write!(
                        f,
                        "reachable within limits (error {e:.1e} m), q = [{}]",
                        q.join(", ")
                    )?
                }
                Err(e) => write!(f, "NOT reachable: {e}")?,
            }
        }
        Ok(())
    }
}

impl Scene {
    /// The thesis's scene (`configs/scenes/thesis.toml`, built in).
    pub fn thesis() -> Result<Self, InputError> {
        parse_scene(Path::new("configs/scenes/thesis.toml"), THESIS_SCENE)
    }

    /// A built-in scene by name (`thesis`, `fr3`) or a scene file.
    pub fn named_or_file(word: &str) -> Result<Self, InputError> {
        match word {
            "thesis" => Self::thesis(),
            "fr3" => parse_scene(Path::new("configs/scenes/fr3.toml"), FR3_SCENE),
            path => load_scene(Path::new(path)),
        }
    }

    /// The robot's name as CoppeliaSim's scene names it (`Panda` for `panda`).
    pub fn sim_robot_name(&self) -> String {
        match self.robot.name.as_str() {
            "panda" => "Panda".to_string(),
            other => other.to_string(),
        }
    }

    /// The tool at the initial configuration and, for every object, an IK solution within
    /// the joint limits from the robot's ready pose (seeded restarts, seed 1).
    pub fn reach(&self) -> Result<Reach, KinematicsError> {
        let chain = &self.robot.chain;
        let tool = chain.fk(&self.initial_q)?.translation.vector;
        let config = IkConfig {
            seed: 1,
            ..IkConfig::default()
        };
        let q = &self.initial_q;
        let outside_limits = chain.limits().map_or(Vec::new(), |(lo, hi)| {
            (0..q.len())
                .filter(|&i| q[i] < lo[i] || q[i] > hi[i])
                .map(|i| (i + 1, q[i], lo[i], hi[i]))
                .collect()
        });
        let objects = self
            .objects
            .iter()
            .map(|(name, p)| {
                let r = solve_ik(chain, &IkTarget::Position(*p), &self.robot.ready, &config);
                (name.clone(), *p, r)
            })
            .collect();
        Ok(Reach {
            robot: self.robot.name.clone(),
            tool_name: self.robot.tool.clone(),
            tool,
            outside_limits,
            objects,
        })
    }
}
