"""DMPs: rollouts against a numpy transcription of the equations, imitation recovering
known weights, the command line's model files and rollouts bit for bit, stepping, rhythmic
and orientation DMPs, bad input."""

import json
import pickle

import numpy as np
import pytest

import cps
from conftest import read_csv, reference_dmp


def basis(dmp):
    m = json.loads(dmp.to_json())
    return np.array(m["basis"]["centers"]), np.array(m["basis"]["widths"])


@pytest.mark.parametrize("formulation", ["ijspeert", "robust"])
def test_rollout_converges_to_a_numpy_integration_of_the_equations(formulation):
    # cps holds the forcing term linearly over each step (exact otherwise), so its error
    # against a fine Runge-Kutta integration of the ODE is second order in dt: halving dt
    # quarters it, for position, velocity and acceleration alike.
    rng = np.random.default_rng(4)
    w = rng.normal(0.0, 30.0, size=(2, 10))
    errors = []
    for dt in (0.005, 0.0025):
        dmp = cps.DMP([0.2, -0.4], [1.0, 0.3], tau=1.5, dt=dt, bases=10, weights=w,
                      formulation=formulation)
        centers, widths = basis(dmp)
        # The published basis: c_i = exp(-alpha_x (i-1)/(N-1)), h_i = (c_{i+1} - c_i)^-2.
        c = np.exp(-25.0 / 3.0 * np.arange(10) / 9)
        assert np.allclose(centers, c, rtol=1e-14)
        assert np.allclose(widths[:-1], 1.0 / np.diff(c) ** 2, rtol=1e-12)
        got = dmp.rollout()
        ref = reference_dmp([0.2, -0.4], [1.0, 0.3], w, centers, widths, 1.5, dt,
                            formulation=formulation, substeps=10)
        np.testing.assert_allclose(got.t, ref[0], rtol=0, atol=1e-12)
        errors.append([np.abs(g - r).max() / np.abs(r).max()
                       for g, r in zip((got.y, got.yd, got.ydd), ref[1:])])
    ratio = np.array(errors[0]) / np.array(errors[1])
    assert ((ratio > 3.8) & (ratio < 4.2)).all(), ratio
    assert max(errors[1]) < 5e-4, errors


def test_zero_weights_converge_to_the_goal_and_tau_only_stretches_time():
    dmp = cps.DMP([0.0, 1.0, 2.0], [1.0, -1.0, 0.5], tau=2.0, dt=0.01, bases=15,
                  weights=np.random.default_rng(1).normal(size=(3, 15)) * 50)
    t, y, _, _ = dmp.rollout()
    t2, y2, yd2, _ = dmp.rollout(tau=4.0, dt=0.02)
    assert len(t) == len(t2) == 201
    np.testing.assert_allclose(y2, y, rtol=0, atol=1e-12)  # same path, twice as slow
    assert abs(t2[-1] - 4.0) < 1e-12
    z = cps.DMP([0.0, 1.0, 2.0], [1.0, -1.0, 0.5], tau=2.0, dt=0.01, bases=15)
    _, yz, _, _ = z.rollout()
    assert np.abs(yz[-1] - [1.0, -1.0, 0.5]).max() < 1e-2


def test_imitation_recovers_a_numpy_generated_movement():
    # The demonstration is the numpy reference's integration of known weights, on a fine
    # grid of its own; cps learns from the samples alone.
    rng = np.random.default_rng(7)
    w = rng.normal(0.0, 40.0, size=(3, 20))
    probe = cps.DMP([0.0] * 3, [1.0] * 3, tau=2.0, dt=0.002, bases=20)
    centers, widths = basis(probe)
    start, goal = np.array([0.1, 0.5, -0.2]), np.array([0.8, -0.3, 0.4])
    t, y, _, _ = reference_dmp(start, goal, w, centers, widths, 2.0, 0.002, substeps=10)
    dmp = cps.imitate(t, y, bases=20)
    assert dmp.dims == 3 and dmp.bases == 20 and abs(dmp.tau - 2.0) < 1e-12
    assert dmp.fit["rmse"].max() < 1e-4
    _, yl, _, _ = dmp.rollout()
    assert np.abs(yl - y).max() < 5e-4
    np.testing.assert_allclose(dmp.start, start, atol=1e-12)
    np.testing.assert_allclose(dmp.goal, y[-1], atol=1e-12)  # the last sample
    assert np.abs(y[-1] - goal).max() < 1e-2


def test_every_method_and_several_demonstrations():
    t = np.linspace(0.0, 1.0, 201)
    base = np.column_stack([np.sin(2 * t), np.cos(3 * t)])
    for method, lam in [("lwr", None), ("ridge", 1e-8), ("ridge", "auto"), ("jerk", None), ("jerk", 1e-12)]:
        d = cps.imitate(t, base, method=method, lambda_=lam, bases=20)
        assert d.fit["rmse"].max() < 0.05, (method, lam, d.fit["rmse"])
    gcv = cps.imitate(t, base, method="jerk", bases=20)
    assert (gcv.fit["lambda"] > 0).all()  # chosen by generalised cross-validation
    # The mean of two offset demonstrations is the demonstration in the middle.
    a, b = base + 0.1, base - 0.1
    two = cps.imitate([t, t], [a, b], bases=20)
    one = cps.imitate(t, base, bases=20)
    np.testing.assert_allclose(two.weights, one.weights, rtol=1e-9, atol=1e-9)
    stacked = cps.imitate([t, t], [a, b], bases=20, combine="stack")
    np.testing.assert_allclose(stacked.goal, one.goal, atol=1e-12)


def test_the_robust_formulation_learns_a_loop_back_to_its_start():
    t = np.linspace(0.0, 2.0, 401)
    y = np.column_stack([0.5 * np.sin(np.pi * t / 2) ** 2 * np.sin(np.pi * t / 2) ** 2,
                         0.2 * (1 - np.cos(np.pi * t))])  # at rest at both ends, start = end
    dmp = cps.imitate(t, y, formulation="robust", bases=30)
    assert dmp.formulation == "robust"
    assert dmp.fit["rmse"].max() < 1e-2
    with pytest.raises(ValueError, match="goal"):
        # Ijspeert's form cannot represent start == goal: the forcing term vanishes.
        cps.imitate(t, y, formulation="ijspeert", bases=30)
    # One vocabulary: the model files' former names are refused with the present one.
    with pytest.raises(ValueError, match='formulation: "goal_robust" is now called "robust"'):
        cps.imitate(t, y, formulation="goal_robust", bases=30)
    with pytest.raises(ValueError, match='method: "lasso" is not one of "lwr", "ridge", "jerk"'):
        cps.imitate(t, y, method="lasso")


def test_imitate_keeps_a_shape_by_default_and_the_thesiss_form_warns_of_a_mirrored_start():
    t = np.linspace(0.0, 2.0, 201)
    s = 10 * (t / 2) ** 3 - 15 * (t / 2) ** 4 + 6 * (t / 2) ** 5
    y = np.column_stack([0.2 + 0.3 * s, -0.1 + 0.05 * s + 0.05 * np.sin(np.pi * t / 2)])
    robust = cps.imitate(t, y, bases=20)
    assert robust.formulation == "robust"
    thesis = cps.imitate(t, y, bases=20, formulation="ijspeert")
    with pytest.warns(UserWarning, match=r"y0: goal − start is -0.2000 .* mirrors it .* formulation=\"robust\""):
        thesis.rollout(start=[0.7, -0.1])
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        robust.rollout(start=[0.7, -0.1])  # no warning: the shape is kept


def test_models_and_rollouts_equal_the_command_line_bit_for_bit(tmp_path, cli):
    t = np.linspace(0.0, 1.2, 121)
    y = np.column_stack([0.3 + 0.2 * np.sin(3 * t), np.cos(2 * t), t ** 2])
    demo = tmp_path / "demo.csv"
    np.savetxt(demo, np.column_stack([t, y]), delimiter=",", header="t,x,y,z", comments="",
               fmt="%.17g")
    cli("imitate", demo, "--out", tmp_path / "cli.json", "--bases", 20)
    mine = cps.imitate(t, y, bases=20, names=["x", "y", "z"])
    from_cli = json.loads((tmp_path / "cli.json").read_text())
    assert json.loads(mine.to_json()) == from_cli  # the same file, every bit
    mine.save(tmp_path / "py.json")
    cli("rollout", tmp_path / "py.json", "--goal", "1,0,2", "--tau", 2.0,
        "--out", tmp_path / "roll.csv")
    csv = read_csv(tmp_path / "roll.csv")
    t2, pos, vel, acc = cps.DMP.load(tmp_path / "py.json").rollout(goal=[1, 0, 2], tau=2.0)
    assert np.array_equal(csv["t"], t2)
    for d, n in enumerate("xyz"):
        assert np.array_equal(csv[n], pos[:, d])
        assert np.array_equal(csv[n + "_vel"], vel[:, d])
        assert np.array_equal(csv[n + "_acc"], acc[:, d])


def test_save_refuses_to_overwrite_and_loading_checks_the_version(tmp_path):
    dmp = cps.DMP([0.0], [1.0], bases=5)
    path = tmp_path / "m.json"
    dmp.save(path)
    with pytest.raises(ValueError, match="already exists; pass force=True"):
        dmp.save(path)
    dmp.save(path, force=True)
    other = tmp_path / "notes.txt"
    other.write_text("my notes")
    with pytest.raises(ValueError, match="does not look like a file cps writes"):
        dmp.save(other, force=True)
    assert other.read_text() == "my notes"
    assert '"version": 2' in path.read_text()
    text = path.read_text().replace('"version": 2', '"version": 3')
    bad = tmp_path / "v3.json"
    bad.write_text(text)
    with pytest.raises(ValueError, match="version 3 is not supported"):
        cps.DMP.load(bad)
    # A version 1 file, the formulation by its former name, still loads.
    old = tmp_path / "v1.json"
    old.write_text(path.read_text().replace('"version": 2', '"version": 1')
                   .replace('"formulation": "ijspeert"', '"formulation": "ijspeert2013"'))
    assert cps.DMP.load(old).to_json() == dmp.to_json()
    back = pickle.loads(pickle.dumps(dmp))
    assert back.to_json() == dmp.to_json()


def test_stepping_with_the_grid_step_reproduces_the_rollout():
    w = np.random.default_rng(3).normal(0, 20, size=(2, 12))
    dmp = cps.DMP([0.0, 0.5], [1.0, -0.5], tau=1.0, dt=0.01, bases=12, weights=w)
    _, y, yd, _ = dmp.rollout()
    s = dmp.stepper()
    for k in range(1, len(y)):
        s.step(dmp.dt)
        assert np.abs(s.position - y[k]).max() < 1e-12
    assert np.abs(s.velocity - yd[-1]).max() < 1e-9
    assert abs(s.time - 1.0) < 1e-12
    # A live goal change moves the end point.
    s2 = dmp.stepper()
    s2.set_goal([2.0, 2.0])
    for _ in range(300):
        s2.step(0.01)
    assert np.abs(s2.position - [2.0, 2.0]).max() < 1e-2


def test_rollout_batch_equals_single_rollouts():
    dmp = cps.DMP([0.0, 0.0], [1.0, 1.0], bases=8)
    W = np.random.default_rng(0).normal(size=(21, 2, 8)) * 10  # two groups and a rest
    Y = dmp.rollout_batch(W)
    assert Y.shape == (21, dmp.rollout().y.shape[0], 2)
    for i in range(21):
        assert np.array_equal(Y[i], dmp.rollout(weights=W[i]).y)


def test_rhythmic_dmp_reproduces_a_period():
    period = 2.0
    t = np.linspace(0.0, period, 401)
    y = np.column_stack([np.sin(2 * np.pi * t / period), np.cos(2 * np.pi * t / period) ** 3])
    r = cps.RhythmicDMP.learn(t, y)
    assert abs(r.tau * 2 * np.pi - period) < 1e-12
    tt, yy, vv = r.rollout(2 * period, 0.005)
    k = np.searchsorted(tt, period + 0.5)
    assert abs(yy[k, 0] - np.sin(2 * np.pi * tt[k] / period)) < 2e-2
    r.amplitude = [2.0, 2.0]
    _, y2, _ = r.rollout(period, 0.005)
    assert np.ptp(y2[:, 0]) > 1.5 * np.ptp(yy[: len(y2), 0])


def test_quaternion_dmp_learns_an_orientation_movement():
    t = np.linspace(0.0, 1.0, 201)
    angle = 1.2 * t ** 2 * (3 - 2 * t)  # smooth 0 -> 1.2 rad about a tilted axis
    axis = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    q = np.column_stack([np.outer(np.sin(angle / 2), axis), np.cos(angle / 2)])  # xyzw
    dmp = cps.QuaternionDMP.learn(t, q, bases=25)
    tt, qq, w = dmp.rollout()
    assert np.allclose(np.linalg.norm(qq, axis=1), 1.0, atol=1e-12)
    assert abs(abs(qq[-1] @ q[-1]) - 1.0) < 1e-4
    err = np.arccos(np.clip(np.abs(np.sum(qq * q, axis=1)), 0, 1)) * 2
    assert err.max() < 1e-2


def test_bad_input_names_the_argument_and_the_rule():
    t = np.linspace(0.0, 1.0, 50)
    y = np.column_stack([t, t ** 2])
    cases = [
        (lambda: cps.imitate(t, y[:40]), "y: 40 samples"),
        (lambda: cps.imitate(t, np.where(t > 0.5, np.nan, t)), r"y\[25\] is NaN; every value must be finite"),
        (lambda: cps.imitate(t, y.astype(complex)), "y: expected real numbers"),
        (lambda: cps.imitate(t, [["a", "b"]] * 50), "y: expected real numbers"),
        (lambda: cps.imitate(t, y, bases=0), "bases"),
        (lambda: cps.imitate(t, y, method="magic"), 'method: "magic"'),
        (lambda: cps.imitate(t, y, lambda_=-1.0), "lambda_"),
        (lambda: cps.imitate(t[::-1], y), "time stamps must increase"),
        (lambda: cps.DMP([0, 0], [1]), "goal: expected 2 values"),
        (lambda: cps.DMP([0], [1], tau=-1.0), "tau"),
        (lambda: cps.DMP([0], [1], weights=np.ones((2, 25))), "weights"),
        (lambda: cps.DMP([0], [1]).rollout(goal=[np.inf]), "goal"),
        (lambda: cps.CMAES([0.0] * 3, 1.0, {"popsiz": 5}), "`popsiz` is not an option"),
        (lambda: cps.Robot("nao"), "nao"),
    ]
    for call, pattern in cases:
        with pytest.raises(ValueError, match=pattern):
            call()
    with pytest.raises(TypeError, match="bases_"):
        cps.imitate(t, y, bases_=3)


def test_non_contiguous_and_integer_inputs_give_the_same_result():
    t = np.linspace(0.0, 1.0, 101)
    big = np.column_stack([np.sin(t), np.zeros_like(t), t ** 2, np.zeros_like(t)])
    view = big[:, ::2]  # a strided view
    assert not view.flags["C_CONTIGUOUS"]
    a = cps.imitate(t, view)
    b = cps.imitate(t, np.ascontiguousarray(view))
    assert np.array_equal(a.weights, b.weights)
    d1 = cps.DMP([0, 1], [2, 3], bases=5)
    d2 = cps.DMP(np.array([0.0, 1.0]), np.array([2.0, 3.0]), bases=5)
    assert np.array_equal(d1.rollout().y, d2.rollout().y)
