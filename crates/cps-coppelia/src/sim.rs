//! Typed wrappers of the `sim` functions cps uses, and the constants they need.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use crate::codec::{self, Value};
use crate::{Client, CoppeliaError};

/// `sim.handle_world`: positions relative to the world.
pub const HANDLE_WORLD: i64 = -1;
/// `sim.simulation_stopped`.
pub const SIMULATION_STOPPED: i64 = 0;
/// `sim.simulation_paused`.
pub const SIMULATION_PAUSED: i64 = 8;
/// `sim.simulation_advancing_running`.
pub const SIMULATION_RUNNING: i64 = 17;

impl Client {
    fn one(&mut self, func: &str, args: Vec<Value>) -> Result<Value, CoppeliaError> {
        let ret = self.call(func, args)?;
        ret.into_iter()
            .next()
            .ok_or_else(|| CoppeliaError::Protocol {
                endpoint: self.endpoint().into(),
                function: func.into(),
                message: "no return value".into(),
            })
    }

    fn typed<T>(
        &mut self,
        func: &str,
        args: Vec<Value>,
        what: &str,
        f: impl Fn(&Value) -> Option<T>,
    ) -> Result<T, CoppeliaError> {
        let v = self.one(func, args)?;
        f(&v).ok_or_else(|| CoppeliaError::Protocol {
            endpoint: self.endpoint().into(),
            function: func.into(),
            message: format!("expected {what}, got {}", codec::describe(&v)),
        })
    }

    /// `sim.getObject(path)`: the handle of a scene object, e.g. `/Panda_joint1`.
    pub fn get_object(&mut self, path: &str) -> Result<i64, CoppeliaError> {
        self.typed(
            "sim.getObject",
            vec![codec::text(path)],
            "a handle",
            codec::as_i64,
        )
    }

    /// `sim.getJointPosition(handle)` in radians.
    pub fn get_joint_position(&mut self, joint: i64) -> Result<f64, CoppeliaError> {
        self.typed(
            "sim.getJointPosition",
            vec![codec::int(joint)],
            "a number",
            codec::as_f64,
        )
    }

    /// `sim.setJointPosition(handle, position)`.
    pub fn set_joint_position(&mut self, joint: i64, position: f64) -> Result<(), CoppeliaError> {
        self.call(
            "sim.setJointPosition",
            vec![codec::int(joint), Value::Float(position)],
        )
        .map(drop)
    }

    /// `sim.getObjectPosition(handle, relativeTo)` in metres.
    pub fn get_object_position(
        &mut self,
        object: i64,
        relative_to: i64,
    ) -> Result<[f64; 3], CoppeliaError> {
        self.typed(
            "sim.getObjectPosition",
            vec![codec::int(object), codec::int(relative_to)],
            "3 numbers",
            |v| codec::as_f64_vec(v).and_then(|p| p.try_into().ok()),
        )
    }

    /// `sim.setObjectPosition(handle, position, relativeTo)`.
    pub fn set_object_position(
        &mut self,
        object: i64,
        position: [f64; 3],
        relative_to: i64,
    ) -> Result<(), CoppeliaError> {
        let args = self.setter_args(object, codec::floats(&position), relative_to);
        self.call("sim.setObjectPosition", args).map(drop)
    }

    /// `sim.getObjectPose(handle, relativeTo)` as an isometry (`[x y z qx qy qz qw]` on the
    /// wire).
    pub fn get_object_pose(
        &mut self,
        object: i64,
        relative_to: i64,
    ) -> Result<Isometry3<f64>, CoppeliaError> {
        let p: [f64; 7] = self.typed(
            "sim.getObjectPose",
            vec![codec::int(object), codec::int(relative_to)],
            "7 numbers",
            |v| codec::as_f64_vec(v).and_then(|p| p.try_into().ok()),
        )?;
        Ok(Isometry3::from_parts(
            Translation3::new(p[0], p[1], p[2]),
            UnitQuaternion::from_quaternion(Quaternion::new(p[6], p[3], p[4], p[5])),
        ))
    }

    /// `sim.setObjectPose(handle, pose, relativeTo)`.
    pub fn set_object_pose(
        &mut self,
        object: i64,
        pose: &Isometry3<f64>,
        relative_to: i64,
    ) -> Result<(), CoppeliaError> {
        let (t, q) = (pose.translation.vector, pose.rotation);
        let wire = [t.x, t.y, t.z, q.i, q.j, q.k, q.w];
        let args = self.setter_args(object, codec::floats(&wire), relative_to);
        self.call("sim.setObjectPose", args).map(drop)
    }

    /// `sim.getObjectMatrix(handle, relativeTo)`: the 3×4 matrix row-major (12 numbers).
    pub fn get_object_matrix(
        &mut self,
        object: i64,
        relative_to: i64,
    ) -> Result<[f64; 12], CoppeliaError> {
        self.typed(
            "sim.getObjectMatrix",
            vec![codec::int(object), codec::int(relative_to)],
            "12 numbers",
            |v| codec::as_f64_vec(v).and_then(|p| p.try_into().ok()),
        )
    }

    /// `sim.setObjectMatrix(handle, matrix, relativeTo)`: 12 numbers, the 3×4 matrix
    /// row-major.
    pub fn set_object_matrix(
        &mut self,
        object: i64,
        matrix: [f64; 12],
        relative_to: i64,
    ) -> Result<(), CoppeliaError> {
        let args = self.setter_args(object, codec::floats(&matrix), relative_to);
        self.call("sim.setObjectMatrix", args).map(drop)
    }

    /// `sim.createDummy(size)`: a new dummy's handle.
    pub fn create_dummy(&mut self, size: f64) -> Result<i64, CoppeliaError> {
        self.typed(
            "sim.createDummy",
            vec![Value::Float(size)],
            "a handle",
            codec::as_i64,
        )
    }

    /// `sim.setObjectAlias(handle, alias)`.
    pub fn set_object_alias(&mut self, object: i64, alias: &str) -> Result<(), CoppeliaError> {
        self.call(
            "sim.setObjectAlias",
            vec![codec::int(object), codec::text(alias)],
        )
        .map(drop)
    }

    /// `sim.removeObjects(handles)`.
    pub fn remove_objects(&mut self, objects: &[i64]) -> Result<(), CoppeliaError> {
        let list = Value::Array(objects.iter().map(|h| codec::int(*h)).collect());
        self.call("sim.removeObjects", vec![list]).map(drop)
    }

    /// `sim.setObjectColor(handle, 0, colorcomponent_ambient_diffuse, rgb)`.
    pub fn set_object_color(&mut self, object: i64, rgb: [f64; 3]) -> Result<(), CoppeliaError> {
        self.call(
            "sim.setObjectColor",
            vec![
                codec::int(object),
                codec::int(0),
                codec::int(0),
                codec::floats(&rgb),
            ],
        )
        .map(drop)
    }

    /// `sim.startSimulation()`.
    pub fn start_simulation(&mut self) -> Result<(), CoppeliaError> {
        self.call("sim.startSimulation", vec![]).map(drop)
    }

    /// `sim.stopSimulation()`; it also ends stepping for every client.
    pub fn stop_simulation(&mut self) -> Result<(), CoppeliaError> {
        self.call("sim.stopSimulation", vec![]).map(drop)
    }

    /// `sim.getSimulationTime()` in seconds.
    pub fn get_simulation_time(&mut self) -> Result<f64, CoppeliaError> {
        self.typed("sim.getSimulationTime", vec![], "a number", codec::as_f64)
    }

    /// `sim.getSimulationTimeStep()` in seconds.
    pub fn get_simulation_time_step(&mut self) -> Result<f64, CoppeliaError> {
        self.typed(
            "sim.getSimulationTimeStep",
            vec![],
            "a number",
            codec::as_f64,
        )
    }

    /// `sim.getSimulationState()` (see [`SIMULATION_STOPPED`] and friends).
    pub fn get_simulation_state(&mut self) -> Result<i64, CoppeliaError> {
        self.typed(
            "sim.getSimulationState",
            vec![],
            "an integer",
            codec::as_i64,
        )
    }

    /// `sim.setStepping(enabled)`: returns the previous stepping level. (v1: the global
    /// `setStepping`, after connecting the step counter.)
    pub fn set_stepping(&mut self, enabled: bool) -> Result<i64, CoppeliaError> {
        if self.protocol() == crate::Protocol::V1 {
            return self.v1_set_stepping(enabled);
        }
        self.typed(
            "sim.setStepping",
            vec![Value::Bool(enabled)],
            "an integer",
            codec::as_i64,
        )
    }

    /// `sim.step()`: one simulation step (waits until it has happened).
    pub fn step(&mut self) -> Result<(), CoppeliaError> {
        if self.protocol() == crate::Protocol::V1 {
            return self.v1_step();
        }
        self.call("sim.step", vec![]).map(drop)
    }

    /// `sim.callScriptFunction(name, script, args...)` (4.6+ argument order): a function of
    /// the scene script whose handle is `script`; its return values.
    pub fn call_script_function(
        &mut self,
        name: &str,
        script: i64,
        args: Vec<Value>,
    ) -> Result<Vec<Value>, CoppeliaError> {
        let mut all = vec![codec::text(name), codec::int(script)];
        all.extend(args);
        self.call("sim.callScriptFunction", all)
    }

    /// A setter's arguments: `(handle, value, relativeTo)` in v2, `(handle, relativeTo,
    /// value)` in v1.
    fn setter_args(&self, object: i64, value: Value, relative_to: i64) -> Vec<Value> {
        match self.protocol() {
            crate::Protocol::V2 => vec![codec::int(object), value, codec::int(relative_to)],
            crate::Protocol::V1 => vec![codec::int(object), codec::int(relative_to), value],
        }
    }
}
