"""The settings LeRobot's scripts give a cps robot: each field is `--robot.<field>=…`.

Both robots share the execution's settings (`CpsRobotConfig`); `cps_franka` adds the
robot's address, `cps_dynamics` where the simulated arm starts. Every value is checked
once, by cps, when the robot connects: a wrong one stops the script there with a
sentence naming the field, before anything moves.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from lerobot.cameras import CameraConfig

# Every camera LeRobot ships for any robot, registered so that each can be named in a cps
# robot's --robot.cameras by every script (asynchronous inference's robot_client registers
# only opencv and realsense itself). None needs its driver until it is used.
from lerobot.cameras.opencv import OpenCVCameraConfig  # noqa: F401
from lerobot.cameras.realsense import RealSenseCameraConfig  # noqa: F401
from lerobot.cameras.zmq import ZMQCameraConfig  # noqa: F401
from lerobot.robots import RobotConfig


@dataclass(kw_only=True)
class CpsRobotConfig(RobotConfig):
    """What every cps robot takes (not a robot type of its own)."""

    # Which arm: fr3 (the Franka Research 3) or panda.
    arm: str = "fr3"
    # LeRobot's own cameras (`--robot.cameras="{front: {type: opencv, ...}}"`), read with
    # each observation: cps needs nothing of them.
    cameras: dict[str, CameraConfig] = field(default_factory=dict)
    # A scene file (cps's `configs/scenes/fr3.toml`, or one of yours) whose obstacles —
    # the table, a shelf — every command is checked against at 1 kHz, besides the arm
    # against itself: a command that would touch one is not sent, the arm brakes, and the
    # next call says why. Its robot must be the arm.
    scene: Path | None = None
    # The share of the arm's velocity, acceleration and jerk limits the 1 kHz loop may use,
    # in (0, 1].
    limit_share: float = 0.95
    # The farthest (rad, any joint) an action may be from where the arm is commanded to be:
    # a farther one is not followed (the arm goes on as before) and send_action returns
    # what the arm targets instead.
    max_step: float = 0.2
    # A first action farther than max_step from the arm: approached (true: the arm moves
    # there at approach_share of its limits before the first action returns) or refused
    # (false: send_action raises, nothing moves).
    approach: bool = False
    # The share of the limits an approach plans with, in (0, 1].
    approach_share: float = 0.3
    # Without a new action for this long (s), the arm brakes to rest where it is. An action
    # that comes later than this after the one before it is not followed (a client whose
    # policy server died hands over its queue so); the next one at the caller's rhythm
    # starts the arm again.
    stall_timeout: float = 0.25
    # The caller's actions per second; measured from the calls when not given.
    action_rate: float | None = None
    # Where cps's 1 kHz recording is written when the robot disconnects (its report and
    # the actions as chunks beside it). Default: $HF_LEROBOT_HOME/cps/<type>-<UTC time>.csv,
    # beside LeRobot's own datasets.
    record: Path | None = None
    # The longest session (s): the 1 kHz recording is made for it before the loop starts.
    max_duration: float = 900.0
    # What observations hold besides the joints' positions (<joint>.pos): their
    # velocities (<joint>.vel), their torques (<joint>.effort), the tool's pose (tool.x,
    # tool.y, tool.z in m; tool.qx, tool.qy, tool.qz, tool.qw).
    velocities: bool = True
    efforts: bool = True
    tool_pose: bool = True


@RobotConfig.register_subclass("cps_franka")
@dataclass(kw_only=True)
class CpsFrankaConfig(CpsRobotConfig):
    """A Franka (FR3, or a Panda on a protocol-10 system) over the Franka Control
    Interface, driven by cps's 1 kHz loop."""

    # The robot's address (its Control, e.g. 172.16.0.2).
    host: str
    # enforce (a realtime kernel is required, as libfranka's default) or ignore.
    realtime: str = "enforce"
    # A Franka Hand is fitted: actions and observations hold `gripper.pos`, the fingers'
    # width (m). A narrower width than the fingers' is grasped (held with gripper_force),
    # a wider one moved to; both at gripper_speed (m/s). The hand must have been homed
    # once since the robot started (`cps-cli franka gripper home --host …`).
    gripper: bool = False
    gripper_speed: float = 0.05
    gripper_force: float = 20.0


@RobotConfig.register_subclass("cps_dynamics")
@dataclass(kw_only=True)
class CpsDynamicsConfig(CpsRobotConfig):
    """cps's simulated FR3 with its dynamics (franky-sim's PD and drives) in real time: the
    same loop, limits and recording as on the arm, without one."""

    # Where the arm starts (7 joint positions, rad); default its ready pose.
    start: list[float] | None = None
