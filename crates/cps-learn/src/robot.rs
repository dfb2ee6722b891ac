//! Between learned movements and robots: way-point reachability, trajectories turned into
//! controller targets at the robot's control period, and execution on any backend.

use cps_dmp::Trajectory;
use cps_kinematics::{IkConfig, IkTarget, KinematicsError, SerialChain, solve_ik};
use cps_robot::{ExecutionConfig, Recording, Robot, StopToken, execute, move_to};
use nalgebra::Vector3;

use crate::{LearnError, ViaPointTask};

/// A robot placed in the world with its start configuration: what the pipelines execute
/// on and check reachability against.
#[derive(Debug, Clone)]
pub struct RobotSetup {
    /// The kinematic model (base placed in the world, tool point set).
    pub chain: SerialChain,
    /// The configuration every execution starts from (radians).
    pub initial_q: Vec<f64>,
    /// How trajectories are followed (controller, tolerances, iteration cap).
    pub execution: ExecutionConfig,
}

/// Checks that the start, every via point and the goal of a 3-D task can be reached by
/// the tool within the joint limits. The first that cannot is named in
/// [`LearnError::Unreachable`] with its distance to the closest reachable point inverse
/// kinematics found (seeded by `initial_q`, then 300 seeded restarts).
///
/// Returns one configuration per point (start, via points, goal), each solve seeded by the
/// previous one so that they stay on one branch.
pub fn check_way_points(
    task: &ViaPointTask,
    robot: &RobotSetup,
) -> Result<Vec<Vec<f64>>, LearnError> {
    if task.start.len() != 3 {
        return Err(LearnError::task(
            "start",
            format!(
                "must have 3 coordinates (x, y, z) to be executed on a robot (got {})",
                task.start.len()
            ),
        ));
    }
    let mut points: Vec<(String, &[f64])> = vec![("start".into(), &task.start)];
    for (i, v) in task.via.iter().enumerate() {
        points.push((format!("via[{i}]"), &v.position));
    }
    points.push(("goal".into(), &task.goal));
    let ik = IkConfig {
        position_tolerance: 1e-7,
        ..IkConfig::default()
    };
    let mut seed = robot.initial_q.clone();
    let mut out = Vec::with_capacity(points.len());
    for (name, p) in points {
        let position = [p[0], p[1], p[2]];
        let target = IkTarget::Position(Vector3::from(position));
        match solve_ik(&robot.chain, &target, &seed, &ik) {
            Ok(sol) => {
                seed.clone_from(&sol.q);
                out.push(sol.q);
            }
            Err(KinematicsError::Unreachable { position_error, .. }) => {
                return Err(LearnError::Unreachable {
                    point: name,
                    position,
                    distance: position_error,
                });
            }
            Err(e) => return Err(e.into()),
        }
    }
    Ok(out)
}

/// The positions of a 3-D trajectory at the control period `dt`: samples at `t = k·dt`
/// for `k = 0 ..= ⌊T/dt⌋` (linear interpolation between grid samples), as position targets,
/// with their times.
pub fn targets_at(traj: &Trajectory, dt: f64) -> (Vec<f64>, Vec<IkTarget>) {
    let end = *traj.times().last().unwrap_or(&0.0);
    let n = (end / dt + 1e-9).floor() as usize + 1;
    let times: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let targets = times
        .iter()
        .map(|&t| {
            IkTarget::Position(Vector3::new(
                traj.position_at(0, t),
                traj.position_at(1, t),
                traj.position_at(2, t),
            ))
        })
        .collect();
    (times, targets)
}

/// Executes a 3-D trajectory on `backend` from the setup's initial configuration: the
/// robot is put there (a simulator, clock at 0) or moves there ([`move_to`]), then follows
/// one target per control period ([`execute`]). `stop` brakes a robot that moves.
pub fn execute_trajectory(
    backend: &mut dyn Robot,
    robot: &RobotSetup,
    traj: &Trajectory,
    stop: &StopToken,
) -> Result<Recording, LearnError> {
    execute_trajectory_from(backend, robot, traj, &robot.initial_q, stop)
}

/// [`execute_trajectory`] from the configuration `q0` instead of the setup's initial one.
pub fn execute_trajectory_from(
    backend: &mut dyn Robot,
    robot: &RobotSetup,
    traj: &Trajectory,
    q0: &[f64],
    stop: &StopToken,
) -> Result<Recording, LearnError> {
    move_to(backend, q0, stop)?;
    let (_, targets) = targets_at(traj, backend.dt());
    Ok(execute(
        backend,
        &robot.chain,
        &targets,
        &robot.execution,
        stop,
    )?)
}
