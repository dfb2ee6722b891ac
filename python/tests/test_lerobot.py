"""LeRobot datasets from Python: the dataset LeRobot 0.6.1's own writer made
(crates/cps-lerobot/tests/data) read as demonstrations, and datasets cps writes opened
by pyarrow and pandas — the readers LeRobot's loader stands on — with the parquet schema
of LeRobot's own files, every value back, and the tasks indexed as LeRobot reads them."""

import importlib.util
import math
import os
from pathlib import Path

import numpy as np
import pytest

import cps
import cps.lerobot

for needed in ("pyarrow", "pandas"):
    if importlib.util.find_spec(needed) is None:
        if os.environ.get("CI"):
            pytest.fail(f"{needed} is not installed (.ci/run installs it)", pytrace=False)
        pytest.skip(f"{needed} is not installed", allow_module_level=True)

import pandas as pd  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402

FIXTURE = Path(__file__).resolve().parents[2] / "crates/cps-lerobot/tests/data/fr3_reach"
START = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
DIRECTION = np.array([1.0, 0.5, -0.5, 0.8, 0.3, -0.4, 0.6])


def reach(episode, n):
    s = np.arange(n) / (n - 1)
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    return START + blend[:, None] * 0.1 * (episode + 1) * DIRECTION


def test_lerobots_own_dataset_as_demonstrations():
    info = cps.lerobot.show(FIXTURE)
    assert info["fps"] == 30 and info["robot_type"] == "panda"
    assert [e["frames"] for e in info["episodes"]] == [40, 52, 35]
    names, demos = cps.lerobot.demos(FIXTURE, episodes=[0, 2])
    assert names == [f"panda_joint{j}" for j in range(1, 8)]
    for (t, y), (e, n) in zip(demos, [(0, 40), (2, 35)]):
        assert np.array_equal(t, np.arange(n) / 30.0)
        assert np.max(np.abs(y - reach(e, n))) < 1e-6
    dmp = cps.imitate([t for t, _ in demos], [y for _, y in demos], names=names)
    assert dmp.dims == 7
    promp = cps.ProMP.fit(demos)
    assert promp.dims == 7
    # The action's gripper is not one of the Panda's joints: matched by name, dropped.
    names, _ = cps.lerobot.demos(FIXTURE, feature="action")
    assert len(names) == 7
    with pytest.raises(ValueError, match=r"\(x, y, z\) do not name `panda_joint1`"):
        cps.lerobot.demos(FIXTURE, feature="observation.environment_state", robot="panda")
    with pytest.raises(ValueError, match="has no episode 7"):
        cps.lerobot.demos(FIXTURE, episodes=[7])


def leaves(path):
    """Each leaf column of a parquet file: its path, physical and logical type."""
    s = pq.ParquetFile(path).schema
    return [(c.path, c.physical_type, str(c.logical_type)) for c in s]


def test_written_arrays_have_lerobots_schema_and_read_back(tmp_path):
    joints = [f"fr3_joint{j}" for j in range(1, 8)]
    rng = np.random.default_rng(4)
    eps = [{"observation.state": rng.normal(size=(n, 7)), "action": rng.normal(size=(n, 7))}
           for n in (25, 9)]
    out = tmp_path / "arrays"
    cps.lerobot.write_episodes(out, eps, names={"observation.state": joints, "action": joints},
                               fps=20, task=["pick", "place"], robot_type="fr3")
    data = out / "data/chunk-000/file-000.parquet"
    theirs = [c for c in leaves(FIXTURE / "data/chunk-000/file-000.parquet")
              if not c[0].startswith("observation.environment_state")]
    assert leaves(data) == theirs
    for f in ("meta/tasks.parquet", "meta/episodes/chunk-000/file-000.parquet"):
        ours = leaves(out / f)
        assert ours == [c for c in leaves(FIXTURE / f) if not c[0].startswith("stats/")], f
    table = pq.read_table(data).to_pydict()
    assert table["index"] == list(range(34))
    assert table["episode_index"] == [0] * 25 + [1] * 9
    assert table["task_index"] == [0] * 25 + [1] * 9
    assert np.allclose(table["timestamp"], [k / 20 for k in range(25)] + [k / 20 for k in range(9)])
    state = np.array(table["observation.state"])
    assert np.array_equal(state, np.vstack([e["observation.state"] for e in eps]).astype(np.float32))
    # LeRobot reads the tasks with pandas, indexed by the task's words.
    tasks = pd.read_parquet(out / "meta/tasks.parquet")
    assert list(tasks.index) == ["pick", "place"] and list(tasks["task_index"]) == [0, 1]
    episodes = pq.read_table(out / "meta/episodes/chunk-000/file-000.parquet").to_pydict()
    assert episodes["dataset_from_index"] == [0, 25] and episodes["dataset_to_index"] == [25, 34]
    assert episodes["tasks"] == [["pick"], ["place"]]
    again = cps.lerobot.show(out)
    assert again["frames"] == 34 and again["tasks"] == ["pick", "place"]


def franka_recording(path, seconds, phase):
    """A recording in `franka execute --record`'s layout at 1 kHz."""
    cols = ["t"] + [f"{p}{j}" for p in ("q", "dq", "tau", "q_d") for j in range(1, 8)]
    cols += ["tool_x", "tool_y", "tool_z"]
    rows = []
    for k in range(int(seconds * 1000) + 1):
        t = k / 1000
        q = [0.1 * j + 0.2 * math.sin(t + phase) for j in range(7)]
        rows.append([t] + q + [0.2 * math.cos(t + phase)] * 7 + [0.5 * j for j in range(7)]
                    + [v + 0.001 for v in q] + [0.3, 0.0, 0.5])
    path.write_text(",".join(cols) + "\n" + "\n".join(",".join(repr(v) for v in r) for r in rows) + "\n")


def test_recordings_become_episodes_on_the_frame_grid(tmp_path):
    recs = [tmp_path / "a.csv", tmp_path / "b.csv"]
    franka_recording(recs[0], 2.0, 0.0)
    franka_recording(recs[1], 1.5, 1.0)
    out = tmp_path / "ds"
    done = cps.lerobot.write(out, recs, task="wave", fps=50)
    assert done["episodes"] == [101, 76] and done["action"] == "commands"
    assert done["features"] == ["observation.state", "observation.velocity", "observation.effort", "action"]
    table = pq.read_table(out / "data/chunk-000/file-000.parquet").to_pydict()
    for i, (e, k) in enumerate(zip(table["episode_index"], table["frame_index"])):
        t = k / 50
        q = np.array([0.1 * j + 0.2 * math.sin(t + e) for j in range(7)])
        assert np.max(np.abs(np.array(table["observation.state"][i]) - q)) < 1e-6
        assert np.max(np.abs(np.array(table["action"][i]) - q - 0.001)) < 1e-6
    # The same folder again: refused unless forced; forced, replaced whole.
    with pytest.raises(ValueError, match="--force replaces it"):
        cps.lerobot.write(out, recs[:1], task="wave", fps=50)
    assert cps.lerobot.write(out, recs[:1], task="wave", fps=10, force=True)["episodes"] == [21]
    assert cps.lerobot.show(out)["frames"] == 21
    # A folder that is not a dataset is never replaced.
    other = tmp_path / "mine"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(ValueError, match="not a LeRobot dataset cps would replace"):
        cps.lerobot.write(other, recs, task="wave", force=True)
    assert (other / "keep.txt").read_text() == "mine"
