"""Beyond DMPs, against movement_primitives (installed from PyPI) on its own scenarios and
against formulas: obstacle avoidance, retargeting a circle, sequences, ProMP blending,
files and a ProMP as CMA-ES's start."""

import numpy as np
import pytest

import cps

mp_dmp = pytest.importorskip("movement_primitives.dmp")
from scipy.spatial.distance import cdist  # noqa: E402


def test_obstacle_avoidance_keeps_the_same_distances_as_movement_primitives():
    # movement_primitives' test: start 0.2 + 0.2 randn (numpy seed 42), goal 1, obstacle
    # 0.5, 10 weights, dt 0.01, its steering-angle term with the same default gains.
    rs = np.random.RandomState(42)
    obstacle = 0.5 * np.ones(2)
    ours, theirs = [], []
    for _ in range(20):
        start = 0.2 + 0.2 * rs.randn(2)
        ref = mp_dmp.DMP(n_dims=2, execution_time=1.0, n_weights_per_dim=10, dt=0.01)
        ref.configure(start_y=start, goal_y=np.ones(2))
        _, Y = ref.open_loop(coupling_term=mp_dmp.CouplingTermObstacleAvoidance2D(obstacle))
        dmp = cps.DMP(start, [1.0, 1.0], tau=1.0, dt=0.01, bases=10)
        _, y, _, _ = dmp.rollout_avoiding([obstacle])
        theirs.append(cdist(Y, obstacle[None]).min())
        ours.append(cdist(y, obstacle[None]).min())
        assert np.linalg.norm(y[-1] - 1.0) < 1e-2
    ours, theirs = np.array(ours), np.array(theirs)
    assert ours.min() > 0.1 and theirs.min() > 0.1
    # Euler steps there, exact steps here: the distances agree on average to 5 mm.
    assert np.abs(ours - theirs).mean() < 5e-3, (ours, theirs)
    # Without avoidance the straight path passes through the obstacle.
    _, y, _, _ = cps.DMP([0, 0], [1, 1], tau=1.0, dt=0.01, bases=10).rollout()
    assert cdist(y, obstacle[None]).min() < 0.03
    # The dynamic potential field keeps away too; an obstacle on the goal is refused.
    _, y, _, _ = dmp.rollout_avoiding([obstacle], avoidance="potential")
    assert cdist(y, obstacle[None]).min() > 0.1
    with pytest.raises(ValueError, match="from the movement's goal"):
        dmp.rollout_avoiding([[1.0, 1.0]])
    with pytest.raises(ValueError, match="steering"):
        dmp.rollout_avoiding([obstacle], avoidance="magnets")


def circle():
    t = np.linspace(0, 1, 101)
    a = t**2 * 1.99 * np.pi
    return t, np.column_stack([np.sin(a), np.cos(a)])


def test_a_retargeted_circle_matches_movement_primitives_smooth_scaling():
    t, y = circle()
    start, goal = np.array([5.0, 0.5]), np.array([-5.0, 0.5])
    ref = mp_dmp.DMP(n_dims=2, execution_time=1.0, dt=0.01, n_weights_per_dim=20)
    ref.imitate(t, y)
    ref.configure(start_y=start, goal_y=goal)
    ref.smooth_scaling = False
    _, plain = ref.open_loop()
    ref.smooth_scaling = True
    _, smooth = ref.open_loop()
    dmp = cps.imitate(t, y, bases=20, formulation="robust", dt=0.01)
    _, moved, _, acc = dmp.retarget(start, goal, mode="translate").rollout()
    peak = lambda p: np.abs(np.gradient(np.gradient(p, axis=0), axis=0)).max()  # noqa: E731
    # movement_primitives' plain form pulls the whole 10 m at once; its smooth scaling
    # and ours take it up with the phase (its phase decays slower, e^-4.6 against cps's
    # e^-8.3 at τ, so its transfer is gentler): both far below the plain form.
    assert peak(smooth) < 0.2 * peak(plain)
    assert peak(moved) < 0.3 * peak(plain) and peak(moved) < 1.5 * peak(smooth)
    assert np.linalg.norm(moved[-1] - goal) < 0.1
    # "rotate" (the default) turns the shape: its start→goal direction is the new one.
    rotated = dmp.retarget([0.0, 0.0], [0.0, 3.0])
    assert rotated.formulation == "robust"
    with pytest.raises(ValueError, match="rotate"):
        dmp.retarget(start, goal, mode="mirror")


def test_a_sequence_is_c2_at_its_junction_and_c1_is_not():
    def across(dt, junction):
        a = cps.DMP([0.0], [1.0], tau=1.0, dt=dt, bases=8, weights=np.full((1, 8), 30.0))
        b = cps.DMP([0.0], [-0.5], tau=1.5, dt=dt, bases=8, weights=np.full((1, 8), -20.0))
        t, y, yd, ydd = cps.sequence([a, b], junction=junction)
        k = int(np.argmin(np.abs(t - 1.0)))
        assert abs(t[k] - 1.0) < 1e-12 and abs(t[-1] - 2.5) < 1e-9
        assert abs(y[-1, 0] + 0.5) < 1e-2
        # The change of the recorded acceleration across the junction, one step each side.
        return abs(ydd[k + 1, 0] - ydd[k - 1, 0])

    # C²: that change shrinks with the step (it is the jerk's jump times 2h); C¹: the
    # acceleration's jump stays whatever the step.
    c2, c2_half = across(0.005, "c2"), across(0.0025, "c2")
    c1, c1_half = across(0.005, "c1"), across(0.0025, "c1")
    assert 1.8 < c2 / c2_half < 2.2, (c2, c2_half)
    assert 0.9 < c1 / c1_half < 1.1 and c1_half > 10 * c2_half, (c1, c1_half)
    a = cps.DMP([0.0], [1.0], tau=1.0, bases=8)
    with pytest.raises(ValueError, match="junction"):
        cps.sequence([a, a], junction="c0")


def demos(n=25, seed=3):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, 200)
    return [
        (t, np.column_stack([np.sin(np.pi * t) * rng.normal(1, 0.2), t + rng.normal(0, 0.05) * t**2]))
        for _ in range(n)
    ]


def test_promp_statistics_agree_with_movement_primitives_on_the_same_demonstrations():
    from movement_primitives.promp import ProMP as MpProMP

    d = demos()
    t = d[0][0]
    ours = cps.ProMP.fit(d, bases=20)
    ref = MpProMP(n_dims=2, n_weights_per_dim=20)
    ref.imitate(np.array([t] * len(d)), np.array([y for _, y in d]))
    m_ours, _ = ours.mean(t)
    s_ours, _ = ours.std(t)
    m_ref = ref.mean_trajectory(t)
    s_ref = np.sqrt(ref.var_trajectory(t))
    # Two bases, one data set: the same mean to 2 mm and spread to 3 % inside the
    # movement (the basis ends differ).
    inner = slice(10, -10)
    assert np.abs(m_ours - m_ref)[inner].max() < 2e-3
    assert np.abs(s_ours - s_ref)[inner].max() < 0.03 * s_ref.max()


def test_blending_is_the_product_of_gaussians_and_files_round_trip(tmp_path):
    # One dimension, so each time's distribution is a scalar Gaussian.
    one = lambda seed: [(t, y[:, :1]) for t, y in demos(seed=seed)]  # noqa: E731
    p = cps.ProMP.fit(one(1), bases=12)
    q = cps.ProMP.fit(one(2), bases=12).condition(0.5, [0.9], 0.02)
    t = np.linspace(0, 1, 21)
    a1, a2 = np.full(21, 0.3), np.full(21, 0.7)
    mean, std = cps.ProMP.blend([p, q], [a1, a2], t)
    m1, s1 = p.mean(t)[0], p.std(t)[0]
    m2, s2 = q.mean(t)[0], q.std(t)[0]
    prec = 0.3 / s1**2 + 0.7 / s2**2
    np.testing.assert_allclose(mean, (0.3 * m1 / s1**2 + 0.7 * m2 / s2**2) / prec, atol=1e-8)
    np.testing.assert_allclose(std, 1 / np.sqrt(prec), rtol=1e-5)
    with pytest.raises(ValueError, match="one activation array per ProMP"):
        cps.ProMP.blend([p, q], [a1], t)
    path = tmp_path / "q.json"
    q.save(path)
    back = cps.ProMP.load(path)
    np.testing.assert_array_equal(back.weight_mean, q.weight_mean)
    with pytest.raises(ValueError, match="already exists"):
        q.save(path)
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="does not look like"):
        q.save(tmp_path / "notes.txt", force=True)


def test_cmaes_starts_in_a_promps_shape():
    p = cps.ProMP.fit(demos(seed=4), bases=10)
    x0, sigma0, c0 = p.search_start()
    assert c0.shape == (20, 20) and abs(np.trace(c0) / 20 - 1) < 1e-6
    # (C0 carries a ridge of 1e-10 on its diagonal.)
    np.testing.assert_allclose(sigma0**2 * c0, p.weight_cov, rtol=0, atol=1e-9 * sigma0**2)
    # The MAP weights of "pass 0.8 at t = 0.5" (closed form: conditioning).
    phi, _ = p.features(0.5)
    prec = np.linalg.inv(p.weight_cov + 1e-12 * np.eye(20))
    target, s = np.array([0.8, 0.7]), 0.02
    mu = p.weight_mean

    def cost(w):
        d = w - mu
        r = phi @ w - target
        return 0.5 * d @ prec @ d + 0.5 * r @ r / s**2

    best = cost(p.condition(0.5, target, s).weight_mean)
    runs = {}
    for name, opts in (("shaped", {"C0": c0}), ("isotropic", {})):
        es = cps.CMAES(x0, sigma0, {"seed": 2, **opts})
        while not es.stop() and es.result.fbest > best + 1e-6:
            X = es.ask()
            es.tell(X, [cost(x) for x in X])
        runs[name] = es.result.evaluations
    assert runs["shaped"] < 0.5 * runs["isotropic"], runs
    with pytest.raises(ValueError, match="C0"):
        cps.CMAES(x0, sigma0, {"C0": np.eye(3)})


def test_learning_keeps_an_obstacles_clearance():
    task = dict(
        start=[0.0, 0.0, 0.0],
        goal=[1.0, 0.2, 0.1],
        via=[(0.5, [0.5, 0.2, 0.0])],
        tau=1.0,
        bases=10,
    )
    free = cps.learn_via_points(**task, method="exact")
    _, y, _, _ = free.trajectory
    o = y[np.argmin(np.abs(free.trajectory.t - 0.75))]
    r = cps.learn_via_points(
        **task, obstacles=[(o, 0.05)], warm_start=True, sigma0=0.02, generations=800, seed=3
    )
    _, y, _, _ = r.trajectory
    assert cdist(y, o[None]).min() > 0.049
    # CMA-ES with the polish (Levenberg-Marquardt from its best) ends no higher, in far
    # fewer generations; the quadratic form is refused where obstacles make the cost not
    # quadratic.
    p = cps.learn_via_points(
        **task, obstacles=[(o, 0.05)], warm_start=True, sigma0=0.02, generations=100, seed=3,
        polish=True,
    )
    assert p.termination.endswith("+polished") and p.cost <= r.cost * 1.0001
    _, y, _, _ = p.trajectory
    assert cdist(y, o[None]).min() > 0.049  # the penalty (weight 1e5) allows ~1 mm
    with pytest.raises(ValueError, match="quadratic"):
        cps.learn_via_points(**task, obstacles=[(o, 0.05)], evaluation="quadratic")
    with pytest.raises(ValueError, match="evaluation"):
        cps.learn_via_points(**task, evaluation="fast")
    with pytest.raises(ValueError, match="clearance"):
        cps.learn_via_points(**task, obstacles=[(o, -1.0)])


def test_promp_means_chain_into_one_c2_movement():
    # Each ProMP's mean, imitated by a goal-robust DMP, then sequenced.
    rng = np.random.default_rng(0)
    t = np.linspace(0, 1, 200)
    first = [(t, np.column_stack([np.sin(np.pi * t / 2) * rng.normal(1, 0.1), t**2])) for _ in range(10)]
    second = [(t, np.column_stack([1 + 0.5 * t * rng.normal(1, 0.1), 1 - t])) for _ in range(10)]

    def across(dt, junction):
        dmps = []
        for demos in (first, second):
            p = cps.ProMP.fit(demos, bases=12)
            tt = np.linspace(0, p.duration, 201)
            mean, _ = p.mean(tt)
            dmps.append(cps.imitate(tt, mean, bases=25, formulation="robust", dt=dt))
        T, y, _, ydd = cps.sequence(dmps, junction=junction)
        k = int(np.argmin(np.abs(T - 1.0)))
        np.testing.assert_allclose(y[-1], dmps[1].goal, atol=1e-2)
        return np.abs(ydd[k + 1] - ydd[k - 1]).max()

    c2, c2_half = across(0.005, "c2"), across(0.0025, "c2")
    c1 = across(0.005, "c1")
    # C²: the change across the junction shrinks with the step; C¹ keeps its jump.
    assert c2_half < 0.75 * c2 and c1 > 8 * c2, (c2, c2_half, c1)
