//! The thesis's Franka scene over the remote API: the robot `/Panda`, its joints
//! `/Panda_joint1..7`, tool tip `/Panda_tip`, IK target `/Panda_target`, way points `/p0`,
//! `/p1`, …, `/pT`; and a [`RobotBackend`] that drives the joints.

use cps_kinematics::{KinematicsError, RobotBackend};
use nalgebra::{IsometryMatrix3, Vector3};

use crate::sim::{HANDLE_WORLD, SIMULATION_STOPPED};
use crate::{Client, CoppeliaError};

/// The handles of a robot in a CoppeliaSim scene, named as in the thesis.
#[derive(Debug)]
pub struct FrankaScene {
    client: Client,
    joints: Vec<i64>,
    tip: i64,
    dt: f64,
    /// `/<robot>_target` while the scene's IK follows it (see [`FrankaScene::follow_ik_target`]).
    target: Option<i64>,
    robot: String,
}

impl FrankaScene {
    /// Looks up `/<robot>_joint1..dof` and `/<robot>_tip` (the thesis: robot `Panda`,
    /// seven joints). `dt` is the scene's simulation time step in seconds.
    pub fn open(
        mut client: Client,
        robot: &str,
        dof: usize,
        dt: f64,
    ) -> Result<Self, CoppeliaError> {
        let joints = (1..=dof)
            .map(|i| client.get_object(&format!("/{robot}_joint{i}")))
            .collect::<Result<Vec<_>, _>>()?;
        let tip = client.get_object(&format!("/{robot}_tip"))?;
        Ok(Self {
            client,
            joints,
            tip,
            dt,
            target: None,
            robot: robot.to_string(),
        })
    }

    /// Switches to CoppeliaSim's own inverse kinematics: trajectories are then executed
    /// by moving `/<robot>_target` (the thesis's `/Panda_target`), which the scene's IK
    /// makes the tip follow at every step, instead of commanding joints from cps's
    /// controller. The scene must run that IK (the thesis's scene does;
    /// `cps-cli sim serve --ik-following` does).
    pub fn follow_ik_target(&mut self, on: bool) -> Result<(), CoppeliaError> {
        self.target = if on {
            Some(self.client.get_object(&format!("/{}_target", self.robot))?)
        } else {
            None
        };
        Ok(())
    }

    /// Starts the simulation in stepping mode, so that [`RobotBackend::step`] advances it
    /// exactly one time step.
    pub fn start_stepping(&mut self) -> Result<(), CoppeliaError> {
        self.client.start_simulation()?;
        self.client.set_stepping(true)?;
        Ok(())
    }

    /// Stops the simulation (which also ends stepping) and waits until it has stopped:
    /// CoppeliaSim stops asynchronously, restoring the scene over a few passes. Gives up
    /// with [`CoppeliaError::Timeout`] after 10 s.
    pub fn stop(&mut self) -> Result<(), CoppeliaError> {
        self.client.stop_simulation()?;
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while self.client.get_simulation_state()? != SIMULATION_STOPPED {
            if std::time::Instant::now() > deadline {
                return Err(CoppeliaError::Timeout {
                    endpoint: self.client.endpoint().to_string(),
                    function: "sim.stopSimulation (waiting for the stopped state)".into(),
                    timeout_ms: 10_000,
                });
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        Ok(())
    }

    /// The client, for calls this type does not wrap.
    pub fn client(&mut self) -> &mut Client {
        &mut self.client
    }

    /// The way points of the scene: `/p0`, `/p1`, … as long as they exist, then `/pT`
    /// (world positions, metres).
    pub fn way_points(&mut self) -> Result<Vec<(String, Vector3<f64>)>, CoppeliaError> {
        let mut out = Vec::new();
        let mut names: Vec<String> = Vec::new();
        for i in 0.. {
            let name = format!("p{i}");
            match self.client.get_object(&format!("/{name}")) {
                Ok(h) => {
                    let p = self.client.get_object_position(h, HANDLE_WORLD)?;
                    out.push((name.clone(), Vector3::from(p)));
                    names.push(name);
                }
                Err(CoppeliaError::Remote { .. }) => break,
                Err(e) => return Err(e),
            }
        }
        if let Ok(h) = self.client.get_object("/pT") {
            let p = self.client.get_object_position(h, HANDLE_WORLD)?;
            out.push(("pT".into(), Vector3::from(p)));
        }
        Ok(out)
    }

    /// Creates a way-point dummy (size 0.04 m, as the thesis) named `name` at `position`,
    /// coloured `rgb`; returns its handle.
    pub fn create_way_point(
        &mut self,
        name: &str,
        position: [f64; 3],
        rgb: [f64; 3],
    ) -> Result<i64, CoppeliaError> {
        let h = self.client.create_dummy(0.04)?;
        self.client.set_object_alias(h, name)?;
        self.client.set_object_position(h, position, HANDLE_WORLD)?;
        self.client.set_object_color(h, rgb)?;
        Ok(h)
    }
}

impl RobotBackend for FrankaScene {
    fn dof(&self) -> usize {
        self.joints.len()
    }

    fn time_step(&self) -> f64 {
        self.dt
    }

    fn joint_positions(&mut self) -> Result<Vec<f64>, KinematicsError> {
        let joints = self.joints.clone();
        Ok(joints
            .iter()
            .map(|&j| self.client.get_joint_position(j))
            .collect::<Result<Vec<_>, _>>()?)
    }

    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        if q.len() != self.joints.len() {
            return Err(KinematicsError::JointCount {
                expected: self.joints.len(),
                got: q.len(),
            });
        }
        let joints = self.joints.clone();
        for (j, v) in joints.iter().zip(q) {
            self.client.set_joint_position(*j, *v)?;
        }
        Ok(())
    }

    fn command_joint_velocities(&mut self, dq: &[f64]) -> Result<(), KinematicsError> {
        // Kinematic joints: integrate one step here.
        let q = self.joint_positions()?;
        let next: Vec<f64> = q.iter().zip(dq).map(|(a, v)| a + v * self.dt).collect();
        self.command_joint_positions(&next)
    }

    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, KinematicsError> {
        let pose = self.client.get_object_pose(self.tip, HANDLE_WORLD)?;
        Ok(IsometryMatrix3::from_parts(
            pose.translation,
            pose.rotation.to_rotation_matrix(),
        ))
    }

    fn time(&mut self) -> Result<f64, KinematicsError> {
        Ok(self.client.get_simulation_time()?)
    }

    fn step(&mut self) -> Result<(), KinematicsError> {
        Ok(self.client.step()?)
    }

    /// Stops the simulation (CoppeliaSim restores the scene and resets its clock), sets
    /// the joints to `q` and starts stepping again. Following the IK target, the target is
    /// put on the tip first, so the robot stays where it was set.
    fn reset(&mut self, q: &[f64]) -> Result<(), KinematicsError> {
        self.stop()?;
        self.command_joint_positions(q)?;
        if let Some(target) = self.target {
            let tip = self.client.get_object_pose(self.tip, HANDLE_WORLD)?;
            self.client.set_object_pose(target, &tip, HANDLE_WORLD)?;
        }
        self.start_stepping()?;
        Ok(())
    }

    fn follows_targets(&self) -> bool {
        self.target.is_some()
    }

    /// Moves `/<robot>_target`: its position for a position target (orientation kept),
    /// its whole pose for a pose target.
    fn command_target(&mut self, target: &cps_kinematics::IkTarget) -> Result<(), KinematicsError> {
        let Some(handle) = self.target else {
            return Err(KinematicsError::Backend {
                backend: format!("CoppeliaSim at {}", self.client.endpoint()),
                message: "not following the IK target: call follow_ik_target(true) first".into(),
            });
        };
        match target {
            cps_kinematics::IkTarget::Position(p) => {
                self.client
                    .set_object_position(handle, [p.x, p.y, p.z], HANDLE_WORLD)?;
            }
            cps_kinematics::IkTarget::Pose(pose) => {
                let iso = nalgebra::Isometry3::from_parts(
                    pose.translation,
                    nalgebra::UnitQuaternion::from_rotation_matrix(&pose.rotation),
                );
                self.client.set_object_pose(handle, &iso, HANDLE_WORLD)?;
            }
        }
        Ok(())
    }
}
