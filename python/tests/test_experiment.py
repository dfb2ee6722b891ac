"""Experiments from Python: the same numbers and files as `cps-cli run`, learn_via_points
against the experiment and the exact optimum, result directories, progress."""

import csv
import io
import json
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import cps
from conftest import EXPERIMENTS, ROOT, read_csv

# Header fields that differ between two runs of the same file (when and how fast), and
# which robot of a pool ran what (the in-process robot runs one copy per thread).
VARYING = {"wall_time_s", "threads", "seconds", "versions", "simulators"}


def strip(value):
    if isinstance(value, list):
        return [strip(v) for v in value]
    if not isinstance(value, dict):
        return value
    return {k: strip(v) for k, v in value.items()
            if k not in VARYING and not k.endswith("_seconds") and not k.endswith("_s")}


@pytest.mark.parametrize("name", ["viapoint", "imitation", "viapoint_executed"])
def test_run_experiment_equals_the_command_line(tmp_path, cli, name):
    path = EXPERIMENTS / f"{name}.toml"
    cli("run", path, "--out", tmp_path / "cli", "--quiet", "--threads", 2)
    outcome = cps.run_experiment(path, out=tmp_path / "py", threads=1, figures=False)
    assert outcome.complete and outcome.kind == name
    from_cli = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert strip(outcome.summary) == strip(from_cli)
    assert strip(json.loads((tmp_path / "py" / "summary.json").read_text())) == strip(from_cli)
    for table_name, table in outcome.tables.items():
        cli_csv = (tmp_path / "cli" / f"{table_name}.csv").read_text()
        assert without_clock(table.to_csv()) == without_clock(cli_csv), table_name
        assert (tmp_path / "py" / f"{table_name}.csv").read_text() == table.to_csv()
    # The summary's numbers are shortest round-trip decimals, so the equality above is bit
    # for bit; the CSVs' fixed decimals (13 in the thesis's format) are what both print.
    if name == "viapoint":
        data = read_csv(tmp_path / "cli" / "trajectory.csv")
        table = outcome.tables["trajectory"]
        for column in table.columns:
            np.testing.assert_allclose(table[column], data[column], rtol=0, atol=1e-12)


def test_run_experiment_on_the_robot_with_dynamics_equals_the_command_line(tmp_path, cli):
    """The joint experiment on the FR3 with dynamics, learned on its executions (a short
    search), from Python on one thread and from the command line on two: the same
    summary, the same command."""
    text = (EXPERIMENTS / "dynamics" / "viapoint_joint.toml").read_text()
    # Three iterations: on franky-sim's drives (friction smoothed over 5 mrad/s) the second
    # has taken the worst via point from 39 to 15 mm, the third to 7.7 mm.
    text = text.replace("generations = 15 ", "generations = 3  ")
    assert "generations = 3  " in text
    path = tmp_path / "dynamics.toml"
    path.write_text(text)
    cli("run", path, "--out", tmp_path / "cli", "--quiet", "--threads", 2)
    outcome = cps.run_experiment(path, out=tmp_path / "py", threads=1, figures=False)
    assert outcome.complete and outcome.kind == "viapoint_joint"
    from_cli = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert strip(outcome.summary) == strip(from_cli)
    learned = outcome.summary["executed_learning"]
    assert learned["iterations"] == 3
    assert max(learned["via_errors_m"]) < max(learned["model_learned_via_errors_m"]) / 3
    assert outcome.summary["backend"].startswith("dynamics (in-process, joint_pd controller")
    assert (tmp_path / "py" / "trajectory.csv").read_text() == (tmp_path / "cli" / "trajectory.csv").read_text()


def without_clock(csv_text):
    """The CSV without the columns of the clock (the thesis's weights table stamps the
    wall time and the compute time)."""
    rows = list(csv.reader(io.StringIO(csv_text)))
    for name in ("Time", "ComputeTime"):
        if rows and name in rows[0]:
            i = rows[0].index(name)
            rows = [r[:i] + r[i + 1:] for r in rows]
    return rows


def test_table_columns_keep_their_types():
    outcome = cps.run_experiment(EXPERIMENTS / "scaling.toml", seed=3)
    integer_columns = 0
    for table in outcome.tables.values():
        rows = list(csv.reader(io.StringIO(table.to_csv())))
        for i, column in enumerate(table.columns):
            values = table[column]
            assert isinstance(values, list) or values.dtype in (np.float64, np.uint64), (table.name, column)
            if not isinstance(values, list) and values.dtype == np.uint64:
                integer_columns += 1
                # Counts and seeds come back whole, even above 2**63.
                assert [int(v) for v in values] == [int(r[i]) for r in rows[1:]], (table.name, column)
    assert integer_columns > 0


def test_learn_via_points_is_the_viapoint_experiment():
    outcome = cps.run_experiment(EXPERIMENTS / "viapoint.toml")
    s = outcome.summary
    res = cps.learn_via_points(
        start=[0.75, 0.02, 1.87], goal=[0.55, -0.57, 1.45],
        via=[(2.0, [0.78, 0.60, 1.70]), (4.0, [1.12, 0.37, 1.45]),
             (6.0, [1.15, -0.15, 1.20]), (8.0, [0.90, -0.53, 1.20])],
        tau=10.0, dt=0.01, bases=25,
        cost={"goal": 1e5, "via": 1e5, "final_velocity": 1e3, "acceleration": 1e-2, "jerk": 0.0},
        sigma0=0.5, population=96, generations=3000, tol_fun=1e-3, seed=1)
    assert res.cost == s["best_cost"]
    assert res.optimum_cost == s["optimum_cost"]
    traj = outcome.tables["trajectory"]
    np.testing.assert_array_equal(res.trajectory.y[:, 0], traj["x"])
    assert 0 <= res.gap_to_optimum < 0.01
    exact = cps.learn_via_points([0.75, 0.02, 1.87], [0.55, -0.57, 1.45],
                                 [{"time": 2.0, "position": [0.78, 0.60, 1.70]},
                                  {"time": 8.0, "position": [0.90, -0.53, 1.20]}],
                                 method="exact")
    assert exact.termination == "exact" and exact.gap_to_optimum == 0.0
    assert exact.via_errors.max() < 1e-2
    # The learned DMP goes anywhere: roll it out to a new goal.
    moved = exact.dmp.rollout(goal=[0.6, -0.5, 1.5])
    assert np.abs(moved.y[-1] - [0.6, -0.5, 1.5]).max() < 1e-2


def test_result_directories_are_safe(tmp_path):
    out = tmp_path / "res"
    small = tmp_path / "small.toml"
    small.write_text((EXPERIMENTS / "viapoint.toml").read_text().replace("generations = 3000", "generations = 20")
                     .replace("plots = true", "plots = false"))
    o = cps.run_experiment(small, out=out)
    assert (out / "summary.json").is_file() and (out / "trajectory.csv").is_file()
    with pytest.raises(ValueError, match="force=True"):
        cps.run_experiment(small, out=out)
    cps.run_experiment(small, out=out, force=True)  # replaces its own results
    mine = out / "my_notes.txt"
    mine.write_text("keep me")
    with pytest.raises(ValueError, match="holds `my_notes.txt`, which cps did not write"):
        cps.run_experiment(small, out=out, force=True)
    assert mine.read_text() == "keep me"
    o.save(tmp_path / "again")
    assert (tmp_path / "again" / "trajectory.csv").read_text() == (out / "trajectory.csv").read_text()


def test_bad_experiment_files_raise_value_error_with_the_place(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((EXPERIMENTS / "viapoint.toml").read_text().replace("tau = 10.0", "tau = -1.0"))
    with pytest.raises(ValueError, match=r"bad.toml:\d+:\d+"):
        cps.run_experiment(bad)
    with pytest.raises(ValueError, match="threads"):
        cps.run_experiment(EXPERIMENTS / "viapoint.toml", threads=0)
    with pytest.raises(ValueError, match="does not exist|cannot read|No such"):
        cps.run_experiment(tmp_path / "missing.toml")


def test_progress_is_reported():
    seen = []
    cps.run_experiment(EXPERIMENTS / "viapoint_joint.toml", progress=seen.append)
    assert seen and seen[-1]["planned"] > 0
    assert all(a["generations"] <= b["generations"] for a, b in zip(seen, seen[1:]))


# The script first restores Python's Ctrl-C handler: a shell that starts the tests in the
# background (`cmd &`) hands them SIGINT ignored, and Python then leaves it ignored.
SCRIPT = textwrap.dedent("""
    import signal, sys, cps
    signal.signal(signal.SIGINT, signal.default_int_handler)
    print("started", flush=True)
    try:
        cps.run_experiment(sys.argv[1], out=sys.argv[2], progress=lambda p: None)
    except KeyboardInterrupt:
        print("interrupted", flush=True)
        sys.exit(130)
    print("finished", flush=True)
""")


def test_ctrl_c_stops_a_run_and_keeps_what_was_done(tmp_path):
    long = tmp_path / "long.toml"
    long.write_text((EXPERIMENTS / "viapoint.toml").read_text()
                    .replace("generations = 3000", "generations = 1000000")
                    .replace("tol_fun = 1e-3", "tol_fun = 0.0").replace("plots = true", "plots = false"))
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-c", SCRIPT, str(long), str(out)],
                         stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "started"
    import time
    time.sleep(1.5)
    p.send_signal(signal.SIGINT)
    rest, _ = p.communicate(timeout=60)
    assert p.returncode == 130, rest
    assert "interrupted" in rest
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False
    assert summary["best_cost"] > 0
