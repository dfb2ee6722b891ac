"""cps on a live ROS 2 graph, with no ROS installation: cps speaks DDS itself.

``send`` puts a joint trajectory on a ros2_control joint_trajectory_controller (its
FollowJointTrajectory action, or its ``joint_trajectory`` topic), checked against the
robot's limits first; ``record`` takes a robot's ``sensor_msgs/JointState`` in the robot
model's joint order; ``graph`` lists the nodes, topics, services and actions on the graph
and each participant's middleware. cps's node is on the graph as any ROS 2 node is, on
Fast DDS (ROS 2's default) and CycloneDDS alike. The DDS domain is ``domain``, else
``ROS_DOMAIN_ID``, else 0.

Example (a Panda's controller on the graph)::

    import numpy as np, cps.ros2
    t = np.linspace(0.0, 2.0, 201)
    q = np.tile([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], (201, 1))
    q[:, 0] = 0.2 * (0.5 - 0.5 * np.cos(np.pi * t / 2.0))
    cps.ros2.send(t, q, "/panda_arm_controller")["status"]   # 'succeeded'
    rec = cps.ros2.record(5.0)                                # 5 s of /joint_states
    rec["t"], rec["q"], rec["report"]["lost"]                 # (n,), (n, 7), 0
"""

from __future__ import annotations

from typing import Any, Optional, Sequence

from . import _cps

__all__ = ["send", "record", "graph"]


def send(
    t: Any,
    q: Any,
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
) -> dict:
    """Sends the joint trajectory ``q`` (shape (samples, joints), rad) at times ``t`` (s).

    It is checked against ``robot``'s limits and against the robot itself, and with
    ``scene`` (a scene file whose robot is ``robot``) against the scene's obstacles (a
    broken limit or a collision raises ``CpsError`` naming it, and nothing is sent), sampled every ``period`` s by a spline with
    velocities and accelerations, and sent to ``controller``: ``via="action"`` waits for
    the goal's result (Ctrl-C cancels the goal, then raises KeyboardInterrupt);
    ``via="topic"`` publishes on ``<controller>/joint_trajectory`` once the controller
    listens. Joint names are the robot's (``panda_joint1``…) unless ``joint_names``.
    The action's services speak the controller's middleware's request/reply mapping
    (``service_mapping="auto"``, told by discovery), or ``"cyclone"`` / ``"fastdds"``.

    Returns the answer: ``status``, ``succeeded``, ``error_code``, ``error_string``,
    ``feedback``, ``discovery_s``, ``points``, ``duration_s``, ``goal_id``… A controller
    that does not answer within ``wait`` s raises ``CpsError``.
    """
    names = list(joint_names) if joint_names is not None else None
    return _cps._ros2_send(
        t, q, controller, via=via, robot=robot, joint_names=names, domain=domain,
        period=period, wait=wait, service_mapping=service_mapping, scene=scene,
    )


def record(
    duration: float,
    *,
    topic: str = "/joint_states",
    robot: str = "panda",
    joint_names: Optional[Sequence[str]] = None,
    domain: Optional[int] = None,
    wait: float = 10.0,
    best_effort: bool = False,
) -> dict:
    """Records ``sensor_msgs/JointState`` on ``topic`` for ``duration`` s from the first
    message published after it began (waiting up to ``wait`` s for it); what a publisher
    hands over from before is dropped and counted (``report["older"]``).

    Returns ``t`` (samples,) from 0 (the messages' stamps, else their arrival), ``q``
    (samples, joints) in the robot model's order whatever order the messages use, ``dq``
    where every message carried velocities, ``joints``, and ``report`` (messages, lost,
    incomplete, malformed, the limit check). Ctrl-C raises KeyboardInterrupt.
    """
    names = list(joint_names) if joint_names is not None else None
    return _cps._ros2_record(
        duration, topic=topic, robot=robot, joint_names=names, domain=domain, wait=wait,
        best_effort=best_effort,
    )


def graph(*, domain: Optional[int] = None, seconds: float = 2.0) -> dict:
    """Watches the graph for ``seconds`` s and describes it, as ``cps-cli ros2 graph
    --json`` does: ``participants`` (``guid_prefix``, ``middleware``, ``nodes``),
    ``nodes``, and ``topics``, ``services``, ``actions`` by name, each with its ``types``
    and the ends (``node``, ``middleware``, ``reliability``, ``durability``) that publish
    and subscribe, or serve and call.
    """
    return _cps._ros2_graph(domain=domain, seconds=seconds)
