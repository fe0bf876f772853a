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
# # Execution under delays: slack, STN re-solve, re-planning, reordering
#
# The second half of the overview paper's framework: robots execute the MAPF-POST
# schedule, delays are absorbed by **slack**, an **STN re-solve** (polynomial,
# incremental) fixes larger ones, and only when that is not enough (deadlines, a
# broken-down robot in the way) is a **MAPF re-plan** made from the robots' current
# positions. `hierplan_opt.execution.simulate` runs a schedule under disturbances in
# continuous time and records which layer handled each one; a robot never passes a TPG
# node before its Type-2 predecessors have happened, so the guaranteed distance
# `r_i + r_j + margin` holds for every policy but `naive`.

# %%
import io
import os

from IPython.display import Image, display

import hierplan_opt as hp
from hierplan_opt.execution import RandomDelays, Stop, load_disturbances, simulate
from hierplan_opt.execution.montecarlo import monte_carlo
from hierplan_opt.execution.report import text_report
from hierplan_opt.experiments import instances_dir
from hierplan_opt.io import load_instance
from hierplan_opt.schedule import check_bounds, postprocess, replay
from hierplan_opt.viz.animation import plot_distance, plot_layers


def show(fig) -> None:
    """Display a matplotlib Figure made without pyplot, as a small PNG."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=70)
    display(Image(buf.getvalue()))


SMALL = bool(os.environ.get("HIERPLAN_NOTEBOOK_SMALL"))
PAPER = instances_dir() / "paper"
inst = load_instance(PAPER / "warehouse-part1.yaml")  # 10 youBots, 2 Pioneers
plan = hp.solve(inst, "cbm", time_limit=60).plan
s = postprocess(inst, plan, check_plan=False)
print(f"schedule: makespan {s.makespan:.2f} s, guaranteed distance {s.safety_distance} m")

# %% [markdown]
# ## One delay, three outcomes
#
# A youBot halts in the middle of a move. A short halt fits in the slack of its next
# event: nothing is re-computed and nobody else moves differently. A long one does not:
# the `stn` layer re-solves the STN incrementally (only the events reachable from the
# late one are visited) and the new times meet every bound.

# %%
tpg = s.stn.tpg
j = tpg.agent_names.index("youbot3")
nodes = list(tpg.agent_nodes(j))
v = next(n for n in nodes[1:] if s.slack[n] > 3 and s.times[n] > s.times[n - 1] + 0.5)
t_stop = float(s.times[v - 1] + 0.2)
for d in (1.0, float(s.slack[v]) + 5.0):
    ex = simulate(inst, s, disturbances=[Stop("youbot3", d, at_time=t_stop)], policy="stn")
    phase = ex.phases[0]
    st = ex.statistics
    print(
        f"halt {d:5.2f} s: layer {ex.log[0].layer:5}, makespan {st['makespan']:.2f} s, "
        f"STN re-solves {st['stn_resolves']}, "
        f"bounds broken {len(check_bounds(phase.stn, phase.targets))}"
    )
    assert st["collisions"] == 0 and st["distance_kept"]

# %% [markdown]
# ## The whole hierarchy on the bundled disturbances
#
# `instances/paper/warehouse-disturbances.yaml`: a stop, a breakdown in an aisle (it
# blocks another robot: MAPF re-plan with ECBS from the current positions, the broken
# robot an obstacle, then MAPF-POST again), a water spill near the conveyor and random
# delays. This is what `hierplan run` prints.

# %%
dist = load_disturbances(PAPER / "warehouse-disturbances.yaml")
ex = simulate(inst, s, disturbances=dist, policy="replan")
print(text_report(ex))
assert ex.statistics["replans"] == 1 and ex.statistics["collisions"] == 0
((inst2, plan2),) = ex.replans
assert hp.validate(inst2, plan2) == []

# %%
show(plot_distance(ex, inst))

# %% [markdown]
# ## Policies side by side
#
# Same random delays for every policy. `adg` runs without a schedule (each action as
# soon as its dependencies allow), `naive` follows the clock and ignores the TPG: it is
# the only one that lets robots collide. `reorder` lets robots queued behind a late one
# pass first (passing orders chosen by CP-SAT, see `formulations/reorder.md`).

# %%
delays = [RandomDelays(0.2, "exponential", 3.0), Stop("youbot5", 8.0, at_time=3.0)]
rows = []
for policy in ("slack", "stn", "replan", "reorder", "adg", "naive"):
    st = simulate(inst, s, disturbances=delays, policy=policy, seed=7).statistics
    rows.append(
        (
            policy,
            st["collisions"],
            round(st["min_distance"], 3),
            round(st["makespan"], 2),
            round(st["arrival_avg"], 2),
            st["stn_resolves"],
            st["reorders"],
            st["replans"],
        )
    )
    if policy != "naive":
        assert st["collisions"] == 0
print(
    f"{'policy':8} {'coll':>4} {'min d':>6} {'makespan':>8} {'avg arr':>7} {'stn':>4} "
    f"{'reord':>5} {'repl':>4}"
)
for r in rows:
    print(f"{r[0]:8} {r[1]:>4} {r[2]:>6} {r[3]:>8} {r[4]:>7} {r[5]:>4} {r[6]:>5} {r[7]:>4}")

# %% [markdown]
# ## Monte Carlo: how much does each layer absorb?
#
# Random delays at three rates, with delivery windows (every robot due 10 % after its
# planned arrival) so that large delays make the STN inconsistent and escalate. The
# bars show the share of delays handled by each layer; `monte_carlo` also gives, per
# location, the probability of arriving within its window.

# %%
due = {n: float(w.arrival[-1]) * 1.1 for n, w in zip(s.agent_names, s.waypoints, strict=True)}
windowed = postprocess(inst, plan, check_plan=False, deadlines=due)
runs = 6 if SMALL else 30
bars = []
for p in (0.05, 0.1, 0.2):
    mc = monte_carlo(
        inst,
        windowed,
        [RandomDelays(p, "exponential", 2.0)],
        runs=runs,
        workers=1,
        progress=False,
    )
    bars.append((f"p={p}", mc.handled))
    print(
        f"p={p}: {mc.summary()['handled']}, collisions {mc.collisions}, "
        f"lowest on-time probability {mc.on_time.min():.2f}"
    )
    assert mc.collisions == 0
show(plot_layers(bars))

# %% [markdown]
# ## Re-planning when an arrival becomes unlikely
#
# The paper's delay-probability idea: re-plan only when the probability that a location
# is reached within its time window becomes small. With `replan_below=0.9`, a location
# on time in fewer than 90 % of the runs triggers a *delay-aware re-plan*: the instance
# is solved again (CBM for these teams), MAPF-POST makes the schedule, and its target
# times are raised to the 95 % quantile of the executed times a Monte Carlo batch gives,
# until every location is on time with 0.9 (fresh seeds). The new plan validates and its
# schedule replays; the buffer costs makespan.

# %%
mc = monte_carlo(
    inst,
    s,
    [RandomDelays(0.2, "constant", 1.0)],
    runs=runs,
    workers=1,
    progress=False,
    replan_below=0.9,
)
new = mc.replanned
assert mc.replan_advised and new is not None
print(
    f"before: lowest on-time probability {mc.on_time.min():.2f}, {len(mc.below)} locations "
    f"below 0.9, planned makespan {s.makespan:.2f} s"
)
print(
    f"after ({new.solver}, {new.rounds} rounds, quantile {new.quantile:g}): lowest "
    f"{new.result.on_time.min():.2f}, planned makespan {new.schedule.makespan:.2f} s"
)
assert hp.validate(inst, new.plan) == [] and replay(new.schedule, inst).ok
assert new.result.on_time.min() >= 0.9 and new.result.collisions == 0
