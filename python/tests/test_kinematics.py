"""Kinematics: forward kinematics and Jacobians against roboticstoolbox/pinocchio values
(../shared/data/panda_reference.json, when the shared folder is beside the repository) and a
numpy modified-DH transcription, IK round trips single and batched, limits, bad input."""

import json

import numpy as np
import pytest

import cps
from conftest import ROOT

REFERENCE = ROOT.parent / "shared" / "data" / "panda_reference.json"
PANDA = [  # (a, d, alpha) of Craig's modified DH, Franka's published table
    (0.0, 0.333, 0.0), (0.0, 0.0, -np.pi / 2), (0.0, 0.316, np.pi / 2), (0.0825, 0.0, np.pi / 2),
    (-0.0825, 0.384, -np.pi / 2), (0.0, 0.0, np.pi / 2), (0.088, 0.0, np.pi / 2)]


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def trans(x=0.0, z=0.0):
    t = np.eye(4)
    t[0, 3], t[2, 3] = x, z
    return t


def panda_fk(q, hand=True):
    """T_i = RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(q_i) TransZ(d_i), then the flange and
    the Franka Hand's TCP (RotZ(-pi/4) TransZ(0.1034))."""
    t = np.eye(4)
    for (a, d, alpha), qi in zip(PANDA, q):
        t = t @ rot_x(alpha) @ trans(x=a) @ rot_z(qi) @ trans(z=d)
    t = t @ trans(z=0.107)
    return t @ rot_z(-np.pi / 4) @ trans(z=0.1034) if hand else t


def random_q(robot, n, seed):
    lo, hi = robot.limits
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, robot.dof))


def test_fk_matches_a_numpy_transcription_of_the_dh_table():
    hand, flange = cps.Robot("panda", tool="hand"), cps.Robot("panda", tool="flange")
    Q = random_q(hand, 50, 1)
    T = hand.fk(Q)
    assert T.shape == (50, 4, 4)
    for q, t in zip(Q, T):
        np.testing.assert_allclose(t, panda_fk(q), rtol=0, atol=1e-12)
        np.testing.assert_allclose(flange.fk(q), panda_fk(q, hand=False), rtol=0, atol=1e-12)


@pytest.mark.skipif(not REFERENCE.is_file(), reason="../shared/data/panda_reference.json not beside the repository")
def test_fk_and_jacobian_match_roboticstoolbox_and_pinocchio():
    ref = json.loads(REFERENCE.read_text())
    robots = {"flange": cps.Robot("panda", tool="flange"), "hand_tcp": cps.Robot("panda", tool="hand")}
    for config in ref["configs"]:
        for frame, robot in robots.items():
            np.testing.assert_allclose(robot.fk(config["q"]), config[frame]["T"], rtol=0, atol=1e-9)
            np.testing.assert_allclose(robot.jacobian(config["q"]), config[frame]["J"], rtol=0, atol=1e-9)
        assert robots["flange"].within_limits(config["q"]) == config["within_limits"]
    puma = cps.Robot("puma560")
    for config in ref["puma560_standard_dh"]["configs"]:
        np.testing.assert_allclose(puma.fk(config["q"]), config["T"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(puma.jacobian(config["q"]), config["J"], rtol=0, atol=1e-9)
    lo, hi = robots["flange"].limits
    np.testing.assert_array_equal(lo, ref["meta"]["q_min"])
    np.testing.assert_array_equal(hi, ref["meta"]["q_max"])
    np.testing.assert_array_equal(robots["flange"].velocity_limits, ref["meta"]["dq_max"])


def test_jacobian_is_the_derivative_of_fk():
    robot = cps.Robot("ur3")
    q = random_q(robot, 1, 5)[0]
    J = robot.jacobian(q)
    h = 1e-6
    for j in range(robot.dof):
        dq = np.zeros(robot.dof)
        dq[j] = h
        tp, tm = robot.fk(q + dq), robot.fk(q - dq)
        np.testing.assert_allclose(J[:3, j], (tp[:3, 3] - tm[:3, 3]) / (2 * h), atol=1e-8)
        dr = (tp[:3, :3] - tm[:3, :3]) / (2 * h) @ robot.fk(q)[:3, :3].T  # = [w]x
        np.testing.assert_allclose(J[3:, j], [dr[2, 1], dr[0, 2], dr[1, 0]], atol=1e-8)


def test_ik_round_trips_single_and_batched():
    robot = cps.Robot("panda")
    Q = random_q(robot, 20, 9)
    T = robot.fk(Q)
    # Full poses as 4x4 matrices, batched.
    q = robot.ik(T)
    assert q.shape == (20, 7)
    np.testing.assert_allclose(robot.fk(q), T, rtol=0, atol=1e-8)
    assert robot.within_limits(q).all()
    # Positions and [x, y, z, qx, qy, qz, qw] poses, one at a time.
    p = T[0, :3, 3]
    np.testing.assert_allclose(robot.fk(robot.ik(p))[:3, 3], p, atol=1e-8)
    from_matrix = robot.ik(T[0])
    assert from_matrix.shape == (7,)
    np.testing.assert_allclose(robot.fk(from_matrix), T[0], atol=1e-8)


def test_robot_files_load_like_the_built_in():
    built_in = cps.Robot("panda", tool="flange")
    toml = cps.Robot(str(ROOT / "configs" / "robots" / "panda.toml"), tool="flange")
    urdf = cps.Robot(str(ROOT / "configs" / "robots" / "panda.urdf"), tip="panda_link8")
    q = random_q(built_in, 5, 2)
    assert toml.dof == urdf.dof == 7
    np.testing.assert_allclose(urdf.fk(q), built_in.fk(q), atol=1e-12)
    np.testing.assert_allclose(toml.fk(q), built_in.fk(q), atol=1e-12)
    hand = cps.Robot(str(ROOT / "configs" / "robots" / "panda.urdf"), tip="panda_hand_tcp")
    np.testing.assert_allclose(hand.fk(q), cps.Robot("panda", tool="hand").fk(q), atol=1e-12)
    assert "panda" in toml.describe().lower()


def test_bad_input():
    robot = cps.Robot("panda")
    with pytest.raises(ValueError, match="q: expected 7 joint values"):
        robot.fk([0.0] * 6)
    with pytest.raises(ValueError, match=r"q\[0, 2\] is NaN"):
        robot.fk([[0.0, 0.0, np.nan, -1.0, 0.0, 1.0, 0.0]])
    with pytest.raises(ValueError, match="target: expected a position"):
        robot.ik([1.0, 2.0])
    with pytest.raises(ValueError, match="quaternion has zero length"):
        robot.ik([0.3, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(cps.CpsError, match=r"target\[1\]"):
        robot.ik([[0.3, 0.0, 0.5], [5.0, 0.0, 0.0]])  # 5 m away: out of reach
    with pytest.raises(ValueError, match="q0"):
        robot.ik([0.3, 0.0, 0.5], q0=[0.0] * 7)  # joint 4 outside its limits
    with pytest.raises(ValueError, match="robot"):
        cps.Robot("no_such_robot.toml")


def test_the_tool_pose_as_position_and_quaternion_agrees_with_pytransform3d():
    from pytransform3d.rotations import quaternion_from_matrix

    robot = cps.Robot("fr3")
    rng = np.random.default_rng(3)
    lower, upper = robot.limits
    # The ready pose (the hand straight down: a half turn, qw = 0) and random ones.
    qs = np.vstack([robot.ready, rng.uniform(lower, upper, size=(20, 7))])
    poses = robot.pose(qs)
    assert poses.shape == (21, 7)
    for q, pose in zip(qs, poses):
        m = robot.fk(q)
        np.testing.assert_allclose(pose[:3], m[:3, 3], atol=1e-12)
        wxyz = quaternion_from_matrix(m[:3, :3])
        xyzw = np.r_[wxyz[1:], wxyz[0]]
        # The same rotation (a quaternion and its negative are one), with qw >= 0.
        assert min(np.abs(pose[3:] - xyzw).max(), np.abs(pose[3:] + xyzw).max()) < 1e-9
        assert pose[6] >= 0.0 and abs(np.linalg.norm(pose[3:]) - 1.0) < 1e-12
    np.testing.assert_array_equal(robot.pose(qs[1]), poses[1])
