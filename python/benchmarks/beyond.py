"""cps's ProMPs and obstacle avoidance beside movement_primitives, on the same data.

    pip install ./python movement-primitives pytransform3d scipy   # from the repository root
    python python/benchmarks/beyond.py

1. ProMPs: 20 demonstrations × 1000 samples × 3 dimensions (a sine, a cosine and a
   parabola with seeded offsets and gains, as benches/core.rs `promp/*` builds them),
   25 basis functions: fitting, conditioning on one exact via point, drawing 1000
   trajectories of 1000 samples.
2. A 3-D DMP (10 basis functions, τ = 1 s, dt = 1 ms) rolled out without and with the
   steering-angle obstacle term (Hoffmann et al. 2009, the same default gains).

Both libraries are called from Python; criterion's `promp/*` and `obstacle/*` are the
Rust figures. Timings are the best of several repetitions (the machine is shared).
"""

import timeit

import numpy as np

import cps


def best(f, number=1, repeat=5):
    return min(timeit.repeat(f, number=number, repeat=repeat)) / number


def fmt(s):
    return f"{s * 1e6:9.1f} µs" if s < 1e-3 else f"{s * 1e3:9.2f} ms"


def demos():
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 1.0, 1000)
    out = []
    for _ in range(20):
        a, b, c, d = rng.uniform(-0.1, 0.1), rng.uniform(-0.05, 0.05), rng.uniform(-0.1, 0.1), rng.uniform(-0.05, 0.05)
        y = np.column_stack([np.sin(2 * np.pi * t + a) + b, np.cos(np.pi * t) * (1 + c), t**2 + d])
        out.append((t, y))
    return out


def promps():
    from movement_primitives.promp import ProMP

    d = demos()
    t = d[0][0]
    rows = []
    fit = best(lambda: cps.ProMP.fit(d, bases=25, duration=1.0))
    p = cps.ProMP.fit(d, bases=25, duration=1.0)
    cond = best(lambda: p.condition(0.5, [0.5, 0.2, 0.3], 0.0), number=100)
    samp = best(lambda: p.sample(1000, t, seed=1), repeat=3)
    Ts = np.array([t] * 20)
    Ys = np.array([y for _, y in d])
    ref_fit = best(lambda: ProMP(n_dims=3, n_weights_per_dim=25).imitate(Ts, Ys), repeat=3)
    ref = ProMP(n_dims=3, n_weights_per_dim=25)
    ref.imitate(Ts, Ys)
    ref_cond = best(lambda: ref.condition_position(np.array([0.5, 0.2, 0.3]), t=0.5, t_max=1.0), number=100)
    ref_samp = best(lambda: ref.sample_trajectories(t, 1000, np.random.RandomState(1)), repeat=3)
    rows.append(("ProMP fit 20×1000×3, 25 bases", fit, ref_fit))
    rows.append(("ProMP condition on 1 via point", cond, ref_cond))
    rows.append(("ProMP 1000 samples × 1000 × 3", samp, ref_samp))
    return rows


def obstacles():
    from movement_primitives.dmp import DMP, CouplingTermObstacleAvoidance3D

    w = np.random.default_rng(5).normal(0, 100, (3, 10))
    ours = cps.DMP([0, 0, 0], [1, 1, 1], tau=1.0, dt=0.001, bases=10, weights=w)
    plain = best(lambda: ours.rollout(), number=20)
    steer = best(lambda: ours.rollout_avoiding([[0.5, 0.5, 0.5]]), number=20)
    ref = DMP(n_dims=3, execution_time=1.0, n_weights_per_dim=10, dt=0.001)
    ref.configure(start_y=np.zeros(3), goal_y=np.ones(3))
    ref.set_weights(w.ravel())
    term = CouplingTermObstacleAvoidance3D(0.5 * np.ones(3))
    ref_plain = best(lambda: ref.open_loop(), repeat=3)
    ref_steer = best(lambda: ref.open_loop(coupling_term=term), repeat=3)
    return [
        ("DMP rollout 3×10×1000, no coupling", plain, ref_plain),
        ("DMP rollout 3×10×1000, steering angle", steer, ref_steer),
    ]


def main():
    print(f"{'':42} {'cps':>12} {'movement_primitives':>20} {'ratio':>8}")
    for name, a, b in promps() + obstacles():
        print(f"{name:42} {fmt(a):>12} {fmt(b):>20} {b / a:7.0f}×")


if __name__ == "__main__":
    main()
