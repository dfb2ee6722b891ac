"""cps's torque loop against a pylibfranka torque loop, on franky-sim, side by side.

    python3 -m venv target/franka-venv
    target/franka-venv/bin/pip install -r crates/cps-franka/tests/requirements.txt
    cargo build --release -p cps-cli
    target/franka-venv/bin/python python/benchmarks/franka_torque_loop.py

cps: experiments/contact.toml on a simulator with the test fixture's table, every tick the
robot's model (mass matrix by seven Newton-Euler passes, Coriolis, gravity, Jacobian), the
momentum observer and the wrench, the force primitive stepped, the Cartesian impedance
with force along z and its null space; the loop times itself (state in -> command out).

pylibfranka 0.21.3: Franka's own Python binding running the Cartesian impedance of
Franka's example (libfranka's model for the Jacobian and Coriolis, numpy for the law) along
a 10 cm line in free space for the same number of ticks, timed around readOnce -> writeOnce.
It does less per tick than cps (no observer, no force loop, no primitive).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SERVER = ROOT / "crates/cps-franka/tests/sim_server.py"


def start_sim(host, *extra):
    p = subprocess.Popen([sys.executable, str(SERVER), "--host", host, *extra],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    if not line.startswith("ready"):
        raise SystemExit(f"franky-sim did not start on {host}: {line!r}")
    return p


def cps_side(host, cli):
    text = (ROOT / "experiments/contact.toml").read_text().replace('host = "127.0.0.1"', f'host = "{host}"')
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "contact.toml"
        f.write_text(text)
        out = subprocess.run([cli, "run", str(f), "--out", str(Path(d) / "out"), "--quiet"],
                             capture_output=True, text=True)
        if out.returncode != 0:
            raise SystemExit(f"cps-cli failed: {out.stderr}")
        s = json.loads((Path(d) / "out" / "summary.json").read_text())["contact"]
        return {"median_us": s["loop_median_us"], "p99_us": s["loop_p99_us"], "ticks": s["samples"],
                "missed": s["missed_ticks"], "what": s["ending"]}


def pylibfranka_side(host, n):
    import pylibfranka as p
    robot = p.Robot(host, p.RealtimeConfig.kIgnore)
    model = robot.load_model()
    state = robot.read_once()
    pose0 = np.array(state.O_T_EE).reshape(4, 4, order="F")
    p0, r_d = pose0[:3, 3].copy(), pose0[:3, :3].copy()
    k = np.diag([2000.0] * 3 + [150.0] * 3)
    d = 2.0 * np.sqrt(k)
    ctl = robot.start_torque_control()
    lat, ids = [], []
    for i in range(n + 1):
        state, _ = ctl.readOnce()
        t0 = time.perf_counter()
        s = min(1.0, i / n)
        target = p0 + np.array([0.0, 0.1, 0.0]) * (s * s * s * (10 - 15 * s + 6 * s * s))
        pose = np.array(state.O_T_EE).reshape(4, 4, order="F")
        j = np.array(model.zero_jacobian(state)).reshape(6, 7, order="F")
        dq = np.array(state.dq)
        err = np.zeros(6)
        err[:3] = target - pose[:3, 3]
        r_e = r_d @ pose[:3, :3].T
        angle = np.arccos(np.clip((np.trace(r_e) - 1) / 2, -1, 1))
        axis = np.array([r_e[2, 1] - r_e[1, 2], r_e[0, 2] - r_e[2, 0], r_e[1, 0] - r_e[0, 1]])
        err[3:] = 0.0 if angle < 1e-9 else axis * angle / (2 * np.sin(angle))
        tau = j.T @ (k @ err - d @ (j @ dq)) + np.array(model.coriolis(state))
        cmd = p.Torques(tau.tolist())
        if i == n:
            cmd.motion_finished = True
        ctl.writeOnce(cmd)
        lat.append(time.perf_counter() - t0)
        ids.append(round(state.time.to_sec() * 1000))
    lat.sort()
    missed = sum(max(0, b - a - 1) for a, b in zip(ids, ids[1:]))
    return {"median_us": lat[len(lat) // 2] * 1e6, "p99_us": lat[int(0.99 * len(lat))] * 1e6,
            "ticks": len(lat), "missed": missed, "what": "Cartesian impedance along a line"}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", default=str(ROOT / "target/release/cps-cli"))
    args = ap.parse_args()
    rows = []
    sim = start_sim("127.0.0.91", "--table", "0.40", "--friction", "0.5")
    try:
        rows.append(("cps (Rust): contact task", cps_side("127.0.0.91", args.cli)))
    finally:
        sim.kill()
        sim.wait()
    sim = start_sim("127.0.0.92")
    try:
        rows.append(("pylibfranka 0.21.3 (Python)", pylibfranka_side("127.0.0.92", rows[0][1]["ticks"])))
    finally:
        sim.kill()
        sim.wait()
    print("torque mode on franky-sim 1.0.4, state in -> command out")
    print(f"{'loop':30} {'median':>9} {'p99':>9} {'ticks':>7} {'missed':>7}  what")
    for name, r in rows:
        print(f"{name:30} {r['median_us']:7.1f}us {r['p99_us']:7.1f}us {r['ticks']:7d} {r['missed']:7d}  {r['what']}")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    main()
