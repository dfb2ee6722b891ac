"""Shared helpers: the repository, the command line to compare against, a numpy DMP."""

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENTS = ROOT / "experiments"


def _find_cli():
    """The cps-cli binary: $CPS_CLI, else a build in the repository's target/."""
    env = os.environ.get("CPS_CLI")
    if env:
        return env
    for profile in ("checked", "release", "debug"):
        p = ROOT / "target" / profile / "cps-cli"
        if p.is_file():
            return str(p)
    return shutil.which("cps-cli")


@pytest.fixture(scope="session")
def cli():
    """Runs cps-cli and returns the completed process. In CI (CI=1) a missing binary is a
    failure, elsewhere the comparison tests are skipped."""
    exe = _find_cli()
    if exe is None:
        if os.environ.get("CI"):
            pytest.fail("cps-cli not found: build it (cargo build --profile checked -p cps-cli) or set CPS_CLI")
        pytest.skip("cps-cli not found (set CPS_CLI to compare against the command line)")

    def run(*args, check=True, cwd=None):
        p = subprocess.run([exe, *map(str, args)], capture_output=True, text=True, cwd=cwd)
        if check and p.returncode != 0:
            raise AssertionError(f"cps-cli {' '.join(map(str, args))} exited {p.returncode}:\n{p.stderr}")
        return p

    return run


def read_csv(path):
    """A CSV with a header as {column: float array}; shortest round-trip decimals parse to
    the same doubles cps wrote."""
    lines = Path(path).read_text().splitlines()
    header = lines[0].split(",")
    columns = list(zip(*[line.split(",") for line in lines[1:]])) or [()] * len(header)

    def parse(cells):
        try:
            return np.array([float(v) if v != "" else float("nan") for v in cells])
        except ValueError:
            return list(cells)  # a text column

    return {name: parse(cells) for name, cells in zip(header, columns)}


def reference_dmp(start, goal, weights, centers, widths, tau, dt, alpha_z=25.0, beta_z=None,
                  alpha_x=None, formulation="ijspeert", substeps=20):
    """A discrete DMP integrated by classic Runge-Kutta with `substeps` steps per grid step,
    written from the equations (Ijspeert et al. 2013; Hoffmann/Pastor 2009):

        tau z' = alpha_z (beta_z (g - y) - z) + f(x),   tau y' = z,   x(t) = exp(-alpha_x t / tau)
        Phi(x) w = x sum_i psi_i(x) w_i / sum_i psi_i(x),  psi_i = exp(-h_i (x - c_i)^2)
        ijspeert: f = (g - y0) Phi(x) w;   robust: f = alpha_z beta_z (Phi(x) w - (g - y0) x)

    Returns t, y, yd, ydd with y of shape (samples, dims)."""
    beta_z = alpha_z / 4.0 if beta_z is None else beta_z
    alpha_x = alpha_z / 3.0 if alpha_x is None else alpha_x
    start, goal, weights = map(np.asarray, (start, goal, weights))
    k_steps = int(round(tau / dt))
    h = tau / k_steps

    def forcing(t):
        x = np.exp(-alpha_x * t / tau)
        psi = np.exp(-widths * (x - centers) ** 2)
        phi_w = x * (weights @ psi) / psi.sum()
        if formulation == "ijspeert":
            return (goal - start) * phi_w
        return alpha_z * beta_z * (phi_w - (goal - start) * x)

    def deriv(t, s):
        y, z = s
        zd = (alpha_z * (beta_z * (goal - y) - z) + forcing(t)) / tau
        return np.array([z / tau, zd])

    s = np.array([start, np.zeros_like(start)], dtype=float)
    ts, ys, zs, zds = [], [], [], []
    for k in range(k_steps + 1):
        t = k * h
        ts.append(t)
        ys.append(s[0].copy())
        zs.append(s[1].copy())
        zds.append(deriv(t, s)[1])
        if k == k_steps:
            break
        hh = h / substeps
        for j in range(substeps):
            tt = t + j * hh
            k1 = deriv(tt, s)
            k2 = deriv(tt + hh / 2, s + hh / 2 * k1)
            k3 = deriv(tt + hh / 2, s + hh / 2 * k2)
            k4 = deriv(tt + hh, s + hh * k3)
            s = s + hh / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return np.array(ts), np.array(ys), np.array(zs) / tau, np.array(zds) / tau
