"""LeRobot robots on cps's chunk executor.

LeRobot's scripts call `send_action` once per step (30 Hz, say) with joint positions, and
expect the arm to go there. Sent to a Franka as they are, such steps break its velocity,
acceleration and jerk limits at every step and trip its reflexes. Here each action
becomes a short chunk for cps's executor — the last actions at the caller's rate, the
newest due two steps from now — and the executor's 1 kHz loop follows the path they make
within every limit (the FCI's rules included), braking to rest when the actions stop.

What the arm measures each millisecond is read back for `get_observation`; when the robot
disconnects (LeRobot's scripts always do, also after an exception or Ctrl-C), the stream
is closed, the arm comes to rest, and cps's 1 kHz recording is written. The executor runs
in a process of its own (`process.py`); a Franka Hand, when fitted, in a thread of its own
(`hand.py`).
"""

from __future__ import annotations

import logging
import math
import time
from datetime import datetime, timezone
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

import cps
from lerobot.cameras import make_cameras_from_configs
from lerobot.robots import Robot
from lerobot.utils.errors import DeviceAlreadyConnectedError, DeviceNotConnectedError

from .config import CpsDynamicsConfig, CpsFrankaConfig, CpsRobotConfig
from .hand import Hand
from .process import LoopProcess

logger = logging.getLogger(__name__)

JOINTS = 7
# The tool pose's entries (m; the rotation's unit quaternion, qw >= 0), as cps.Robot.pose gives them.
TOOL = ("x", "y", "z", "qx", "qy", "qz", "qw")
# The caller's action rate assumed until two calls have measured it (LeRobot's default fps).
DEFAULT_RATE = 30.0
# Steps from a call of send_action to the time its action is due (see send_action).
LEAD = 2
# The acceleration an approach is planned with, at approach_share (rad/s^2: the FR3's limit).
APPROACH_ACCELERATION = 10.0
# How long connect waits for the robot's loop to measure its first state.
FIRST_STATE_S = 10.0
# The hand's entry in actions and observations: the fingers' width (m).
GRIPPER = "gripper.pos"


class CpsRobot(Robot):
    """What `cps_franka` and `cps_dynamics` share (see the module's text)."""

    config_class = CpsRobotConfig
    name = "cps"

    def __init__(self, config: CpsRobotConfig):
        super().__init__(config)
        self.config = config
        self.model = cps.Robot(config.arm)
        self.cameras = make_cameras_from_configs(config.cameras)
        self._ex: LoopProcess | None = None
        self._hand: Hand | None = None
        # The loop ended by itself and was closed; disconnect closes what is left.
        self._over = False
        self._width = math.nan
        self._record: Path | None = None
        self.last_run: dict[str, Any] | None = None
        self.clock_start_unix = math.nan
        self._new_session()

    def _new_session(self) -> None:
        """What a session learns of the caller's actions, from nothing (each connect: the
        executor's clock starts again at 0)."""
        self._history: list[np.ndarray] = []
        self._last_call: float | None = None
        self._period = 1.0 / (self.config.action_rate or DEFAULT_RATE)
        self._observed = -math.inf
        self._due = -math.inf
        self._first = True
        self.not_followed = 0
        self.resumed_late = 0

    def _check_settings(self) -> None:
        """The plugin's own settings (cps checks the executor's when it starts)."""
        c = self.config
        if c.action_rate is not None and not (math.isfinite(c.action_rate) and c.action_rate > 0):
            raise ValueError(f"{self}: action_rate {c.action_rate} is not a number of actions per second")
        if not 0.0 < c.approach_share <= 1.0:
            raise ValueError(f"{self}: approach_share {c.approach_share} is not in (0, 1]")
        if self._fitted_hand():
            if not 0.0 < c.gripper_speed <= 0.1:
                raise ValueError(f"{self}: gripper_speed {c.gripper_speed} m/s is not in (0, 0.1]")
            if not 0.0 < c.gripper_force <= 140.0:
                raise ValueError(f"{self}: gripper_force {c.gripper_force} N is not in (0, 140]")

    def __str__(self) -> str:
        return self.name if self.id is None else f"{self.name} {self.id}"

    # -- what LeRobot reads of the robot -------------------------------------------------

    @cached_property
    def _joints(self) -> list[str]:
        return [f"joint{i + 1}" for i in range(JOINTS)]

    @cached_property
    def observation_features(self) -> dict[str, type | tuple]:
        c = self.config
        features: dict[str, type | tuple] = {f"{j}.pos": float for j in self._joints}
        if c.velocities:
            features.update({f"{j}.vel": float for j in self._joints})
        if c.efforts:
            features.update({f"{j}.effort": float for j in self._joints})
        if c.tool_pose:
            features.update({f"tool.{k}": float for k in TOOL})
        if self._fitted_hand():
            features[GRIPPER] = float
        for key, cam in c.cameras.items():
            features[key] = (cam.height, cam.width, 3)
        return features

    @cached_property
    def action_features(self) -> dict[str, type]:
        features = {f"{j}.pos": float for j in self._joints}
        if self._fitted_hand():
            features[GRIPPER] = float
        return features

    def _fitted_hand(self) -> bool:
        """Whether a hand takes `gripper.pos` (a Franka's, when configured)."""
        return False

    @cached_property
    def _range(self) -> tuple[np.ndarray, np.ndarray] | None:
        limits = self.model.limits
        return None if limits is None else (np.asarray(limits[0]), np.asarray(limits[1]))

    @property
    def is_connected(self) -> bool:
        return self._ex is not None and all(cam.is_connected for cam in self.cameras.values())

    @property
    def is_calibrated(self) -> bool:
        return True  # a Franka's joints are absolute: nothing to calibrate

    def calibrate(self) -> None:
        """Nothing to calibrate (a Franka's encoders are absolute)."""

    def configure(self) -> None:
        """Nothing to configure: the limits and the loop are cps's."""

    # -- the session ---------------------------------------------------------------------

    def _robot(self) -> dict[str, Any]:
        """Which robot `cps.ChunkExecutor` opens, with its own settings."""
        raise NotImplementedError

    def _executor(self, record: Path) -> LoopProcess:
        """cps's chunk executor, in a process of its own (see `process.py`)."""
        c = self.config
        return LoopProcess(dict(
            arm=c.arm, rate=1.0 / self._period, stall_timeout=c.stall_timeout, max_gap=c.max_step,
            idle_end=c.max_duration, max_duration=c.max_duration, record=str(record),
            limit_share=c.limit_share, scene=None if c.scene is None else str(c.scene), **self._robot(),
        ))

    def _record_path(self) -> Path:
        if self.config.record is not None:
            return Path(self.config.record)
        from lerobot.utils.constants import HF_LEROBOT_HOME

        stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S.%fZ")
        folder = Path(HF_LEROBOT_HOME) / "cps"
        folder.mkdir(parents=True, exist_ok=True)
        return folder / f"{self.name}-{stamp}.csv"

    def connect(self, calibrate: bool = True) -> None:
        if self._ex is not None:
            raise DeviceAlreadyConnectedError(f"{self} is already connected.")
        if self._over:
            self.disconnect()  # the cameras of a session whose loop ended by itself
        self._check_settings()
        self._new_session()
        self._record = self._record_path()
        self._ex = self._executor(self._record)
        try:
            deadline = time.monotonic() + FIRST_STATE_S
            while not math.isfinite(self._ex.observe()["t"]):
                if not self._ex.running:
                    raise self._ended()
                if time.monotonic() > deadline:
                    raise cps.CpsError(f"{self}: the robot's loop measured no state within {FIRST_STATE_S:.0f} s")
                time.sleep(0.002)
            if self._fitted_hand():
                self._hand = Hand(self.config.host, self.config.gripper_speed, self.config.gripper_force)
                self._width = self._hand.width
            for cam in self.cameras.values():
                cam.connect()
        except BaseException:
            self._close()
            raise
        # The executor's clock against the wall's, for matching cps's recording (its t) with
        # what happened around it.
        self.clock_start_unix = time.time() - self._ex.observe()["t"]
        logger.info(
            "%s connected; cps records the run at 1 kHz to %s (its clock started at unix time %.3f)",
            self, self._record, self.clock_start_unix,
        )

    def disconnect(self) -> None:
        """Ends the action stream: the arm follows the last action to its end and comes to
        rest (or, if it was stopped, is at rest already); cps's recording is written. Also
        after the robot's loop has ended by itself (a reflex, a lost connection, a command
        the scene refused), whose error the script has seen: then only the cameras are left
        to close (LeRobot's scripts disconnect in `finally`)."""
        if self._ex is None and not self._over:
            raise DeviceNotConnectedError(f"{self} is not connected.")
        self._over = False
        try:
            self._close()
        finally:
            for cam in self.cameras.values():
                if cam.is_connected:
                    cam.disconnect()
        logger.info("%s disconnected", self)

    def _close(self) -> dict[str, Any] | None:
        hand, self._hand = self._hand, None
        if hand is not None:
            hand.close()
        ex, self._ex = self._ex, None
        if ex is None:
            return None
        run = ex.close()
        self.last_run = run
        for line in run["lines"]:
            logger.info("cps: %s", line)
        logger.info("cps: %s; recording: %s", run["ending"], run["record"])
        return run

    def _ended(self) -> cps.CpsError:
        """The robot's loop ended by itself: close it (the recording is written) and say why."""
        run = self._close()
        self._over = True
        ending = run["ending"] if run else "the loop ended"
        where = run["record"] if run else None
        return cps.CpsError(f"{self}: the robot's loop ended: {ending} (the arm is at rest; recording: {where})")

    # -- observations and actions --------------------------------------------------------

    def get_observation(self) -> dict[str, Any]:
        if self._ex is None:
            raise DeviceNotConnectedError(f"{self} is not connected.")
        o = self._ex.observe()
        obs: dict[str, Any] = {f"{j}.pos": float(x) for j, x in zip(self._joints, o["q"])}
        c = self.config
        if c.velocities:
            obs.update({f"{j}.vel": float(x) for j, x in zip(self._joints, o["dq"])})
        if c.efforts:
            obs.update({f"{j}.effort": float(x) for j, x in zip(self._joints, o["tau"])})
        if c.tool_pose:
            pose = self.model.pose(o["q"])
            obs.update({f"tool.{k}": float(x) for k, x in zip(TOOL, pose)})
        if self._hand is not None:
            obs[GRIPPER] = self._hand.width
        for key, cam in self.cameras.items():
            obs[key] = cam.read_latest()
        return obs

    def _entry(self, action: dict[str, Any], key: str, what: str) -> float:
        """The action's number at `key`; a sentence naming it when missing or not a number."""
        if key not in action:
            raise ValueError(f"{self}: the action has no `{key}` (it needs {', '.join(self.action_features)})")
        try:
            x = float(action[key])
        except (TypeError, ValueError):
            raise ValueError(f"{self}: action `{key}` is {action[key]!r}, not {what}") from None
        if not math.isfinite(x):
            raise ValueError(f"{self}: action `{key}` is {x}, not {what}")
        return x

    def _targets(self, action: dict[str, Any]) -> np.ndarray:
        return np.array([self._entry(action, f"{j}.pos", "a joint position (rad)") for j in self._joints])

    def send_action(self, action: dict[str, Any]) -> dict[str, Any]:
        """Hands `action` (joint positions, rad) to the 1 kHz loop, due two steps from now
        (the path through the actions is smooth), and returns what the arm targets: the
        action within the joints' ranges, or, for an action not followed, where the arm is
        commanded to be. Not followed: one farther than `max_step` from the arm, and one
        that comes more than `stall_timeout` after the action before it (the arm has
        braked to rest; the next action at the caller's rhythm starts it again). With a
        hand, `gripper.pos` (m) goes to the hand's thread, and the width it will move to is
        returned."""
        if self._ex is None:
            raise DeviceNotConnectedError(f"{self} is not connected.")
        if not self._ex.running:
            raise self._ended()
        target = self._clip(self._targets(action))
        if self._hand is not None:
            self._width = self._hand.want(self._entry(action, GRIPPER, "the fingers' width (m)"))
        now = time.perf_counter()
        gap = math.inf if self._last_call is None else now - self._last_call
        self._last_call = now
        o = self._ex.observe()
        command = o["q_d"]
        if gap <= self.config.stall_timeout and self.config.action_rate is None:
            self._period += 0.2 * (max(gap, 1e-3) - self._period)
        if not self._first and gap > self.config.stall_timeout:
            # The stream had stopped (the arm braked to rest): a lone late action is not
            # followed — a client whose policy server died hands over what it had queued,
            # one action every few hundred milliseconds. Following starts again with the
            # next action that comes at the caller's rhythm, from where the arm rests.
            self._history.clear()
            self.resumed_late += 1
            return self._said(command)
        far = np.abs(target - command)
        if self._first and far.max() > self.config.max_step:
            self._first_far(target, command, far)
            return self._said(target)
        self._first = False
        if far.max() > self.config.max_step:
            self.not_followed += 1
            if self.not_followed in (1, 10, 100, 1000):
                j = int(far.argmax())
                logger.warning(
                    "%s: an action %.3f rad from the arm at %s (more than max_step %.3f) is not followed (%d so far)",
                    self, far[j], self._joints[j], self.config.max_step, self.not_followed,
                )
            return self._said(command)
        if not self._history:
            # From where the arm is commanded to be (its first target now at the latest).
            self._history = [command] * LEAD
        self._history = [*self._history[-3:], target]
        period = self._period
        # The newest action is due LEAD steps from now, the ones before it a step apart: the
        # arm is between the two before the newest, on a cubic whose tangents (Catmull-Rom's,
        # from the neighbours) are the same in the next chunk, so the path the chunks make
        # is smooth across them. Due one step after the action before it when the call came
        # on time (within half a step: the caller's sleep jitters, its actions do not).
        due = self._due + period
        if not abs(due - LEAD * period - o["t"]) < 0.5 * period:
            due = o["t"] + LEAD * period
        self._due = due
        observed = max(due - period * (len(self._history) - 1), self._observed)
        self._observed = observed
        try:
            self._ex.push(np.array(self._history), observed_at=observed, rate=1.0 / period)
        except cps.CpsError:
            if not self._ex.running:
                raise self._ended() from None
            raise
        return self._said(target)

    def _said(self, q: np.ndarray) -> dict[str, float]:
        said = {f"{j}.pos": float(x) for j, x in zip(self._joints, q)}
        if self._hand is not None:
            said[GRIPPER] = self._width
        return said

    def _clip(self, q: np.ndarray) -> np.ndarray:
        return q if self._range is None else np.clip(q, *self._range)

    def _first_far(self, target: np.ndarray, command: np.ndarray, far: np.ndarray) -> None:
        j = int(far.argmax())
        if not self.config.approach:
            raise ValueError(
                f"{self}: the first action is {far[j]:.3f} rad from the arm at {self._joints[j]} "
                f"(more than max_step {self.config.max_step}): move the arm near the episode's start, "
                "or pass --robot.approach=true to approach it within the limits"
            )
        share = self.config.approach_share
        vmax = np.asarray(self.model.velocity_limits) * share
        # A quintic from rest to rest (peak velocity 15/8 d/T, acceleration 5.77 d/T^2) at
        # the share of the velocity limits and of APPROACH_ACCELERATION; the executor keeps
        # the arm's own limits whatever the plan.
        seconds = max(
            float(np.max(15.0 / 8.0 * far / vmax)),
            float(np.sqrt(np.max(5.78 * far / (APPROACH_ACCELERATION * share)))),
            0.5,
        )
        rate = 50.0
        t0 = self._ex.observe()["t"]

        def path(t: float) -> np.ndarray:
            # The rest of the quintic from t, then its end held for a second.
            s = np.clip((t - t0 + np.arange(int((seconds + 1.0) * rate)) / rate) / seconds, 0.0, 1.0)[:, None]
            return command + (target - command) * (10 * s**3 - 15 * s**4 + 6 * s**5)

        logger.info("%s: approaching the first action (%.3f rad at %s) in %.1f s", self, far[j], self._joints[j], seconds)
        deadline = time.monotonic() + seconds + 10.0
        while True:
            if not self._ex.running:
                raise self._ended()
            # The path from now, again and again: the executor stalls (brakes) when no
            # chunk has come for its stall timeout, however long the last one is.
            now = self._ex.observe()["t"]
            self._ex.push(path(now), observed_at=now, rate=rate)
            # Arrived: the command at the target, at rest (the arm follows it by the
            # robot's own control).
            before = self._ex.observe()["q_d"]
            time.sleep(0.01)
            after = self._ex.observe()["q_d"]
            if np.abs(after - target).max() < 1e-4 and np.abs(after - before).max() < 1e-6:
                break
            if time.monotonic() > deadline:
                raise cps.CpsError(f"{self}: the approach did not arrive within {seconds + 10.0:.1f} s")
            time.sleep(min(0.04, self.config.stall_timeout / 3))
        self._first = False
        self._history = [target] * LEAD
        self._last_call = time.perf_counter()


class CpsFranka(CpsRobot):
    """A Franka over the Franka Control Interface, on cps's 1 kHz loop (`cps_franka`)."""

    config_class = CpsFrankaConfig
    name = "cps_franka"

    def _robot(self) -> dict[str, Any]:
        return {"robot": "franka", "host": self.config.host, "realtime": self.config.realtime}

    def _fitted_hand(self) -> bool:
        return self.config.gripper


class CpsDynamics(CpsRobot):
    """cps's simulated FR3 with its dynamics, in real time (`cps_dynamics`)."""

    config_class = CpsDynamicsConfig
    name = "cps_dynamics"

    def _robot(self) -> dict[str, Any]:
        return {"robot": "dynamics", "start": self.config.start}
