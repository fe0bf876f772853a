"""The ``hungarian`` solver: target assignment by distance, then a MAPF solver (baseline).

For every team the robots are assigned to targets by their BFS distances
(:mod:`hierplan_opt.search.assignment`):

* ``objective="soc"``: the assignment of minimum total distance (Hungarian method,
  :func:`scipy.optimize.linear_sum_assignment`); its value is a lower bound on the
  TAPF sum of costs;
* ``objective="makespan"``: first the *bottleneck* value (the smallest d such that
  every robot can get a target within d steps, found by bisection over bipartite
  matchings), then the minimum total distance among assignments within d. The
  largest bottleneck value over the teams is a lower bound on the TAPF makespan.

The resulting MAPF instance (fixed goals) is solved by a MAPF solver (CBS by
default). Assignment ignores interactions between robots, so the plan is not optimal
for TAPF in general; the result is FEASIBLE unless its cost meets the lower bound.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hierplan_opt import registry
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.registry import solver
from hierplan_opt.search.assignment import assign, distance_matrix


@solver(
    "hungarian",
    Option("mapf_solver", "solver", "MAPF solver for the assigned goals"),
    Option("mapf_options", "options", "options of that solver", optional=True, of="mapf_solver"),
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "makespan",
    mapf_solver: str = "cbs",
    mapf_options: dict[str, Any] | None = None,
) -> Result:
    """Assign targets by distance (Hungarian / bottleneck), then solve the MAPF.

    Parameters
    ----------
    mapf_solver
        Registered MAPF solver for the fixed assignment (``"cbs"``, ``"ecbs"``,
        ``"cbm"``, ...). Its own options go in ``mapf_options``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(4, 1)
    >>> inst = Instance.tapf(g, [([(0, 0), (1, 0)], [(2, 0), (3, 0)])])
    >>> r = solve(inst, mapf_solver="cbm")
    >>> r.status.value, r.cost, r.lower_bound
    ('OPTIMAL', 2, 2)
    """
    deadline = Deadline(time_limit)
    g = instance.graph
    goals = [0] * instance.num_agents
    bound = 0
    for team in instance.teams:
        starts = [instance.agents[i].start for i in team.agents]
        dist = distance_matrix(g, starts, team.targets)
        cols = assign(dist, objective)
        for i, c in zip(team.agents, cols.tolist(), strict=True):
            goals[i] = team.targets[c]
        chosen = dist[np.arange(len(cols)), cols]
        if objective == "makespan":
            bound = max(bound, int(chosen.max()))
        else:
            bound += int(chosen.sum())
    mapf = instance.with_goals(goals)
    remaining = deadline.remaining()
    if remaining <= 0:
        return Result(
            Status.TIME_LIMIT,
            None,
            lower_bound=bound,
            objective=objective,
            stats={"stopped_by": "time_limit"},
        )
    inner = registry.run(
        mapf_solver,
        mapf,
        time_limit=None if time_limit is None else remaining,
        seed=seed,
        objective=objective,
        **(mapf_options or {}),
    )
    stats = dict(inner.stats)
    stats["mapf_solver"] = mapf_solver
    stats["mapf_status"] = str(inner.status)
    stats["assignment"] = {
        a.name: g.plain_location(goal) for a, goal in zip(instance.agents, goals, strict=True)
    }
    if inner.plan is None:
        if inner.status == Status.INFEASIBLE:
            # The fixed assignment has no plan; another assignment might.
            stats["error"] = "the MAPF instance of the chosen assignment has no plan"
            return Result(Status.ERROR, None, lower_bound=bound, objective=objective, stats=stats)
        return Result(inner.status, None, lower_bound=bound, objective=objective, stats=stats)
    cost = inner.plan.cost(objective)
    status = Status.OPTIMAL if cost <= bound else Status.FEASIBLE
    return Result(
        status, inner.plan, cost=cost, lower_bound=bound, objective=objective, stats=stats
    )
