"""MuJoCo's signed distances between the FR3's collision geoms (franky-sim's fr3.xml: the
franka_description link and hand meshes, which MuJoCo collides as convex hulls) and a box
in front of it, at the configurations given: the reference for cps's robot collision model.

    python mujoco_robot.py FR3_XML  <  {"box": [cx, cy, cz, hx, hy, hz], "pairs": [[g1, g2], ...],
                                       "q": [[q1..q7], ...]}
    ->  {"distances": [[d per pair] per configuration], "checked": [[g1, g2], ...]}

Geoms are named by their link (`fr3_link0` … `fr3_link7`, `fr3_hand`) or `box`. `checked`
lists the pairs MuJoCo's own contact filter would consider (not parent and child, not
excluded), fingers left out, so the test can compare the pair sets too.
"""
import json
import os
import re
import sys

import mujoco
import numpy as np


def main():
    path = sys.argv[1]
    job = json.load(sys.stdin)
    cx, cy, cz, hx, hy, hz = job["box"]
    text = open(path).read()
    meshes = os.path.join(os.path.dirname(path), "meshes")
    text = re.sub(r'meshdir="[^"]*"', f'meshdir="{meshes}"', text)
    text = text.replace(
        "</worldbody>",
        f'<body name="obstacle" pos="{cx} {cy} {cz}"><geom name="box" type="box" size="{hx} {hy} {hz}" '
        'contype="0" conaffinity="0"/></body></worldbody>',
    )
    m = mujoco.MjModel.from_xml_string(text)
    m.opt.ccd_iterations = 500
    m.opt.ccd_tolerance = 1e-10
    d = mujoco.MjData(m)
    geom = {}
    for g in range(m.ngeom):
        if m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0 and m.geom(g).name != "box":
            continue  # visual
        body = m.body(m.geom_bodyid[g]).name
        name = m.geom(g).name or ""
        if "finger" in body:
            continue
        key = "box" if name == "box" else ("fr3_hand" if body == "hand" else body)
        geom[key] = g
    # MuJoCo's filter: no parent–child pairs, no <exclude> pairs.
    excluded = {(m.body(m.exclude_signature[i] >> 16).name, m.body(m.exclude_signature[i] & 0xFFFF).name)
                for i in range(m.nexclude)} if hasattr(m, "exclude_signature") else set()
    checked = []
    names = sorted(k for k in geom if k != "box")
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            ba, bb = m.geom_bodyid[geom[a]], m.geom_bodyid[geom[b]]
            if m.body_parentid[ba] == bb or m.body_parentid[bb] == ba:
                continue
            na, nb = m.body(ba).name, m.body(bb).name
            if (na, nb) in excluded or (nb, na) in excluded:
                continue
            checked.append([a, b])
    arm = [m.joint(f"fr3_joint{k}").qposadr[0] for k in range(1, 8)]
    fingers = [m.joint(n).qposadr[0] for n in ("finger_joint1", "finger_joint2")]
    fromto = np.zeros(6)
    out = []
    for q in job["q"]:
        d.qpos[:] = 0
        d.qpos[arm] = q
        d.qpos[fingers] = 0.04
        mujoco.mj_kinematics(m, d)
        out.append([mujoco.mj_geomDistance(m, d, geom[a], geom[b], 10.0, fromto) for a, b in job["pairs"]])
    json.dump({"distances": out, "checked": checked}, sys.stdout)


if __name__ == "__main__":
    main()
