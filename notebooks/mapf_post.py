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
# # MAPF-POST: from a discrete plan to an execution schedule
#
# A discrete plan moves every robot one cell per timestep. `hp.postprocess` builds the
# temporal plan graph (TPG) with safety markers chosen from the robots' radii (every pair
# keeps `r_i + r_j + margin` between centres), turns it into a simple temporal network
# with each robot's kinematics, and computes node times:
#
# * `makespan` — earliest schedule (`method="graph"`, longest paths) or the LP; both must agree;
# * `safety` — LP maximising the slowest speed, then the makespan at that level;
# * `flowtime` — LP minimising the sum of arrival times.
#
# A constant-velocity replay (`hierplan_opt.schedule.replay`) measures the true minimum
# distance of every pair of robots, which must be at least `r_i + r_j + margin`.

# %%
import time

import matplotlib.pyplot as plt
import numpy as np

import hierplan_opt as hp
from hierplan_opt.experiments import instances_dir
from hierplan_opt.io import load_instance
from hierplan_opt.viz.plots import format_table, plot_plan

ROOT = instances_dir()  # the benchmark instances shipped with the package
MOVINGAI = ROOT / "movingai"
PAPER = ROOT / "paper"

# %%
import dataclasses

from hierplan_opt.schedule import check_bounds, replay

MAP, SCEN = MOVINGAI / "random-32-32-20.map", MOVINGAI / "random-32-32-20-random-1.scen"
base = load_instance(MAP, SCEN, 10)
# Two robot types (our choice, for illustration): even agents are fast omni-directional
# robots, odd agents slow differential-drive robots that turn in place.
fast = hp.Kinematics("fast", "omni", v_max=1.0, a_max=1.0, radius=0.3)
slow = hp.Kinematics("slow", "differential", v_max=0.5, omega_max=1.0, a_max=0.5, radius=0.3)
agents = tuple(
    dataclasses.replace(a, kinematics=fast if i % 2 == 0 else slow)
    for i, a in enumerate(base.agents)
)
inst = dataclasses.replace(base, agents=agents)
res = hp.solve(inst, "cbs", time_limit=30)
plan = res.plan
print(f"CBS plan: sum of costs {plan.sum_of_costs}, makespan {plan.makespan} timesteps")

# %%
runs = [("makespan", "graph"), ("makespan", "lp"), ("safety", "lp"), ("flowtime", "lp")]
schedules, rows = {}, []
for objective, method in runs:
    t0 = time.perf_counter()
    s = hp.postprocess(inst, plan, objective, method=method, margin=0.25)
    elapsed = time.perf_counter() - t0
    rep = replay(s, inst, all_pairs=True)
    schedules[objective, method] = s
    rows.append(
        {
            "objective": objective,
            "method": method,
            "makespan": round(s.makespan, 4),
            "flowtime": round(s.flowtime, 4),
            "safety_dist": round(s.safety_distance, 4),
            "replay_min_dist": round(rep.min_distance, 4),
            "stn_nodes": len(s.times),
            "runtime": round(elapsed, 3),
        }
    )
    assert rep.ok and rep.min_distance >= s.safety_distance - 1e-9, (objective, method)
    assert check_bounds(s.stn, s.times) == [], (objective, method)
print(format_table(rows))
graph_ms = schedules["makespan", "graph"].makespan
assert abs(schedules["makespan", "lp"].makespan - graph_ms) <= 1e-6 * max(1.0, graph_ms)
assert schedules["flowtime", "lp"].flowtime <= schedules["makespan", "graph"].flowtime + 1e-6
assert schedules["safety", "lp"].makespan >= graph_ms - 1e-6

# %% [markdown]
# The graph method and the LP agree on the minimum makespan. The flowtime LP cannot beat
# the earliest schedule here (with lower bounds only, every node at its earliest time
# minimises every arrival at once) — the check above asserts it is never worse. The safety
# LP raises the slowest speed: robots keep moving, and the replay's distances grow beyond
# the guaranteed `r_i + r_j + margin`. Below: the Gantt chart of the earliest schedule —
# one row per robot, bars are arrival windows (slack), red ticks the critical path.

# %%
try:
    from hierplan_opt.viz.gantt import plot_gantt
except ImportError as exc:  # the Gantt module belongs to the MAPF-POST part
    print("no Gantt plot:", exc)
else:
    fig = plot_gantt(schedules["makespan", "graph"])
    fig.set_size_inches(10, 4.5)

# %%
fig, axes = plt.subplots(1, 2, figsize=(12, 4))
s = schedules["makespan", "graph"]
for kin, marker in ((fast, "o"), (slow, "s")):
    idx = [i for i, a in enumerate(inst.agents) if a.kinematics is kin]
    steps = [plan.costs[i] for i in idx]
    finish = [float(s.waypoints[i].arrival[-1]) for i in idx]
    axes[0].scatter(steps, finish, marker=marker, label=f"{kin.robot_type} ({kin.drive})")
    x = np.array([0, max(plan.costs)])
    axes[0].plot(x, x / kin.v_max, ls=":", color="0.5")  # straight driving at v_max
axes[0].axhline(s.makespan, color="0.3", ls="--", lw=1, label="makespan")
axes[0].set_xlabel("discrete path cost [steps]")
axes[0].set_ylabel("arrival at the goal [s]")
axes[0].legend(fontsize=8)
axes[0].set_title("finish time per robot (dotted: distance / v_max)")
margins = [0.0, 0.1, 0.2, 0.3, 0.35]  # robots of radius 0.3 m on 1 m cells
ms = [hp.postprocess(inst, plan, margin=d).makespan for d in margins]
axes[1].plot(margins, ms, marker="o")
axes[1].set_xlabel("margin beyond r_i + r_j [m]")
axes[1].set_ylabel("earliest-schedule makespan [s]")
axes[1].set_title("makespan vs clearance margin")
fig.tight_layout()
print("makespan per margin:", {d: round(float(m), 3) for d, m in zip(margins, ms, strict=True)})

# %% [markdown]
# Left: every robot needs at least its distance divided by its top speed (dotted lines).
# The acceleration-aware bounds add more (with `a_max` = 1 m/s² a fast robot needs 2 s per
# 1 m cell here, as its way-points below show), slow robots turn in place, and robots wait
# for each other. Right: the
# makespan of the earliest schedule as the clearance margin beyond the two radii grows
# (robots hold a cell until they are `cell/2 + r + margin/2` beyond it). The numbers are
# this plan's, not a general law.

# %%
ax = plot_plan(inst, plan, legend=False, title="the plan that was scheduled")
ax.figure.set_size_inches(6, 5.5)
print("first robot's way-points (x, y, arrival):")
wp = s.waypoints[0]
for xy, kind, t in list(zip(wp.coords.tolist(), wp.kind, wp.arrival.tolist(), strict=True))[:8]:
    print(f"  {kind:6s} {xy}  t = {t:.3f}")
