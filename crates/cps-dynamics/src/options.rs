//! A dynamics robot from words: the robot's model (with its link inertias) and the
//! options an experiment's `[robot] backend = "dynamics"` gives — controller by name with
//! its gains, the joints' drive, the integrator, noise — checked, with sentences that name
//! what is wrong.

use cps_kinematics::contact::JointFriction;
use cps_kinematics::{ArmModel, LinkInertia};
use cps_robot::{Robot, RobotError, RobotModel};

use crate::arm::{Arm, FRANKY_SIM_ARMATURE, FRANKY_SIM_FRICTION, Integrator};
use crate::controller::{Controller, FRANKY_SIM_KP};
use crate::robot::{DynamicsRobot, DynamicsSettings};

/// What a joint's drive adds to the rigid bodies: the dynamics robot's plant, and what the
/// contact task's momentum observer must model beyond the rigid bodies where the robot's
/// torques are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Drive {
    /// franky-sim's FR3: [`FRANKY_SIM_ARMATURE`] and [`FRANKY_SIM_FRICTION`] (its reported
    /// torques are those it applies before them).
    #[default]
    FrankySim,
    /// Rigid bodies only: no rotor inertia, no friction (a Franka's torque sensors sit
    /// after the gears, so its measured torques need nothing more: `link` names it too).
    Rigid,
}

impl Drive {
    /// Every drive's name, for messages.
    pub const NAMES: &str = "franky-sim (franky-sim's FR3: rotor inertia and joint friction), rigid (or link: a Franka's torque sensors, after the gears)";

    /// By name: `franky-sim`, or `rigid` (also `link`).
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "franky-sim" => Some(Drive::FrankySim),
            "rigid" | "link" => Some(Drive::Rigid),
            _ => None,
        }
    }

    /// The name [`Drive::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Drive::FrankySim => "franky-sim",
            Drive::Rigid => "rigid",
        }
    }

    /// `model` with this drive's rotor inertia, and the drive's joint friction, on `N`
    /// joints (franky-sim's on seven; a longer arm repeats its last joint's values).
    pub fn apply<const N: usize>(
        self,
        model: ArmModel<N>,
    ) -> Result<(ArmModel<N>, JointFriction<N>), cps_kinematics::KinematicsError> {
        match self {
            Drive::Rigid => Ok((model, JointFriction::none())),
            Drive::FrankySim => {
                let f = FRANKY_SIM_FRICTION;
                let model =
                    model.with_armature(std::array::from_fn(|i| FRANKY_SIM_ARMATURE[i.min(6)]))?;
                Ok((
                    model,
                    JointFriction {
                        viscous: std::array::from_fn(|i| f.viscous[i.min(6)]),
                        coulomb: std::array::from_fn(|i| f.coulomb[i.min(6)]),
                        speed: f.speed,
                    },
                ))
            }
        }
    }
}

/// How to build a dynamics robot (`[robot] backend = "dynamics"`).
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicsOptions {
    /// The controller's name ([`crate::CONTROLLERS`]).
    pub controller: String,
    /// Its first gains (kp, or the impedance's stiffness), one per joint; None: its
    /// defaults ([`default_gains`]).
    pub kp: Option<Vec<f64>>,
    /// Its second gains (kv, or the impedance's damping).
    pub kv: Option<Vec<f64>>,
    /// The joints' drive.
    pub drive: Drive,
    /// The integrator.
    pub integrator: Integrator,
    /// Measurement noise (rad, standard deviation).
    pub noise: f64,
    /// The noise's seed.
    pub seed: u64,
    /// The period plans are made at (s).
    pub dt: f64,
    /// The control and integration period (s).
    pub control_period: f64,
    /// Whether a joint leaving its range stops the arm ([`crate::DynamicsSettings::reflexes`]).
    pub reflexes: bool,
    /// The controller and drives identified on a robot (`cps-cli identify`): they replace
    /// the drive, the gains and the lag.
    pub calibration: Option<CalibrationValues>,
}

/// A calibration's values for any joint count (see [`crate::Calibration`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationValues {
    /// The robot it was identified on (its model's name).
    pub robot: String,
    /// Position gains (N m/rad).
    pub kp: Vec<f64>,
    /// Velocity gains (N m s/rad).
    pub kv: Vec<f64>,
    /// The command's lag (control periods).
    pub lag: usize,
    /// Rotor inertia (kg m²).
    pub armature: Vec<f64>,
    /// Viscous friction (N m s/rad).
    pub viscous: Vec<f64>,
    /// Coulomb friction (N m).
    pub coulomb: Vec<f64>,
    /// The speed the Coulomb term fades over (rad/s).
    pub speed: f64,
}

impl CalibrationValues {
    /// The values of a calibration of `robot`.
    pub fn of<const N: usize>(robot: &str, c: &crate::Calibration<N>) -> Self {
        CalibrationValues {
            robot: robot.to_string(),
            kp: c.kp.to_vec(),
            kv: c.kv.to_vec(),
            lag: c.lag,
            armature: c.armature.to_vec(),
            viscous: c.friction.viscous.to_vec(),
            coulomb: c.friction.coulomb.to_vec(),
            speed: c.friction.speed,
        }
    }

    /// Checks it against a robot named `robot` with `n` joints and, where known, its
    /// drives' torque limits: the same robot, every list one value a joint, every value
    /// finite, the gains of a stable controller (kp > 0, kv ≥ 0), rotor inertia and
    /// friction ≥ 0, Coulomb friction below the drive's torque (else the joint could never
    /// move), the lag at most [`crate::MAX_LAG`]. The error names the key (`kp`, `kv`,
    /// `lag_ms`, `armature`, `viscous`, `coulomb`, `coulomb_speed`, or `robot`) and says
    /// what is wrong.
    pub fn check(
        &self,
        robot: &str,
        n: usize,
        torque: Option<&[f64]>,
    ) -> Result<(), (&'static str, String)> {
        if self.robot != robot {
            return Err((
                "robot",
                format!("it calibrates the robot {}, not {robot}", self.robot),
            ));
        }
        type Rule = fn(f64) -> bool;
        let rules: [(&'static str, &Vec<f64>, Rule, &str); 5] = [
            (
                "kp",
                &self.kp,
                |x| x > 0.0,
                "> 0 (a position controller pulls toward its command)",
            ),
            ("kv", &self.kv, |x| x >= 0.0, "≥ 0"),
            ("armature", &self.armature, |x| x >= 0.0, "≥ 0"),
            ("viscous", &self.viscous, |x| x >= 0.0, "≥ 0"),
            ("coulomb", &self.coulomb, |x| x >= 0.0, "≥ 0"),
        ];
        for (what, v, rule, needs) in rules {
            if v.len() != n {
                return Err((
                    what,
                    format!("{what} has {} values for {n} joints", v.len()),
                ));
            }
            if let Some(j) = v.iter().position(|&x| !(x.is_finite() && rule(x))) {
                return Err((
                    what,
                    format!(
                        "{what} of joint {} is {}: it must be finite and {needs}",
                        j + 1,
                        v[j]
                    ),
                ));
            }
        }
        if let Some(limit) = torque
            && let Some(j) = (0..n.min(limit.len())).find(|&j| self.coulomb[j] >= limit[j])
        {
            return Err((
                "coulomb",
                format!(
                    "coulomb of joint {} is {} N m, at or above its drive's {} N m: the joint could never move",
                    j + 1,
                    self.coulomb[j],
                    limit[j]
                ),
            ));
        }
        if self.lag > crate::MAX_LAG {
            return Err((
                "lag_ms",
                format!(
                    "a lag of {} control periods is more than the {} simulated",
                    self.lag,
                    crate::MAX_LAG
                ),
            ));
        }
        if !(self.speed.is_finite() && self.speed > 0.0) {
            return Err((
                "coulomb_speed",
                format!("the Coulomb speed {} must be > 0", self.speed),
            ));
        }
        Ok(())
    }
}

impl Default for DynamicsOptions {
    /// franky-sim's PD and drive, semi-implicit Euler at 1 ms, plans every 10 ms, no noise.
    fn default() -> Self {
        DynamicsOptions {
            controller: "joint_pd".into(),
            kp: None,
            kv: None,
            drive: Drive::FrankySim,
            integrator: Integrator::SemiImplicitEuler,
            noise: 0.0,
            seed: 0,
            dt: 0.01,
            control_period: 0.001,
            reflexes: true,
            calibration: None,
        }
    }
}

/// A controller's default gains on `n` joints: `joint_pd` franky-sim's (on seven joints;
/// 1000 and 100 on others), `computed_torque` kp 400 /s², kv 40 /s (critically damped at
/// 20 rad/s), `joint_impedance` cps's torque mode's defaults on a Franka.
pub fn default_gains(controller: &str, n: usize) -> (Vec<f64>, Vec<f64>) {
    match controller {
        "joint_pd" if n == 7 => (
            FRANKY_SIM_KP.to_vec(),
            FRANKY_SIM_KP.iter().map(|k| k / 10.0).collect(),
        ),
        "joint_pd" => (vec![1000.0; n], vec![100.0; n]),
        "computed_torque" => (vec![400.0; n], vec![40.0; n]),
        _ => {
            let k = [600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0];
            let d = [50.0, 50.0, 50.0, 20.0, 20.0, 20.0, 10.0];
            (
                (0..n).map(|i| k[i.min(6)]).collect(),
                (0..n).map(|i| d[i.min(6)]).collect(),
            )
        }
    }
}

fn fixed<const N: usize>(v: &[f64]) -> [f64; N] {
    std::array::from_fn(|i| v[i])
}

fn open_n<const N: usize>(
    model: RobotModel,
    links: &[LinkInertia],
    start: &[f64],
    options: &DynamicsOptions,
    kp: &[f64],
    kv: &[f64],
    torque: &[f64],
) -> Result<Box<dyn Robot>, RobotError> {
    let bad = |m: String| RobotError::Robot {
        robot: "the dynamics robot".into(),
        message: m,
    };
    let mut dynamics = ArmModel::<N>::new(&model.chain, links).map_err(|e| bad(e.to_string()))?;
    let friction = match (&options.calibration, options.drive) {
        (Some(c), _) => {
            c.check(&model.name, N, Some(torque))
                .map_err(|(_, e)| bad(format!("the calibration: {e}")))?;
            dynamics = dynamics
                .with_armature(fixed(&c.armature))
                .map_err(|e| bad(e.to_string()))?;
            JointFriction {
                viscous: fixed(&c.viscous),
                coulomb: fixed(&c.coulomb),
                speed: c.speed,
            }
        }
        (None, drive) => {
            let (with_drive, friction) = drive.apply(dynamics).map_err(|e| bad(e.to_string()))?;
            dynamics = with_drive;
            friction
        }
    };
    let controller =
        Controller::<N>::by_name(&options.controller, fixed(kp), fixed(kv)).map_err(bad)?;
    let mut arm = Arm::at_rest(dynamics, friction, fixed(torque), fixed(start));
    arm.integrator = options.integrator;
    let robot = DynamicsRobot::new(
        model,
        arm,
        DynamicsSettings {
            controller,
            control_period: options.control_period,
            dt: options.dt,
            noise: options.noise,
            seed: options.seed,
            reflexes: options.reflexes,
            lag: options.calibration.as_ref().map_or(0, |c| c.lag),
        },
    )?;
    Ok(Box::new(robot))
}

/// The dynamics robot of `model` at rest at `start`, built as `options` say. Errors, each
/// a sentence: a model without link inertias, a joint count other than 6 or 7, gains of
/// the wrong count, negative or not finite, an unknown controller.
pub fn open(
    model: RobotModel,
    start: &[f64],
    options: &DynamicsOptions,
) -> Result<Box<dyn Robot>, RobotError> {
    let bad = |m: String| RobotError::Robot {
        robot: "the dynamics robot".into(),
        message: m,
    };
    let n = model.chain.dof();
    let Some(links) = model.inertia.clone() else {
        return Err(bad(format!(
            "the robot {} has no link inertias, so its dynamics cannot be simulated (the built-in panda and fr3 have them; a URDF gives them with <inertial>)",
            model.name
        )));
    };
    if start.len() != n {
        return Err(bad(format!(
            "{} start positions for a {n}-joint robot",
            start.len()
        )));
    }
    let (dkp, dkv) = match &options.calibration {
        // A calibration identifies franky-sim's kind of controller, and its gains.
        Some(c) if options.controller == "joint_pd" => (c.kp.clone(), c.kv.clone()),
        Some(_) => {
            return Err(bad(format!(
                "a calibration identifies a joint_pd controller; the controller is {}",
                options.controller
            )));
        }
        None => default_gains(&options.controller, n),
    };
    let kp = options.kp.clone().unwrap_or(dkp);
    let kv = options.kv.clone().unwrap_or(dkv);
    for (what, v) in [("kp", &kp), ("kv", &kv)] {
        if v.len() != n {
            return Err(bad(format!(
                "{what} has {} values, the robot {} has {n} joints",
                v.len(),
                model.name
            )));
        }
    }
    let torque = model
        .limits
        .torque
        .clone()
        .unwrap_or_else(|| vec![f64::INFINITY; n]);
    if torque.len() != n || torque.iter().any(|t| t.is_nan() || *t <= 0.0) {
        return Err(bad(format!(
            "the robot {}'s torque limits must be {n} values > 0 (got {torque:?})",
            model.name
        )));
    }
    match n {
        7 => open_n::<7>(model, &links, start, options, &kp, &kv, &torque),
        6 => open_n::<6>(model, &links, start, options, &kp, &kv, &torque),
        _ => Err(bad(format!(
            "the robot {} has {n} joints; the dynamics robot simulates arms of 6 or 7",
            model.name
        ))),
    }
}
