"""The same 30 Hz action stream on franka-sim (reflexes on), three ways: cps's LeRobot robot
`cps_franka`, franka-rs 0.4.0's joint target loop (`JointTargets.move_to` per action, as a
LeRobot robot written over franka-rs would send them), and, for reference, what plain
LeRobot glue would command (each action held from its call; not run: computed).

The actions are `test_lerobot.py`'s swing (joints 1, 2 and 4 out by 0.4, 0.2 and 0.3 rad
and back in 4 s) from franka-sim's start. Per way: whether franka-sim aborted the motion
with a reflex, how close the arm's path came to each action (the worst action), and how
far the arm was from each action when the next one came (the worst, and the RMS: the
lag). Each run in a network namespace of its own (franka-sim binds 0.0.0.0:1337) beside
--hogs CPU hogs (2: a busy machine), franka-sim at a realtime priority; as root:

    sudo target/lerobot-venv/bin/python python/benchmarks/lerobot_glue.py \\
        --franka-rs-python /path/to/venv-with-franka-rs/bin/python --runs 2

cps runs in the interpreter given (LeRobot's venv, with cps and lerobot_robot_cps);
franka-rs in --franka-rs-python (`pip install franka-rs==0.4.0 numpy`). franka-sim and
franky-sim come from .ci/peers's venvs. Prints a Markdown table.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

import franka_sim_peer
START = [0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785]
FPS = 30.0
SECONDS = 4.0

# Run by each way inside the namespace: sends the swing at 30 Hz, samples the arm's joints
# as often as it can, prints {"t": [...], "q": [[...]], "calls": [...], "error": ...}.
SWING = """
import json, math, threading, time
import numpy as np
START = np.array({start})
n = int({seconds} * {fps})
t = np.arange(n) / {fps}
s = 0.5 - 0.5 * np.cos(2 * np.pi * t / {seconds})
actions = np.repeat(START[None, :], n, axis=0)
actions[:, 0] += 0.4 * s
actions[:, 1] += 0.2 * s
actions[:, 3] += 0.3 * s
"""

CPS = SWING + """
from lerobot_robot_cps import CpsFranka, CpsFrankaConfig
robot = CpsFranka(CpsFrankaConfig(host="127.0.0.1", realtime="ignore", record="{work}/cps.csv"))
robot.connect()
calls, error = [], None
try:
    t0 = time.perf_counter()
    for k, a in enumerate(actions):
        calls.append(robot._ex.observe()["t"])
        robot.send_action({{f"joint{{i + 1}}.pos": a[i] for i in range(7)}})
        time.sleep(max(0.0, t0 + (k + 1) / {fps} - time.perf_counter()))
except Exception as e:
    error = str(e)
finally:
    robot.disconnect()
import csv
rows = list(csv.reader(open("{work}/cps.csv")))
col = {{name: i for i, name in enumerate(rows[0])}}
data = np.array([[float(x) for x in r] for r in rows[1:]])
print("RESULT " + json.dumps({{"t": data[:, col["t"]].tolist(),
      "q": data[:, [col[f"q{{j}}"] for j in range(1, 8)]].tolist(), "calls": calls, "error": error,
      "actions": actions.tolist()}}))
"""

FRANKA_RS = SWING + """
import franka
robot = franka.Robot("127.0.0.1", realtime="ignore")
samples, calls, error = [], [], None
done = threading.Event()
def sample(arm, t0):
    while not done.is_set():
        samples.append((time.perf_counter() - t0, list(arm.state().flat()[0:7])))
        time.sleep(0.001)
try:
    with robot.joint_targets(fraction={fraction}) as arm:
        t0 = time.perf_counter()
        th = threading.Thread(target=sample, args=(arm, t0)); th.start()
        for k, a in enumerate(actions):
            calls.append(time.perf_counter() - t0)
            arm.move_to(a.tolist())
            time.sleep(max(0.0, t0 + (k + 1) / {fps} - time.perf_counter()))
        time.sleep(1.0)
        done.set(); th.join()
except Exception as e:
    error = f"{{type(e).__name__}}: {{e}}"
done.set()
print("RESULT " + json.dumps({{"t": [x[0] for x in samples], "q": [x[1] for x in samples], "calls": calls,
      "error": error, "actions": actions.tolist()}}))
"""


def inner(args):
    """Inside the namespace: franka-sim at a realtime priority, one way, its RESULT line."""
    work = tempfile.mkdtemp(prefix="cps-glue-")
    server, log = franka_sim_peer.start(work)
    hogs = franka_sim_peer.hogs(args.hogs)
    fmt = dict(start=START, seconds=SECONDS, fps=FPS, work=work, fraction=args.fraction)
    if args.way == "cps":
        python, code = sys.executable, CPS.format(**fmt)
    else:
        python, code = args.franka_rs_python, FRANKA_RS.format(**fmt)
    try:
        out = subprocess.run([python, "-c", code], capture_output=True, text=True, timeout=120,
                             env={**os.environ, "FRANKA_REALTIME": "ignore"})
        lines = [x for x in out.stdout.splitlines() if x.startswith("RESULT ")]
        result = json.loads(lines[-1][7:]) if lines else {"error": out.stderr[-2000:], "t": [], "q": []}
    finally:
        franka_sim_peer.stop(server, log, hogs)
    result["reflex"] = franka_sim_peer.reflexes(work)[:1]
    print("RESULT " + json.dumps(result), flush=True)


def measure(r):
    """Path closeness to each action, and the distance from each action when the next came."""
    a = np.array(r["actions"])
    t, q = np.array(r["t"]), np.array(r["q"])
    if len(q) == 0:
        return {}
    closest = max(np.abs(q - x).max(axis=1).min() for x in a)
    calls = np.array(r["calls"])
    behind = []
    for k in range(len(calls) - 1):
        i = min(np.searchsorted(t, calls[k + 1]), len(t) - 1)
        behind.append(np.abs(q[i] - a[k]).max())
    behind = np.array(behind)
    return {"closest_mrad": 1e3 * closest, "behind_max_mrad": 1e3 * behind.max(),
            "behind_rms_mrad": 1e3 * np.sqrt((behind ** 2).mean())}


def naive():
    """Plain glue: each action held from its call, judged at 1 kHz against the FR3's limits."""
    n = int(SECONDS * FPS)
    t = np.arange(n) / FPS
    s = 0.5 - 0.5 * np.cos(2 * np.pi * t / SECONDS)
    a = np.repeat(np.array(START)[None, :], n, axis=0)
    a[:, 0] += 0.4 * s
    a[:, 1] += 0.2 * s
    a[:, 3] += 0.3 * s
    q = np.repeat(a, int(1000 / FPS), axis=0)
    v = np.diff(q, axis=0) / 1e-3
    acc = np.diff(v, axis=0) / 1e-3
    jerk = np.diff(acc, axis=0) / 1e-3
    limits = np.array([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26])
    return (np.abs(v) / limits).max(), np.abs(acc).max() / 10.0, np.abs(jerk).max() / 5000.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--franka-rs-python", required=True)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--fractions", default="0.2,1.0", help="franka-rs's joint_targets(fraction=…)")
    ap.add_argument("--hogs", type=int, default=2, help="CPU hogs beside each run (a busy machine)")
    ap.add_argument("--way", help=argparse.SUPPRESS)
    ap.add_argument("--fraction", type=float, default=0.2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.way:
        return inner(args)
    ways = [("cps", "cps_franka", 0.0)] + [("franka-rs", f"franka-rs move_to, fraction {f}", float(f))
                                           for f in args.fractions.split(",")]
    print("| way | runs | ended by a reflex | path's closest to the worst action (mrad) | "
          "behind when the next action came, worst / RMS (mrad) |")
    print("|---|---|---|---|---|")
    for way, name, fraction in ways:
        results = []
        for _ in range(args.runs):
            cmd = ["unshare", "-n", "sh", "-c", 'ip link set lo up && exec "$0" "$@"', sys.executable,
                   os.path.abspath(__file__), "--franka-rs-python", args.franka_rs_python, "--way", way,
                   "--fraction", str(fraction), "--hogs", str(args.hogs)]
            out = subprocess.run(cmd, capture_output=True, text=True, timeout=300).stdout
            lines = [x for x in out.splitlines() if x.startswith("RESULT ")]
            r = json.loads(lines[-1][7:]) if lines else {"error": "no result", "reflex": ["no result"]}
            m = measure(r) if r.get("q") else {}
            print(json.dumps({"way": name, "error": r.get("error"), "reflex": r.get("reflex"), **m}),
                  file=sys.stderr, flush=True)
            results.append((r, m))

        def span(key):
            v = [m[key] for _, m in results if key in m]
            return "—" if not v else f"{min(v):.1f}–{max(v):.1f}" if len(v) > 1 else f"{v[0]:.1f}"
        reflexes = sum(bool(r.get("reflex")) or bool(r.get("error")) for r, _ in results)
        print(f"| {name} | {len(results)} | {reflexes} | {span('closest_mrad')} | "
              f"{span('behind_max_mrad')} / {span('behind_rms_mrad')} |")
    v, a, j = naive()
    print(f"| plain glue (each action held from its call; computed, not run) | — | its first step is "
          f"{v:.1f}× the velocity, {a:.0f}× the acceleration and {j:.0f}× the jerk limit | — | — |")


if __name__ == "__main__":
    main()
