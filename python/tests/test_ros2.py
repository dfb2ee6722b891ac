"""cps.ros2 against CycloneDDS (crates/cps-ros2/tests/peer.py): a FollowJointTrajectory
server that plays the goal and publishes the joints, recorded at the same time.

DDS discovers by multicast, so each graph test runs in a network namespace of its own
(only loopback): the test re-runs itself under ``unshare -n``. The peer's interpreter is
$CPS_ROS2_PYTHON or the repository's target/ros2-venv (which .ci/run creates); in CI a
missing one is a failure, elsewhere the tests skip.
"""

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import cps

ROOT = Path(__file__).resolve().parents[2]
PEER = ROOT / "crates/cps-ros2/tests/peer.py"
READY = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]


def _peer_python():
    p = os.environ.get("CPS_ROS2_PYTHON") or str(ROOT / "target/ros2-venv/bin/python")
    if Path(p).exists():
        return p
    if os.environ.get("CI"):
        pytest.fail(f"CI must provide CycloneDDS: {p} does not exist")
    pytest.skip("CycloneDDS is not installed (see crates/cps-ros2/tests/requirements.txt)")


def _inside(test):
    """True inside the test's own network namespace; outside, runs it there and checks it."""
    if os.environ.get("CPS_IN_NETNS"):
        return True
    _peer_python()
    setup = ("ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo"
             ' && exec "$0" "$@"')
    r = subprocess.run(
        ["unshare", "-n", "sh", "-c", setup, sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
         f"{__file__}::{test}"],
        env={**os.environ, "CPS_IN_NETNS": "1"}, capture_output=True, text=True, timeout=300)
    if r.returncode != 0 and "unshare failed" in r.stderr and not os.environ.get("CI"):
        pytest.skip(f"no network namespace for the DDS tests: {r.stderr.strip()}")
    assert r.returncode == 0 and "1 passed" in r.stdout, r.stdout + r.stderr
    return False


def _move(seconds=2.0, amplitude=0.2, n=101):
    t = np.linspace(0.0, seconds, n)
    s = 0.5 - 0.5 * np.cos(np.pi * t / seconds)
    return t, np.array(READY)[None, :] + amplitude * s[:, None]


def test_send_follows_the_goal_while_record_takes_the_joint_states(tmp_path):
    if not _inside("test_send_follows_the_goal_while_record_takes_the_joint_states"):
        return
    seen = tmp_path / "server.json"
    names = ",".join(f"panda_joint{i}" for i in range(1, 8))
    peer = subprocess.Popen(
        [_peer_python(), str(PEER), "serve", "/arm/follow_joint_trajectory", str(seen),
         "--joint-states", "/joint_states", "--rate", "200", "--joints", names,
         "--start", ",".join(map(str, READY))],
        stdout=subprocess.PIPE, text=True)
    try:
        assert peer.stdout.readline().strip() == "ready"
        recorded = {}
        recorder = threading.Thread(target=lambda: recorded.update(cps.ros2.record(3.0, wait=30.0)))
        recorder.start()
        t, q = _move()
        answer = cps.ros2.send(t, q, "/arm", wait=30.0)
        recorder.join(timeout=60)
        peer.wait(timeout=60)
    finally:
        peer.kill()
    assert answer["succeeded"] and answer["status"] == "succeeded", answer
    assert answer["points"] == 201 and answer["joint_names"][0] == "panda_joint1"
    goal = json.loads(seen.read_text())["goals"][0]["trajectory"]
    assert np.allclose(goal["points"][-1]["positions"], q[-1], atol=1e-12)
    assert recorded["report"]["lost"] == 0, recorded["report"]
    assert recorded["q"].shape[1] == 7 and recorded["t"][0] == 0.0
    # The joints rest where the goal ended once it is over.
    assert np.allclose(recorded["q"][-1], q[-1], atol=1e-9)


def test_bad_input_is_refused_before_the_graph():
    t, q = _move()
    with pytest.raises(ValueError, match="via"):
        cps.ros2.send(t, q, "/arm", via="carrier-pigeon")
    with pytest.raises(ValueError, match="rows for"):
        cps.ros2.send(t[:-1], q, "/arm")
    with pytest.raises(ValueError, match="3 name"):
        cps.ros2.send(t, q, "/arm", joint_names=["a", "b", "c"])
    fast_t, fast_q = _move(seconds=0.1, amplitude=1.2)
    with pytest.raises(cps.CpsError, match="refused, nothing was sent"):
        cps.ros2.send(fast_t, fast_q, "/arm", wait=1.0)
    with pytest.raises(ValueError, match="service_mapping"):
        cps.ros2.send(t, q, "/arm", service_mapping="zenoh")
    with pytest.raises(ValueError, match="--seconds 0"):
        cps.ros2.graph(seconds=0.0)


def _post_scene(tmp_path, model, at):
    """A scene of `model` at the Panda's ready pose with a 4 cm post centred at `at`."""
    path = tmp_path / f"{model}.toml"
    path.write_text(
        f'[robot]\nmodel = "{model}"\ntool = "hand"\ninitial_q = {list(READY)}\n\n'
        f'[[obstacle]]\nname = "post"\nshape = "box"\nxyz = {list(map(float, at))}\nsize = [0.04, 0.04, 0.3]\n')
    return path


def test_a_scene_s_obstacle_in_the_way_is_refused_before_the_graph(tmp_path):
    # A post where the hand ends (cps's forward kinematics places it): the move is refused
    # naming the hand and the post, before anything joins the graph (no namespace needed).
    t, q = _move()
    end = cps.Robot("panda", tool="hand").fk(q[-1])[:3, 3]
    with pytest.raises(cps.CpsError, match=r"`panda_hand` and `post` at t = .* within the clearance margin"):
        cps.ros2.send(t, q, "/arm", wait=1.0, scene=str(_post_scene(tmp_path, "panda", end)))
    with pytest.raises(ValueError, match="the scene's robot is `fr3`, not the panda"):
        cps.ros2.send(t, q, "/arm", wait=1.0, scene=str(_post_scene(tmp_path, "fr3", end)))
    # The post a metre higher: the same move is clear of it (cps.collide, the guard's check).
    far = _post_scene(tmp_path, "panda", end + np.array([0.0, 0.0, 1.0]))
    assert cps.collide(t, q, scene=str(far))["ok"]


def test_graph_shows_the_cyclone_server_and_its_middleware(tmp_path):
    if not _inside("test_graph_shows_the_cyclone_server_and_its_middleware"):
        return
    peer = subprocess.Popen(
        [_peer_python(), str(PEER), "serve", "/arm/follow_joint_trajectory",
         str(tmp_path / "server.json"), "--linger", "30"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert peer.stdout.readline().strip() == "ready"
        g = cps.ros2.graph(seconds=1.5)
    finally:
        peer.kill()
    assert [p["middleware"] for p in g["participants"]] == ["CycloneDDS"], g["participants"]
    action = g["actions"]["/arm/follow_joint_trajectory"]
    assert action["types"] == ["control_msgs/action/FollowJointTrajectory"]
    assert [s["middleware"] for s in action["servers"]] == ["CycloneDDS"]
    assert g["nodes"] == []
