"""Collision checking from Python: the robot's distances to itself and its scene, a
trajectory checked as the guard checks it (equal to ``cps-cli collide --json``), and the
invariant a sphere gives: growing a ball by δ brings every shape exactly δ closer."""

import json

import numpy as np
import pytest

import cps

from conftest import ROOT

FR3_SCENE = (ROOT / "configs" / "scenes" / "fr3.toml").read_text()


def scene_with_ball(tmp_path, name, radius, at):
    path = tmp_path / name
    path.write_text(
        FR3_SCENE
        + f'\n[[obstacle]]\nname = "ball"\nshape = "sphere"\nxyz = [{at[0]}, {at[1]}, {at[2]}]\nradius = {radius}\n'
    )
    return path


def test_distances_name_franka_links_and_a_grown_ball_comes_exactly_closer(tmp_path):
    fr3 = cps.Robot("fr3")
    assert fr3.margin == 0.005
    pairs = fr3.distances(fr3.ready, within=0.5)
    assert pairs, "the arm's links are within 0.5 m of each other at rest"
    assert all(a.startswith("fr3_") and b.startswith("fr3_") for a, b, _ in pairs)
    d = [p[2] for p in pairs]
    assert d == sorted(d) and d[0] > 0.005, "at rest every pair keeps the margin"
    assert len({(a, b) for a, b, _ in pairs}) == len(pairs), "each pair once"
    # A ball 12 cm beside the tool at the scene's start, then grown by 3 cm.
    plain = tmp_path / "plain.toml"
    plain.write_text(FR3_SCENE)
    start = np.array(
        [0.0, 0.0, 0.0, -0.3, 0.0, 1.8707963267948966, 0.7853981633974483]
    )
    tool = cps.Robot(scene=plain).fk(start)[:3, 3]
    at = tool + np.array([0.0, 0.25, 0.0])
    small = cps.Robot(scene=scene_with_ball(tmp_path, "small.toml", 0.05, at))
    large = cps.Robot(scene=scene_with_ball(tmp_path, "large.toml", 0.08, at))
    near_small = {(a, b): x for a, b, x in small.distances(start, within=1.0) if b == "ball"}
    near_large = {(a, b): x for a, b, x in large.distances(start, within=1.0) if b == "ball"}
    # Every pair within 1 m of the small ball is within 1 m of the large one.
    assert len(near_small) >= 5 and near_small.keys() <= near_large.keys()
    for k, x in near_small.items():
        assert x > 0.03
        assert abs((x - near_large[k]) - 0.03) < 1e-7, (k, x, near_large[k])


def test_a_trajectory_is_checked_as_the_command_line_checks_it(tmp_path, cli):
    plain = tmp_path / "plain.toml"
    plain.write_text(FR3_SCENE)
    start = np.array([0.0, 0.0, 0.0, -0.3, 0.0, 1.8707963267948966, 0.7853981633974483])
    robot = cps.Robot(scene=plain)
    # Joint 1 swings 1.2 rad; a ball sits where the tool is at 0.8 rad.
    turned = start.copy()
    turned[0] += 0.8
    ball = scene_with_ball(tmp_path, "ball.toml", 0.05, robot.fk(turned)[:3, 3])
    t = np.linspace(0.0, 3.0, 301)
    q = np.tile(start, (301, 1))
    q[:, 0] += 1.2 * (0.5 - 0.5 * np.cos(np.pi * t / 3.0))
    mine = cps.Robot(scene=ball).collide(t, q)
    path = tmp_path / "swing.csv"
    np.savetxt(path, np.column_stack([t, q]), delimiter=",", comments="", fmt="%.17g",
               header="t,q1,q2,q3,q4,q5,q6,q7")
    out = cli("collide", path, "--scene", ball, "--json", check=False)
    assert out.returncode == 1
    assert mine == json.loads(out.stdout)
    assert mine["ok"] is False and mine["collision"]["second"] == "ball"
    assert mine["collision"]["time"] < 1.77
    assert cps.collide(t, q, scene=ball) == mine
    # A margin the user sets: none at all still finds the ball, the swing stopped short
    # does not.
    assert cps.collide(t, q, scene=ball, margin=0.0)["ok"] is False
    assert cps.collide(t[:60], q[:60], scene=ball)["ok"] is True


def test_robots_without_shapes_and_bad_arguments_say_so(tmp_path):
    ur3 = cps.Robot("ur3")
    assert ur3.margin is None
    with pytest.raises(ValueError, match="has no collision geometry"):
        ur3.distances(np.zeros(6))
    with pytest.raises(ValueError, match="margin: the clearance margin must be a finite distance"):
        cps.Robot("fr3", margin=-0.01)
    plain = tmp_path / "plain.toml"
    plain.write_text(FR3_SCENE)
    with pytest.raises(ValueError, match="give either scene or robot"):
        cps.Robot("fr3", scene=plain)
    with pytest.raises(ValueError, match="q: expected"):
        cps.Robot("fr3").distances(np.zeros(6))


def ball_in_the_swing(tmp_path):
    """The FR3's scene (`plain`), and the same with a 5 cm ball (`ball`) where the hand is
    when joint 1 has turned 0.8 rad from `start` (`turned`): the straight swing from
    `start` to `goal`, 1.6 rad on, meets it."""
    plain = tmp_path / "plain.toml"
    plain.write_text(FR3_SCENE)
    start = np.array([0.0, 0.0, 0.0, -0.3, 0.0, 1.8707963267948966, 0.7853981633974483])
    turned = start.copy()
    turned[0] += 0.8
    ball = scene_with_ball(tmp_path, "ball.toml", 0.05, cps.Robot(scene=plain).fk(turned)[:3, 3])
    goal = start.copy()
    goal[0] += 1.6
    return plain, ball, start, turned, goal


def test_a_path_around_the_ball_is_what_the_command_line_plans(tmp_path, cli):
    """cps.plan goes around a ball the swing of joint 1 meets, as `cps-cli plan --json`
    does (the same seed, the same waypoints), and its timed motion passes cps.collide;
    a bad end is a ValueError naming it, no path within the samples a cps.CpsError."""
    plain, ball, start, turned, goal = ball_in_the_swing(tmp_path)
    straight = np.linspace(start, goal, 50)
    assert cps.collide(np.linspace(0, 3, 50), straight, scene=ball)["ok"] is False
    way = cps.plan(start, goal, scene=ball, seed=3)
    assert len(way["waypoints"]) >= 3
    assert np.allclose(way["q"][0], start, atol=0) and np.allclose(way["q"][-1], goal, atol=0)
    assert way["q"].shape == (len(way["t"]), 7)
    assert way["clearance_m"] >= 0.005
    assert cps.collide(way["t"], way["q"], scene=ball)["ok"] is True
    out = cli("plan", "--scene", ball, "--from", ",".join(repr(float(x)) for x in start),
              "--to", ",".join(repr(float(x)) for x in goal), "--seed", "3", "--json")
    assert json.loads(out.stdout)["waypoints"] == way["waypoints"]
    inside = turned.copy()
    with pytest.raises(ValueError, match="goal: the goal is in collision: `fr3_.*` and `ball`"):
        cps.plan(start, inside, scene=ball)
    with pytest.raises(ValueError, match="start: the start's joint 4 = 0.5000 rad is outside"):
        cps.plan(np.r_[start[:3], 0.5, start[4:]], goal, scene=ball)
    with pytest.raises(cps.CpsError, match="no collision-free path found within 1 random"):
        cps.plan(start, goal, scene=ball, samples=1)


def test_a_path_to_a_pose_ends_with_the_tool_there_as_the_command_line_plans(tmp_path, cli):
    """cps.plan(goal_pose=...) ends where the tool is at the pose (the robot's own forward
    kinematics agree to a micrometre), clear of the ball, with `cps-cli plan --to-pose`'s
    waypoints; a pose out of reach or two goals at once are ValueErrors naming the
    argument."""
    plain, ball, start, turned, goal = ball_in_the_swing(tmp_path)
    robot = cps.Robot(scene=plain)
    target = robot.fk(goal)
    way = cps.plan(start, goal_pose=target, scene=ball, seed=3)
    reached = robot.fk(way["q"][-1])
    assert np.abs(reached[:3, 3] - target[:3, 3]).max() < 1e-6
    assert np.abs(reached[:3, :3] - target[:3, :3]).max() < 1e-6
    assert cps.collide(way["t"], way["q"], scene=ball)["ok"] is True
    quat = cps.Robot(scene=ball).pose(goal)
    out = cli("plan", "--scene", ball, "--from", ",".join(repr(float(x)) for x in start),
              "--to-pose", ",".join(repr(float(x)) for x in quat), "--seed", "3", "--json")
    assert np.allclose(json.loads(out.stdout)["waypoints"][-1], way["waypoints"][-1], atol=1e-6)
    with pytest.raises(ValueError, match="goal_pose: "):
        cps.plan(start, goal_pose=[5.0, 0.0, 0.5], scene=ball)
    with pytest.raises(ValueError, match="one of the two"):
        cps.plan(start, goal, goal_pose=target, scene=ball)
    with pytest.raises(ValueError, match="goal_pose: expected a position"):
        cps.plan(start, goal_pose=np.zeros(5), scene=ball)


def test_movements_on_either_side_of_the_ball_are_joined_around_it_as_the_command_line_joins_them(tmp_path, cli):
    """cps.join runs two movements — a wrist turn on each side of a ball the straight way
    between them meets — as one motion: the movements' samples come through unchanged where
    its stretches put them, the whole passes cps.collide, and `cps-cli plan --join` makes
    the same motion from the same movements in files. A movement through the ball is a
    ValueError naming it and the ball."""
    plain, ball, start, turned, goal = ball_in_the_swing(tmp_path)
    t = np.arange(1001) / 1000.0
    s = t * t * t * (10 - 15 * t + 6 * t * t)

    def wrist(q):
        m = np.tile(q, (len(t), 1))
        m[:, 6] += 0.3 * s
        return m

    a, b = wrist(start), wrist(goal)
    joined = cps.join([(t, a), (t, b)], scene=ball, seed=3)
    parts = [x["part"] for x in joined["stretches"]]
    assert parts == ["movement", "transition", "movement"]
    assert len(joined["stretches"][1]["waypoints"]) >= 3
    for stretch, movement in [(joined["stretches"][0], a), (joined["stretches"][2], b)]:
        first = round(stretch["start_s"] * 1000)
        assert np.abs(joined["q"][first:first + len(movement)] - movement).max() < 1e-12
    assert cps.collide(joined["t"], joined["q"], scene=ball)["ok"] is True
    files = []
    for name, m in [("a.csv", a), ("b.csv", b)]:
        path = tmp_path / name
        np.savetxt(path, np.column_stack([t, m]), delimiter=",", fmt="%.17g",
                   header="t,q1,q2,q3,q4,q5,q6,q7", comments="")
        files.append(str(path))
    out = tmp_path / "task.csv"
    cli("plan", "--scene", ball, "--join", *files, "--seed", "3", "--out", out)
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert rows.shape == (len(joined["t"]), 8)
    assert np.abs(rows[:, 1:] - joined["q"]).max() < 1e-9
    slow = 3 * t
    sweep = start + np.outer(s, goal - start)
    with pytest.raises(ValueError, match=r"movement 2, .*`ball`.*\(movement 2 is movements\[1\]\)"):
        cps.join([(t, a), (slow, sweep)], scene=ball)
    with pytest.raises(ValueError, match=r"movements\[0\]: q"):
        cps.join([(t, a[:, :6])], scene=ball)
