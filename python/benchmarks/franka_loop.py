"""cps's 1 kHz loop against a pylibfranka loop, on franky-sim, side by side in one run.

    python3 -m venv target/franka-venv
    target/franka-venv/bin/pip install -r crates/cps-franka/tests/requirements.txt
    cargo build --release -p cps-cli
    target/franka-venv/bin/python python/benchmarks/franka_loop.py [--seconds 10]

Each side gets a fresh simulator (its own loopback address) and streams the same joint
motion (joints 1, 4 and 6 swinging out and back over the duration) in joint-position
mode. Prints per side: the latency from a state's arrival to the command's departure
(median, p99, max), the ticks missed (robot ticks without a command: message ids
skipped) and the tracking of the commanded motion. cps measures its loop itself (the
report of `cps-cli franka execute --json`); the Python loop is timed around its
readOnce → writeOnce body.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SERVER = ROOT / "crates/cps-franka/tests/sim_server.py"


def start_sim(host):
    p = subprocess.Popen([sys.executable, str(SERVER), "--host", host],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    if not line.startswith("ready"):
        raise SystemExit(f"franky-sim did not start on {host}: {line!r}")
    return p


def offsets(k, n):
    s = 0.5 - 0.5 * math.cos(2 * math.pi * k / n)
    return {0: 0.5 * s, 3: 0.4 * s, 5: -0.3 * s}


def pylibfranka_side(host, n):
    import pylibfranka as p
    robot = p.Robot(host, p.RealtimeConfig.kIgnore)
    q0 = list(robot.read_once().q_d)
    ctl = robot.start_joint_position_control(p.ControllerMode.JointImpedance)
    lat, ids, err = [], [], []
    for k in range(n + 1):
        state, _ = ctl.readOnce()
        t0 = time.perf_counter()
        q = list(q0)
        for j, d in offsets(k, n).items():
            q[j] += d
        cmd = p.JointPositions(q)
        if k == n:
            cmd.motion_finished = True
        ctl.writeOnce(cmd)
        lat.append(time.perf_counter() - t0)
        ids.append(round(state.time.to_sec() * 1000))
        err.append(max(abs(a - b) for a, b in zip(state.q, q)))
    lat.sort()
    missed = sum(max(0, b - a - 1) for a, b in zip(ids, ids[1:]))
    return {"median_us": lat[len(lat) // 2] * 1e6, "p99_us": lat[int(0.99 * len(lat))] * 1e6,
            "max_us": lat[-1] * 1e6, "ticks": len(lat), "missed": missed,
            "max_tracking_rad": max(err)}


def cps_side(host, n, cli):
    with tempfile.TemporaryDirectory() as d:
        import pylibfranka as p
        q0 = list(p.Robot(host, p.RealtimeConfig.kIgnore).read_once().q_d)
        traj = Path(d) / "swing.csv"
        with open(traj, "w") as f:
            f.write("t,q1,q2,q3,q4,q5,q6,q7\n")
            for k in range(n + 1):
                q = list(q0)
                for j, dq in offsets(k, n).items():
                    q[j] += dq
                f.write(f"{k / 1000:.3f}," + ",".join(f"{v:.12f}" for v in q) + "\n")
        out = subprocess.run([cli, "franka", "execute", str(traj), "--host", host, "--record",
                              str(Path(d) / "rec.csv"), "--realtime", "ignore", "--approach", "--json"],
                             capture_output=True, text=True)
        if out.returncode != 0:
            raise SystemExit(f"cps-cli failed: {out.stderr}")
        r = json.loads(out.stdout)
        t = r["timing"]
        return {"median_us": t["median_us"], "p99_us": t["p99_us"], "max_us": t["max_us"],
                "ticks": t["ticks"], "missed": t["missed_ticks"],
                "max_tracking_rad": max(r["tracking"]["max_rad"]), "realtime": t["realtime"]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--cli", default=str(ROOT / "target/release/cps-cli"))
    args = ap.parse_args()
    n = int(args.seconds * 1000)
    rows = []
    for name, host, run in [("cps (Rust)", "127.0.0.61", lambda h: cps_side(h, n, args.cli)),
                            ("pylibfranka 0.21.3 (Python)", "127.0.0.62", lambda h: pylibfranka_side(h, n))]:
        sim = start_sim(host)
        try:
            rows.append((name, run(host)))
        finally:
            sim.kill()
            sim.wait()
    print(f"{args.seconds:.0f} s joint-position motion on franky-sim 1.0.4, state in -> command out")
    print(f"{'loop':30} {'median':>9} {'p99':>9} {'max':>9} {'ticks':>7} {'missed':>7} {'max |q - q_c|':>14}")
    for name, r in rows:
        print(f"{name:30} {r['median_us']:7.1f}us {r['p99_us']:7.1f}us {r['max_us']:7.1f}us "
              f"{r['ticks']:7d} {r['missed']:7d} {r['max_tracking_rad']:12.4f} rad")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    main()
