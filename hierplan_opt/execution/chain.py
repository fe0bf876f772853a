"""The checked chain every part of the hierarchy plans with: solve -> validate ->
MAPF-POST (:func:`plan_and_post`).

``hierplan run`` and :func:`hierplan_opt.run` (through :mod:`.pipeline`), the sweeps'
``post`` stage, re-planning during execution (:mod:`.replan`) and the delay-aware
re-plan of Monte Carlo (:mod:`.montecarlo`) all call it, so a plan is always validated
before MAPF-POST and a failure is always reported the same way.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from hierplan_opt.api import solve
from hierplan_opt.core.errors import HierplanError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.post import postprocess

#: MAPF-POST objectives (``makespan`` by the graph method, the others by the LP).
POST_OBJECTIVES = ("makespan", "safety", "flowtime")


@dataclass(frozen=True)
class Planned:
    """What :func:`plan_and_post` made: the planner's validated result, the schedule
    (None: no plan, or MAPF-POST refused it - ``why`` says which) and the seconds each
    stage took."""

    result: Result
    schedule: Schedule | None
    solver: str
    solve_time: float
    post_time: float = 0.0
    why: str = ""
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.schedule is not None


def plan_and_post(
    instance: Instance,
    solver: str = "cbs",
    *,
    time_limit: float | None = 60.0,
    seed: int = 0,
    cost: str | None = None,
    post: str | None = "makespan",
    margin: float | None = None,
    method: str | None = None,
    lp_backend: str = "auto",
    deadlines: Mapping[str | int, float] | None = None,
    **options: Any,
) -> Planned:
    """Solve ``instance`` with a registered solver (``options`` are the solver's,
    checked), validate the plan (:func:`hierplan_opt.solve` does), then MAPF-POST with
    objective ``post`` (None: no schedule).

    ``method`` defaults to ``graph`` for ``makespan`` and ``lp`` for the others.

    Example
    -------
    >>> from hierplan_opt import Graph
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    >>> p = plan_and_post(inst, "cbs")
    >>> p.ok, p.result.cost, round(p.schedule.makespan, 6)  # margin 0.1: markers
    (True, 4, 2.1)
    """
    if post is not None and post not in POST_OBJECTIVES:
        raise HierplanError(
            f"unknown MAPF-POST objective {post!r} (use makespan, safety, flowtime)"
        )
    t0 = time.perf_counter()
    res = solve(instance, solver, time_limit=time_limit, seed=seed, cost=cost, **options)
    solve_time = time.perf_counter() - t0
    if res.plan is None:
        why = str(res.stats.get("error") or f"{solver} found no plan ({res.status.value})")
        return Planned(res, None, solver, solve_time, why=why)
    if post is None:
        return Planned(res, None, solver, solve_time, why="no MAPF-POST asked for")
    if method is None:
        method = "graph" if post == "makespan" else "lp"
    t1 = time.perf_counter()
    try:
        sched = postprocess(
            instance,
            res.plan,
            post,
            margin=margin,
            method=method,
            lp_backend=lp_backend,
            deadlines=deadlines,
            check_plan=False,  # validated by solve
        )
    except HierplanError as exc:
        return Planned(
            res, None, solver, solve_time, time.perf_counter() - t1, f"MAPF-POST failed: {exc}"
        )
    return Planned(res, sched, solver, solve_time, time.perf_counter() - t1)
