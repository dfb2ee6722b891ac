"""Regenerates robots_pinocchio.json: forward kinematics and inverse dynamics of the UR3 and
the FANUC CRX-10iA by pinocchio, for crates/cps-movement/tests/robots.rs.

    pip install pin numpy
    python crates/cps-movement/tests/data/make_robot_references.py

UR3: a URDF written here from Universal Robots' standard-DH table and link masses and
centres of mass (UR support article "DH Parameters for calculations of kinematics and
dynamics"; point masses, as UR publishes no tensors): joint i turns about z in frame i-1,
then the fixed part TransZ(d) TransX(a) RotX(alpha) leads to DH frame i, where the centre of
mass is given. CRX-10iA: pinocchio reads configs/robots/crx10ia.urdf itself. Gravity
(0, 0, -9.81). States: numpy default_rng(11); q uniform in the joint ranges, qd in
[-2, 2] rad/s, qdd in [-5, 5] rad/s^2.
"""

import json
from pathlib import Path

import numpy as np
import pinocchio

ROOT = Path(__file__).resolve().parents[4]
UR3_DH = [(0.0, 0.1519, np.pi / 2), (-0.24365, 0.0, 0.0), (-0.21325, 0.0, 0.0),
          (0.0, 0.11235, np.pi / 2), (0.0, 0.08535, -np.pi / 2), (0.0, 0.0819, 0.0)]
UR3_MASS = [2.0, 3.42, 1.26, 0.8, 0.8, 0.35]
UR3_COM = [[0.0, -0.02, 0.0], [0.13, 0.0, 0.1157], [0.05, 0.0, 0.0238],
           [0.0, 0.0, 0.01], [0.0, 0.0, 0.01], [0.0, 0.0, -0.02]]


def ur3_urdf():
    parts = ['<robot name="ur3_dh"><link name="base"/>']
    prev = (0.0, 0.0, 0.0)  # (a, d, alpha) of the previous row: the fixed part before joint i
    for i, ((a, d, alpha), m, c) in enumerate(zip(UR3_DH, UR3_MASS, UR3_COM), start=1):
        pa, pd, palpha = prev
        ca, sa = np.cos(alpha), np.sin(alpha)
        # The centre of mass in the rotating frame: TransZ(d) TransX(a) RotX(alpha) applied.
        com = [float(x) for x in (a + c[0], ca * c[1] - sa * c[2], d + sa * c[1] + ca * c[2])]
        parts.append(
            f'<joint name="j{i}" type="revolute"><parent link="{"base" if i == 1 else f"r{i - 1}"}"/>'
            f'<child link="r{i}"/><origin xyz="{pa!r} 0 {pd!r}" rpy="{palpha!r} 0 0"/><axis xyz="0 0 1"/>'
            f'<limit lower="-6.283185307179586" upper="6.283185307179586" effort="100" velocity="3"/></joint>'
            f'<link name="r{i}"><inertial><origin xyz="{com[0]!r} {com[1]!r} {com[2]!r}" rpy="0 0 0"/>'
            f'<mass value="{m!r}"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>')
        prev = (a, d, alpha)
    a, d, alpha = prev
    parts.append(f'<joint name="tool" type="fixed"><parent link="r6"/><child link="flange"/>'
                 f'<origin xyz="{a!r} 0 {d!r}" rpy="{alpha!r} 0 0"/></joint><link name="flange"/></robot>')
    return "".join(parts)


def states(model, tip, rng, n=30):
    data = model.createData()
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    out = []
    for _ in range(n):
        q = rng.uniform(lo, hi)
        qd = rng.uniform(-2.0, 2.0, model.nv)
        qdd = rng.uniform(-5.0, 5.0, model.nv)
        tau = pinocchio.rnea(model, data, q, qd, qdd)
        pinocchio.framesForwardKinematics(model, data, q)
        pose = data.oMf[model.getFrameId(tip)]
        out.append({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist(), "tau": tau.tolist(),
                    "tip_position": pose.translation.tolist(), "tip_rotation": pose.rotation.tolist()})
    return out


def main():
    rng = np.random.default_rng(11)
    ur3 = pinocchio.buildModelFromXML(ur3_urdf())
    crx = pinocchio.buildModelFromUrdf(str(ROOT / "configs/robots/crx10ia.urdf"))
    crx_data = crx.createData()
    out = {
        "generator": "pinocchio on a URDF of UR's DH table and point masses, and on configs/robots/crx10ia.urdf "
                     "(crates/cps-movement/tests/data/make_robot_references.py)",
        "versions": {"pinocchio": pinocchio.__version__, "numpy": np.__version__},
        "gravity": [0.0, 0.0, -9.81],
        "ur3": states(ur3, "flange", rng),
        "crx10ia": states(crx, "flange", rng),
        "crx10ia_gravity_at_zero": pinocchio.computeGeneralizedGravity(crx, crx_data, np.zeros(6)).tolist(),
    }
    path = Path(__file__).with_name("robots_pinocchio.json")
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {path}: gravity of the CRX-10iA at q = 0: {np.round(out['crx10ia_gravity_at_zero'], 3)}")


if __name__ == "__main__":
    main()
