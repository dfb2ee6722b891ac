"""franky-sim's MuJoCo FR3 behind the Franka Control Interface, on one loopback address,
for cps's tests. Prints `ready <host>` once it serves, and exits when its standard input
closes (the test process that started it ended, however it ended).

usage: python sim_server.py --host 127.0.0.11
"""
import argparse
import logging
import os
import sys
import threading

parser = argparse.ArgumentParser()
parser.add_argument("--host", required=True, help="a loopback address of its own")
parser.add_argument("--fast", action="store_true", help="step as fast as it can (no 1 kHz pacing)")
args = parser.parse_args()
logging.basicConfig(level=logging.ERROR)

import franky_sim  # noqa: E402
from franky_sim.mujoco_simulator import MujocoSimulator  # noqa: E402


def exit_with_parent():
    sys.stdin.read()
    os._exit(0)


threading.Thread(target=exit_with_parent, daemon=True).start()
with MujocoSimulator(enable_visualization=False) as sim:
    sim.add_robot()
    with franky_sim.SimulationServer(sim, hostname_candidates=[args.host]) as server:
        print(f"ready {args.host}", flush=True)
        server.run_forever(realtime=not args.fast)
