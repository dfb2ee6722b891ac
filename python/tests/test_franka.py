"""cps.Franka against franky-sim (a MuJoCo FR3 behind the Franka Control Interface).

The simulator runs in its own virtual environment ($CPS_FRANKA_PYTHON, or the repository's
target/franka-venv, which .ci/run creates); in CI a missing one is a failure, elsewhere
the tests skip. Each test has its own loopback address.
"""

import os
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest

import cps

ROOT = Path(__file__).resolve().parents[2]


def _sim_python():
    p = os.environ.get("CPS_FRANKA_PYTHON") or str(ROOT / "target/franka-venv/bin/python")
    if Path(p).exists():
        return p
    if os.environ.get("CI"):
        pytest.fail(f"CI must provide franky-sim: {p} does not exist")
    pytest.skip("franky-sim is not installed (see crates/cps-franka/tests/requirements.txt)")


def _start(host, *extra):
    p = subprocess.Popen([_sim_python(), str(ROOT / "crates/cps-franka/tests/sim_server.py"), "--host", host, *extra],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    assert line.startswith("ready"), line
    return p


@pytest.fixture
def sim(request):
    p = _start(request.param)
    yield request.param
    p.kill()
    p.wait()


def swing(q0, seconds=3.0, amplitude=0.5, dt=0.01):
    t = np.arange(0.0, seconds + dt / 2, dt)
    s = 0.5 - 0.5 * np.cos(2 * np.pi * t / seconds)
    q = np.tile(q0, (len(t), 1))
    q[:, 0] += amplitude * s
    q[:, 3] += 0.3 * s
    return t, q


@pytest.mark.parametrize("sim", ["127.0.0.51"], indirect=True)
def test_state_execute_and_record(sim):
    robot = cps.Franka(sim, realtime="ignore")
    s = robot.state()
    assert s["robot_mode"] == "idle" and s["errors"] == []
    q0 = np.array(s["q_d"])
    assert q0.shape == (7,)
    t, q = swing(q0)
    out = robot.execute(t, q)
    assert out["complete"] is True
    n = len(out["t"])
    # One row per state answered, on the robot's clock: the rows span every period of the
    # motion; on a loaded machine a state cps skipped as stale leaves a 2 ms row (2 998
    # rows over 3 001 periods in a cold CI).
    periods = int(np.rint((out["t"][-1] - out["t"][0]) / 0.001)) + 1
    assert 3001 <= periods <= 3004 + 50
    assert 0.95 * periods <= n <= periods
    for k in ("q", "dq", "tau", "q_d"):
        assert out[k].shape == (n, 7)
    assert out["tool"].shape == (n, 3)
    # The commanded joint 1 peaks half way at the swing; the measured one follows.
    mid = np.argmax(out["q_d"][:, 0])
    assert abs(out["q_d"][mid, 0] - (q0[0] + 0.5)) < 1e-3
    assert abs(out["q"][mid, 0] - out["q_d"][mid, 0]) < 0.05
    usage = out["report"]["limit_usage_percent"]
    assert max(max(v) for v in usage.values()) <= 100.0
    # The commands, differentiated as the robot does, keep the FR3's published limits
    # (over the rows' own periods: a state lost on a loaded machine makes one of 2 ms).
    dt = np.diff(out["t"])[:, None]
    v = np.diff(out["q_d"], axis=0) / dt
    a = np.diff(v, axis=0) / dt[1:]
    one_ms = ((dt[1:] < 1.5e-3) & (dt[:-1] < 1.5e-3))[:, 0]
    assert np.abs(v).max() < 2.62 and np.abs(a[one_ms]).max() <= 10.0 + 1e-9
    rec = robot.record(0.3)
    assert 250 <= len(rec["t"]) <= 301 and rec["report"]["complete"] is True


@pytest.mark.parametrize("sim", ["127.0.0.52"], indirect=True)
def test_refusals_and_bad_input(sim):
    robot = cps.Franka(sim, realtime="ignore")
    q0 = np.array(robot.state()["q_d"])
    t = np.arange(0.0, 1.0, 0.001)
    q = np.tile(q0, (len(t), 1))
    q[500:, 2] += 0.05  # a step
    with pytest.raises(cps.CpsError, match="joint 3 at t = 0.500 s .*velocity .* beyond the limit"):
        robot.execute(t, q)
    after = np.array(robot.state()["q"])
    assert np.abs(after - q0).max() < 1e-3
    with pytest.raises(ValueError, match="expected 7 columns"):
        robot.execute(t, q[:, :6])
    with pytest.raises(ValueError, match="times must increase strictly"):
        robot.execute(np.zeros(len(t)), q)
    with pytest.raises(ValueError, match="arm"):
        cps.Franka(sim, arm="ur5")
    with pytest.raises(ValueError, match="force"):
        robot.gripper("grasp", 0.01, force=500.0)


@pytest.mark.parametrize("sim", ["127.0.0.53"], indirect=True)
def test_the_gripper(sim):
    robot = cps.Franka(sim, realtime="ignore")
    robot.gripper("home")
    s = robot.gripper("move", 0.03)
    assert abs(s["width"] - 0.03) < 5e-3  # franky-sim stops the fingers a few mm short (see franky_sim.rs)


def test_a_host_without_a_robot_is_named():
    with pytest.raises(cps.CpsError, match="127.0.0.59: cannot reach the robot"):
        cps.Franka("127.0.0.59").state()


def test_a_scene_is_read_when_the_robot_is_made(tmp_path):
    # Franka(scene=) checks every command among the scene's obstacles (the command line's
    # --scene, tested on franky-sim in crates/cps-cli/tests/franka.rs); a scene that is
    # missing, or made for another arm, is named before anything connects.
    with pytest.raises(ValueError, match="missing.toml: cannot read the scene file"):
        cps.Franka("127.0.0.59", scene=str(tmp_path / "missing.toml"))
    panda = tmp_path / "panda.toml"
    panda.write_text('[robot]\nmodel = "panda"\ninitial_q = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]\n')
    with pytest.raises(ValueError, match="the scene's robot is `panda`, not the fr3"):
        cps.Franka("127.0.0.59", scene=str(panda))
    assert "127.0.0.59" in repr(cps.Franka("127.0.0.59", arm="panda", scene=str(panda)))


def test_guiding_records_what_a_hand_does():
    host = "127.0.0.54"
    p = _start(host)
    try:
        robot = cps.Franka(host, realtime="ignore")
        start = np.array(robot.state()["tool_position"])
        # A hand pulls the tool 10 cm along y, 0.4 s after the arm starts floating.
        timer = threading.Timer(0.4, lambda: (p.stdin.write(
            f"lead {start[0]} {start[1] + 0.1} {start[2]} 1.0 400 20\n"), p.stdin.flush()))
        timer.start()
        out = robot.guide(2.0)
        timer.join()
        assert out["report"]["complete"] is True
        n = len(out["t"])
        assert 1900 <= n <= 2002 and out["q"].shape == (n, 7)
        moved = out["tool"][-1] - start
        assert abs(moved[1] - 0.1) < 0.01 and abs(moved[0]) < 0.01 and abs(moved[2]) < 0.01, moved
        with pytest.raises(ValueError, match=r"joint 1 damping .* 50 is out of range"):
            robot.guide(1.0, damping=50.0)
    finally:
        p.kill()
        p.wait()


def test_contact_presses_the_simulated_table_and_impedance_follows_a_line():
    host = "127.0.0.55"
    p = _start(host, "--table", "0.40", "--friction", "0.5")
    try:
        robot = cps.Franka(host, realtime="ignore")
        waypoints = [[0, 0, 0, 0, 0], [1, 0, 0, 0, 10], [3, 0.1, 0, 0, 10], [4, 0.1, 0, 0, 0]]
        out = robot.contact(waypoints, above=[0.45, 0.0, 0.47], drive="franky-sim")
        s = out["summary"]
        assert s["done"] is True, s
        assert abs(s["contact_point_m"][2] - 0.40) < 0.015
        pressing = (np.array(out["stage"]) == "press") & (out["desired"] > 9.9)
        assert pressing.sum() > 1000
        assert abs(out["pressing"][pressing].mean() - 10.0) < 1.0
        assert out["tool"][-1, 2] > 0.43  # lifted off
        with pytest.raises(ValueError, match="ceiling"):
            robot.contact(waypoints, above=[0.45, 0.0, 0.47], ceiling=5.0)
        with pytest.raises(ValueError, match="waypoints"):
            robot.contact([[0, 0, 0, 0, 0]], above=[0.45, 0.0, 0.47])
        # Impedance: 8 cm along y in 2 s from where the tool is, in free space above the table.
        start = np.array(robot.state()["tool_position"])
        t = np.array([0.0, 2.0])
        line = np.array([start, start + [0.0, 0.08, 0.0]])
        f = robot.impedance(t, line, drive="franky-sim")
        assert f["report"]["complete"] is True
        end = f["tool"][-1]
        assert np.linalg.norm(end - line[1]) < 0.01, end
        assert np.abs(f["wrench"][300:, :3]).max() < 8.0  # nothing touched it
        with pytest.raises(ValueError, match="stiffness"):
            robot.impedance(t, line, stiffness=(9000.0, 150.0))
    finally:
        p.kill()
        p.wait()
