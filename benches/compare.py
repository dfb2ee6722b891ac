"""cps beside the Python references on the same work, in one run, as one table.

Run it through `benches/compare` (it builds cps's Python package and installs the pinned
references first); by hand, in an environment with `cps` installed:

    python benches/compare.py [--quick]

Every row is one task done by cps (from Python, so both sides pay the same interpreter)
and by a reference library; the ratio is the reference's time over cps's (above 1: cps is
faster). Where the result itself can differ (a trajectory's duration, a final cost), the
row says so beside the time. A reference that is not installed is skipped with a sentence
saying what to install. Timings are the best of several repetitions: the machine may be
shared, and the best is the least disturbed.
"""

import argparse
import importlib
import logging
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python" / "benchmarks"))

import cps  # noqa: E402

# The helpers of the per-topic scripts in python/benchmarks (the same paths and tasks).
thesis = importlib.import_module("compare")  # THESIS, demonstration, numpy_pycma_viapoint
robot_ready = importlib.import_module("robot_ready")  # path, panda_file, VMAX, AMAX, JMAX

# The references and the versions `benches/compare` installs (benches/compare-requirements.txt).
PINNED = {
    "cma": "cma==4.5.0",
    "movement_primitives": "movement-primitives==0.9.1",
    "pydmps": "pydmps==0.2",
    "toppra": "toppra==0.6.10",
    "ruckig": "ruckig==0.19.4",
    "pinocchio": "pin==4.1.0",
    "ezc3d": "ezc3d==1.7.2",
}

ROWS = []
SKIPPED = []


def best(f, number=1, repeat=5):
    """Seconds per call: the best of `repeat` batches of `number` calls."""
    return min(timeit.repeat(f, number=number, repeat=repeat)) / number


def reference(module):
    """The reference module, or None after noting what to install."""
    try:
        return importlib.import_module(module)
    except ImportError:
        SKIPPED.append(f"{module} is not installed: `pip install {PINNED[module]}` adds its rows")
        return None


def row(task, cps_s, ref, ref_s, note=""):
    ROWS.append((task, cps_s, ref, ref_s, note))


def fmt(s):
    if s >= 1.0:
        return f"{s:.2f} s"
    if s >= 1e-3:
        return f"{s * 1e3:.2f} ms"
    return f"{s * 1e6:.1f} µs"


def viapoint(quick):
    """The thesis's via-point task, 200 CMA-ES generations of 16, one thread."""
    generations = 50 if quick else 200
    run = lambda: cps.learn_via_points(**thesis.THESIS, population=16, generations=generations,  # noqa: E731
                                       tol_fun=None, threads=1)
    ours = best(run, repeat=3)
    cost = run().cost
    if reference("cma") is None:
        return
    theirs = best(lambda: thesis.numpy_pycma_viapoint(generations=generations), repeat=3)
    their_cost = thesis.numpy_pycma_viapoint(generations=generations)
    row(f"thesis via points, CMA-ES {generations}×16", ours, "numpy + pycma (vectorised)", theirs,
        f"final cost {cost:.3g} vs {their_cost:.3g}")


def cmaes_generation():
    """One CMA-ES ask + tell at n = 75, λ = 16, on a trivial objective."""
    es = cps.CMAES(np.zeros(75), 0.5, {"seed": 1, "popsize": 16})
    ours = best(lambda: _generation(es), 200)
    cma = reference("cma")
    if cma is None:
        return
    theirs_es = cma.CMAEvolutionStrategy(np.zeros(75), 0.5, {"seed": 1, "popsize": 16, "verbose": -9})

    def theirs_generation():
        x = theirs_es.ask()
        theirs_es.tell(x, [float(v @ v) for v in x])

    row("CMA-ES ask + tell, n = 75, λ = 16", ours, "pycma", best(theirs_generation, 200))


def _generation(es):
    x = es.ask()
    es.tell(x, [float(v @ v) for v in x])


def imitation():
    """Imitate a 3-D, 1000-sample demonstration with 25 bases, then roll out."""
    t, y = thesis.demonstration()
    ours = best(lambda: cps.imitate(t, y, bases=25).rollout(), 50)
    mp = reference("movement_primitives")
    if mp is not None:
        from movement_primitives.dmp import DMP

        def with_mp():
            d = DMP(n_dims=3, execution_time=10.0, dt=0.01, n_weights_per_dim=25)
            d.imitate(t, y)
            return d.open_loop()

        row("imitate + rollout, 3-D, 1000 samples, 25 bases", ours, "movement_primitives",
            best(with_mp, 3, repeat=3))
    pydmps = reference("pydmps")
    if pydmps is not None:
        import pydmps.dmp_discrete

        def with_pydmps():
            d = pydmps.dmp_discrete.DMPs_discrete(n_dmps=3, n_bfs=25, dt=0.001)
            d.imitate_path(y_des=y.T)
            return d.rollout()

        row("imitate + rollout, 3-D, 1000 samples, 25 bases", ours, "pydmps", best(with_pydmps, 3, repeat=3))


def promp():
    """Fit a ProMP to 20 demonstrations × 1000 samples × 3 dimensions, 25 bases."""
    if reference("movement_primitives") is None:
        return
    beyond = importlib.import_module("beyond")
    from movement_primitives.promp import ProMP

    d = beyond.demos()
    ours = best(lambda: cps.ProMP.fit(d, bases=25, duration=1.0), 5)
    ts, ys = np.array([t for t, _ in d]), np.array([y for _, y in d])
    theirs = best(lambda: ProMP(n_dims=3, n_weights_per_dim=25).imitate(ts, ys), 3, repeat=3)
    row("ProMP fit, 20 × 1000 × 3, 25 bases", ours, "movement_primitives", theirs)


def retiming(folder):
    """Time-optimal retiming of a 1000-sample Panda path, velocity + acceleration limits."""
    t, q = robot_ready.path()
    va = robot_ready.panda_file(["ddq_max"], folder)
    r = va.retime(t, q)
    ours = best(lambda: va.retime(t, q), repeat=3)
    toppra = reference("toppra")
    if toppra is None:
        return
    from toppra import algorithm, constraint

    logging.getLogger("toppra").setLevel(logging.WARNING)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
    vmax, amax = robot_ready.VMAX, robot_ready.AMAX

    def solve():
        p = toppra.SplineInterpolator(arc, q, bc_type="natural")
        cv = constraint.JointVelocityConstraint(np.stack([-vmax, vmax], 1))
        ca = constraint.JointAccelerationConstraint(np.stack([-amax, amax], 1))
        grid = np.linspace(0.0, p.duration, 1001)
        return algorithm.TOPPRA([cv, ca], p, gridpoints=grid,
                                parametrizer="ParametrizeConstAccel").compute_trajectory()

    d = solve().duration
    row("retime a 1000-sample Panda path (velocity, acceleration)", ours, "toppra", best(solve, repeat=3),
        f"duration {r['duration_s']:.4f} s vs {d:.4f} s ({r['duration_s'] / d:.3f}×)")
    # Every joint-space limit of the Panda in cps (jerk and torque rate too), against
    # toppra's time-optimal law with the torque constraint (pinocchio's RNEA on the same
    # inertias): how close to the optimum the limits toppra cannot hold leave cps.
    pinocchio = reference("pinocchio")
    if pinocchio is None:
        return
    model, data = robot_ready.panda_pinocchio(pinocchio)
    tau = np.array([87.0] * 4 + [12.0] * 3)
    joint = robot_ready.panda_file(["ddq_max", "dddq_max", "tau_max", "dtau_max", "mass", "com", "inertia"],
                                   folder)
    rj = joint.retime(t, q)
    ours_j = best(lambda: joint.retime(t, q), repeat=3)

    def solve_torque(*more):
        p = toppra.SplineInterpolator(arc, q, bc_type="natural")
        cv = constraint.JointVelocityConstraint(np.stack([-vmax, vmax], 1))
        ca = constraint.JointAccelerationConstraint(np.stack([-amax, amax], 1))
        ct = constraint.JointTorqueConstraint(lambda x, xd, xdd: pinocchio.rnea(model, data, x, xd, xdd),
                                              np.stack([-tau, tau], 1), np.zeros(7),
                                              discretization_scheme=constraint.DiscretizationType.Interpolation)
        grid = np.linspace(0.0, p.duration, 1001)
        return algorithm.TOPPRA([cv, ca, ct, *more], p, gridpoints=grid,
                                parametrizer="ParametrizeConstAccel").compute_trajectory()

    dt = solve_torque().duration
    row("retime, every joint limit (+ jerk, torque, torque rate)", ours_j, "toppra + torque (pinocchio)",
        best(solve_torque, repeat=3),
        f"duration {rj['duration_s']:.4f} s vs {dt:.4f} s ({rj['duration_s'] / dt:.3f}×; toppra holds no jerk or torque rate)")
    full = cps.Robot("panda")
    rf = full.retime(t, q)
    # The same with the tool's Cartesian limits (configs/robots/panda.toml [cartesian]) as
    # one second-order constraint on the Franka Hand's TCP, from pinocchio's frame
    # velocity and classical acceleration: the squared translation and rotation speeds
    # (linear in ṡ²) and the two acceleration norms, each held by the tangent planes of
    # its ball at 200 directions (an outer polyhedron: toppra's duration is a lower bound
    # of the optimum). The elbow's limits are joint 3's, already held.
    cartesian = robot_ready.toppra_cartesian(pinocchio, constraint)

    def solve_cartesian():
        return solve_torque(cartesian)

    dc = solve_cartesian().duration
    row("retime, every Panda limit (+ Cartesian tool and elbow)", best(lambda: full.retime(t, q), repeat=2),
        "toppra + torque + Cartesian", best(solve_cartesian, repeat=2),
        f"duration {rf['duration_s']:.4f} s vs {dc:.4f} s ({rf['duration_s'] / dc:.3f}×; "
        f"{rf['duration_s'] / dt:.3f}× toppra without the Cartesian limits)")


def rest_to_rest(folder):
    """A jerk-limited rest-to-rest move of seven joints."""
    a = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7])
    b = np.array([1.5, 0.3, -0.8, -1.2, 0.6, 2.4, -0.5])
    s = np.linspace(0.0, 1.0, 50)
    robot = robot_ready.panda_file(["ddq_max", "dddq_max"], folder)
    line = a + np.outer(s, b - a)
    r = robot.retime(s, line)
    ours = best(lambda: robot.retime(s, line), repeat=3)
    ruckig = reference("ruckig")
    if ruckig is None:
        return

    def solve():
        otg, inp, traj = ruckig.Ruckig(7), ruckig.InputParameter(7), ruckig.Trajectory(7)
        inp.current_position, inp.target_position = a.tolist(), b.tolist()
        inp.max_velocity = robot_ready.VMAX.tolist()
        inp.max_acceleration = robot_ready.AMAX.tolist()
        inp.max_jerk = robot_ready.JMAX.tolist()
        otg.calculate(inp, traj)
        return traj.duration

    d = solve()
    row("rest-to-rest, 7 joints, jerk limits", ours, "ruckig", best(solve, 200),
        f"duration {r['duration_s']:.4f} s vs {d:.4f} s ({r['duration_s'] / d:.3f}×)")


def dynamics():
    """Inverse dynamics of the Panda, one state."""
    robot = cps.Robot("panda")
    rng = np.random.default_rng(1)
    lo, hi = robot.limits
    q, qd, qdd = rng.uniform(lo, hi), rng.uniform(-2, 2, 7), rng.uniform(-5, 5, 7)
    ours = best(lambda: robot.inverse_dynamics(q, qd, qdd), 20000)
    pinocchio = reference("pinocchio")
    if pinocchio is None:
        return
    model, data = robot_ready.panda_pinocchio(pinocchio)
    err = np.abs(robot.inverse_dynamics(q, qd, qdd) - pinocchio.rnea(model, data, q, qd, qdd)).max()
    row("Panda inverse dynamics, one state", ours, "pinocchio.rnea",
        best(lambda: pinocchio.rnea(model, data, q, qd, qdd), 20000), f"largest difference {err:.1e} N m")


def mocap(folder, quick):
    """Read a C3D take: 60 s (10 s with --quick) at 240 Hz, 40 markers, float."""
    ezc3d = reference("ezc3d")
    if ezc3d is None:
        return
    seconds = 10 if quick else 60
    path = Path(folder) / "take.c3d"
    built = ROOT / "target" / "release" / "examples" / "synthetic_take"
    import subprocess

    if not built.exists():
        subprocess.run(["cargo", "build", "-q", "--release", "-p", "cps-mocap", "--example", "synthetic_take"],
                       cwd=ROOT, check=True)
    subprocess.run([str(built), str(path), "--markers", "40", "--seconds", str(seconds), "--noise-mm", "0.5"],
                   check=True, stdout=subprocess.DEVNULL)
    ours = best(lambda: cps.mocap.take(str(path)), repeat=3)
    theirs = best(lambda: ezc3d.c3d(str(path)), repeat=2)
    row(f"read a C3D take, {seconds} s × 240 Hz × 40 markers", ours, "ezc3d", theirs)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="shorter tasks (a smoke run, not figures)")
    args = parser.parse_args()
    started = time.perf_counter()
    import cps.mocap  # noqa: F401

    with tempfile.TemporaryDirectory() as folder:
        for step in [lambda: viapoint(args.quick), cmaes_generation, imitation, promp,
                     lambda: retiming(folder), lambda: rest_to_rest(folder), dynamics,
                     lambda: mocap(folder, args.quick)]:
            step()
    width = max(len(r[0]) for r in ROWS) if ROWS else 10
    ref_width = max(len(r[2]) for r in ROWS) if ROWS else 10
    print(f"{'task':{width}}  {'cps':>10}  {'reference':{ref_width}}  {'time':>10}  {'ratio':>8}  result")
    for task, ours, ref, theirs, note in ROWS:
        ratio = theirs / ours
        ratio = f"{ratio:7.1f}×" if ratio >= 10 else f"{ratio:7.2f}×" if ratio >= 0.1 else f"1/{ours / theirs:.0f}"
        print(f"{task:{width}}  {fmt(ours):>10}  {ref:{ref_width}}  {fmt(theirs):>10}  {ratio:>8}  {note}")
    for s in dict.fromkeys(SKIPPED):
        print(f"skipped: {s}")
    print(f"(cps {cps.__version__}; ratio = the reference's time / cps's; "
          f"{time.perf_counter() - started:.0f} s in all)")


if __name__ == "__main__":
    main()
