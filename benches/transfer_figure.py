"""The transfer figure of docs/robots.md: the shipped dynamics experiment's learned
command, the tool as cps's robot with dynamics executed it, and the tool as franky-sim
(MuJoCo) executed the same command streamed by `cps-cli franka execute`, with the via
points; the via-point errors printed.

MuJoCo's tool is read from its own state (tests/sim_server.py --truth), at the simulation
step whose joints the robot reported at each 10 ms of the plan.

Run (after `cargo build --profile checked -p cps-cli`, with the test environments .ci/run
makes):
    target/ci-pyenv/bin/python benches/transfer_figure.py
Writes docs/figures/transfer.png.
"""

import argparse
import csv
import math
import pathlib
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent
BASE = (0.42244, 0.02, 0.74177)  # the fr3 scene's robot base (configs/scenes/fr3.toml)
VIAS = [(2.0, (0.78, 0.60, 1.70)), (4.0, (1.12, 0.37, 1.45)), (6.0, (1.15, -0.15, 1.20)),
        (8.0, (0.90, -0.53, 1.20))]
GOAL = (10.0, (0.55, -0.57, 1.45))


def rows(path):
    with open(path) as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cli", default=str(ROOT / "target" / "checked" / "cps-cli"))
    ap.add_argument("--franka-python", default=str(ROOT / "target" / "franka-venv" / "bin" / "python"))
    ap.add_argument("--host", default="127.0.0.98")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "transfer.png"))
    args = ap.parse_args()
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="cps-transfer-"))
    learned = tmp / "learned"
    subprocess.run([args.cli, "run", str(ROOT / "experiments/dynamics/viapoint_joint.toml"),
                    "--out", str(learned), "--quiet"], check=True)
    truth_file = tmp / "truth.csv"
    sim = subprocess.Popen([args.franka_python, str(ROOT / "crates/cps-franka/tests/sim_server.py"),
                            "--host", args.host, "--truth", str(truth_file)],
                           stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        if not sim.stdout.readline().startswith("ready"):
            sys.exit("franky-sim did not start")
        record = tmp / "franky.csv"
        subprocess.run([args.cli, "franka", "execute", str(learned / "trajectory.csv"), "--host",
                        args.host, "--record", str(record), "--realtime", "ignore", "--approach"],
                       check=True, stdout=subprocess.DEVNULL)
        sim.stdin.write("flush\n")
        sim.stdin.flush()
        if sim.stdout.readline().strip() != "flushed":
            sys.exit("franky-sim did not write its truth")
    finally:
        sim.kill()
    import json

    approach = round(json.loads((tmp / "franky.report.json").read_text())["approach_s"] * 1000)
    franky = rows(record)
    truth = rows(truth_file)
    key = lambda r, p: tuple(round(r[f"{p}{j}"], 6) for j in range(1, 8))  # noqa: E731
    by_q = {}
    for r in truth:
        by_q.setdefault(key(r, "q"), r)
    mujoco_t, mujoco = [], []
    for k in range(0, 10001, 10):
        step = by_q.get(key(franky[approach + k], "q"))
        if step is not None:
            mujoco_t.append(k / 1000)
            mujoco.append([step[a] + b for a, b in zip("xyz", BASE)])
    command = rows(learned / "trajectory.csv")
    executed = rows(learned / "recording.csv")

    def error(series_t, series, t, p):
        i = min(range(len(series_t)), key=lambda i: abs(series_t[i] - t))
        return 1e3 * math.dist(series[i], p)

    for name, st, s in [
        ("cps dynamics", [r["t"] for r in executed], [[r[f"tool_{a}"] for a in "xyz"] for r in executed]),
        ("franky-sim (MuJoCo)", mujoco_t, mujoco),
    ]:
        print(f"{name}: via points " + ", ".join(f"{error(st, s, t, p):.2f}" for t, p in VIAS) + " mm")
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for d, (ax, axis) in enumerate(zip(axes, "xyz")):
        ax.plot([r["t"] for r in command], [r[f"tool_{axis}"] for r in command],
                label="command (learned on the executions)", color="0.6", lw=1.2)
        ax.plot([r["t"] for r in executed], [r[f"tool_{axis}"] for r in executed],
                label="executed by cps's robot with dynamics", color="C0", lw=2.2)
        ax.plot(mujoco_t, [m[d] for m in mujoco], label="executed by franky-sim (MuJoCo's tool)",
                color="C3", lw=1.0, ls="--")
        for t, p in VIAS + [GOAL]:
            ax.plot(t, p[d], "ko", ms=4)
        ax.set_ylabel(f"{axis} [m]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    axes[-1].set_xlabel("t [s]")
    fig.suptitle("The via points (black), the learned command, and the two arms that executed it", fontsize=10)
    fig.tight_layout()
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
