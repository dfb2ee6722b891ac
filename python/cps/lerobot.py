"""LeRobot datasets (format v3.0, a local folder) in and out: a dataset's episodes as
demonstrations for ``cps.imitate`` and ``cps.ProMP.fit``, and recordings or arrays
written as a dataset that LeRobot's own ``LeRobotDataset(repo_id, root=...)`` opens
(joint states and actions, no video). Read and written by cps (parquet in Rust, no
pyarrow needed); ``cps-cli lerobot`` does the same from the command line.

Example::

    import cps, cps.lerobot
    cps.lerobot.show("datasets/fr3_reach")["episodes"]          # frames, duration, tasks
    names, demos = cps.lerobot.demos("datasets/fr3_reach", episodes=[0, 2])
    dmp = cps.imitate([t for t, _ in demos], [y for _, y in demos], names=names)
    promp = cps.ProMP.fit(demos)
    cps.lerobot.write("out/pour", ["run1.csv", "run2.csv"], task="pour", robot="fr3", fps=50)
"""

from __future__ import annotations

import os
from typing import Any, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _cps

__all__ = ["show", "demos", "write", "write_episodes"]

PathLike = Union[str, "os.PathLike[str]"]


def show(root: PathLike) -> dict:
    """A dataset's description: ``format``, ``fps``, ``robot_type``, ``frames``,
    ``tasks``, ``features`` (``name``, ``dtype``, ``shape``, ``names``) and ``episodes``
    (``episode``, ``frames``, ``duration_s``, ``tasks``).

    A folder that is not a v3.0 dataset, or a file in it that cannot be read, raises
    ``ValueError`` naming the file and the fault.
    """
    return _cps._lerobot_show(os.fspath(root))


def demos(
    root: PathLike,
    episodes: Optional[Sequence[int]] = None,
    *,
    feature: str = "observation.state",
    robot: Optional[str] = None,
    columns: Optional[Sequence[str]] = None,
) -> Tuple[list, list]:
    """``(names, [(t, y), ...])``: one demonstration per episode (all by default) of the
    vector feature ``feature`` — ``t`` (frames,) seconds from 0, ``y`` (frames, entries).

    The entries are matched by name to the joints of ``robot`` (``"panda"``, ``"fr3"``, a
    robot file), by default to the dataset's ``robot_type`` when cps knows it, or chosen
    by name with ``columns``. A feature that is not a vector of numbers, or whose entries
    do not name the robot's joints, raises ``ValueError`` saying which entries it has.
    """
    names, found = _cps._lerobot_demos(
        os.fspath(root),
        None if episodes is None else [int(e) for e in episodes],
        feature,
        robot,
        None if columns is None else list(columns),
    )
    return list(names), list(found)


def write(
    out: PathLike,
    recordings: Sequence[PathLike],
    *,
    task: str,
    robot: str = "fr3",
    fps: Optional[int] = None,
    force: bool = False,
) -> dict:
    """Recordings (``franka execute --record``, ``franka record``, ``franka guide``,
    ``ros2 record``, a joint CSV) written as a new dataset at ``out``, one episode each:
    ``observation.state`` (and ``observation.velocity``, ``observation.effort`` where
    recorded) and ``action`` (the commanded joints; the next frame's state where none were
    recorded), resampled to ``fps`` (default: the first recording's rate).

    ``force`` replaces a dataset at ``out`` that holds nothing but the files cps writes;
    a folder with any other file is never touched. Returns what was
    written: ``fps``, ``episodes`` (frames each), ``features``, ``action``.
    """
    return _cps._lerobot_write(
        os.fspath(out), [os.fspath(p) for p in recordings], robot, task, fps, force
    )


def write_episodes(
    out: PathLike,
    episodes: Sequence[Mapping[str, Any]],
    *,
    names: Mapping[str, Sequence[str]],
    fps: int,
    task: Union[str, Sequence[str]],
    robot_type: Optional[str] = None,
) -> None:
    """Episodes given as arrays written as a new dataset at ``out``: each a dict of
    feature → (frames, entries) array, frame ``k`` at ``k / fps`` s; ``names`` gives each
    feature's entry names (and the features' order); ``task`` one for all, or one per
    episode.
    """
    tasks = [task] * len(episodes) if isinstance(task, str) else list(task)
    eps = [{k: np.asarray(v, dtype=float) for k, v in e.items()} for e in episodes]
    _cps._lerobot_write_arrays(
        os.fspath(out), eps, {k: list(v) for k, v in names.items()}, int(fps), tasks, robot_type
    )
