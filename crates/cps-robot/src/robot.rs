//! The execution contract: what every robot cps drives offers ([`Robot`]), and what the
//! robots that step offer besides ([`Stepped`]).

use cps_kinematics::IkTarget;
use nalgebra::IsometryMatrix3;

use crate::check::Breach;
use crate::plan::{Plan, Run};
use crate::{RobotError, RobotModel, StopToken};

/// A robot cps can drive: read where it stands, run a [`Plan`] and say what it did.
///
/// Implementations run plans as given; the limits are the [`crate::Guarded`] wrapper's,
/// which every robot cps opens for a user is wrapped in (a raw robot is for tests and for
/// wrappers). Every method may fail with [`RobotError::Robot`] naming the robot.
pub trait Robot: Send {
    /// The robot in messages: `the Franka at 192.168.0.2`, `ros2 /arm_controller`, …
    fn name(&self) -> String;

    /// Its model: kinematics, joint names, and the limits its plans are checked against.
    fn model(&self) -> &RobotModel;

    /// The period (s) the robot takes plans at: its control period, what experiments plan
    /// at.
    fn dt(&self) -> f64;

    /// Where the robot stands (rad): the position a plan must start from.
    fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError>;

    /// The period (s) of the commands the robot receives when it runs a plan, which is
    /// what the guard checks: a robot that steps through a plan's points (a simulator)
    /// receives the motion sampled at its step; a robot that interpolates it (a Franka at
    /// 1 kHz, a ros2_control controller) the motion itself, checked every
    /// [`CHECK_PERIOD`](crate::CHECK_PERIOD). Default: [`CHECK_PERIOD`](crate::CHECK_PERIOD).
    fn command_period(&self) -> f64 {
        crate::CHECK_PERIOD
    }

    /// Where the robot stands, if it can tell before it moves: None for a robot driven
    /// blind (a ROS 2 controller whose joint states cps does not read), which is trusted to
    /// start from a plan's first point — the guard then checks the plan's motion only.
    /// Default: `Some(`[`Robot::joint_positions`]`)`.
    fn standing(&mut self) -> Result<Option<Vec<f64>>, RobotError> {
        self.joint_positions().map(Some)
    }

    /// The tool's pose in the world frame now. Default: the model's forward kinematics of
    /// [`Robot::joint_positions`].
    fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, RobotError> {
        let q = self.joint_positions()?;
        Ok(self.model().chain.fk(&q)?)
    }

    /// Runs `plan` from where the robot stands (its first point, within
    /// [`crate::START_TOLERANCE`]), as it is: one entry per point reached, at that point's
    /// time. A stop asked for through `stop` brakes the robot within its limits and ends the
    /// run with [`crate::Ending::Stopped`]; a failure while moving ends it with
    /// [`crate::Ending::Failed`]; in both cases what was recorded is kept. An error is
    /// returned only when nothing moved.
    fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError>;

    /// Puts the robot at `q` at rest, its clock at 0, without a motion through space (a
    /// simulator's reset): true if it did; false for a robot that must move there (the
    /// guard then approaches). Default: false.
    fn teleport(&mut self, q: &[f64]) -> Result<bool, RobotError> {
        let _ = q;
        Ok(false)
    }

    /// Records what the robot does for `duration` without commanding it (at rest, or moved
    /// by hand where the robot allows it), until `stop`: one entry per reading. Default:
    /// [`Robot::joint_positions`] and [`Robot::tool_pose`] read every [`Robot::dt`].
    fn record(
        &mut self,
        duration: std::time::Duration,
        stop: &StopToken,
    ) -> Result<Run, RobotError> {
        let mut run = Run::new(crate::Ending::Finished);
        let start = std::time::Instant::now();
        let period = std::time::Duration::from_secs_f64(self.dt());
        loop {
            let t = start.elapsed();
            let q = self.joint_positions()?;
            let tool = self.tool_pose()?;
            run.push(t.as_secs_f64(), q, tool);
            if stop.is_stopped() {
                run.ending = crate::Ending::Stopped;
                break;
            }
            let next = period * run.len() as u32;
            if next > duration {
                break;
            }
            if let Some(wait) = next.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        Ok(run)
    }

    /// The robot's own rules for a plan beyond its model's limits, checked before anything
    /// is sent (a Franka's position-dependent speed and its distance to stop, judged on the
    /// commands it would stream). Default: none.
    fn check(&mut self, plan: &Plan) -> Result<Option<Breach>, RobotError> {
        let _ = plan;
        Ok(None)
    }

    /// A sentence on how the runs so far went on this robot (limit usage, timing, goals),
    /// for summaries; None where the recording says it all. Default: None.
    fn report(&self) -> Option<String> {
        None
    }

    /// The stepped interface, for robots that step (simulators); None for robots that only
    /// run whole plans (a Franka, a ROS 2 controller). Default: None.
    fn stepped(&mut self) -> Option<&mut dyn Stepped> {
        None
    }

    /// The streaming interface, for robots that take a command computed each control
    /// period from what they measured (a Franka's realtime loop, the stand-in); None for
    /// robots that only run whole plans. Default: None.
    fn streaming(&mut self) -> Option<&mut dyn Streaming> {
        None
    }
}

/// What a streaming robot measured in a control period, handed to the command generator.
#[derive(Debug, Clone, Copy)]
pub struct Measured<'a> {
    /// Joint positions (rad).
    pub q: &'a [f64],
    /// Joint velocities (rad/s).
    pub dq: &'a [f64],
    /// Joint torques (N m): a Franka's measured link-side torques (`tau_J`), the drives'
    /// torques of a simulated arm (gravity included), zeros where the robot has none (the
    /// in-process robot).
    pub tau: &'a [f64],
}

/// A command generator for [`Streaming::stream`]: given what the robot measured and the
/// time since the start (s), it writes the next command into the last argument and returns
/// true when that command is the last. It runs on the robot's loop: it must not allocate,
/// lock or log.
pub type Generator<'a> = dyn FnMut(&Measured<'_>, f64, &mut [f64]) -> bool + Send + 'a;

/// An empty vector with room for `n` values whose memory has been written once, for what
/// a realtime loop records: filling it later faults no page in (a first touch inside the
/// loop is a page fault, which waits on the process's memory map — held at times by
/// threads of normal priority — and, on a huge page, on the kernel zeroing or compacting
/// megabytes: milliseconds a 1 kHz loop does not have).
pub fn prefaulted<T: Default + Clone>(n: usize) -> Vec<T> {
    // Written element by element: `vec![0; n]` would take zeroed pages untouched.
    let mut v = Vec::with_capacity(n);
    v.resize(n, T::default());
    v.clear();
    v
}

/// A robot that takes one command per control period, computed from what it measured: a
/// movement generated online (a DMP stepped with phase stopping, which slows when the
/// robot lags). What cannot be checked before (the commands depend on the robot) is
/// checked command by command: [`crate::Guarded::stream`] checks the movement's nominal
/// plan first, then judges every command as it is made against every limit (unless the
/// robot's own loop does, [`Streaming::limits_each_command`]) and the shapes; a command
/// that would break one is not sent, and the robot stops. The command period is the
/// robot's [`Robot::command_period`].
pub trait Streaming: Robot {
    /// Whether the robot's own loop limits every command against the reference it holds
    /// (the Franka's, with the FCI's rules): the guard then leaves the limits to it, and
    /// judges the shapes only. Default: false, the guard judges every limit.
    fn limits_each_command(&self) -> bool {
        false
    }

    /// Runs `next` every [command period](Robot::command_period) from where the robot
    /// holds its position, at most `max_commands` times (then the robot brakes: the run is
    /// [`crate::Ending::Failed`]). `stop` brakes it. One entry per command period.
    fn stream(
        &mut self,
        next: &mut Generator<'_>,
        max_commands: usize,
        stop: &StopToken,
    ) -> Result<Run, RobotError>;
}

/// How cps's closed-loop executor ([`crate::execute`]) drives a [`Stepped`] robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Stepping {
    /// cps's controller commands joint positions, one step at a time (the in-process
    /// robot, a scene without cps's script).
    #[default]
    Joints,
    /// The robot moves its joints itself to follow a commanded tool target
    /// ([`Stepped::command_target`]), as CoppeliaSim's IK follows `/Panda_target`: the
    /// executor commands targets instead of running cps's controller. `plans`: whether it
    /// also runs whole plans cheaply (a scene with cps's script), for [`Robot::run`].
    Targets {
        /// It runs whole plans cheaply too.
        plans: bool,
    },
    /// Whole plans are cheaper than steps (a simulator running cps's scene script: a few
    /// exchanges a plan instead of several a step), or truer (an arm with dynamics runs in
    /// time, and iterating a sample until a lagging arm reaches it would stretch the
    /// movement): the executor plans the controller's commands on the model and runs them
    /// as one plan.
    Plans,
}

/// A robot that is stepped one period at a time (the in-process robot, CoppeliaSim, the
/// dynamics robot): commands take effect at the next [`Stepped::step`], which advances
/// [`Robot::dt`]. What it measures (joints, tool) and its period are the [`Robot`]'s;
/// stepping adds a clock, commands and the step. cps's closed-loop controller
/// ([`crate::execute`]) runs on it, and a [guarded](crate::Guarded) robot judges each
/// command as a plan's.
pub trait Stepped: Robot {
    /// The robot's clock (s).
    fn time(&mut self) -> Result<f64, RobotError>;
    /// Commands joint positions, reached at the next step.
    fn command_joint_positions(&mut self, q: &[f64]) -> Result<(), RobotError>;
    /// Advances one period ([`Robot::dt`]).
    fn step(&mut self) -> Result<(), RobotError>;
    /// How the executor drives it. Default: [`Stepping::Joints`].
    fn stepping(&self) -> Stepping {
        Stepping::Joints
    }
    /// Commands the tool target, followed from the next step on. Only for robots whose
    /// [`Stepped::stepping`] is [`Stepping::Targets`]; the default refuses.
    fn command_target(&mut self, target: &IkTarget) -> Result<(), RobotError> {
        let _ = target;
        Err(RobotError::Robot {
            robot: self.name(),
            message: "it does not follow tool targets; command joint positions".into(),
        })
    }
}

/// A robot behind a pointer is that robot: every method forwarded.
macro_rules! forward_robot {
    ($pointer:ty) => {
        impl<R: Robot + ?Sized> Robot for $pointer {
            fn name(&self) -> String {
                (**self).name()
            }
            fn model(&self) -> &RobotModel {
                (**self).model()
            }
            fn dt(&self) -> f64 {
                (**self).dt()
            }
            fn joint_positions(&mut self) -> Result<Vec<f64>, RobotError> {
                (**self).joint_positions()
            }
            fn command_period(&self) -> f64 {
                (**self).command_period()
            }
            fn standing(&mut self) -> Result<Option<Vec<f64>>, RobotError> {
                (**self).standing()
            }
            fn tool_pose(&mut self) -> Result<IsometryMatrix3<f64>, RobotError> {
                (**self).tool_pose()
            }
            fn run(&mut self, plan: &Plan, stop: &StopToken) -> Result<Run, RobotError> {
                (**self).run(plan, stop)
            }
            fn teleport(&mut self, q: &[f64]) -> Result<bool, RobotError> {
                (**self).teleport(q)
            }
            fn record(
                &mut self,
                duration: std::time::Duration,
                stop: &StopToken,
            ) -> Result<Run, RobotError> {
                (**self).record(duration, stop)
            }
            fn check(&mut self, plan: &Plan) -> Result<Option<Breach>, RobotError> {
                (**self).check(plan)
            }
            fn report(&self) -> Option<String> {
                (**self).report()
            }
            fn stepped(&mut self) -> Option<&mut dyn Stepped> {
                (**self).stepped()
            }
            fn streaming(&mut self) -> Option<&mut dyn Streaming> {
                (**self).streaming()
            }
        }
    };
}

forward_robot!(Box<R>);
forward_robot!(&mut R);

/// Runs a plan on a stepped robot: the plan's motion sampled at the robot's step
/// ([`Plan::samples`]: the points themselves when the plan is at the robot's period), each
/// sample after the first commanded and followed by one step, the joints, the tool and the
/// clock recorded after it. Each of the plan's points gets the step at its time. Stops (the
/// robot holds where it is) when `stop` is asked.
pub fn run_stepped(
    robot: &mut dyn Stepped,
    plan: &Plan,
    stop: &StopToken,
) -> Result<Run, RobotError> {
    plan.check_dof(robot.model().chain.dof())?;
    let dt = robot.dt();
    let samples = plan.samples(dt);
    let _moving = stop.moving(); // from the first command to the last
    let mut run = Run::new(crate::Ending::Finished);
    let t0 = robot.time()?;
    let mut times = vec![0.0];
    let mut q = vec![robot.joint_positions()?];
    let mut tool = vec![robot.tool_pose()?];
    for point in &samples[1..] {
        if stop.is_stopped() {
            run.ending = crate::Ending::Stopped;
            break;
        }
        // Once the robot has moved, a failure ends the run with what was recorded.
        let mut advance = || -> Result<_, RobotError> {
            robot.command_joint_positions(point)?;
            robot.step()?;
            Ok((
                robot.joint_positions()?,
                robot.tool_pose()?,
                robot.time()? - t0,
            ))
        };
        match advance() {
            Ok((qk, toolk, tk)) => {
                q.push(qk);
                tool.push(toolk);
                times.push(tk);
            }
            Err(e) if times.len() == 1 => return Err(e), // nothing moved
            Err(e) => {
                run.ending = crate::Ending::Failed(e.to_string());
                break;
            }
        }
    }
    if samples.len() == plan.points().len() && (plan.dt() - dt).abs() <= 1e-12 * dt {
        run.time = times;
        run.q = q;
        run.tool = tool;
        return Ok(run);
    }
    for k in 0..plan.points().len() {
        let i = step_of(plan, k, dt, samples.len());
        if i >= times.len() {
            break;
        }
        run.push(plan.time(k), q[i].clone(), tool[i]);
    }
    Ok(run)
}

/// The sample (of `samples` samples every `dt`, the last at the plan's end) at plan point
/// `k`'s time.
pub fn step_of(plan: &Plan, k: usize, dt: f64, samples: usize) -> usize {
    ((plan.time(k) / dt).round() as usize).min(samples - 1)
}

impl Stepping {
    /// Whether whole plans run cheaply on it ([`Stepping::Plans`], or targets with
    /// `plans`): a learner that runs thousands of plans needs it.
    pub fn runs_plans(self) -> bool {
        matches!(self, Stepping::Plans | Stepping::Targets { plans: true })
    }
}
