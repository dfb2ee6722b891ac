# %% [markdown]
# # cps from Python: a via-point movement, learned, imitated and checked on the Panda
#
# A notebook in plain Python (`# %%` cells run in VS Code, Jupyter via jupytext, or
# `python viapoint_notebook.py`). It learns the thesis's via-point movement with CMA-ES,
# compares it with the exact optimum, imitates the result from samples, moves the goal,
# checks the path on the Panda by inverse kinematics, and ends in a figure.

# %%
import sys
from pathlib import Path

import matplotlib

if "ipykernel" not in sys.modules:
    matplotlib.use("Agg")  # no display needed when run as a script
import matplotlib.pyplot as plt
import numpy as np

import cps

# %% [markdown]
# ## 1. Learn the movement through four via points (thesis Table 3)

# %%
start, goal = [0.75, 0.02, 1.87], [0.55, -0.57, 1.45]
via = [(2.0, [0.78, 0.60, 1.70]), (4.0, [1.12, 0.37, 1.45]),
       (6.0, [1.15, -0.15, 1.20]), (8.0, [0.90, -0.53, 1.20])]
res = cps.learn_via_points(start, goal, via, tau=10.0, population=96, generations=3000,
                           tol_fun=1e-3, seed=1)
print(res)
print(f"{res.generations} generations, {res.evaluations} evaluations; "
      f"cost {res.cost:.6f} vs the exact optimum {res.optimum_cost:.6f}")

# %% [markdown]
# ## 2. Imitate the learned movement from its samples, then send it to a new goal

# %%
t, y, yd, ydd = res.trajectory
dmp = cps.imitate(t, y, bases=25, names=["x", "y", "z"])
print("imitation RMSE per axis (m):", dmp.fit["rmse"])
moved = dmp.rollout(goal=[0.60, -0.40, 1.30])

# %% [markdown]
# ## 3. Can the Panda follow it? Inverse kinematics of every 10th sample, in one call

# %%
panda = cps.Robot("panda")
base = np.array([0.5396, 0.02, 0.749])  # where the thesis scene puts the Panda's base
q = panda.ik(moved.y[::10] - base)
print(f"{len(q)} configurations, all within the joint limits: {bool(panda.within_limits(q).all())}")

# %% [markdown]
# ## 4. The figure

# %%
fig, axes = plt.subplots(1, 3, figsize=(13, 3.6), constrained_layout=True)
for d, name in enumerate("xyz"):
    ax = axes[d]
    ax.plot(t, y[:, d], label="learned (CMA-ES)")
    ax.plot(moved.t, moved.y[:, d], "--", label="imitated, new goal")
    ax.plot([v[0] for v in via], [v[1][d] for v in via], "o", color="k", label="via points")
    ax.set_xlabel("t (s)")
    ax.set_ylabel(f"{name} (m)")
axes[0].legend(loc="best", fontsize=8)
fig.suptitle(f"Thesis via-point task: cost {res.cost:.4f} (optimum {res.optimum_cost:.4f})")
out = Path(__file__).with_name("viapoint.png")
fig.savefig(out, dpi=110)
print(f"figure: {out}")
