#!/usr/bin/env python3
"""Fails when a module imports a module of its own crate that is not below it.

For every crate (and the facade), each file under src/ is a module (`a/mod.rs` and `a.rs`
are `a`; `a/b.rs` is `a::b`, counted as part of `a`), and an edge a -> b is any
`crate::b` path in a's code (use lines and inline paths; items that lib.rs re-exports are
followed to the module that defines them when lib.rs says `pub use b::...`). A module's
own children are part of it.

Every crate with three modules or more has its layers below, lowest first; a module may
import only modules of lower layers, so the house reads bottom up and nothing points
back. A module no layer names is an error (a new module takes its place here). Crates
without layers (fewer modules) are checked for circles only. ARCHITECTURE.md describes the
layers.
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Lowest layer first; each layer a list of modules.
LAYERS = {
    "cps-dmp": [
        ["basis", "canonical", "discretize", "error", "jet", "trajectory"],
        ["names"],
        ["config"],
        ["dmp"],
        ["generalize", "imitation", "model", "online"],
        ["coupling", "quaternion", "rhythmic", "sequence"],
        ["pose"],
    ],
    "cps-cmaes": [
        ["error", "params", "stop"],
        ["bounds"],
        ["config"],
        ["cmaes"],
        ["driver"],
        ["functions"],
    ],
    "cps-kinematics": [
        ["error", "fastmath", "transforms", "xml"],
        ["chain", "spline", "urdf_collision"],
        ["controllers", "dynamics"],
        ["ik", "limits", "urdf"],
        ["retime", "robots", "workspace"],
        ["arm_model"],
        ["contact"],
        ["forward"],
    ],
    "cps-dynamics": [
        ["arm", "controller"],
        ["robot"],
        ["identify"],
        ["options"],
    ],
    "cps-plan": [
        ["free"],
        ["rrt"],
        ["join"],
    ],
    "cps-robot": [
        ["setting"],
        ["plan", "stop"],
        ["collision", "never"],
        ["model"],
        ["check"],
        ["cycles"],
        ["robot", "watch"],
        ["execute", "guard", "kinematic"],
    ],
    "cps-chunks": [
        ["error"],
        ["chunk", "follow"],
        ["executor"],
        ["feed"],
        ["run"],
        ["report"],
    ],
    "cps-learn": [
        ["clearance", "error", "pool", "search", "space"],
        ["task"],
        ["exact", "robot"],
        ["executed", "lsq"],
        ["keep_clear", "viapoint"],
        ["energy", "imitation", "joint", "pose"],
        ["executions", "joint_executed"],
    ],
    "cps-geometry": [
        ["error", "gjk"],
        ["hull"],
        ["mesh", "shape"],
        ["model", "surface"],
    ],
    "cps-mocap": [
        ["error", "fit"],
        ["take"],
        ["c3d", "clean", "motive", "register", "synthetic"],
        ["demo"],
    ],
    "cps-coppelia": [
        ["codec", "error"],
        ["config", "zmtp"],
        ["client", "client_absent", "executor"],
        ["server", "sim"],
        ["franka"],
    ],
    "cps-testkit": [
        ["franky_sim", "ros2_graph"],
        ["franka_sim"],
    ],
    "cps-franka": [
        ["wire"],
        ["limits"],
        ["reference"],
        ["error"],
        ["session"],
        ["control", "gripper", "rt"],
        ["guide", "motion"],
        ["robot"],
    ],
    "cps-ros2": [
        ["names"],
        ["discovery"],
        ["markers", "node"],
        ["graph", "publish", "record", "service"],
        ["action"],
        ["robot"],
    ],
    "cps-files": [
        ["error"],
        ["count", "read", "replace"],
    ],
    "cps-outcome": [
        ["error", "outcome"],
        ["files", "results_dir", "source"],
    ],
    "cps-report": [
        ["figures", "report"],
        ["write"],
    ],
    "cps-lerobot": [
        ["error"],
        ["info", "table"],
        ["dataset"],
        ["write"],
    ],
    "cps-movement": [
        ["calibration", "chunks", "dae", "left_out"],
        ["collision"],
        ["robot_file"],
        ["lerobot"],
        ["movement", "scene"],
        ["lerobot_write", "limits", "mocap", "promp"],
        ["collide", "planning", "retiming"],
        ["export"],
    ],
    "cps-drive": [
        # the crate's error, and the words of what its commands return
        ["error", "said"],
        ["chunk_socket", "recording", "ros2_graph", "scene", "stand_in"],
        ["franka", "ros2"],
        # the contact task, identification and chunks on a Franka use its connection's words
        ["contact", "follow", "identify", "ros2_follow"],
    ],
    "cps-experiment": [
        # what the others use: progress events
        ["observer"],
        # each kind's sections of the file and the robot chosen, read into plans
        ["sections"],
        # the chosen robot opened
        ["robots"],
        # the sections checked against the kind: one Experiment
        ["plan"],
        # what it asks of the machine
        ["budget"],
        # the file read, with places in errors
        ["experiment"],
        # each kind's run
        ["kinds"],
        # the entry points
        ["markers", "run"],
    ],
    "cps-studio": [
        ["assets", "robot"],
        ["api"],
        ["files", "imitation"],
        ["config"],
        ["http", "http_absent"],
    ],
    "cps-python": [
        ["errors"],
        ["arrays", "interrupt"],
        ["cmaes", "dmp", "experiment", "promp"],
        ["chunks", "franka", "kinematics", "learn", "lerobot", "mocap", "ros2"],
    ],
    "cps-cli": [
        ["progress", "robot", "simserve", "studio"],
        ["cmaes_bench", "franka", "lerobot", "mocap", "movement", "ros2", "scene", "trajectory"],
        ["promp"],
    ],
}


def top_module(src, path):
    rel = os.path.relpath(path, src)[:-3].replace(os.sep, "/")
    head = rel.split("/")[0]
    return None if head in ("lib", "main") else head


def crate_graph(src):
    files = []
    for d, _, names in os.walk(src):
        files += [os.path.join(d, n) for n in names if n.endswith(".rs")]
    modules = {top_module(src, f) for f in files} - {None}
    # lib.rs re-exports: `pub use module::{A, B}` or `pub use module::A;` (only of this
    # crate's modules: re-exported crates are not modules)
    reexport = {}
    lib = os.path.join(src, "lib.rs")
    if os.path.exists(lib):
        text = open(lib, encoding="utf-8").read()
        for m, items in re.findall(r"pub use (\w+)::\{([^}]*)\}", text):
            for it in re.findall(r"\w+", items):
                if m in modules:
                    reexport[it] = m
        for m, it in re.findall(r"pub use (\w+)::(\w+);", text):
            if m in modules:
                reexport[it] = m
    edges = {m: set() for m in modules}
    for f in files:
        a = top_module(src, f)
        if a is None:
            continue
        text = open(f, encoding="utf-8").read()
        text = re.sub(r"//[^\n]*", "", text)
        names = set(re.findall(r"crate::(\w+)", text))
        for group in re.findall(r"crate::\{([^}]*)\}", text):
            names |= set(re.findall(r"\b(\w+)\b", group))
        for n in names:
            b = n if n in modules else reexport.get(n)
            if b and b != a:
                edges[a].add(b)
    return edges


def cycles(edges):
    found, state, stack = [], {}, []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in sorted(edges[n]):
            if state.get(m) == 1:
                found.append(stack[stack.index(m):] + [m])
            elif m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(edges):
        if n not in state:
            visit(n)
    return found


def layer_faults(crate, edges):
    layers = LAYERS.get(crate)
    if layers is None:
        if len(edges) >= 3:
            return [f"{crate} has {len(edges)} modules and no layers: add them to .ci/module-layers.py"]
        return []
    level = {}
    faults = []
    for i, layer in enumerate(layers):
        for m in layer:
            level[m] = i
    for m in sorted(set(edges) - set(level)):
        faults.append(f"{crate}: module `{m}` is in no layer: add it to .ci/module-layers.py")
    for m in sorted(set(level) - set(edges)):
        faults.append(f"{crate}: layer module `{m}` does not exist: remove it from .ci/module-layers.py")
    for a in sorted(edges):
        for b in sorted(edges[a]):
            if a in level and b in level and level[b] >= level[a]:
                faults.append(
                    f"{crate}: `{a}` (layer {level[a] + 1}) imports `{b}` (layer {level[b] + 1}); "
                    "a module may import only modules below it"
                )
    return faults


def main():
    # The check must be able to see an edge: cps-experiment's run module calls its kinds.
    probe = crate_graph(os.path.join(ROOT, "crates", "cps-experiment", "src"))
    if "kinds" not in probe.get("run", set()):
        print("FAIL: the module check cannot see cps-experiment's run -> kinds")
        return 1
    bad = []
    crates = [(".", os.path.join(ROOT, "src"))] + [
        (c, os.path.join(ROOT, "crates", c, "src"))
        for c in sorted(os.listdir(os.path.join(ROOT, "crates")))
    ]
    for crate, src in crates:
        if not os.path.isdir(src):
            continue
        edges = crate_graph(src)
        for c in cycles(edges):
            bad.append(f"{crate}: modules in a circle: {' -> '.join(c)}")
        bad += layer_faults(crate, edges)
    for b in bad:
        print(b)
    if bad:
        return 1
    print(f"modules layered: {len(LAYERS)} crates, no import upwards, no circles")
    return 0


if __name__ == "__main__":
    sys.exit(main())
