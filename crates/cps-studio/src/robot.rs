//! The robot the studio shows: a scene's robot (the thesis's Panda by default), its pose
//! as points to draw (base, every joint's frame, the tool) and as the shapes the guard
//! checks (its links' collision hulls and the scene's obstacles, as triangles), and a
//! learned movement executed on it — the same reachability check, inverse controller and
//! collision check the pipelines use, with every near miss at its time.

use cps_dmp::Trajectory;
use cps_kinematics::SerialChain;
use cps_learn::{LearnError, RobotSetup, ViaPointTask, check_way_points, execute_trajectory};
use cps_robot::{KinematicRobot, Recording, StopToken};
use serde::Serialize;

/// Drawn poses per second of movement (the execution runs at the movement's dt).
const FRAMES_PER_SECOND: f64 = 25.0;

/// Pairs closer than this (m) are near misses the page colours (those within the robot's
/// clearance margin, which the guard would refuse, in another colour).
pub const NEAR_M: f64 = 0.02;

/// A shape to draw: its surface as triangles, in the frame that carries it.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeView {
    /// The link's URDF name, or the obstacle's scene name.
    pub name: String,
    /// The robot frame that carries it (0 the base, `k` the link joint `k` moves; an index
    /// into a pose's frames); None for an obstacle, whose corners are in the world frame.
    pub frame: Option<usize>,
    /// Corners, `x y z` after one another (m, in the frame).
    pub vertices: Vec<f32>,
    /// Triangles, three corner indices after one another, counter-clockwise from outside.
    pub triangles: Vec<u32>,
}

/// The robot's and the scene's shapes, as the guard checks them.
#[derive(Debug, Clone, Serialize)]
pub struct ShapesView {
    /// The robot's bodies (links; a link may have several).
    pub bodies: Vec<ShapeView>,
    /// The scene's obstacles.
    pub obstacles: Vec<ShapeView>,
    /// The clearance margin the guard keeps (m).
    pub margin: f64,
    /// The distance within which a pair is reported as a near miss (m).
    pub near: f64,
}

/// Two shapes closer than [`NEAR_M`] around one drawn pose.
#[derive(Debug, Clone, Serialize)]
pub struct NearView {
    /// A body (index into [`ShapesView::bodies`]).
    pub body: usize,
    /// The other body, if it is one.
    pub other_body: Option<usize>,
    /// The obstacle, if it is one (index into [`ShapesView::obstacles`]).
    pub obstacle: Option<usize>,
    /// Their smallest signed distance (m; negative: overlapping) over the executed samples
    /// the pose stands for.
    pub distance: f64,
}

/// The robot of a studio.
#[derive(Debug, Clone)]
pub struct StudioRobot {
    /// Its name (`panda`).
    pub name: String,
    /// Model, initial configuration, execution settings.
    pub setup: RobotSetup,
    /// Its joint names, limits and inertias (for the limit check and the exports).
    pub model: cps_movement::robot_file::RobotModel,
}

/// The robot at rest, for the page to draw before anything is learned.
#[derive(Debug, Clone, Serialize)]
pub struct RobotView {
    /// The robot's name.
    pub name: String,
    /// Joints.
    pub dof: usize,
    /// The points to draw at the initial configuration: base, each joint's frame origin,
    /// tool (world frame, metres).
    pub points: Vec<[f64; 3]>,
    /// Its shapes and the scene's (None: the robot has no collision geometry).
    pub shapes: Option<ShapesView>,
    /// Why nothing but the skeleton is drawn, when the robot has no shapes.
    pub shapes_note: Option<String>,
    /// The frames at the initial configuration: base and each link, each a world pose as
    /// 3 × 4 numbers (rotation rows, translation last in each row).
    pub pose: Vec<[f32; 12]>,
}

/// A learned movement executed on the robot.
#[derive(Debug, Clone, Serialize)]
pub struct RobotAnswer {
    /// Why the robot cannot execute the task: the first way point out of reach, with its
    /// distance to the reachable set (nothing is executed then).
    pub unreachable: Option<String>,
    /// Times of the drawn poses, seconds.
    pub t: Vec<f64>,
    /// The drawn poses: per time, the points of [`RobotView::points`].
    pub frames: Vec<Vec<[f64; 3]>>,
    /// The executed tool path at the control period.
    pub tool: Vec<[f64; 3]>,
    /// The executed tool's largest distance from its target (m).
    pub max_tracking_error_m: f64,
    /// Samples the controller did not reach within its iteration cap.
    pub unconverged: usize,
    /// The executed joint movement against every limit at 1 kHz, as `cps-cli limits
    /// check` reports it (`ok`, peak usages, violations).
    pub limit_usage: serde_json::Value,
    /// The same in words, one line per finding.
    pub limit_lines: Vec<String>,
    /// Per drawn pose: its frames, as [`RobotView::pose`] (empty without shapes).
    pub poses: Vec<Vec<[f32; 12]>>,
    /// Per drawn pose: the pairs closer than [`NEAR_M`] over the executed samples since the
    /// previous pose (empty without shapes).
    pub near: Vec<Vec<NearView>>,
    /// With `limits`: the guard's verdict on the executed movement at 1 kHz, the first
    /// pair closer than the margin in words (None: clear, or not checked).
    pub collision: Option<String>,
}

impl StudioRobot {
    /// The thesis's scene: the Panda placed as in its CoppeliaSim scene.
    pub fn thesis() -> Result<Self, String> {
        let scene = cps_movement::scene::Scene::thesis().map_err(|e| e.to_string())?;
        Ok(Self {
            name: scene.robot.name.clone(),
            setup: RobotSetup {
                chain: scene.robot.chain.clone(),
                initial_q: scene.initial_q,
                execution: cps_robot::ExecutionConfig::default(),
            },
            model: scene.robot,
        })
    }

    /// The robot at rest.
    pub fn view(&self) -> RobotView {
        let shapes = self.model.shapes.as_ref().map(|s| {
            let view = |name: &str,
                        frame,
                        pose: &nalgebra::Isometry3<f64>,
                        shape: &cps_geometry::Shape| {
                let surface = shape.surface();
                ShapeView {
                    name: name.to_string(),
                    frame,
                    vertices: surface
                        .vertices
                        .iter()
                        .flat_map(|v| {
                            let p = pose * nalgebra::Point3::from(*v);
                            [p.x as f32, p.y as f32, p.z as f32]
                        })
                        .collect(),
                    triangles: surface.triangles.concat(),
                }
            };
            ShapesView {
                bodies: s
                    .bodies()
                    .iter()
                    .map(|b| view(&b.link, Some(b.frame), &b.origin, &b.shape))
                    .collect(),
                obstacles: s
                    .obstacles()
                    .iter()
                    .map(|o| view(&o.name, None, &o.pose, &o.shape))
                    .collect(),
                margin: s.margin(),
                near: NEAR_M,
            }
        });
        RobotView {
            name: self.name.clone(),
            dof: self.setup.chain.dof(),
            points: points(&self.setup.chain, &self.setup.initial_q),
            shapes_note: self.model.shapes_note(),
            shapes,
            pose: frames(&self.setup.chain, &self.setup.initial_q),
        }
    }

    /// Checks that the task's way points are reachable, then executes `traj` from the
    /// initial configuration on the in-process robot, stepped at the movement's `dt`,
    /// and, with `limits`, checks the executed movement against every limit at 1 kHz.
    pub fn execute(
        &self,
        task: &ViaPointTask,
        traj: &Trajectory,
        limits: bool,
    ) -> Result<RobotAnswer, String> {
        let mut answer = RobotAnswer {
            unreachable: None,
            t: Vec::new(),
            frames: Vec::new(),
            tool: Vec::new(),
            max_tracking_error_m: 0.0,
            unconverged: 0,
            limit_usage: serde_json::Value::Null,
            limit_lines: Vec::new(),
            poses: Vec::new(),
            near: Vec::new(),
            collision: None,
        };
        match check_way_points(task, &self.setup) {
            Ok(_) => {}
            Err(e @ LearnError::Unreachable { .. }) => {
                answer.unreachable = Some(e.to_string());
                return Ok(answer);
            }
            Err(e) => return Err(e.to_string()),
        }
        let dt = task.dmp.dt;
        let rec = self.run(traj, dt)?;
        if limits {
            let usage =
                cps_movement::limits::check_samples(&self.model, &self.joints(&rec), 1000.0)
                    .map_err(|e| e.to_string())?;
            answer.limit_usage = usage.json();
            answer.limit_lines = usage.lines();
            if self.model.shapes.is_some() {
                answer.collision =
                    cps_movement::collide::first_collision(&self.model, &self.joints(&rec), 1000.0)
                        .map_err(|e| e.to_string())?
                        .map(|c| c.to_string());
            }
        }
        let every = ((1.0 / FRAMES_PER_SECOND) / dt).round().max(1.0) as usize;
        let mut near = Near::new(self.model.shapes.as_deref(), self.setup.chain.dof());
        for (k, q) in rec.q.iter().enumerate() {
            near.add(&self.setup.chain, q);
            if k % every == 0 || k + 1 == rec.q.len() {
                answer.t.push(k as f64 * dt);
                answer.frames.push(points(&self.setup.chain, q));
                if near.walk.is_some() {
                    answer.poses.push(frames(&self.setup.chain, q));
                    answer.near.push(near.take());
                }
            }
        }
        answer.tool = rec.position.clone();
        answer.max_tracking_error_m = rec.max_position_error();
        answer.unconverged = rec.unconverged;
        Ok(answer)
    }
}

impl StudioRobot {
    /// Executes `traj` from the initial configuration, stepped every `dt`.
    fn run(&self, traj: &Trajectory, dt: f64) -> Result<Recording, String> {
        let mut robot = KinematicRobot::new(self.setup.chain.clone(), &self.setup.initial_q, dt)
            .map_err(|e| e.to_string())?;
        execute_trajectory(&mut robot, &self.setup, traj, &StopToken::new())
            .map_err(|e| e.to_string())
    }

    /// The executed joints as a named joint trajectory.
    fn joints(&self, rec: &Recording) -> cps_movement::limits::JointTrajectory {
        cps_movement::limits::JointTrajectory {
            names: self.model.joint_names.clone(),
            times: rec.time.clone(),
            q: rec.q.clone(),
        }
    }

    /// `traj` executed and exported for ROS 2 and viewers (`ros2-yaml`, `mcap`,
    /// `csv-1khz`, as `cps-cli export`): the file's name suffix, content type and bytes.
    pub fn export(
        &self,
        traj: &Trajectory,
        dt: f64,
        format: &str,
    ) -> Result<(String, Vec<u8>), String> {
        use cps_movement::export::{ExportFormat, ExportOptions, export_samples};
        let format = ExportFormat::parse(format)?;
        let rec = self.run(traj, dt)?;
        let e = export_samples(
            &self.model,
            &self.joints(&rec),
            format,
            &ExportOptions::default(),
        )
        .map_err(|e| e.0)?;
        Ok((format.file_name().to_string(), e.bytes))
    }
}

/// The closest approach of every near pair over the samples since it was last taken.
struct Near {
    frames: Vec<nalgebra::Isometry3<f64>>,
    /// The samples walked as the guard walks a plan: pairs within [`NEAR_M`] exactly,
    /// the others only when their motion could have closed the gap.
    walk: Option<cps_geometry::PathCheck>,
    /// Per pair: its smallest distance so far (infinite when not near).
    closest: Vec<f64>,
}

impl Near {
    fn new(shapes: Option<&cps_robot::Shapes>, dof: usize) -> Self {
        Near {
            frames: Vec::with_capacity(dof + 1),
            walk: shapes.map(|s| cps_geometry::PathCheck::new(s.model().clone(), NEAR_M)),
            closest: vec![f64::INFINITY; shapes.map_or(0, |s| s.model().pair_count())],
        }
    }

    fn add(&mut self, chain: &SerialChain, q: &[f64]) {
        let Some(walk) = self.walk.as_mut() else {
            return;
        };
        if chain.frames_into(q, &mut self.frames).is_err() {
            return;
        }
        walk.step(&self.frames);
        for c in walk.near() {
            let d = &mut self.closest[c.pair];
            *d = d.min(c.separation.distance);
        }
    }

    fn take(&mut self) -> Vec<NearView> {
        let Some(walk) = &self.walk else {
            return Vec::new();
        };
        let mut out = Vec::new();
        for (p, d) in self.closest.iter_mut().enumerate() {
            if d.is_finite() {
                let (body, other) = walk.model().pair(p);
                let (other_body, obstacle) = match other {
                    cps_geometry::Other::Body(j) => (Some(j), None),
                    cps_geometry::Other::Obstacle(k) => (None, Some(k)),
                };
                out.push(NearView {
                    body,
                    other_body,
                    obstacle,
                    distance: *d,
                });
                *d = f64::INFINITY;
            }
        }
        out
    }
}

/// The base's and every link's world pose at `q`, each as 3 × 4 numbers, row by row.
fn frames(chain: &SerialChain, q: &[f64]) -> Vec<[f32; 12]> {
    let mut out = Vec::new();
    if chain.frames_into(q, &mut out).is_err() {
        return Vec::new();
    }
    out.iter()
        .map(|f| {
            let m = f.to_homogeneous();
            let mut a = [0f32; 12];
            for r in 0..3 {
                for c in 0..4 {
                    // A tenth of a millimetre (or of a milliradian): what a view shows, in
                    // a few characters of JSON.
                    a[4 * r + c] = ((m[(r, c)] * 1e4).round() / 1e4) as f32;
                }
            }
            a
        })
        .collect()
}

/// Base, joint frame origins, tool: the robot's skeleton at `q`.
fn points(chain: &SerialChain, q: &[f64]) -> Vec<[f64; 3]> {
    let b = chain.base().translation.vector;
    let mut out = vec![[b.x, b.y, b.z]];
    if let Ok(pose) = chain.fk_frames(q) {
        for f in &pose.link_frames {
            let p = f.translation.vector;
            out.push([p.x, p.y, p.z]);
        }
        let p = pose.tool.translation.vector;
        out.push([p.x, p.y, p.z]);
    }
    out
}
