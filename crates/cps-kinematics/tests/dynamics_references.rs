//! Forward dynamics against two independent implementations, each on the model it reads
//! itself from the installed franky-sim, at 1 000 random states:
//!
//! - MuJoCo on franky-sim's own FR3 (the model franky-sim simulates: MuJoCo Menagerie's
//!   FR3 with the Franka Hand, joint armature and damping). MuJoCo gives each body's mass,
//!   centre of mass and inertia in the world at q = 0; cps builds its model from them on
//!   its own FR3 kinematics (the joint axes are checked to be MuJoCo's).
//! - pinocchio's articulated-body algorithm (`pin.aba`) on the URDF franky-sim's
//!   controller uses (`fr3_clean.urdf`), with the same armature; cps reads the same file
//!   with its own URDF reader.
//!
//! The interpreter is `$CPS_FRANKA_PYTHON`, else `target/franka-venv/bin/python` (`.ci/run`
//! makes it with franky-sim and MuJoCo); without it the test says so and passes, except in
//! CI.

use std::path::PathBuf;
use std::process::Command;

use cps_kinematics::contact::JointFriction;
use cps_kinematics::robots::{PandaTool, fr3, fr3_inertia};
use cps_kinematics::{ArmModel, LinkInertia, chain_from_urdf};
use nalgebra::{Matrix3, Vector3};
use serde_json::Value;

fn python() -> Option<PathBuf> {
    let workspace = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let p = std::env::var_os("CPS_FRANKA_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace.join("target/franka-venv/bin/python"));
    if p.exists() {
        return Some(p);
    }
    cps_testkit::skip(&format!("no MuJoCo ({} missing)", p.display()));
    None
}

/// franky-sim's fr3.xml in MuJoCo, the fingers' joints removed (the hand rigid, as cps's
/// arm model carries it), frictionloss, contacts and joint limits off (constraints, not
/// smooth forces): bodies at q = 0 and `qacc` at seeded random states.
const SCRIPT: &str = r#"
import json, os, sys
import mujoco, numpy as np, franky_sim
assets = os.path.join(os.path.dirname(franky_sim.__file__), "assets")
spec = mujoco.MjSpec.from_file(os.path.join(assets, "fr3.xml"))
spec.meshdir = os.path.join(assets, "meshes")
for kind in ("actuators", "tendons", "equalities", "keys"):
    for x in list(getattr(spec, kind)):
        spec.delete(x)
for j in list(spec.joints):
    if j.name.startswith("finger"):
        spec.delete(j)
m = spec.compile()
off = mujoco.mjtDisableBit
m.opt.disableflags |= off.mjDSBL_FRICTIONLOSS | off.mjDSBL_CONTACT | off.mjDSBL_LIMIT
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
bodies = []
for b in range(m.nbody):
    r = d.ximat[b].reshape(3, 3)
    bodies.append({"name": m.body(b).name, "mass": float(m.body_mass[b]),
                   "com": d.xipos[b].tolist(),
                   "inertia": (r @ np.diag(m.body_inertia[b]) @ r.T).tolist()})
anchors, axes = d.xanchor.tolist(), d.xaxis.tolist()
rng = np.random.default_rng(int(sys.argv[1]))
lo, hi = m.jnt_range[:, 0], m.jnt_range[:, 1]
limit = np.array([87, 87, 87, 87, 12, 12, 12.0])
states = []
for _ in range(int(sys.argv[2])):
    q = rng.uniform(lo, hi)
    dq = rng.uniform(-2.0, 2.0, 7)
    tau = rng.uniform(-limit, limit)
    d.qpos[:] = q; d.qvel[:] = dq; d.qfrc_applied[:] = tau
    mujoco.mj_forward(m, d)
    states.append({"q": q.tolist(), "dq": dq.tolist(), "tau": tau.tolist(),
                   "qacc": d.qacc.tolist()})
print(json.dumps({"bodies": bodies, "anchors": anchors, "axes": axes,
                  "armature": m.dof_armature.tolist(), "damping": m.dof_damping.tolist(),
                  "states": states}))
"#;

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn vector(v: &Value) -> Vector3<f64> {
    Vector3::from_column_slice(&floats(v))
}

fn matrix(v: &Value) -> Matrix3<f64> {
    let rows: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(floats).collect();
    Matrix3::from_fn(|i, j| rows[i][j])
}

/// Bodies (mass, centre of mass and inertia about it, world frame) merged into one.
fn merge(parts: &[(f64, Vector3<f64>, Matrix3<f64>)]) -> (f64, Vector3<f64>, Matrix3<f64>) {
    let mass: f64 = parts.iter().map(|p| p.0).sum();
    let com = parts.iter().map(|p| p.1 * p.0).sum::<Vector3<f64>>() / mass;
    let inertia = parts
        .iter()
        .map(|(m, c, i)| {
            let r = c - com;
            i + *m * (Matrix3::identity() * r.norm_squared() - r * r.transpose())
        })
        .sum();
    (mass, com, inertia)
}

#[test]
fn forward_dynamics_equals_mujoco_s_qacc_on_franky_sim_s_fr3() {
    let Some(python) = python() else {
        return;
    };
    let out = Command::new(python)
        .args(["-c", SCRIPT, "7", "1000"])
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "MuJoCo's side failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mj: Value = serde_json::from_slice(&out.stdout).unwrap();
    let body = |name: &str| {
        let b = mj["bodies"]
            .as_array()
            .unwrap()
            .iter()
            .find(|b| b["name"] == name)
            .unwrap_or_else(|| panic!("MuJoCo's model has no body {name}"));
        (
            b["mass"].as_f64().unwrap(),
            vector(&b["com"]),
            matrix(&b["inertia"]),
        )
    };
    let chain = fr3(PandaTool::Flange);
    let zero = chain.fk_frames(&[0.0; 7]).unwrap();
    let links: Vec<LinkInertia> = (1..=7)
        .map(|i| {
            let (mass, com, inertia) = if i < 7 {
                body(&format!("fr3_link{i}"))
            } else {
                merge(&[
                    body("fr3_link7"),
                    body("hand"),
                    body("left_finger"),
                    body("right_finger"),
                ])
            };
            let frame = zero.link_frames[i - 1];
            let r = frame.rotation.matrix();
            let local = r.transpose() * (com - frame.translation.vector);
            let i_local = r.transpose() * inertia * r;
            LinkInertia {
                mass,
                com: local,
                inertia: i_local,
            }
        })
        .collect();
    // cps's built-in FR3 inertias are MuJoCo's, hand included.
    for (i, (mine, theirs)) in fr3_inertia().iter().zip(&links).enumerate() {
        assert!((mine.mass - theirs.mass).abs() < 1e-12, "link {}", i + 1);
        assert!((mine.com - theirs.com).norm() < 1e-12, "link {}", i + 1);
        assert!(
            (mine.inertia - theirs.inertia).amax() < 1e-12,
            "link {}",
            i + 1
        );
    }
    let armature: [f64; 7] = floats(&mj["armature"]).try_into().unwrap();
    let damping: [f64; 7] = floats(&mj["damping"]).try_into().unwrap();
    let model = ArmModel::<7>::new(&chain, &links)
        .unwrap()
        .with_armature(armature)
        .unwrap();
    // cps's FR3 kinematics are MuJoCo's: every joint axis through MuJoCo's anchor.
    let axes = mj["axes"].as_array().unwrap();
    let anchors = mj["anchors"].as_array().unwrap();
    for i in 0..7 {
        let frame = zero.link_frames[i];
        let axis = frame.rotation.matrix().column(2).into_owned();
        let anchor = vector(&anchors[i]);
        assert!(
            (axis - vector(&axes[i])).norm() < 1e-9,
            "joint {} axis: cps {axis:?}, MuJoCo {:?}",
            i + 1,
            vector(&axes[i])
        );
        // The anchor lies on cps's axis.
        let off = (anchor - frame.translation.vector).cross(&axis).norm();
        assert!(
            off < 1e-9,
            "joint {}'s anchor is {off} m off cps's axis",
            i + 1
        );
    }
    let friction = JointFriction {
        viscous: damping,
        coulomb: [0.0; 7],
        speed: 1.0,
    };
    let mut worst: f64 = 0.0;
    let states = mj["states"].as_array().unwrap();
    assert_eq!(states.len(), 1000);
    for s in states {
        let q: [f64; 7] = floats(&s["q"]).try_into().unwrap();
        let dq: [f64; 7] = floats(&s["dq"]).try_into().unwrap();
        let tau: [f64; 7] = floats(&s["tau"]).try_into().unwrap();
        let reference = floats(&s["qacc"]);
        let f = model.frames(&q);
        let aba = model.forward_dynamics(&f, &dq, &tau, Some(&friction));
        let crba = model
            .forward_dynamics_crba(&f, &dq, &tau, Some(&friction))
            .unwrap();
        for i in 0..7 {
            worst = worst
                .max((aba[i] - reference[i]).abs())
                .max((crba[i] - reference[i]).abs());
        }
    }
    println!("forward dynamics vs MuJoCo's qacc, 1000 states: worst {worst:.2e} rad/s²");
    assert!(worst < 1e-6, "{worst}");
}

/// pinocchio's `aba` on franky-sim's fr3_clean.urdf with MuJoCo's armature, at seeded
/// random states; the URDF's text comes along.
const PINOCCHIO: &str = r#"
import json, os, sys
import numpy as np, pinocchio as pin, franky_sim
path = os.path.join(os.path.dirname(franky_sim.__file__), "assets", "fr3_clean.urdf")
model = pin.buildModelFromUrdf(path)
model.armature = np.array([0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074])
data = model.createData()
rng = np.random.default_rng(int(sys.argv[1]))
states = []
for _ in range(int(sys.argv[2])):
    q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
    v = rng.uniform(-2.0, 2.0, 7)
    tau = rng.uniform(-40.0, 40.0, 7)
    states.append({"q": q.tolist(), "dq": v.tolist(), "tau": tau.tolist(),
                   "qacc": pin.aba(model, data, q, v, tau).tolist()})
print(json.dumps({"urdf": open(path).read(), "armature": model.armature.tolist(),
                  "states": states}))
"#;

#[test]
fn forward_dynamics_equals_pinocchio_s_aba_on_franky_sim_s_urdf() {
    let Some(python) = python() else {
        return;
    };
    let out = Command::new(python)
        .args(["-c", PINOCCHIO, "8", "1000"])
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "pinocchio's side failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let pin: Value = serde_json::from_slice(&out.stdout).unwrap();
    let urdf = chain_from_urdf(pin["urdf"].as_str().unwrap(), Some("link8")).unwrap();
    let armature: [f64; 7] = floats(&pin["armature"]).try_into().unwrap();
    let model = ArmModel::<7>::new(&urdf.chain, &urdf.inertia.unwrap())
        .unwrap()
        .with_armature(armature)
        .unwrap();
    let mut worst: f64 = 0.0;
    for s in pin["states"].as_array().unwrap() {
        let q: [f64; 7] = floats(&s["q"]).try_into().unwrap();
        let dq: [f64; 7] = floats(&s["dq"]).try_into().unwrap();
        let tau: [f64; 7] = floats(&s["tau"]).try_into().unwrap();
        let reference = floats(&s["qacc"]);
        let f = model.frames(&q);
        let aba = model.forward_dynamics(&f, &dq, &tau, None);
        let crba = model.forward_dynamics_crba(&f, &dq, &tau, None).unwrap();
        for i in 0..7 {
            worst = worst
                .max((aba[i] - reference[i]).abs())
                .max((crba[i] - reference[i]).abs());
        }
    }
    println!("forward dynamics vs pinocchio's aba, 1000 states: worst {worst:.2e} rad/s²");
    assert!(worst < 1e-9, "{worst}");
}
