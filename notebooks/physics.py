# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Agent, robot and physics runs of the paper's warehouse
#
# The overview paper runs its experiments on three levels: an agent simulation
# (constant velocity), a robot simulation in a physics engine, and real robots. Here the
# same warehouse schedule (10 youBots, 2 Pioneers; CBM plan, MAPF-POST) runs under the
# bundled disturbances (a stop, a blocking breakdown, a water spill, random delays) in
# `agent` mode, in `robot` mode (bounded acceleration, turning in place) and in
# `physics` mode: MuJoCo bodies with force-limited motors, floor grip, inertia and the
# controllers of `hierplan_opt.physics` (docs/physics.md), closed loop with the
# execution hierarchy (slack -> STN re-solve -> re-plan).

# %%
import io
import os
import time

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from IPython.display import Image, display

import hierplan_opt as hp
from hierplan_opt.execution import load_disturbances, simulate
from hierplan_opt.io import load_instance
from hierplan_opt.schedule import postprocess

here = "instances" if os.path.isdir("instances") else "../instances"
inst = load_instance(f"{here}/paper/warehouse-part1.yaml")
dist = load_disturbances(f"{here}/paper/warehouse-disturbances.yaml")
res = hp.solve(inst, "cbm", time_limit=60)
sched = postprocess(inst, res.plan)
print(f"plan makespan {res.plan.makespan} steps; schedule makespan {sched.makespan:.2f} s")

# %% [markdown]
# ## The three runs side by side

# %%
runs = {}
for mode in ("agent", "robot", "physics"):
    t0 = time.perf_counter()
    runs[mode] = simulate(inst, sched, disturbances=dist, mode=mode)
    runs[mode].statistics["wall_s"] = time.perf_counter() - t0

cols = ["makespan", "collisions", "min_distance", "guaranteed_distance", "finished"]
print(f"{'mode':8} " + " ".join(f"{c:>19}" for c in cols) + f" {'layers':>34} {'wall s':>7}")
for mode, ex in runs.items():
    st = ex.statistics
    layers = ", ".join(f"{k} {v}" for k, v in st["handled"].items() if v)
    vals = " ".join(f"{st[c]:>19.3f}" if isinstance(st[c], float) else f"{st[c]:>19}" for c in cols)
    print(f"{mode:8} {vals} {layers:>34} {st['wall_s']:>7.2f}")
for mode, ex in runs.items():
    st = ex.statistics
    assert st["collisions"] == 0 and st["distance_kept"], mode
phys = runs["physics"].statistics
print(
    f"physics: {phys['physics_steps']} physics steps, {phys['real_time_factor']:.1f}x real time, "
    f"tracking error max {phys['tracking_error_max']:.2f} m, "
    f"RMS {phys['tracking_error_rms']:.2f} m"
)
assert phys["real_time_factor"] >= 10

# %% [markdown]
# Each disturbance and the layer that handled it in the physics run (the cause is what
# the plant saw act on the robot; `tracking` is the physics' own lag):

# %%
for e in runs["physics"].log:
    if e.kind != "tracking":
        print(f"t={e.time:6.1f}  {e.agent:9} {e.kind:9} -> {e.layer:6} {e.detail}")

# %% [markdown]
# ## Where the robots were
#
# Paths of four robots in the three runs (the physics run's re-plan after the breakdown
# of youbot8 sends youbot7 another way), and the arrival of every working robot at its
# goal.

# %%
names = list(runs["agent"].agent_names)
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.2))
style = {"agent": ("-", 2.5), "robot": ("--", 1.8), "physics": (":", 1.8)}
for k, n in enumerate(["youbot6", "youbot7", "pioneer1", "pioneer2"]):
    i = names.index(n)
    for mode, ex in runs.items():
        tr = ex.trajectories[i]
        ls, lw = style[mode]
        ax1.plot(
            tr[:, 1],
            tr[:, 2],
            ls,
            lw=lw,
            color=f"C{k}",
            label=f"{n} {mode}" if k == 0 or mode == "agent" else None,
        )
ax1.invert_yaxis()
ax1.set_aspect("equal")
ax1.set_title("paths (grid cells; solid agent, dashed robot, dotted physics)")
ax1.legend(fontsize=7, loc="lower left")
x = np.arange(len(names))
for j, (mode, ex) in enumerate(runs.items()):
    ax2.bar(x + (j - 1) * 0.27, ex.arrival, 0.27, label=mode)
ax2.set_xticks(x, names, rotation=60, fontsize=8)
ax2.set_ylabel("arrival at goal (s)")
ax2.set_title("arrivals (youbot8 breaks down)")
ax2.legend()
fig.tight_layout()
buf = io.BytesIO()
fig.savefig(buf, format="png", dpi=70)
plt.close(fig)
display(Image(buf.getvalue()))

# %% [markdown]
# ## Tracking error and clearance in physics
#
# The distance of each robot from where the first schedule has it, over time (large
# where a robot waits for the re-plan or follows it), and the smallest distance of any
# pair against the guaranteed clearance.

# %%
from hierplan_opt.physics.run import scheduled_positions

ex = runs["physics"]
t = ex.trajectories[0][:, 0]
pos = np.stack([tr[:, 1:] for tr in ex.trajectories], axis=1) * sched.scale
plan_pos = scheduled_positions(sched, t)[:, :, : pos.shape[2]]
err = np.linalg.norm(pos - plan_pos, axis=2)
iu = np.triu_indices(len(names), 1)
dmin = np.array([np.linalg.norm(p[iu[0]] - p[iu[1]], axis=1).min() for p in pos])
fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 3.5))
for i, n in enumerate(names):
    a1.plot(t, err[:, i], lw=1, label=n)
a1.set_xlabel("time (s)")
a1.set_ylabel("tracking error (m)")
a1.legend(fontsize=6, ncol=2)
a2.plot(t, dmin, label="closest pair")
a2.axhline(sched.safety_distance, color="r", ls="--", label="guaranteed")
a2.set_xlabel("time (s)")
a2.set_ylabel("distance (m)")
a2.legend()
fig.tight_layout()
buf = io.BytesIO()
fig.savefig(buf, format="png", dpi=70)
plt.close(fig)
display(Image(buf.getvalue()))
assert dmin.min() >= sched.safety_distance - 1e-9
print(f"closest pair {dmin.min():.3f} m (guaranteed {sched.safety_distance:.3f} m)")
