"""Multi-valued decision diagrams (MDDs): all optimal paths of one agent at once.

The MDD of an agent for cost ``c`` under its constraints has one level per timestep
``0..c``; level ``t`` holds every vertex some cost-``c`` path (final arrival at ``c``)
visits at ``t``, with the moves between levels. After ``c`` the agent is parked at its
goal. A level of width 1 means every optimal path is there at that time: conflicts
there are *cardinal* (Sharon et al. 2015; Boyarski et al. 2015).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from hierplan_opt.search import jit
from hierplan_opt.search.constraints import (
    LEN_GT,
    LEN_LE,
    NEG_E,
    NEG_RANGE,
    NEG_V,
    POS_E,
    POS_V,
    AgentConstraints,
    Constraint,
    Moves,
)


class MDD:
    """Levels ``0..cost`` of ``dict vertex -> children at the next level``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(2, 2)
    >>> m = build_mdd(g.adj, 0, 3, g.dist_list(3), AgentConstraints(), 2)
    >>> [sorted(lv) for lv in m.levels]
    [[0], [1, 2], [3]]
    """

    __slots__ = ("levels", "cost", "goal")

    def __init__(self, levels: list[dict[int, list[int]]], cost: int, goal: int) -> None:
        self.levels = levels
        self.cost = cost
        self.goal = goal

    def width(self, t: int) -> int:
        return len(self.levels[t]) if t <= self.cost else 1

    def single(self, t: int, v: int) -> bool:
        """Whether every optimal path is at ``v`` at time ``t``."""
        if t > self.cost:
            return v == self.goal
        lv = self.levels[t]
        return len(lv) == 1 and v in lv

    def has(self, t: int, v: int) -> bool:
        if t >= self.cost:
            return v == self.goal
        return v in self.levels[t]

    def children(self, t: int, v: int) -> list[int]:
        if t >= self.cost:
            return [self.goal]
        return self.levels[t][v]


def build_mdd(
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    cons: AgentConstraints,
    cost: int,
    dist_of: Callable[[int], Sequence[int]] | None = None,
) -> MDD:
    """The MDD of all paths with final arrival exactly at ``cost`` that obey ``cons``.

    ``cost`` should be the optimal cost under ``cons`` (then the MDD is non-empty).
    """
    if cost == 0:
        return MDD([{start: []}], 0, goal)
    k = jit.kernel()  # the compiled twin of the two passes below (see search.jit)
    if k is not None:
        return MDD(jit.build_mdd(k, adj, start, goal, dist, cons, cost, dist_of), cost, goal)
    moves = Moves(adj, goal, dist, cons, dist_of)
    fwd: list[dict[int, list[int]]] = [{start: []}]
    for t in range(1, cost):
        cur: dict[int, list[int]] = {}
        slack = cost - t  # a move on must still arrive by ``cost``: h <= slack
        prev = fwd[t - 1]
        for kids, mv in zip(prev.values(), moves.layer(list(prev), t), strict=True):
            for u, hu in mv:
                if hu <= slack:
                    kids.append(u)
                    if u not in cur:
                        cur[u] = []
        fwd.append(cur)
    # The last level: only the final arrival (a move into the goal, not a wait there).
    prev = fwd[cost - 1]
    for (v, kids), mv in zip(prev.items(), moves.layer(list(prev), cost), strict=True):
        if v != goal:
            for u, hu in mv:
                if u == goal and hu <= 0:
                    kids.append(u)
    # Backward pass: keep only nodes that lead to the goal at level ``cost``.
    levels: list[dict[int, list[int]]] = [{} for _ in range(cost + 1)]
    if any(prev.values()):
        levels[cost][goal] = []
    for t in range(cost - 1, -1, -1):
        nxt = levels[t + 1]
        lv = levels[t]
        for v, kids in fwd[t].items():
            if kids:
                keep = [u for u in kids if u in nxt]
                if keep:
                    lv[v] = keep
    return MDD(levels, cost, goal)


def restrict(m: MDD, own: list[Constraint], derived: list[tuple[Constraint, int]]) -> MDD | None:
    """The MDD of the same cost under extra constraints, or None if that cost is gone.

    The paths of the new MDD are exactly the old MDD's paths that obey the extra
    constraints (all of them are conditions on single vertices, moves or the finish
    time), so deleting the offending nodes and moves and pruning what no longer lies
    on a start-to-goal path gives the same result as :func:`build_mdd`, faster.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(2, 2)
    >>> m = build_mdd(g.adj, 0, 3, g.dist_list(3), AgentConstraints(), 2)
    >>> [sorted(lv) for lv in restrict(m, [(NEG_V, 0, 1, -1, 1)], []).levels]
    [[0], [2], [3]]
    >>> restrict(m, [(NEG_V, 0, 3, -1, 5)], []) is None
    True
    """
    cost = m.cost
    goal = m.goal
    # The old MDD is shared (cached): nothing of it is changed. The constraints become
    # vertices dropped per level, a vertex a level is reduced to, and cut moves; one
    # backward pass then builds the new levels, one forward pass prunes them.
    drop: list[set[int] | None] = [None] * (cost + 1)
    only: list[int | None] = [None] * (cost + 1)  # -1: no vertex left
    cut: set[tuple[int, int, int]] = set()  # (time of u, u, v)

    def neg_v(v: int, t: int) -> bool:
        if t > cost:
            return v != goal
        if t > 0:  # like the low level, time 0 (the start) is never constrained
            d = drop[t]
            if d is None:
                drop[t] = {v}
            else:
                d.add(v)
        return True

    def neg_e(u: int, v: int, t: int) -> None:
        if 1 <= t <= cost:
            cut.add((t - 1, u, v))

    def pos_v(v: int, t: int) -> bool:
        if t > cost:
            return v == goal
        o = only[t]
        only[t] = v if o is None or o == v else -1
        return True

    for kind, _, a, b, t in own:
        ok = True
        if kind == NEG_V:
            ok = neg_v(a, t)
        elif kind == NEG_E:
            neg_e(a, b, t)
        elif kind == NEG_RANGE:
            for tt in range(b, t + 1):
                ok = ok and neg_v(a, tt)
        elif kind == POS_V:
            ok = pos_v(a, t)
        elif kind == POS_E:
            if t > cost:
                return None
            ok = pos_v(a, t - 1) and pos_v(b, t)
        elif kind == LEN_GT:
            ok = cost > t
        elif kind == LEN_LE:
            ok = cost <= t
        else:  # pragma: no cover
            return None
        if not ok:
            return None
    for (kind, _, a, b, t), other_goal in derived:
        ok = True
        if kind == POS_V:
            ok = neg_v(a, t)
        elif kind == POS_E:
            ok = neg_v(b, t) and neg_v(a, t - 1)
            neg_e(b, a, t)
        elif kind == LEN_LE:
            if other_goal == goal:
                return None
            for tt in range(t, cost + 1):
                neg_v(other_goal, tt)
        if not ok:
            return None
    # Backward: the nodes that still reach the goal, with the moves that do.
    old = m.levels
    levels: list[dict[int, list[int]]] = [{} for _ in range(cost + 1)]
    d, o = drop[cost], only[cost]
    if goal in old[cost] and not (d is not None and goal in d) and o in (None, goal):
        levels[cost][goal] = []
    for t in range(cost - 1, -1, -1):
        nxt = levels[t + 1]
        if not nxt:
            return None
        lv = levels[t]
        d = drop[t]
        o = only[t]
        for v, kids in old[t].items():
            if (d is not None and v in d) or (o is not None and v != o):
                continue
            keep = [x for x in kids if x in nxt]
            if cut and keep:
                keep = [x for x in keep if (t, v, x) not in cut]
            if keep:
                lv[v] = keep
    if not levels[0]:
        return None
    # Forward: what the start still reaches (the kids of a kept node are all kept).
    for t in range(cost):
        nxt = levels[t + 1]
        reach: set[int] = set()
        for kids in levels[t].values():
            reach.update(kids)
        if len(reach) < len(nxt):
            for v in [v for v in nxt if v not in reach]:
                del nxt[v]
    return MDD(levels, cost, goal)
