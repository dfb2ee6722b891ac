"""Motion capture against independent C3D tools: ezc3d (C++, PyPI) writes and reads takes
with a known rigid-body motion, py-c3d (pure Python, PyPI) writes integer files; cps's
markers must equal theirs and the recovered pose the known one. Motive CSV files are
written here in Motive's published layout."""

import json
import math
import os

import numpy as np
import pytest

import cps
import cps.mocap

ezc3d = pytest.importorskip("ezc3d") if not os.environ.get("CI") else __import__("ezc3d")
pyc3d = pytest.importorskip("c3d") if not os.environ.get("CI") else __import__("c3d")

# The tool: markers in its frame (metres), spread as on a hand-held tool.
BODY = np.array([[0.0, 0.0, 0.0], [0.16, 0.0, 0.0], [0.04, 0.10, 0.0], [0.0, 0.0, 0.08]])


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def motion(t):
    """The known pose at times t: positions (n, 3) m and rotations (n, 3, 3)."""
    w = 2 * math.pi / 8.0
    p = np.stack([0.4 + 0.25 * np.sin(w * t), 0.9 + 0.15 * np.sin(2 * w * t), 0.2 + 0.1 * np.cos(w * t)], 1)
    angle = 1.2 * np.sin(w * t)
    axis = np.stack([0.2 + 0.3 * np.cos(w * t), np.ones_like(t), 0.4 * np.sin(w * t)], 1)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    q = np.concatenate([axis * np.sin(angle / 2)[:, None], np.cos(angle / 2)[:, None]], 1)
    return p, np.array([quat_to_matrix(v) for v in q])


def markers_mm(t, n, noise_mm=0.0, seed=0):
    p, r = motion(t)
    m = np.einsum("fij,mj->fmi", r, BODY[:n]) + p[:, None, :]
    rng = np.random.default_rng(seed)
    return m * 1000.0 + noise_mm * rng.standard_normal(m.shape)


def write_ezc3d(path, xyz_mm, rate, labels, gaps=(), analog=None):
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, len(labels), xyz_mm.shape[0]))
    pts[:3] = xyz_mm.transpose(2, 1, 0)
    for m, a, b in gaps:
        pts[:3, m, a:b] = np.nan
    c["data"]["points"] = pts
    if analog is not None:
        c["parameters"]["ANALOG"]["RATE"]["value"] = [rate * analog.shape[1] // xyz_mm.shape[0]]
        c["parameters"]["ANALOG"]["LABELS"]["value"] = tuple(f"emg{i}" for i in range(analog.shape[0]))
        c["data"]["analogs"] = analog[None]
    c.write(str(path))


def angle_between(a, b):
    r = a.T @ b
    return math.atan2(np.linalg.norm([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2, (np.trace(r) - 1) / 2)


@pytest.mark.parametrize("n", [3, 4])
def test_markers_equal_ezc3d_and_the_pose_is_the_known_one(tmp_path, n):
    rate, frames = 240.0, 1920
    t = np.arange(frames) / rate
    labels = [f"tool{i + 1}" for i in range(n)]
    path = tmp_path / "take.c3d"
    write_ezc3d(path, markers_mm(t, n), rate, labels)
    ref = ezc3d.c3d(str(path))
    take = cps.mocap.take(path)
    assert take["labels"] == labels and take["rate"] == rate and take["frames"] == frames
    assert take["units"] == "mm"
    ez = ref["data"]["points"][:3].transpose(2, 1, 0)
    np.testing.assert_array_equal(take["points"], ez)
    # Noise-free: the tool frame from markers 1 (origin), 2 (x) and 3 (x-y plane).
    demo = cps.mocap.read(path, labels, origin="tool1", axes=["tool1", "tool2", "tool3"], cutoff=None)
    p, r = motion(t)
    assert demo["t"].shape == (frames,)
    ep = np.abs(demo["position"] - p).max()
    er = max(angle_between(quat_to_matrix(q), rr) for q, rr in zip(demo["quaternion"], r))
    print(f"{n} markers, noise-free: position {ep:.2e} m, rotation {er:.2e} rad")
    assert ep < 1e-6 and er < 1e-6


def test_gaps_noise_and_analog_against_ezc3d(tmp_path):
    rate, frames = 240.0, 2400
    t = np.arange(frames) / rate
    labels = ["tool1", "tool2", "tool3", "tool4"]
    gaps = [(1, 300, 306), (2, 1200, 1209), (3, 2000, 2040)]
    analog = np.stack([np.sin(np.arange(frames * 4) * 0.01), np.cos(np.arange(frames * 4) * 0.02)])
    path = tmp_path / "noisy.c3d"
    write_ezc3d(path, markers_mm(t, 4, noise_mm=0.5, seed=3), rate, labels, gaps, analog)
    ref = ezc3d.c3d(str(path))
    take = cps.mocap.take(path)
    ez = ref["data"]["points"][:3].transpose(2, 1, 0)
    np.testing.assert_array_equal(np.isnan(take["points"]), np.isnan(ez))
    np.testing.assert_array_equal(take["points"][~np.isnan(ez)], ez[~np.isnan(ez)])
    np.testing.assert_allclose(take["analog"]["values"], ref["data"]["analogs"][0].T, rtol=0, atol=1e-6)
    assert take["analog"]["labels"] == ["emg0", "emg1"]
    demo = cps.mocap.read(path, labels, origin="tool1", axes=["tool1", "tool2", "tool3"], max_gap=10)
    rep = demo["report"]
    assert [m["frames_filled"] for m in rep["markers"]] == [0, 6, 9, 0]
    assert rep["markers"][3]["open_gaps"] == [[2001, 2040]]
    p, r = motion(t)
    err = np.linalg.norm(demo["position"] - p, axis=1)
    ang = np.array([angle_between(quat_to_matrix(q), rr) for q, rr in zip(demo["quaternion"], r)])
    raw = cps.mocap.read(path, labels, origin="tool1", axes=["tool1", "tool2", "tool3"], cutoff=None)
    raw_err = np.linalg.norm(raw["position"] - p, axis=1)
    print(f"0.5 mm noise: smoothed {np.sqrt((err ** 2).mean()) * 1e3:.3f} mm RMS (max {err.max() * 1e3:.3f}), "
          f"{np.degrees(ang).mean():.3f}° mean; unsmoothed {np.sqrt((raw_err ** 2).mean()) * 1e3:.3f} mm RMS")
    assert np.sqrt((err ** 2).mean()) < 0.5e-3 and err.max() < 1.5e-3 and ang.max() < math.radians(1)
    assert np.sqrt((err ** 2).mean()) < np.sqrt((raw_err ** 2).mean())


def test_a_take_longer_than_the_header_can_say(tmp_path):
    # ezc3d writes 70 000 frames with POINT:FRAMES = -1 and the header's last frame at
    # 65 535 (no TRIAL fields): cps counts the frames the file holds and says so.
    rate, frames = 100.0, 70_000
    t = np.arange(frames) / rate
    path = tmp_path / "long.c3d"
    write_ezc3d(path, markers_mm(t, 3), rate, ["a", "b", "c"])
    take = cps.mocap.take(path)
    assert take["frames"] == frames
    assert any("counted from the file's length" in n for n in take["notes"]), take["notes"]
    np.testing.assert_allclose(take["points"][-1], markers_mm(t[-1:], 3)[0], atol=1e-3)
    # ezc3d 1.7.2 reads its own file back short, at the header's 65 535.
    assert ezc3d.c3d(str(path))["data"]["points"].shape[2] == 65_535


@pytest.mark.parametrize("scale", [0.1, 0.05])
def test_integer_files_from_py_c3d_read_as_ezc3d_reads_them(tmp_path, scale):
    rate, frames = 120.0, 600
    t = np.arange(frames) / rate
    xyz = markers_mm(t, 3) - np.array([400.0, 900.0, 200.0])  # within ±32767 × scale
    w = pyc3d.Writer(point_rate=rate, point_scale=scale)
    w.set_point_labels(["a", "b", "c"])
    frames_out = []
    for f in range(frames):
        pts = np.zeros((3, 5), dtype=np.float32)
        pts[:, :3] = xyz[f]
        pts[:, 3] = 0.0 if f % 97 else -1.0  # every 97th frame: all markers missing
        frames_out.append((pts, np.zeros((0, 0), dtype=np.float32)))
    w.add_frames(frames_out)
    path = tmp_path / "int.c3d"
    with open(path, "wb") as h:
        w.write(h)
    ref = ezc3d.c3d(str(path))
    take = cps.mocap.take(path)
    assert take["frames"] == frames
    ez = ref["data"]["points"][:3].transpose(2, 1, 0)
    np.testing.assert_array_equal(np.isnan(take["points"]), np.isnan(ez))
    ok = ~np.isnan(ez)
    np.testing.assert_allclose(take["points"][ok], ez[ok], rtol=1e-6, atol=1e-9)
    # py-c3d truncates to the integer grid: within one step of the written value.
    assert np.abs(take["points"][ok] - xyz[np.broadcast_to(ok, xyz.shape)]).max() <= scale + 1e-3


def write_motive(path, t, positions_mm, quats, markers_mm, units="Millimeters", occluded=()):
    names = [f"Tool:Marker{i + 1}" for i in range(markers_mm.shape[1])]
    head = [
        f"Format Version,1.23,Take Name,pour,Take Notes,,Capture Frame Rate,120.000000,Export Frame Rate,120.000000,"
        f"Capture Start Time,2026-11-26 11.00.00.000 AM,Capture Start Frame,0,Total Frames in Take,{len(t)},"
        f"Total Exported Frames,{len(t)},Rotation Type,Quaternion,Length Units,{units},Coordinate Space,Global",
        "",
        ",Type," + ",".join(["Rigid Body"] * 8 + ["Marker"] * (3 * len(names))),
        ",Name," + ",".join(["Tool"] * 8 + [n for n in names for _ in range(3)]),
        ",ID," + ",".join(["1"] * 8 + [f"{i + 2}" for i in range(len(names)) for _ in range(3)]),
        ",," + ",".join(["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"] + ["Position"] * (3 * len(names))),
        "Frame,Time (Seconds)," + ",".join(["X", "Y", "Z", "W", "X", "Y", "Z", ""] + ["X", "Y", "Z"] * len(names)),
    ]
    rows = []
    for f in range(len(t)):
        if f in occluded:
            cells = [""] * (8 + 3 * len(names))
        else:
            cells = [f"{v:.6f}" for v in quats[f]] + [f"{v:.6f}" for v in positions_mm[f]] + ["0.000120"]
            cells += [f"{v:.6f}" for v in markers_mm[f].ravel()]
        rows.append(f"{f},{t[f]:.6f}," + ",".join(cells))
    path.write_text("\n".join(head + rows) + "\n")


def test_motive_csv_rigid_body_and_markers(tmp_path):
    rate, frames = 120.0, 960
    t = np.arange(frames) / rate
    p, r = motion(t)
    # Motive's quaternion of each rotation (x, y, z, w), from the matrix.
    def m2q(m):
        w = math.sqrt(max(0.0, 1 + np.trace(m))) / 2
        return np.array([(m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w), (m[1, 0] - m[0, 1]) / (4 * w), w])
    quats = np.array([m2q(m) for m in r])
    path = tmp_path / "pour.csv"
    write_motive(path, t, p * 1000, quats, markers_mm(t, 3), occluded={100, 101, 102})
    take = cps.mocap.take(path)
    assert take["labels"] == ["Tool:Marker1", "Tool:Marker2", "Tool:Marker3"]
    assert take["rate"] == 120.0 and take["units"] == "Millimeters" and take["frames"] == frames
    assert np.isnan(take["points"][100]).all()
    body = cps.mocap.read(path, rigid_body="Tool", cutoff=None)
    assert body["report"]["markers"][0]["frames_filled"] == 3
    keep = np.ones(frames, bool)
    keep[100:103] = False
    assert np.abs(body["position"][keep] - p[keep]).max() < 1e-6   # 6 decimals of mm
    assert np.abs(body["position"][~keep] - p[~keep]).max() < 1e-4  # spline across 3 frames
    # The same pose from the markers (labels shortened: `Marker1` is `Tool:Marker1`).
    demo = cps.mocap.read(path, ["Marker1", "Marker2", "Marker3"], origin="Marker1",
                          axes=["Marker1", "Marker2", "Marker3"], cutoff=None)
    assert np.abs(demo["position"][keep] - p[keep]).max() < 1e-6
    er = max(angle_between(quat_to_matrix(q), rr) for q, rr in zip(demo["quaternion"][keep], r[keep]))
    assert er < 1e-5
    # A Y-up take turned Z-up: z becomes the take's y.
    up = cps.mocap.read(path, rigid_body="Tool", cutoff=None, y_up=True)
    np.testing.assert_allclose(up["position"][:, 2], body["position"][:, 1], atol=1e-12)
    np.testing.assert_allclose(up["position"][:, 1], -body["position"][:, 2], atol=1e-12)


def test_the_command_line_imports_into_the_robot_frame_and_refuses_bad_input(tmp_path, cli):
    rate, frames = 240.0, 1200
    t = np.arange(frames) / rate
    labels = ["tool1", "tool2", "tool3"]
    take = tmp_path / "take.c3d"
    write_ezc3d(take, markers_mm(t, 3), rate, labels)
    # The robot's base at (0.5, 0.2) on the floor of a Y-up lab, its z the lab's y.
    calib = tmp_path / "lab.toml"
    pts = [[0, 0, 0], [1000, 0, 0], [0, 1000, 0], [300, 200, 1000]]
    to_robot = lambda q: [q[0] / 1e3 - 0.5, -q[2] / 1e3 - 0.2, q[1] / 1e3]
    calib.write_text('mocap_units = "mm"\n' + "".join(
        f"[[points]]\nmocap = {q}\nrobot = {to_robot(q)}\n" for q in pts))
    out = tmp_path / "demo.csv"
    p = cli("mocap", "import", take, "--markers", ",".join(labels), "--origin", "tool1",
            "--axes", "tool1,tool2,tool3", "--to-robot", calib, "--cutoff", "0", "--out", out, "--json")
    rep = json.loads(p.stdout)
    assert rep["report"]["registration"]["rms_m"] < 1e-9
    d = np.loadtxt(out, delimiter=",", skiprows=1)
    assert open(out).readline().strip() == "t,x,y,z,qx,qy,qz,qw"
    pos, _ = motion(t)
    want = np.array([to_robot(q * 1000) for q in pos])
    assert np.abs(d[:, 1:4] - want).max() < 1e-6
    # The same through Python.
    py = cps.mocap.read(take, labels, origin="tool1", axes=["tool1", "tool2", "tool3"], to_robot=calib, cutoff=None)
    np.testing.assert_allclose(py["position"], d[:, 1:4], atol=1e-12)
    # `imitate` takes the demonstration as it is.
    cli("imitate", out, "--bases", "20", "--out", tmp_path / "model.json")

    def refused(*args, words):
        target = tmp_path / "refused.csv"
        r = cli("mocap", "import", *args, "--out", target, check=False)
        assert r.returncode == 2, r.stderr
        assert all(w in r.stderr for w in words), r.stderr
        assert not target.exists()
        assert "panicked" not in r.stderr

    refused(take, "--markers", "tool1,tool2,wrist", words=['"wrist"', "tool1, tool2, tool3"])
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(take.read_bytes()[:5000])
    refused(cut, "--markers", "tool1,tool2,tool3", words=["cut.c3d", "truncated"])
    line = tmp_path / "line.toml"
    line.write_text("".join(f"[[points]]\nmocap = [{i}, {i}, {i}]\nrobot = [{i}, 0, 0]\n" for i in range(3)))
    refused(take, "--markers", "tool1,tool2,tool3", "--to-robot", line, words=["line.toml", "collinear"])
    gap = tmp_path / "gap.c3d"
    write_ezc3d(gap, markers_mm(t, 3), rate, labels, gaps=[(2, 500, 560)])
    refused(gap, "--markers", "tool1,tool2,tool3", words=["gap.c3d", "frames", "tool3"])
    # A parameter section that lies: POINT:LABELS declares 255 × 255 characters.
    lie = bytearray(take.read_bytes())
    at = lie.index(b"LABELS")
    assert lie[at + 6 + 3] == 2  # two dimensions follow the offset and the type
    lie[at + 6 + 4] = lie[at + 6 + 5] = 0xFF
    bad = tmp_path / "lie.c3d"
    bad.write_bytes(bytes(lie))
    r = cli("mocap", "show", bad, check=False)
    assert r.returncode == 2, r.stderr
    assert "lie.c3d" in r.stderr and "parameter LABELS" in r.stderr and "declares" in r.stderr, r.stderr
    refused(bad, "--markers", "tool1,tool2,tool3", words=["lie.c3d", "parameter LABELS"])
    # An existing output is kept unless --force.
    out.write_text("keep me")
    r = cli("mocap", "import", take, "--markers", "tool1,tool2,tool3", "--out", out, check=False)
    assert r.returncode == 2 and out.read_text() == "keep me"


def test_a_take_feeds_the_pose_dmp(tmp_path):
    """The demonstration's orientation is learned by the quaternion DMP and its position by
    a position DMP: the rolled-out pose follows the take's (the known motion, here started
    and ended at rest as a demonstration is, by a minimum-jerk time warp)."""
    rate, frames = 120.0, 961
    t = np.arange(frames) / rate
    duration = t[-1]
    s = t / duration
    warped = duration * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)
    labels = ["tool1", "tool2", "tool3", "tool4"]
    path = tmp_path / "take.c3d"
    write_ezc3d(path, markers_mm(warped, 4), rate, labels)
    demo = cps.mocap.read(path, labels, origin="tool1", axes=["tool1", "tool2", "tool3"], cutoff=None)
    orientation = cps.QuaternionDMP.learn(demo["t"], demo["quaternion"], bases=40)
    tq, q, _ = orientation.rollout()
    p, r = motion(warped)
    assert len(tq) == frames
    err = max(angle_between(quat_to_matrix(a), b) for a, b in zip(q, r))
    # The loop returns near its start: the goal-robust forcing term.
    position = cps.imitate(demo["t"], demo["position"], bases=40, formulation="robust")
    _, y, _, _ = position.rollout()
    print(f"pose DMP of the take: orientation within {np.degrees(err):.3f}°, position within "
          f"{np.abs(y - p).max() * 1e3:.3f} mm")
    assert err < math.radians(1.0)
    assert np.abs(y - p).max() < 2e-3


def test_the_shipped_takes_lie_within_the_thesis_robots_reach(tmp_path, cli):
    """The example takes, registered into the thesis scene's world frame, are within the
    placed Panda's reach; read as if in the Panda's base frame they are not."""
    from conftest import EXPERIMENTS

    takes = EXPERIMENTS / "demos" / "takes"
    args = ["mocap", "import", takes / "pour_1.c3d", "--markers", "tip,m2,m3,m4", "--origin", "tip",
            "--to-robot", takes / "lab.toml", "--out", tmp_path / "pour.csv", "--json", "--force"]
    placed = json.loads(cli(*args, "--scene", "thesis", "--plot", tmp_path / "pour.png").stdout)
    assert placed["beyond_reach"] == 0 and 0.8 < placed["reach_m"] < 1.3
    assert sorted(p.name for p in tmp_path.glob("pour_*.png")) == ["pour_demonstration.png", "pour_markers.png"]
    assert placed["report"]["registration"]["rms_m"] < 1e-3
    assert [m["outliers"] for m in placed["report"]["markers"]] == [0, 0, 0, 0]
    based = json.loads(cli(*args, "--robot", "panda").stdout)
    assert based["beyond_reach"] == based["report"]["frames"]
