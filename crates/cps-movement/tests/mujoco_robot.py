"""MuJoCo's signed distances between the FR3's collision geoms (franky-sim's fr3.xml: the
franka_description link and hand meshes, which MuJoCo collides as convex hulls) and a box
in front of it, at the configurations given: the reference for cps's robot collision model.

    python mujoco_robot.py FR3_XML  <  {"box": [cx, cy, cz, hx, hy, hz], "pairs": [[g1, g2], ...],
                                       "q": [[q1..q7], ...]}
    ->  {"distances": [[d per pair] per configuration], "checked": [[g1, g2], ...]}

With `"time": true` it also times, per configuration: `mj_kinematics` + `mj_collision`
(MuJoCo's broad and narrow phase, contacts only), `mj_geomDistance` over every pair, and —
when coal (FCL's successor, PyPI `coal`) is installed — coal's distance over every pair on
the same hulls (MuJoCo's mesh vertices, hulled by coal) at MuJoCo's geom poses, whose
distances come back as `coal`. The per-pair loops run from Python: `call_s` is a Python
call of a C function that does nothing worth timing, for the overhead.

Geoms are named by their link (`fr3_link0` … `fr3_link7`, `fr3_hand`) or `box`. `checked`
lists the pairs MuJoCo's own contact filter would consider (not parent and child, not
excluded), fingers left out, so the test can compare the pair sets too.
"""
import json
import os
import re
import sys
import time

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
    pairs = [(geom[a], geom[b]) for a, b in job["pairs"]]

    def place(q):
        d.qpos[:] = 0
        d.qpos[arm] = q
        d.qpos[fingers] = 0.04
        mujoco.mj_kinematics(m, d)

    started = time.perf_counter()
    for q in job["q"]:
        place(q)
        out.append([mujoco.mj_geomDistance(m, d, a, b, 10.0, fromto) for a, b in pairs])
    reply = {"distances": out, "checked": checked}
    if job.get("time"):
        n = len(job["q"])
        reply["distance_s"] = (time.perf_counter() - started) / n
        started = time.perf_counter()
        for q in job["q"]:
            place(q)
            mujoco.mj_collision(m, d)
        reply["collision_s"] = (time.perf_counter() - started) / n
        started = time.perf_counter()
        for q in job["q"]:
            place(q)
        reply["kinematics_s"] = (time.perf_counter() - started) / n
        started = time.perf_counter()
        for _ in range(100000):
            mujoco.mj_resetCallbacks()
        reply["call_s"] = (time.perf_counter() - started) / 100000
        try:
            import coal
        except ImportError:
            coal = None
        if coal is not None:
            shapes = {}
            for g in set(x for p in pairs for x in p):
                if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
                    shapes[g] = coal.Box(*(2 * m.geom_size[g]))
                else:
                    mesh = m.geom_dataid[g]
                    start, count = m.mesh_vertadr[mesh], m.mesh_vertnum[mesh]
                    bvh = coal.BVHModelOBBRSS()
                    bvh.beginModel(0, int(count))
                    bvh.addVertices(np.array(m.mesh_vert[start:start + count], dtype=float))
                    bvh.endModel()
                    bvh.buildConvexHull(True, "Qt")
                    shapes[g] = bvh.convex
            request, result = coal.DistanceRequest(), coal.DistanceResult()
            request.gjk_tolerance = 1e-9

            def pose(g):
                return coal.Transform3s(d.geom_xmat[g].reshape(3, 3).copy(), d.geom_xpos[g].copy())

            coal_out, spent = [], 0.0
            for q in job["q"]:
                place(q)
                poses = {g: pose(g) for g in shapes}
                started = time.perf_counter()
                row = []
                for a, b in pairs:
                    result.clear()
                    row.append(coal.distance(shapes[a], poses[a], shapes[b], poses[b], request, result))
                spent += time.perf_counter() - started
                coal_out.append(row)
            reply["coal"] = coal_out
            reply["coal_s"] = spent / n
    json.dump(reply, sys.stdout)


if __name__ == "__main__":
    main()
