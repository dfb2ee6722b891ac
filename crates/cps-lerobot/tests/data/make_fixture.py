"""Writes the fixture dataset `fr3_reach/` with LeRobot's own writer, once (it is kept in
the repository, so CI needs no LeRobot). Run with PyPI's lerobot 0.6.1, which needs Python
3.12 and torch (about 5 GB):

    python3.12 -m venv /tmp/lerobot-venv
    /tmp/lerobot-venv/bin/pip install 'lerobot[dataset]==0.6.1'
    /tmp/lerobot-venv/bin/python crates/cps-lerobot/tests/data/make_fixture.py

Three episodes of a 7-joint arm at 30 frames/s (40, 52 and 35 frames): the state's names
are the Panda's joints, the action adds a gripper after them, and a 3-D environment state
stands for a feature that is not joint-space. Each episode is a smooth reach, q(t) =
start + (goal - start) * (10 s^3 - 15 s^4 + 6 s^5), so a test can check every value.
"""

import shutil
from pathlib import Path

import numpy as np
from lerobot.datasets.lerobot_dataset import LeRobotDataset

HERE = Path(__file__).resolve().parent
ROOT = HERE / "fr3_reach"
JOINTS = [f"panda_joint{k}" for k in range(1, 8)]
FPS = 30
LENGTHS = [40, 52, 35]
TASKS = ["reach the left bin", "reach the right bin", "reach the left bin"]
START = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def reach(episode, n):
    goal = START + 0.1 * (episode + 1) * np.array([1.0, 0.5, -0.5, 0.8, 0.3, -0.4, 0.6])
    s = np.arange(n) / (n - 1)
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    return START + blend[:, None] * (goal - START)


def main():
    if ROOT.exists():
        shutil.rmtree(ROOT)
    features = {
        "observation.state": {"dtype": "float32", "shape": (7,), "names": JOINTS},
        "action": {"dtype": "float32", "shape": (8,), "names": JOINTS + ["gripper"]},
        "observation.environment_state": {"dtype": "float32", "shape": (3,),
                                          "names": ["x", "y", "z"]},
    }
    ds = LeRobotDataset.create("cps/fr3_reach", fps=FPS, features=features, root=ROOT,
                               robot_type="panda", use_videos=False)
    for e, (n, task) in enumerate(zip(LENGTHS, TASKS)):
        q = reach(e, n)
        for k in range(n):
            action = np.append(q[min(k + 1, n - 1)], 0.04 if k < n // 2 else 0.0)
            ds.add_frame({
                "observation.state": q[k].astype(np.float32),
                "action": action.astype(np.float32),
                "observation.environment_state": np.array([0.5, 0.1 * e, 0.2], np.float32),
                "task": task,
            })
        ds.save_episode()
    ds.finalize()
    back = LeRobotDataset("cps/fr3_reach", root=ROOT)
    print(f"wrote {ROOT}: {back.num_episodes} episodes, {back.num_frames} frames")


if __name__ == "__main__":
    main()
