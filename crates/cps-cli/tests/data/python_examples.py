"""The calls of CoppeliaSim's own first examples (simpleTest.py, simpleTest-nonBlocking.py
of the ZMQ remote API), written anew, against `cps-cli sim serve`: dummies with a colour
argument, a free-running and a stepped run with sim.addLog, waiting for the stopped
state, removing the dummies; once with the blocking client and once with the asyncio one.

Usage: python python_examples.py PORT   (exit status 0 when every check holds)
"""
import asyncio
import sys

from coppeliasim_zmqremoteapi_client import RemoteAPIClient

PORT = int(sys.argv[1])


def blocking():
    client = RemoteAPIClient(host="127.0.0.1", port=PORT)
    sim = client.require("sim")
    marks = [sim.createDummy(0.02, [0.5] * 12) for _ in range(8)]
    for k, h in enumerate(marks):
        sim.setObjectPosition(h, -1, [0.02 * k, -0.02 * k, 0.5])
    assert sim.getObjectPosition(marks[3], -1) == [0.06, -0.06, 0.5]

    # Free-running: the simulation advances without sim.step.
    sim.startSimulation()
    seen = 0
    while (t := sim.getSimulationTime()) < 1.0:
        sim.addLog(sim.verbosity_scriptinfos, f"free t={t:.2f}")
        seen += 1
    assert 0 < seen < 1000, seen
    sim.stopSimulation()
    while sim.getSimulationState() != sim.simulation_stopped:
        pass
    assert sim.getSimulationTime() == 0.0

    # Stepped: the client advances it.
    sim.setStepping(True)
    sim.startSimulation()
    dt = sim.getSimulationTimeStep()
    for k in range(10):
        assert abs(sim.getSimulationTime() - k * dt) < 1e-9
        sim.addLog(sim.verbosity_warnings, f"stepped k={k}")
        sim.step()
    sim.stopSimulation()
    for h in marks:
        sim.removeObject(h)
    try:
        sim.getObjectPosition(marks[0], -1)
        raise AssertionError("a removed dummy still answers")
    except Exception as e:  # the server's error reply
        assert "does not exist" in str(e), e


async def concurrent():
    from coppeliasim_zmqremoteapi_client.asyncio import RemoteAPIClient as AsyncClient

    async with AsyncClient(host="127.0.0.1", port=PORT) as client:
        sim = await client.require("sim")
        marks = await asyncio.gather(*[sim.createDummy(0.02, [0.1] * 12) for _ in range(8)])
        assert len(set(marks)) == 8, marks
        await asyncio.gather(*[
            sim.setObjectPosition(h, -1, [0.0, 0.01 * k, 0.2]) for k, h in enumerate(marks)
        ])
        await sim.startSimulation()
        while (t := await sim.getSimulationTime()) < 0.5:
            await sim.addLog(sim.verbosity_scriptinfos, f"async t={t:.2f}")
        await sim.stopSimulation()
        while await sim.getSimulationState() != sim.simulation_stopped:
            await asyncio.sleep(0.01)
        await asyncio.gather(*[sim.removeObject(h) for h in marks])


blocking()
asyncio.run(concurrent())
print("python examples ok")
