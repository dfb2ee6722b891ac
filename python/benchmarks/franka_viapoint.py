"""The thesis's joint-space via-point movement on a simulated FR3: cps's learned movement
against franky's JointWaypointMotion through the same way points, side by side in one run.

    python3 -m venv target/franka-venv
    target/franka-venv/bin/pip install -r crates/cps-franka/tests/requirements.txt franky-control==2.0.0
    cargo build --release -p cps-cli
    target/franka-venv/bin/python python/benchmarks/franka_viapoint.py

cps: `cps-cli run experiments/franka/viapoint_joint.toml` with the host set to a fresh
franky-sim (learning on the FR3 model, then the movement streamed at 1 kHz and recorded
every 10 ms). franky 2.0.0 (libfranka 0.21 inside, ruckig's time-optimal waypoints) on
another fresh simulator: a JointMotion to the same start, then a JointWaypointMotion
through the configurations cps's inverse kinematics found for the via points and the
goal (summary.json's way_configurations_rad), at rest at each, at 15 % of the limits
(about the thesis's 10 s); its state read at about 200 Hz by Python while it moves. Its
via-point "time" is the moment it reaches each way point's configuration.

Printed per side: how long the movement took, the tool's distance from each via point
at its time and its closest approach (mm), the commanded-vs-measured joint error (RMS,
max; franky's commanded is the robot's q_d) and the largest joint speed (share of the
FR3's limit). franky-sim's joint PD damps absolute velocity (kv/kp = 0.1 s), so a moving
arm runs about 100 ms behind what it is commanded, on both sides.
"""

import argparse
import json
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from franka_loop import start_sim  # this folder: a franky-sim on a loopback address

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENT = ROOT / "experiments/franka/viapoint_joint.toml"
VIA = [(2.0, [0.78, 0.60, 1.70]), (4.0, [1.12, 0.37, 1.45]), (6.0, [1.15, -0.15, 1.20]),
       (8.0, [0.90, -0.53, 1.20]), (10.0, [0.55, -0.57, 1.45])]
BASE = np.array([0.42244, 0.02, 0.74177])  # configs/scenes/fr3.toml
DQ_MAX = np.array([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26])


def path_stats(t, tool, t0):
    """Distance at each via point's time and closest approach, mm."""
    out = []
    for tv, p in VIA:
        d = np.linalg.norm(tool - np.array(p), axis=1)
        k = int(np.argmin(np.abs(t - (t0 + tv))))
        out.append((d[k] * 1e3, d.min() * 1e3))
    return out


def run_cps(cli, host, generations):
    text = EXPERIMENT.read_text().replace(
        'host = "172.16.0.2"', f'host = "{host}"\nrealtime = "ignore"')
    if generations:
        text = text.replace("generations = 1500", f"generations = {generations}")
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "fr3.toml"
        f.write_text(text)
        out = Path(d) / "out"
        started = time.perf_counter()
        r = subprocess.run([cli, "run", str(f), "--out", str(out), "--quiet"],
                           capture_output=True, text=True)
        wall = time.perf_counter() - started
        if r.returncode != 0:
            raise SystemExit(f"cps-cli run failed: {r.stderr}")
        summary = json.loads((out / "summary.json").read_text())
        rec = np.genfromtxt(out / "recording.csv", delimiter=",", names=True)
        traj = np.genfromtxt(out / "trajectory.csv", delimiter=",", names=True)
    q = np.stack([rec[f"q{j}"] for j in range(1, 8)], 1)
    qc = np.stack([traj[f"q{j}"] for j in range(1, 8)], 1)[: len(q)]
    tool = np.stack([rec["tool_x"], rec["tool_y"], rec["tool_z"]], 1)
    t = rec["t"] - 0.01  # row k is the state when command k (planned at k * 10 ms) was sent
    err = q - qc
    speed = np.abs(np.diff(q, axis=0) / 0.01).max(0) / DQ_MAX
    return {
        "duration": t[-1],
        "via": path_stats(t, tool, 0.0),
        "rms": np.sqrt((err ** 2).mean(0)),
        "max": np.abs(err).max(0),
        "speed": speed.max(),
        "ways": summary["way_configurations_rad"],
        "wall": wall,
    }


def run_franky(host, ways):
    import franky

    robot = franky.Robot(host, realtime_config=franky.RealtimeConfig.Ignore)
    robot.recover_from_errors()
    robot.move(franky.JointMotion(ways[0], relative_dynamics_factor=0.2))
    time.sleep(0.5)
    # Rest at every way point, at 15 % of the limits: about the thesis's 10 s. (A minimum
    # time of 2 s per way point makes franky 2.0.0's planner fail mid-way, ruckig -111.)
    motion = franky.JointWaypointMotion(
        [franky.JointWaypoint(franky.JointState(w)) for w in ways[1:]],
        relative_dynamics_factor=0.15)
    t, q, qd, dq, tool = [], [], [], [], []
    started = time.perf_counter()
    robot.move(motion, asynchronous=True)
    while True:
        s = robot.state
        t.append(time.perf_counter() - started)
        q.append(list(s.q))
        qd.append(list(s.q_d))
        dq.append(list(s.dq))
        tool.append(np.array(s.O_T_EE.matrix)[:3, 3] + BASE)
        if not robot.is_in_control and t[-1] > 0.5:
            break
        time.sleep(0.005)
    robot.join_motion()
    t, q, qd, dq, tool = map(np.array, (t, q, qd, dq, tool))
    err = q - qd
    speed = np.abs(dq).max(0) / DQ_MAX  # the measured velocities (Python's clock is too coarse)
    via = []
    for (_, p), w in zip(VIA, ways[1:]):
        d = np.linalg.norm(tool - np.array(p), axis=1)
        k = int(np.argmin(np.linalg.norm(qd - np.array(w), axis=1)))
        via.append((d[k] * 1e3, d.min() * 1e3))
    return {
        "duration": t[-1],
        "via": via,
        "rms": np.sqrt((err ** 2).mean(0)),
        "max": np.abs(err).max(0),
        "speed": speed.max(),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cli", default=str(ROOT / "target/release/cps-cli"))
    ap.add_argument("--generations", type=int, default=0,
                    help="CMA-ES generations for cps (default: the file's 1500)")
    args = ap.parse_args()
    sims = [start_sim("127.0.0.66"), start_sim("127.0.0.67")]
    try:
        ours = run_cps(args.cli, "127.0.0.66", args.generations)
        theirs = run_franky("127.0.0.67", ours["ways"])
    finally:
        for s in sims:
            s.stdin.close()
    print(f"thesis via points on franky-sim's FR3 (cps-cli run took {ours['wall']:.1f} s, learning included)")
    print(f"{'':28}{'cps (learned DMPs)':>22}{'franky JointWaypointMotion':>30}")
    print(f"{'movement duration (s)':28}{ours['duration']:>22.2f}{theirs['duration']:>30.2f}")
    for i, ((a1, a2), (b1, b2)) in enumerate(zip(ours["via"], theirs["via"])):
        name = f"p{i + 1}" if i < 4 else "goal"
        print(f"{name + ' at its time / closest (mm)':28}{a1:>12.1f} / {a2:<7.2f}{b1:>20.1f} / {b2:<7.2f}")
    print(f"{'q_c - q RMS per joint (mrad)':28}{' '.join(f'{x * 1e3:.1f}' for x in ours['rms']):>22}  "
          f"{' '.join(f'{x * 1e3:.1f}' for x in theirs['rms'])}")
    print(f"{'q_c - q max (mrad)':28}{ours['max'].max() * 1e3:>22.1f}{theirs['max'].max() * 1e3:>30.1f}")
    print(f"{'peak joint speed (of limit)':28}{ours['speed'] * 100:>21.0f}%{theirs['speed'] * 100:>29.0f}%")


if __name__ == "__main__":
    main()
