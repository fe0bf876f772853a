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
# # Certifying optimality with an independent formulation
#
# `hp.verify(instance, plan, method=..., objective=...)` checks a plan without trusting
# the solver that made it: the plan is validated, then an exact time-expanded model
# (CP-SAT or the HiGHS MIP) decides whether a cheaper plan exists
# (see `formulations/verify.md`). The verdict is one of `optimal`, `suboptimal` (with a
# better plan, and the optimum when found), `invalid` or `unknown` (time limit, with the
# proven lower bound, so the gap is still bounded).

# %%

import matplotlib.pyplot as plt

import hierplan_opt as hp
from hierplan_opt.experiments import instances_dir
from hierplan_opt.io import load_instance
from hierplan_opt.viz.plots import format_table, plot_plan

ROOT = instances_dir()  # the benchmark instances shipped with the package
MOVINGAI = ROOT / "movingai"
PAPER = ROOT / "paper"

# %% [markdown]
# ## 1. A CBS plan, certified by CP-SAT and by the MIP

# %%
MAP, SCEN = MOVINGAI / "random-32-32-20.map", MOVINGAI / "random-32-32-20-random-1.scen"
inst = load_instance(MAP, SCEN, 8)
cbs = hp.solve(inst, "cbs", time_limit=30)
print(cbs.status.value, "sum of costs", cbs.cost, f"in {cbs.runtime:.3f} s")
certificates = {}
for method in ("cpsat", "mip"):
    v = hp.verify(inst, cbs.plan, method=method, objective="soc", time_limit=30)
    certificates[method] = v
    print(f"{method:6s}", v.message())
    assert v.status == "optimal" and v.cost == cbs.cost and v.gap == 0

# %% [markdown]
# The makespan objective works the same way. When a plan's makespan *M* is above the
# distance lower bound, the formulation proves that no plan fits in horizon *M* − 1. Two
# robots swapping the ends of a 3x2 grid need makespan 4 although each is only 2 steps from
# its goal:

# %%
swap = hp.Instance.mapf(hp.Graph.grid(3, 2), [(0, 0), (2, 0)], [(2, 0), (0, 0)])
ms = hp.solve(swap, "cbs", cost="makespan", time_limit=30)
print("swap: makespan", ms.cost, "| distance lower bound", swap.makespan_lower_bound())
for method in ("cpsat", "mip"):
    v = hp.verify(swap, ms.plan, objective="makespan", method=method, time_limit=30)
    print(f"{method:6s}", v.message())
    assert v.optimal and v.proof == method  # settled by the model, not by the bound

# %% [markdown]
# And a plan that is one step too slow is caught: on the first 12 agents of
# `empty-8-8-even-1` (a crowded 8x8 room) we take CBS's makespan-optimal plan and make the
# robot with the longest path wait once before its last move, keeping the plan valid.

# %%
small = load_instance(MOVINGAI / "empty-8-8.map", MOVINGAI / "empty-8-8-even-1.scen", 12)
best = hp.solve(small, "cbs", cost="makespan", time_limit=30).plan
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
assert v.better_plan.makespan < late.makespan and hp.validate(small, v.better_plan) == []

# %% [markdown]
# ## 2. The gap of an ECBS plan
#
# ECBS(*w*) guarantees cost ≤ *w* · optimum and reports its own lower bound. On the same
# 8x8 room ECBS with *w* = 2 returns a plan whose sum of costs is *not* optimal; `verify`
# proves that and returns the optimum with a better plan.

# %%
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
print("CBS optimum:", reference.cost, "| ECBS/optimum:", round(ecbs.cost / reference.cost, 3))

# %%
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
fig.tight_layout()

# %% [markdown]
# ## 3. Invalid plans are refused, not certified
#
# A plan that swaps two robots' paths (so that both end on the wrong goal) is reported as
# `invalid` with the first violation from the validator.

# %%
paths = list(cbs.plan.paths)
paths[0], paths[1] = paths[1], paths[0]
bad = hp.Plan.from_paths(paths)
v = hp.verify(inst, bad, method="cpsat")
print(v.message())
assert v.status == "invalid" and v.violations
