"""A policy stand-in's action chunks executed three ways on franky-sim, side by side in one
run: cps's chunk executor (`cps-cli franka follow`), Ruckig's online generator (PyPI
`ruckig`, its free edition: one target at a time) and naive execution (each chunk from its
first point when it arrives, linearly interpolated at 1 kHz) — both streamed with
`cps-cli franka execute`, whose guard refuses what breaks a limit before anything moves
(where a Franka would stop with a reflex).

    python3 -m venv target/franka-venv
    target/franka-venv/bin/pip install -r crates/cps-franka/tests/requirements.txt ruckig==0.19.4
    cargo build --release -p cps-cli
    target/franka-venv/bin/python python/benchmarks/chunks_compare.py [--hz 10 30]

The stand-in: chunks of 50 targets at 50 Hz, at --hz, each from an observation 50-150 ms
old, every target off by up to +-2 mrad (seeded), of a swing of joints 1, 2 and 4 about
the simulator's start. Prints per executor: the commands' velocity, acceleration and jerk
peaks as shares of the FR3's limits, whether the robot ran it, and the measured joints'
worst distance to the demonstration after the first second.
"""

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SERVER = ROOT / "crates/cps-franka/tests/sim_server.py"
DT = 1e-3
FR3_V = np.array([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26])
FR3_A, FR3_J = 10.0, 5000.0


def cli():
    """$CPS_CLI, else the newest cps-cli built under target/."""
    import os
    if os.environ.get("CPS_CLI"):
        return os.environ["CPS_CLI"]
    built = [p for p in (ROOT / "target" / d / "cps-cli" for d in ("release", "checked", "debug")) if p.exists()]
    if not built:
        raise SystemExit("build cps-cli first: cargo build --release -p cps-cli")
    return str(max(built, key=lambda p: p.stat().st_mtime))


def start_sim(host):
    p = subprocess.Popen([sys.executable, str(SERVER), "--host", host],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    if not p.stdout.readline().startswith("ready"):
        raise SystemExit(f"franky-sim did not start on {host}")
    return p


def state_q(host):
    o = subprocess.run([cli(), "franka", "state", "--host", host, "--json"],
                       capture_output=True, text=True, check=True)
    return np.array(json.loads(o.stdout)["q"])


def demo_of(q0):
    def demo(t):
        s = 0.5 - 0.5 * np.cos(math.pi / 2 * np.clip(t, 0.0, None))
        d = np.zeros(7)
        d[0], d[1], d[3] = 0.3, -0.15, 0.2
        return q0 + np.multiply.outer(s, d)
    return demo


def stand_in(demo, hz, seconds, seed):
    rng = np.random.default_rng(seed)
    period, chunks = 1.0 / hz, []
    delay = rng.uniform(0.05, 0.15)
    for k in range(int(seconds * hz) + 1):
        if k:
            delay = rng.uniform(0.05, min(0.15, delay + period))
        arrived = k * period
        observed = arrived - delay
        targets = demo(observed + np.arange(50) / 50.0) + rng.uniform(-0.002, 0.002, (50, 7))
        chunks.append((observed, arrived, targets))
    return chunks


def write_chunks(path, chunks):
    with open(path, "w") as f:
        f.write("chunk,arrived_s,observed_s,k," + ",".join(f"q{j}" for j in range(1, 8)) + "\n")
        for i, (obs, arr, targets) in enumerate(chunks):
            for k, q in enumerate(targets):
                f.write(f"{i},{arr!r},{obs!r},{k}," + ",".join(repr(float(x)) for x in q) + "\n")


def naive(chunks, q0, n):
    out, current, nxt = np.tile(q0, (n, 1)), None, 0
    for k in range(n):
        t = (k + 1) * DT
        while nxt < len(chunks) and chunks[nxt][1] <= t:
            current, nxt = chunks[nxt], nxt + 1
        if current is not None:
            s = min((t - current[1]) * 50.0, 49.0)
            i = int(s)
            out[k] = current[2][i] + (s - i) * (current[2][min(i + 1, 49)] - current[2][i])
    return out


def ruckig_commands(chunks, q0, n):
    import ruckig
    otg = ruckig.Ruckig(7, DT)
    inp, out = ruckig.InputParameter(7), ruckig.OutputParameter(7)
    inp.current_position, inp.current_velocity = q0.tolist(), [0.0] * 7
    inp.current_acceleration = [0.0] * 7
    inp.max_velocity = (0.95 * FR3_V).tolist()
    inp.max_acceleration, inp.max_jerk = [9.5] * 7, [4750.0] * 7
    q, current, nxt = np.tile(q0, (n, 1)), None, 0
    for k in range(n):
        t = (k + 1) * DT
        while nxt < len(chunks) and chunks[nxt][1] <= t:
            current, nxt = chunks[nxt], nxt + 1
        if current is not None:
            s = min(max((t - current[0]) * 50.0, 0.0), 49.0)
            i = min(int(s), 48)
            inp.target_position = (current[2][i] + (s - i) * (current[2][i + 1] - current[2][i])).tolist()
            inp.target_velocity = np.clip((current[2][i + 1] - current[2][i]) * 50.0, -2.4, 2.4).tolist()
            inp.target_acceleration = [0.0] * 7
            otg.update(inp, out)
            out.pass_to_input(inp)
            q[k] = out.new_position
        elif k:
            q[k] = q[k - 1]
    # Then to rest where it is.
    tail = []
    inp.target_position, inp.target_velocity = list(out.new_position), [0.0] * 7
    while otg.update(inp, out) == ruckig.Result.Working:
        out.pass_to_input(inp)
        tail.append(out.new_position)
    return np.vstack([q] + ([np.array(tail)] if tail else []))


def shares(q, q0):
    q = np.vstack([q0, q])
    v = np.diff(q, axis=0) / DT
    a = np.diff(np.vstack([np.zeros(7), v]), axis=0) / DT
    j = np.diff(np.vstack([np.zeros(7), a]), axis=0) / DT
    return np.max(np.abs(v) / FR3_V), np.max(np.abs(a)) / FR3_A, np.max(np.abs(j)) / FR3_J


def measured(rec, demo, shift=0.0):
    data = np.genfromtxt(rec, delimiter=",", names=True)
    t = data["t"] - shift
    q = np.column_stack([data[f"q{j}"] for j in range(1, 8)])
    keep = (t > 1.0) & (t < 4.0)
    return np.max(np.abs(q[keep] - demo(t[keep])))


def run(args, host):
    o = subprocess.run([cli(), *args, "--host", host, "--realtime", "ignore", "--json"],
                       capture_output=True, text=True)
    return o.returncode, o.stdout, o.stderr


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hz", type=float, nargs="+", default=[10.0, 30.0])
    ap.add_argument("--seconds", type=float, default=4.0)
    args = ap.parse_args()
    host = "127.0.0.121"
    sim = start_sim(host)
    try:
        for hz in args.hz:
            q0 = state_q(host)
            demo = demo_of(q0)
            chunks = stand_in(demo, hz, args.seconds, 7)
            n = int(args.seconds * 1000) + 1000
            with tempfile.TemporaryDirectory() as d:
                d = Path(d)
                write_chunks(d / "chunks.csv", chunks)
                print(f"{hz:.0f} Hz, {len(chunks)} chunks of 50 at 50 Hz, 50-150 ms old, +-2 mrad:")
                code, out, err = run(["franka", "follow", str(d / "chunks.csv"), "--rate", "50",
                                      "--record", str(d / "cps.csv")], host)
                rec = np.genfromtxt(d / "cps.csv", delimiter=",", names=True)
                qd = np.column_stack([rec[f"q_d{j}"] for j in range(1, 8)])
                v, a, j = shares(qd, qd[0])
                report = json.loads(out) if code == 0 else {}
                print(f"  cps:    v {v:.2f}x a {a:.2f}x j {j:.3f}x of the FR3's limits; "
                      f"ran: {code == 0}; from the demonstration {1e3 * measured(d / 'cps.csv', demo):.1f} mrad; "
                      f"loop p99 {report.get('timing', {}).get('p99_us', float('nan')):.1f} us")
                for name, q in (("ruckig", ruckig_commands(chunks, q0, n)), ("naive", naive(chunks, q0, n))):
                    v, a, j = shares(q, q0)
                    traj = d / f"{name}.csv"
                    t = np.arange(len(q) + 1) * DT
                    np.savetxt(traj, np.column_stack([t, np.vstack([q0, q])]), delimiter=",",
                               header="t,q1,q2,q3,q4,q5,q6,q7", comments="", fmt="%.12g")
                    code, out, err = run(["franka", "execute", str(traj), "--approach",
                                          "--record", str(d / f"{name}.rec.csv")], host)
                    shift = json.loads(out)["approach_s"] if code == 0 else 0.0
                    how = (f"from the demonstration {1e3 * measured(d / f'{name}.rec.csv', demo, shift):.1f} mrad"
                           if code == 0 else "refused: " + err.strip().splitlines()[-1][:140])
                    print(f"  {name}: v {v:.2f}x a {a:.2f}x j {j:.3f}x of the FR3's limits; ran: {code == 0}; {how}")
    finally:
        sim.kill()


if __name__ == "__main__":
    main()
