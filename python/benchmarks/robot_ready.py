"""cps's retiming and inverse dynamics beside toppra, ruckig and pinocchio, in one run.

    pip install ./python toppra ruckig pin      # from the repository root
    python python/benchmarks/robot_ready.py

1. Retiming a 1000-sample 7-joint Panda path (the path of benches/core.rs
   `retime/panda_1000_*`) with velocity and acceleration limits: toppra's TOPP-RA on the
   same path (cps's parameter: chord length, natural cubic spline) and grid (1000
   intervals), against `cps.Robot.retime` (TOPP-RA, then verification at 1 kHz and ten
   times finer), durations side by side; then cps with every Panda limit.
2. A rest-to-rest straight move with jerk limits: ruckig against cps.
3. Inverse dynamics of the Panda: pinocchio's rnea against `cps.Robot.inverse_dynamics`,
   both called from Python (criterion's `rnea/panda` is the Rust figure).

Timings are the best of several repetitions (the machine is shared). Libraries that are
not installed are skipped.
"""

import importlib.util
import logging
import tempfile
import timeit
from pathlib import Path

import numpy as np

import cps

ROOT = Path(__file__).resolve().parents[2]
VMAX = np.array([2.175] * 4 + [2.61] * 3)
AMAX = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
JMAX = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])
# configs/robots/panda.toml [cartesian]: [velocity, acceleration, jerk] of the tool point's
# translation (m/s …) and of its rotation (rad/s …).
CARTESIAN = ((1.7, 13.0, 6500.0), (2.5, 25.0, 12500.0))


def panda_pinocchio(pinocchio):
    """pinocchio's model of the Panda with cps's inertias, written independently of cps's
    Rust code (crates/cps-kinematics/tests/data/make_panda_rnea.py), and its data."""
    spec = importlib.util.spec_from_file_location(
        "make_panda_rnea", ROOT / "crates/cps-kinematics/tests/data/make_panda_rnea.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    model = pinocchio.buildModelFromXML(gen.urdf())
    return model, model.createData()


def toppra_cartesian(pinocchio, constraint, directions=200):
    """toppra's second-order constraint for the Panda's Cartesian limits (CARTESIAN) at the
    Franka Hand's TCP, from pinocchio's frame velocity and classical acceleration: the
    squared translation and rotation speeds (linear in ṡ²) and the two acceleration norms,
    each held by the tangent planes of its ball at `directions` points of a Fibonacci
    sphere. The polyhedron holds the ball from outside, so toppra's duration under it is a
    lower bound of the optimum. The elbow's limits are joint 3's, held as joint limits."""
    model, _ = panda_pinocchio(pinocchio)
    # configs/robots/panda.toml [tools.hand]: 0.2104 m along joint 7's z, turned -45° about it.
    placement = pinocchio.SE3(pinocchio.utils.rotate("z", -np.pi / 4), np.array([0.0, 0.0, 0.2104]))
    frame = model.addFrame(pinocchio.Frame("tcp", model.getJointId("j7"), model.getFrameId("link7"),
                                           placement, pinocchio.FrameType.OP_FRAME))
    data = model.createData()
    world = pinocchio.ReferenceFrame.LOCAL_WORLD_ALIGNED
    (v_lin, a_lin, _), (v_rot, a_rot, _) = CARTESIAN

    def tcp(x, xd, xdd):
        pinocchio.forwardKinematics(model, data, x, xd, xdd)
        pinocchio.updateFramePlacement(model, data, frame)
        acc = pinocchio.getFrameClassicalAcceleration(model, data, frame, world)
        vel = pinocchio.getFrameVelocity(model, data, frame, world)
        return np.concatenate([acc.linear, acc.angular, [vel.linear @ vel.linear, vel.angular @ vel.angular]])

    k = np.arange(directions) + 0.5
    polar, turn = np.arccos(1.0 - 2.0 * k / directions), np.pi * (1.0 + 5.0 ** 0.5) * k
    d = np.stack([np.cos(turn) * np.sin(polar), np.sin(turn) * np.sin(polar), np.cos(polar)], 1)
    f = np.zeros((2 * directions + 2, 8))
    f[:directions, :3], f[directions:-2, 3:6], f[-2, 6], f[-1, 7] = d, d, 1.0, 1.0
    g = np.concatenate([np.full(directions, a_lin), np.full(directions, a_rot), [v_lin ** 2, v_rot ** 2]])
    return constraint.SecondOrderConstraint(tcp, lambda x: f, lambda x: g, dof=7,
                                            discretization_scheme=constraint.DiscretizationType.Interpolation)


def best(f, number, repeat=5):
    return min(timeit.repeat(f, number=number, repeat=repeat)) / number


def fmt(s):
    return f"{s * 1e6:8.1f} µs" if s < 1e-3 else f"{s * 1e3:8.2f} ms"


def path():
    amp = np.array([0.25, 0.5, 0.35, 0.3, 0.45, 0.4, 0.55])
    freq = np.array([0.7, 1.2, 0.9, 1.4, 0.6, 1.1, 0.8])
    mid = np.array([0.0, 0.0, 0.0, -1.5, 0.0, 1.8, 0.0])
    s = np.arange(1000) / 999.0
    q = mid + amp * np.sin(2 * np.pi * freq * s[:, None] + np.arange(7))
    return 2.0 * s, q


def panda_file(keep, folder):
    """configs/robots/panda.toml with only the limits in `keep` beyond range and speed."""
    drop = {"ddq_max", "dddq_max", "tau_max", "dtau_max", "mass", "com", "inertia",
            "[cartesian]", "translation", "rotation", "elbow"} - set(keep)
    lines = (ROOT / "configs/robots/panda.toml").read_text().splitlines()
    p = Path(folder) / f"panda_{'_'.join(keep)}.toml"
    p.write_text("\n".join(l for l in lines if l.split(" = ")[0].strip() not in drop) + "\n")
    return cps.Robot(str(p))


def retiming(folder):
    t, q = path()
    va = panda_file(["ddq_max"], folder)
    r = va.retime(t, q)
    print(f"1000-sample 7-joint path, velocity + acceleration limits:")
    print(f"  cps      {fmt(best(lambda: va.retime(t, q), 5))}  duration {r['duration_s']:.4f} s "
          f"(TOPP-RA law {r['topp_duration_s']:.4f} s, {r['rounds']} rounds)")
    try:
        import toppra
        from toppra import algorithm, constraint
    except ImportError:
        print("  toppra   not installed")
    else:
        logging.getLogger("toppra").setLevel(logging.WARNING)
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])

        def solve():
            p = toppra.SplineInterpolator(arc, q, bc_type="natural")
            cv = constraint.JointVelocityConstraint(np.stack([-VMAX, VMAX], 1))
            ca = constraint.JointAccelerationConstraint(np.stack([-AMAX, AMAX], 1))
            grid = np.linspace(0.0, p.duration, 1001)
            return algorithm.TOPPRA([cv, ca], p, gridpoints=grid, parametrizer="ParametrizeConstAccel").compute_trajectory()

        d = solve().duration
        print(f"  toppra   {fmt(best(solve, 3))}  duration {d:.4f} s "
              f"(cps / toppra = {r['duration_s'] / d:.4f})")
    full = cps.Robot("panda")
    f = full.retime(t, q)
    print(f"  cps, every Panda limit (jerk, torque, torque rate, Cartesian): {fmt(best(lambda: full.retime(t, q), 2, 3))}, "
          f"duration {f['duration_s']:.4f} s")


def rest_to_rest(folder):
    a = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7])
    b = np.array([1.5, 0.3, -0.8, -1.2, 0.6, 2.4, -0.5])
    s = np.linspace(0.0, 1.0, 50)
    robot = panda_file(["ddq_max", "dddq_max"], folder)
    r = robot.retime(s, a + np.outer(s, b - a))
    print("rest-to-rest straight move with jerk limits:")
    print(f"  cps      {fmt(best(lambda: robot.retime(s, a + np.outer(s, b - a)), 5))}  duration {r['duration_s']:.4f} s")
    try:
        import ruckig
    except ImportError:
        print("  ruckig   not installed")
        return

    def solve():
        otg, inp, traj = ruckig.Ruckig(7), ruckig.InputParameter(7), ruckig.Trajectory(7)
        inp.current_position, inp.target_position = a.tolist(), b.tolist()
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = VMAX.tolist(), AMAX.tolist(), JMAX.tolist()
        otg.calculate(inp, traj)
        return traj.duration

    d = solve()
    print(f"  ruckig   {fmt(best(solve, 200))}  duration {d:.4f} s (cps / ruckig = {r['duration_s'] / d:.4f})")


def dynamics():
    robot = cps.Robot("panda")
    rng = np.random.default_rng(1)
    lo, hi = robot.limits
    q, qd, qdd = rng.uniform(lo, hi), rng.uniform(-2, 2, 7), rng.uniform(-5, 5, 7)
    print("inverse dynamics of the Panda, one state, from Python:")
    print(f"  cps.Robot.inverse_dynamics {fmt(best(lambda: robot.inverse_dynamics(q, qd, qdd), 20000))}")
    Q = rng.uniform(lo, hi, (1000, 7))
    try:
        import pinocchio
    except ImportError:
        print("  pinocchio not installed")
        return
    spec = __import__("importlib.util").util.spec_from_file_location(
        "gen", ROOT / "crates/cps-kinematics/tests/data/make_panda_rnea.py")
    gen = __import__("importlib.util").util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    model = pinocchio.buildModelFromXML(gen.urdf())
    data = model.createData()
    print(f"  pinocchio.rnea             {fmt(best(lambda: pinocchio.rnea(model, data, q, qd, qdd), 20000))}")
    err = max(np.abs(robot.inverse_dynamics(x, qd, qdd) - pinocchio.rnea(model, data, x, qd, qdd)).max() for x in Q)
    print(f"  largest difference over 1000 states: {err:.1e} N m")


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as folder:
        retiming(folder)
        rest_to_rest(folder)
    dynamics()
