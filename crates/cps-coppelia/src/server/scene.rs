//! The stand-in's scene and its side of the remote API, without the network: a robot
//! (joints set kinematically, the tip by forward kinematics, optionally following an IK
//! target), dummies, simulation time and each client's stepping, and [`handle`]: one
//! CBOR request in, one reply out.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use cps_kinematics::SerialChain;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use super::log::LogBuffer;
use crate::codec::{self, Value};
use crate::executor::{self, Run};

/// The robot and objects the server starts with.
#[derive(Debug, Clone)]
pub struct SceneSetup {
    /// The robot's name: objects are `/<name>`, `/<name>_joint1..n`, `/<name>_tip`.
    pub robot_name: String,
    /// The robot's chain, placed at its base in the world, ending at its tool point.
    pub chain: SerialChain,
    /// Initial joint positions.
    pub initial_q: Vec<f64>,
    /// Named dummies and their world positions (way points).
    pub dummies: Vec<(String, [f64; 3])>,
    /// Simulation time step in seconds (CoppeliaSim's default is 0.05).
    pub dt: f64,
    /// Make the tip follow the IK target `/<name>_target` at every simulation step, as
    /// CoppeliaSim's IK does in the thesis's scene (position constraints, damped least
    /// squares within the joint limits, up to 10 iterations per step). Off: the joints move
    /// only when set.
    pub ik_following: bool,
    /// Wall time each simulation step takes (the server sleeps it, without spinning), to
    /// stand in for a simulator's physics: CoppeliaSim takes ≈ 5–8 ms a step with
    /// dynamics. Zero: as fast as the kinematics.
    pub step_cost: std::time::Duration,
    /// The scene has cps's script object `/<name>/cpsExecutor`, which executes a whole
    /// joint-target sequence and records it ([`crate::executor`]). Off: a scene without
    /// it, where clients fall back to stepping one call at a time.
    pub script: bool,
}

#[derive(Debug, Clone)]
enum Kind {
    Base,
    Joint(usize),
    Tip,
    Dummy(Isometry3<f64>),
    /// cps's scene script (`cpsExecutor`).
    Script,
}

#[derive(Debug, Clone)]
struct Object {
    alias: String,
    kind: Kind,
}

#[derive(Debug)]
struct ClientState {
    /// The last request from this client (its lease runs from here).
    last_seen: Instant,
    stepping: i64,
    waiting: bool,
    /// A `sim.testCB` in progress: the client's callback is called until `calls` is 0.
    callback: Option<PendingCallback>,
}

impl Default for ClientState {
    fn default() -> Self {
        Self {
            last_seen: Instant::now(),
            stepping: 0,
            waiting: false,
            callback: None,
        }
    }
}

/// Clients (uuids) remembered at once; beyond it the longest-silent one is forgotten.
const MAX_CLIENTS: usize = 1024;
/// Objects in the scene at once (`sim.createDummy` refuses beyond it).
const MAX_OBJECTS: usize = 100_000;
/// Largest coordinate accepted for a position (metres) and joint value (rad or m).
const MAX_COORDINATE: f64 = 1e6;

/// CoppeliaSim's `sim.testCB(a, cb, b, iterations)`: calls `cb(a, b)` iterations + 1
/// times through the client and returns the last result.
#[derive(Debug)]
struct PendingCallback {
    name: String,
    args: Vec<Value>,
    calls: u32,
}

pub(super) struct Sim {
    /// Messages of `sim.addLog`, for the server's owner to print.
    pub(super) log: Arc<LogBuffer>,
    setup: SceneSetup,
    q: Vec<f64>,
    objects: HashMap<i64, Object>,
    next_handle: i64,
    running: bool,
    steps: u64,
    clients: HashMap<String, ClientState>,
    lease: Duration,
    /// The sequence the scene script executes, and since when (and from which step) the
    /// simulation has run freely through it.
    run: Option<Run>,
    free_since: Option<(Instant, usize)>,
}

type Reply = Result<Vec<Value>, String>;

impl Sim {
    pub(super) fn new(setup: SceneSetup, lease: Duration) -> Self {
        let mut objects = HashMap::new();
        let name = setup.robot_name.clone();
        objects.insert(
            16,
            Object {
                alias: name.clone(),
                kind: Kind::Base,
            },
        );
        for j in 0..setup.chain.dof() {
            objects.insert(
                17 + j as i64,
                Object {
                    alias: format!("{name}_joint{}", j + 1),
                    kind: Kind::Joint(j),
                },
            );
        }
        let tip = 17 + setup.chain.dof() as i64;
        objects.insert(
            tip,
            Object {
                alias: format!("{name}_tip"),
                kind: Kind::Tip,
            },
        );
        // The IK target, where the tip is at the start (CoppeliaSim's `/Panda_target`).
        let tip_pose = tip_at(&setup.chain, &setup.initial_q);
        objects.insert(
            tip + 1,
            Object {
                alias: format!("{name}_target"),
                kind: Kind::Dummy(tip_pose),
            },
        );
        if setup.script {
            objects.insert(
                tip + 2,
                Object {
                    alias: executor::SCRIPT_ALIAS.into(),
                    kind: Kind::Script,
                },
            );
        }
        let mut next = 100;
        for (alias, p) in &setup.dummies {
            objects.insert(
                next,
                Object {
                    alias: alias.clone(),
                    kind: Kind::Dummy(Isometry3::translation(p[0], p[1], p[2])),
                },
            );
            next += 1;
        }
        Self {
            log: Arc::default(),
            q: setup.initial_q.clone(),
            setup,
            objects,
            next_handle: next,
            running: false,
            steps: 0,
            clients: HashMap::new(),
            lease,
            run: None,
            free_since: None,
        }
    }

    /// Records a request from `uuid` and forgets clients whose lease ran out, so a client
    /// that enabled stepping and died does not hold the simulation for the others.
    fn touch(&mut self, uuid: &str) {
        let now = Instant::now();
        let lease = self.lease;
        self.clients
            .retain(|_, c| now.saturating_duration_since(c.last_seen) <= lease);
        if !self.clients.contains_key(uuid)
            && self.clients.len() >= MAX_CLIENTS
            && let Some(oldest) = self
                .clients
                .iter()
                .min_by_key(|(_, c)| c.last_seen)
                .map(|(k, _)| k.clone())
        {
            self.clients.remove(&oldest);
        }
        self.clients.entry(uuid.to_string()).or_default().last_seen = now;
    }

    fn time(&self) -> f64 {
        self.steps as f64 * self.setup.dt
    }

    fn pose(&self, h: i64) -> Result<Isometry3<f64>, String> {
        let o = self.objects.get(&h).ok_or("Object does not exist.")?;
        Ok(match &o.kind {
            Kind::Base => self.setup.chain.base(),
            Kind::Joint(j) => {
                let frames = self
                    .setup
                    .chain
                    .fk_frames(&self.q)
                    .map_err(|e| e.to_string())?;
                let f = frames.link_frames[*j];
                Isometry3::from_parts(
                    f.translation,
                    UnitQuaternion::from_rotation_matrix(&f.rotation),
                )
            }
            Kind::Tip => {
                let f = self.setup.chain.fk(&self.q).map_err(|e| e.to_string())?;
                Isometry3::from_parts(
                    f.translation,
                    UnitQuaternion::from_rotation_matrix(&f.rotation),
                )
            }
            Kind::Dummy(p) => *p,
            Kind::Script => self.setup.chain.base(),
        })
    }

    fn relative(&self, h: i64, rel: i64) -> Result<Isometry3<f64>, String> {
        let p = self.pose(h)?;
        if rel == -1 {
            Ok(p)
        } else {
            Ok(self.pose(rel)?.inverse() * p)
        }
    }

    fn set_pose(&mut self, h: i64, pose: Isometry3<f64>, rel: i64) -> Result<(), String> {
        let world = if rel == -1 {
            pose
        } else {
            self.pose(rel)? * pose
        };
        match self.objects.get_mut(&h).map(|o| &mut o.kind) {
            Some(Kind::Dummy(p)) => {
                *p = world;
                Ok(())
            }
            Some(_) => Err(
                "the stand-in server moves dummies only; move the robot through its joints".into(),
            ),
            None => Err("Object does not exist.".into()),
        }
    }

    fn find(&self, path: &str) -> Option<i64> {
        let name = path.trim_start_matches('/').rsplit('/').next()?;
        let name = name.split(['[', '{']).next()?;
        self.objects
            .iter()
            .filter(|(_, o)| o.alias == name)
            .map(|(h, _)| *h)
            .min()
    }

    /// Advances the simulation when it runs freely (no client stepping): one step per
    /// request, or, while the scene script executes a sequence, every step the wall time
    /// since the simulation was released allows at the step cost (all of them at zero
    /// cost), as a free-running simulator would have taken meanwhile.
    fn tick(&mut self) {
        if !(self.running && self.clients.values().all(|c| c.stepping == 0)) {
            self.free_since = None;
            return;
        }
        let Some(run) = self.run.as_ref().filter(|r| r.next_target().is_some()) else {
            self.advance();
            return;
        };
        let done = run.done();
        let (since, from) = *self.free_since.get_or_insert((Instant::now(), done));
        let remaining = run.total() - done;
        let due = if self.setup.step_cost.is_zero() {
            remaining
        } else {
            let elapsed = since.elapsed().as_secs_f64() / self.setup.step_cost.as_secs_f64();
            ((elapsed as usize).saturating_sub(done - from)).min(remaining)
        };
        for _ in 0..due {
            self.step_once();
        }
    }

    /// One simulation step, taking its wall time: the clock advances and, with IK
    /// following, the joints move the tip towards the IK target.
    fn advance(&mut self) {
        if !self.setup.step_cost.is_zero() {
            std::thread::sleep(self.setup.step_cost);
        }
        self.step_once();
    }

    /// One simulation step without its wall time: the scene script commands its next row
    /// (actuation), the clock advances, IK follows its target, the script records
    /// (sensing).
    fn step_once(&mut self) {
        if let Some(row) = self.run.as_ref().and_then(Run::next_target) {
            self.q.copy_from_slice(row);
        }
        self.steps += 1;
        if self.setup.ik_following {
            self.follow_target();
        }
        if self.run.as_ref().is_some_and(|r| r.next_target().is_some()) {
            let pose = tip_at(&self.setup.chain, &self.q);
            let time = self.time();
            if let Some(run) = self.run.as_mut() {
                run.record(time, &self.q, &pose);
            }
        }
    }

    /// `sim.callScriptFunction(name, script, ...)` (or, as in the newest calltips,
    /// `(script, name, ...)`) for cps's scene script.
    fn call_script(&mut self, args: &[Value]) -> Reply {
        let (name, handle) = match (args.first(), args.get(1)) {
            (Some(a), Some(b)) => match (codec::as_text(a), codec::as_text(b)) {
                (Some(name), None) => (name, codec::as_i64(b)),
                (None, Some(name)) => (name, codec::as_i64(a)),
                _ => {
                    return Err(
                        "arguments 1 and 2 must be a function name and a script handle".into(),
                    );
                }
            },
            _ => {
                return Err("arguments 1 and 2 must be a function name and a script handle".into());
            }
        };
        let is_script = handle
            .and_then(|h| self.objects.get(&h))
            .is_some_and(|o| matches!(o.kind, Kind::Script));
        if !is_script {
            return Err("Invalid script handle.".into());
        }
        if !self.running {
            return Err(
                "script is not initialized: simulation scripts run only while the simulation runs"
                    .into(),
            );
        }
        match name.as_str() {
            executor::LOAD => {
                let run = Run::load(self.setup.chain.dof(), &args[2..], MAX_COORDINATE)?;
                let n = run.total();
                self.run = Some(run);
                self.free_since = None;
                Ok(vec![codec::int(n as i64)])
            }
            executor::RESULT => match &self.run {
                Some(run) => Ok(vec![run.result()]),
                None => Err("cpsResult(): no sequence loaded (call cpsLoad first)".into()),
            },
            executor::STOP => match &mut self.run {
                Some(run) => {
                    run.stop();
                    Ok(vec![run.result()])
                }
                None => Err("cpsStop(): no sequence loaded (call cpsLoad first)".into()),
            },
            other => Err(format!(
                "Failed calling script function: {other} does not exist in {}.",
                executor::SCRIPT_ALIAS
            )),
        }
    }

    fn follow_target(&mut self) {
        let name = format!("{}_target", self.setup.robot_name);
        let Some(target) = self.objects.values().find_map(|o| match &o.kind {
            Kind::Dummy(p) if o.alias == name => Some(*p),
            _ => None,
        }) else {
            return;
        };
        // Position constraints only, as the IK in the thesis's scene.
        let goal = cps_kinematics::IkTarget::Position(target.translation.vector);
        let config = cps_kinematics::controllers::ControllerConfig::default();
        for _ in 0..10 {
            let Ok(step) = cps_kinematics::controllers::control_step(
                &self.setup.chain,
                &self.q,
                &goal,
                self.setup.dt,
                &config,
            ) else {
                return;
            };
            if step.position_error < 1e-9 {
                return;
            }
            for (q, d) in self.q.iter_mut().zip(&step.dq) {
                *q += d;
            }
        }
    }

    // Long on purpose (over 150 lines): the remote API's dispatch table, one short arm per
    // function CoppeliaSim's client calls.
    fn call(&mut self, uuid: &str, func: &str, args: &[Value]) -> Reply {
        let int = |i: usize| {
            args.get(i)
                .and_then(codec::as_i64)
                .ok_or(format!("argument {} must be an integer", i + 1))
        };
        let num = |i: usize| {
            args.get(i)
                .and_then(codec::as_f64)
                .ok_or(format!("argument {} must be a number", i + 1))
        };
        let vec = |i: usize, n: usize| {
            args.get(i)
                .and_then(codec::as_f64_vec)
                .filter(|v| v.len() == n)
                .ok_or(format!("argument {} must be a table of {n} numbers", i + 1))
                .and_then(|v| {
                    if v.iter().all(|x| x.is_finite() && x.abs() <= MAX_COORDINATE) {
                        Ok(v)
                    } else {
                        Err(format!(
                            "argument {} must hold finite numbers of magnitude at most {MAX_COORDINATE:e}",
                            i + 1
                        ))
                    }
                })
        };
        let rel = |i: usize| {
            args.get(i).map_or(Ok(-1), |v| {
                codec::as_i64(v).ok_or(format!("argument {} must be an integer", i + 1))
            })
        };
        // Setters: 4.6+ order (handle, value, relativeTo) when argument 2 is a table, the
        // old order (handle, relativeTo, value) otherwise.
        let new_order = || matches!(args.get(1).map(codec::untag), Some(Value::Array(_)));
        let none = Ok(vec![]);
        match func {
            "zmqRemoteApi.require" => match args.first().and_then(codec::as_text).as_deref() {
                Some("sim") => none,
                Some(other) => Err(format!(
                    "module '{other}' not found (the stand-in server provides 'sim')"
                )),
                None => Err("argument 1 must be a string".into()),
            },
            "zmqRemoteApi.info" => Ok(vec![info()]),
            "sim.addLog" => {
                let verbosity = int(0)?;
                let message = args
                    .get(1)
                    .and_then(codec::as_text)
                    .ok_or("argument 2 must be a string")?;
                self.log.push(verbosity, &message);
                none
            }
            "sim.getObject" => {
                let path = args
                    .first()
                    .and_then(codec::as_text)
                    .ok_or("argument 1 must be a string")?;
                self.find(&path)
                    .map(|h| vec![codec::int(h)])
                    .ok_or_else(|| "Object does not exist.".into())
            }
            "sim.getObjectAlias" => {
                let h = int(0)?;
                let o = self.objects.get(&h).ok_or("Object does not exist.")?;
                Ok(vec![codec::text(&o.alias)])
            }
            "sim.setObjectAlias" => {
                let h = int(0)?;
                let alias = args
                    .get(1)
                    .and_then(codec::as_text)
                    .ok_or("argument 2 must be a string")?;
                self.objects
                    .get_mut(&h)
                    .ok_or("Object does not exist.")?
                    .alias = alias;
                none
            }
            "sim.getJointPosition" => match self.objects.get(&int(0)?).map(|o| &o.kind) {
                Some(Kind::Joint(j)) => Ok(vec![Value::Float(self.q[*j])]),
                Some(_) => Err("object is not a joint".into()),
                None => Err("Object does not exist.".into()),
            },
            "sim.setJointPosition" | "sim.setJointTargetPosition" => {
                let (h, v) = (int(0)?, num(1)?);
                if !(v.is_finite() && v.abs() <= MAX_COORDINATE) {
                    return Err(format!(
                        "argument 2 must be a finite joint value of magnitude at most {MAX_COORDINATE:e}"
                    ));
                }
                match self.objects.get(&h).map(|o| o.kind.clone()) {
                    Some(Kind::Joint(j)) => {
                        self.q[j] = v;
                        none
                    }
                    Some(_) => Err("object is not a joint".into()),
                    None => Err("Object does not exist.".into()),
                }
            }
            "sim.getObjectPosition" => {
                let p = self.relative(int(0)?, rel(1)?)?.translation.vector;
                Ok(vec![codec::floats(&[p.x, p.y, p.z])])
            }
            "sim.getObjectQuaternion" => {
                let q = self.relative(int(0)?, rel(1)?)?.rotation;
                Ok(vec![codec::floats(&[q.i, q.j, q.k, q.w])])
            }
            "sim.getObjectPose" => {
                let p = self.relative(int(0)?, rel(1)?)?;
                let (t, q) = (p.translation.vector, p.rotation);
                Ok(vec![codec::floats(&[t.x, t.y, t.z, q.i, q.j, q.k, q.w])])
            }
            "sim.getObjectMatrix" => {
                let m = self.relative(int(0)?, rel(1)?)?.to_homogeneous();
                let v: Vec<f64> = (0..3)
                    .flat_map(|r| (0..4).map(move |c| (r, c)))
                    .map(|(r, c)| m[(r, c)])
                    .collect();
                Ok(vec![codec::floats(&v)])
            }
            "sim.setObjectPosition" => {
                let h = int(0)?;
                // 4.6+ order (h, pos, rel); the old order (h, rel, pos) is accepted too.
                let (p, r) = if new_order() {
                    (vec(1, 3)?, rel(2)?)
                } else {
                    (vec(2, 3)?, rel(1)?)
                };
                let mut pose = self.relative(h, r)?;
                pose.translation = Translation3::new(p[0], p[1], p[2]);
                self.set_pose(h, pose, r)?;
                none
            }
            "sim.setObjectPose" => {
                let h = int(0)?;
                let (p, r) = if new_order() {
                    (vec(1, 7)?, rel(2)?)
                } else {
                    (vec(2, 7)?, rel(1)?)
                };
                let q = Quaternion::new(p[6], p[3], p[4], p[5]);
                let norm = q.norm();
                if !(norm.is_finite() && norm > 1e-9) {
                    return Err("the pose's quaternion must be finite and non-zero".into());
                }
                let pose = Isometry3::from_parts(
                    Translation3::new(p[0], p[1], p[2]),
                    UnitQuaternion::from_quaternion(q),
                );
                self.set_pose(h, pose, r)?;
                none
            }
            "sim.setObjectMatrix" => {
                let h = int(0)?;
                let (m, r) = if new_order() {
                    (vec(1, 12)?, rel(2)?)
                } else {
                    (vec(2, 12)?, rel(1)?)
                };
                let rot =
                    nalgebra::Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
                let rotation = rotation_of(&rot)?;
                let pose = Isometry3::from_parts(Translation3::new(m[3], m[7], m[11]), rotation);
                self.set_pose(h, pose, r)?;
                none
            }
            "sim.createDummy" => {
                if self.objects.len() >= MAX_OBJECTS {
                    return Err(format!(
                        "the scene holds {MAX_OBJECTS} objects, the stand-in server's limit; remove some first"
                    ));
                }
                let size = num(0)?;
                if !(size.is_finite() && size > 0.0) {
                    return Err("argument 1 must be a positive size".into());
                }
                let h = self.next_handle;
                self.next_handle += 1;
                self.objects.insert(
                    h,
                    Object {
                        alias: "Dummy".into(),
                        kind: Kind::Dummy(Isometry3::identity()),
                    },
                );
                Ok(vec![codec::int(h)])
            }
            "sim.removeObjects" | "sim.removeObject" => {
                let handles: Vec<i64> = match args.first().map(codec::untag) {
                    Some(Value::Array(a)) => a
                        .iter()
                        .map(|v| codec::as_i64(v).ok_or("argument 1 must be a table of handles"))
                        .collect::<Result<_, _>>()?,
                    Some(v) => vec![codec::as_i64(v).ok_or("argument 1 must be a handle")?],
                    None => return Err("argument 1 missing".into()),
                };
                for h in &handles {
                    match self.objects.get(h).map(|o| &o.kind) {
                        Some(Kind::Dummy(_)) => {}
                        Some(_) => return Err("the robot's objects cannot be removed".into()),
                        None => return Err("Object does not exist.".into()),
                    }
                }
                for h in handles {
                    self.objects.remove(&h);
                }
                none
            }
            "sim.setObjectColor" => {
                self.objects.get(&int(0)?).ok_or("Object does not exist.")?;
                vec(3, 3)?;
                Ok(vec![Value::Bool(true)])
            }
            "sim.setShapeColor" => {
                self.objects.get(&int(0)?).ok_or("Object does not exist.")?;
                vec(3, 3)?;
                none
            }
            "sim.startSimulation" => {
                self.running = true;
                none
            }
            "sim.stopSimulation" => {
                self.running = false;
                self.steps = 0;
                self.run = None;
                self.free_since = None;
                for c in self.clients.values_mut() {
                    c.stepping = 0;
                }
                none
            }
            "sim.getSimulationState" => Ok(vec![codec::int(if self.running { 17 } else { 0 })]),
            "sim.getSimulationTime" => Ok(vec![Value::Float(self.time())]),
            "sim.getSimulationTimeStep" => Ok(vec![Value::Float(self.setup.dt)]),
            "sim.callScriptFunction" => self.call_script(args),
            "sim.setStepping" => {
                let on = args
                    .first()
                    .and_then(codec::as_bool)
                    .ok_or("argument 1 must be a boolean")?;
                let c = self.clients.entry(uuid.into()).or_default();
                let previous = c.stepping;
                c.stepping = if on {
                    c.stepping + 1
                } else {
                    (c.stepping - 1).max(0)
                };
                Ok(vec![codec::int(previous)])
            }
            other => Err(format!("No such function: {other}")),
        }
    }
}

/// The tip's world pose at `q` (the identity if `q` does not fit the chain).
fn tip_at(chain: &SerialChain, q: &[f64]) -> Isometry3<f64> {
    chain
        .fk(q)
        .map(|f| {
            Isometry3::from_parts(
                f.translation,
                UnitQuaternion::from_rotation_matrix(&f.rotation),
            )
        })
        .unwrap_or_else(|_| Isometry3::identity())
}

/// The rotation of a 3×3 matrix that must be one: orthonormal to 1e-6 with determinant +1
/// (CoppeliaSim normalises slightly off matrices; a reflection, a scaling or zeros are not
/// rotations, and an iterative conversion of them would not end).
fn rotation_of(m: &nalgebra::Matrix3<f64>) -> Result<UnitQuaternion<f64>, String> {
    let off = (m.transpose() * m - nalgebra::Matrix3::identity())
        .abs()
        .max();
    let det = m.determinant();
    if !(off.is_finite() && off <= 1e-6 && det > 0.0) {
        return Err(format!(
            "argument 2: invalid matrix: its rotation part must be orthonormal with determinant +1 (|RᵀR − I| = {off:.3e}, det = {det:.3e})"
        ));
    }
    let r = nalgebra::Rotation3::from_matrix_unchecked(*m);
    Ok(UnitQuaternion::new_normalize(
        *UnitQuaternion::from_rotation_matrix(&r).quaternion(),
    ))
}

/// `zmqRemoteApi.info("sim")`: every function and constant the server provides.
fn info() -> Value {
    let mut entries: Vec<(&'static str, Value)> = FUNCTIONS
        .iter()
        .map(|f| (*f, codec::map([("func", Value::Map(Default::default()))])))
        .collect();
    for (name, v) in CONSTANTS {
        entries.push((name, codec::map([("const", codec::int(*v))])));
    }
    codec::map(entries)
}

const FUNCTIONS: &[&str] = &[
    "addLog",
    "getObject",
    "getObjectAlias",
    "setObjectAlias",
    "getJointPosition",
    "setJointPosition",
    "setJointTargetPosition",
    "getObjectPosition",
    "setObjectPosition",
    "getObjectQuaternion",
    "getObjectPose",
    "setObjectPose",
    "getObjectMatrix",
    "setObjectMatrix",
    "createDummy",
    "removeObjects",
    "removeObject",
    "setObjectColor",
    "setShapeColor",
    "startSimulation",
    "stopSimulation",
    "getSimulationState",
    "getSimulationTime",
    "getSimulationTimeStep",
    "setStepping",
    "callScriptFunction",
    "step",
    "testCB",
];

const CONSTANTS: &[(&str, i64)] = &[
    ("handle_world", -1),
    ("handle_all", -2),
    ("simulation_stopped", 0),
    ("simulation_paused", 8),
    ("simulation_advancing_running", 17),
    ("colorcomponent_ambient_diffuse", 0),
    ("object_joint_type", 1),
    ("object_dummy_type", 4),
    ("verbosity_none", 100),
    ("verbosity_errors", 200),
    ("verbosity_warnings", 300),
    ("verbosity_loadinfos", 400),
    ("verbosity_questions", 410),
    ("verbosity_scripterrors", 420),
    ("verbosity_scriptwarnings", 430),
    ("verbosity_scriptinfos", 450),
    ("verbosity_msgs", 450),
    ("verbosity_infos", 500),
    ("verbosity_debug", 600),
    ("verbosity_trace", 700),
    ("verbosity_tracelua", 800),
    ("verbosity_traceall", 900),
    ("verbosity_default", 400),
    ("verbosity_undecorated", 0xf000),
    ("verbosity_onlyterminal", 0x10000),
    ("verbosity_once", 0x20000),
];

/// One request in, one reply out (never blocks: a stepping client is parked with
/// `_*wait*_`).
pub(super) fn handle(sim: &mut Sim, bytes: &[u8]) -> Value {
    let err = |m: String| codec::map([("err", codec::text(&m))]);
    let request = match codec::decode(bytes) {
        Ok(v) => v,
        Err(e) => return err(e),
    };
    let Some(func) = codec::get(&request, "func").and_then(codec::as_text) else {
        return err("the request has no `func` text".into());
    };
    let Some(uuid) = codec::get(&request, "uuid").and_then(codec::as_text) else {
        return codec::map([
            ("success", Value::Bool(false)),
            (
                "error",
                codec::text(
                    "The client ZeroMQ remote API version does not match CoppeliaSim's version",
                ),
            ),
        ]);
    };
    sim.touch(&uuid);
    let Some(args) = codec::as_list(codec::get(&request, "args")) else {
        return err("`args` must be an array".into());
    };
    let ret = |values: Vec<Value>| {
        codec::map([(
            "ret",
            if values.is_empty() {
                Value::Map(Default::default())
            } else {
                Value::Array(values)
            },
        )])
    };
    let wait = || {
        codec::map([
            ("func", codec::text("_*wait*_")),
            ("args", Value::Map(Default::default())),
        ])
    };
    match func.as_str() {
        "_*end*_" => {
            sim.clients.remove(&uuid);
            Value::Map(Default::default())
        }
        "sim.step" => {
            let c = sim.clients.entry(uuid).or_default();
            c.waiting = true;
            wait()
        }
        "_*executed*_" => {
            let c = sim.clients.entry(uuid).or_default();
            if let Some(cb) = &mut c.callback {
                // The client answered its callback: call again or return its result.
                if cb.calls > 0 {
                    cb.calls -= 1;
                    return codec::map([
                        ("func", codec::text(&cb.name)),
                        ("args", Value::Array(cb.args.clone())),
                    ]);
                }
                c.callback = None;
                return ret(args.first().cloned().into_iter().collect());
            }
            if c.waiting {
                c.waiting = false;
                if sim.running {
                    sim.advance();
                }
            }
            ret(vec![])
        }
        "sim.testCB" => {
            let name = args
                .get(1)
                .and_then(codec::as_text)
                .and_then(|t| t.strip_suffix("@func").map(str::to_string));
            let (Some(a), Some(name), Some(b)) = (args.first(), name, args.get(2)) else {
                return err(
                    "sim.testCB(a, callback, b[, iterations]): argument 2 must be a function (in function 'sim.testCB')".into(),
                );
            };
            let iterations = args
                .get(3)
                .and_then(codec::as_i64)
                .unwrap_or(99)
                .clamp(0, 10_000);
            let call = codec::map([
                ("func", codec::text(&name)),
                ("args", Value::Array(vec![a.clone(), b.clone()])),
            ]);
            sim.clients.entry(uuid).or_default().callback = Some(PendingCallback {
                name,
                args: vec![a.clone(), b.clone()],
                calls: iterations as u32,
            });
            call
        }
        f => {
            sim.tick();
            match sim.call(&uuid, f, &args) {
                Ok(values) => ret(values),
                Err(m) if m.starts_with("No such function") => err(m),
                Err(m) => err(format!("{m} (in function '{f}')")),
            }
        }
    }
}

/// The stand-in server's request handling without the network: one CBOR request in, one
/// CBOR reply out, exactly what each connection does between reading a request and writing
/// its reply. For tests and fuzzing of the protocol layer.
pub struct RequestHandler {
    sim: Sim,
}

impl std::fmt::Debug for RequestHandler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RequestHandler")
            .field("robot", &self.sim.setup.robot_name)
            .field("objects", &self.sim.objects.len())
            .finish()
    }
}

impl RequestHandler {
    /// A scene as [`StandInServer::start`](crate::StandInServer::start) would serve it, with clients' stepping holds
    /// released after `client_lease` of silence.
    pub fn new(scene: SceneSetup, client_lease: Duration) -> Self {
        Self {
            sim: Sim::new(scene, client_lease),
        }
    }

    /// Answers one request (CBOR bytes) with its reply (CBOR bytes); never panics.
    pub fn handle(&mut self, request: &[u8]) -> Vec<u8> {
        codec::encode(&handle(&mut self.sim, request))
    }
}

#[cfg(test)]
mod tests {

    use super::*;
    use cps_kinematics::robots::{PandaTool, panda};
    use rand::{Rng, SeedableRng};

    fn sim() -> Sim {
        sim_with_lease(Duration::from_secs(60))
    }

    fn sim_with_lease(lease: Duration) -> Sim {
        Sim::new(
            SceneSetup {
                robot_name: "Panda".into(),
                chain: panda(PandaTool::HandTcp),
                initial_q: vec![0.0; 7],
                dummies: vec![("p0".into(), [0.1, 0.2, 0.3])],
                dt: 0.05,
                ik_following: false,
                step_cost: std::time::Duration::ZERO,
                script: true,
            },
            lease,
        )
    }

    fn request(func: &str, args: Vec<Value>, uuid: bool) -> Vec<u8> {
        let mut e = vec![
            ("func", codec::text(func)),
            ("argsL", codec::int(args.len() as i64)),
            ("args", Value::Array(args)),
        ];
        if uuid {
            e.push(("uuid", codec::text("5b9c2a7e-0000-4000-8000-000000000001")));
        }
        codec::encode(&codec::map(e))
    }

    #[test]
    fn protocol_edge_cases_are_answered_like_coppeliasim() {
        let mut s = sim();
        let reply = handle(
            &mut s,
            &request("sim.getObject", vec![codec::text("/p0")], false),
        );
        assert_eq!(
            codec::get(&reply, "success").and_then(codec::as_bool),
            Some(false)
        );
        assert!(
            codec::get(&reply, "error")
                .and_then(codec::as_text)
                .unwrap()
                .contains("version does not match")
        );
        let reply = handle(
            &mut s,
            &request("sim.getJointPosition", vec![codec::text("x")], true),
        );
        let err = codec::get(&reply, "err").and_then(codec::as_text).unwrap();
        assert_eq!(
            err,
            "argument 1 must be an integer (in function 'sim.getJointPosition')"
        );
        let reply = handle(&mut s, &request("sim.getJointPosition", vec![], true));
        assert!(codec::get(&reply, "err").is_some());
        let reply = handle(
            &mut s,
            &request("os.execute", vec![codec::text("rm -rf /")], true),
        );
        assert_eq!(
            codec::get(&reply, "err").and_then(codec::as_text).unwrap(),
            "No such function: os.execute"
        );
        let reply = handle(&mut s, &[0xff, 0x00]);
        assert!(codec::get(&reply, "err").is_some());
        // A void function answers {"ret": {}}, like CoppeliaSim.
        let reply = handle(&mut s, &request("sim.startSimulation", vec![], true));
        assert_eq!(
            codec::encode(&reply),
            vec![0xa1, 0x63, b'r', b'e', b't', 0xa0]
        );
    }

    /// 10⁵ malformed, truncated, mutated and random messages: every one gets a reply map,
    /// none panics.
    #[test]
    fn hostile_bytes_never_panic() {
        let mut s = sim();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let seeds: Vec<Vec<u8>> = vec![
            request("sim.getObject", vec![codec::text("/Panda_joint3")], true),
            request(
                "sim.setObjectPose",
                vec![
                    codec::int(100),
                    codec::floats(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
                    codec::int(-1),
                ],
                true,
            ),
            request(
                "sim.removeObjects",
                vec![Value::Array(vec![codec::int(100)])],
                true,
            ),
            request("sim.step", vec![], true),
            request("_*executed*_", vec![], true),
            request(
                "sim.setJointPosition",
                vec![codec::int(17), Value::Float(0.5)],
                true,
            ),
        ];
        for i in 0..100_000u32 {
            let mut bytes = seeds[i as usize % seeds.len()].clone();
            match i % 4 {
                0 => {
                    for _ in 0..rng.random_range(1..4) {
                        let k = rng.random_range(0..bytes.len());
                        bytes[k] = rng.random();
                    }
                }
                1 => bytes.truncate(rng.random_range(0..bytes.len())),
                2 => {
                    let k = rng.random_range(0..=bytes.len());
                    let extra: Vec<u8> =
                        (0..rng.random_range(1..16)).map(|_| rng.random()).collect();
                    bytes.splice(k..k, extra);
                }
                _ => bytes = (0..rng.random_range(0..64)).map(|_| rng.random()).collect(),
            }
            let reply = handle(&mut s, &bytes);
            assert!(matches!(reply, Value::Map(_)), "input {i}: {reply:?}");
        }
    }
}
