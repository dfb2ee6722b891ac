"""A ROS 2 peer in CycloneDDS (Eclipse's DDS, the one under rmw_cyclonedds), for cps's tests.

The ROS 2 types are declared here, from their .msg/.action definitions, as rmw names them
on the wire; services carry rmw_cyclonedds's request header (client id, sequence number).
Nothing of cps is imported. Modes:

  listen TOPIC OUT.json [--count N]   JointTrajectory messages received, written as JSON
  publish TOPIC --rate HZ --seconds S --joints a,b,c [--junk N] [--huge N]
                                      JointState at HZ (positions q_i = 0.1 i + sin(t + i),
                                      the joints shuffled and an extra one added; --junk
                                      malformed and --huge oversized samples interleaved);
                                      prints `sent K` when done
  serve ACTION OUT.json [--reject] [--abort] [--joint-states TOPIC] [--rate HZ]
        [--joints a,b,c --start q1,q2,q3] [--linger S]
                                      a FollowJointTrajectory server that plays each goal's
                                      trajectory in time (feedback at 50 Hz, joint states
                                      at HZ, from --start before the first goal), answers
                                      get_result at its end, honours cancel; leaves S s
                                      (default 1) after a goal ends with no new one; what
                                      it saw written as JSON at exit
  markers TOPIC OUT.json              one MarkerArray received (transient local), as JSON

Each mode prints `ready` when its entities exist and exits by itself.
"""

import json
import math
import random
import sys
import time
from dataclasses import dataclass, field

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

F64S = t.sequence[t.float64]


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32 = 0
    nanosec: t.uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class JointTrajectoryPoint(IdlStruct, typename="trajectory_msgs::msg::dds_::JointTrajectoryPoint_"):
    positions: F64S = field(default_factory=list)
    velocities: F64S = field(default_factory=list)
    accelerations: F64S = field(default_factory=list)
    effort: F64S = field(default_factory=list)
    time_from_start: Time = field(default_factory=Time)


@dataclass
class JointTrajectory(IdlStruct, typename="trajectory_msgs::msg::dds_::JointTrajectory_"):
    header: Header = field(default_factory=Header)
    joint_names: t.sequence[str] = field(default_factory=list)
    points: t.sequence[JointTrajectoryPoint] = field(default_factory=list)


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header = field(default_factory=Header)
    name: t.sequence[str] = field(default_factory=list)
    position: F64S = field(default_factory=list)
    velocity: F64S = field(default_factory=list)
    effort: F64S = field(default_factory=list)


@dataclass
class Junk(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    """Bytes under JointState's name: what a broken or hostile publisher sends."""
    data: t.sequence[t.uint8] = field(default_factory=list)


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0
    w: t.float64 = 1.0


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class MultiDOFJointTrajectoryPoint(IdlStruct, typename="trajectory_msgs::msg::dds_::MultiDOFJointTrajectoryPoint_"):
    transforms: t.sequence[Transform] = field(default_factory=list)
    velocities: t.sequence[Twist] = field(default_factory=list)
    accelerations: t.sequence[Twist] = field(default_factory=list)
    time_from_start: Time = field(default_factory=Time)


@dataclass
class MultiDOFJointTrajectory(IdlStruct, typename="trajectory_msgs::msg::dds_::MultiDOFJointTrajectory_"):
    header: Header = field(default_factory=Header)
    joint_names: t.sequence[str] = field(default_factory=list)
    points: t.sequence[MultiDOFJointTrajectoryPoint] = field(default_factory=list)


@dataclass
class JointTolerance(IdlStruct, typename="control_msgs::msg::dds_::JointTolerance_"):
    name: str = ""
    position: t.float64 = 0.0
    velocity: t.float64 = 0.0
    acceleration: t.float64 = 0.0


@dataclass
class JointComponentTolerance(IdlStruct, typename="control_msgs::msg::dds_::JointComponentTolerance_"):
    joint_name: str = ""
    component: t.uint16 = 0
    position: t.float64 = 0.0
    velocity: t.float64 = 0.0
    acceleration: t.float64 = 0.0


@dataclass
class Goal(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_Goal_"):
    trajectory: JointTrajectory = field(default_factory=JointTrajectory)
    multi_dof_trajectory: MultiDOFJointTrajectory = field(default_factory=MultiDOFJointTrajectory)
    path_tolerance: t.sequence[JointTolerance] = field(default_factory=list)
    component_path_tolerance: t.sequence[JointComponentTolerance] = field(default_factory=list)
    goal_tolerance: t.sequence[JointTolerance] = field(default_factory=list)
    component_goal_tolerance: t.sequence[JointComponentTolerance] = field(default_factory=list)
    goal_time_tolerance: Time = field(default_factory=Time)


UUID = t.array[t.uint8, 16]


@dataclass
class SendGoalRequest(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_SendGoal_Request_"):
    client: t.uint64 = 0
    seq: t.int64 = 0
    goal_id: UUID = field(default_factory=lambda: [0] * 16)
    goal: Goal = field(default_factory=Goal)


@dataclass
class SendGoalResponse(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_SendGoal_Response_"):
    client: t.uint64 = 0
    seq: t.int64 = 0
    accepted: bool = False
    stamp: Time = field(default_factory=Time)


@dataclass
class GetResultRequest(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_GetResult_Request_"):
    client: t.uint64 = 0
    seq: t.int64 = 0
    goal_id: UUID = field(default_factory=lambda: [0] * 16)


@dataclass
class GetResultResponse(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_GetResult_Response_"):
    client: t.uint64 = 0
    seq: t.int64 = 0
    status: t.int8 = 0
    error_code: t.int32 = 0
    error_string: str = ""


@dataclass
class GoalInfo(IdlStruct, typename="action_msgs::msg::dds_::GoalInfo_"):
    goal_id: UUID = field(default_factory=lambda: [0] * 16)
    stamp: Time = field(default_factory=Time)


@dataclass
class CancelRequest(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Request_"):
    client: t.uint64 = 0
    seq: t.int64 = 0
    goal_info: GoalInfo = field(default_factory=GoalInfo)


@dataclass
class CancelResponse(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Response_"):
    client: t.uint64 = 0
    seq: t.int64 = 0
    return_code: t.int8 = 0
    goals_canceling: t.sequence[GoalInfo] = field(default_factory=list)


@dataclass
class Feedback(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_Feedback_"):
    header: Header = field(default_factory=Header)
    joint_names: t.sequence[str] = field(default_factory=list)
    desired: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    actual: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    error: JointTrajectoryPoint = field(default_factory=JointTrajectoryPoint)
    index: t.int32 = 0
    multi_dof_joint_names: t.sequence[str] = field(default_factory=list)
    multi_dof_desired: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_actual: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_error: MultiDOFJointTrajectoryPoint = field(default_factory=MultiDOFJointTrajectoryPoint)
    multi_dof_index: t.int32 = 0


@dataclass
class FeedbackMessage(IdlStruct, typename="control_msgs::action::dds_::FollowJointTrajectory_FeedbackMessage_"):
    goal_id: UUID = field(default_factory=lambda: [0] * 16)
    feedback: Feedback = field(default_factory=Feedback)


@dataclass
class Marker(IdlStruct, typename="visualization_msgs::msg::dds_::Marker_"):
    header: Header = field(default_factory=Header)
    ns: str = ""
    id: t.int32 = 0
    type: t.int32 = 0
    action: t.int32 = 0
    position: t.array[t.float64, 3] = field(default_factory=lambda: [0.0] * 3)
    orientation: t.array[t.float64, 4] = field(default_factory=lambda: [0.0] * 4)
    scale: t.array[t.float64, 3] = field(default_factory=lambda: [0.0] * 3)
    color: t.array[t.float32, 4] = field(default_factory=lambda: [0.0] * 4)
    lifetime: Time = field(default_factory=Time)
    frame_locked: bool = False
    points: t.sequence[Vector3] = field(default_factory=list)
    colors: t.sequence[t.array[t.float32, 4]] = field(default_factory=list)
    texture_resource: str = ""
    texture_header: Header = field(default_factory=Header)
    texture_format: str = ""
    texture_data: t.sequence[t.uint8] = field(default_factory=list)
    uv_coordinates: t.sequence[t.array[t.float32, 2]] = field(default_factory=list)
    text: str = ""
    mesh_resource: str = ""
    mesh_filename: str = ""
    mesh_data: t.sequence[t.uint8] = field(default_factory=list)
    mesh_use_embedded_materials: bool = False


@dataclass
class MarkerArray(IdlStruct, typename="visualization_msgs::msg::dds_::MarkerArray_"):
    markers: t.sequence[Marker] = field(default_factory=list)


def qos(depth=100, latched=False):
    policies = [Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
                Policy.History.KeepLast(depth)]
    if latched:
        policies.append(Policy.Durability.TransientLocal)
    return Qos(*policies)


def topic_name(ros_name):
    return "rt" + ros_name


def point_json(p):
    return {"positions": list(p.positions), "velocities": list(p.velocities),
            "accelerations": list(p.accelerations), "effort": list(p.effort),
            "time_from_start": [p.time_from_start.sec, p.time_from_start.nanosec]}


def trajectory_json(m):
    return {"frame_id": m.header.frame_id, "stamp": [m.header.stamp.sec, m.header.stamp.nanosec],
            "joint_names": list(m.joint_names), "points": [point_json(p) for p in m.points]}


def take_valid(reader):
    return [s for s in reader.take(N=1000) if isinstance(s, IdlStruct)]


def arg(name, default=None):
    if name in sys.argv:
        return sys.argv[sys.argv.index(name) + 1]
    return default


def listen(dp, topic, out):
    count = int(arg("--count", "1"))
    r = DataReader(dp, Topic(dp, topic_name(topic), JointTrajectory), qos=qos())
    print("ready", flush=True)
    got, end = [], time.time() + 30
    while len(got) < count and time.time() < end:
        got += [trajectory_json(m) for m in take_valid(r)]
        time.sleep(0.002)
    json.dump({"messages": got, "received_at": time.time()}, open(out, "w"))


def positions(i, tt):
    return 0.1 * i + math.sin(tt + i)


def publish(dp, topic):
    rate, seconds = float(arg("--rate")), float(arg("--seconds"))
    joints = arg("--joints").split(",")
    junk, huge = int(arg("--junk", "0")), int(arg("--huge", "0"))
    w = DataWriter(dp, Topic(dp, topic_name(topic), JointState), qos=qos(depth=int(rate * seconds) + 10))
    wj = DataWriter(dp, Topic(dp, topic_name(topic), Junk), qos=qos()) if junk or huge else None
    print("ready", flush=True)
    # Wait for cps's reader (at most 20 s).
    end = time.time() + 20
    while w.get_matched_subscriptions() == [] and time.time() < end:
        time.sleep(0.01)
    time.sleep(0.2)
    rng = random.Random(7)
    order = list(range(len(joints)))
    n = int(round(rate * seconds))
    t0 = time.time()
    bad_every = n // (junk + huge + 1) if (junk or huge) else 0
    junk_left, huge_left = junk, huge
    for k in range(n):
        tt = k / rate
        rng.shuffle(order)
        names = [joints[i] for i in order] + ["gripper_finger"]
        pos = [positions(i, tt) for i in order] + [0.04]
        vel = [math.cos(tt + i) for i in order] + [0.0]
        stamp_ns = 1_700_000_000_000_000_000 + k * int(1e9 / rate)
        w.write(JointState(header=Header(stamp=Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)),
                           name=names, position=pos, velocity=vel, effort=[]))
        if bad_every and k % bad_every == bad_every // 2:
            if junk_left:
                junk_left -= 1
                wj.write(Junk(data=[0xff] * 64))
            elif huge_left:
                huge_left -= 1
                wj.write(Junk(data=bytes(17 << 20)))
        # Hold the rate against the wall clock, not the loop's own time.
        ahead = t0 + (k + 1) / rate - time.time()
        if ahead > 0:
            time.sleep(ahead)
    time.sleep(0.5)
    print(f"sent {n} in {time.time() - t0:.3f} s", flush=True)


def sample_at(points, tt):
    """Linear interpolation of the goal's positions at time tt (s)."""
    times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in points]
    if tt <= times[0]:
        return list(points[0].positions)
    for a in range(len(times) - 1):
        if times[a] <= tt <= times[a + 1]:
            s = (tt - times[a]) / (times[a + 1] - times[a])
            return [x + s * (y - x) for x, y in zip(points[a].positions, points[a + 1].positions)]
    return list(points[-1].positions)


def serve(dp, action, out):
    a = action + "/_action/"
    rq = lambda s, T: DataReader(dp, Topic(dp, "rq" + a + s + "Request", T), qos=qos())
    rr = lambda s, T: DataWriter(dp, Topic(dp, "rr" + a + s + "Reply", T), qos=qos())
    goal_rq, goal_rr = rq("send_goal", SendGoalRequest), rr("send_goal", SendGoalResponse)
    res_rq, res_rr = rq("get_result", GetResultRequest), rr("get_result", GetResultResponse)
    can_rq, can_rr = rq("cancel_goal", CancelRequest), rr("cancel_goal", CancelResponse)
    fb = DataWriter(dp, Topic(dp, "rt" + a + "feedback", FeedbackMessage), qos=qos())
    js_topic = arg("--joint-states")
    js = DataWriter(dp, Topic(dp, topic_name(js_topic), JointState), qos=qos(depth=1000)) if js_topic else None
    rate = float(arg("--rate", "100"))
    linger = float(arg("--linger", "1.0"))
    names = arg("--joints").split(",") if arg("--joints") else None
    current = [float(x) for x in arg("--start").split(",")] if arg("--start") else None
    print("ready", flush=True)
    seen = {"goals": [], "cancels": [], "result_requests": 0, "feedback_sent": 0, "results": []}
    goal, started, result_waiting, ended = None, None, [], None
    last_fb, last_js, k_js = 0.0, 0.0, 0
    deadline = time.time() + 60
    while time.time() < deadline:
        now = time.time()
        for req in take_valid(goal_rq):
            traj = req.goal.trajectory
            seen["goals"].append({"goal_id": list(req.goal_id), "trajectory": trajectory_json(traj),
                                  "goal_time_tolerance": [req.goal.goal_time_tolerance.sec, req.goal.goal_time_tolerance.nanosec]})
            accept = "--reject" not in sys.argv
            now_ns = int(now * 1e9)
            goal_rr.write(SendGoalResponse(client=req.client, seq=req.seq, accepted=accept,
                                           stamp=Time(sec=now_ns // 10**9, nanosec=now_ns % 10**9)))
            if accept:
                goal, started, ended = req, now, None
                deadline = max(deadline, now + 60)
                if names is None:
                    names = list(traj.joint_names)
                elif list(traj.joint_names) != names:
                    order = [list(traj.joint_names).index(n) for n in names]
                    for p in traj.points:
                        p.positions = [p.positions[i] for i in order]
        for req in take_valid(res_rq):
            seen["result_requests"] += 1
            result_waiting.append(req)
        for req in take_valid(can_rq):
            seen["cancels"].append(list(req.goal_info.goal_id))
            known = goal is not None and list(req.goal_info.goal_id) == list(goal.goal_id) and ended is None
            can_rr.write(CancelResponse(client=req.client, seq=req.seq, return_code=0 if known else 2,
                                        goals_canceling=[GoalInfo(goal_id=list(goal.goal_id))] if known else []))
            if known:
                ended = (5, 0, "canceled by the client")
        if goal is not None and ended is None:
            pts = goal.goal.trajectory.points
            tt = now - started
            current = sample_at(pts, tt)
            end_t = pts[-1].time_from_start.sec + pts[-1].time_from_start.nanosec * 1e-9
            if "--abort" in sys.argv and tt > 0.5 * end_t:
                ended = (6, -4, "path tolerance violated at joint panda_joint2 (test server)")
            elif tt >= end_t:
                ended = (4, 0, "")
            if now - last_fb >= 0.02:
                last_fb = now
                p = JointTrajectoryPoint(positions=current)
                fb.write(FeedbackMessage(goal_id=list(goal.goal_id), feedback=Feedback(
                    joint_names=list(goal.goal.trajectory.joint_names), desired=p, actual=p,
                    error=JointTrajectoryPoint(positions=[0.0] * len(current)))))
                seen["feedback_sent"] += 1
        if js is not None and current is not None and now - last_js >= 1.0 / rate:
            last_js = now
            stamp_ns = int(now * 1e9)
            js.write(JointState(header=Header(stamp=Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)),
                                name=names, position=current, velocity=[], effort=[]))
            k_js += 1
        if ended is not None and goal is not None:
            for req in [r for r in result_waiting if list(r.goal_id) == list(goal.goal_id)]:
                res_rr.write(GetResultResponse(client=req.client, seq=req.seq, status=ended[0],
                                               error_code=ended[1], error_string=ended[2]))
                result_waiting.remove(req)
                seen["result"] = list(ended)
                seen["results"].append(list(ended))
                seen["joint_states_sent"] = k_js
                # Keep publishing the final state a moment, then leave (unless a new
                # goal comes).
                deadline = min(deadline, time.time() + linger)
        if seen["goals"] and "--reject" in sys.argv:
            deadline = min(deadline, time.time() + 1.0)
        time.sleep(0.001)
    json.dump(seen, open(out, "w"))


def markers(dp, topic, out):
    r = DataReader(dp, Topic(dp, topic_name(topic), MarkerArray), qos=qos(depth=1, latched=True))
    print("ready", flush=True)
    end = time.time() + 30
    while time.time() < end:
        for m in take_valid(r):
            json.dump([{"ns": k.ns, "id": k.id, "type": k.type, "frame_id": k.header.frame_id,
                        "position": list(k.position), "orientation": list(k.orientation),
                        "color": list(k.color), "text": k.text,
                        "points": [[p.x, p.y, p.z] for p in k.points]} for k in m.markers], open(out, "w"))
            return
        time.sleep(0.005)


def main():
    mode = sys.argv[1]
    dp = DomainParticipant(int(arg("--domain", "0")))
    if mode == "listen":
        listen(dp, sys.argv[2], sys.argv[3])
    elif mode == "publish":
        publish(dp, sys.argv[2])
    elif mode == "serve":
        serve(dp, sys.argv[2], sys.argv[3])
    elif mode == "markers":
        markers(dp, sys.argv[2], sys.argv[3])
    else:
        sys.exit(f"unknown mode {mode}")


if __name__ == "__main__":
    main()
