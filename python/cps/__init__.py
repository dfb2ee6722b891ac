"""cps — motor-control learning for robot arms, from Python.

DMPs, CMA-ES with pycma's interface, via-point and imitation learning, every experiment
kind of ``cps-cli run``, and robot kinematics — computed in Rust, with numpy arrays in and
out. Arrays of samples have shape (samples, dims); time is its own array.

>>> import numpy as np, cps
>>> t = np.linspace(0.0, 1.0, 101)
>>> dmp = cps.imitate(t, np.column_stack([np.sin(t), t**2]))
>>> t2, y, yd, ydd = dmp.rollout(goal=[1.0, 2.0])
>>> res = cps.fmin(lambda x: float((x**2).sum()), np.full(5, 3.0), 2.0, {"ftarget": 1e-8, "seed": 1})
>>> res.fbest <= 1e-8
True

Long calls release the GIL and stop cleanly on Ctrl-C (KeyboardInterrupt). Bad input
raises ``ValueError`` with a sentence naming the argument and the rule; a failure while
working raises ``cps.CpsError`` (a ``RuntimeError``). Everything stochastic takes a seed:
the same seed gives the same bits, whatever the number of threads.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple, Optional

from . import _cps, lerobot, mocap, ros2
from ._cps import (
    DMP,
    ChunkExecutor,
    CpsError,
    Franka,
    Outcome,
    ProMP,
    QuaternionDMP,
    RhythmicDMP,
    Robot,
    Stepper,
    Table,
    Trajectory,
    ViaPointResult,
    __version__,
    chunk_commands,
    identify,
    imitate,
    learn_via_points,
    run_experiment,
    sequence,
)

__all__ = [
    "CMAES",
    "ChunkExecutor",
    "chunk_commands",
    "collide",
    "plan",
    "join",
    "CMAEvolutionStrategy",
    "CMAEvolutionStrategyResult",
    "CpsError",
    "DMP",
    "FminResult",
    "Franka",
    "Outcome",
    "ProMP",
    "QuaternionDMP",
    "RhythmicDMP",
    "Robot",
    "Stepper",
    "Table",
    "Trajectory",
    "ViaPointResult",
    "__version__",
    "fmin",
    "identify",
    "imitate",
    "learn_via_points",
    "run_experiment",
    "lerobot",
    "mocap",
    "ros2",
    "sequence",
]

class CMAEvolutionStrategyResult(NamedTuple):
    """pycma's result tuple: the best point and its cost, the evaluation that found it,
    evaluations and iterations spent, the distribution mean (``xfavorite``), the standard
    deviations sigma * sqrt(diag(C)) and the stop conditions met."""

    xbest: Any
    fbest: float
    evals_best: int
    evaluations: int
    iterations: int
    xfavorite: Any
    stds: Any
    stop: dict


# What `cps.fmin` returns: pycma's `fmin` result (its first eight entries) as the same
# named tuple, so `res[0]`, `res[1]` and `res.xbest` all work.
FminResult = CMAEvolutionStrategyResult


class CMAES(_cps._CMAES):
    """CMA-ES with pycma's ask-and-tell interface (Hansen 2016, active covariance update).

    ``es = cps.CMAES(x0, sigma0, inopts)``, where ``inopts`` (a dict) and keyword
    arguments take pycma's option names: ``seed`` (default 1; same seed, same bits),
    ``popsize``, ``bounds`` (``[lower, upper]``, each None, a number or one per
    coordinate), ``maxfevals``, ``maxiter``, ``ftarget``, ``tolfun`` (1e-11), ``tolx``
    (1e-11), ``tolupsigma`` (1e20), ``tolconditioncov`` (1e14), ``tolflatfitness``,
    ``CMA_diagonal`` (the separable variant), ``CMA_stds``; ``verbose``, ``verb_disp`` and
    ``verb_log`` are accepted and ignored (cps prints and writes nothing).

    >>> es = CMAES([3.0] * 10, 2.0, {"seed": 1})
    >>> while not es.stop():
    ...     X = es.ask()                      # (popsize, N) array
    ...     es.tell(X, [float((x**2).sum()) for x in X])
    >>> es.result.fbest < 1e-10
    True

    Differences from pycma: ``tell`` takes exactly the candidates of the last ``ask``
    (no injected solutions); asking again before ``tell`` returns the same candidates.
    """

    @property
    def result(self) -> CMAEvolutionStrategyResult:
        """``CMAEvolutionStrategyResult(xbest, fbest, evals_best, evaluations, iterations,
        xfavorite, stds, stop)``."""
        return CMAEvolutionStrategyResult(*self._result())

    def __repr__(self) -> str:
        return f"CMAES(N={self.N}, popsize={self.popsize}, iteration={self.countiter}, sigma={self.sigma:.3g})"


CMAEvolutionStrategy = CMAES


def fmin(
    objective_function: Optional[Callable[..., Any]],
    x0: Any,
    sigma0: float,
    options: Optional[dict[str, Any]] = None,
    args: tuple[Any, ...] = (),
    restarts: int = 0,
    bipop: bool = False,
    incpopsize: float = 2,
    parallel_objective: Optional[Callable[..., Any]] = None,
) -> FminResult:
    """Minimises ``objective_function(x, *args)`` from ``x0`` with step size ``sigma0``:
    pycma's ``fmin``, its options under pycma's names (see ``CMAES``).

    ``parallel_objective=f`` instead calls ``f(X, *args)`` once per generation with the
    (popsize, N) array and takes popsize costs. ``restarts=k`` restarts up to k times with
    IPOP (population doubled each time), or BIPOP with ``bipop=True``. The loop runs in
    Rust; Ctrl-C stops it after the current generation (KeyboardInterrupt).

    Returns the named tuple ``(xbest, fbest, evals_best, evaluations, iterations, xfavorite,
    stds, stop)``: ``res[0]`` is the best point, ``res[1]`` its cost, as in pycma.
    """
    res = _cps._fmin(
        objective_function,
        x0,
        sigma0,
        options,
        tuple(args),
        restarts,
        bipop,
        float(incpopsize),
        parallel_objective,
    )
    return FminResult(*res)


def collide(
    t: Any,
    q: Any,
    *,
    robot: Optional[str] = None,
    tool: Optional[str] = None,
    tip: Optional[str] = None,
    scene: Any = None,
    margin: Optional[float] = None,
    rate: float = 1000.0,
) -> dict:
    """Checks a joint trajectory (``t`` (samples,), ``q`` (samples, dof)) for collisions of
    the robot with itself and its scene's obstacles, as the guard will before sending it at
    ``rate`` Hz: what ``cps-cli collide --json`` prints (``ok``, ``collision``, ``closest``,
    and each row's pairs within 10 cm with their signed distances in metres). The robot is
    ``robot`` (a built-in name or a file; default the Panda) or ``scene``'s, keeping
    ``margin`` metres (default: the scene's, else 5 mm).

    >>> import numpy as np, cps
    >>> fr3 = cps.Robot("fr3")
    >>> report = cps.collide([0.0, 1.0], np.tile(fr3.ready, (2, 1)), robot="fr3")
    >>> report["ok"], report["bodies"]
    (True, 17)
    """
    r = Robot(robot, tool=tool, tip=tip, scene=scene, margin=margin)
    return r.collide(t, q, rate=rate)


def plan(
    start: Any,
    goal: Any = None,
    *,
    goal_pose: Any = None,
    robot: Optional[str] = None,
    tool: Optional[str] = None,
    tip: Optional[str] = None,
    scene: Any = None,
    margin: Optional[float] = None,
    seed: int = 1,
    samples: int = 20000,
    share: float = 0.5,
) -> dict:
    """A collision-free joint path from ``start`` to ``goal`` around the robot itself and
    its scene, as ``cps-cli plan --json`` finds it (``waypoints``, ``length_rad``,
    ``duration_s``, ``clearance_m``, ``planning_s``, ...), with the timed motion ``t``
    (samples,) and ``q`` (samples, dof) every millisecond, verified as the guard checks a
    plan. The robot is ``robot`` (a built-in name or a file; default the Panda) or
    ``scene``'s, keeping ``margin`` metres (default: the scene's, else 5 mm). Instead of
    ``goal`` (joint angles), ``goal_pose`` puts the tool there: a position (3,), a pose
    ``[x, y, z, qx, qy, qz, qw]`` (7,) or a 4×4 matrix, world frame; the goal is the clear
    inverse-kinematics solution nearest ``start`` (``cps-cli plan --to-pose``). Raises
    ``ValueError`` for a bad end (the pair named when it is in collision, a pose out of
    reach) and ``cps.CpsError`` when no path is found within ``samples`` random
    configurations.

    >>> import cps
    >>> way = cps.plan([0, -0.8, 0, -2.4, 0, 1.6, 0.8], [1, -0.3, 0, -2, 0, 1.8, 0.8], robot="fr3")
    >>> len(way["waypoints"]), way["q"].shape[1]
    (2, 7)
    """
    r = Robot(robot, tool=tool, tip=tip, scene=scene, margin=margin)
    return r.plan(start, goal, goal_pose=goal_pose, seed=seed, samples=samples, share=share)


def join(
    movements: Any,
    *,
    start: Any = None,
    robot: Optional[str] = None,
    tool: Optional[str] = None,
    tip: Optional[str] = None,
    scene: Any = None,
    margin: Optional[float] = None,
    seed: int = 1,
    samples: int = 20000,
    share: float = 0.5,
) -> dict:
    """Movements — a list of ``(t, q)`` pairs, ``q`` (samples, dof) — run one after another
    as one motion, as ``cps-cli plan --join --json`` makes it: wherever the robot would
    stand elsewhere than the next movement's start (after the one before, or at ``start``,
    default the first movement's start), a path ``cps.plan`` would find leads there; the
    movements themselves come through unchanged (resampled every millisecond), and the
    whole is verified as the guard checks a plan. Returns ``stretches`` (each movement or
    transition with its ``start_s`` and ``end_s``) with the motion ``t`` and ``q``. Raises
    ``ValueError`` naming the movement (``movements[k]``) that breaks a limit or comes
    within the margin, and ``cps.CpsError`` when no transition is found.

    >>> import cps, numpy as np
    >>> t = np.linspace(0, 1, 11)
    >>> a = np.tile([0, -0.8, 0, -2.4, 0, 1.6, 0.8], (11, 1))
    >>> b = np.tile([1, -0.3, 0, -2, 0, 1.8, 0.8], (11, 1))
    >>> [s["part"] for s in cps.join([(t, a), (t, b)], robot="fr3")["stretches"]]
    ['movement', 'transition', 'movement']
    """
    r = Robot(robot, tool=tool, tip=tip, scene=scene, margin=margin)
    return r.join(movements, start=start, seed=seed, samples=samples, share=share)
