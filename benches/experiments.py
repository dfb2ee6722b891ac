"""Every shipped experiment as a user runs it: the whole process, median of five.

    cargo build --release -p cps-cli
    python3 benches/experiments.py [--cli target/release/cps-cli] [--runs 5] [--threads 2]

Runs `cps-cli run experiments/NAME.toml --quiet --threads 2` for each file in
`experiments/` that needs no robot (the Franka, ROS 2 and contact files need one), into a
temporary directory, and prints per file the median wall time of the whole process
(start-up, learning, figures, report, files) with every run's time, and what it learned:
the cost and the worst via-point or goal error from its summary.json. Compare two builds
by running it with each `--cli`.
"""

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NEEDS_A_ROBOT = {"contact"}


def learned(s):
    """(cost, worst position error in m) of a summary, where the kind has them."""
    kind = s["kind"]
    if kind == "viapoint":
        return s["best_cost"], s["max_position_error_m"]
    if kind == "scaling":
        best = min(s["arms"], key=lambda a: a["final_cost_mean"])
        return best["final_cost_mean"], max(best["max_position_error_m"])
    if kind in ("viapoint_joint", "viapoint_energy"):
        return s["cost"], s["max_position_error_m"]
    if kind == "viapoint_pose":
        return s["position_cost"] + s["orientation_cost"], max(s["via_errors_m"] + [s["goal_error_m"]])
    if kind == "viapoint_executed":
        return s["best_cost"], max(s["via_errors_m"])
    return None, None


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cli", default=str(ROOT / "target/release/cps-cli"))
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    if not Path(args.cli).exists():
        sys.exit(f"{args.cli} does not exist: build it with `cargo build --release -p cps-cli`")
    files = sorted(p for p in (ROOT / "experiments").glob("*.toml") if p.stem not in NEEDS_A_ROBOT)
    print(f"{'experiment':20} {'median':>8}  {'cost':>12}  {'worst error':>12}  runs")
    with tempfile.TemporaryDirectory() as out:
        for f in files:
            times = []
            for _ in range(args.runs):
                started = time.perf_counter()
                run = subprocess.run([args.cli, "run", str(f), "--out", f"{out}/{f.stem}", "--force",
                                      "--quiet", "--threads", str(args.threads)], capture_output=True, text=True)
                times.append(time.perf_counter() - started)
                if run.returncode != 0:
                    sys.exit(f"{f.name}: exit {run.returncode}: {run.stderr.strip()}")
            cost, error = learned(json.loads(Path(f"{out}/{f.stem}/summary.json").read_text()))
            cost = "—" if cost is None else f"{cost:.6g}"
            error = "—" if error is None else f"{error * 1e3:.4f} mm"
            print(f"{f.stem:20} {statistics.median(times):7.2f}s  {cost:>12}  {error:>12}  "
                  + " ".join(f"{t:.2f}" for t in times), flush=True)


if __name__ == "__main__":
    main()
