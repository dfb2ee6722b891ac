"""`cps-cli retime` against independent references: the `toppra` package (TOPP-RA by its
authors) on the same paths, and `ruckig` (time-optimal jerk-limited motions) for
rest-to-rest moves; the output is checked with numpy, not with cps."""

import csv
import json
import logging

import numpy as np
import pytest

from conftest import ROOT

toppra = pytest.importorskip("toppra")
ruckig = pytest.importorskip("ruckig")
from toppra import algorithm as ta_algorithm  # noqa: E402
from toppra import constraint as ta_constraint  # noqa: E402

logging.getLogger("toppra").setLevel(logging.WARNING)

VMAX = np.array([2.175] * 4 + [2.61] * 3)
AMAX = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
JMAX = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])
QMIN = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
QMAX = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])


def panda_file(tmp_path, keep):
    """configs/robots/panda.toml with only the limits in `keep` beyond range and speed
    (`cartesian` keeps the [cartesian] section)."""
    dropped = {"ddq_max", "dddq_max", "tau_max", "dtau_max", "mass", "com", "inertia"} - set(keep)
    if "cartesian" not in keep:
        dropped |= {"[cartesian]", "translation", "rotation", "elbow"}
    lines = (ROOT / "configs/robots/panda.toml").read_text().splitlines()
    text = "\n".join(l for l in lines if l.split(" = ")[0].strip() not in dropped)
    p = tmp_path / f"panda_{'_'.join(keep) or 'none'}.toml"
    p.write_text(text + "\n")
    return p


def write_path(path, t, q):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t"] + [f"q{i + 1}" for i in range(q.shape[1])])
        for ti, row in zip(t, q):
            w.writerow([repr(float(ti))] + [repr(float(x)) for x in row])


def read_retimed(path):
    data = np.genfromtxt(path, delimiter=",", names=True)
    names = data.dtype.names
    t = data["t"]
    q = np.stack([data[n] for n in names[1:8]], 1)
    qd = np.stack([data[n] for n in names[8:15]], 1)
    qdd = np.stack([data[n] for n in names[15:22]], 1)
    return t, q, qd, qdd


def smooth_path(n, seed):
    """A random smooth 7-joint path inside the Panda's range, n samples over 2 s."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, n)
    mid = np.array([0.0, 0.0, 0.0, -1.5, 0.0, 1.8, 0.0])
    amp = rng.uniform(0.2, 0.6, 7)
    freq = rng.uniform(0.5, 1.5, 7)
    phase = rng.uniform(0, 2 * np.pi, 7)
    q = mid + amp * np.sin(2 * np.pi * freq * s[:, None] + phase)
    assert np.all(q > QMIN) and np.all(q < QMAX)
    return 2.0 * s, q


def chord_knots(q):
    """cps's path parameter: cumulative chord length in joint space (module docs of
    cps_kinematics::retime)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])


def toppra_duration(q, grid):
    path = toppra.SplineInterpolator(chord_knots(q), q, bc_type="natural")
    cv = ta_constraint.JointVelocityConstraint(np.stack([-VMAX, VMAX], 1))
    ca = ta_constraint.JointAccelerationConstraint(np.stack([-AMAX, AMAX], 1))
    s = np.linspace(0.0, path.duration, grid + 1)
    algo = ta_algorithm.TOPPRA([cv, ca], path, gridpoints=s, parametrizer="ParametrizeConstAccel")
    return algo.compute_trajectory().duration


@pytest.mark.parametrize("seed,n", [(1, 1000), (2, 1000), (3, 12), (4, 5)])
def test_fastest_timing_matches_toppra_with_velocity_and_acceleration_limits(cli, tmp_path, seed, n):
    robot = panda_file(tmp_path, ["ddq_max"])
    t, q = smooth_path(n, seed)
    write_path(tmp_path / "p.csv", t, q)
    out = tmp_path / "r.csv"
    r = json.loads(cli("retime", tmp_path / "p.csv", "--robot", robot, "--out", out, "--json").stdout)
    reference = toppra_duration(q, max(1000, n))
    assert r["ok"] and r["mode"] == "fastest"
    # Within 1 % of toppra (cps rounds the end up to a control period and, when its
    # verification sees a limit touched between grid points, tightens by 0.1 %).
    assert abs(r["duration_s"] / reference - 1.0) < 0.01, (r["duration_s"], reference)
    tr, qr, qd, qdd = read_retimed(out)
    # The same path: every input sample is passed through, in order, from start to end.
    assert np.allclose(qr[0], q[0], atol=1e-12) and np.allclose(qr[-1], q[-1], atol=1e-12)
    assert np.allclose(np.diff(tr), 1e-3)
    # The exact derivatives and numpy's differences of the commands keep every limit.
    assert np.all(np.abs(qd) <= VMAX * (1 + 1e-9)) and np.all(np.abs(qdd) <= AMAX * (1 + 1e-9))
    v = np.diff(np.vstack([qr[:1], qr, qr[-1:]]), axis=0) / 1e-3
    a = np.diff(np.vstack([np.zeros((1, 7)), v]), axis=0) / 1e-3
    assert np.all(np.abs(v) <= VMAX * (1 + 1e-9)) and np.all(np.abs(a) <= AMAX * (1 + 1e-9))
    # Numpy's derivatives agree with the written ones.
    assert np.max(np.abs(np.gradient(qr, tr, axis=0) - qd)[2:-2]) < 0.02 * VMAX.max()


def test_between_commands_ten_times_finer_no_limit_is_exceeded(cli, tmp_path):
    """The same path retimed at 10 kHz gives the same law (TOPP-RA does not depend on the
    rate) sampled ten times finer: its exact derivatives keep every limit."""
    robot = panda_file(tmp_path, ["ddq_max", "dddq_max"])
    t, q = smooth_path(1000, 5)
    write_path(tmp_path / "p.csv", t, q)
    coarse = json.loads(cli("retime", tmp_path / "p.csv", "--robot", robot, "--out", tmp_path / "c.csv", "--json").stdout)
    fine = json.loads(
        cli("retime", tmp_path / "p.csv", "--robot", robot, "--rate", 10000, "--out", tmp_path / "f.csv", "--json").stdout
    )
    assert abs(fine["topp_duration_s"] - coarse["topp_duration_s"]) < 2e-3 * coarse["topp_duration_s"]
    _, _, qd, qdd = read_retimed(tmp_path / "f.csv")
    assert np.all(np.abs(qd) <= VMAX * (1 + 1e-9)) and np.all(np.abs(qdd) <= AMAX * (1 + 1e-9))


@pytest.mark.parametrize(
    "a,b",
    [
        ([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7], [1.5, 0.3, -0.8, -1.2, 0.6, 2.4, -0.5]),
        ([0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0], [0.3, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0]),
        ([-1.0, 0.5, 1.0, -2.5, 1.0, 1.0, 2.0], [1.0, -0.5, -1.0, -0.5, -1.0, 3.0, -2.0]),
    ],
)
def test_rest_to_rest_with_jerk_limits_is_as_fast_as_ruckig(cli, tmp_path, a, b):
    """For a straight joint-space move from rest to rest, ruckig's time-synchronised
    duration (each joint's own time-optimal jerk-limited profile, stretched to the slowest)
    is a lower bound on any straight-line timing; cps's smoothed TOPP-RA law is the
    S-curve of the binding joint and should sit within a few control periods of it."""
    robot = panda_file(tmp_path, ["ddq_max", "dddq_max"])
    a, b = np.array(a), np.array(b)
    t = np.linspace(0.0, 1.0, 50)
    write_path(tmp_path / "p.csv", t, a + np.outer(t, b - a))
    r = json.loads(cli("retime", tmp_path / "p.csv", "--robot", robot, "--out", tmp_path / "r.csv", "--json").stdout)
    otg = ruckig.Ruckig(7)
    inp, traj = ruckig.InputParameter(7), ruckig.Trajectory(7)
    inp.current_position, inp.target_position = a.tolist(), b.tolist()
    inp.current_velocity = inp.current_acceleration = [0.0] * 7
    inp.target_velocity = inp.target_acceleration = [0.0] * 7
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = VMAX.tolist(), AMAX.tolist(), JMAX.tolist()
    assert otg.calculate(inp, traj) == ruckig.Result.Working
    assert r["duration_s"] >= traj.duration - 1e-3
    assert r["duration_s"] <= traj.duration * 1.01 + 2e-3, (r["duration_s"], traj.duration)
    _, q, qd, qdd = read_retimed(tmp_path / "r.csv")
    j = np.diff(np.vstack([np.zeros((1, 7)), np.diff(np.vstack([np.zeros((1, 7)), np.diff(np.vstack([q[:1], q, q[-1:]]), axis=0) / 1e-3]), axis=0) / 1e-3]), axis=0) / 1e-3
    assert np.all(np.abs(j) <= JMAX * (1 + 1e-9))


def test_uniform_slowing_is_the_smallest_stretch(cli, tmp_path):
    """A quintic rest-to-rest move over 0.2 s is too fast; uniform slowing stretches it to
    the speed limit of the moving joint (peak speed 1.875·Δq/T)."""
    robot = panda_file(tmp_path, ["ddq_max", "dddq_max"])
    s = np.linspace(0.0, 1.0, 2001)
    sigma = s**3 * (10 - 15 * s + 6 * s**2)
    q = np.tile([0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0], (len(s), 1))
    q[:, 0] = sigma
    write_path(tmp_path / "p.csv", 0.2 * s, q)
    r = json.loads(
        cli("retime", tmp_path / "p.csv", "--robot", robot, "--mode", "uniform", "--out", tmp_path / "r.csv", "--json").stdout
    )
    assert r["ok"] and r["peak_usage_before"]["velocity"] > 100
    assert r["duration_s"] == pytest.approx(1.875 / 2.175, rel=0.005)
    assert r["factor"] == pytest.approx(r["duration_s"] / 0.2, rel=1e-3)
    assert 99.0 < r["peak_usage_after"]["velocity"] <= 100.0


def test_bad_input_is_named_and_nothing_is_written(cli, tmp_path):
    out = tmp_path / "r.csv"
    (tmp_path / "few.csv").write_text("t,q1,q2\n0,0,0\n1,1,1\n")
    p = cli("retime", tmp_path / "few.csv", "--robot", "panda", "--out", out, check=False)
    assert p.returncode == 2 and "7-joint robot" in p.stderr and not out.exists()
    t, q = smooth_path(20, 1)
    t[5] = t[4]
    write_path(tmp_path / "back.csv", t, q)
    p = cli("retime", tmp_path / "back.csv", "--robot", "panda", "--out", out, check=False)
    assert p.returncode == 2 and "back.csv" in p.stderr and "line" in p.stderr and not out.exists()
    # Held at a pose where gravity needs more than joint 2's torque limit: infeasible.
    robot = panda_file(tmp_path, ["ddq_max", "tau_max", "mass", "com", "inertia"])
    text = robot.read_text().replace("tau_max = 87.0", "tau_max = 5.0", 2)
    robot.write_text(text)
    q = np.tile([0.0, 0.8, 0.0, -1.5, 0.0, 1.5, 0.0], (10, 1))
    q[:, 0] = np.linspace(0, 0.5, 10)
    write_path(tmp_path / "weak.csv", np.linspace(0, 1, 10), q)
    p = cli("retime", tmp_path / "weak.csv", "--robot", robot, "--out", out, check=False)
    assert p.returncode == 2 and not out.exists()
    assert "joint 2 needs" in p.stderr and "against gravity" in p.stderr and "t = 0.000 s" in p.stderr


def test_the_built_in_panda_s_cartesian_limits_hold_by_pinocchio(cli, tmp_path):
    """The full Panda (joint, torque and Cartesian limits): the retimed tool, through
    pinocchio's forward kinematics of the exported /robot_description, moves no faster than
    1.7 m/s and turns no faster than 2.5 rad/s between any two commands."""
    pin = pytest.importorskip("pinocchio")
    mcap_reader = pytest.importorskip("mcap_ros2.reader")
    t, q = smooth_path(300, 2)
    write_path(tmp_path / "p.csv", t, q)
    r = json.loads(cli("retime", tmp_path / "p.csv", "--robot", "panda", "--out", tmp_path / "r.csv", "--json").stdout)
    assert r["ok"] and r["peak_usage_before"]["rotation_velocity"] > 100
    assert 90 < max(r["peak_usage_after"]["translation_velocity"], r["peak_usage_after"]["rotation_velocity"]) <= 100
    cli("export", tmp_path / "r.csv", "--robot", "panda", "--format", "mcap", "--out", tmp_path / "r.mcap")
    (urdf,) = [m.ros_msg.data for m in mcap_reader.read_ros2_messages(str(tmp_path / "r.mcap")) if m.channel.topic == "/robot_description"]
    model = pin.buildModelFromXML(urdf)
    data = model.createData()
    tool = model.getFrameId("panda_tool")
    _, qr, _, _ = read_retimed(tmp_path / "r.csv")
    poses = []
    for row in qr:
        pin.framesForwardKinematics(model, data, row)
        poses.append(data.oMf[tool].copy())
    speed = [np.linalg.norm(b.translation - a.translation) / 1e-3 for a, b in zip(poses, poses[1:])]
    turn = [np.linalg.norm(pin.log3(b.rotation @ a.rotation.T)) / 1e-3 for a, b in zip(poses, poses[1:])]
    assert max(speed) <= 1.7 * (1 + 1e-9) and max(speed) > 1.0
    assert max(turn) <= 2.5 * (1 + 1e-9)


def test_every_panda_limit_is_within_5_percent_of_toppra_under_the_limits_it_can_hold(cli, tmp_path):
    """The full Panda (jerk, torque rate and every Cartesian limit held) against toppra's
    time-optimal law under the joint velocity, acceleration and torque limits (pinocchio's
    RNEA on an independently written model) and the tool's Cartesian speed and
    acceleration limits at the Hand's TCP (pinocchio's frame kinematics; an outer
    polyhedron, so toppra's duration is a lower bound): no faster than that bound, and
    within 5 % of it."""
    pin = pytest.importorskip("pinocchio")
    import sys

    sys.path.insert(0, str(ROOT / "python" / "benchmarks"))
    import robot_ready

    model, data = robot_ready.panda_pinocchio(pin)
    tau = np.array([87.0] * 4 + [12.0] * 3)
    t, q = robot_ready.path()
    write_path(tmp_path / "p.csv", t, q)
    r = json.loads(cli("retime", tmp_path / "p.csv", "--robot", "panda", "--out", tmp_path / "r.csv", "--json").stdout)
    assert r["ok"] and r["peak_usage_after"]["rotation_velocity"] > 99
    path = toppra.SplineInterpolator(chord_knots(q), q, bc_type="natural")
    constraints = [
        ta_constraint.JointVelocityConstraint(np.stack([-VMAX, VMAX], 1)),
        ta_constraint.JointAccelerationConstraint(np.stack([-AMAX, AMAX], 1)),
        ta_constraint.JointTorqueConstraint(lambda x, xd, xdd: pin.rnea(model, data, x, xd, xdd),
                                            np.stack([-tau, tau], 1), np.zeros(7),
                                            discretization_scheme=ta_constraint.DiscretizationType.Interpolation),
        robot_ready.toppra_cartesian(pin, ta_constraint),
    ]
    algo = ta_algorithm.TOPPRA(constraints, path, gridpoints=np.linspace(0.0, path.duration, 1001),
                               parametrizer="ParametrizeConstAccel")
    bound = algo.compute_trajectory().duration
    assert bound * 0.999 <= r["duration_s"] <= bound * 1.05, (r["duration_s"], bound)


def test_python_retime_and_export_match_the_command_line(cli, tmp_path):
    import cps

    robot = cps.Robot("panda")
    t, q = smooth_path(200, 3)
    write_path(tmp_path / "p.csv", t, q)
    from_cli = json.loads(cli("retime", tmp_path / "p.csv", "--robot", "panda", "--out", tmp_path / "r.csv", "--json").stdout)
    r = robot.retime(t, q)
    assert r["duration_s"] == pytest.approx(from_cli["duration_s"], rel=1e-12)
    assert r["peak_usage_after"] == pytest.approx(from_cli["peak_usage_after"], rel=1e-9)
    tr, qr, qd, qdd = read_retimed(tmp_path / "r.csv")
    assert r["q"].shape == (len(tr), 7) and r["qd"].shape == r["qdd"].shape == r["q"].shape
    np.testing.assert_allclose(r["t"], tr, atol=1e-12)
    np.testing.assert_allclose(r["q"], qr, atol=1e-12)
    np.testing.assert_allclose(r["qd"], qd, atol=1e-12)
    u = robot.retime(t, q, mode="uniform")
    assert u["mode"] == "uniform" and u["duration_s"] >= r["duration_s"]
    out = tmp_path / "r.mcap"
    info = robot.export(r["t"], r["q"], out, format="mcap")
    assert out.read_bytes()[:8] == b"\x89MCAP0\r\n" and info["points"] == len(np.arange(0, r["t"][-1] - 1e-9, 0.01)) + 1
    with pytest.raises(ValueError, match="force=True"):
        robot.export(r["t"], r["q"], out, format="mcap")
    with pytest.raises(ValueError, match='format: "bag" is not one of'):
        robot.export(r["t"], r["q"], tmp_path / "x", format="bag")
    with pytest.raises(ValueError, match="mode"):
        robot.retime(t, q, mode="quick")
    with pytest.raises(ValueError, match="t: time stamps must increase"):
        robot.retime(np.zeros(200), q)
