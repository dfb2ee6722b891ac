"""Action chunks from Python: a policy stand-in's chunks (H = 50 at 50 Hz, at 10 and 30 Hz,
each from a state 50-150 ms old, +-2 mrad of noise) made commands by cps's executor,
beside naive execution and Ruckig's online generator (PyPI ``ruckig``, its free edition:
one target at a time) on the same stream — every cps command within the limits where naive
execution breaks them, and cps's commands no farther from the demonstration than Ruckig's;
then a live executor on the dynamics robot fed from Python, bad chunks refused in
sentences, a stall braked to rest."""

import json
import math
import time

import numpy as np
import pytest

import cps

READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
# The FR3's velocity, acceleration and jerk limits.
FR3_V = np.array([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26])
FR3_A, FR3_J = 10.0, 5000.0
DT = 1e-3


def demo(t):
    s = 0.5 - 0.5 * np.cos(math.pi / 2 * np.clip(t, 0.0, None))
    sign = np.array([1, -0.5, 1, -0.5, 1, -0.5, 1])
    return READY + 0.3 * np.outer(s, sign) if np.ndim(t) else READY + 0.3 * s * sign


def stand_in(hz, seconds=6.0, seed=3):
    """(observed_s, arrived_s, targets) per chunk, as cps_robot::StandIn makes them."""
    rng = np.random.default_rng(seed)
    period, chunks = 1.0 / hz, []
    delay = rng.uniform(0.05, 0.15)
    for k in range(int(seconds * hz) + 1):
        if k:
            delay = rng.uniform(0.05, min(0.15, delay + period))
        arrived = k * period
        observed = arrived - delay
        targets = demo(observed + np.arange(50) / 50.0) + rng.uniform(-0.002, 0.002, (50, 7))
        chunks.append((observed, arrived, targets))
    return chunks


def rates(q):
    """Velocity, acceleration and jerk of commands every millisecond, from rest."""
    q = np.vstack([q[:1], q])
    v = np.diff(q, axis=0) / DT
    a = np.diff(np.vstack([np.zeros(7), v]), axis=0) / DT
    j = np.diff(np.vstack([np.zeros(7), a]), axis=0) / DT
    return v, a, j


def naive(chunks, n):
    """Each chunk from its first point when it arrives, linearly interpolated."""
    out, current, nxt = np.tile(READY, (n, 1)), None, 0
    for k in range(n):
        t = (k + 1) * DT
        while nxt < len(chunks) and chunks[nxt][1] <= t:
            current, nxt = chunks[nxt], nxt + 1
        if current is not None:
            s = min((t - current[1]) * 50.0, 49.0)
            i = int(s)
            out[k] = current[2][i] + (s - i) * (current[2][min(i + 1, 49)] - current[2][i])
    return out


def ruckig_commands(chunks, n, v, a, j):
    """Ruckig's online generator toward the newest chunk's target at each instant (its
    position and the slope to the next target), fed back its own state."""
    import ruckig  # pinned in CI's environment
    otg = ruckig.Ruckig(7, DT)
    inp, out = ruckig.InputParameter(7), ruckig.OutputParameter(7)
    inp.current_position = READY.tolist()
    inp.current_velocity = [0.0] * 7
    inp.current_acceleration = [0.0] * 7
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = v.tolist(), a.tolist(), j.tolist()
    q, current, nxt = np.tile(READY, (n, 1)), None, 0
    for k in range(n):
        t = (k + 1) * DT
        while nxt < len(chunks) and chunks[nxt][1] <= t:
            current, nxt = chunks[nxt], nxt + 1
        if current is not None:
            s = min(max((t - current[0]) * 50.0, 0.0), 49.0)
            i = min(int(s), 48)
            slope = (current[2][i + 1] - current[2][i]) * 50.0
            target = current[2][i] + (s - i) * (current[2][i + 1] - current[2][i])
            inp.target_position = target.tolist()
            inp.target_velocity = np.clip(slope, -0.99 * v, 0.99 * v).tolist()
            inp.target_acceleration = [0.0] * 7
            res = otg.update(inp, out)
            assert res in (ruckig.Result.Working, ruckig.Result.Finished), res
            out.pass_to_input(inp)
            q[k] = out.new_position
        elif k:
            q[k] = q[k - 1]
    return q


@pytest.mark.parametrize("hz", [10.0, 30.0])
def test_cps_keeps_every_limit_where_naive_breaks_them_and_tracks_as_well_as_ruckig(hz):
    chunks = stand_in(hz)
    cmd = cps.chunk_commands(READY, chunks)
    q_cps = cmd["q_d"][1:]
    n = 6000
    v, a, j = rates(cmd["q_d"])
    tol = 1 + 1e-6
    assert np.all(np.abs(v) <= cmd["velocity_limits"] * tol)
    assert np.all(np.abs(a) <= cmd["acceleration_limits"] * tol)
    assert np.all(np.abs(j) <= cmd["jerk_limits"] * tol)
    nv, _, nj = rates(naive(chunks, n))
    naive_v, naive_j = np.max(np.abs(nv) / FR3_V), np.max(np.abs(nj)) / FR3_J
    assert naive_v > 2 and naive_j > 100, (naive_v, naive_j)
    # Ruckig with the same limits cps keeps (the FR3's, its jerks lowered for the torque rate).
    q_r = ruckig_commands(
        chunks, n, cmd["velocity_limits"], cmd["acceleration_limits"], cmd["jerk_limits"]
    )
    t = (np.arange(n) + 1) * DT
    after = t > 1.0
    err = lambda q: np.max(np.abs(q[:n][after] - demo(t[after])))
    rv, ra, rj = rates(q_r)
    # For the record: Ruckig with the FR3's own limits (its jerk not lowered for the torque
    # rate, which Ruckig does not know).
    q_full = ruckig_commands(chunks, n, 0.95 * FR3_V, np.full(7, 9.5), np.full(7, 4750.0))
    print(f"{hz} Hz: Ruckig with the FR3's full jerk: {1e3 * err(q_full):.2f} mrad")
    print(
        f"{hz} Hz: from the demonstration cps {1e3 * err(q_cps):.2f} mrad, Ruckig"
        f" {1e3 * err(q_r):.2f} mrad; jerk peaks (share of FR3's) cps"
        f" {np.max(np.abs(j)) / FR3_J:.3f}, Ruckig {np.max(np.abs(rj)) / FR3_J:.3f},"
        f" naive {naive_j:.0f}; naive velocity {naive_v:.1f}x"
    )
    assert err(q_cps) <= err(q_r) + 1e-4


def test_a_live_executor_on_the_dynamics_robot_takes_chunks_from_python():
    with cps.ChunkExecutor("dynamics", rate=50.0, stall_timeout=0.2, idle_end=1.0) as ex:
        t0, q0 = ex.state()
        while math.isnan(t0):
            time.sleep(0.005)
            t0, q0 = ex.state()
        np.testing.assert_allclose(q0, READY, atol=1e-3)
        with pytest.raises(ValueError, match=r"targets\[2, 2\] is NaN"):
            bad = np.tile(q0, (5, 1))
            bad[2, 2] = np.nan
            ex.push(bad, t0)
        with pytest.raises(ValueError, match="expected 7 columns"):
            ex.push(np.zeros((5, 6)), t0)
        # A chunk far from the arm: refused by the executor, in the report.
        ex.push(np.tile(q0 + 0.5, (10, 1)), t0)
        for _ in range(8):
            t, q = ex.state()
            time.sleep(0.03)  # inference
            s = np.clip(t + np.arange(50) / 50.0, 0, None)
            targets = np.tile(q0, (50, 1))
            targets[:, 0] += 0.1 * (0.5 - 0.5 * np.cos(math.pi * s))
            ex.push(targets, t)
            time.sleep(0.07)
        # Then nothing: a stall, braked to rest; close ends the run.
        time.sleep(0.5)
        rec = ex.close()
    r = rec["report"]
    assert r["refused"] == 1 and "from where the arm is commanded" in r["refusals"][0]["why"]
    assert r["taken"] == 8
    # Every chunk kept with its verdict, in order: the run can be replayed.
    assert len(rec["chunks"]) == 9 and rec["chunks"][0]["verdict"].startswith("refused: the chunk wants")
    assert all(c["verdict"].startswith("taken") for c in rec["chunks"][1:])
    assert rec["chunks"][1]["targets"].shape == (50, 7)
    assert len(r["stalls_s"]) >= 1
    v, a, j = rates(rec["q_d"])
    assert np.max(np.abs(v) / FR3_V) <= 1 and np.max(np.abs(a)) <= FR3_A and np.max(np.abs(j)) <= FR3_J
    # 30 ms of the wall clock on the robot's clock (held to the wall, never ahead of it).
    assert 0.01 <= r["inference_delay_s"]["mean"] <= 1.0
    assert rec["q"].shape == rec["q_d"].shape and rec["q"].shape[1] == 7
    # At rest at the end.
    np.testing.assert_array_equal(rec["q_d"][-1], rec["q_d"][-2])


def test_a_live_executor_observes_the_whole_state_and_writes_its_recording(tmp_path):
    record = tmp_path / "run.csv"
    record.write_text("t,q1\n0,0\n")
    # An existing recording is not replaced without force, before anything moves.
    with pytest.raises(ValueError, match="run.csv"):
        cps.ChunkExecutor("kinematic", record=record)
    with cps.ChunkExecutor("kinematic", rate=50.0, idle_end=1.0, record=record, force=True) as ex:
        o = ex.observe()
        while math.isnan(o["t"]):
            time.sleep(0.005)
            o = ex.observe()
        np.testing.assert_allclose(o["q"], READY, atol=1e-12)
        np.testing.assert_array_equal(o["q_d"], o["q"])
        np.testing.assert_array_equal(o["tau"], np.zeros(7))  # the in-process robot has none
        targets = np.tile(o["q"], (25, 1))
        targets[:, 0] += np.linspace(0.0, 0.05, 25)
        ex.push(targets, o["t"])
        time.sleep(0.25)
        moving = ex.observe()
        # It does what it is told: it stands where the command in force put it, moving
        # as the command moves (0.1 rad/s along the chunk).
        np.testing.assert_array_equal(moving["q_d"], moving["q"])
        assert 0.03 < moving["dq"][0] < 0.2, moving["dq"]
    rows = record.read_text().splitlines()
    assert rows[0].split(",")[:2] == ["t", "q1"] and rows[0].split(",")[8] == "q_d1"
    t = np.array([float(r.split(",")[0]) for r in rows[1:]])
    assert np.all(np.diff(t) > 0) and t[-1] > 0.25
    report = json.loads(record.with_suffix(".report.json").read_text())
    assert report["chunks"]["taken"] == 1, report
    assert record.with_suffix(".chunks.csv").read_text().count("\n") == 1 + 25
