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
# # Solver comparison: how far each MAPF solver goes
#
# Success rate and runtime against the number of agents for every MAPF solver of the
# toolkit, from a **sweep database**: `sweeps/solver_comparison.yaml` ran
#
# * `cbs` — optimal CBS (MDD prioritisation, bypass, WDG heuristic, disjoint splitting,
#   symmetry and rectangle reasoning);
# * `ecbs` and `eecbs` with *w* = 1.2 — bounded-suboptimal (cost ≤ 1.2 · optimum);
# * `ecbs` with *w* = 1.2 on generated crisscross highways (`highways: crisscross`,
#   *w_hwy* = 2.0: moves against the highway cost twice in the search) — cost ≤ 2.4 ·
#   optimum (Cohen, Uras and Koenig 2015);
# * `mip` (time-expanded network, Pyomo + HiGHS) and `cpsat` (OR-Tools CP-SAT) — the exact
#   formulations;
# * `cbm` — conflict-based min-cost flow, which optimises the **makespan** (it applies to
#   MAPF as teams of one robot), so its costs are not comparable, only its reach;
#
# on the first *K* agents of three MovingAI scenarios (random-32-32-20, a warehouse and an
# empty 32x32 grid), *K* from 5 to 400, 20 s per run, each run in its own process.
# `stop_on_failure` skips the larger *K* of a solver on an instance once it failed (those
# runs are recorded as SKIPPED and count as unsolved). To run the sweep again (9 minutes
# with two runs at a time on 2 cores) and look at the result:
#
# ```bash
# hierplan sweep notebooks/sweeps/solver_comparison.yaml --workers 2
# hierplan sweep report notebooks/sweeps/solver_comparison.sqlite --plots plots/
# ```
#
# Timings come from a shared 2-core machine (two runs at a time), so they are noisy.
# The checks at the end **assert** that the proven optima agree across solvers and that
# the bounded solvers keep their bound.

# %%
# %matplotlib inline

import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import hierplan_opt as hp
from hierplan_opt.experiments import instances_dir, reports, sweep
from hierplan_opt.io import load_instance
from hierplan_opt.viz.plots import plot_plan

ROOT = instances_dir()  # the benchmark instances shipped with the package
MOVINGAI = ROOT / "movingai"
SWEEP_DB = Path("sweeps") / "solver_comparison.sqlite"  # beside this notebook
# CI executes the notebooks with HIERPLAN_NOTEBOOK_SMALL=1: smaller live examples
SMALL = os.environ.get("HIERPLAN_NOTEBOOK_SMALL") == "1"
plt.rcParams["figure.dpi"] = 72  # small stored figures

# %% [markdown]
# ## The standard tables
#
# Success rate by number of agents, the runtime distribution of the solved runs (PAR2
# counts an unsolved run as twice the time limit) and the cost over lower bounds: each
# solver's own proven bound, and the best bound any solver proved for the same
# instance and *K*.

# %%
runs = reports.read_runs(SWEEP_DB)
print(reports.report(SWEEP_DB))

# %%
reach = (
    runs[runs["solved"]]
    .groupby(["label", "instance"])["agents"]
    .max()
    .unstack("instance")
    .reindex(runs["label"].unique())
)
print("Largest number of agents solved within the time limit")
print(reach.to_string(na_rep="-"))

# %%
reports.success_rate_figure(runs, title="Success rate (3 MovingAI instances, 20 s)")

# %%
reports.runtime_figure(runs, title="Runtime of the solved runs")

# %%
reports.cactus_figure(runs, title="Cactus plot: runs solved within a time")

# %% [markdown]
# ## Checks
#
# * every run finished with a status of the one vocabulary (a crash would be ERROR, a
#   memory blow-up MEMOUT); no solver returned an invalid plan (the front door turns one
#   into ERROR);
# * all solvers that proved an optimal sum of costs on the same instance and *K* agree;
# * a bounded solver's cost is at most *w* times the optimum where one is known, and at
#   most *w* times its own lower bound; no lower bound exceeds the optimum.

# %%
assert set(runs["status"]) <= {"OPTIMAL", "FEASIBLE", "TIME_LIMIT", "MEMOUT", "SKIPPED"}, set(
    runs["status"]
)
soc = runs[runs["objective"] == "soc"]
optimal = soc[soc["status"] == "OPTIMAL"].groupby(["instance", "agents"])["cost"]
assert (optimal.nunique() == 1).all(), optimal.unique()
optimum = optimal.first()
W = {"ecbs(w=1.2)": 1.2, "eecbs(w=1.2)": 1.2, "ecbs(w=1.2)+hwy(2.0)": 1.2 * 2.0}
for label, w in W.items():
    b = soc[(soc["label"] == label) & soc["cost"].notna()]
    assert (b["cost"] <= w * b["lower_bound"] + 1e-9).all(), label
    known = b.join(optimum.rename("opt"), on=["instance", "agents"]).dropna(subset=["opt"])
    assert (known["cost"] <= w * known["opt"] + 1e-9).all(), label
    assert (known["lower_bound"] <= known["opt"] + 1e-9).all(), label
    print(f"{label}: {len(b)} plans, worst cost/optimum where known "
          f"{(known['cost'] / known['opt']).max():.4f}")  # fmt: skip
bounds = soc.join(optimum.rename("opt"), on=["instance", "agents"]).dropna(subset=["opt"])
assert (bounds["lower_bound"].fillna(0) <= bounds["opt"] + 1e-9).all()
print(f"{len(optimum)} (instance, K) pairs with a proven optimum; all solvers agree")

# %% [markdown]
# ## A sweep of your own, in a few lines
#
# `hierplan_opt.experiments.sweep` takes the same spec as a dict; here a tiny one on an
# 8x8 grid (each run still gets its own process, time and memory limit).

# %%
spec = {
    "name": "tiny",
    "solvers": [{"name": "cbs"}, {"name": "ecbs", "options": {"w": 1.5}}, {"name": "cpsat"}],
    "instances": [
        {"map": str(MOVINGAI / "empty-8-8.map"), "scen": str(MOVINGAI / "empty-8-8-even-1.scen")}
    ],
    "agents": [3] if SMALL else [2, 4, 8, 12],
    "time_limit": 20,
    "workers": 2,
    "db": str(Path(tempfile.mkdtemp()) / "tiny.sqlite"),
}
summary = sweep(spec, progress=False)
print(summary.message())
tiny = reports.read_runs(summary.db)
tiny[["label", "agents", "status", "cost", "lower_bound", "runtime", "wall", "peak_mb"]]

# %%
assert summary.statuses.get("ERROR", 0) == 0 and tiny["solved"].all()
by_k = tiny[tiny["status"] == "OPTIMAL"].groupby("agents")["cost"].nunique()
assert (by_k == 1).all()  # cbs and cpsat agree

# %% [markdown]
# ## What the plans look like
#
# CBS (optimal) and ECBS (*w* = 1.5) on the same agents of random-32-32-20.

# %%
K = 10 if SMALL else 30
MAP, SCEN = MOVINGAI / "random-32-32-20.map", MOVINGAI / "random-32-32-20-random-1.scen"
inst = load_instance(MAP, SCEN, K)
fig, axes = plt.subplots(1, 2, figsize=(11, 4.8))
for ax, (name, opts) in zip(axes, [("cbs", {}), ("ecbs", {"w": 1.5})], strict=True):
    res = hp.solve(inst, name, time_limit=30, **opts)
    assert res.solved and hp.validate(inst, res.plan) == []
    plot_plan(inst, res.plan, ax, legend=False, title=f"{name}, {K} agents, cost {res.cost:g}")
fig.tight_layout()
