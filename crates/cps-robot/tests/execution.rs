//! Execution on robots: the in-process stand-in within its limits, the closed loop, and
//! plans planned on the model (moved here from cps-kinematics with the code they test).

use cps_kinematics::IkTarget;
use cps_kinematics::KinematicsError;
use cps_kinematics::robots::{PANDA_DQ_MAX, PANDA_Q_MAX, PANDA_Q_MIN, PandaTool, panda};
use cps_robot::{
    ExecutionConfig, KinematicRobot, Plan, Robot, RobotError, RobotModel, Run, Stepped, Stepping,
    StopToken, execute, run_stepped,
};
use nalgebra::Vector3;

const THESIS_Q0: [f64; 7] = [
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    std::f64::consts::FRAC_PI_2,
    std::f64::consts::FRAC_PI_4,
];
const READY: [f64; 7] = cps_kinematics::robots::PANDA_READY;

#[test]
fn kinematic_robot_integrates_commands_within_limits() {
    let arm = panda(PandaTool::HandTcp);
    let mut robot = KinematicRobot::new(arm, &THESIS_Q0, 0.01).unwrap();
    // Joint 4 starts above its upper limit (−0.0698): it may only move back.
    robot
        .command_joint_velocities(&[0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
        .unwrap();
    for _ in 0..100 {
        robot.step().unwrap();
    }
    let q = robot.joint_positions().unwrap();
    assert!((q[0] - 0.5).abs() < 1e-12, "q1 = {}", q[0]); // v t exactly
    assert_eq!(q[3], 0.0, "joint 4 pushed further out");
    assert!((robot.time().unwrap() - 1.0).abs() < 1e-15);
    // A position command far away is approached at the speed limit, never beyond.
    robot
        .command_joint_positions(&[2.0, 0.0, 0.0, -2.0, 0.0, 1.5, 0.0])
        .unwrap();
    robot.step().unwrap();
    let q1 = robot.joint_positions().unwrap();
    assert!((q1[0] - (0.5 + PANDA_DQ_MAX[0] * 0.01)).abs() < 1e-12);
    assert!((q1[3] - (-PANDA_DQ_MAX[3] * 0.01)).abs() < 1e-12);
    assert!(robot.command_joint_positions(&[0.0; 6]).is_err());
    assert!(matches!(
        robot.command_joint_velocities(&[f64::NAN; 7]),
        Err(KinematicsError::InvalidConfig(_))
    ));
    assert!(KinematicRobot::new(panda(PandaTool::Flange), &READY, 0.0).is_err());
}

/// A circle of radius 0.1 m in 4 s, 10 ms per sample: tracked to within 0.1 mm, and
/// limits are never exceeded at any step.
#[test]
fn execution_tracks_a_circle_and_respects_limits_at_every_step() {
    let arm = panda(PandaTool::HandTcp);
    let c = arm.fk(&READY).unwrap().translation.vector;
    let n = 400;
    let targets: Vec<IkTarget> = (0..=n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            IkTarget::Position(c + Vector3::new(0.1 * (a.cos() - 1.0), 0.1 * a.sin(), 0.0))
        })
        .collect();
    let mut robot = KinematicRobot::new(arm.clone(), &READY, 0.01).unwrap();
    let cfg = ExecutionConfig {
        max_iterations_per_sample: 1,
        ..ExecutionConfig::default()
    };
    let rec = execute(&mut robot, &arm, &targets, &cfg, &StopToken::new()).unwrap();
    assert_eq!(rec.time.len(), n + 1);
    assert_eq!(rec.steps, n + 1);
    assert!(
        rec.max_position_error() < 1e-4,
        "max error {}",
        rec.max_position_error()
    );
    let mut prev = READY.to_vec();
    for q in &rec.q {
        for i in 0..7 {
            assert!((PANDA_Q_MIN[i]..=PANDA_Q_MAX[i]).contains(&q[i]));
            assert!((q[i] - prev[i]).abs() <= PANDA_DQ_MAX[i] * 0.01 + 1e-12);
        }
        prev.clone_from(q);
    }
    // A target out of reach: the robot stops at its limits, the error is reported,
    // the iteration cap ends every sample.
    let far = vec![IkTarget::Position(Vector3::new(2.0, 0.0, 0.5)); 50];
    let mut robot = KinematicRobot::new(arm.clone(), &READY, 0.01).unwrap();
    let rec = execute(
        &mut robot,
        &arm,
        &far,
        &ExecutionConfig::default(),
        &StopToken::new(),
    )
    .unwrap();
    assert_eq!(rec.unconverged, 50);
    assert_eq!(rec.steps, 500);
    assert!(rec.max_position_error() > 0.9);
    for q in &rec.q {
        for i in 0..7 {
            assert!(
                (PANDA_Q_MIN[i]..=PANDA_Q_MAX[i]).contains(&q[i]),
                "joint {} at {}",
                i + 1,
                q[i]
            );
        }
    }
}

/// A robot that says it prefers whole plans, running them through its stepped robot inside
/// (per-step calls on the kinematic robot).
struct Batched(KinematicRobot);

impl Stepped for Batched {
    fn time(&mut self) -> Result<f64, RobotError> {
        Stepped::time(&mut self.0)
    }
    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), RobotError> {
        Stepped::command_joint_positions(&mut self.0, q)
    }
    fn step(&mut self) -> Result<(), RobotError> {
        Stepped::step(&mut self.0)
    }
    fn stepping(&self) -> Stepping {
        Stepping::Plans
    }
}

impl Robot for Batched {
    fn name(&self) -> String {
        "batched".into()
    }
    fn model(&self) -> &RobotModel {
        Robot::model(&self.0)
    }
    fn dt(&self) -> f64 {
        Robot::dt(&self.0)
    }
    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        Robot::joint_positions(&mut self.0)
    }
    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
        run_stepped(self, plan, stop)
    }
    fn stepped(&mut self) -> Option<&mut dyn Stepped> {
        Some(self)
    }
}

/// Planning the controller's commands on the model and sending them at once records
/// exactly what the closed loop records on a robot that follows its commands: the
/// same samples, steps, iteration caps and measurements, bit for bit. A robot that
/// lags behind its commands shows it as tracking error.
#[test]
fn sequences_planned_on_the_model_record_what_the_closed_loop_records() {
    let arm = panda(PandaTool::HandTcp);
    let c = arm.fk(&READY).unwrap().translation.vector;
    let circle: Vec<IkTarget> = (0..=300)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / 300.0;
            IkTarget::Position(c + Vector3::new(0.15 * (a.cos() - 1.0), 0.15 * a.sin(), 0.0))
        })
        .collect();
    let far = vec![IkTarget::Position(Vector3::new(2.0, 0.0, 0.5)); 20];
    for targets in [&circle, &far] {
        let cfg = ExecutionConfig::default();
        let mut stepped = KinematicRobot::new(arm.clone(), &READY, 0.01).unwrap();
        let closed = execute(&mut stepped, &arm, targets, &cfg, &StopToken::new()).unwrap();
        let mut batched = Batched(KinematicRobot::new(arm.clone(), &READY, 0.01).unwrap());
        let planned = execute(&mut batched, &arm, targets, &cfg, &StopToken::new()).unwrap();
        assert_eq!(closed, planned);
        assert!(closed.steps >= targets.len());
        if targets.len() == far.len() {
            assert_eq!((planned.steps, planned.unconverged), (200, 20));
        }
    }
    // A robot whose speed limits are a tenth of the model's lags behind the plan: the
    // closed loop catches up, the planned sequence records the lag.
    let slow: Vec<f64> = PANDA_DQ_MAX.iter().map(|v| v * 0.1).collect();
    let slow = arm.clone().with_velocity_limits(&slow).unwrap();
    let mut batched = Batched(KinematicRobot::new(slow, &READY, 0.01).unwrap());
    let lagging = execute(
        &mut batched,
        &arm,
        &circle,
        &ExecutionConfig::default(),
        &StopToken::new(),
    )
    .unwrap();
    assert!(
        lagging.max_position_error() > 1e-3,
        "{}",
        lagging.max_position_error()
    );
}

/// A stepped robot whose connection dies after `left` steps.
struct Dying {
    robot: KinematicRobot,
    left: usize,
}

impl Stepped for Dying {
    fn time(&mut self) -> Result<f64, RobotError> {
        Stepped::time(&mut self.robot)
    }
    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), RobotError> {
        Stepped::command_joint_positions(&mut self.robot, q)
    }
    fn step(&mut self) -> Result<(), RobotError> {
        if self.left == 0 {
            return Err(RobotError::Robot {
                robot: "the dying robot".into(),
                message: "the connection was lost".into(),
            });
        }
        self.left -= 1;
        Stepped::step(&mut self.robot)
    }
}

impl Robot for Dying {
    fn name(&self) -> String {
        "the dying robot".into()
    }
    fn model(&self) -> &RobotModel {
        Robot::model(&self.robot)
    }
    fn dt(&self) -> f64 {
        Robot::dt(&self.robot)
    }
    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
        Robot::joint_positions(&mut self.robot)
    }
    fn tool_pose(&mut self) -> Result<nalgebra::IsometryMatrix3<f64>, RobotError> {
        Robot::tool_pose(&mut self.robot)
    }
    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
        run_stepped(self, plan, stop)
    }
}

/// `Robot::run` promises an error only when nothing moved: a stepped robot that fails
/// mid-plan ends the run Failed with what it recorded (it returned the error and lost the
/// recording); one that fails at its first step moved nothing and says so as an error.
#[test]
fn a_stepped_robot_failing_mid_plan_keeps_its_recording() {
    let arm = panda(PandaTool::HandTcp);
    let points: Vec<Vec<f64>> = (0..=50)
        .map(|k| {
            let mut q = READY.to_vec();
            q[0] += 0.002 * k as f64;
            q
        })
        .collect();
    let plan = Plan::new(0.01, points).unwrap();
    let mut dying = Dying {
        robot: KinematicRobot::new(arm.clone(), &READY, 0.01).unwrap(),
        left: 20,
    };
    let run = run_stepped(&mut dying, &plan, &StopToken::new()).unwrap();
    assert_eq!(run.len(), 21, "the start and the 20 steps made");
    match &run.ending {
        cps_robot::Ending::Failed(why) => assert!(why.contains("connection was lost"), "{why}"),
        other => panic!("{other:?}"),
    }
    assert!(
        (run.q[20][0] - (READY[0] + 0.04)).abs() < 1e-9,
        "{:?}",
        run.q[20]
    );
    let mut dead = Dying {
        robot: KinematicRobot::new(arm, &READY, 0.01).unwrap(),
        left: 0,
    };
    assert!(run_stepped(&mut dead, &plan, &StopToken::new()).is_err());
}
