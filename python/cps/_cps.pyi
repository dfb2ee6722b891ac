"""Type stubs of the extension module cps._cps (see cps/__init__.py for the package)."""

from __future__ import annotations

import os
from typing import Any, Callable, Iterator, Literal, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
F64 = npt.NDArray[np.float64]
PathLike = Union[str, os.PathLike[str]]
Formulation = Literal["ijspeert", "robust"]

__version__: str

class CpsError(RuntimeError):
    """A failure while cps was working (not a problem with the input)."""

class Trajectory:
    """One sampled movement; unpacks as ``t, y, yd, ydd``."""
    t: F64
    y: F64
    yd: F64
    ydd: F64
    names: list[str]
    def __iter__(self) -> Iterator[F64]: ...

class Stepper:
    """A DMP advanced one control period at a time."""
    def step(self, dt: float, *, coupling: Optional[ArrayLike] = None, tracking_error: float = 0.0) -> None: ...
    def set_goal(self, goal: ArrayLike) -> None: ...
    def set_tau(self, tau: float) -> None: ...
    @property
    def position(self) -> F64: ...
    @property
    def velocity(self) -> F64: ...
    @property
    def acceleration(self) -> F64: ...
    @property
    def phase(self) -> float: ...
    @property
    def time(self) -> float: ...
    @property
    def goal(self) -> F64: ...
    @property
    def tau(self) -> float: ...

class DMP:
    """A discrete DMP with its weights (Ijspeert et al. 2013)."""
    def __init__(
        self,
        start: ArrayLike,
        goal: ArrayLike,
        *,
        tau: float = 1.0,
        dt: float = 0.01,
        bases: int = 25,
        weights: Optional[ArrayLike] = None,
        formulation: Formulation = "ijspeert",
        alpha_z: float = 25.0,
        beta_z: Optional[float] = None,
        alpha_x: Optional[float] = None,
        names: Optional[Sequence[str]] = None,
    ) -> None: ...
    @property
    def dims(self) -> int: ...
    @property
    def bases(self) -> int: ...
    @property
    def tau(self) -> float: ...
    @property
    def dt(self) -> float: ...
    @property
    def gains(self) -> tuple[float, float, float]: ...
    @property
    def formulation(self) -> Literal["ijspeert", "robust"]: ...
    @property
    def start(self) -> F64: ...
    @property
    def goal(self) -> F64: ...
    @property
    def weights(self) -> F64: ...
    @property
    def names(self) -> list[str]: ...
    @property
    def times(self) -> F64: ...
    @property
    def fit(self) -> Optional[dict[str, Any]]: ...
    def rollout(
        self,
        *,
        start: Optional[ArrayLike] = None,
        goal: Optional[ArrayLike] = None,
        tau: Optional[float] = None,
        dt: Optional[float] = None,
        weights: Optional[ArrayLike] = None,
    ) -> Trajectory: ...
    def rollout_batch(self, weights: ArrayLike) -> F64: ...
    def retarget(
        self,
        start: ArrayLike,
        goal: ArrayLike,
        *,
        mode: Literal["rotate", "similar", "translate"] = "rotate",
    ) -> DMP: ...
    def rollout_avoiding(
        self,
        obstacles: ArrayLike,
        *,
        avoidance: Literal["steering", "potential"] = "steering",
        gains: Optional[tuple[float, float]] = None,
    ) -> Trajectory: ...
    def with_weights(self, weights: ArrayLike) -> DMP: ...
    def stepper(self, *, error_gain: float = 1.0) -> Stepper: ...
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str) -> DMP: ...
    def save(self, path: PathLike, *, force: bool = False) -> None: ...
    @staticmethod
    def load(path: PathLike) -> DMP: ...

def sequence(dmps: Sequence[DMP], *, junction: Literal["c2", "c1"] = "c2") -> Trajectory: ...
def imitate(
    t: Union[ArrayLike, Sequence[ArrayLike]],
    y: Union[ArrayLike, Sequence[ArrayLike]],
    *,
    bases: int = 25,
    method: Literal["lwr", "ridge", "jerk"] = "ridge",
    lambda_: Union[None, float, Literal["auto"]] = None,
    tau: Optional[float] = None,
    dt: Optional[float] = None,
    formulation: Formulation = "robust",
    combine: Literal["mean", "stack"] = "mean",
    names: Optional[Sequence[str]] = None,
) -> DMP: ...

class RhythmicDMP:
    """A periodic DMP; one period lasts 2 pi tau seconds."""
    @staticmethod
    def learn(t: ArrayLike, y: ArrayLike, *, bases: int = 30, samples: int = 400, lambda_: float = 1e-10) -> RhythmicDMP: ...
    def rollout(self, duration: float, dt: float) -> tuple[F64, F64, F64]: ...
    tau: float
    anchor: F64
    amplitude: F64
    @property
    def weights(self) -> F64: ...

class QuaternionDMP:
    """An orientation DMP on unit quaternions [x, y, z, w]."""
    def __init__(
        self,
        start: ArrayLike,
        goal: ArrayLike,
        *,
        tau: float = 1.0,
        dt: float = 0.01,
        bases: int = 25,
        weights: Optional[ArrayLike] = None,
    ) -> None: ...
    @staticmethod
    def learn(
        t: ArrayLike,
        q: ArrayLike,
        *,
        bases: int = 25,
        tau: Optional[float] = None,
        dt: Optional[float] = None,
        lambda_: float = 1e-10,
    ) -> QuaternionDMP: ...
    def rollout(self, *, goal: Optional[ArrayLike] = None) -> tuple[F64, F64, F64]: ...
    @property
    def start(self) -> F64: ...
    @property
    def goal(self) -> F64: ...
    @property
    def weights(self) -> F64: ...

class _CMAES:
    def __init__(self, x0: ArrayLike, sigma0: float, inopts: Optional[dict[str, Any]] = None, **kwargs: Any) -> None: ...
    def ask(self) -> F64: ...
    def tell(self, X: ArrayLike, f: ArrayLike) -> None: ...
    def stop(self) -> dict[str, Any]: ...
    def optimize(
        self,
        f: Callable[..., Any],
        iterations: Optional[int] = None,
        args: Optional[tuple[Any, ...]] = None,
        *,
        vectorized: bool = False,
        callback: Optional[Callable[[Any], Any]] = None,
    ) -> Any: ...
    def _result(self) -> tuple[Any, ...]: ...
    @property
    def mean(self) -> F64: ...
    @property
    def sigma(self) -> float: ...
    @property
    def stds(self) -> F64: ...
    @property
    def C(self) -> F64: ...
    @property
    def countiter(self) -> int: ...
    @property
    def countevals(self) -> int: ...
    @property
    def popsize(self) -> int: ...
    @property
    def N(self) -> int: ...

def _fmin(
    objective_function: Optional[Callable[..., Any]],
    x0: ArrayLike,
    sigma0: float,
    options: Optional[dict[str, Any]] = None,
    args: Optional[tuple[Any, ...]] = None,
    restarts: int = 0,
    bipop: bool = False,
    incpopsize: float = 2.0,
    parallel_objective: Optional[Callable[..., Any]] = None,
) -> tuple[Any, ...]: ...

class ViaPointResult:
    """A via-point learning result."""
    @property
    def trajectory(self) -> Trajectory: ...
    @property
    def dmp(self) -> DMP: ...
    @property
    def cost(self) -> float: ...
    @property
    def optimum_cost(self) -> float: ...
    @property
    def gap_to_optimum(self) -> float: ...
    @property
    def breakdown(self) -> dict[str, float]: ...
    @property
    def via_errors(self) -> F64: ...
    @property
    def goal_error(self) -> float: ...
    @property
    def final_speed(self) -> float: ...
    @property
    def history(self) -> dict[str, F64]: ...
    @property
    def generations(self) -> int: ...
    @property
    def evaluations(self) -> int: ...
    @property
    def termination(self) -> str: ...
    @property
    def runs(self) -> list[dict[str, Any]]: ...

def learn_via_points(
    start: ArrayLike,
    goal: ArrayLike,
    via: Sequence[Any],
    *,
    tau: float = 10.0,
    dt: float = 0.01,
    bases: int = 25,
    goal_velocity: Optional[ArrayLike] = None,
    cost: Optional[dict[str, float]] = None,
    obstacles: Optional[Sequence[tuple[ArrayLike, float]]] = None,
    method: Literal["cmaes", "exact", "least_squares"] = "cmaes",
    parametrisation: Literal["anchor_offset", "raw", "thesis_scaling"] = "anchor_offset",
    warm_start: bool = False,
    evaluation: Literal["auto", "rollout", "quadratic"] = "auto",
    polish: bool = False,
    sigma0: float = 0.5,
    population: Optional[int] = None,
    generations: int = 1000,
    tol_fun: Optional[float] = 1e-9,
    repetitions: int = 1,
    seed: int = 1,
    threads: Optional[int] = None,
    names: Optional[Sequence[str]] = None,
) -> ViaPointResult: ...

class Table:
    """A named table: columns by name."""
    @property
    def name(self) -> str: ...
    @property
    def columns(self) -> list[str]: ...
    def __len__(self) -> int: ...
    def __contains__(self, name: str) -> bool: ...
    def __getitem__(self, name: str) -> Union[F64, npt.NDArray[np.uint64], list[str]]: ...
    def to_dict(self) -> dict[str, Any]: ...
    def to_csv(self) -> str: ...

class Outcome:
    """What a run produced."""
    @property
    def complete(self) -> bool: ...
    @property
    def failure(self) -> Optional[str]: ...
    @property
    def kind(self) -> str: ...
    @property
    def summary(self) -> dict[str, Any]: ...
    @property
    def tables(self) -> dict[str, Table]: ...
    @property
    def figures(self) -> list[tuple[str, str]]: ...
    @property
    def lines(self) -> list[str]: ...
    def save(self, out: PathLike, *, force: bool = False, figures: Optional[bool] = None) -> None: ...

def identify(
    recording: PathLike,
    *,
    out: PathLike,
    robot: str = "fr3",
    force: bool = False,
) -> dict[str, Any]: ...

def run_experiment(
    path: PathLike,
    *,
    out: Optional[PathLike] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    force: bool = False,
    figures: Optional[bool] = None,
    max_memory: float = 4.0,
    max_work: float = 1e13,
    progress: Optional[Callable[[dict[str, Any]], Any]] = None,
) -> Outcome: ...

class ChunkExecutor:
    """Follows a learned policy's action chunks on a robot (``"franka"`` at ``host``,
    ``"dynamics"``, ``"kinematic"``) within every limit; the robot's loop runs from
    construction until ``close()``."""
    def __init__(
        self,
        robot: str = "dynamics",
        arm: str = "fr3",
        host: Optional[str] = None,
        rate: float = 50.0,
        start: Optional[ArrayLike] = None,
        stall_timeout: float = 0.25,
        max_gap: float = 0.2,
        idle_end: float = 5.0,
        max_duration: float = 300.0,
        realtime: str = "enforce",
        record: Optional[Union[str, os.PathLike[str]]] = None,
        force: bool = False,
        limit_share: float = 0.95,
        scene: Optional[Union[str, os.PathLike[str]]] = None,
    ) -> None: ...
    def state(self) -> tuple[float, np.ndarray]: ...
    def observe(self) -> dict[str, Any]: ...
    def push(self, targets: ArrayLike, observed_at: float, rate: Optional[float] = None, velocities: Optional[ArrayLike] = None) -> None: ...
    @property
    def running(self) -> bool: ...
    def stop(self) -> None: ...
    def close(self) -> dict[str, Any]: ...
    def __enter__(self) -> ChunkExecutor: ...
    def __exit__(self, kind: Any, value: Any, traceback: Any) -> bool: ...

def chunk_commands(
    start: ArrayLike,
    chunks: list[tuple[float, float, ArrayLike]],
    rate: float = 50.0,
    arm: str = "fr3",
    stall_timeout: float = 0.25,
    max_gap: float = 0.2,
    max_duration: float = 300.0,
) -> dict[str, np.ndarray]: ...

class Franka:
    """A Franka robot (FR3, or a Panda on a protocol-10 system) over the Franka Control
    Interface. Each call connects, works and disconnects; with ``scene`` (a scene file whose
    robot is the arm) every command is checked against its obstacles too."""
    def __init__(self, host: str, arm: str = "fr3", realtime: str = "enforce", scene: Optional[str] = None) -> None: ...
    @property
    def host(self) -> str: ...
    @property
    def last_recording(self) -> Optional[dict[str, Any]]: ...
    def state(self) -> dict[str, Any]: ...
    def execute(self, t: ArrayLike, q: ArrayLike, *, retime: bool = False, approach: bool = False) -> dict[str, Any]: ...
    def record(self, duration: float) -> dict[str, Any]: ...
    def guide(self, duration: float, *, damping: float | None = ...) -> dict[str, Any]: ...
    def contact(
        self,
        waypoints: ArrayLike,
        *,
        above: Sequence[float],
        direction: Sequence[float] = (0.0, 0.0, -1.0),
        search: float = 0.15,
        speed: float = 0.03,
        detect: float = 3.0,
        ceiling: float = 30.0,
        retreat: float = 0.05,
        error_gain: float = 0.2,
        stiffness: tuple[float, float] = (2000.0, 150.0),
        force_gains: tuple[float, float, float] = (0.2, 5.0, 30.0),
        drive: str = "link",
    ) -> dict[str, Any]: ...
    def impedance(
        self,
        t: ArrayLike,
        positions: ArrayLike,
        *,
        stiffness: tuple[float, float] = (2000.0, 150.0),
        drive: str = "link",
    ) -> dict[str, Any]: ...
    def gripper(
        self,
        action: str,
        width: Optional[float] = None,
        *,
        speed: float = 0.05,
        force: float = 20.0,
        epsilon: float = 0.005,
    ) -> dict[str, Any]: ...

class Robot:
    """A serial robot arm with its tool point."""
    def __init__(
        self,
        robot: Optional[str] = None,
        *,
        tool: Optional[str] = None,
        tip: Optional[str] = None,
        scene: Optional[Union[str, os.PathLike[str]]] = None,
        margin: Optional[float] = None,
    ) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def margin(self) -> Optional[float]: ...
    def distances(self, q: ArrayLike, *, within: float = 0.1) -> list[tuple[str, str, float]]: ...
    def collide(self, t: ArrayLike, q: ArrayLike, *, rate: float = 1000.0) -> dict[str, Any]: ...
    def plan(
        self,
        start: ArrayLike,
        goal: Optional[ArrayLike] = None,
        *,
        goal_pose: Optional[ArrayLike] = None,
        seed: int = 1,
        samples: int = 20000,
        share: float = 0.5,
    ) -> dict[str, Any]: ...
    def join(
        self,
        movements: list[tuple[ArrayLike, ArrayLike]],
        *,
        start: Optional[ArrayLike] = None,
        seed: int = 1,
        samples: int = 20000,
        share: float = 0.5,
    ) -> dict[str, Any]: ...
    @property
    def dof(self) -> int: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def tool(self) -> str: ...
    @property
    def ready(self) -> F64: ...
    @property
    def limits(self) -> Optional[tuple[F64, F64]]: ...
    @property
    def velocity_limits(self) -> Optional[F64]: ...
    def within_limits(self, q: ArrayLike) -> Union[bool, npt.NDArray[np.bool_]]: ...
    def fk(self, q: ArrayLike) -> F64: ...
    def pose(self, q: ArrayLike) -> F64: ...
    def jacobian(self, q: ArrayLike) -> F64: ...
    def ik(
        self,
        target: ArrayLike,
        q0: Optional[ArrayLike] = None,
        *,
        tolerance: float = 1e-9,
        restarts: int = 300,
        seed: int = 0,
    ) -> F64: ...
    def inverse_dynamics(
        self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, *, gravity: Optional[ArrayLike] = None
    ) -> F64: ...
    def forward_dynamics(
        self,
        q: ArrayLike,
        qd: ArrayLike,
        tau: ArrayLike,
        *,
        gravity: Optional[ArrayLike] = None,
        armature: Optional[ArrayLike] = None,
    ) -> F64: ...
    def check_limits(self, t: ArrayLike, q: ArrayLike, *, rate: float = 1000.0) -> dict[str, Any]: ...
    def retime(
        self, t: ArrayLike, q: ArrayLike, *, mode: Literal["fastest", "uniform"] = "fastest", rate: float = 1000.0
    ) -> dict[str, Any]: ...
    def export(
        self,
        t: ArrayLike,
        q: ArrayLike,
        path: Union[str, os.PathLike[str]],
        *,
        format: Literal["ros2-yaml", "mcap", "csv-1khz"],
        period: float = 0.01,
        force: bool = False,
    ) -> dict[str, Any]: ...
    def describe(self) -> str: ...


class ProMP:
    """A probabilistic movement primitive: a Gaussian over basis weights."""

    @staticmethod
    def fit(
        demos: Sequence[tuple[ArrayLike, ArrayLike]], *, bases: int = 20, duration: Optional[float] = None
    ) -> ProMP: ...
    @property
    def dims(self) -> int: ...
    @property
    def bases(self) -> int: ...
    @property
    def duration(self) -> float: ...
    @property
    def weight_mean(self) -> F64: ...
    @property
    def weight_cov(self) -> F64: ...
    def features(self, t: float) -> tuple[F64, F64]: ...
    def mean(self, t: ArrayLike) -> tuple[F64, F64]: ...
    def std(self, t: ArrayLike) -> tuple[F64, F64]: ...
    def condition(
        self,
        time: Optional[float] = None,
        position: Optional[ArrayLike] = None,
        std: float = 0.0,
        *,
        velocity: Optional[ArrayLike] = None,
        velocity_std: float = 0.0,
        points: Optional[Sequence[tuple[float, ArrayLike, float]]] = None,
    ) -> ProMP: ...
    def sample(self, n: int, t: ArrayLike, *, seed: int = 0) -> F64: ...
    def search_start(self) -> tuple[F64, float, F64]: ...
    @staticmethod
    def blend(
        promps: Sequence[ProMP], activations: Sequence[ArrayLike], t: ArrayLike
    ) -> tuple[F64, F64]: ...
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str) -> ProMP: ...
    def save(self, path: PathLike, *, force: bool = False) -> None: ...
    @staticmethod
    def load(path: PathLike) -> ProMP: ...

def _ros2_send(
    t: ArrayLike,
    q: ArrayLike,
    controller: str,
    *,
    via: str = "action",
    robot: str = "panda",
    joint_names: Optional[Sequence[str]] = None,
    domain: Optional[int] = None,
    period: float = 0.01,
    wait: float = 10.0,
    service_mapping: str = "auto",
    scene: Optional[str] = None,
) -> dict[str, Any]: ...
def _lerobot_show(path: str) -> dict[str, Any]: ...
def _lerobot_demos(
    path: str,
    episodes: Optional[list[int]] = None,
    feature: str = "observation.state",
    robot: Optional[str] = None,
    columns: Optional[list[str]] = None,
) -> tuple[list[str], list[tuple[F64, F64]]]: ...
def _lerobot_write(
    out: str, recordings: list[str], robot: str, task: str, fps: Optional[int] = None, force: bool = False
) -> dict[str, Any]: ...
def _lerobot_write_arrays(
    out: str,
    episodes: list[dict[str, F64]],
    names: dict[str, list[str]],
    fps: int,
    tasks: list[str],
    robot_type: Optional[str] = None,
) -> None: ...
def _ros2_graph(*, domain: Optional[int] = None, seconds: float = 2.0) -> dict[str, Any]: ...
def _ros2_record(
    duration: float,
    *,
    topic: str = "/joint_states",
    robot: str = "panda",
    joint_names: Optional[Sequence[str]] = None,
    domain: Optional[int] = None,
    wait: float = 10.0,
    best_effort: bool = False,
) -> dict[str, Any]: ...
