"""`cps-cli export` read back by readers nobody here wrote: MCAP through `mcap` and
`mcap-ros2-support` (every message decoded and compared with the trajectory), the URDF on
/robot_description through pinocchio (its forward kinematics against /tf and `cps-cli fk`),
the YAML through PyYAML and mcap_ros2's own CDR encoder."""

import json

import numpy as np
import pytest

mcap_reader = pytest.importorskip("mcap.reader")
mcap_ros2_reader = pytest.importorskip("mcap_ros2.reader")
mcap_ros2_dynamic = pytest.importorskip("mcap_ros2._dynamic")
yaml = pytest.importorskip("yaml")

PANDA_NAMES = [f"panda_joint{i}" for i in range(1, 8)]


@pytest.fixture(scope="module")
def trajectory(tmp_path_factory, cli):
    """A quintic move of every joint from Franka's ready pose, 1 kHz, 0.8 s."""
    d = tmp_path_factory.mktemp("export")
    a = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    b = a + np.array([0.4, 0.3, -0.3, 0.5, 0.2, -0.3, 0.6])
    t = np.arange(801) / 1000.0
    s = t / t[-1]
    sigma = s**3 * (10 - 15 * s + 6 * s**2)
    q = a + np.outer(sigma, b - a)
    path = d / "move.csv"
    with open(path, "w") as fh:
        fh.write("t," + ",".join(f"q{i}" for i in range(1, 8)) + "\n")
        for ti, row in zip(t, q):
            fh.write(",".join(repr(float(x)) for x in [ti, *row]) + "\n")
    return d, path, t, q


def export(cli, trajectory, fmt, *extra):
    d, path, _, _ = trajectory
    out = d / f"out.{fmt}"
    p = cli("export", path, "--robot", "panda", "--format", fmt, "--out", out, "--force", "--json", *extra)
    return out, json.loads(p.stdout)


def test_mcap_messages_decode_to_the_trajectory(cli, trajectory):
    _, _, t, q = trajectory
    out, info = export(cli, trajectory, "mcap")
    with open(out, "rb") as fh:
        reader = mcap_reader.make_reader(fh)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        schemas = {s.id: s for s in summary.schemas.values()}
    assert set(channels) == {
        "/robot_description",
        "/tf_static",
        "/tf",
        "/joint_states",
        "/joint_trajectory_controller/joint_trajectory",
    }
    for c in channels.values():
        assert c.message_encoding == "cdr" and schemas[c.schema_id].encoding == "ros2msg"
        qos = yaml.safe_load(c.metadata["offered_qos_profiles"])
        latched = c.topic in ("/tf_static", "/robot_description")
        assert qos[0]["durability"] == (1 if latched else 2) and qos[0]["reliability"] == 1
    msgs = {}
    for m in mcap_ros2_reader.read_ros2_messages(str(out)):
        msgs.setdefault(m.channel.topic, []).append(m)
    assert {k: len(v) for k, v in msgs.items()} == info["topics"]
    # Every 10 ms falls on a sample of the 1 kHz file: the spline passes through it.
    states = msgs["/joint_states"]
    assert len(states) == 81
    for k, m in enumerate(states):
        js = m.ros_msg
        assert list(js.name) == PANDA_NAMES
        assert m.log_time_ns == 10_000_000 * k
        assert js.header.stamp.sec * 10**9 + js.header.stamp.nanosec == m.log_time_ns
        np.testing.assert_allclose(js.position, q[10 * k], atol=1e-12)
    np.testing.assert_allclose(states[0].ros_msg.velocity, 0.0, atol=1e-9)
    (jt,) = msgs["/joint_trajectory_controller/joint_trajectory"]
    points = jt.ros_msg.points
    assert list(jt.ros_msg.joint_names) == PANDA_NAMES and len(points) == 81
    for k, p in enumerate(points):
        assert p.time_from_start.sec * 10**9 + p.time_from_start.nanosec == 10_000_000 * k
        np.testing.assert_allclose(p.positions, q[10 * k], atol=1e-12)
    # Velocities against numpy's central differences of the 1 kHz positions.
    dq = np.gradient(q, t, axis=0)
    for k in range(1, 80):
        np.testing.assert_allclose(points[k].velocities, dq[10 * k], atol=2e-4)


def test_robot_description_and_tf_agree_with_pinocchio_and_cps_fk(cli, trajectory):
    pin = pytest.importorskip("pinocchio")
    _, _, _, q = trajectory
    out, _ = export(cli, trajectory, "mcap")
    msgs = {}
    for m in mcap_ros2_reader.read_ros2_messages(str(out)):
        msgs.setdefault(m.channel.topic, []).append(m.ros_msg)
    urdf = msgs["/robot_description"][0].data
    model = pin.buildModelFromXML(urdf)
    data = model.createData()
    assert [model.names[i] for i in range(1, model.njoints)] == PANDA_NAMES

    def pose(tf):
        t, r = tf.translation, tf.rotation
        return pin.SE3(pin.Quaternion(r.w, r.x, r.y, r.z).matrix(), np.array([t.x, t.y, t.z]))

    static = {x.child_frame_id: (x.header.frame_id, pose(x.transform)) for x in msgs["/tf_static"][0].transforms}
    for k in (0, 37, 80):
        frames = dict(static)
        for x in msgs["/tf"][k].transforms:
            frames[x.child_frame_id] = (x.header.frame_id, pose(x.transform))

        def world(frame):
            parent, t = frames[frame]
            return t if parent == "world" else world(parent) * t

        pin.framesForwardKinematics(model, data, q[10 * k])
        for name in ["panda_link3", "panda_link7", "panda_tool"]:
            expect = data.oMf[model.getFrameId(name)]
            got = world(name)
            np.testing.assert_allclose(got.translation, expect.translation, atol=1e-12)
            np.testing.assert_allclose(got.rotation, expect.rotation, atol=1e-12)
        fk = json.loads(cli("fk", "--robot", "panda", "--q", ",".join(repr(float(x)) for x in q[10 * k]), "--json").stdout)
        np.testing.assert_allclose(world("panda_tool").translation, fk["position"], atol=1e-12)


def test_yaml_is_a_joint_trajectory_for_topic_pub_and_action_goals(cli, trajectory):
    _, _, _, q = trajectory
    out, info = export(cli, trajectory, "ros2-yaml", "--period", "0.02")
    text = out.read_text()
    msg = yaml.safe_load(text)
    goal = yaml.safe_load("{trajectory: " + text + "}")
    assert goal["trajectory"] == msg
    assert msg["joint_names"] == PANDA_NAMES and len(msg["points"]) == 41 == info["points"]
    for k, p in enumerate(msg["points"]):
        for field in ("positions", "velocities", "accelerations"):
            assert len(p[field]) == 7 and all(type(x) is float for x in p[field]), (k, field)
        assert p["time_from_start"] == {"sec": 0, "nanosec": 20_000_000 * k}
        np.testing.assert_allclose(p["positions"], q[20 * k], atol=1e-12)
    # mcap_ros2's encoder fills the message from the YAML as ROS's typed fields would,
    # and gives the bytes cps wrote into the MCAP file.
    mc, _ = export(cli, trajectory, "mcap", "--period", "0.02")
    with open(mc, "rb") as fh:
        reader = mcap_reader.make_reader(fh)
        for schema, channel, message in reader.iter_messages(topics=["/joint_trajectory_controller/joint_trajectory"]):
            encode = mcap_ros2_dynamic.serialize_dynamic(schema.name, schema.data.decode())[schema.name]
            for p in msg["points"]:
                p["effort"] = []
            assert encode(msg) == message.data


def test_csv_1khz_and_bad_input(cli, trajectory):
    d, path, t, q = trajectory
    out, info = export(cli, trajectory, "csv-1khz")
    data = np.genfromtxt(out, delimiter=",", names=True)
    assert data.dtype.names[1:8] == tuple(PANDA_NAMES) and data.dtype.names[8] == "panda_joint1_vel"
    np.testing.assert_allclose(np.stack([data[n] for n in PANDA_NAMES], 1), q, atol=1e-12)
    assert info["limits_ok"] is True
    # Wrong joint count, an unknown format, a foreign file at --out: exit 2, nothing touched.
    (d / "three.csv").write_text("t,a,b,c\n0,0,0,0\n1,1,1,1\n")
    target = d / "new.mcap"
    p = cli("export", d / "three.csv", "--robot", "panda", "--format", "mcap", "--out", target, check=False)
    assert p.returncode == 2 and "7-joint robot" in p.stderr and not target.exists()
    p = cli("export", path, "--robot", "panda", "--format", "bag", "--out", target, check=False)
    assert p.returncode == 2 and "`ros2-yaml`" in p.stderr and not target.exists()
    foreign = d / "notes.mcap"
    foreign.write_text("my notes")
    p = cli("export", path, "--robot", "panda", "--format", "mcap", "--out", foreign, "--force", check=False)
    assert p.returncode == 2 and foreign.read_text() == "my notes"
