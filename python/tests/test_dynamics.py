"""Inverse dynamics and limit checks from Python: the Panda's torques against pinocchio's
RNEA (installed in the test venv) on random states, and check_limits equal to
`cps-cli limits check` on the same trajectory."""

import importlib.util
import json
import os

import numpy as np
import pytest

import cps
from conftest import ROOT

GENERATOR = ROOT / "crates" / "cps-kinematics" / "tests" / "data" / "make_panda_rnea.py"


def pinocchio_model():
    try:
        import pinocchio
    except ImportError:
        if os.environ.get("CI"):
            pytest.fail("pinocchio (PyPI: pin) is not installed in the test environment")
        pytest.skip("pinocchio is not installed")
    # The URDF written from Franka's published MDH table and Gaz et al.'s tables, by the
    # script that made the Rust test's reference data.
    spec = importlib.util.spec_from_file_location("make_panda_rnea", GENERATOR)
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    model = pinocchio.buildModelFromXML(gen.urdf())
    return pinocchio, model, model.createData()


def test_panda_torques_match_pinocchio_on_random_states():
    pin, model, data = pinocchio_model()
    panda = cps.Robot("panda")
    lo, hi = panda.limits
    rng = np.random.default_rng(11)
    q = rng.uniform(lo, hi, size=(200, 7))
    qd = rng.uniform(-2.175, 2.175, size=(200, 7))
    qdd = rng.uniform(-15.0, 15.0, size=(200, 7))
    tau = panda.inverse_dynamics(q, qd, qdd)
    assert tau.shape == (200, 7)
    reference = np.array([pin.rnea(model, data, *state) for state in zip(q, qd, qdd)])
    assert np.abs(tau - reference).max() < 1e-9
    # One state at a time, and gravity alone.
    np.testing.assert_array_equal(panda.inverse_dynamics(q[0], qd[0], qdd[0]), tau[0])
    g = panda.inverse_dynamics(q[1], np.zeros(7), np.zeros(7))
    np.testing.assert_allclose(g, pin.computeGeneralizedGravity(model, data, q[1]), atol=1e-9)
    zero_g = panda.inverse_dynamics(q[1], np.zeros(7), np.zeros(7), gravity=[0, 0, 0])
    assert np.abs(zero_g).max() == 0.0


def test_panda_forward_dynamics_matches_pinocchio_s_aba_and_inverts_newton_euler():
    pin, model, data = pinocchio_model()
    panda = cps.Robot("panda")
    lo, hi = panda.limits
    rng = np.random.default_rng(12)
    q = rng.uniform(lo, hi, size=(300, 7))
    qd = rng.uniform(-2.175, 2.175, size=(300, 7))
    tau = rng.uniform(-40.0, 40.0, size=(300, 7))
    armature = np.array([0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074])
    model.armature = armature
    mine = panda.forward_dynamics(q, qd, tau, armature=armature)
    assert mine.shape == (300, 7)
    reference = np.array([pin.aba(model, data, *state) for state in zip(q, qd, tau)])
    assert np.abs(mine - reference).max() < 1e-9
    # Without armature it inverts inverse_dynamics.
    qdd = panda.forward_dynamics(q, qd, tau)
    np.testing.assert_allclose(panda.inverse_dynamics(q, qd, qdd), tau, atol=1e-9)
    np.testing.assert_array_equal(panda.forward_dynamics(q[0], qd[0], tau[0]), qdd[0])
    with pytest.raises(ValueError, match="armature"):
        panda.forward_dynamics(q[0], qd[0], tau[0], armature=[0.1] * 6)
    with pytest.raises(ValueError, match="tau: expected the shape of q"):
        panda.forward_dynamics(q, qd, tau[:3])


def test_check_limits_equals_the_command_line(tmp_path, cli):
    panda = cps.Robot("panda")
    t = np.linspace(0.0, 1.0, 101)
    x = t * t * (3 - 2 * t)
    q = np.tile(panda.ready, (101, 1))
    q[:, 0] = 2.5 * x  # 3.75 rad/s at mid-way: beyond joint 1's 2.175
    mine = panda.check_limits(t, q)
    path = tmp_path / "fast.csv"
    np.savetxt(path, np.column_stack([t, q]), delimiter=",", comments="", fmt="%.17g",
               header="t,q1,q2,q3,q4,q5,q6,q7")
    out = cli("limits", "check", path, "--robot", "panda", "--json", check=False)
    assert out.returncode == 1
    assert mine == json.loads(out.stdout)
    assert mine["ok"] is False
    assert any(v["quantity"] == "velocity" and v["joint"] == 1 for v in mine["violations"])


def test_robots_without_data_say_what_they_lack():
    puma = cps.Robot("puma560")
    with pytest.raises(ValueError, match="link inertias are not known"):
        puma.inverse_dynamics(np.zeros(6), np.zeros(6), np.zeros(6))
    report = puma.check_limits([0.0, 0.5, 1.0], np.zeros((3, 6)))
    assert report["ok"] is True
    assert report["not_checked"]["torque"] == "the robot has no torque limits"
    # The UR3 has Universal Robots' point masses and torque limits, but no acceleration
    # limits: torques are checked, accelerations named as not checked.
    ur3 = cps.Robot("ur3")
    report = ur3.check_limits([0.0, 0.5, 1.0], np.zeros((3, 6)))
    assert "torque" in report["peak_usage"] and "acceleration" in report["not_checked"]
    panda = cps.Robot("panda")
    with pytest.raises(ValueError, match="qd: expected the shape of q"):
        panda.inverse_dynamics(np.zeros(7), np.zeros(6), np.zeros(7))
    with pytest.raises(ValueError, match="time stamps must increase"):
        panda.check_limits([0.0, 0.0, 1.0], np.zeros((3, 7)))


def test_the_panda_robot_file_carries_the_same_limits_and_inertias():
    built_in = cps.Robot("panda")
    from_file = cps.Robot(str(ROOT / "configs" / "robots" / "panda.toml"))
    rng = np.random.default_rng(5)
    q, qd, qdd = (rng.uniform(-1, 1, size=(20, 7)) for _ in range(3))
    q[:, 3] = -1.5  # joint 4 inside its range
    np.testing.assert_allclose(from_file.inverse_dynamics(q, qd, qdd),
                               built_in.inverse_dynamics(q, qd, qdd), rtol=0, atol=1e-12)
    t = np.linspace(0.0, 2.0, 201)
    path = np.tile(built_in.ready, (201, 1))
    path[:, 1] += 0.3 * np.sin(np.pi * t / 2) ** 2
    a, b = built_in.check_limits(t, path), from_file.check_limits(t, path)
    assert a["ok"] == b["ok"] and a["peak_usage"].keys() == b["peak_usage"].keys()
    for k in a["peak_usage"]:
        np.testing.assert_allclose(a["peak_usage"][k], b["peak_usage"][k], rtol=1e-12, atol=1e-9)


def test_the_crx10ia_agrees_with_pinocchio_on_fanuc_s_urdf():
    """pinocchio reads configs/robots/crx10ia.urdf itself; cps's built-in CRX-10iA gives
    the same tool pose and torques over random states."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(ROOT / "configs/robots/crx10ia.urdf"))
    data = model.createData()
    crx = cps.Robot("crx10ia")
    rng = np.random.default_rng(5)
    lo, hi = crx.limits
    for _ in range(100):
        q = rng.uniform(lo, hi)
        qd, qdd = rng.uniform(-2, 2, 6), rng.uniform(-5, 5, 6)
        np.testing.assert_allclose(crx.inverse_dynamics(q, qd, qdd), pin.rnea(model, data, q, qd, qdd), atol=1e-9)
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(crx.fk(q)[:3, 3], data.oMf[model.getFrameId("flange")].translation, atol=1e-12)


def test_identify_recovers_a_controller_simulated_in_numpy(tmp_path):
    """A robot of franky-sim's kind (PD with gravity and Coriolis compensation, rotor
    inertia, viscous friction) integrated here step by step with cps's forward dynamics,
    recorded as a Franka reports it; cps.identify recovers its gains and predicts the
    quarter of the recording it held back. (Wrist gains below franky-sim's, which explicit
    Euler at 1 ms keeps stable only by clipping the torques.)"""
    fr3 = cps.Robot("fr3", tool="hand")
    kp = np.array([4500.0, 4500.0, 3500.0, 3500.0, 1000.0, 800.0, 400.0])
    kv = np.array([450.0, 450.0, 350.0, 350.0, 80.0, 60.0, 30.0])
    armature = np.array([0.195] * 4 + [0.074] * 3)
    viscous = 0.21
    h = 0.001
    center = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.785])
    q, dq, tau = center.copy(), np.zeros(7), np.zeros(7)
    zero = np.zeros(7)
    rows = []
    steps = 3000
    for k in range(steps):
        t = k * h
        fade = min(1.0, t / 0.3) * min(1.0, (steps * h - t) / 0.3)
        phase = 2 * np.pi * (0.3 * t + 0.35 * t * t) + 0.9 * np.arange(7)
        q_c = center + 0.05 * fade * np.sin(phase)
        rows.append([t, *q, *dq, *tau, *q_c])
        gravity = fr3.inverse_dynamics(q, zero, zero)
        coriolis = fr3.inverse_dynamics(q, dq, zero, gravity=[0.0, 0.0, 0.0])
        tau = kp * (q_c - q) - kv * dq + coriolis + gravity
        ddq = fr3.forward_dynamics(q, dq, tau - viscous * dq, armature=armature)
        dq = dq + h * ddq
        q = q + h * dq
    names = ["t"] + [f"{p}{j}" for p in ("q", "dq", "tau", "q_d") for j in range(1, 8)]
    recording = tmp_path / "rec.csv"
    np.savetxt(recording, np.array(rows), delimiter=",", header=",".join(names), comments="", fmt="%.12g")
    out = tmp_path / "robot.toml"
    found = cps.identify(recording, out=out)
    c = found["calibration"]
    np.testing.assert_allclose(c["kp"], kp, rtol=1e-3)
    np.testing.assert_allclose(c["kv"], kv, rtol=1e-3)
    np.testing.assert_allclose(c["armature"], armature, atol=0.01)
    np.testing.assert_allclose(c["viscous"], viscous, atol=0.05)
    assert c["lag_ms"] == 0 and c["robot"] == "fr3"
    assert max(found["fit"]["held_back_rms_mrad"]) < 0.01
    assert out.read_text().startswith("# A robot's calibration, identified by cps")
    # An existing calibration is replaced only when asked; a recording of another kind is
    # named.
    with pytest.raises(ValueError, match="already exists"):
        cps.identify(recording, out=out)
    cps.identify(recording, out=out, force=True)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,q1\n0,0\n")
    with pytest.raises(ValueError, match="bad.csv"):
        cps.identify(bad, out=tmp_path / "other.toml")
