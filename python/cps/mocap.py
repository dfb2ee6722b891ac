"""Demonstrations from motion capture: C3D files (Vicon, Qualisys, OptiTrack Motive…) and
Motive's CSV export, read by cps's own readers.

``take`` gives a take's markers as they are in the file; ``read`` makes a demonstration
of it — the pose of a tool carrying three or more labelled markers (fitted as one rigid
body at every frame), or of a rigid body Motive solved — with short gaps filled,
outliers rejected, smoothing without lag, and, given a registration file, in the
robot's frame. It is what ``cps-cli mocap import`` writes.

Example::

    import cps.mocap
    take = cps.mocap.take("pour.c3d")
    take["labels"], take["rate"], take["points"].shape     # [...], 240.0, (frames, markers, 3)
    demo = cps.mocap.read("pour.c3d", ["tool1", "tool2", "tool3"], to_robot="lab.toml")
    demo["t"], demo["position"], demo["quaternion"]         # (n,), (n, 3) m, (n, 4) xyzw
    demo["report"]["markers"][0]["gaps_filled"]
"""

from __future__ import annotations

import os
from typing import Optional, Sequence, Tuple

from . import _cps

__all__ = ["take", "read"]


def take(path: "str | os.PathLike[str]") -> dict:
    """A take as its file holds it: ``labels``, ``rate`` (Hz), ``frames``,
    ``first_frame``, ``units`` and ``metres_per_unit``; ``points`` (frames, markers, 3) in
    the file's units with NaN where a marker was not seen, ``residuals`` (frames, markers;
    negative where missing); ``analog`` (``labels``, ``units``, ``rate``, ``values``
    (samples, channels)) when the file has analog channels; ``rigid_bodies`` (Motive:
    name → ``position`` (frames, 3), ``quaternion`` (frames, 4) xyzw); ``notes``.

    A file that cannot be read (truncated, corrupt, sizes that do not hold) raises
    ``ValueError`` naming the file and the place.
    """
    return _cps._mocap_take(os.fspath(path))


def read(
    path: "str | os.PathLike[str]",
    markers: Optional[Sequence[str]] = None,
    *,
    rigid_body: Optional[str] = None,
    origin: str = "centroid",
    axes: Optional[Sequence[str]] = None,
    to_robot: "Optional[str | os.PathLike[str]]" = None,
    y_up: bool = False,
    max_gap: int = 10,
    cutoff: Optional[float] = 10.0,
    outlier_mm: float = 20.0,
    frames: Optional[Tuple[int, int]] = None,
) -> dict:
    """The demonstration of a take: ``t`` (s from 0), ``position`` (n, 3) m,
    ``quaternion`` (n, 4) ``[qx, qy, qz, qw]`` (continuous) and ``report``.

    ``markers`` (three or more labels; ``Subject:label`` may be shortened to ``label``)
    are fitted as one rigid body, its origin their ``"centroid"`` or one marker's label,
    its axes the take's at the first frame that sees them all, or built from ``axes =
    [O, X, P]`` (x from O to X, z normal to the plane O-X-P). ``rigid_body`` takes
    Motive's own instead. Gaps of at most ``max_gap`` frames are filled by a cubic
    spline; a sample more than ``outlier_mm`` from its neighbours' median or from the
    body's fit is rejected; ``cutoff`` Hz is the zero-phase low-pass (``None``: none).
    ``to_robot`` is a registration file (points measured in both frames) that carries
    the pose into the robot's frame; ``y_up`` turns a Y-up take Z-up instead. ``frames``
    ``(first, end)`` uses only those frames (indices from 0).

    An unknown label, too few markers for too long, or a registration that does not
    hold raises ``ValueError`` with a sentence naming the file and the frames.
    """
    return _cps._mocap_read(
        os.fspath(path),
        list(markers) if markers is not None else None,
        rigid_body=rigid_body,
        origin=origin,
        axes=list(axes) if axes is not None else None,
        to_robot=os.fspath(to_robot) if to_robot is not None else None,
        y_up=y_up,
        max_gap=max_gap,
        cutoff=cutoff,
        outlier_mm=outlier_mm,
        frames=tuple(frames) if frames is not None else None,
    )
