"""A sweep of seeds x settings of the thesis's via-point experiment as Ray tasks.

    pip install ray
    python ray_sweep.py            # a local Ray (ray.init() starts one)
    RAY_ADDRESS=auto python ray_sweep.py   # the same code on a running Ray cluster

Every task is one call of `cps.learn_via_points` (threads=1: Ray spreads the tasks over
the cores); the same seed gives the same bits on any machine, so the results equal the
serial sweep's exactly, which the script checks. `cps.run_experiment(path, seed=s)`
sweeps any experiment file the same way.
"""

import itertools
import sys

import ray

import cps

TASK = dict(
    start=[0.75, 0.02, 1.87],
    goal=[0.55, -0.57, 1.45],
    via=[(2.0, [0.78, 0.60, 1.70]), (4.0, [1.12, 0.37, 1.45]),
         (6.0, [1.15, -0.15, 1.20]), (8.0, [0.90, -0.53, 1.20])],
    generations=3000,
    tol_fun=1e-3,
)
SEEDS = range(1, 5)
POPULATIONS = [16, 48, 96]


def one(seed, population):
    r = cps.learn_via_points(**TASK, population=population, seed=seed, threads=1)
    return {"seed": seed, "population": population, "cost": r.cost,
            "evaluations": r.evaluations, "gap": r.gap_to_optimum}


@ray.remote
def one_remote(seed, population):
    return one(seed, population)


def main():
    grid = list(itertools.product(SEEDS, POPULATIONS))
    ray.init(include_dashboard=False, log_to_driver=False)
    remote = ray.get([one_remote.remote(s, p) for s, p in grid])
    ray.shutdown()
    serial = [one(s, p) for s, p in grid]
    same = all(a["cost"] == b["cost"] and a["evaluations"] == b["evaluations"]
               for a, b in zip(remote, serial))
    print(f"{'seed':>4} {'pop':>4} {'evaluations':>11} {'cost':>10} {'gap':>9}")
    for r in remote:
        print(f"{r['seed']:>4} {r['population']:>4} {r['evaluations']:>11} {r['cost']:>10.6f} {r['gap']:>9.2e}")
    print(f"Ray results equal the serial sweep bit for bit: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
