"""A full session of the official CoppeliaSim Python client against `cps-cli sim serve`.

Usage: python python_session.py PORT   (exit status 0 when every check holds)
"""
import math
import sys

from coppeliasim_zmqremoteapi_client import RemoteAPIClient

client = RemoteAPIClient(host="127.0.0.1", port=int(sys.argv[1]))
sim = client.require("sim")

# Handles of the seven joints; read and set them.
joints = [sim.getObject(f"/Panda_joint{i}") for i in range(1, 8)]
q0 = [sim.getJointPosition(j) for j in joints]
assert q0 == [0, 0, 0, 0, 0, math.pi / 2, math.pi / 4], q0
for j, v in zip(joints, [0.1, -0.2, 0.3, -1.5, 0.2, 1.6, 0.7]):
    sim.setJointPosition(j, v)
assert abs(sim.getJointPosition(joints[3]) + 1.5) < 1e-15

# The tip moves with the joints.
tip = sim.getObject("/Panda_tip")
p = sim.getObjectPosition(tip, sim.handle_world)
assert len(p) == 3 and abs(p[2] - 1.87) > 1e-3, p

# A dummy: create, alias, move, find, remove.
d = sim.createDummy(0.04)
sim.setObjectAlias(d, "pX")
sim.setObjectPosition(d, [0.1, 0.2, 0.3], sim.handle_world)
assert sim.getObject("/pX") == d
assert sim.getObjectPosition(d, sim.handle_world) == [0.1, 0.2, 0.3]
sim.removeObjects([d])

# Start, stepping, several steps with the time advancing by dt, stop.
sim.startSimulation()
assert sim.setStepping(True) == 0
t0 = sim.getSimulationTime()
for k in range(1, 6):
    sim.step()
    assert abs(sim.getSimulationTime() - t0 - 0.05 * k) < 1e-12
sim.stopSimulation()
assert sim.getSimulationState() == sim.simulation_stopped

# A callback: the server calls the client's function (21 * 2) four times during one call.
calls = []
def multiply(a, b):
    calls.append((a, b))
    return a * b
assert sim.testCB(21, multiply, 2, 3) == 42
assert calls == [(21, 2)] * 4, calls

# An error raised on the server raises here.
try:
    sim.getObject("/DoesNotExist")
except Exception as e:  # the client raises a plain Exception with the server's text
    assert "Object does not exist" in str(e), e
else:
    raise AssertionError("no exception for a missing object")
# Degenerate matrices, poses and joint values get an error reply; the server keeps
# answering (a reflection used to hang it).
d = sim.createDummy(0.01)
degenerate = [
    [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0],           # a reflection
    [0] * 12,                                        # zeros
    [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0],            # a scaling
    [1e300, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0],        # huge
    [float("nan"), 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0], # not finite
]
for m in degenerate:
    try:
        sim.setObjectMatrix(d, m, sim.handle_world)
    except Exception as e:
        assert "matrix" in str(e) or "finite" in str(e), e
    else:
        raise AssertionError(f"no exception for the matrix {m}")
for pose in ([0, 0, 0, 0, 0, 0, 0], [float("inf"), 0, 0, 0, 0, 0, 1]):
    try:
        sim.setObjectPose(d, pose, sim.handle_world)
    except Exception:
        pass
    else:
        raise AssertionError(f"no exception for the pose {pose}")
try:
    sim.setJointPosition(sim.getObject("/Panda_joint1"), float("nan"))
except Exception:
    pass
else:
    raise AssertionError("no exception for a NaN joint value")
sim.setObjectMatrix(d, [1, 0, 0, 0.5, 0, 1, 0, 0.25, 0, 0, 1, 0.125], sim.handle_world)
assert sim.getObjectPosition(d, sim.handle_world) == [0.5, 0.25, 0.125]
sim.removeObjects([d])
print("python session ok")
