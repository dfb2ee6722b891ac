"""The references of BENCHMARKS.md › Dynamics, timed on this machine: pinocchio's `aba`
and MuJoCo's `mj_forward` per call (from Python: the call's overhead is included, so
they are upper bounds), and MuJoCo's own stepping in C (`mj_step(m, d, nstep=N)`, no
Python in the loop) on franky-sim's FR3 without contacts — the simulated seconds per
wall second that cps's dynamics backend is measured against.

Run with the interpreter `.ci/run` makes for the Franka tests:
    target/franka-venv/bin/python benches/dynamics_references.py
"""

import os
import time

import franky_sim
import mujoco
import numpy as np
import pinocchio as pin

assets = os.path.join(os.path.dirname(franky_sim.__file__), "assets")


def best(f, repeat=7, number=20000):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(number):
            f()
        times.append((time.perf_counter() - t) / number)
    return min(times)


model = pin.buildModelFromUrdf(os.path.join(assets, "fr3_clean.urdf"))
model.armature = np.array([0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074])
data = model.createData()
q = np.array([0.3, -0.5, 0.2, -2.0, 0.1, 1.6, 0.7])
v = np.array([0.3, -0.2, 0.5, 0.1, -0.4, 0.2, 0.6])
tau = np.array([5.0, -3.0, 2.0, 1.0, 0.5, -0.2, 0.1])
print(f"pinocchio {pin.__version__} aba, fr3 (from Python): {best(lambda: pin.aba(model, data, q, v, tau)) * 1e9:.0f} ns")
print(f"pinocchio {pin.__version__} rnea, fr3 (from Python): {best(lambda: pin.rnea(model, data, q, v, tau)) * 1e9:.0f} ns")

spec = mujoco.MjSpec.from_file(os.path.join(assets, "fr3.xml"))
spec.meshdir = os.path.join(assets, "meshes")
for kind in ("actuators", "tendons", "equalities", "keys"):
    for x in list(getattr(spec, kind)):
        spec.delete(x)
for j in list(spec.joints):
    if j.name.startswith("finger"):
        spec.delete(j)
m = spec.compile()
m.opt.timestep = 0.001
m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
d = mujoco.MjData(m)
d.qpos[:] = q
d.qvel[:] = v
d.qfrc_applied[:] = tau
print(f"MuJoCo {mujoco.__version__} mj_forward, fr3 (from Python): {best(lambda: mujoco.mj_forward(m, d)) * 1e9:.0f} ns")
for integrator in ("EULER", "IMPLICITFAST", "RK4"):
    m.opt.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + integrator)
    steps = 100_000
    runs = []
    for _ in range(5):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = q
        t = time.perf_counter()
        mujoco.mj_step(m, d, nstep=steps)
        runs.append(time.perf_counter() - t)
    wall = min(runs)
    print(f"MuJoCo mj_step {integrator.lower()}, 1 ms steps, frictionloss on, no contacts: "
          f"{wall / steps * 1e9:.0f} ns a step, {steps * 1e-3 / wall:.0f}x real time")
