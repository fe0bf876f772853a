"""Highways in CBS, ECBS and EECBS (Cohen, Uras and Koenig, SoCS 2015).

A highway set ``H`` is a set of directed edges (:mod:`hierplan_opt.core.highways`).
The *highway heuristic* ``h_hwy(v)`` is the cost of a cheapest path from ``v`` to the
goal when an edge of ``H`` costs 1 and every other edge ``w_hwy`` (a backward Dijkstra
from the goal, :class:`HighwayHeuristic`, cached per goal). With ``h`` the true
distance, ``h <= h_hwy <= w_hwy * h``. Two ways to use it (option ``hwy_mode``):

* ``"heuristic"`` (the paper's ECBS+HWY): the low-level focal search orders OPEN by
  ``f = t + h_hwy(v)`` (true costs, one per step; the table is rounded down to integers,
  which keeps ``h <= floor(h_hwy) <= w_hwy * h``). Along an optimal path ``pi*`` of cost
  ``C*`` some state is always open with ``f <= t + w_hwy * (C* - t) <= w_hwy * C*``, so
  ``f_min <= w_hwy * C*`` and the path returned costs at most ``w * f_min``;
* ``"cost"`` (the overview's other variant): the edges themselves cost 1 on ``H`` and
  ``w_hwy`` elsewhere (a wait too: waits costing 1 made waiting cheaper than a detour
  off the highways and the search wander) and the focal search minimises that inflated cost
  with ``h_hwy`` as its exact, consistent heuristic (:func:`inflated_focal_path`). The
  inflated cost of ``pi*`` is at most ``w_hwy * C*``, so again ``f_min <= w_hwy * C*``,
  and a path's true cost is at most its inflated cost ``<= w * f_min``.

Either way ``lb_i = max(dist(start), hold, ceil(f_min / w_hwy))`` is a lower bound on
agent ``i``'s cost under its constraints and its path costs at most ``w * w_hwy *
lb_i``. The high level is ECBS's (or EECBS's) with the factor ``W = w * w_hwy``:
FOCAL = {N : cost(N) <= W * LB_min}, so the plan costs at most ``W`` times the optimum
(ECBS(w)+HWY(w_hwy)). ``cbs`` with highways is CBS+HWY(w_hwy): the same search with
``w = 1`` (the low level is A* on ``t + h_hwy``, ties by conflicts), so the plan costs
at most ``w_hwy`` times the optimum. Its high level uses the freedom the bound leaves
(fewest conflicts among the nodes within ``w_hwy * LB_min``) rather than the paper's
best-first order by cost, which on the 5 x 20 corridor ran out of 20 s where this
order takes 0.3 s (``docs/highways.md``).

This module is a low level only: :class:`HighwayLowLevel` is the strategy object the
high levels take (:func:`hierplan_opt.search.ecbs_engine.run_with_highways`); it imports no
solver. The highway sets (generators, learned ones, by name) are in
:mod:`hierplan_opt.core.highways` and :mod:`hierplan_opt.core.highways_learned`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from heapq import heappop, heappush
from typing import Any

import numpy as np

from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.highways import Highways, highway_share
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search.constraints import NO_BOUND, AgentConstraints
from hierplan_opt.search.focal import FocalLowLevel, LowLevelHost, park_conflicts, scored_moves
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.spacetime import SearchTimeout, successors, unwind


class HighwayHeuristic:
    """Backward-Dijkstra tables: cost 1 on highway edges, ``w_hwy`` on the others.

    Tables are computed in batches (:meth:`precompute`) and cached per goal.

    Example
    -------
    >>> g = Graph.grid(4, 1)
    >>> hh = HighwayHeuristic(g, {(0, 1), (1, 2)}, 2.0)
    >>> hh.exact(3).tolist(), hh.table(3)
    ([4.0, 3.0, 2.0, 0.0], [4, 3, 2, 0])
    """

    def __init__(self, graph: Graph, highways: Iterable[tuple[int, int]], w_hwy: float) -> None:
        import scipy.sparse as sp  # heavy module (scipy): loaded only with highways

        self.graph = graph
        self.w_hwy = float(w_hwy)
        hw = set(highways)
        n = graph.n
        src = np.repeat(np.arange(n), np.diff(graph.indptr))
        dst = graph.indices
        weight = np.array(
            [1.0 if (int(u), int(v)) in hw else self.w_hwy for u, v in zip(src, dst, strict=True)]
        )
        # Reversed graph: Dijkstra from the goal along reversed edges gives cost-to-go.
        self._rev = sp.csr_matrix((weight, (dst, src)), shape=(n, n))
        self._exact: dict[int, np.ndarray] = {}
        self._tables: dict[int, list[int]] = {}

    def precompute(self, goals: Iterable[int]) -> None:
        """Compute the tables of every goal not cached yet (one C-level batch)."""
        from scipy.sparse.csgraph import dijkstra  # heavy module (scipy)

        todo = [t for t in dict.fromkeys(goals) if t not in self._exact]
        if not todo:
            return
        d = np.atleast_2d(dijkstra(self._rev, directed=True, indices=todo))
        for t, row in zip(todo, d, strict=True):
            row.setflags(write=False)
            self._exact[t] = row
            tab = np.floor(row + 1e-9)
            tab[~np.isfinite(row)] = UNREACHABLE
            self._tables[t] = [int(x) for x in tab]

    def exact(self, goal: int) -> np.ndarray:
        """``h_hwy`` to ``goal`` for every vertex (``inf`` where the goal is unreachable)."""
        self.precompute([goal])
        return self._exact[goal]

    def table(self, goal: int) -> list[int]:
        """``floor(h_hwy)`` to ``goal`` as a list of ints (the focal search's ``dist``)."""
        self.precompute([goal])
        return self._tables[goal]


# ---------------------------------------------------------------- the edge-cost variant
# The inner loop of the cost-mode low level, with its relax/push closures (complexity
# 24): its successor rule, conflict counts and park count are focal.scored_moves and
# focal.park_conflicts, the focal search's own; only the float-cost queues are its own.
def inflated_focal_path(
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    h: np.ndarray,
    highways: frozenset[tuple[int, int]],
    w_hwy: float,
    cons: AgentConstraints,
    res: Reservations,
    *,
    w: float = 1.0,
    deadline: Deadline | None = None,
    stats: dict[str, Any] | None = None,
) -> tuple[tuple[int, ...], float] | None:
    """Focal search over inflated edge costs: ``(path, f_min)``, inflated cost <= ``w * f_min``.

    A move along a highway edge costs 1, any other move or wait ``w_hwy``; ``h`` is
    :meth:`HighwayHeuristic.exact` (consistent for these costs). States are
    ``(v, t)`` keyed ``t * N + v`` as in :func:`~hierplan_opt.search.focal.focal_path`,
    each kept with its cheapest ``g`` (re-opened when a cheaper one appears); OPEN is
    ordered by ``f = g + h``, FOCAL = {``f <= w * f_min``} by conflicts with ``res``,
    then by ``f``. Vertex and edge constraints only.

    Example
    -------
    >>> g = Graph.grid(3, 2)
    >>> hw = frozenset({(3, 4), (4, 5), (0, 3)})
    >>> hh = HighwayHeuristic(g, hw, 2.0)
    >>> inflated_focal_path(g.adj, 0, 5, hh.exact(5), hw, 2.0, AgentConstraints(), Reservations(6))
    ((0, 3, 4, 5), 3.0)
    """
    if cons.landmarks or cons.forbid_from or cons.max_finish != NO_BOUND:
        raise ValueError("inflated_focal_path supports vertex and edge constraints only")
    succ = successors(adj)
    n = len(adj)
    vcons, econs = cons.vertex, cons.edge
    hold = cons.min_finish
    max_t = cons.tmax + n + 1
    goal_times = res.visits(goal)
    vt, et, park_t = res.vt, res.et, res.park_t
    inf = math.inf

    g_of: dict[int, float] = {start: 0.0}
    conf: dict[int, int] = {start: 0}
    parent: dict[int, int] = {start: -1}
    closed: set[int] = set()
    open_f: list[tuple[float, int]] = [(float(h[start]), start)]
    pending: list[tuple[float, int, int]] = [(float(h[start]), 0, start)]  # not yet in FOCAL
    focal: list[tuple[int, float, int, int]] = []  # (conflicts, f, -t, key)
    bound = -inf
    expanded = 0

    def f_of(key: int) -> float:
        if key < 0:
            return g_of[key]
        return g_of[key] + float(h[key % n])

    def push(key: int) -> None:
        f = f_of(key)
        heappush(open_f, (f, key))
        if f <= bound:
            t = (-key - 1) // n if key < 0 else key // n
            heappush(focal, (conf[key], f, -t, key))
        else:
            heappush(pending, (f, conf[key], key))

    def relax(key: int, g: float, c: int, par: int) -> None:
        old = g_of.get(key)
        if old is None or g < old - 1e-12 or (abs(g - old) <= 1e-12 and c < conf[key]):
            g_of[key], conf[key], parent[key] = g, c, par
            closed.discard(key)
            push(key)

    if start == goal and hold == 0:  # already there: park from time 0
        relax(-(start + 1), 0.0, park_conflicts(0, 0, goal_times), -1)
    result: tuple[tuple[int, ...], float] | None = None
    while True:
        while open_f and (open_f[0][1] in closed or abs(open_f[0][0] - f_of(open_f[0][1])) > 1e-12):
            heappop(open_f)
        if not open_f:
            break
        fmin = open_f[0][0]
        new_bound = w * fmin + 1e-9
        if new_bound > bound:
            bound = new_bound
            while pending and pending[0][0] <= bound:
                f, c, key = heappop(pending)
                if key not in closed and c == conf[key] and abs(f - f_of(key)) <= 1e-12:
                    t = (-key - 1) // n if key < 0 else key // n
                    heappush(focal, (c, f, -t, key))
        if not focal:  # pragma: no cover - the open f_min state is always admitted
            break
        c, f, _, key = heappop(focal)
        if key in closed or c != conf[key] or abs(f - f_of(key)) > 1e-12:
            continue
        closed.add(key)
        if key < 0:  # terminal: parked at the goal from here on
            result = tuple(unwind(parent, key, goal, n)), fmin
            break
        expanded += 1
        if deadline is not None and not expanded & 1023 and deadline.expired():
            raise SearchTimeout
        t, v = divmod(key, n)
        nt = t + 1
        if nt > max_t:
            continue
        base = nt * n
        gv = g_of[key]
        for u, nc in scored_moves(succ[v], v, nt, n, c, vcons, econs, vt, et, park_t):
            if h[u] == inf:
                continue
            ng = gv + (1.0 if (v, u) in highways else w_hwy)
            nk = base + u
            relax(nk, ng, nc, key)
            if u == goal and nt >= hold:
                relax(-(nk + 1), ng, park_conflicts(nc, nt, goal_times), key)
    if stats is not None:
        stats["low_level_expanded"] = stats.get("low_level_expanded", 0) + expanded
    return result


# ---------------------------------------------------------------- the low level
class HighwayLowLevel(FocalLowLevel):
    """The highway low level and the factor ``W = w * w_hwy`` of an ECBS-family search.

    A strategy given to :class:`~hierplan_opt.search.ecbs_engine._ECBS` (or a subclass):
    replaces the search's distance tables by the highway heuristic (mode
    ``"heuristic"``) or the low level itself by :func:`inflated_focal_path` (mode
    ``"cost"``), and turns its ``f_min`` into the agent's lower bound (see the module
    docstring).

    Example
    -------
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.search.ecbs_engine import _ECBS
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> low = HighwayLowLevel(frozenset({(0, 1), (1, 2)}), 2.0, "cost")
    >>> search = _ECBS(inst, Deadline(None), w=1.0, polish=False, bypass=False, low=low)
    >>> search.w_high, low.plan(search, 0, AgentConstraints())
    (2.0, ((0, 1, 2), 2))
    """

    def __init__(self, highways: Highways, w_hwy: float, mode: str) -> None:
        self.highways = highways
        self.w_hwy = w_hwy
        self.mode = mode
        self.true_dists: list[list[int]] = []

    def prepare(self, search: LowLevelHost) -> None:
        self.hwy = HighwayHeuristic(search.instance.graph, self.highways, self.w_hwy)
        self.hwy.precompute(search.goals)
        self.true_dists = search.dists
        if self.mode == "heuristic":
            search.dists = [self.hwy.table(x) for x in search.goals]
        search.w_high = search.w * self.w_hwy
        search.stats.update(
            bound=search.w_high,
            w_hwy=self.w_hwy,
            hwy_mode=self.mode,
            highway_edges=len(self.highways),
        )

    def plan(
        self, search: LowLevelHost, a: int, cons: AgentConstraints, partner: int = -1
    ) -> tuple[tuple[int, ...], int] | None:
        start, goal = search.starts[a], search.goals[a]
        if self.mode == "heuristic":
            out: tuple[tuple[int, ...], float] | None = super().plan(search, a, cons, partner)
        else:
            search.stats["low_level_calls"] += 1
            out = inflated_focal_path(
                search.adj,
                start,
                goal,
                self.hwy.exact(goal),
                self.highways,
                self.w_hwy,
                cons,
                search.res,
                w=search.w,
                deadline=search.deadline,
                stats=search.stats,
            )
        if out is None:
            return None
        path, fmin = out
        lb = max(
            self.true_dists[a][start],
            cons.min_finish,
            math.ceil(fmin / self.w_hwy - 1e-9),
        )
        return path, lb

    def annotate(self, stats: dict[str, Any], plan: Plan) -> None:
        stats["highway_share"] = highway_share(plan, self.highways)


__all__ = [
    "HighwayHeuristic",
    "HighwayLowLevel",
    "inflated_focal_path",
]
