"""Pipeline stages a sweep runs like solvers (``target: hierplan_opt.experiments.stages:post``).

A sweep runs solvers; the later stages of the pipeline are measured the same way by a
function with a solver's signature that plans first and then runs its stage. The run's
status, plan, cost and lower bound are the planner's (a run without a plan records the
planner's status and skips the stage); ``stats`` adds the stage's sizes and times, so
``hierplan sweep report DB --stats KEY,...`` tabulates them by number of agents. The
canned specs ``post`` and ``post-quick`` are ``hierplan bench post`` as sweeps.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from hierplan_opt import registry
from hierplan_opt.core.errors import HierplanError, OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result
from hierplan_opt.execution.chain import plan_and_post
from hierplan_opt.schedule import replay

#: Statistics of :func:`hierplan_opt.schedule.postprocess` a post run records (``post_`` +).
POST_STATS = (
    "tpg_nodes",
    "tpg_arcs",
    "type2_arcs",
    "stn_arcs",
    "tpg_time",
    "stn_time",
    "solve_time",
    "window_time",
    "total_time",
    "lp_time",
    "R",
)


def post(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    planner: str = "ecbs",
    w: float = 1.5,
    method: str = "lp",
    post_objective: str = "makespan",
    lp_backend: str = "highs",
) -> Result:
    """Plan with ``planner`` (option ``w`` for the bounded ones), then MAPF-POST.

    ``stats`` gains ``post_tpg_nodes``, ``post_stn_arcs``, ``post_type2_arcs``, the
    stage times ``post_tpg_time``, ``post_stn_time``, ``post_solve_time`` (graph method
    or LP), ``post_total_time``, the LP's ``post_lp_time`` and the schedule's
    ``post_makespan`` (seconds) and ``post_flowtime``. The schedule is checked by the
    continuous-time replay (``post_replay_ok``).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    >>> r = post(inst, method="graph")
    >>> st = r.stats  # point robots: default margin 0.1 x cell, markers 0.55 past a vertex
    >>> r.cost, st["post_tpg_nodes"], round(st["post_makespan"], 6), st["post_replay_ok"]
    (4, 10, 2.1, True)
    """

    if method not in ("graph", "lp"):
        raise OptionError(f"post option method must be 'graph' or 'lp', got {method!r}")
    options: dict[str, Any] = {"w": w} if registry.get(planner).bounded else {}
    planned = plan_and_post(
        instance,
        planner,
        time_limit=time_limit,
        seed=seed,
        post=post_objective,
        method=method,
        lp_backend=lp_backend,
        **options,
    )
    res = planned.result
    if res.plan is None:
        return res
    if planned.schedule is None:
        raise HierplanError(planned.why)
    sched = planned.schedule
    stats = dict(res.stats)
    stats.update({f"post_{k}": sched.stats[k] for k in POST_STATS if k in sched.stats})
    stats["post_time"] = planned.post_time
    stats["post_makespan"] = sched.makespan
    stats["post_flowtime"] = sched.flowtime
    stats["post_replay_ok"] = replay(sched, instance).ok
    stats["planner"] = planner
    return replace(res, stats=stats)
