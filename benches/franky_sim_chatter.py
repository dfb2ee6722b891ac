"""franky-sim's own joint controller, stepped directly (no server): joints 1, 5 and 7
follow 0.3·sin(t) for 2 s under franky-sim's PD, and the torques it applies are read
each millisecond. Its wrist gains sit beyond explicit integration's stability at 1 ms
(kv·h/M ≈ 2.6 on joint 7), so the wrist torque flips sign every step, clipped at the
drive's 12 N m — what cps's dynamics robot does with the same gains (docs/robots.md ›
A robot with dynamics).

    target/franka-venv/bin/python benches/franky_sim_chatter.py
"""

import numpy as np
from franky_sim.mujoco_simulator import MujocoSimulator
sim = MujocoSimulator()
robot = sim.add_robot()
sim.init(); sim.start()
q0 = np.array(robot.initial_q)
taus, dqs = [], []
for k in range(2000):
    t = k * 1e-3
    qd = q0.copy(); qd[4] += 0.3 * np.sin(t); qd[6] += 0.3 * np.sin(t); qd[0] += 0.3*np.sin(t)
    robot.joint_position_control(qd)
    sim.step()
    taus.append(robot._applied_torques.copy())
    dqs.append(np.array(robot._get_state().dq))
taus = np.array(taus); dqs = np.array(dqs)
d = np.diff(taus[1000:], axis=0)
alt = (np.sign(d[1:]) != np.sign(d[:-1])).mean(axis=0)
print("share of steps where the torque change flips sign (chatter ~1.0):", np.round(alt, 2))
print("tau7 steps 1000..1008:", np.round(taus[1000:1008, 6], 3))
print("tau5 steps 1000..1008:", np.round(taus[1000:1008, 4], 3))
print("clipped at 12:", (np.abs(taus[:, 4:]) >= 11.999).sum(axis=0))
