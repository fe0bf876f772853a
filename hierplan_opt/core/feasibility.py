"""Cheap checks that prove an instance has no plan.

Search solvers call :func:`quick_infeasibility` first, so they return INFEASIBLE at once
instead of searching forever on instances these checks can decide.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
from scipy.optimize import linear_sum_assignment

from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.core.instance import Instance


def quick_infeasibility(instance: Instance) -> str | None:
    """A one-line reason why ``instance`` has no plan, or None if no check proves it.

    Checks: a goal no agent path can reach; two agents with one goal; for teams, no
    assignment of robots to targets in which every robot reaches its target.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 1, obstacles=[(1, 0)])
    >>> quick_infeasibility(Instance.mapf(g, [(0, 0)], [(2, 0)]))
    "agent 'agent0' cannot reach its goal [2, 0] from [0, 0]"
    """
    g = instance.graph

    def loc(v: int) -> str:
        x = g.location(v)
        return repr(x) if isinstance(x, str) else str(list(x))

    if not instance.is_tapf:
        counts = Counter(a.goal for a in instance.agents)
        for goal, c in counts.items():
            if c > 1:
                who = [a.name for a in instance.agents if a.goal == goal]
                return f"agents {', '.join(map(repr, who))} share the goal {loc(goal)}"  # type: ignore[arg-type]
        for a in instance.agents:
            assert a.goal is not None
            if g.dist_to(a.goal)[a.start] >= UNREACHABLE:
                return f"agent {a.name!r} cannot reach its goal {loc(a.goal)} from {loc(a.start)}"
        return None
    for team in instance.teams:
        starts = [instance.agents[i].start for i in team.agents]
        reach = np.array(
            [[g.dist_to(t)[s] < UNREACHABLE for t in team.targets] for s in starts], dtype=bool
        )
        rows, cols = linear_sum_assignment(~reach)
        if not reach[rows, cols].all():
            return (
                f"team {team.name!r}: no assignment lets every robot reach a target "
                "(some targets are unreachable from enough starts)"
            )
    return None
