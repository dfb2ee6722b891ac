"""MuJoCo's signed distances between two collision meshes at random poses: the reference
for cps-geometry's GJK and EPA on real hulls (MuJoCo collides a mesh's convex hull).

    python mujoco_pairs.py MESH_A MESH_B COUNT SEED  ->  JSON lines on stdout:
    {"a": [x, y, z, qw, qx, qy, qz], "b": [...], "distance": d}

Poses are drawn so that about half the pairs overlap. MuJoCo places a mesh in its body's
frame as the file gives it, so the body poses are the meshes' poses.
"""
import json
import sys

import mujoco
import numpy as np


def main():
    mesh_a, mesh_b, count, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    xml = f"""
<mujoco>
  <option><flag nativeccd="enable"/></option>
  <asset>
    <mesh name="a" file="{mesh_a}"/>
    <mesh name="b" file="{mesh_b}"/>
  </asset>
  <worldbody>
    <body name="A" mocap="true"><geom name="ga" type="mesh" mesh="a"/></body>
    <body name="B" mocap="true"><geom name="gb" type="mesh" mesh="b"/></body>
  </worldbody>
</mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    m.opt.ccd_iterations = 500
    m.opt.ccd_tolerance = 1e-10
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    fromto = np.zeros(6)
    for _ in range(count):
        poses = []
        for k in range(2):
            q = rng.normal(size=4)
            q /= np.linalg.norm(q)
            p = rng.uniform(-0.12, 0.12, size=3)
            d.mocap_pos[k] = p
            d.mocap_quat[k] = q
            poses.append([*p, *q])
        mujoco.mj_kinematics(m, d)
        dist = mujoco.mj_geomDistance(m, d, 0, 1, 1.0, fromto)
        print(json.dumps({"a": poses[0], "b": poses[1], "distance": dist}))


if __name__ == "__main__":
    main()
