"""franka-sim for the benchmarks that run inside a network namespace of their own (it binds
0.0.0.0:1337): its FR3 model from franky-sim's wheel (offline), its reflexes and lost-cycle
rules on, at a realtime priority (the robot's Control, a machine of its own) unless told
otherwise; waits until it listens."""

import os
import socket
import subprocess
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SIM_PY = os.environ.get("CPS_FRANKA_SIM_PYTHON") or os.path.join(ROOT, "target/franka-sim-venv/bin/python")
FRANKY_PY = os.environ.get("CPS_FRANKA_PYTHON") or os.path.join(ROOT, "target/franka-venv/bin/python")


def start(work, realtime=True):
    """franka-sim serving on 127.0.0.1, its log in `work`/sim.log; returns (process, log)."""
    assets = subprocess.check_output(
        [FRANKY_PY, "-c", "import franky_sim, os; print(os.path.dirname(franky_sim.__file__))"],
        text=True).strip() + "/assets"
    model = os.path.join(work, "fr3.xml")
    with open(os.path.join(assets, "fr3.xml")) as f:
        xml = f.read().replace('meshdir="assets"', f'meshdir="{assets}/meshes"')
    with open(model, "w") as f:
        f.write(xml)
    log = open(os.path.join(work, "sim.log"), "w")
    command = [SIM_PY, "-m", "franka_sim.run_server", "--no-gripper", "--enforce-motion-limits",
               "--enforce-comm-constraints"]
    if realtime:
        command = ["chrt", "-f", "20"] + command
    server = subprocess.Popen(command, env={**os.environ, "FR3_MJCF": model}, stdout=log,
                              stderr=subprocess.STDOUT)
    for _ in range(300):
        try:
            socket.create_connection(("127.0.0.1", 1337), timeout=0.2).close()
            break
        except OSError:
            time.sleep(0.1)
    return server, log


def reflexes(work):
    """franka-sim's lines that say it aborted a motion (a reflex, a violated limit)."""
    with open(os.path.join(work, "sim.log")) as f:
        text = f.read()
    return [line for line in text.splitlines() if "violated" in line or "aborting the motion" in line]


def hogs(n):
    """`n` CPU hogs (a busy machine)."""
    return [subprocess.Popen(["sh", "-c", "while :; do :; done"]) for _ in range(n)]


def stop(server, log, busy):
    """Ends the hogs and franka-sim, and closes its log."""
    for h in busy:
        h.kill()
    server.kill()
    server.wait()
    log.close()
