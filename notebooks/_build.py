"""Write the project's notebooks (nbformat 4 JSON) from the Python source below.

The cells live here as plain strings so that changes are reviewable in a diff; the
``.ipynb`` files are generated. Jupyter is not needed:

    python notebooks/_build.py              # write the notebooks without outputs
    python notebooks/_build.py --execute    # run every code cell and store the outputs
                                            # (text and PNG figures) in the notebooks
    python notebooks/_build.py --check      # exit 1 if an .ipynb's cells differ from here
    python notebooks/_build.py --execute --only mapf_post
    python notebooks/_build.py --execute --allow-errors   # keep going past a failing
                                            # cell, store its traceback (exit status 1)

Execution runs each notebook's code cells in order in one fresh namespace, with
matplotlib's Agg backend and the working directory set to ``notebooks/`` (as Jupyter
would); every figure left open after a cell is stored as a base64 PNG and closed.
``tests/test_notebooks.py`` uses :func:`run_cells` the same way.
"""

from __future__ import annotations

import argparse
import ast
import base64
import contextlib
import io
import json
import linecache
import os
import sys
import time
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
#: PNG resolution of stored figures; keeps every notebook well under 1 MB.
DPI = 72
MAX_BYTES = 1_000_000


def setup(viz: str, *, numpy: bool = True, timing: bool = False) -> str:
    """The first code cell: imports (only those used, ruff checks notebooks too) and paths
    that work from ``notebooks/`` (Jupyter) as well as from the repository root."""
    return (
        ("import time\n" if timing else "")
        + "from pathlib import Path\n\nimport matplotlib.pyplot as plt\n"
        + ("import numpy as np\n" if numpy else "")
        + "\nimport hierplan_opt as hp\nfrom hierplan_opt.io import load_instance\n"
        + f"from hierplan_opt.viz.plots import {viz}\n\n"
        + "here = Path.cwd()\n"
        + 'ROOT = next(p for p in (here, *here.parents) if (p / "instances" / "movingai").is_dir())\n'  # noqa: E501
        + 'MOVINGAI = ROOT / "instances" / "movingai"\n'
        + 'PAPER = ROOT / "instances" / "paper"'
    )


# ---------------------------------------------------------------------------------------
# 1. Solver comparison
# ---------------------------------------------------------------------------------------
SOLVER_COMPARISON: list[tuple[str, str]] = [
    (
        "md",
        """\
# Solver comparison on a MovingAI benchmark

The first *K* agents of `random-32-32-20-random-1.scen` (32x32 grid, 20 % obstacles),
solved for **sum of costs** by

* `cbs` — optimal CBS with MDD conflict prioritisation, bypass, WDG heuristic, disjoint
  splitting and symmetry reasoning;
* `ecbs` with *w* = 1.2 and 1.5, `eecbs` with *w* = 1.2 — bounded-suboptimal (cost ≤ *w* ·
  optimum); they report the lower bound they proved;
* `mip` (time-expanded network, Pyomo + HiGHS) and `cpsat` (OR-Tools CP-SAT) — the exact
  formulations, run on the smaller *K* only because they are much slower.

Every solver has a time limit; timings are wall-clock on whatever machine executed the
notebook (the stored outputs come from a shared 2-core machine, so they are noisy).
The last cells **assert** that all proven optima agree and that the bounded solvers keep
their bound.""",
    ),
    ("code", setup("format_table, plot_plan, plot_runtime_table", numpy=False)),
    (
        "code",
        """\
MAP = MOVINGAI / "random-32-32-20.map"
SCEN = MOVINGAI / "random-32-32-20-random-1.scen"
K_SEARCH = (5, 10, 20, 30)  # agents for the search solvers
K_FORM = (4, 8)  # agents for the formulations (MIP, CP-SAT)
TIME_LIMIT = 20.0  # seconds per solver call

SOLVERS = [  # (label, registry name, options)
    ("cbs", "cbs", {}),
    ("ecbs(1.2)", "ecbs", {"w": 1.2}),
    ("ecbs(1.5)", "ecbs", {"w": 1.5}),
    ("eecbs(1.2)", "eecbs", {"w": 1.2}),
    ("mip", "mip", {}),
    ("cpsat", "cpsat", {}),
]
FORMULATIONS = {"mip", "cpsat"}
instances = {K: load_instance(MAP, SCEN, K) for K in sorted(set(K_SEARCH) | set(K_FORM))}
print({K: inst.soc_lower_bound() for K, inst in instances.items()}, "(distance lower bounds)")""",
    ),
    (
        "code",
        """\
rows, plans, errors = [], {}, {}
for K, inst in instances.items():
    for label, name, opts in SOLVERS:
        if K not in (K_FORM if name in FORMULATIONS else K_SEARCH):
            continue
        res = hp.solve(inst, name, time_limit=TIME_LIMIT, **opts)
        plans[label, K] = res.plan
        if res.status == hp.Status.ERROR:  # e.g. the front door refused an invalid plan
            errors[label, K] = res.stats.get("error", "no message")
        rows.append(
            {
                "agents": K,
                "solver": label,
                "status": res.status.value,
                "cost": res.cost,
                "lower_bound": res.lower_bound,
                "cost/LB": res.cost / res.lower_bound if res.cost and res.lower_bound else None,
                "runtime": round(res.runtime, 3),
                "hl_nodes": res.stats.get("high_level_expanded"),
            }
        )
print(format_table(rows))
for (label, K), message in errors.items():
    print(f"ERROR {label} with {K} agents: {message}")""",
    ),
    (
        "code",
        """\
title = "random-32-32-20-random-1: runtime vs agents"
ax = plot_runtime_table(rows, time_limit=TIME_LIMIT, title=title)
ax.figure.set_size_inches(7, 4)""",
    ),
    (
        "md",
        """\
## Checks

* every returned plan passes the one validator (`hp.validate`);
* all solvers that report OPTIMAL on the same *K* agree on the cost;
* a bounded solver's cost is at most *w* times the optimum, and its lower bound is at
  most the optimum (it is a proven bound);
* CBS proves optimality on every *K* here (it is the reference).""",
    ),
    (
        "code",
        """\
assert not errors, f"solver errors: {errors}"
W = {label: opts["w"] for label, _, opts in SOLVERS if "w" in opts}
optimum = {}
for r in rows:
    K, label = r["agents"], r["solver"]
    plan = plans[label, K]
    if plan is not None:
        assert hp.validate(instances[K], plan) == [], (label, K)
    if r["status"] == "OPTIMAL" and label not in W:
        assert optimum.setdefault(K, r["cost"]) == r["cost"], f"{label} disagrees at K={K}"
for K in K_SEARCH:
    cbs_row = next(r for r in rows if r["agents"] == K and r["solver"] == "cbs")
    assert cbs_row["status"] == "OPTIMAL", cbs_row
for r in rows:
    K, label = r["agents"], r["solver"]
    if label in W and r["cost"] is not None:
        assert r["cost"] <= W[label] * optimum[K] + 1e-9, (label, K)
        assert r["lower_bound"] is None or r["lower_bound"] <= optimum[K], (label, K)
    if r["status"] == "TIME_LIMIT" and r["lower_bound"] is not None:
        assert r["lower_bound"] <= optimum[K], (label, K)
print("optimal sums of costs:", optimum)
print(
    "worst achieved cost/optimum per bounded solver:",
    {
        label: round(max(r["cost"] / optimum[r["agents"]] for r in rows if r["solver"] == label), 4)
        for label in W
    },
)""",
    ),
    (
        "code",
        """\
K = max(K_SEARCH)
fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
for ax, label in zip(axes, ("cbs", "ecbs(1.5)"), strict=True):
    plot_plan(instances[K], plans[label, K], ax, legend=False, title=f"{label}, {K} agents")
fig.tight_layout()""",
    ),
]

# ---------------------------------------------------------------------------------------
# 2. Verification
# ---------------------------------------------------------------------------------------
VERIFICATION: list[tuple[str, str]] = [
    (
        "md",
        """\
# Certifying optimality with an independent formulation

`hp.verify(instance, plan, method=..., objective=...)` checks a plan without trusting
the solver that made it: the plan is validated, then an exact time-expanded model
(CP-SAT or the HiGHS MIP) decides whether a cheaper plan exists
(see `formulations/verify.md`). The verdict is one of `optimal`, `suboptimal` (with a
better plan, and the optimum when found), `invalid` or `unknown` (time limit, with the
proven lower bound, so the gap is still bounded).""",
    ),
    ("code", setup("format_table, plot_plan", numpy=False)),
    (
        "md",
        "## 1. A CBS plan, certified by CP-SAT and by the MIP",
    ),
    (
        "code",
        """\
MAP, SCEN = MOVINGAI / "random-32-32-20.map", MOVINGAI / "random-32-32-20-random-1.scen"
inst = load_instance(MAP, SCEN, 8)
cbs = hp.solve(inst, "cbs", time_limit=30)
print(cbs.status.value, "sum of costs", cbs.cost, f"in {cbs.runtime:.3f} s")
certificates = {}
for method in ("cpsat", "mip"):
    v = hp.verify(inst, cbs.plan, method=method, objective="soc", time_limit=30)
    certificates[method] = v
    print(f"{method:6s}", v.message())
    assert v.status == "optimal" and v.cost == cbs.cost and v.gap == 0""",
    ),
    (
        "md",
        """\
The makespan objective works the same way. When a plan's makespan *M* is above the
distance lower bound, the formulation proves that no plan fits in horizon *M* − 1. Two
robots swapping the ends of a 3x2 grid need makespan 4 although each is only 2 steps from
its goal:""",
    ),
    (
        "code",
        """\
swap = hp.Instance.mapf(hp.Graph.grid(3, 2), [(0, 0), (2, 0)], [(2, 0), (0, 0)])
ms = hp.solve(swap, "cbs", objective="makespan", time_limit=30)
print("swap: makespan", ms.cost, "| distance lower bound", swap.makespan_lower_bound())
for method in ("cpsat", "mip"):
    v = hp.verify(swap, ms.plan, objective="makespan", method=method, time_limit=30)
    print(f"{method:6s}", v.message())
    assert v.optimal and v.proof == method  # settled by the model, not by the bound""",
    ),
    (
        "md",
        """\
And a plan that is one step too slow is caught: on the first 12 agents of
`empty-8-8-even-1` (a crowded 8x8 room) we take CBS's makespan-optimal plan and make the
robot with the longest path wait once before its last move, keeping the plan valid.""",
    ),
    (
        "code",
        """\
small = load_instance(MOVINGAI / "empty-8-8.map", MOVINGAI / "empty-8-8-even-1.scen", 12)
best = hp.solve(small, "cbs", objective="makespan", time_limit=30).plan
i = max(range(small.num_agents), key=lambda a: best.costs[a])
late = None
for t in range(len(best.paths[i]) - 2, -1, -1):  # latest wait that keeps the plan valid
    paths = [list(p) for p in best.paths]
    paths[i].insert(t, paths[i][t])
    if not hp.validate(small, hp.Plan.from_paths(paths)):
        late = hp.Plan.from_paths(paths)
        break
assert late is not None and late.makespan == best.makespan + 1
v = hp.verify(small, late, objective="makespan", method="cpsat", time_limit=30)
print(f"makespan {late.makespan} ->", v.message())
assert v.status == "suboptimal" and v.better_plan is not None
assert v.better_plan.makespan < late.makespan and hp.validate(small, v.better_plan) == []""",
    ),
    (
        "md",
        """\
## 2. The gap of an ECBS plan

ECBS(*w*) guarantees cost ≤ *w* · optimum and reports its own lower bound. On the same
8x8 room ECBS with *w* = 2 returns a plan whose sum of costs is *not* optimal; `verify`
proves that and returns the optimum with a better plan.""",
    ),
    (
        "code",
        """\
ecbs = hp.solve(small, "ecbs", w=2.0, time_limit=30)
print(f"ECBS(2.0): cost {ecbs.cost}, its own lower bound {ecbs.lower_bound}")
rows, verdicts = [], {}
for method in ("cpsat", "mip"):
    v = verdicts[method] = hp.verify(small, ecbs.plan, method=method, time_limit=30)
    print(f"{method:6s}", v.message())
    rows.append(
        {
            "method": method,
            "status": v.status,
            "cost": v.cost,
            "optimum": v.optimum,
            "lower_bound": v.lower_bound,
            "gap": v.gap,
            "runtime": round(v.runtime, 2),
        }
    )
print()
print(format_table(rows, ["method", "status", "cost", "optimum", "lower_bound", "gap", "runtime"]))
reference = hp.solve(small, "cbs", time_limit=30)
for r in rows:
    assert r["status"] in ("optimal", "suboptimal", "unknown")
    if r["optimum"] is not None:
        assert r["optimum"] == reference.cost  # CBS and the formulation agree
    assert ecbs.cost <= 2.0 * reference.cost
print("CBS optimum:", reference.cost, "| ECBS/optimum:", round(ecbs.cost / reference.cost, 3))""",
    ),
    (
        "code",
        """\
better = verdicts["cpsat"] if verdicts["cpsat"].better_plan is not None else None
fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
plot_plan(small, ecbs.plan, axes[0], legend=False, title=f"ECBS(2.0): SoC {ecbs.cost}")
if better is not None:
    plot_plan(
        small,
        better.better_plan,
        axes[1],
        legend=False,
        title=f"better plan found by verify: SoC {better.better_plan.sum_of_costs}",
    )
    assert hp.validate(small, better.better_plan) == []
else:
    axes[1].set_axis_off()
    axes[1].set_title("ECBS plan is optimal: no better plan")
fig.tight_layout()""",
    ),
    (
        "md",
        """\
## 3. Invalid plans are refused, not certified

A plan that swaps two robots' paths (so that both end on the wrong goal) is reported as
`invalid` with the first violation from the validator.""",
    ),
    (
        "code",
        """\
paths = list(cbs.plan.paths)
paths[0], paths[1] = paths[1], paths[0]
bad = hp.Plan.from_paths(paths)
v = hp.verify(inst, bad, method="cpsat")
print(v.message())
assert v.status == "invalid" and v.violations""",
    ),
]

# ---------------------------------------------------------------------------------------
# 3. MAPF-POST
# ---------------------------------------------------------------------------------------
MAPF_POST: list[tuple[str, str]] = [
    (
        "md",
        """\
# MAPF-POST: from a discrete plan to an execution schedule

A discrete plan moves every robot one cell per timestep. `hp.postprocess` builds the
temporal plan graph (TPG) with safety markers at distance δ on every move, turns it into a
simple temporal network with each robot's kinematics, and computes node times:

* `makespan` — earliest schedule (`method="graph"`, longest paths) or the LP; both must agree;
* `safety` — LP maximising the slowest speed, then the makespan at that level;
* `flowtime` — LP minimising the sum of arrival times.

A constant-velocity replay (`hierplan_opt.schedule.replay`) measures the true minimum
distance between any two robots, which must be at least the schedule's guaranteed safety
distance.""",
    ),
    ("code", setup("format_table, plot_plan", timing=True)),
    (
        "code",
        """\
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
print(f"CBS plan: sum of costs {plan.sum_of_costs}, makespan {plan.makespan} timesteps")""",
    ),
    (
        "code",
        """\
runs = [("makespan", "graph"), ("makespan", "lp"), ("safety", "lp"), ("flowtime", "lp")]
schedules, rows = {}, []
for objective, method in runs:
    t0 = time.perf_counter()
    s = hp.postprocess(inst, plan, objective, method=method, delta=0.25)
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
    assert rep.min_distance >= s.safety_distance - 1e-9, (objective, method)
    assert check_bounds(s.stn, s.times) == [], (objective, method)
print(format_table(rows))
graph_ms = schedules["makespan", "graph"].makespan
assert abs(schedules["makespan", "lp"].makespan - graph_ms) <= 1e-6 * max(1.0, graph_ms)
assert schedules["flowtime", "lp"].flowtime <= schedules["makespan", "graph"].flowtime + 1e-6
assert schedules["safety", "lp"].makespan >= graph_ms - 1e-6""",
    ),
    (
        "md",
        """\
The graph method and the LP agree on the minimum makespan. The flowtime LP cannot beat
the earliest schedule here (with lower bounds only, every node at its earliest time
minimises every arrival at once) — the check above asserts it is never worse. The safety
LP raises the slowest speed, which raises the guaranteed distance at no makespan cost in
this plan. Below: the Gantt chart of the earliest schedule —
one row per robot, bars are arrival windows (slack), red ticks the critical path.""",
    ),
    (
        "code",
        """\
try:
    from hierplan_opt.viz.gantt import plot_gantt
except ImportError as exc:  # the Gantt module belongs to the MAPF-POST part
    print("no Gantt plot:", exc)
else:
    fig = plot_gantt(schedules["makespan", "graph"])
    fig.set_size_inches(10, 4.5)""",
    ),
    (
        "code",
        """\
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
deltas = [0.0, 0.1, 0.2, 0.3, 0.4, 0.49]
ms = [hp.postprocess(inst, plan, delta=d).makespan for d in deltas]
axes[1].plot(deltas, ms, marker="o")
axes[1].set_xlabel("safety marker distance δ [cells]")
axes[1].set_ylabel("earliest-schedule makespan [s]")
axes[1].set_title("makespan vs δ")
fig.tight_layout()
print("makespan for δ =", {d: round(float(m), 3) for d, m in zip(deltas, ms, strict=True)})""",
    ),
    (
        "md",
        """\
Left: every robot needs at least its distance divided by its top speed (dotted lines).
The acceleration-aware bounds add more (with `a_max` = 1 m/s² a fast robot needs 2 s per
1 m cell here, as its way-points below show), slow robots turn in place, and robots wait
for each other. Right: the
makespan of the earliest schedule as the safety-marker distance δ changes; δ = 0 is the
plain TPG without markers. The numbers are this plan's, not a general law.""",
    ),
    (
        "code",
        """\
ax = plot_plan(inst, plan, legend=False, title="the plan that was scheduled")
ax.figure.set_size_inches(6, 5.5)
print("first robot's way-points (x, y, arrival):")
wp = s.waypoints[0]
for xy, kind, t in list(zip(wp.coords.tolist(), wp.kind, wp.arrival.tolist(), strict=True))[:8]:
    print(f"  {kind:6s} {xy}  t = {t:.3f}")""",
    ),
]

# ---------------------------------------------------------------------------------------
# 4. Paper examples
# ---------------------------------------------------------------------------------------
PAPER_EXAMPLES: list[tuple[str, str]] = [
    (
        "md",
        """\
# The overview paper's examples

The instances in `instances/paper/` encode the examples of Ma et al., *Overview: A
Hierarchical Framework for Plan Generation and Execution in Multi-Robot Systems* (2017):

* **Figure 3** — TAPF with two teams on a small roadmap (optimal makespan 4);
* **automated warehouse** — ten omni-directional youBots and two differential-drive
  Pioneers; part 1 sends the robots (one team per type) to pick-up locations, part 2
  (four teams by box colour) to targets left and right;
* **formation change** — 32 quadcopters leave a building and spell U-S-C (anonymous
  MAPF on a 3D grid).

All are solved with `cbm` (conflict-based min-cost flow, optimal makespan for TAPF), the
one-team formation also with `flow`; the warehouse plan then goes through MAPF-POST with
its heterogeneous robots.""",
    ),
    ("code", setup("format_table, plot_layers, plot_plan")),
    (
        "code",
        """\
fig3 = load_instance(PAPER / "figure3.yaml")
res = hp.solve(fig3, "cbm", time_limit=30)
g = fig3.graph
for a, path in zip(fig3.agents, res.plan.paths, strict=True):
    print(f"{fig3.teams[a.team].name:6s} {a.name:7s}", " -> ".join(g.location(v) for v in path))
print(res.status.value, "makespan", res.cost)
assert res.status == hp.Status.OPTIMAL and res.cost == 4 and hp.validate(fig3, res.plan) == []
ax = plot_plan(fig3, res.plan)
ax.figure.set_size_inches(8, 3)""",
    ),
    (
        "code",
        """\
rows, warehouse = [], {}
for part in ("warehouse-part1", "warehouse-part2"):
    inst = load_instance(PAPER / f"{part}.yaml")
    for solver in ("cbm", "hungarian"):
        r = hp.solve(inst, solver, objective="makespan", time_limit=30)
        assert r.plan is not None and hp.validate(inst, r.plan) == []
        rows.append(
            {
                "instance": part,
                "teams": len(inst.teams),
                "agents": inst.num_agents,
                "solver": solver,
                "status": r.status.value,
                "makespan": r.plan.makespan,
                "makespan_lb": inst.makespan_lower_bound(),
                "soc": r.plan.sum_of_costs,
                "runtime": round(r.runtime, 3),
            }
        )
        warehouse[part, solver] = (inst, r)
print(format_table(rows))
for part in ("warehouse-part1", "warehouse-part2"):
    opt = warehouse[part, "cbm"][1]
    assert opt.status == hp.Status.OPTIMAL
    assert opt.cost <= warehouse[part, "hungarian"][1].plan.makespan  # CBM is optimal""",
    ),
    (
        "md",
        """\
CBM minimises the makespan only, so its sum of costs is not minimised. On both warehouse
parts the distance lower bound (`makespan_lb`: the largest distance from a robot to its
team's nearest target, or from a target to its team's nearest robot) is already reached,
so the Hungarian baseline (assign targets by distance, then solve the fixed-goal MAPF with
CBS) is proven makespan-optimal here as well; on instances where that bound is not tight,
a fixed assignment can cost makespan and only CBM's answer is certified.""",
    ),
    (
        "code",
        """\
fig, axes = plt.subplots(1, 2, figsize=(15, 4.5))
for ax, part in zip(axes, ("warehouse-part1", "warehouse-part2"), strict=True):
    inst, r = warehouse[part, "cbm"]
    plot_plan(inst, r.plan, ax)
fig.tight_layout()""",
    ),
    (
        "code",
        """\
usc = load_instance(PAPER / "formation-usc.yaml")
out = {s: hp.solve(usc, s, time_limit=60) for s in ("cbm", "flow")}
for s, r in out.items():
    soc = r.plan.sum_of_costs
    print(f"{s:5s} {r.status.value} makespan {r.cost} soc {soc} in {r.runtime:.2f} s")
    assert r.status == hp.Status.OPTIMAL and hp.validate(usc, r.plan) == []
assert out["cbm"].cost == out["flow"].cost  # both are optimal for the makespan
ax = plot_plan(usc, out["flow"].plan, legend=False)
ax.figure.set_size_inches(7, 4.5)""",
    ),
    (
        "code",
        """\
fig = plot_layers(usc, out["flow"].plan)  # one panel per altitude; triangles = climb/descend""",
    ),
    (
        "md",
        """\
## MAPF-POST on the warehouse

The youBots (omni-directional, 0.8 m/s) and the Pioneers (differential drive, 0.6 m/s,
turning in place at 1.5 rad/s) share one temporal network; the schedule respects each
robot's own limits and the safety distance.""",
    ),
    (
        "code",
        """\
from hierplan_opt.schedule import replay

inst, r = warehouse["warehouse-part1", "cbm"]
sched = hp.postprocess(inst, r.plan, "makespan")
rep = replay(sched, inst, all_pairs=True)
print(
    f"makespan {sched.makespan:.2f} s (discrete: {r.plan.makespan} steps), "
    f"guaranteed distance {sched.safety_distance:.3f} m, replay minimum {rep.min_distance:.3f} m"
)
assert rep.min_distance >= sched.safety_distance - 1e-9
rows = []
for robot_type in sorted({a.kinematics.robot_type for a in inst.agents}):
    idx = [i for i, a in enumerate(inst.agents) if a.kinematics.robot_type == robot_type]
    k = inst.agents[idx[0]].kinematics
    finish = [float(sched.waypoints[i].arrival[-1]) for i in idx]
    steps = [len(r.plan.paths[i]) - 1 for i in idx]
    rows.append(
        {
            "robot_type": robot_type,
            "drive": k.drive,
            "v_max": k.v_max,
            "robots": len(idx),
            "mean_finish_s": round(float(np.mean(finish)), 2),
            "max_finish_s": round(max(finish), 2),
            "mean_path_steps": round(float(np.mean(steps)), 1),
        }
    )
print(format_table(rows))""",
    ),
    (
        "code",
        """\
try:
    from hierplan_opt.viz.gantt import plot_gantt
except ImportError as exc:
    print("no Gantt plot:", exc)
else:
    fig = plot_gantt(sched)
    fig.set_size_inches(10, 5)""",
    ),
]

NOTEBOOKS: dict[str, list[tuple[str, str]]] = {
    "solver_comparison": SOLVER_COMPARISON,
    "verification": VERIFICATION,
    "mapf_post": MAPF_POST,
    "paper_examples": PAPER_EXAMPLES,
}


# ---------------------------------------------------------------------------------------
# nbformat 4 JSON
# ---------------------------------------------------------------------------------------
def _lines(text: str) -> list[str]:
    return text.splitlines(keepends=True)


def notebook_dict(
    name: str, cells: Sequence[tuple[str, str]], outputs: Sequence[list[dict]] | None = None
) -> dict[str, Any]:
    """The nbformat 4.5 document for ``cells``; ``outputs`` per code cell if executed."""
    out_cells = []
    code_no = 0
    for i, (kind, src) in enumerate(cells):
        cell: dict[str, Any] = {"id": f"{name.replace('_', '-')}-{i}", "metadata": {}}
        if kind == "md":
            cell.update(cell_type="markdown", source=_lines(src))
        else:
            executed = outputs is not None
            cell.update(
                cell_type="code",
                execution_count=code_no + 1 if executed else None,
                outputs=list(outputs[code_no]) if outputs is not None else [],
                source=_lines(src),
            )
            code_no += 1
        out_cells.append(cell)
    return {
        "cells": out_cells,
        "metadata": {
            "kernelspec": {"display_name": "Python 3", "language": "python", "name": "python3"},
            "language_info": {"name": "python", "version": "3.11"},
        },
        "nbformat": 4,
        "nbformat_minor": 5,
    }


def code_cells(path: str | Path) -> list[str]:
    """The sources of the code cells of an ``.ipynb`` file, in order."""
    nb = json.loads(Path(path).read_text(encoding="utf-8"))
    return ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"]


def cell_sources(path: str | Path) -> list[tuple[str, str]]:
    """(kind, source) of every cell of an ``.ipynb`` file, kinds "md" and "code"."""
    nb = json.loads(Path(path).read_text(encoding="utf-8"))
    kinds = {"markdown": "md", "code": "code"}
    return [(kinds[c["cell_type"]], "".join(c["source"])) for c in nb["cells"]]


# ---------------------------------------------------------------------------------------
# execution
# ---------------------------------------------------------------------------------------
class CellError(RuntimeError):
    """A code cell raised; the message names the notebook cell and the exception."""


def _figure_outputs(dpi: int) -> list[dict]:
    import matplotlib.pyplot as plt

    outs = []
    for num in plt.get_fignums():
        fig = plt.figure(num)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
        w, h = fig.get_size_inches() * fig.dpi
        outs.append(
            {
                "output_type": "display_data",
                "data": {
                    "image/png": base64.b64encode(buf.getvalue()).decode("ascii"),
                    "text/plain": [f"<Figure size {w:.0f}x{h:.0f} with {len(fig.axes)} Axes>"],
                },
                "metadata": {},
            }
        )
    plt.close("all")
    return outs


def _is_artist(value: Any) -> bool:
    mod = type(value).__module__ or ""
    if mod.startswith("matplotlib"):
        return True
    return isinstance(value, list | tuple) and bool(value) and _is_artist(value[0])


def run_cells(
    sources: Sequence[str],
    *,
    cwd: str | Path = HERE,
    label: str = "notebook",
    capture: bool = True,
    dpi: int = DPI,
    allow_errors: bool = False,
) -> list[list[dict]]:
    """Execute code cells in order in one fresh namespace; return nbformat outputs.

    Uses matplotlib's Agg backend and runs with ``cwd`` as the working directory. Any
    exception is re-raised as :class:`CellError` naming the cell, with the traceback;
    with ``allow_errors=True`` it is stored as the cell's ``error`` output instead and
    the following cells still run (as ``jupyter nbconvert --allow-errors`` does).
    With ``capture=False`` outputs are not collected (figures are just closed).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    namespace: dict[str, Any] = {"__name__": "__main__"}
    all_outputs: list[list[dict]] = []
    old_cwd = os.getcwd()
    os.chdir(cwd)
    try:
        for n, src in enumerate(sources, start=1):
            stdout, stderr = io.StringIO(), io.StringIO()
            outputs: list[dict] = []
            filename = f"<{label} cell {n}>"
            # Register the source so that tracebacks show the failing line.
            linecache.cache[filename] = (len(src), None, src.splitlines(True), filename)
            tree = ast.parse(src, filename=filename)
            last = None
            if tree.body and isinstance(tree.body[-1], ast.Expr):
                last = ast.Expression(tree.body.pop().value)
            try:
                with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
                    exec(compile(tree, filename, "exec"), namespace)
                    value = (
                        eval(compile(last, filename, "eval"), namespace)
                        if last is not None
                        else None
                    )
            except Exception as exc:
                tb = traceback.format_exc()
                if allow_errors:
                    value = None
                    outputs.append(
                        {
                            "output_type": "error",
                            "ename": type(exc).__name__,
                            "evalue": str(exc),
                            "traceback": tb.splitlines(),
                        }
                    )
                else:
                    plt.close("all")
                    raise CellError(
                        f"{label}, code cell {n} raised {type(exc).__name__}: {exc}\n"
                        f"--- cell output ---\n{stdout.getvalue()[-2000:]}"
                        f"{stderr.getvalue()[-2000:]}--- traceback ---\n{tb}"
                    ) from exc
            if not capture:
                plt.close("all")
                all_outputs.append([])
                continue
            streams = [
                {"output_type": "stream", "name": name, "text": _lines(buf.getvalue())}
                for name, buf in (("stdout", stdout), ("stderr", stderr))
                if buf.getvalue()
            ]
            outputs[:0] = streams
            if value is not None and not _is_artist(value):
                outputs.append(
                    {
                        "output_type": "execute_result",
                        "execution_count": n,
                        "data": {"text/plain": _lines(repr(value))},
                        "metadata": {},
                    }
                )
            outputs += _figure_outputs(dpi)
            all_outputs.append(outputs)
    finally:
        os.chdir(old_cwd)
        plt.close("all")
    return all_outputs


# ---------------------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------------------
def write_notebook(
    name: str, *, execute: bool = False, allow_errors: bool = False
) -> tuple[Path, float]:
    """Write ``notebooks/NAME.ipynb`` (executed when asked); return its path and run time."""
    cells = NOTEBOOKS[name]
    outputs = None
    elapsed = 0.0
    if execute:
        t0 = time.perf_counter()
        outputs = run_cells(
            [s for k, s in cells if k == "code"], label=name, allow_errors=allow_errors
        )
        elapsed = time.perf_counter() - t0
    path = HERE / f"{name}.ipynb"
    # Sorted keys and one-space indent: the layout `ruff format` writes for notebooks.
    nb = notebook_dict(name, cells, outputs)
    text = json.dumps(nb, indent=1, ensure_ascii=False, sort_keys=True) + "\n"
    if len(text.encode("utf-8")) > MAX_BYTES:
        raise SystemExit(f"{path.name} would be {len(text) / 1e6:.2f} MB (limit 1 MB)")
    path.write_text(text, encoding="utf-8")
    return path, elapsed


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--execute", action="store_true", help="run the cells, store outputs")
    parser.add_argument("--check", action="store_true", help="only compare cell sources")
    parser.add_argument(
        "--allow-errors",
        action="store_true",
        help="store a failing cell's error in the notebook and go on (exit status 1)",
    )
    parser.add_argument("--only", nargs="+", choices=sorted(NOTEBOOKS), help="these notebooks")
    args = parser.parse_args(argv)
    names = args.only or list(NOTEBOOKS)
    if args.check:
        stale = [
            n
            for n in names
            if not (HERE / f"{n}.ipynb").exists()
            or cell_sources(HERE / f"{n}.ipynb") != list(NOTEBOOKS[n])
        ]
        for n in stale:
            print(f"{n}.ipynb is out of date: run python notebooks/_build.py --execute")
        return 1 if stale else 0
    failed = 0
    for n in names:
        try:
            path, elapsed = write_notebook(n, execute=args.execute, allow_errors=args.allow_errors)
        except CellError as exc:
            print(exc, file=sys.stderr)
            return 1
        size = path.stat().st_size / 1e3
        ran = f", executed in {elapsed:.1f} s" if args.execute else ""
        errors = [
            f"cell {i}: {o['ename']}: {o['evalue']}"
            for i, c in enumerate(json.loads(path.read_text(encoding="utf-8"))["cells"])
            for o in c.get("outputs", [])
            if o["output_type"] == "error"
        ]
        failed += bool(errors)
        print(f"wrote {path.relative_to(HERE.parent)} ({size:.0f} kB{ran})")
        for e in errors:
            print(f"  ERROR in {e}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
