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

/// How many other inverse-kinematics solutions [`clear_way_points`] tries for a way
/// configuration that does not keep the clearance.
pub const CLEAR_TRIES: usize = 64;

/// Way configurations ([`check_way_points`]'s) that keep `clearance`: one whose shapes
/// does not keep `clearance` (the arm into itself or its scene, [`crate::Clearance::kept_at`]) is replaced by
/// the inverse-kinematics solution for the same point, from seeded random starts, that
/// keeps it and lies closest to the configuration before it (so the way stays on one
/// branch); where none of [`CLEAR_TRIES`] does, the first solution stays (learning's
/// clearance cost and the guard then judge the movement). Deterministic.
pub fn clear_way_points(
    task: &ViaPointTask,
    robot: &RobotSetup,
    clearance: &crate::Clearance,
    configs: Vec<Vec<f64>>,
) -> Result<Vec<Vec<f64>>, LearnError> {
    use rand::SeedableRng;
    let mut buffers = crate::clearance::ClearanceBuffers::default();
    let mut keeps = |q: &[f64]| -> Result<bool, LearnError> {
        Ok(clearance.kept_at(&robot.chain, q, &mut buffers)?)
    };
    let mut points: Vec<&[f64]> = vec![&task.start];
    points.extend(task.via.iter().map(|v| v.position.as_slice()));
    points.push(&task.goal);
    let ik = IkConfig {
        position_tolerance: 1e-7,
        restarts: 0,
        ..IkConfig::default()
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(51);
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(configs.len());
    for (k, (q, p)) in configs.into_iter().zip(points).enumerate() {
        // The start is where the robot stands: it is what it is.
        if k == 0 || keeps(&q)? {
            out.push(q);
            continue;
        }
        let before = out
            .last()
            .cloned()
            .unwrap_or_else(|| robot.initial_q.clone());
        let target = IkTarget::Position(Vector3::new(p[0], p[1], p[2]));
        let mut best: Option<(f64, Vec<f64>)> = None;
        for _ in 0..CLEAR_TRIES {
            let seed = robot.chain.random_configuration(&mut rng);
            let Ok(sol) = solve_ik(&robot.chain, &target, &seed, &ik) else {
                continue;
            };
            if !keeps(&sol.q)? {
                continue;
            }
            let gap: f64 = sol
                .q
                .iter()
                .zip(&before)
                .map(|(a, b)| (a - b).powi(2))
                .sum();
            if best.as_ref().is_none_or(|(g, _)| gap < *g) {
                best = Some((gap, sol.q));
            }
        }
        out.push(best.map_or(q, |(_, q)| q));
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
