"""A real ROS 2 node for cps's tests: rclpy (ROS 2 Jazzy, from the Python package index's
binary wheels) on the middleware RMW_IMPLEMENTATION names (rmw_fastrtps_cpp, ROS 2's
default). Nothing of cps is imported; what rclpy sees and receives is printed as JSON.

Modes (each prints `ready` once its node exists, then works as below):

  graph NODE        reads commands on stdin, one a line:
                      wait S     until NODE (a node name) is on the graph, at most S s,
                                 then a snapshot
                      gone S     until NODE is no longer on the graph, at most S s, then
                                 a snapshot
                      snapshot   the graph as rclpy's graph API gives it, one JSON line:
                                 nodes, and NODE's publishers, subscribers, services,
                                 clients and action clients, and, for each of NODE's
                                 topics, the node names rclpy gives its endpoints
                      quit
  serve DELAY       a node with the parameter `answer` = 42 (so its built-in
                    rcl_interfaces parameter services have something to give) and a
                    test_msgs/action/Fibonacci server at /fibonacci: a goal of order n < 0
                    is rejected; otherwise the sequence 0, 1, 1, 2, … grows one number
                    every DELAY s, each step sent as feedback, until it holds n + 1
                    numbers (succeeded) or a cancel comes (canceled, with what it had);
                    what it saw is printed as JSON lines (`goal`, `cancel`, `end`); runs
                    until `quit` on stdin
  states RATE SECONDS DEPTH [latched]
                    sensor_msgs/JointState on /joint_states (reliable, keep-last DEPTH,
                    volatile or, with `latched`, transient-local)
                    at RATE Hz for SECONDS s: joints panda_joint1..7, q_i = 0.1 i +
                    sin(t + i), header stamps from the node's clock; then prints
                    `{"sent": K}`
  listen TOPIC      the first trajectory_msgs/JointTrajectory on TOPIC (reliable), printed
                    as one JSON line: joint_names, points (positions, velocities,
                    accelerations, effort, time_from_start [sec, nanosec]) and
                    `received_ns`, when it came (this machine's clock)
  fjt ACTION DIR    a control_msgs/action/FollowJointTrajectory server (control_msgs built
                    by tests/control_msgs/build) at ACTION that plays each goal in time:
                    a feedback at each point (desired = actual = the point) and a
                    sensor_msgs/JointState of it on /joint_states (reliable, keep-last
                    100), then succeeded (error_code 0), or canceled when asked; a goal
                    without joint names is rejected. Goal k's trajectory is written to DIR/goal-k.json
                    (as `listen` prints one) and `{"goal": k, "points": n}` printed (a pipe
                    would hold a long goal's JSON and block the callback); each end is
                    printed as `{"end": status}`; runs until `quit` on stdin
  markers TOPIC     the first visualization_msgs/MarkerArray on TOPIC (transient-local,
                    so one published before this subscribed still comes), as one JSON
                    line: its markers' ns, id, type, frame_id and points

rclpy's own figures for the work cps's benchmark (tests/numbers.rs) measures, the same
way:

  send TOPIC        publishes tests/support's 10 s trajectory at 100 Hz (1001 points,
                    reliable, keep-last 1) once a subscriber has matched, and prints
                    `{"started_ns": …, "matched_s": …}`: when this process began (before
                    rclpy.init) and how long until the subscriber matched
  count             counts sensor_msgs/JointState on /joint_states (reliable, keep-last
                    5000) until `quit` on stdin, then prints `{"received": K}`
  goals ACTION      a FollowJointTrajectory client: six one-point goals (sent → accepted
                    → result; the first includes discovery), then a 10 s goal cancelled
                    after 1.5 s; prints `{"trips_ms": [...], "cancel_ms": …}`, the last
                    the time from asking the cancel to the goal's end
"""

import json
import math
import os
import sys
import time

import rclpy
import rclpy.action
from rclpy.node import Node


def snapshot(node, name):
    nodes = sorted(f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces())
    out = {"rmw": rclpy.get_rmw_implementation_identifier(), "nodes": nodes}
    ns = next((ns for n, ns in node.get_node_names_and_namespaces() if n == name), None)
    if ns is None:
        return out
    by_node = {
        "publishers": node.get_publisher_names_and_types_by_node,
        "subscribers": node.get_subscriber_names_and_types_by_node,
        "services": node.get_service_names_and_types_by_node,
        "clients": node.get_client_names_and_types_by_node,
    }
    for key, f in by_node.items():
        out[key] = {t: types for t, types in f(name, ns)}
    out["action_clients"] = {
        t: types for t, types in rclpy.action.get_action_client_names_and_types_by_node(node, name, ns)
    }
    endpoints = {}
    for topic in list(out["publishers"]) + list(out["subscribers"]):
        infos = node.get_publishers_info_by_topic(topic) + node.get_subscriptions_info_by_topic(topic)
        endpoints[topic] = sorted(
            {f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in infos}
        )
    out["endpoint_nodes"] = endpoints
    return out


def listed(node, name):
    return any(n == name for n, _ in node.get_node_names_and_namespaces())


def graph(node, name):
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        if words[0] == "quit":
            return
        if words[0] in ("wait", "gone"):
            want = words[0] == "wait"
            end = time.monotonic() + float(words[1])
            while listed(node, name) != want and time.monotonic() < end:
                time.sleep(0.02)
            # The node's endpoints may be announced a moment after the node itself.
            time.sleep(0.3)
        print(json.dumps(snapshot(node, name)), flush=True)


def serve_until_quit(node):
    """Spins `node` on four threads, says `ready`, and exits when stdin says `quit`."""
    import threading

    from rclpy.executors import MultiThreadedExecutor

    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    print("ready", flush=True)
    for line in sys.stdin:
        if line.strip() == "quit":
            break
    # Out at once: an executor's shutdown waits for its callbacks, and a callback may be
    # stuck in rclpy; what the server saw is already printed.
    sys.stdout.flush()
    os._exit(0)


def say(**what):
    print(json.dumps(what), flush=True)


def serve(node, delay):
    from rclpy.action import ActionServer, CancelResponse, GoalResponse
    from rclpy.callback_groups import ReentrantCallbackGroup
    from test_msgs.action import Fibonacci

    node.declare_parameter("answer", 42)

    def on_goal(request):
        say(event="goal", order=request.order)
        return GoalResponse.REJECT if request.order < 0 else GoalResponse.ACCEPT

    def on_cancel(_handle):
        say(event="cancel")
        return CancelResponse.ACCEPT

    def execute(handle):
        sequence = [0, 1][: handle.request.order + 1]
        while len(sequence) < handle.request.order + 1:
            if handle.is_cancel_requested:
                handle.canceled()
                say(event="end", status="canceled", length=len(sequence))
                return Fibonacci.Result(sequence=sequence)
            time.sleep(delay)
            sequence.append(sequence[-1] + sequence[-2])
            handle.publish_feedback(Fibonacci.Feedback(sequence=sequence))
        handle.succeed()
        say(event="end", status="succeeded", length=len(sequence))
        return Fibonacci.Result(sequence=sequence)

    ActionServer(
        node,
        Fibonacci,
        "/fibonacci",
        execute_callback=execute,
        goal_callback=on_goal,
        cancel_callback=on_cancel,
        callback_group=ReentrantCallbackGroup(),
    )
    serve_until_quit(node)


def states(node, rate, seconds, depth, latched):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    durability = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
    qos = QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE, durability=durability)
    pub = node.create_publisher(JointState, "/joint_states", qos)
    print("ready", flush=True)
    names = [f"panda_joint{i}" for i in range(1, 8)]
    start = time.monotonic()
    sent = 0
    while True:
        due = start + sent / rate
        if due - start >= seconds:
            break
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        t = sent / rate
        m = JointState()
        m.header.stamp = node.get_clock().now().to_msg()
        m.name = names
        m.position = [0.1 * i + math.sin(t + i) for i in range(7)]
        pub.publish(m)
        sent += 1
    print(json.dumps({"sent": sent}), flush=True)
    # Stay until the reader has had everything (reliable delivery), then leave.
    for line in sys.stdin:
        if line.strip() == "quit":
            break


def first_message(node, msg_type, topic, qos):
    got = []
    node.create_subscription(msg_type, topic, lambda m: got.append((m, time.time_ns())), qos)
    print("ready", flush=True)
    while not got:
        rclpy.spin_once(node, timeout_sec=0.1)
    return got[0]


def trajectory_json(m):
    point = lambda p: {
        "positions": list(p.positions), "velocities": list(p.velocities),
        "accelerations": list(p.accelerations), "effort": list(p.effort),
        "time_from_start": [p.time_from_start.sec, p.time_from_start.nanosec],
    }
    return {"joint_names": list(m.joint_names), "points": [point(p) for p in m.points]}


def fjt(node, action, out_dir):
    from pathlib import Path

    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionServer, CancelResponse, GoalResponse
    from rclpy.callback_groups import ReentrantCallbackGroup

    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    states = node.create_publisher(
        JointState, "/joint_states", QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    )
    goals = []

    def on_goal(request):
        goals.append(1)
        k = len(goals)
        with open(Path(out_dir) / f"goal-{k}.json", "w") as f:
            json.dump(trajectory_json(request.trajectory), f)
        say(goal=k, points=len(request.trajectory.points))
        if not request.trajectory.joint_names:
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def execute(handle):
        t = handle.request.trajectory
        start = time.monotonic()
        for p in t.points:
            due = start + p.time_from_start.sec + p.time_from_start.nanosec * 1e-9
            while time.monotonic() < due:
                if handle.is_cancel_requested:
                    handle.canceled()
                    say(end="canceled")
                    return FollowJointTrajectory.Result()
                time.sleep(min(0.002, max(0.0, due - time.monotonic())))
            f = FollowJointTrajectory.Feedback()
            f.header.stamp = node.get_clock().now().to_msg()
            f.joint_names = list(t.joint_names)
            f.desired = p
            f.actual = p
            handle.publish_feedback(f)
            state = JointState()
            state.header.stamp = f.header.stamp
            state.name = list(t.joint_names)
            state.position = list(p.positions)
            states.publish(state)
        handle.succeed()
        say(end="succeeded")
        return FollowJointTrajectory.Result(error_code=0, error_string="")

    ActionServer(node, FollowJointTrajectory, action, execute_callback=execute,
                 goal_callback=on_goal, cancel_callback=lambda _h: CancelResponse.ACCEPT,
                 callback_group=ReentrantCallbackGroup())
    serve_until_quit(node)


def listen(node, topic):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from trajectory_msgs.msg import JointTrajectory

    m, at = first_message(
        node, JointTrajectory, topic, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    )
    say(**trajectory_json(m), received_ns=at)


def markers(node, topic):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from visualization_msgs.msg import MarkerArray

    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    m, _ = first_message(node, MarkerArray, topic, qos)
    say(markers=[{"ns": k.ns, "id": k.id, "type": k.type, "frame_id": k.header.frame_id,
                  "points": [[p.x, p.y, p.z] for p in k.points]} for k in m.markers])


def support_trajectory(seconds, rate):
    """tests/support's `trajectory`, number for number."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    m = JointTrajectory()
    m.joint_names = [f"panda_joint{i}" for i in range(1, 8)]
    step_ns = round(1e9 / rate)
    for k in range(round(seconds * rate) + 1):
        t = k / rate
        p = JointTrajectoryPoint()
        p.positions = [0.1 * i + 0.3 * math.sin(t + i) for i in range(7)]
        p.velocities = [0.3 * math.cos(t + i) for i in range(7)]
        p.accelerations = [-0.3 * math.sin(t + i) for i in range(7)]
        ns = k * step_ns
        p.time_from_start = Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        m.points.append(p)
    return m


def send(node, topic):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from trajectory_msgs.msg import JointTrajectory

    pub = node.create_publisher(
        JointTrajectory, topic, QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
    )
    m = support_trajectory(10.0, 100.0)
    began = time.monotonic()
    while pub.get_subscription_count() == 0:
        time.sleep(0.001)
    matched = time.monotonic() - began
    pub.publish(m)
    say(started_ns=STARTED_NS, matched_s=matched)
    # Stay until the subscriber has it (reliable delivery), then leave.
    for line in sys.stdin:
        if line.strip() == "quit":
            break


def count(node):
    import threading

    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    received = [0]

    def on_state(_m):
        received[0] += 1

    qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(JointState, "/joint_states", on_state, qos)
    done = threading.Event()

    def wait_quit():
        for line in sys.stdin:
            if line.strip() == "quit":
                break
        done.set()

    threading.Thread(target=wait_quit, daemon=True).start()
    while not done.is_set():
        rclpy.spin_once(node, timeout_sec=0.05)
    say(received=received[0])


def goals(node, action):
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient

    client = ActionClient(node, FollowJointTrajectory, action)

    def until(future):
        while not future.done():
            rclpy.spin_once(node, timeout_sec=0.01)
        return future.result()

    client.wait_for_server()
    trips = []
    goal = FollowJointTrajectory.Goal(trajectory=support_trajectory(0.0, 100.0))
    for _ in range(6):
        start = time.monotonic()
        handle = until(client.send_goal_async(goal))
        assert handle.accepted
        result = until(handle.get_result_async())
        assert result.status == 4, result.status  # succeeded
        trips.append((time.monotonic() - start) * 1e3)
    handle = until(client.send_goal_async(
        FollowJointTrajectory.Goal(trajectory=support_trajectory(10.0, 100.0))))
    assert handle.accepted
    result = handle.get_result_async()
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.01)
    asked = time.monotonic()
    handle.cancel_goal_async()
    status = until(result).status
    say(trips_ms=trips, cancel_ms=(time.monotonic() - asked) * 1e3, cancel_status=status)


STARTED_NS = time.time_ns()


def main():
    mode, args = sys.argv[1], sys.argv[2:]
    rclpy.init()
    node = Node("rclpy_peer")
    if mode not in ("serve", "states", "listen", "markers", "fjt"):
        print("ready", flush=True)
    try:
        if mode == "graph":
            graph(node, args[0])
        elif mode == "serve":
            serve(node, float(args[0]))
        elif mode == "fjt":
            fjt(node, args[0], args[1])
        elif mode == "listen":
            listen(node, args[0])
        elif mode == "markers":
            markers(node, args[0])
        elif mode == "send":
            send(node, args[0])
        elif mode == "count":
            count(node)
        elif mode == "goals":
            goals(node, args[0])
        elif mode == "states":
            states(node, float(args[0]), float(args[1]), int(args[2]), args[3:] == ["latched"])
        else:
            raise SystemExit(f"unknown mode {mode}")
    finally:
        node.destroy_node()
        rclpy.shutdown()


if __name__ == "__main__":
    main()
