"""cps.ProMP against numpy: Gaussian conditioning computed here from the ProMP's own
weight distribution and features, the sampled moments against the predicted ones, and
demonstrations that are exact samples."""

import numpy as np
import pytest

import cps


def demos(n=30, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, 101)
    out = []
    for _ in range(n):
        a, b = rng.normal(1.0, 0.2), rng.normal(0.0, 0.3)
        y = np.stack([a * np.sin(np.pi * t / 2), b * t + 0.1 * np.sin(3 * t)], 1)
        out.append((t, y))
    return out


def test_conditioning_is_the_gaussian_formula_in_numpy():
    p = cps.ProMP.fit(demos(), bases=15)
    assert (p.dims, p.bases, p.duration) == (2, 15, pytest.approx(2.0))
    mu, cov = p.weight_mean, p.weight_cov
    phi, _ = p.features(0.7)
    y, s = np.array([0.9, 0.2]), 0.05
    gain = cov @ phi.T @ np.linalg.inv(phi @ cov @ phi.T + s**2 * np.eye(2))
    want_mu = mu + gain @ (y - phi @ mu)
    want_cov = cov - gain @ phi @ cov
    q = p.condition(0.7, y, s)
    np.testing.assert_allclose(q.weight_mean, want_mu, atol=1e-9)
    np.testing.assert_allclose(q.weight_cov, want_cov, atol=1e-9)
    exact = p.condition(points=[(0.5, [0.8, 0.1], 0.0), (1.5, [1.0, -0.2], 0.0)])
    m, _ = exact.mean([0.5, 1.5])
    np.testing.assert_allclose(m, [[0.8, 0.1], [1.0, -0.2]], atol=1e-8)
    sd, _ = exact.std([0.5, 1.5])
    assert sd.max() < 1e-4


def test_samples_have_the_predicted_moments():
    p = cps.ProMP.fit(demos(50, 1), bases=20)
    t = np.linspace(0.0, 2.0, 21)
    y = p.sample(20000, t, seed=4)
    assert y.shape == (20000, 21, 2)
    m, _ = p.mean(t)
    s, _ = p.std(t)
    assert np.abs(y.mean(0) - m).max() < 0.01
    assert np.abs(y.std(0, ddof=1) - s).max() < 0.01
    np.testing.assert_array_equal(p.sample(3, t, seed=9), p.sample(3, t, seed=9))


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="at least 2 demonstrations"):
        cps.ProMP.fit(demos(1))
    p = cps.ProMP.fit(demos(5))
    with pytest.raises(ValueError, match="outside the movement"):
        p.mean([3.0])
    with pytest.raises(ValueError, match="position"):
        p.condition(0.5, [1.0])
    with pytest.raises(ValueError, match="contradict"):
        p.condition(points=[(0.5, [0.0, 0.0], 0.0), (0.5, [1.0, 0.0], 0.0)])
