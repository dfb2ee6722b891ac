"""Regenerates panda_rnea_pinocchio.json: Panda joint torques by pinocchio's RNEA.

    pip install pin numpy
    python crates/cps-kinematics/tests/data/make_panda_rnea.py

The model is written here from the published data, independently of cps's Rust code:
Franka's modified-DH table (frankaemika/docs, control parameters) turned into URDF joints
(xyz = (a, -d sin(alpha), d cos(alpha)), rpy = (alpha, 0, 0), axis z), and Gaz et al. 2019
(IEEE RA-L 4(4):4147, supplementary Tables VIII and IX, column p-hat) for each link's mass,
centre of mass (in its MDH frame) and inertia about the centre of mass. Gravity
(0, 0, -9.81). States: numpy default_rng(7); q uniform in the joint limits, qd in
[-2, 2] rad/s, qdd in [-5, 5] rad/s^2.
"""

import json
from pathlib import Path

import numpy as np
import pinocchio

DH = [(0.0, 0.333, 0.0), (0.0, 0.0, -np.pi / 2), (0.0, 0.316, np.pi / 2), (0.0825, 0.0, np.pi / 2),
      (-0.0825, 0.384, -np.pi / 2), (0.0, 0.0, np.pi / 2), (0.088, 0.0, np.pi / 2)]
Q_MIN = [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]
Q_MAX = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]
MASS = [4.970684, 0.646926, 3.228604, 3.587895, 1.225946, 1.666555, 0.735522]
COM = [[3.875e-3, 2.081e-3, 0.0], [-3.141e-3, -2.872e-2, 3.495e-3], [2.7518e-2, 3.9252e-2, -6.6502e-2],
       [-5.317e-2, 1.04419e-1, 2.7454e-2], [-1.1953e-2, 4.1065e-2, -3.8437e-2],
       [6.0149e-2, -1.4117e-2, -1.0517e-2], [1.0517e-2, -4.252e-3, 6.1597e-2]]
INERTIA = [  # xx, xy, xz, yy, yz, zz
    [7.0337e-1, -1.39e-4, 6.772e-3, 7.0661e-1, 1.9169e-2, 9.117e-3],
    [7.962e-3, -3.925e-3, 1.0254e-2, 2.811e-2, 7.04e-4, 2.5995e-2],
    [3.7242e-2, -4.761e-3, -1.1396e-2, 3.6155e-2, -1.2805e-2, 1.083e-2],
    [2.5853e-2, 7.796e-3, -1.332e-3, 1.9552e-2, 8.641e-3, 2.8323e-2],
    [3.5549e-2, -2.117e-3, -4.037e-3, 2.9474e-2, 2.29e-4, 8.627e-3],
    [1.964e-3, 1.09e-4, -1.158e-3, 4.354e-3, 3.41e-4, 5.433e-3],
    [1.2516e-2, -4.28e-4, -1.196e-3, 1.0027e-2, -7.41e-4, 4.815e-3]]


def urdf():
    parts = ['<robot name="panda_gaz"><link name="link0"/>']
    for i, ((a, d, alpha), m, c, inertia) in enumerate(zip(DH, MASS, COM, INERTIA), start=1):
        xx, xy, xz, yy, yz, zz = inertia
        parts.append(
            f'<joint name="j{i}" type="revolute"><parent link="link{i - 1}"/><child link="link{i}"/>'
            f'<origin xyz="{a!r} {float(-d * np.sin(alpha))!r} {float(d * np.cos(alpha))!r}" rpy="{alpha!r} 0 0"/>'
            f'<axis xyz="0 0 1"/><limit lower="{Q_MIN[i - 1]}" upper="{Q_MAX[i - 1]}" effort="100" velocity="3"/></joint>'
            f'<link name="link{i}"><inertial><origin xyz="{c[0]!r} {c[1]!r} {c[2]!r}" rpy="0 0 0"/>'
            f'<mass value="{m!r}"/><inertia ixx="{xx!r}" ixy="{xy!r}" ixz="{xz!r}" iyy="{yy!r}" '
            f'iyz="{yz!r}" izz="{zz!r}"/></inertial></link>')
    parts.append("</robot>")
    return "".join(parts)


def main():
    model = pinocchio.buildModelFromXML(urdf())
    data = model.createData()
    rng = np.random.default_rng(7)
    states = []
    for _ in range(50):
        q = rng.uniform(Q_MIN, Q_MAX)
        qd = rng.uniform(-2.0, 2.0, 7)
        qdd = rng.uniform(-5.0, 5.0, 7)
        tau = pinocchio.rnea(model, data, q, qd, qdd)
        states.append({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist(), "tau": tau.tolist()})
    out = {
        "generator": "pinocchio.rnea on a URDF written from Franka's MDH table and Gaz et al. 2019 "
                     "(crates/cps-kinematics/tests/data/make_panda_rnea.py)",
        "versions": {"pinocchio": pinocchio.__version__, "numpy": np.__version__},
        "gravity": [0.0, 0.0, -9.81],
        "states": states,
    }
    path = Path(__file__).with_name("panda_rnea_pinocchio.json")
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {path} ({len(states)} states)")


if __name__ == "__main__":
    main()
