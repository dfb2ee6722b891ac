//! The Franka Control Interface on the wire, protocol version 10 (libfranka 0.18–0.21,
//! FR3 system 5.9 and later): fixed layouts decoded and encoded with their sizes checked,
//! no sockets.
//!
//! Everything is little-endian. TCP messages (port 1337) start with a 12-byte header
//! `u32 command, u32 command_id, u32 size` (size counts the header); a reply carries the
//! request's header fields and a status byte first. The robot sends its state as one
//! 1377-byte UDP datagram per tick ([`STATE_SIZE`]) and takes one 371-byte command back
//! ([`COMMAND_SIZE`]).
//!
//! Older versions differ: protocol 5 (libfranka 0.9–0.13, Panda) has a 2373-byte state
//! with f64 fields and no accelerometers; the version check of [`Request::Connect`]
//! refuses them before any state is read.

/// The protocol version cps speaks.
pub const PROTOCOL_VERSION: u16 = 10;
/// The robot's TCP command port.
pub const COMMAND_PORT: u16 = 1337;
/// Bytes of one robot state datagram.
pub const STATE_SIZE: usize = 1377;
/// Bytes of one command datagram.
pub const COMMAND_SIZE: usize = 371;
/// Bytes of a TCP message header.
pub const HEADER_SIZE: usize = 12;
/// Joints of a Franka arm.
pub const JOINTS: usize = 7;
/// Error and reflex flags in a state.
pub const ERROR_COUNT: usize = 41;

/// The TCP commands of protocol 10.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum CommandKind {
    /// Version check and the client's UDP port.
    Connect = 0,
    /// Start a motion or a controller.
    Move = 1,
    /// Stop the current motion.
    StopMove = 2,
    /// Contact and collision thresholds.
    SetCollisionBehavior = 3,
    /// The internal joint impedance's stiffness.
    SetJointImpedance = 4,
    /// The internal Cartesian impedance's stiffness.
    SetCartesianImpedance = 5,
    /// Guiding mode (not sent by cps: franky-sim stops stepping when it receives it).
    SetGuidingMode = 6,
    /// The stiffness frame relative to the end effector.
    SetEEToK = 7,
    /// The end effector relative to the nominal end effector.
    SetNEToEE = 8,
    /// The payload's mass, centre of mass and inertia.
    SetLoad = 9,
    /// Leave a reflex.
    AutomaticErrorRecovery = 10,
    /// The robot's URDF.
    GetRobotModel = 11,
}

impl CommandKind {
    /// The command for a wire number.
    pub fn from_u32(n: u32) -> Option<Self> {
        use CommandKind::*;
        Some(match n {
            0 => Connect,
            1 => Move,
            2 => StopMove,
            3 => SetCollisionBehavior,
            4 => SetJointImpedance,
            5 => SetCartesianImpedance,
            6 => SetGuidingMode,
            7 => SetEEToK,
            8 => SetNEToEE,
            9 => SetLoad,
            10 => AutomaticErrorRecovery,
            11 => GetRobotModel,
            _ => return None,
        })
    }

    /// The name libfranka uses, e.g. `Move`.
    pub fn name(self) -> &'static str {
        use CommandKind::*;
        match self {
            Connect => "Connect",
            Move => "Move",
            StopMove => "StopMove",
            SetCollisionBehavior => "SetCollisionBehavior",
            SetJointImpedance => "SetJointImpedance",
            SetCartesianImpedance => "SetCartesianImpedance",
            SetGuidingMode => "SetGuidingMode",
            SetEEToK => "SetEEToK",
            SetNEToEE => "SetNEToEE",
            SetLoad => "SetLoad",
            AutomaticErrorRecovery => "AutomaticErrorRecovery",
            GetRobotModel => "GetRobotModel",
        }
    }
}

/// Which controller a `Move` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControllerMode {
    /// The robot's joint impedance follows the motion generator.
    JointImpedance = 0,
    /// The robot's Cartesian impedance follows the motion generator.
    CartesianImpedance = 1,
    /// Torques computed by the client (gravity is added by the robot).
    ExternalController = 2,
}

/// Which motion generator a `Move` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionGeneratorMode {
    /// Joint positions `q_c`.
    JointPosition = 0,
    /// Joint velocities `dq_c`.
    JointVelocity = 1,
    /// The end effector's pose `O_T_EE_c`.
    CartesianPosition = 2,
    /// The end effector's twist `O_dP_EE_c`.
    CartesianVelocity = 3,
    /// No motion generator (torque control alone).
    None = 4,
}

/// The robot's operating mode, as its state reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RobotMode {
    /// Any other mode (for example the user stop being released).
    Other,
    /// Ready for a motion.
    Idle,
    /// Running a motion.
    Move,
    /// Being guided by hand.
    Guiding,
    /// Stopped by a reflex: needs error recovery.
    Reflex,
    /// The user stop is pressed.
    UserStopped,
    /// Recovering from an error.
    AutomaticErrorRecovery,
}

impl RobotMode {
    /// The mode for a state's byte; unknown values read as [`RobotMode::Other`].
    pub fn from_u8(b: u8) -> Self {
        match b {
            1 => RobotMode::Idle,
            2 => RobotMode::Move,
            3 => RobotMode::Guiding,
            4 => RobotMode::Reflex,
            5 => RobotMode::UserStopped,
            6 => RobotMode::AutomaticErrorRecovery,
            _ => RobotMode::Other,
        }
    }

    /// A short name: `idle`, `move`, `reflex`, ….
    pub fn name(self) -> &'static str {
        match self {
            RobotMode::Other => "other",
            RobotMode::Idle => "idle",
            RobotMode::Move => "move",
            RobotMode::Guiding => "guiding",
            RobotMode::Reflex => "reflex",
            RobotMode::UserStopped => "user_stopped",
            RobotMode::AutomaticErrorRecovery => "automatic_error_recovery",
        }
    }

    /// What the mode means for a client, as a sentence.
    pub fn sentence(self) -> &'static str {
        match self {
            RobotMode::Other => {
                "the robot is in no controllable mode (its brakes may be closed, or the FCI not activated in Desk)"
            }
            RobotMode::Idle => "the robot is idle and ready",
            RobotMode::Move => "the robot is executing a motion",
            RobotMode::Guiding => "the robot is being guided by hand",
            RobotMode::Reflex => "the robot is in a reflex and needs error recovery",
            RobotMode::UserStopped => "the user stop is pressed",
            RobotMode::AutomaticErrorRecovery => "the robot is recovering from an error",
        }
    }
}

/// The status of a `Move` reply: first [`MoveStatus::MotionStarted`] at once, then the
/// outcome under the same command id when the motion ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoveStatus {
    /// The motion ended as commanded.
    Success,
    /// The motion started; the outcome follows later.
    MotionStarted,
    /// Another command preempted the motion.
    Preempted,
    /// A safety function preempted the motion.
    PreemptedDueToActivatedSafetyFunctions,
    /// A safety function is active: the motion was not started.
    CommandRejectedDueToActivatedSafetyFunctions,
    /// The robot cannot run a motion now (not idle, or another motion running).
    CommandNotPossibleRejected,
    /// The motion would start at a singular pose.
    StartAtSingularPoseRejected,
    /// An argument of the `Move` was invalid.
    InvalidArgumentRejected,
    /// A reflex aborted the motion.
    ReflexAborted,
    /// The emergency stop aborted the motion.
    EmergencyAborted,
    /// An input error aborted the motion.
    InputErrorAborted,
    /// The motion was aborted.
    Aborted,
    /// A status byte this version does not define.
    Unknown(u8),
}

impl MoveStatus {
    /// The status of a reply byte.
    pub fn from_u8(b: u8) -> Self {
        use MoveStatus::*;
        match b {
            0 => Success,
            1 => MotionStarted,
            2 => Preempted,
            3 => PreemptedDueToActivatedSafetyFunctions,
            4 => CommandRejectedDueToActivatedSafetyFunctions,
            5 => CommandNotPossibleRejected,
            6 => StartAtSingularPoseRejected,
            7 => InvalidArgumentRejected,
            8 => ReflexAborted,
            9 => EmergencyAborted,
            10 => InputErrorAborted,
            11 => Aborted,
            other => Unknown(other),
        }
    }

    /// The status as a sentence a user can act on.
    pub fn sentence(self) -> String {
        use MoveStatus::*;
        match self {
            Success => "the motion finished".into(),
            MotionStarted => "the motion started".into(),
            Preempted => "the motion was preempted by another command".into(),
            PreemptedDueToActivatedSafetyFunctions => {
                "the motion was preempted by an activated safety function".into()
            }
            CommandRejectedDueToActivatedSafetyFunctions => {
                "the motion was refused: a safety function is active".into()
            }
            CommandNotPossibleRejected => {
                "the motion was refused: the robot cannot start a motion now (is it idle, with the FCI active and the user stop released?)".into()
            }
            StartAtSingularPoseRejected => "the motion was refused: it starts at a singular pose".into(),
            InvalidArgumentRejected => "the motion was refused: an argument was invalid".into(),
            ReflexAborted => "the motion was aborted by a reflex".into(),
            EmergencyAborted => "the motion was aborted by the emergency stop".into(),
            InputErrorAborted => "the motion was aborted by an input error".into(),
            Aborted => "the motion was aborted".into(),
            Unknown(b) => format!("the robot answered the motion with status {b}, unknown to protocol 10"),
        }
    }
}

/// The 41 error and reflex flags, in the order of the state's bytes: libfranka's
/// `research_interface::robot::Error` enum (not the order of the fields of its public
/// `franka::Errors`, which differs from the 24th on; franka-sim's table is the test's
/// reference, `tests/franka_sim.rs`).
pub const ERROR_NAMES: [&str; ERROR_COUNT] = [
    "joint_position_limits_violation",
    "cartesian_position_limits_violation",
    "self_collision_avoidance_violation",
    "joint_velocity_violation",
    "cartesian_velocity_violation",
    "force_control_safety_violation",
    "joint_reflex",
    "cartesian_reflex",
    "max_goal_pose_deviation_violation",
    "max_path_pose_deviation_violation",
    "cartesian_velocity_profile_safety_violation",
    "joint_position_motion_generator_start_pose_invalid",
    "joint_motion_generator_position_limits_violation",
    "joint_motion_generator_velocity_limits_violation",
    "joint_motion_generator_velocity_discontinuity",
    "joint_motion_generator_acceleration_discontinuity",
    "cartesian_position_motion_generator_start_pose_invalid",
    "cartesian_motion_generator_elbow_limit_violation",
    "cartesian_motion_generator_velocity_limits_violation",
    "cartesian_motion_generator_velocity_discontinuity",
    "cartesian_motion_generator_acceleration_discontinuity",
    "cartesian_motion_generator_elbow_sign_inconsistent",
    "cartesian_motion_generator_start_elbow_invalid",
    "force_controller_desired_force_tolerance_violation",
    "start_elbow_sign_inconsistent",
    "communication_constraints_violation",
    "power_limit_violation",
    "cartesian_motion_generator_joint_position_limits_violation",
    "cartesian_motion_generator_joint_velocity_limits_violation",
    "cartesian_motion_generator_joint_velocity_discontinuity",
    "cartesian_motion_generator_joint_acceleration_discontinuity",
    "cartesian_position_motion_generator_invalid_frame",
    "controller_torque_discontinuity",
    "joint_p2p_insufficient_torque_for_planning",
    "tau_j_range_violation",
    "instability_detected",
    "joint_move_in_wrong_direction",
    "cartesian_spline_motion_generator_violation",
    "joint_via_motion_generator_planning_joint_limit_violation",
    "base_acceleration_initialization_timeout",
    "base_acceleration_invalid_reading",
];

/// A set of the 41 error flags.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Errors(pub [bool; ERROR_COUNT]);

impl Default for Errors {
    fn default() -> Self {
        Errors([false; ERROR_COUNT])
    }
}

impl Errors {
    /// Whether any flag is set.
    pub fn any(&self) -> bool {
        self.0.iter().any(|&b| b)
    }

    /// The names of the set flags, in order.
    pub fn names(&self) -> Vec<&'static str> {
        self.0
            .iter()
            .zip(ERROR_NAMES)
            .filter_map(|(&b, n)| b.then_some(n))
            .collect()
    }

    /// The set flags as one phrase: `joint_reflex, cartesian_reflex`, or `none`.
    pub fn describe(&self) -> String {
        let names = self.names();
        if names.is_empty() {
            "none".into()
        } else {
            names.join(", ")
        }
    }
}

/// One robot state, decoded from its datagram. Matrices are 4 × 4 column-major.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotState {
    /// The robot's tick counter (milliseconds).
    pub message_id: u64,
    /// Measured end-effector pose in the base frame.
    pub o_t_ee: [f64; 16],
    /// Last desired end-effector pose.
    pub o_t_ee_d: [f64; 16],
    /// End effector in the flange frame.
    pub f_t_ee: [f64; 16],
    /// Stiffness frame in the end-effector frame.
    pub ee_t_k: [f64; 16],
    /// Nominal end effector in the flange frame.
    pub f_t_ne: [f64; 16],
    /// End effector in the nominal end-effector frame.
    pub ne_t_ee: [f64; 16],
    /// Configured end-effector mass (kg).
    pub m_ee: f64,
    /// Configured end-effector inertia (column-major 3 × 3).
    pub i_ee: [f64; 9],
    /// Configured end-effector centre of mass in the flange frame.
    pub f_x_cee: [f64; 3],
    /// Configured load mass (kg).
    pub m_load: f64,
    /// Configured load inertia.
    pub i_load: [f64; 9],
    /// Configured load centre of mass in the flange frame.
    pub f_x_cload: [f64; 3],
    /// Elbow configuration (joint 3's position, sign of joint 4).
    pub elbow: [f64; 2],
    /// Desired elbow configuration.
    pub elbow_d: [f64; 2],
    /// Measured link-side joint torques (N m).
    pub tau_j: [f64; 7],
    /// Desired link-side joint torques without gravity (N m).
    pub tau_j_d: [f64; 7],
    /// Derivative of the measured torques (N m/s).
    pub dtau_j: [f64; 7],
    /// Measured joint positions (rad).
    pub q: [f64; 7],
    /// Desired joint positions (rad).
    pub q_d: [f64; 7],
    /// Measured joint velocities (rad/s).
    pub dq: [f64; 7],
    /// Desired joint velocities (rad/s).
    pub dq_d: [f64; 7],
    /// Desired joint accelerations (rad/s²).
    pub ddq_d: [f64; 7],
    /// Contact level per joint (0 or 1).
    pub joint_contact: [f64; 7],
    /// Contact level per Cartesian direction.
    pub cartesian_contact: [f64; 6],
    /// Collision level per joint.
    pub joint_collision: [f64; 7],
    /// Collision level per Cartesian direction.
    pub cartesian_collision: [f64; 6],
    /// The robot's filtered external torque estimate (N m).
    pub tau_ext_hat_filtered: [f64; 7],
    /// The robot's external wrench estimate in the base frame.
    pub o_f_ext_hat_k: [f64; 6],
    /// The robot's external wrench estimate in the stiffness frame.
    pub k_f_ext_hat_k: [f64; 6],
    /// Desired end-effector twist in the base frame.
    pub o_dp_ee_d: [f64; 6],
    /// Linear acceleration of the base (m/s²).
    pub o_ddp_o: [f64; 3],
    /// Commanded elbow configuration.
    pub elbow_c: [f64; 2],
    /// Commanded elbow velocity.
    pub delbow_c: [f64; 2],
    /// Commanded elbow acceleration.
    pub ddelbow_c: [f64; 2],
    /// Last commanded end-effector pose.
    pub o_t_ee_c: [f64; 16],
    /// Last commanded end-effector twist.
    pub o_dp_ee_c: [f64; 6],
    /// Last commanded end-effector acceleration.
    pub o_ddp_ee_c: [f64; 6],
    /// Motor positions (rad).
    pub theta: [f64; 7],
    /// Motor velocities (rad/s).
    pub dtheta: [f64; 7],
    /// The top accelerometer's readings.
    pub accelerometer_top: [f64; 18],
    /// The bottom accelerometer's readings.
    pub accelerometer_bottom: [f64; 18],
    /// The motion generator running (state numbering: 0 idle, 1 joint position, …, 5 none).
    pub motion_generator_mode: u8,
    /// The controller running (0 joint impedance, 1 Cartesian impedance, 2 external, 3 other).
    pub controller_mode: u8,
    /// Errors active now.
    pub errors: Errors,
    /// Errors that ended the last motion (the reflex's reason).
    pub reflex_reason: Errors,
    /// The robot's mode.
    pub robot_mode: RobotMode,
    /// Share of commands that arrived in time over the last 100 ms (1.0 = all).
    pub control_command_success_rate: f64,
}

/// A little-endian reader over a fixed buffer whose size was checked up front.
struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn u8(&mut self) -> u8 {
        let b = self.buf[self.at];
        self.at += 1;
        b
    }

    fn f32(&mut self) -> f64 {
        let b: [u8; 4] = self.buf[self.at..self.at + 4].try_into().expect("4 bytes");
        self.at += 4;
        f64::from(f32::from_le_bytes(b))
    }

    fn f32s<const N: usize>(&mut self) -> [f64; N] {
        let mut out = [0.0; N];
        for x in &mut out {
            *x = self.f32();
        }
        out
    }

    fn flags(&mut self) -> Errors {
        let mut e = [false; ERROR_COUNT];
        for x in &mut e {
            *x = self.u8() != 0;
        }
        Errors(e)
    }
}

/// Why a datagram or a reply could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum WireError {
    /// A datagram or payload had the wrong size.
    #[error("{what} has {got} bytes but protocol 10 has {expected}")]
    Size {
        /// What was decoded.
        what: &'static str,
        /// Its size.
        got: usize,
        /// The protocol's size.
        expected: usize,
    },
    /// A reply named an unknown command or was shorter than its header.
    #[error("malformed reply: {0}")]
    Malformed(String),
}

impl RobotState {
    /// Decodes one state datagram; its size must be exactly [`STATE_SIZE`].
    pub fn decode(buf: &[u8]) -> Result<Self, WireError> {
        if buf.len() != STATE_SIZE {
            return Err(WireError::Size {
                what: "the robot state datagram",
                got: buf.len(),
                expected: STATE_SIZE,
            });
        }
        let message_id = u64::from_le_bytes(buf[..8].try_into().expect("8 bytes"));
        let mut r = Reader { buf, at: 8 };
        let s = RobotState {
            message_id,
            o_t_ee: r.f32s(),
            o_t_ee_d: r.f32s(),
            f_t_ee: r.f32s(),
            ee_t_k: r.f32s(),
            f_t_ne: r.f32s(),
            ne_t_ee: r.f32s(),
            m_ee: r.f32(),
            i_ee: r.f32s(),
            f_x_cee: r.f32s(),
            m_load: r.f32(),
            i_load: r.f32s(),
            f_x_cload: r.f32s(),
            elbow: r.f32s(),
            elbow_d: r.f32s(),
            tau_j: r.f32s(),
            tau_j_d: r.f32s(),
            dtau_j: r.f32s(),
            q: r.f32s(),
            q_d: r.f32s(),
            dq: r.f32s(),
            dq_d: r.f32s(),
            ddq_d: r.f32s(),
            joint_contact: r.f32s(),
            cartesian_contact: r.f32s(),
            joint_collision: r.f32s(),
            cartesian_collision: r.f32s(),
            tau_ext_hat_filtered: r.f32s(),
            o_f_ext_hat_k: r.f32s(),
            k_f_ext_hat_k: r.f32s(),
            o_dp_ee_d: r.f32s(),
            o_ddp_o: r.f32s(),
            elbow_c: r.f32s(),
            delbow_c: r.f32s(),
            ddelbow_c: r.f32s(),
            o_t_ee_c: r.f32s(),
            o_dp_ee_c: r.f32s(),
            o_ddp_ee_c: r.f32s(),
            theta: r.f32s(),
            dtheta: r.f32s(),
            accelerometer_top: r.f32s(),
            accelerometer_bottom: r.f32s(),
            motion_generator_mode: r.u8(),
            controller_mode: r.u8(),
            errors: r.flags(),
            reflex_reason: r.flags(),
            robot_mode: RobotMode::from_u8(r.u8()),
            control_command_success_rate: r.f32(),
        };
        debug_assert_eq!(r.at, STATE_SIZE);
        Ok(s)
    }

    /// Encodes the state into its datagram (for fake robots in tests; f32 fields round).
    pub fn encode(&self, out: &mut [u8; STATE_SIZE]) {
        let mut w = Writer { buf: out, at: 0 };
        w.bytes(&self.message_id.to_le_bytes());
        for x in [
            &self.o_t_ee[..],
            &self.o_t_ee_d,
            &self.f_t_ee,
            &self.ee_t_k,
            &self.f_t_ne,
            &self.ne_t_ee,
            &[self.m_ee],
            &self.i_ee,
            &self.f_x_cee,
            &[self.m_load],
            &self.i_load,
            &self.f_x_cload,
            &self.elbow,
            &self.elbow_d,
            &self.tau_j,
            &self.tau_j_d,
            &self.dtau_j,
            &self.q,
            &self.q_d,
            &self.dq,
            &self.dq_d,
            &self.ddq_d,
            &self.joint_contact,
            &self.cartesian_contact,
            &self.joint_collision,
            &self.cartesian_collision,
            &self.tau_ext_hat_filtered,
            &self.o_f_ext_hat_k,
            &self.k_f_ext_hat_k,
            &self.o_dp_ee_d,
            &self.o_ddp_o,
            &self.elbow_c,
            &self.delbow_c,
            &self.ddelbow_c,
            &self.o_t_ee_c,
            &self.o_dp_ee_c,
            &self.o_ddp_ee_c,
            &self.theta,
            &self.dtheta,
            &self.accelerometer_top,
            &self.accelerometer_bottom,
        ] {
            w.f32s(x);
        }
        w.bytes(&[self.motion_generator_mode, self.controller_mode]);
        for flags in [self.errors, self.reflex_reason] {
            for b in flags.0 {
                w.bytes(&[u8::from(b)]);
            }
        }
        let mode = match self.robot_mode {
            RobotMode::Other => 0u8,
            RobotMode::Idle => 1,
            RobotMode::Move => 2,
            RobotMode::Guiding => 3,
            RobotMode::Reflex => 4,
            RobotMode::UserStopped => 5,
            RobotMode::AutomaticErrorRecovery => 6,
        };
        w.bytes(&[mode]);
        w.f32s(&[self.control_command_success_rate]);
        debug_assert_eq!(w.at, STATE_SIZE);
    }

    /// The end effector's position in the base frame (m).
    pub fn tool_position(&self) -> [f64; 3] {
        [self.o_t_ee[12], self.o_t_ee[13], self.o_t_ee[14]]
    }
}

/// A little-endian writer into a fixed buffer.
struct Writer<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) {
        self.buf[self.at..self.at + b.len()].copy_from_slice(b);
        self.at += b.len();
    }

    fn f64s(&mut self, x: &[f64]) {
        for v in x {
            self.bytes(&v.to_le_bytes());
        }
    }

    fn f32s(&mut self, x: &[f64]) {
        for &v in x {
            self.bytes(&(v as f32).to_le_bytes());
        }
    }
}

/// One command datagram: the motion generator's part and the controller's part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    /// The state's message id this command answers.
    pub message_id: u64,
    /// Commanded joint positions (joint position generator).
    pub q_c: [f64; 7],
    /// Commanded joint velocities (joint velocity generator).
    pub dq_c: [f64; 7],
    /// Commanded end-effector pose (Cartesian position generator).
    pub o_t_ee_c: [f64; 16],
    /// Commanded end-effector twist (Cartesian velocity generator).
    pub o_dp_ee_c: [f64; 6],
    /// Commanded elbow.
    pub elbow_c: [f64; 2],
    /// Whether `elbow_c` is used.
    pub valid_elbow: bool,
    /// Set on the last command of a motion: the robot then answers the `Move` with its outcome.
    pub motion_generation_finished: bool,
    /// Commanded joint torques without gravity (external controller).
    pub tau_j_d: [f64; 7],
    /// Set on the last command of a torque-controlled motion.
    pub torque_command_finished: bool,
}

impl Default for Command {
    fn default() -> Self {
        Command {
            message_id: 0,
            q_c: [0.0; 7],
            dq_c: [0.0; 7],
            o_t_ee_c: [0.0; 16],
            o_dp_ee_c: [0.0; 6],
            elbow_c: [0.0; 2],
            valid_elbow: false,
            motion_generation_finished: false,
            tau_j_d: [0.0; 7],
            torque_command_finished: false,
        }
    }
}

impl Command {
    /// Encodes the command into exactly [`COMMAND_SIZE`] bytes (no allocation).
    pub fn encode(&self, out: &mut [u8; COMMAND_SIZE]) {
        let mut w = Writer { buf: out, at: 0 };
        w.bytes(&self.message_id.to_le_bytes());
        w.f64s(&self.q_c);
        w.f64s(&self.dq_c);
        w.f64s(&self.o_t_ee_c);
        w.f64s(&self.o_dp_ee_c);
        w.f64s(&self.elbow_c);
        w.bytes(&[
            u8::from(self.valid_elbow),
            u8::from(self.motion_generation_finished),
        ]);
        w.f64s(&self.tau_j_d);
        w.bytes(&[u8::from(self.torque_command_finished)]);
        debug_assert_eq!(w.at, COMMAND_SIZE);
    }

    /// Decodes a command datagram (for tests and fake robots).
    pub fn decode(buf: &[u8]) -> Result<Self, WireError> {
        if buf.len() != COMMAND_SIZE {
            return Err(WireError::Size {
                what: "the command datagram",
                got: buf.len(),
                expected: COMMAND_SIZE,
            });
        }
        let mut at = 8;
        let mut f = |out: &mut [f64]| {
            for x in out {
                *x = f64::from_le_bytes(buf[at..at + 8].try_into().expect("8 bytes"));
                at += 8;
            }
        };
        let mut c = Command {
            message_id: u64::from_le_bytes(buf[..8].try_into().expect("8 bytes")),
            ..Command::default()
        };
        f(&mut c.q_c);
        f(&mut c.dq_c);
        f(&mut c.o_t_ee_c);
        f(&mut c.o_dp_ee_c);
        f(&mut c.elbow_c);
        c.valid_elbow = buf[at] != 0;
        c.motion_generation_finished = buf[at + 1] != 0;
        at += 2;
        let mut f = |out: &mut [f64]| {
            for x in out {
                *x = f64::from_le_bytes(buf[at..at + 8].try_into().expect("8 bytes"));
                at += 8;
            }
        };
        f(&mut c.tau_j_d);
        c.torque_command_finished = buf[at] != 0;
        Ok(c)
    }
}

/// Contact and collision thresholds of `SetCollisionBehavior` (N m per joint, N and N m per
/// Cartesian direction); "acceleration" thresholds apply while the robot accelerates,
/// "nominal" ones otherwise. Above a lower threshold the state reports contact; above an
/// upper one the robot stops with a reflex.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollisionBehavior {
    /// Joint contact thresholds while accelerating.
    pub lower_torque_acceleration: [f64; 7],
    /// Joint collision thresholds while accelerating.
    pub upper_torque_acceleration: [f64; 7],
    /// Joint contact thresholds otherwise.
    pub lower_torque_nominal: [f64; 7],
    /// Joint collision thresholds otherwise.
    pub upper_torque_nominal: [f64; 7],
    /// Cartesian contact thresholds while accelerating.
    pub lower_force_acceleration: [f64; 6],
    /// Cartesian collision thresholds while accelerating.
    pub upper_force_acceleration: [f64; 6],
    /// Cartesian contact thresholds otherwise.
    pub lower_force_nominal: [f64; 6],
    /// Cartesian collision thresholds otherwise.
    pub upper_force_nominal: [f64; 6],
}

impl CollisionBehavior {
    /// The same thresholds for every joint and direction.
    pub fn uniform(
        lower_torque: f64,
        upper_torque: f64,
        lower_force: f64,
        upper_force: f64,
    ) -> Self {
        CollisionBehavior {
            lower_torque_acceleration: [lower_torque; 7],
            upper_torque_acceleration: [upper_torque; 7],
            lower_torque_nominal: [lower_torque; 7],
            upper_torque_nominal: [upper_torque; 7],
            lower_force_acceleration: [lower_force; 6],
            upper_force_acceleration: [upper_force; 6],
            lower_force_nominal: [lower_force; 6],
            upper_force_nominal: [upper_force; 6],
        }
    }
}

/// A TCP request of protocol 10 with its payload.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)] // a few hundred bytes, built once per command
pub enum Request {
    /// `u16 version, u16 udp_port`.
    Connect {
        /// The client's protocol version.
        version: u16,
        /// The client's UDP port that the robot sends its state to.
        udp_port: u16,
    },
    /// Start a motion: modes and the path and goal deviations (translation, rotation, elbow).
    Move {
        /// The controller.
        controller: ControllerMode,
        /// The motion generator.
        generator: MotionGeneratorMode,
        /// Largest deviation from the commanded path.
        maximum_path_deviation: [f64; 3],
        /// Largest deviation from the commanded goal.
        maximum_goal_pose_deviation: [f64; 3],
    },
    /// Stop the current motion.
    StopMove,
    /// Contact and collision thresholds.
    SetCollisionBehavior(CollisionBehavior),
    /// Joint stiffness (N m/rad).
    SetJointImpedance([f64; 7]),
    /// Cartesian stiffness (N/m, N m/rad).
    SetCartesianImpedance([f64; 6]),
    /// Stiffness frame in the end-effector frame.
    SetEEToK([f64; 16]),
    /// End effector in the nominal end-effector frame.
    SetNEToEE([f64; 16]),
    /// Load: mass, centre of mass in the flange frame, inertia (column-major).
    SetLoad {
        /// kg.
        mass: f64,
        /// m.
        center_of_mass: [f64; 3],
        /// kg m².
        inertia: [f64; 9],
    },
    /// Leave a reflex.
    AutomaticErrorRecovery,
    /// The robot's URDF.
    GetRobotModel,
}

impl Request {
    /// The request's command.
    pub fn kind(&self) -> CommandKind {
        match self {
            Request::Connect { .. } => CommandKind::Connect,
            Request::Move { .. } => CommandKind::Move,
            Request::StopMove => CommandKind::StopMove,
            Request::SetCollisionBehavior(_) => CommandKind::SetCollisionBehavior,
            Request::SetJointImpedance(_) => CommandKind::SetJointImpedance,
            Request::SetCartesianImpedance(_) => CommandKind::SetCartesianImpedance,
            Request::SetEEToK(_) => CommandKind::SetEEToK,
            Request::SetNEToEE(_) => CommandKind::SetNEToEE,
            Request::SetLoad { .. } => CommandKind::SetLoad,
            Request::AutomaticErrorRecovery => CommandKind::AutomaticErrorRecovery,
            Request::GetRobotModel => CommandKind::GetRobotModel,
        }
    }

    /// The whole message: header then payload.
    pub fn encode(&self, command_id: u32) -> Vec<u8> {
        let mut payload = Vec::with_capacity(512);
        let f64s = |p: &mut Vec<u8>, x: &[f64]| {
            for v in x {
                p.extend_from_slice(&v.to_le_bytes());
            }
        };
        match self {
            Request::Connect { version, udp_port } => {
                payload.extend_from_slice(&version.to_le_bytes());
                payload.extend_from_slice(&udp_port.to_le_bytes());
            }
            Request::Move {
                controller,
                generator,
                maximum_path_deviation,
                maximum_goal_pose_deviation,
            } => {
                payload.extend_from_slice(&(*controller as u32).to_le_bytes());
                payload.extend_from_slice(&(*generator as u32).to_le_bytes());
                f64s(&mut payload, maximum_path_deviation);
                f64s(&mut payload, maximum_goal_pose_deviation);
            }
            Request::StopMove | Request::AutomaticErrorRecovery | Request::GetRobotModel => {}
            Request::SetCollisionBehavior(c) => {
                for x in [
                    &c.lower_torque_acceleration[..],
                    &c.upper_torque_acceleration,
                    &c.lower_torque_nominal,
                    &c.upper_torque_nominal,
                    &c.lower_force_acceleration,
                    &c.upper_force_acceleration,
                    &c.lower_force_nominal,
                    &c.upper_force_nominal,
                ] {
                    f64s(&mut payload, x);
                }
            }
            Request::SetJointImpedance(k) => f64s(&mut payload, k),
            Request::SetCartesianImpedance(k) => f64s(&mut payload, k),
            Request::SetEEToK(m) | Request::SetNEToEE(m) => f64s(&mut payload, m),
            Request::SetLoad {
                mass,
                center_of_mass,
                inertia,
            } => {
                f64s(&mut payload, &[*mass]);
                f64s(&mut payload, center_of_mass);
                f64s(&mut payload, inertia);
            }
        }
        let mut msg = Vec::with_capacity(HEADER_SIZE + payload.len());
        msg.extend_from_slice(&(self.kind() as u32).to_le_bytes());
        msg.extend_from_slice(&command_id.to_le_bytes());
        msg.extend_from_slice(&((HEADER_SIZE + payload.len()) as u32).to_le_bytes());
        msg.extend_from_slice(&payload);
        msg
    }
}

/// A reply's header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// The command answered.
    pub command: CommandKind,
    /// The request's id.
    pub command_id: u32,
    /// Bytes of the payload after the header.
    pub payload_len: usize,
}

impl Header {
    /// Decodes a header; `size` must count at least the header itself.
    pub fn decode(buf: &[u8; HEADER_SIZE]) -> Result<Self, WireError> {
        let word = |i: usize| u32::from_le_bytes(buf[i..i + 4].try_into().expect("4 bytes"));
        let command = CommandKind::from_u32(word(0)).ok_or_else(|| {
            WireError::Malformed(format!("command number {} is not in protocol 10", word(0)))
        })?;
        let size = word(8) as usize;
        if size < HEADER_SIZE {
            return Err(WireError::Malformed(format!(
                "a {} reply declares {size} bytes, fewer than its {HEADER_SIZE}-byte header",
                command.name()
            )));
        }
        Ok(Header {
            command,
            command_id: word(4),
            payload_len: size - HEADER_SIZE,
        })
    }
}

/// The status and version of a `Connect` reply. libfranka reads `u8 status, u16 version`
/// (3 bytes, packed); franky-sim sends `u16 status, u16 version` and 4 padding bytes, so
/// both are accepted by their length.
pub fn decode_connect_reply(payload: &[u8]) -> Result<(u8, u16), WireError> {
    match payload.len() {
        3 => Ok((payload[0], u16::from_le_bytes([payload[1], payload[2]]))),
        n if n >= 4 => Ok((
            u16::from_le_bytes([payload[0], payload[1]]).min(255) as u8,
            u16::from_le_bytes([payload[2], payload[3]]),
        )),
        n => Err(WireError::Size {
            what: "the Connect reply",
            got: n,
            expected: 3,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_round_trips_and_has_protocol_size() {
        let mut c = Command {
            message_id: 0x0102_0304_0506_0708,
            motion_generation_finished: true,
            torque_command_finished: true,
            ..Command::default()
        };
        for i in 0..7 {
            c.q_c[i] = i as f64 * 0.5 - 1.0;
            c.dq_c[i] = -(i as f64);
            c.tau_j_d[i] = 1e-3 * i as f64;
        }
        c.o_t_ee_c[15] = 1.0;
        let mut buf = [0u8; COMMAND_SIZE];
        c.encode(&mut buf);
        assert_eq!(Command::decode(&buf).unwrap(), c);
        // The layout: q_c right after the id, the finished flags at 312 and 313, tau at 314.
        assert_eq!(&buf[8..16], &(-1.0f64).to_le_bytes());
        assert_eq!(buf[313], 1);
        assert_eq!(&buf[314 + 8..322 + 8], &1e-3f64.to_le_bytes());
        assert_eq!(buf[370], 1);
        assert!(Command::decode(&buf[..370]).is_err());
    }

    #[test]
    fn state_fields_sit_at_the_documented_offsets() {
        let mut buf = vec![0u8; STATE_SIZE];
        buf[..8].copy_from_slice(&42u64.to_le_bytes());
        buf[596..600].copy_from_slice(&0.25f32.to_le_bytes()); // q[0]
        buf[652 + 24..652 + 28].copy_from_slice(&(-1.5f32).to_le_bytes()); // dq[6]
        buf[1290 + 6] = 1; // errors: joint_reflex
        buf[1331 + 25] = 1; // reflex reason: communication_constraints_violation
        buf[1372] = 4; // reflex mode
        buf[1373..].copy_from_slice(&0.5f32.to_le_bytes());
        let s = RobotState::decode(&buf).unwrap();
        assert_eq!(s.message_id, 42);
        assert_eq!(s.q[0], 0.25);
        assert_eq!(s.dq[6], -1.5);
        assert_eq!(s.errors.names(), ["joint_reflex"]);
        assert_eq!(
            s.reflex_reason.describe(),
            "communication_constraints_violation"
        );
        assert_eq!(s.robot_mode, RobotMode::Reflex);
        assert_eq!(s.control_command_success_rate, 0.5);
        let mut again = [0u8; STATE_SIZE];
        s.encode(&mut again);
        assert_eq!(&again[..], &buf[..], "encode is decode's inverse");
        let err = RobotState::decode(&buf[..1376]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "the robot state datagram has 1376 bytes but protocol 10 has 1377"
        );
    }

    #[test]
    fn requests_have_their_protocol_sizes() {
        let sizes = [
            (
                Request::Connect {
                    version: 10,
                    udp_port: 5,
                },
                4,
            ),
            (
                Request::Move {
                    controller: ControllerMode::JointImpedance,
                    generator: MotionGeneratorMode::JointPosition,
                    maximum_path_deviation: [0.0; 3],
                    maximum_goal_pose_deviation: [0.0; 3],
                },
                56,
            ),
            (Request::StopMove, 0),
            (
                Request::SetCollisionBehavior(CollisionBehavior::uniform(1.0, 2.0, 3.0, 4.0)),
                416,
            ),
            (Request::SetJointImpedance([1.0; 7]), 56),
            (Request::SetCartesianImpedance([1.0; 6]), 48),
            (Request::SetEEToK([0.0; 16]), 128),
            (Request::SetNEToEE([0.0; 16]), 128),
            (
                Request::SetLoad {
                    mass: 1.0,
                    center_of_mass: [0.0; 3],
                    inertia: [0.0; 9],
                },
                104,
            ),
            (Request::AutomaticErrorRecovery, 0),
            (Request::GetRobotModel, 0),
        ];
        for (req, payload) in sizes {
            let msg = req.encode(7);
            assert_eq!(msg.len(), HEADER_SIZE + payload, "{:?}", req.kind());
            let h = Header::decode(msg[..12].try_into().unwrap()).unwrap();
            assert_eq!(
                (h.command, h.command_id, h.payload_len),
                (req.kind(), 7, payload)
            );
        }
    }

    #[test]
    fn connect_replies_of_both_layouts() {
        assert_eq!(decode_connect_reply(&[0, 10, 0]).unwrap(), (0, 10));
        assert_eq!(
            decode_connect_reply(&[1, 0, 9, 0, 0, 0, 0, 0]).unwrap(),
            (1, 9)
        );
        assert!(decode_connect_reply(&[0, 1]).is_err());
        let bad = Header::decode(&[99, 0, 0, 0, 1, 0, 0, 0, 12, 0, 0, 0]).unwrap_err();
        assert!(bad.to_string().contains("99"), "{bad}");
    }
}
