"""CMA-ES: evaluation counts against pycma (installed in the test venv), the command
line's reference runs bit for bit, ask/tell against fmin, bounds, restarts, determinism,
exceptions and bad input."""

import json
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import cps

cma = pytest.importorskip("cma")


def sphere(x):
    return sum(v * v for v in x)  # left to right, as cps's Rust sphere sums


def ellipsoid(x):
    n = len(x)
    return sum(10.0 ** (6.0 * i / (n - 1)) * x[i] * x[i] for i in range(n))


def rosenbrock(x):
    return sum(100.0 * (x[i + 1] - x[i] ** 2) ** 2 + (1.0 - x[i]) ** 2 for i in range(len(x) - 1))


def start(name, n):
    return (np.zeros(n), 0.5) if name == "rosenbrock" else (np.full(n, 3.0), 2.0)


FUNCTIONS = {"sphere": sphere, "ellipsoid": ellipsoid, "rosenbrock": rosenbrock}
PYCMA = {"sphere": cma.ff.sphere, "ellipsoid": cma.ff.elli, "rosenbrock": cma.ff.rosen}


@pytest.mark.parametrize("name", ["sphere", "ellipsoid", "rosenbrock"])
def test_evaluation_counts_are_within_15_percent_of_pycma(name):
    n = 10
    x0, sigma0 = start(name, n)
    assert abs(PYCMA[name](x0 + 0.3) - FUNCTIONS[name](x0 + 0.3)) < 1e-9 * (1 + FUNCTIONS[name](x0 + 0.3))
    ours, theirs = [], []
    for seed in range(1, 11):
        res = cps.fmin(FUNCTIONS[name], x0, sigma0, {"ftarget": 1e-8, "seed": seed})
        if res.fbest <= 1e-8:
            ours.append(res.evaluations)
        es = cma.CMAEvolutionStrategy(x0, sigma0, {"ftarget": 1e-8, "seed": seed, "verbose": -9})
        es.optimize(PYCMA[name])
        if es.result.fbest <= 1e-8:
            theirs.append(es.result.evaluations)
    assert len(ours) >= (8 if name == "rosenbrock" else 10)
    ratio = np.median(ours) / np.median(theirs)
    print(f"{name}: cps median {np.median(ours):.0f}, pycma {np.median(theirs):.0f}, ratio {ratio:.3f}")
    assert 0.85 <= ratio <= 1.15, (name, np.median(ours), np.median(theirs))


def test_fmin_equals_the_command_lines_reference_runs_bit_for_bit(cli):
    # `cps-cli cmaes bench` runs cps's Rust sphere in the same set-up (pycma's default
    # termination, ftarget 1e-8, a budget of 2e6 n evaluations).
    out = cli("cmaes", "bench", "ellipsoid", "--dim", 10, "--seeds", "1..4", "--json")
    for run in json.loads(out.stdout):
        res = cps.fmin(ellipsoid, np.full(10, 3.0), 2.0,
                       {"ftarget": 1e-8, "seed": run["seed"], "maxfevals": 2e7})
        assert res.evaluations == run["evaluations"]
        assert res.fbest == run["best"]


def test_ask_and_tell_equal_fmin_and_the_vectorised_objective():
    x0 = np.full(6, 3.0)
    es = cps.CMAES(x0, 2.0, {"seed": 5, "ftarget": 1e-10})
    while not es.stop():
        X = es.ask()
        assert X.shape == (es.popsize, 6)
        es.tell(X, [sphere(x) for x in X])
    res = cps.fmin(sphere, x0, 2.0, {"seed": 5, "ftarget": 1e-10})
    vec = cps.fmin(None, x0, 2.0, {"seed": 5, "ftarget": 1e-10},
                   parallel_objective=lambda X: (X * X).sum(axis=1))
    assert es.result.evaluations == res.evaluations == vec.evaluations
    assert np.array_equal(es.result.xbest, res.xbest)
    assert es.stop() == {"ftarget": 1e-10} == res.stop
    assert res.evals_best <= res.evaluations
    # es.optimize runs the same loop.
    es2 = cps.CMAES(x0, 2.0, seed=5, ftarget=1e-10).optimize(sphere)
    assert es2.result.fbest == es.result.fbest


def test_the_same_seed_gives_the_same_bits_and_another_seed_another_run():
    a = cps.fmin(rosenbrock, np.zeros(8), 0.5, {"seed": 11, "maxfevals": 3000})
    b = cps.fmin(rosenbrock, np.zeros(8), 0.5, {"seed": 11, "maxfevals": 3000})
    c = cps.fmin(rosenbrock, np.zeros(8), 0.5, {"seed": 12, "maxfevals": 3000})
    assert np.array_equal(a.xbest, b.xbest) and a.fbest == b.fbest
    assert a.fbest != c.fbest
    assert a.stop == {"maxfevals": 3000}


def test_bounds_keep_every_candidate_in_the_box():
    lower, upper = np.full(5, 1.0), np.array([2.0, 2.0, 2.0, 2.0, np.inf])
    es = cps.CMAES(np.full(5, 1.5), 0.3, bounds=[lower, upper], seed=2)  # sigma0 ~ box / 3
    seen = []
    es.optimize(lambda x: seen.append(x.copy()) or sphere(x), iterations=400)
    seen = np.array(seen)
    assert (seen >= lower).all() and (seen <= upper).all()
    np.testing.assert_allclose(es.result.xbest, np.ones(5), atol=1e-4)  # the optimum is on the bound
    res = cps.fmin(sphere, [1.5] * 3, 0.5, {"bounds": [1.0, None], "ftarget": 3.0 + 1e-12, "seed": 1})
    assert (res.xbest >= 1.0).all() and res.fbest <= 3.0 + 1e-12


def test_ipop_and_bipop_solve_rastrigin():
    def rastrigin(x):
        x = np.asarray(x)
        return 10 * len(x) + float((x * x - 10 * np.cos(2 * np.pi * x)).sum())

    single = cps.fmin(rastrigin, np.full(5, 3.0), 2.0, {"ftarget": 1e-8, "seed": 3})
    ipop = cps.fmin(rastrigin, np.full(5, 3.0), 2.0, {"ftarget": 1e-8, "seed": 3}, restarts=9)
    bipop = cps.fmin(rastrigin, np.full(5, 3.0), 2.0, {"ftarget": 1e-8, "seed": 3}, restarts=9, bipop=True)
    assert single.fbest > 1e-8
    assert ipop.fbest <= 1e-8 and bipop.fbest <= 1e-8
    assert ipop.evaluations > single.evaluations


def test_nan_costs_rank_last_and_exceptions_propagate():
    rng = np.random.default_rng(0)
    res = cps.fmin(lambda x: np.nan if rng.random() < 0.3 else sphere(x), np.full(5, 3.0), 2.0,
                   {"ftarget": 1e-8, "seed": 4})
    assert res.fbest <= 1e-8

    class Boom(Exception):
        pass

    calls = []

    def f(x):
        calls.append(1)
        if len(calls) == 25:
            raise Boom("simulator died")
        return sphere(x)

    with pytest.raises(Boom, match="simulator died"):
        cps.fmin(f, np.zeros(4), 1.0)
    with pytest.raises(ValueError, match="not a number"):
        cps.fmin(lambda x: "cheap", np.zeros(4), 1.0)


def test_tell_takes_exactly_the_asked_candidates():
    es = cps.CMAES(np.zeros(4), 1.0, seed=1)
    with pytest.raises(ValueError, match="call ask"):
        es.tell(np.zeros((es.popsize, 4)), np.zeros(es.popsize))
    X = es.ask()
    assert np.array_equal(es.ask(), X)  # asking again returns the same candidates
    with pytest.raises(ValueError, match="f: expected 8 costs"):
        es.tell(X, np.zeros(3))
    Y = X.copy()
    Y[2, 1] += 1e-3
    with pytest.raises(ValueError, match="candidate 2 is not the one ask"):
        es.tell(Y, np.zeros(es.popsize))
    with pytest.raises(ValueError, match="X: expected 4 columns"):
        es.tell(X[:, :3], np.zeros(es.popsize))
    es.tell(list(X), list(np.arange(es.popsize, dtype=float)))  # lists work, as with pycma
    assert es.countiter == 1 and es.countevals == es.popsize


@pytest.mark.parametrize("options, pattern", [
    ({"popsize": 1}, "popsize"),
    ({"seed": -1}, "seed"),
    ({"bounds": [2.0, 1.0]}, "bounds"),
    ({"bounds": [0.0]}, "bounds: expected \\[lower, upper\\]"),
    ({"maxiter": "many"}, "maxiter: expected a number"),
    ({"CMA_stds": [1.0, 2.0]}, "CMA_stds: expected 3 values"),
    ({"tolx": float("nan")}, "tolx: must not be NaN"),
])
def test_bad_options_name_the_option(options, pattern):
    with pytest.raises(ValueError, match=pattern):
        cps.CMAES(np.zeros(3), 1.0, options)
    with pytest.raises(ValueError):
        cps.CMAES(np.zeros(3), -1.0)


# Each script first restores Python's Ctrl-C handler: a shell that starts the tests in the
# background (`cmd &`) hands them SIGINT ignored, and Python then leaves it ignored.
FMIN_SCRIPT = textwrap.dedent("""
    import signal, time, numpy as np, cps
    signal.signal(signal.SIGINT, signal.default_int_handler)
    print("started", flush=True)
    try:
        cps.fmin(lambda x: time.sleep(0.001) or float(x @ x), np.ones(20), 1.0,
                 {"maxfevals": 10**9, "ftarget": -1, "tolfun": 0, "tolx": 0})
    except KeyboardInterrupt:
        print("interrupted", flush=True)
""")


def test_ctrl_c_stops_fmin_with_keyboard_interrupt():
    p = subprocess.Popen([sys.executable, "-c", FMIN_SCRIPT], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "started"
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    out, _ = p.communicate(timeout=30)
    assert "interrupted" in out and p.returncode == 0
