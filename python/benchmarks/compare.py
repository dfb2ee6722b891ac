"""cps from Python against the Python libraries of the same tasks, side by side in one run.

    pip install ./python cma movement_primitives pydmps      # from the repository root
    python python/benchmarks/compare.py

Prints per-call costs of cps from Python (to set beside the Rust criterion figures in
BENCHMARKS.md), imitate + rollout of a 3-D 1000-sample demonstration in cps,
movement_primitives and pydmps, and the thesis's 200-generation via-point run in cps and
in numpy + pycma. Libraries that are not installed are skipped. Timings are the best of
several repetitions (the machine is shared).
"""

import time
import timeit

import numpy as np

import cps


def best(f, number, repeat=7):
    """Seconds per call: the best of `repeat` batches of `number` calls."""
    return min(timeit.repeat(f, number=number, repeat=repeat)) / number


def fmt(s):
    return f"{s * 1e6:9.1f} µs" if s < 1e-3 else f"{s * 1e3:9.2f} ms"


def per_call():
    print("== per call, cps from Python")
    dmp = cps.DMP([0.75, 0.02, 1.87], [0.55, -0.57, 1.45], tau=10.0, dt=0.01, bases=25,
                  weights=np.random.default_rng(1).normal(size=(3, 25)) * 100)
    print(f"rollout 3x25x1000 (t, y, yd, ydd arrays)    {fmt(best(dmp.rollout, 2000))}")
    W = np.random.default_rng(2).normal(size=(16, 3, 25))
    print(f"rollout_batch 16x3x25x1000 (positions)      {fmt(best(lambda: dmp.rollout_batch(W), 200))}")
    s = dmp.stepper()
    print(f"Stepper.step, 3-D                           {fmt(best(lambda: s.step(0.001), 20000))}")
    es = cps.CMAES(np.zeros(75), 0.5, seed=1, maxiter=10**9, tolfun=0, tolx=0)
    f = np.arange(es.popsize, dtype=float)

    def generation():
        es.tell(es.ask(), f)

    print(f"CMAES ask + tell, n = 75, popsize 16         {fmt(best(generation, 200))}")
    panda = cps.Robot("panda")
    q = panda.ready
    print(f"Robot.fk, Panda                             {fmt(best(lambda: panda.fk(q), 20000))}")
    Q = np.tile(q, (1000, 1))
    print(f"Robot.fk, Panda, 1000 rows batched          {fmt(best(lambda: panda.fk(Q), 50))}")
    target = panda.fk(q + 0.1)
    print(f"Robot.ik, Panda, full pose                  {fmt(best(lambda: panda.ik(target), 200))}")


def demonstration():
    t = np.linspace(0.0, 10.0, 1000)
    y = np.column_stack([0.75 + 0.3 * np.sin(0.5 * t), 0.02 + 0.4 * np.sin(0.3 * t) ** 2,
                         1.87 - 0.04 * t])
    return t, y


def imitation():
    print("\n== imitate + rollout of a 3-D, 1000-sample demonstration, 25 bases")
    t, y = demonstration()

    def with_cps():
        return cps.imitate(t, y, bases=25).rollout()

    fresh = iter(range(10**9))

    def with_cps_new_configuration():
        # Another duration each call: nothing of an earlier call's grid can be reused.
        return cps.imitate(t, y, bases=25, tau=10.0 + 1e-9 * next(fresh)).rollout()

    times = {"cps": best(with_cps, 50),
             "cps, a new configuration": best(with_cps_new_configuration, 50)}
    try:
        from movement_primitives.dmp import DMP

        def with_mp():
            d = DMP(n_dims=3, execution_time=10.0, dt=0.01, n_weights_per_dim=25)
            d.imitate(t, y)
            return d.open_loop()

        times["movement_primitives"] = best(with_mp, 3, repeat=3)
    except ImportError:
        print("movement_primitives not installed: skipped")
    try:
        import pydmps

        def with_pydmps():
            d = pydmps.dmp_discrete.DMPs_discrete(n_dmps=3, n_bfs=25, dt=0.001)
            d.imitate_path(y_des=y.T)
            return d.rollout()

        times["pydmps"] = best(with_pydmps, 3, repeat=3)
    except ImportError:
        print("pydmps not installed: skipped")
    for name, s in times.items():
        print(f"{name:22s} {fmt(s)}   ({s / times['cps']:7.0f}x cps)")


THESIS = dict(start=[0.75, 0.02, 1.87], goal=[0.55, -0.57, 1.45],
              via=[(2.0, [0.78, 0.60, 1.70]), (4.0, [1.12, 0.37, 1.45]),
                   (6.0, [1.15, -0.15, 1.20]), (8.0, [0.90, -0.53, 1.20])])


def numpy_pycma_viapoint(generations=200, seed=1, vectorised=True):
    """The thesis task in numpy + pycma at its best: the rollout is affine in the weights,
    so it is integrated once per basis weight (semi-implicit Euler, dt = 0.01) and every
    candidate's trajectory is one matrix product; CMA-ES is pycma's."""
    import cma

    n_basis, tau, dt, az = 25, 10.0, 0.01, 25.0
    bz, ax = az / 4, az / 3
    k = int(round(tau / dt))
    ts = np.arange(k + 1) * dt
    x = np.exp(-ax * ts / tau)
    c = np.exp(-ax * np.arange(n_basis) / (n_basis - 1))
    h = np.append(1 / np.diff(c) ** 2, 1 / (c[-1] - c[-2]) ** 2)
    psi = np.exp(-h * (x[:, None] - c) ** 2)
    phi = x[:, None] * psi / psi.sum(axis=1, keepdims=True)  # (samples, bases)
    y0, g = np.array(THESIS["start"]), np.array(THESIS["goal"])

    def integrate(f):
        """Integrates m forcing terms at once: f (samples, m, dims) -> positions,
        velocities and accelerations, each (samples, m, dims)."""
        m = f.shape[1]
        y, z = np.tile(y0, (m, 1)), np.zeros((m, 3))
        ys, vs, acc = (np.empty((k + 1, m, 3)) for _ in range(3))
        for i in range(k + 1):
            zd = (az * (bz * (g - y) - z) + f[i]) / tau
            ys[i], vs[i], acc[i] = y, z / tau, zd / tau
            z = z + zd * dt
            y = y + z / tau * dt
        return ys, vs, acc

    # Column 0: zero weights; column 1 + d * n_basis + b: a unit weight b on dimension d.
    forcing = np.zeros((k + 1, 1 + 3 * n_basis, 3))
    for d in range(3):
        for b in range(n_basis):
            forcing[:, 1 + d * n_basis + b, d] = (g[d] - y0[d]) * phi[:, b]
    runs = integrate(forcing)
    base = [r[:, 0, :] for r in runs]
    A = [np.moveaxis(r[:, 1:, :] - r[:, :1, :], 1, 2) for r in runs]  # (samples, 3, 75)
    via_idx = [int(round(tv / dt)) for tv, _ in THESIS["via"]]
    via_pos = np.array([p for _, p in THESIS["via"]])

    def cost(w):
        y = base[0] + A[0] @ w
        v = base[1][-1] + A[1][-1] @ w
        a = base[2] + A[2] @ w
        return (1e5 * np.sum((y[-1] - g) ** 2) + 1e5 * np.sum((y[via_idx] - via_pos) ** 2)
                + 1e3 * np.sum(v ** 2) + 1e-2 * np.sum(a ** 2))

    # The whole population at once: one matrix product per quantity and generation.
    rows = via_idx + [k]
    Ay = A[0][rows].reshape(-1, 75)
    Av = A[1][-1]
    Aa = A[2].reshape(-1, 75)
    target = np.vstack([via_pos, g])

    def costs(X):
        X = np.asarray(X)
        y = base[0][rows][None] + (X @ Ay.T).reshape(len(X), len(rows), 3)
        v = base[1][-1] + X @ Av.T
        a = base[2].ravel() + X @ Aa.T
        return (1e5 * ((y - target) ** 2).sum(axis=(1, 2)) + 1e3 * (v ** 2).sum(axis=1)
                + 1e-2 * (a ** 2).sum(axis=1))

    es = cma.CMAEvolutionStrategy(np.zeros(75), 50.0, {"seed": seed, "verbose": -9, "popsize": 16,
                                                       "maxiter": generations, "tolfun": 0,
                                                       "tolx": 0, "tolstagnation": 10 ** 9})
    while not es.stop():
        X = es.ask()
        es.tell(X, list(costs(X)) if vectorised else [cost(w) for w in X])
    return es.result.fbest


def viapoint():
    print("\n== the thesis's via-point task, 200 generations, popsize 16, one thread")
    t0 = time.perf_counter()
    r = cps.learn_via_points(**THESIS, population=16, generations=200, tol_fun=None, threads=1)
    ours = time.perf_counter() - t0
    print(f"cps.learn_via_points   {fmt(ours)}   (cost {r.cost:.4f}, {r.generations} generations)")
    try:
        for vectorised, label in [(False, "numpy + pycma, per candidate"),
                                  (True, "numpy + pycma, vectorised")]:
            t0 = time.perf_counter()
            f = numpy_pycma_viapoint(vectorised=vectorised)
            theirs = time.perf_counter() - t0
            print(f"{label:29s} {fmt(theirs)}   (cost {f:.4f}; {theirs / ours:.0f}x cps)")
    except ImportError:
        print("cma not installed: skipped")
    print("(the costs differ: cps searches anchor offsets in metres, the numpy version raw weights)")


def whole_process():
    """The same 200 generations as whole processes, interpreter start and imports included."""
    import subprocess
    import sys

    print("\n== the same, whole process (python -c ..., best of 3)")
    ours = ("import cps; cps.learn_via_points([0.75, 0.02, 1.87], [0.55, -0.57, 1.45], "
            "[(2.0, [0.78, 0.60, 1.70]), (4.0, [1.12, 0.37, 1.45]), (6.0, [1.15, -0.15, 1.20]), "
            "(8.0, [0.90, -0.53, 1.20])], population=16, generations=200, tol_fun=None, threads=1)")
    theirs = ("import sys; sys.path.insert(0, %r); import compare; compare.numpy_pycma_viapoint()"
              % str(__import__("pathlib").Path(__file__).parent))
    times = {}
    for label, code in [("cps", ours), ("numpy + pycma (vectorised)", theirs)]:
        runs = []
        for _ in range(3):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], check=True)
            runs.append(time.perf_counter() - t0)
        times[label] = min(runs)
        print(f"{label:29s} {fmt(times[label])}   ({times[label] / times['cps']:.1f}x cps)")


if __name__ == "__main__":
    per_call()
    imitation()
    viapoint()
    whole_process()
