"""Admissible high-level heuristics of CBS: CG, DG and WDG (Felner et al. 2018; Li et al. 2019).

All three build a graph on the agents whose paths conflict in a CT node and take a
minimum (edge-weighted) vertex cover of it:

* CG: an edge for every pair with a *cardinal* conflict (weight 1);
* DG: an edge for every pair whose MDDs admit no conflict-free pair of paths at their
  current costs (the pair's joint cost must rise by at least 1);
* WDG: DG edges weighted by the exact rise, from a two-agent CBS under the pair's
  constraints (or its proven lower bound when that search is cut short).

A vertex cover ``x`` with ``x_i + x_j >= w_ij`` for every edge lower-bounds how much the
sum of costs must grow, so ``g + min cover`` is admissible.
"""

from __future__ import annotations

from hierplan_opt.search import jit
from hierplan_opt.search.mdd import MDD

#: Components larger than this use the matching lower bound instead of exact search.
EXACT_COVER_LIMIT = 16


def dependent(ma: MDD, mb: MDD) -> bool:
    """Whether no pair of paths from the two MDDs is free of vertex and swap conflicts.

    Paths continue parked at their goals after their MDD ends.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.search.constraints import AgentConstraints
    >>> from hierplan_opt.search.mdd import build_mdd
    >>> g = Graph.grid(3, 1)
    >>> a = build_mdd(g.adj, 0, 2, g.dist_list(2), AgentConstraints(), 2)
    >>> b = build_mdd(g.adj, 2, 0, g.dist_list(0), AgentConstraints(), 2)
    >>> dependent(a, b)
    True
    """
    ra, rb = ma.arrays, mb.arrays
    if ra is not None and rb is not None:  # both from the kernel: its twin of the below
        return jit.mdd_dependent(ra, ma.cost, ma.goal, rb, mb.cost, mb.goal)
    # Depth-first search for one conflict-free pair of paths, memoising dead states:
    # quick when the pair is independent, exhaustive only when it is dependent.
    horizon = max(ma.cost, mb.cost)
    start = (next(iter(ma.levels[0]), -1), next(iter(mb.levels[0]), -1))
    if start[0] < 0 or start[1] < 0:
        return True
    dead: set[tuple[int, int, int]] = set()
    # Each frame: [t, u, v, iterator over the joint children or None]
    frames: list[list] = [[0, start[0], start[1], None]]
    while frames:
        fr = frames[-1]
        t, u, v, it = fr
        if t >= horizon:
            return False
        if it is None:
            kids = [
                (u2, v2)
                for u2 in ma.children(t, u)
                for v2 in mb.children(t, v)
                if u2 != v2 and not (u2 == v and v2 == u) and (t + 1, u2, v2) not in dead
            ]
            fr[3] = it = iter(kids)
        nxt = next(it, None)
        if nxt is None:
            dead.add((t, u, v))
            frames.pop()
            continue
        if (t + 1, nxt[0], nxt[1]) in dead:
            continue
        frames.append([t + 1, nxt[0], nxt[1], None])
    return True


def min_vertex_cover(weights: dict[tuple[int, int], int]) -> int:
    """Minimum of ``sum x_i`` over integers ``x >= 0`` with ``x_i + x_j >= w_ij``.

    Exact on each connected component of up to :data:`EXACT_COVER_LIMIT` vertices,
    else a greedy-matching lower bound (still admissible).

    Example
    -------
    >>> min_vertex_cover({(0, 1): 1, (1, 2): 1, (2, 0): 1})
    2
    >>> min_vertex_cover({(0, 1): 3, (1, 2): 1})
    3
    """
    edges = {e: w for e, w in weights.items() if w > 0}
    if not edges:
        return 0
    adj: dict[int, dict[int, int]] = {}
    for (i, j), w in edges.items():
        adj.setdefault(i, {})[j] = max(w, adj.get(i, {}).get(j, 0))
        adj.setdefault(j, {})[i] = max(w, adj.get(j, {}).get(i, 0))
    seen: set[int] = set()
    total = 0
    for s in adj:
        if s in seen:
            continue
        comp = [s]
        seen.add(s)
        k = 0
        while k < len(comp):
            for u in adj[comp[k]]:
                if u not in seen:
                    seen.add(u)
                    comp.append(u)
            k += 1
        if len(comp) <= EXACT_COVER_LIMIT:
            total += _exact_cover(comp, adj)
        else:
            total += _matching_bound(comp, adj)
    return total


def _matching_bound(comp: list[int], adj: dict[int, dict[int, int]]) -> int:
    es = sorted(((w, i, j) for i in comp for j, w in adj[i].items() if i < j), reverse=True)
    used: set[int] = set()
    lb = 0
    for w, i, j in es:
        if i not in used and j not in used:
            used.add(i)
            used.add(j)
            lb += w
    return lb


#: Branch-and-bound calls one exact cover may make before it settles for the matching
#: bound (a dense conflict graph of a dozen agents took 0.2 s per cover, past time limits).
EXACT_COVER_BUDGET = 20_000


class _OverBudget(Exception):
    pass


def _exact_cover(comp: list[int], adj: dict[int, dict[int, int]]) -> int:
    try:
        return _exact_cover_search(comp, adj)
    except _OverBudget:
        return _matching_bound(comp, adj)  # still admissible


def _exact_cover_search(comp: list[int], adj: dict[int, dict[int, int]]) -> int:
    return _CoverSearch(comp, adj).best_cover()


class _CoverSearch:
    """Depth-first branch and bound over vertex values (an object, not closures: a
    recursive closure is a reference cycle, and searches run with the cyclic collector
    paused, see core.collector)."""

    __slots__ = ("adj", "order", "pos", "value", "best", "calls")

    def __init__(self, comp: list[int], adj: dict[int, dict[int, int]]) -> None:
        self.adj = adj
        self.order = sorted(comp, key=lambda v: -len(adj[v]))
        self.pos = {v: k for k, v in enumerate(self.order)}
        self.value: dict[int, int] = {}
        self.best = _matching_upper(self.order, adj)
        self.calls = 0

    def best_cover(self) -> int:
        self.rec(0, 0)
        return self.best

    def rest_bound(self, k: int) -> int:
        # Matching bound on edges among unassigned vertices (residual weights).
        adj, pos = self.adj, self.pos
        used: set[int] = set()
        lb = 0
        for v in self.order[k:]:
            if v in used:
                continue
            bw, bu = 0, -1
            for u, w in adj[v].items():
                if pos[u] >= k and u not in used and u != v and w > bw:
                    bw, bu = w, u
            if bu >= 0:
                used.add(v)
                used.add(bu)
                lb += bw
        return lb

    def rec(self, k: int, cost: int) -> None:
        self.calls += 1
        if self.calls > EXACT_COVER_BUDGET:
            raise _OverBudget
        if cost >= self.best:
            return
        order = self.order
        if k == len(order):
            self.best = cost
            return
        if cost + self.rest_bound(k) >= self.best:
            return
        v = order[k]
        value = self.value
        need = 0
        top = 0
        for u, w in self.adj[v].items():
            if u in value:
                r = w - value[u]
                if r > need:
                    need = r
            elif w > top:
                top = w
        for x in range(need, max(need, top) + 1):
            value[v] = x
            self.rec(k + 1, cost + x)
            del value[v]


def _matching_upper(order: list[int], adj: dict[int, dict[int, int]]) -> int:
    # A feasible cover: each vertex takes its largest incident weight (upper bound + 1).
    return sum(max(adj[v].values()) for v in order) + 1
