//! Torque control laws at the robot's rate, on the robot's own dynamic model: joint
//! impedance, Cartesian impedance with a null-space posture, and force along a direction
//! (hybrid force–impedance), with contact sensing from the measured joint torques.
//!
//! - [`robot_dynamics`]: the arm's [`ArmModel`] from the URDF the robot itself sends
//!   (`GetRobotModel`, its `<inertial>` read by cps's URDF loader) with the end effector
//!   the state reports (`m_ee`, `F_x_Cee`, `I_ee`, a load, `F_T_EE`).
//! - [`Sensing`]: the generalized-momentum observer ([`cps_kinematics::contact`]) on the
//!   measured torques, the external wrench at the end effector, its bias taken while the
//!   arm is free, and a contact flag.
//! - [`JointImpedance`] and [`CartesianImpedance`]: `τ = K·e − D·ė + C(q, q̇)·q̇` in joint or
//!   task space (gravity is added by the robot), the latter with a posture in the null
//!   space and an optional [`ForceAlong`] replacing the stiffness along one direction.
//!
//! Every law is a plain struct stepped once per tick with the robot's state; each step
//! allocates nothing. They produce the joint torques of a [`crate::Torques`] for [`crate::run_torques`], which limits
//! the torques and their rate and owns the controlled stop.

use cps_kinematics::contact::{ContactFlag, JointFriction, MomentumObserver, external_wrench};
use cps_kinematics::{ArmFrames, ArmModel, LinkInertia};
use nalgebra::{
    Isometry3, Matrix3, SMatrix, SVector, Translation3, UnitQuaternion, Vector3, Vector6,
};

use crate::wire::{JOINTS, RobotState};
use crate::{Connection, FrankaError};

/// A pose from a column-major 4×4 homogeneous matrix (the FCI's layout).
pub fn pose_from_column_major(m: &[f64; 16]) -> Isometry3<f64> {
    let r = Matrix3::new(m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10]);
    let rotation = UnitQuaternion::from_matrix(&r);
    Isometry3::from_parts(Translation3::new(m[12], m[13], m[14]), rotation)
}

/// The arm's dynamic model from the robot: the URDF `GetRobotModel` returns (up to its
/// flange `link8`, every moving link's `<inertial>` required), carrying the end effector
/// and load the state reports at the flange, with the end-effector frame `F_T_EE` as the
/// model's tool. A robot whose URDF has no masses, an end effector whose inertia is not a
/// body's, or a model that disagrees with the state's `O_T_EE` by more than 1 mm is
/// refused with a sentence.
pub fn robot_dynamics(
    conn: &mut Connection,
    state: &RobotState,
) -> Result<ArmModel<JOINTS>, FrankaError> {
    let xml = conn.robot_model()?;
    let bad = |why: String| FrankaError::Input(format!("the robot's dynamic model: {why}"));
    let urdf = cps_kinematics::chain_from_urdf(&xml, Some("link8"))
        .map_err(|e| bad(format!("its URDF cannot be read: {e}")))?;
    let links = urdf
        .inertia
        .ok_or_else(|| bad("its URDF gives no link masses (no <inertial>)".into()))?;
    let model = ArmModel::<JOINTS>::new(&urdf.chain, &links).map_err(|e| bad(e.to_string()))?;
    with_end_effector(model, state)
}

/// `model` (ending at the flange) carrying the end effector and load `state` reports, its
/// tool moved to the end-effector frame `F_T_EE`; checked against `O_T_EE` (1 mm).
pub fn with_end_effector(
    model: ArmModel<JOINTS>,
    state: &RobotState,
) -> Result<ArmModel<JOINTS>, FrankaError> {
    let bad = |why: String| FrankaError::Input(format!("the robot's dynamic model: {why}"));
    let body = |what: &str, mass: f64, com: [f64; 3], i: [f64; 9]| {
        LinkInertia::new(mass, com, [i[0], i[3], i[6], i[4], i[7], i[8]]).map_err(|e| {
            bad(format!(
                "the {what} reported by the robot is not a body's: {e}"
            ))
        })
    };
    let mut model = model
        .with_payload(body("end effector", state.m_ee, state.f_x_cee, state.i_ee)?)
        .map_err(|e| bad(e.to_string()))?;
    if state.m_load > 0.0 {
        model = model
            .with_payload(body("load", state.m_load, state.f_x_cload, state.i_load)?)
            .map_err(|e| bad(e.to_string()))?;
    }
    let model = model.with_tool(pose_from_column_major(&state.f_t_ee));
    let frames = model.frames(&state.q);
    let measured = pose_from_column_major(&state.o_t_ee);
    let gap = (frames.tool.translation.vector - measured.translation.vector).norm();
    if gap.is_nan() || gap > 1e-3 {
        return Err(bad(format!(
            "it puts the end effector {:.1} mm from the robot's own O_T_EE",
            gap * 1e3
        )));
    }
    Ok(model)
}

/// Settings of [`Sensing`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensingOptions {
    /// The observer's gain per joint (1/s): the estimate follows the external torque as a
    /// first-order filter of time constant 1/gain.
    pub gain: f64,
    /// Seconds at the start during which the arm must be free: the mean wrench then is
    /// the model's bias, subtracted afterwards.
    pub tare: f64,
    /// Contact is flagged when the force's magnitude exceeds this (N) ...
    pub contact_on: f64,
    /// ... and cleared when it falls below this (N).
    pub contact_off: f64,
    /// Friction between the drive and the measured torque: zero for a Franka (its torque
    /// sensors sit after the gears); a simulator that reports the torque it applies
    /// before its joints' friction (franky-sim) needs that friction here.
    pub friction: JointFriction<JOINTS>,
}

impl Default for SensingOptions {
    fn default() -> Self {
        SensingOptions {
            gain: 100.0,
            tare: 0.2,
            contact_on: 3.0,
            contact_off: 1.5,
            friction: JointFriction::none(),
        }
    }
}

/// Contact sensing from the measured joint torques: the generalized-momentum observer on
/// the robot's model, the external wrench at the end effector (world axes, the force the
/// world exerts on the arm), less the bias taken during the tare, and a contact flag.
#[derive(Debug, Clone)]
pub struct Sensing {
    observer: MomentumObserver<JOINTS>,
    flag: ContactFlag,
    tare: f64,
    bias: Vector6<f64>,
    tare_sum: Vector6<f64>,
    tare_ticks: u32,
    last_t: Option<f64>,
    wrench: Vector6<f64>,
}

impl Sensing {
    /// Sensing with `options`; thresholds and gains out of range are named.
    pub fn new(options: SensingOptions) -> Result<Self, FrankaError> {
        let bad = |e: cps_kinematics::KinematicsError| FrankaError::Input(e.to_string());
        if !(options.tare.is_finite() && (0.0..=10.0).contains(&options.tare)) {
            return Err(FrankaError::Input(format!(
                "sensing: tare {} s must lie in [0, 10]",
                options.tare
            )));
        }
        options.friction.check().map_err(bad)?;
        Ok(Sensing {
            observer: MomentumObserver::new([options.gain; JOINTS])
                .map_err(bad)?
                .with_friction(options.friction),
            flag: ContactFlag::new(options.contact_on, options.contact_off).map_err(bad)?,
            tare: options.tare,
            bias: Vector6::zeros(),
            tare_sum: Vector6::zeros(),
            tare_ticks: 0,
            last_t: None,
            wrench: Vector6::zeros(),
        })
    }

    /// One tick at robot time `t`; returns the wrench estimate (bias removed once the tare
    /// is over; zero during it).
    pub fn update(
        &mut self,
        model: &ArmModel<JOINTS>,
        frames: &ArmFrames<JOINTS>,
        state: &RobotState,
        t: f64,
    ) -> Vector6<f64> {
        let dt = self.last_t.map_or(0.0, |last| t - last);
        self.last_t = Some(t);
        let r = self
            .observer
            .update(model, frames, &state.dq, &state.tau_j, dt);
        let raw = external_wrench(frames, &r, 0.01);
        if t < self.tare {
            // Skip the observer's first 50 ms (it starts from zero) in the mean.
            if t >= self.tare * 0.25 {
                self.tare_sum += raw;
                self.tare_ticks += 1;
                self.bias = self.tare_sum / f64::from(self.tare_ticks);
            }
            self.wrench = Vector6::zeros();
        } else {
            self.wrench = raw - self.bias;
        }
        self.flag.update(self.wrench.fixed_rows::<3>(0).norm());
        self.wrench
    }

    /// The last wrench estimate.
    pub fn wrench(&self) -> Vector6<f64> {
        self.wrench
    }

    /// Whether contact is flagged.
    pub fn contact(&self) -> bool {
        self.flag.raised()
    }

    /// Whether the tare is over (the estimate is valid).
    pub fn ready(&self) -> bool {
        self.last_t.is_some_and(|t| t >= self.tare)
    }
}

/// The largest joint stiffness accepted per joint (N m/rad): twice the gains of Franka's
/// joint impedance example, well inside what a 1 kHz loop keeps stable on the wrist.
pub const MAX_JOINT_STIFFNESS: [f64; JOINTS] =
    [1200.0, 1200.0, 1200.0, 1200.0, 500.0, 300.0, 100.0];

/// The largest Cartesian stiffness accepted: translation (N/m) and rotation (N m/rad),
/// Franka's own limits for its internal Cartesian impedance.
pub const MAX_CARTESIAN_STIFFNESS: (f64, f64) = (3000.0, 300.0);

fn check_range(what: &str, v: f64, max: f64, unit: &str) -> Result<(), FrankaError> {
    if v.is_finite() && (0.0..=max).contains(&v) {
        Ok(())
    } else {
        Err(FrankaError::Input(format!(
            "{what} {v} {unit} is out of range: it must lie in [0, {max}]"
        )))
    }
}

/// Joint impedance: `τ = K·(q_d − q) − D·q̇ + C(q, q̇)·q̇`, gravity added by the robot.
#[derive(Debug, Clone)]
pub struct JointImpedance {
    stiffness: [f64; JOINTS],
    damping: [f64; JOINTS],
}

impl JointImpedance {
    /// A law with `stiffness` (N m/rad, at most [`MAX_JOINT_STIFFNESS`]) and `damping`
    /// (N m s/rad, at most 2·√(stiffness·1 kg m²) + 50).
    pub fn new(stiffness: [f64; JOINTS], damping: [f64; JOINTS]) -> Result<Self, FrankaError> {
        for i in 0..JOINTS {
            check_range(
                &format!("joint {} stiffness", i + 1),
                stiffness[i],
                MAX_JOINT_STIFFNESS[i],
                "N m/rad",
            )?;
            let max_d = 2.0 * stiffness[i].sqrt() + 50.0;
            check_range(
                &format!("joint {} damping", i + 1),
                damping[i],
                max_d,
                "N m s/rad",
            )?;
        }
        Ok(JointImpedance { stiffness, damping })
    }

    /// The torques holding the arm at `q_d` (moving at `dq_d`) for `state`.
    pub fn torques(
        &self,
        model: &ArmModel<JOINTS>,
        frames: &ArmFrames<JOINTS>,
        state: &RobotState,
        q_d: &[f64; JOINTS],
        dq_d: &[f64; JOINTS],
    ) -> [f64; JOINTS] {
        let c = model.coriolis(frames, &state.dq);
        let mut tau = [0.0; JOINTS];
        for i in 0..JOINTS {
            tau[i] = self.stiffness[i] * (q_d[i] - state.q[i])
                + self.damping[i] * (dq_d[i] - state.dq[i])
                + c[i];
        }
        tau
    }
}

/// Stiffness and damping of a [`CartesianImpedance`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CartesianGains {
    /// Translational stiffness along x, y, z of the base frame (N/m).
    pub translation: [f64; 3],
    /// Rotational stiffness about x, y, z (N m/rad).
    pub rotation: [f64; 3],
    /// Damping as a ratio of critical for a unit mass: `D = 2·ζ·√K` (0 to 2).
    pub damping_ratio: f64,
    /// Stiffness of the null-space posture (N m/rad, 0 to 50).
    pub nullspace: f64,
}

impl Default for CartesianGains {
    /// franka_ros's example values: 200 N/m, 10 N m/rad, critically damped, a light posture.
    fn default() -> Self {
        CartesianGains {
            translation: [200.0; 3],
            rotation: [10.0; 3],
            damping_ratio: 1.0,
            nullspace: 0.5,
        }
    }
}

/// Force along one direction in place of the stiffness there (hybrid force–impedance).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceAlong {
    /// The direction the arm pushes in (base frame; normalised).
    pub direction: [f64; 3],
    /// The force the arm exerts on the world along it (N).
    pub force: f64,
    /// Proportional gain on the estimated force's error (0 = feedforward alone).
    pub kp: f64,
    /// Integral gain on it (1/s).
    pub ki: f64,
    /// Damping of the motion along the direction (N s/m).
    pub damping: f64,
}

impl ForceAlong {
    /// Pushing with `force` N along `direction`, with cps's default loop gains (0.2 and
    /// 5 /s on the estimate, 30 N s/m of damping).
    pub fn new(direction: [f64; 3], force: f64) -> Self {
        ForceAlong {
            direction,
            force,
            kp: 0.2,
            ki: 5.0,
            damping: 30.0,
        }
    }
}

/// Cartesian impedance at the end effector:
/// `τ = Jᵀ·(K·e − D·J·q̇) + (I − Jᵀ·J⁺ᵀ)·(K_n·(q_n − q) − D_n·q̇) + C(q, q̇)·q̇`, `e` the
/// position error and the rotation error as a rotation vector (base frame), `q_n` the
/// posture; with a [`ForceAlong`], the translational part along its direction is the
/// force (feedforward plus a PI loop on [`Sensing`]'s estimate) instead of the spring.
#[derive(Debug, Clone)]
pub struct CartesianImpedance {
    k: Vector6<f64>,
    d: Vector6<f64>,
    nullspace: f64,
    posture: [f64; JOINTS],
    integral: f64,
}

impl CartesianImpedance {
    /// A law with `gains` (stiffness within [`MAX_CARTESIAN_STIFFNESS`], damping ratio in
    /// [0, 2], null-space stiffness in [0, 50]) holding the null space near `posture`.
    pub fn new(gains: CartesianGains, posture: [f64; JOINTS]) -> Result<Self, FrankaError> {
        let (kt, kr) = MAX_CARTESIAN_STIFFNESS;
        for (axis, v) in ["x", "y", "z"].iter().zip(gains.translation) {
            check_range(
                &format!("translational stiffness along {axis}"),
                v,
                kt,
                "N/m",
            )?;
        }
        for (axis, v) in ["x", "y", "z"].iter().zip(gains.rotation) {
            check_range(
                &format!("rotational stiffness about {axis}"),
                v,
                kr,
                "N m/rad",
            )?;
        }
        check_range("damping ratio", gains.damping_ratio, 2.0, "")?;
        check_range("null-space stiffness", gains.nullspace, 50.0, "N m/rad")?;
        if let Some(v) = posture.iter().find(|v| !v.is_finite()) {
            return Err(FrankaError::Input(format!(
                "posture has a value {v} that is not finite"
            )));
        }
        let mut k = Vector6::zeros();
        for i in 0..3 {
            k[i] = gains.translation[i];
            k[i + 3] = gains.rotation[i];
        }
        let d = k.map(|k| 2.0 * gains.damping_ratio * k.sqrt());
        Ok(CartesianImpedance {
            k,
            d,
            nullspace: gains.nullspace,
            posture,
            integral: 0.0,
        })
    }

    /// The torques pulling the end effector to `target` (moving at `velocity`, `[v; ω]` in
    /// the base frame) for `state`, with `force` along a direction if given (`estimate`:
    /// the wrench the world exerts on the arm, from [`Sensing`]; `dt` the tick's length for
    /// the integral).
    #[allow(clippy::too_many_arguments)]
    pub fn torques(
        &mut self,
        model: &ArmModel<JOINTS>,
        frames: &ArmFrames<JOINTS>,
        state: &RobotState,
        target: &Isometry3<f64>,
        velocity: &Vector6<f64>,
        force: Option<&ForceAlong>,
        estimate: &Vector6<f64>,
        dt: f64,
    ) -> [f64; JOINTS] {
        let j = frames.jacobian();
        let dq = SVector::<f64, JOINTS>::from(state.dq);
        let v = j * dq;
        let x = &frames.tool;
        let mut error = Vector6::zeros();
        error
            .fixed_rows_mut::<3>(0)
            .copy_from(&(target.translation.vector - x.translation.vector));
        error
            .fixed_rows_mut::<3>(3)
            .copy_from(&(target.rotation * x.rotation.inverse()).scaled_axis());
        let mut wrench = self.k.component_mul(&error) + self.d.component_mul(&(velocity - v));
        if let Some(f) = force {
            let n = Vector3::from(f.direction);
            let n = if n.norm() > 0.0 { n / n.norm() } else { n };
            // The force the arm exerts along n is minus the world's force on the arm.
            let exerted = -estimate.fixed_rows::<3>(0).dot(&n);
            let err = f.force - exerted;
            self.integral =
                (self.integral + err * dt).clamp(-f.force.abs() - 5.0, f.force.abs() + 5.0);
            let along = f.force + f.kp * err + f.ki * self.integral
                - f.damping * v.fixed_rows::<3>(0).dot(&n);
            let mut lin: Vector3<f64> = wrench.fixed_rows::<3>(0).into_owned();
            lin -= n * lin.dot(&n);
            lin += n * along;
            wrench.fixed_rows_mut::<3>(0).copy_from(&lin);
        }
        let task = j.transpose() * wrench;
        // Null space of the task: I − Jᵀ·(J Jᵀ + λ²I)⁻¹·J.
        let jjt = j * j.transpose() + SMatrix::<f64, 6, 6>::identity() * 1e-4;
        let pinv_t = jjt
            .cholesky()
            .map(|c| c.solve(&j))
            .unwrap_or_else(SMatrix::<f64, 6, JOINTS>::zeros);
        let projector = SMatrix::<f64, JOINTS, JOINTS>::identity() - j.transpose() * pinv_t;
        let mut posture = SVector::<f64, JOINTS>::zeros();
        let dn = 2.0 * self.nullspace.sqrt();
        for i in 0..JOINTS {
            posture[i] = self.nullspace * (self.posture[i] - state.q[i]) - dn * state.dq[i];
        }
        let tau = task + projector * posture + model.coriolis(frames, &state.dq);
        tau.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gains_out_of_range_are_named() {
        let e = JointImpedance::new([600.0; JOINTS], [50.0; JOINTS]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "joint 5 stiffness 600 N m/rad is out of range: it must lie in [0, 500]"
        );
        let mut g = CartesianGains::default();
        g.translation[1] = 5000.0;
        let e = CartesianImpedance::new(g, [0.0; JOINTS]).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("translational stiffness along y 5000 N/m is out of range"),
            "{e}"
        );
        let g = CartesianGains {
            damping_ratio: f64::NAN,
            ..Default::default()
        };
        assert!(
            CartesianImpedance::new(g, [0.0; JOINTS])
                .unwrap_err()
                .to_string()
                .contains("damping ratio NaN")
        );
        let s = SensingOptions {
            contact_on: 1.0,
            contact_off: 2.0,
            ..Default::default()
        };
        assert!(Sensing::new(s).is_err());
    }

    #[test]
    fn an_end_effector_that_is_not_a_body_is_refused() {
        use cps_kinematics::robots::{PandaTool, fr3, panda_inertia};
        let arm = || ArmModel::<JOINTS>::new(&fr3(PandaTool::Flange), &panda_inertia()).unwrap();
        let mut state = RobotState::decode(&[0u8; crate::wire::STATE_SIZE]).unwrap();
        let eye = [
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        state.f_t_ee = eye;
        let tool = arm().frames(&state.q).tool;
        let mut o = eye;
        o[12..15].copy_from_slice(tool.translation.vector.as_slice());
        state.o_t_ee = o;
        state.m_ee = 0.73;
        state.f_x_cee = [-0.01, 0.0, 0.03];
        state.i_ee = [0.001, 0.0, 0.0, 0.0, 0.0025, 0.0, 0.0, 0.0, 0.0017];
        assert!(with_end_effector(arm(), &state).is_ok());
        let mut bad = state;
        bad.m_ee = -0.5;
        let e = with_end_effector(arm(), &bad).unwrap_err().to_string();
        assert!(
            e.contains("the end effector reported by the robot is not a body's"),
            "{e}"
        );
        let mut bad = state;
        bad.i_ee = [0.001, 0.0, 0.0, 0.0, 0.0025, 0.0, 0.0, 0.0, 0.01]; // zz > xx + yy
        assert!(
            with_end_effector(arm(), &bad)
                .unwrap_err()
                .to_string()
                .contains("principal moments")
        );
        let mut bad = state;
        bad.m_load = 1.0;
        bad.i_load = [f64::NAN; 9];
        assert!(
            with_end_effector(arm(), &bad)
                .unwrap_err()
                .to_string()
                .contains("the load reported")
        );
        let mut off = state;
        off.o_t_ee[14] += 0.01;
        let e = with_end_effector(arm(), &off).unwrap_err().to_string();
        assert!(e.contains("10.0 mm from the robot's own O_T_EE"), "{e}");
    }

    #[test]
    fn poses_read_column_major() {
        // A quarter turn about z and a translation, as the FCI sends O_T_EE.
        let m = [
            0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.3, 0.1, 0.5, 1.0,
        ];
        let p = pose_from_column_major(&m);
        let x = p * nalgebra::Point3::new(1.0, 0.0, 0.0);
        assert!((x.coords - Vector3::new(0.3, 1.1, 0.5)).norm() < 1e-12);
    }
}
