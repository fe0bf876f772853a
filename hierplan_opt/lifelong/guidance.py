"""Guide paths from a registry solver (LaCAM by default) for the windowed PIBT.

The registry's MAPF solvers (:mod:`hierplan_opt.registry`) plan one-shot MAPF: every
agent to one goal, until all are there. In the lifelong loop each planning call can ask
one of them for such a plan from the robots' committed cells to their current errands
(distinct goals are needed: an agent whose errand is taken by a higher-priority agent,
or that has no task, keeps its own cell as its goal) within a time limit. The plan is
not executed as it is -- it ignores turning, the window and the errands that follow --
but its first steps become each agent's preferred next cell, which the windowed PIBT
favours (:class:`~hierplan_opt.lifelong.planner.WindowedPIBT`, ``guide``): agents then
follow routes that were planned together instead of each taking its own shortest one.
When the solver gives no plan in time, the call plans without guidance.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from hierplan_opt import registry
from hierplan_opt.api import solve
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.lifelong.model import Grid

log = logging.getLogger(__name__)


class RegistryGuide:
    """Guide paths by registry solver ``solver`` (see the module doc).

    Example
    -------
    >>> import numpy as np
    >>> g = Grid(1, 4, np.zeros(4, dtype=bool))
    >>> guide = RegistryGuide(g, "lacam", steps=3)
    >>> guide.paths([0, 3], [[3], [0]], [1.0, 0.0]) is None  # they cannot pass in a line
    True
    >>> guide.paths([0, 2], [[1], [3]], [1.0, 0.0])
    [{0: 1, 1: 1}, {2: 3, 3: 3}]
    """

    def __init__(
        self,
        grid: Grid,
        solver: str = "lacam",
        *,
        steps: int = 8,
        time_limit: float = 0.5,
        seed: int = 0,
        options: dict[str, Any] | None = None,
    ) -> None:
        self.grid = grid
        self.solver = solver
        self.steps = steps
        self.time_limit = time_limit
        self.seed = seed
        default: dict[str, Any] = {"anytime": 0.0} if solver == "lacam" else {}
        self.options: dict[str, Any] = dict(options or default)
        registry.get(solver).check_options(self.options)  # bad names fail here, once
        self.graph = Graph.grid(
            grid.cols, grid.rows, blocked=grid.blocked.reshape(grid.rows, grid.cols)
        )
        self.calls = 0
        self.solved = 0

    def paths(
        self, locs: Sequence[int], errands: Sequence[Sequence[int]], priority: Sequence[float]
    ) -> list[dict[int, int]] | None:
        """Per agent, cell -> preferred next cell along its guide path; None without one."""
        self.calls += 1
        n = len(locs)
        goals = [-1] * n
        used: set[int] = set()
        for i in sorted(range(n), key=lambda a: -priority[a]):
            want = errands[i][0] if errands[i] else locs[i]
            if want in used:
                want = self._nearest_unused(locs[i], used)
            goals[i] = want
            used.add(want)
        cols = self.grid.cols
        inst = Instance.mapf(
            self.graph,
            [(v % cols, v // cols) for v in locs],
            [(v % cols, v // cols) for v in goals],
        )
        res = solve(inst, self.solver, time_limit=self.time_limit, seed=self.seed, **self.options)
        if res.plan is None:
            log.debug("guide: %s gave no plan (%s)", self.solver, res.status.value)
            return None
        self.solved += 1
        out: list[dict[int, int]] = []
        for i in range(n):
            path = [res.plan.position(i, t) for t in range(self.steps + 1)]
            nxt: dict[int, int] = {}
            for a, b in zip(path, path[1:], strict=False):
                nxt.setdefault(a, b)
            out.append(nxt)
        return out

    def _nearest_unused(self, v: int, used: set[int]) -> int:
        """The cell nearest to ``v`` (breadth-first) that is no agent's goal yet."""
        seen = {v}
        frontier = [v]
        while frontier:
            nxt = []
            for u in frontier:
                if u not in used:
                    return u
                for w in self.grid.neighbours(u):
                    if w not in seen:
                        seen.add(w)
                        nxt.append(w)
            frontier = nxt
        return v  # unreachable: more agents than cells


__all__ = ["RegistryGuide"]
