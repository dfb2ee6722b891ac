"""How long an action takes from LeRobot's `send_action` to cps's 1 kHz loop.

Drives `cps_dynamics` (cps's simulated FR3, its loop held to the wall clock) with a 30 Hz
swing for N seconds, as LeRobot's scripts do; for each action, the executor's clock just
before `send_action` hands it over, and the clock at which the loop took it (each chunk's
`arrived_s`, stamped by the loop). Prints the delay's median, p99 and worst, in ms.

    target/lerobot-venv/bin/python python/benchmarks/lerobot_delay.py --seconds 20
"""

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from lerobot_robot_cps import CpsDynamics, CpsDynamicsConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--fps", type=float, default=30.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        robot = CpsDynamics(CpsDynamicsConfig(record=Path(d) / "run.csv", velocities=False, efforts=False))
        robot.connect()
        handed = []
        try:
            q0 = np.array([robot.get_observation()[f"joint{i}.pos"] for i in range(1, 8)])
            n = int(args.seconds * args.fps)
            for k in range(n):
                start = time.perf_counter()
                q = q0.copy()
                q[0] += 0.3 * math.sin(2 * math.pi * k / n)
                t = robot._ex.observe()["t"]
                robot.send_action({f"joint{i + 1}.pos": q[i] for i in range(7)})
                handed.append(t)
                time.sleep(max(0.0, 1.0 / args.fps - (time.perf_counter() - start)))
        finally:
            robot.disconnect()
        arrived = [c["arrived_s"] for c in robot.last_run["chunks"]]
    delay_ms = 1e3 * (np.array(arrived) - np.array(handed[: len(arrived)]))
    print(f"{len(delay_ms)} actions at {args.fps:g} Hz: send_action to the 1 kHz loop "
          f"median {np.median(delay_ms):.2f} ms, p99 {np.percentile(delay_ms, 99):.2f} ms, "
          f"worst {delay_ms.max():.2f} ms (the loop's period is 1 ms; the state read before "
          f"the call is up to one period old)")


if __name__ == "__main__":
    main()
