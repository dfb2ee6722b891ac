"""franky-sim's MuJoCo FR3 behind the Franka Control Interface, on one loopback address,
for cps's tests. Prints `ready <host>` once it serves, and exits when its standard input
closes (the test process that started it ended, however it ended).

usage: python sim_server.py --host 127.0.0.11 [--table 0.40 [--friction 0.3]] [--box X Y Z SX SY SZ]
                            [--truth truth.csv] [--stay]

By hand, in the background: `python sim_server.py --host 127.0.0.1 --table 0.40 --stay &`
(without --stay it would stop at once: a background job's input is closed).

--table TOP   a table under the hand: a box over x in [0.35, 0.75], y in [-0.3, 0.3] (the
              robot's base frame is MuJoCo's world frame) with its top at z = TOP.
--friction MU the table's sliding friction coefficient (1 unless given).
--box X Y Z SX SY SZ  a box (a shelf) centred at (X, Y, Z) in the robot's base frame, SX × SY × SZ
              metres; every step's contacts between it and the robot are counted.
--truth FILE  MuJoCo's ground truth, one row per simulation step:
              `id,fx,fy,fz,normal,x,y,z,q1..q7`: the message id of the robot state sent after the
              step; the total force the table exerts on the robot (world axes, N); the sum
              of the contacts' normal forces (N); the hand's tool centre point (0.1034 m
              below the flange, as franky-sim's O_T_EE) in the world (m); the joint
              positions q1..q7 (rad, MuJoCo's qpos, which the robot state reports).

Lines on standard input act on the hand while it runs (a hand pushing the robot):
  push FX FY FZ            a constant force (N, world axes) on the hand body
  lead X Y Z SECONDS K D   a spring (K N/m) and damper (D N s/m) pulling the tool centre point
                           towards an anchor that moves in a straight line from where the
                           point is now to (X, Y, Z) over SECONDS, then stays there
  release                  no more force
  flush                    write the truth out, then print `flushed`
  contacts                 print `contacts STEPS GEOMS`: how many steps had a contact between
                           the box and the robot, and the robot's geoms it touched (`-`: none)
"""
import argparse
import logging
import os
import sys
import threading
import time
import xml.etree.ElementTree as ET

parser = argparse.ArgumentParser()
parser.add_argument("--host", required=True, help="a loopback address of its own")
parser.add_argument("--fast", action="store_true", help="step as fast as it can (no 1 kHz pacing)")
parser.add_argument("--table", type=float, default=None, help="height of the table's top (m)")
parser.add_argument("--friction", type=float, default=1.0,
                    help="the table's sliding friction coefficient (MuJoCo's default: 1)")
parser.add_argument("--box", type=float, nargs=6, default=None,
                    help="a box centred at X Y Z in the base frame, SX SY SZ metres")
parser.add_argument("--truth", default=None, help="file for MuJoCo's ground truth per step")
parser.add_argument("--stay", action="store_true",
                    help="keep serving when standard input closes (run it by hand in the background; stop it with kill)")
args = parser.parse_args()
logging.basicConfig(level=logging.ERROR)

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import franky_sim  # noqa: E402
from franky_sim.mujoco_simulator import MujocoSimulator  # noqa: E402

TCP_OFFSET = 0.1034  # along the hand's z axis, from the flange


def compiled_once(compile_xml):
    """MuJoCo's compiler, each model compiled once per venv: the FR3's meshes (their convex
    hulls) take 0.7 s of CPU to compile, half of a simulator's start, and the tests start
    about a hundred. The compiled model is kept as MuJoCo's own binary (MJB, the same
    mjModel bit for bit) under the venv, named by a hash of the XML, MuJoCo's and
    franky-sim's versions; written whole, then renamed, so simulators starting at once
    never read half a file."""
    import hashlib
    from importlib.metadata import version

    folder = os.path.join(sys.prefix, "cps-mjb-cache")

    def compile_or_load(xml, *rest, **named):
        if rest or named:  # assets given: not a case sim_server.py makes
            return compile_xml(xml, *rest, **named)
        key = hashlib.sha256(
            f"{mujoco.__version__}\0{version('franky-sim')}\0{xml}".encode()).hexdigest()
        path = os.path.join(folder, f"{key}.mjb")
        if os.path.exists(path):
            return mujoco.MjModel.from_binary_path(path)
        model = compile_xml(xml)
        try:
            os.makedirs(folder, exist_ok=True)
            part = f"{path}.{os.getpid()}.part"
            mujoco.mj_saveModel(model, part, None)
            os.replace(part, path)
        except OSError:
            pass  # a read-only venv: compile each time
        return model

    return compile_or_load


mujoco.MjModel.from_xml_string = staticmethod(compiled_once(mujoco.MjModel.from_xml_string))

# What the standard input asks of the hand; read by the simulation thread each step.
action = {"kind": None}
lock = threading.Lock()


def read_commands():
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        try:
            values = [float(w) for w in words[1:]]
            with lock:
                if words[0] == "push" and len(values) == 3:
                    action.update(kind="push", force=np.array(values))
                elif words[0] == "lead" and len(values) == 6:
                    action.update(kind="lead", goal=np.array(values[:3]), seconds=values[3],
                                  k=values[4], d=values[5], start=None)
                elif words[0] == "release":
                    action.update(kind=None)
                elif words[0] == "flush":
                    action["flush"] = True
                elif words[0] == "contacts":
                    action["contacts"] = True
                else:
                    print(f"unknown command: {line.strip()}", file=sys.stderr, flush=True)
        except ValueError:
            print(f"bad numbers in: {line.strip()}", file=sys.stderr, flush=True)
    os._exit(0)


with MujocoSimulator(enable_visualization=False) as sim:
    sim.add_robot()
    if args.table is not None:
        top = args.table
        table = ET.SubElement(sim.worldbody, "body", name="table", pos=f"0.55 0 {top / 2}")
        # priority: the table's friction decides its contacts (not the larger of the two).
        ET.SubElement(table, "geom", name="table_top", type="box",
                      size=f"0.2 0.3 {top / 2}", rgba="0.6 0.5 0.4 1", priority="1",
                      friction=f"{args.friction} 0.005 0.0001")
    if args.box is not None:
        x, y, z, sx, sy, sz = args.box
        shelf = ET.SubElement(sim.worldbody, "body", name="box", pos=f"{x} {y} {z}")
        ET.SubElement(shelf, "geom", name="box", type="box",
                      size=f"{sx / 2} {sy / 2} {sz / 2}", rgba="0.5 0.5 0.6 1")
    with franky_sim.SimulationServer(sim, hostname_candidates=[args.host]) as server:
        robot_server = server.robot_servers[0]
        state = {"model": None}

        def after_step(s):
            model, data = s.model, s.data
            if state["model"] is None:
                state["model"] = model
                state["hand"] = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "robot0_hand")
                state["table"] = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "table_top")
                state["box"] = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "box")
                state["box_steps"], state["box_geoms"] = 0, set()
                state["idle"] = False
                state["file"] = open(args.truth, "w", buffering=1 << 20) if args.truth else None
                if state["file"]:
                    state["file"].write("id,fx,fy,fz,normal,x,y,z," + ",".join(f"q{i}" for i in range(1, 8)) + "\n")
            # Nothing to measure or apply (no table, box or truth file; no force asked for,
            # none left on the hand): the step costs the simulator nothing more (a third of
            # a core goes to franky-sim's own 1 kHz loop).
            if (state["idle"] and state["table"] < 0 and state["box"] < 0 and state["file"] is None
                    and action["kind"] is None and "flush" not in action and "contacts" not in action):
                return
            hand = state["hand"]
            rotation = data.xmat[hand].reshape(3, 3)
            tcp = data.xpos[hand] + rotation[:, 2] * TCP_OFFSET
            force, normal = np.zeros(3), 0.0
            table = state["table"]
            if table >= 0:
                f6 = np.zeros(6)
                for i in range(data.ncon):
                    c = data.contact[i]
                    if table not in (c.geom1, c.geom2):
                        continue
                    mujoco.mj_contactForce(model, data, i, f6)
                    normal += f6[0]
                    # The contact frame's rows are its axes in the world; the force acts
                    # from geom1 on geom2 along the normal.
                    world = c.frame.reshape(3, 3).T @ f6[:3]
                    force += world if c.geom1 == table else -world
            box = state["box"]
            if box >= 0:
                g1, g2 = data.contact.geom1[:data.ncon], data.contact.geom2[:data.ncon]
                mask = (g1 == box) | (g2 == box)
                touched = np.where(g1[mask] == box, g2[mask], g1[mask]).tolist()
                if touched:
                    state["box_steps"] += 1
                    state["box_geoms"].update(
                        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
                        for g in touched)
            with lock:
                kind = action["kind"]
                applied = np.zeros(3)
                if kind == "push":
                    applied = action["force"]
                elif kind == "lead":
                    if action["start"] is None:
                        action["start"], action["t0"] = tcp.copy(), data.time
                    share = min(1.0, (data.time - action["t0"]) / max(action["seconds"], 1e-9))
                    anchor = action["start"] + share * (action["goal"] - action["start"])
                    velocity = np.zeros(6)
                    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, hand,
                                             velocity, 0)
                    applied = action["k"] * (anchor - tcp) - action["d"] * velocity[3:]
                flush = action.pop("flush", False)
                contacts = action.pop("contacts", False)
            # The force acts at the tool centre point: a force and the moment it makes
            # about the hand body's origin.
            data.xfrc_applied[hand, :3] = applied
            data.xfrc_applied[hand, 3:] = np.cross(tcp - data.xipos[hand], applied)
            # Idle once no force is applied (the one just cleared stays cleared).
            state["idle"] = kind is None
            if state["file"]:
                state["file"].write(
                    f"{robot_server._FrankaServer__message_id},{force[0]:.4f},{force[1]:.4f},"
                    f"{force[2]:.4f},{normal:.4f},{tcp[0]:.6f},{tcp[1]:.6f},{tcp[2]:.6f},"
                    + ",".join(f"{x:.9f}" for x in data.qpos[:7]) + "\n"
                )
            if flush:
                if state["file"]:
                    state["file"].flush()
                print("flushed", flush=True)
            if contacts:
                geoms = ",".join(sorted(state["box_geoms"])) or "-"
                print(f"contacts {state['box_steps']} {geoms}", flush=True)

        sim.register_post_step_callback(after_step)
        if not args.stay:
            threading.Thread(target=read_commands, daemon=True).start()
        print(f"ready {args.host}", flush=True)
        gripper = getattr(robot_server, "_FrankaRobotServer__gripper_server", None)
        servers = [robot_server] + ([gripper] if gripper is not None else [])
        # franky-sim steps its arm at 1 kHz whether or not a client is connected: a third of
        # a core each while nobody is (8 % paused; BENCHMARKS › Where a cold CI's time
        # goes). Once nobody has been connected, nothing has been asked on the
        # standard input and the arm has rested for half a second, the physics pauses: the
        # connections are still accepted (every 2 ms), and the first client, command or
        # motion steps it again at 1 kHz. A client sees the same robot (the simulated
        # time resumes where it paused: the robot's clock, like its message ids, starts
        # nothing new).
        still = 0
        while True:
            busy = (any(s.tcp_connected for s in servers) or action["kind"] is not None
                    or "flush" in action or "contacts" in action
                    or float(np.abs(sim.data.qvel).max(initial=0.0)) > 1e-3)
            still = 0 if busy else still + 1
            if still < 500:
                server.run_once(realtime=not args.fast)
            else:
                for s in servers:
                    s.process_commands()
                time.sleep(0.002)
