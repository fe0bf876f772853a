"""Multi-valued decision diagrams (MDDs): all optimal paths of one agent at once.

The MDD of an agent for cost ``c`` under its constraints has one level per timestep
``0..c``; level ``t`` holds every vertex some cost-``c`` path (final arrival at ``c``)
visits at ``t``, with the moves between levels. After ``c`` the agent is parked at its
goal. A level of width 1 means every optimal path is there at that time: conflicts
there are *cardinal* (Sharon et al. 2015; Boyarski et al. 2015).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

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
)
from hierplan_opt.search.spacetime import Moves


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

    __slots__ = ("_levels", "cost", "goal", "_raw", "_one")

    def __init__(
        self, levels: list[dict[int, list[int]]] | None, cost: int, goal: int, raw: Any = None
    ) -> None:
        self._levels = levels
        self.cost = cost
        self.goal = goal
        #: The compiled builder's arrays (see :func:`.jit.build_mdd`) while ``levels`` is
        #: not made yet: many MDDs are only asked :meth:`single`, which needs no dicts.
        self._raw: Any = raw
        #: ``_one[t]``: the vertex of level ``t`` if it has one vertex, else -1.
        self._one: list[int] | None = None

    @property
    def arrays(self) -> Any:
        """The compiled builder's arrays while the levels are not made, else None."""
        return self._raw

    @property
    def levels(self) -> list[dict[int, list[int]]]:
        """Level ``t``: ``vertex -> its children at level t + 1`` (made on first use)."""
        lv = self._levels
        if lv is None:
            lv = self._levels = jit.mdd_levels(self._raw, self.cost, self.goal)
            self._raw = None
        return lv

    def width(self, t: int) -> int:
        return len(self.levels[t]) if t <= self.cost else 1

    def single(self, t: int, v: int) -> bool:
        """Whether every optimal path is at ``v`` at time ``t``."""
        if t > self.cost:
            return v == self.goal
        one = self._one
        if one is None:
            if self._levels is None:
                one = self._one = jit.mdd_singles(self._raw, self.cost, self.goal)
            else:
                one = self._one = [next(iter(lv)) if len(lv) == 1 else -1 for lv in self._levels]
        return one[t] == v

    def has(self, t: int, v: int) -> bool:
        if t >= self.cost:
            return v == self.goal
        lv = self._levels
        if lv is None:  # the kernel's arrays: level t is ov[lo[t]:hi[t]]
            if t < 0:  # as a list index
                return self.has(t + self.cost + 1, v)
            ov, _, _, _, lo, hi, _ = self._raw
            return bool((ov[lo[t] : hi[t]] == v).any())
        return v in lv[t]

    def passes(self, v: int, t: int) -> bool:
        """Whether some optimal path is at ``v`` at some time ``>= t`` (parked included).

        Example
        -------
        >>> from hierplan_opt.core.graph import Graph
        >>> g = Graph.grid(3, 1)
        >>> m = build_mdd(g.adj, 0, 2, g.dist_list(2), AgentConstraints(), 2)
        >>> m.passes(1, 1), m.passes(1, 2), m.passes(2, 9)
        (True, False, True)
        """
        if v == self.goal:
            return True
        if t < 0:  # as a list slice
            t = max(t + self.cost + 1, 0)
        if t >= self.cost:
            return False
        lv = self._levels
        if lv is None:  # the levels t..cost-1 are ov[:hi[t]] (written from cost-1 down)
            ov, _, _, _, _, hi, _ = self._raw
            return bool((ov[: hi[t]] == v).any())
        return any(v in x for x in lv[t:])

    def children(self, t: int, v: int) -> list[int]:
        if t >= self.cost:
            return [self.goal]
        return (self._levels or self.levels)[t][v]


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
    k = jit.kernel(len(adj))  # the compiled twin of the two passes below (see search.jit)
    if k is not None:
        return MDD(None, cost, goal, jit.build_mdd(k, adj, start, goal, dist, cons, cost, dist_of))
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


def restrict(
    m: MDD, own: Sequence[Constraint], derived: Sequence[tuple[Constraint, int]]
) -> MDD | None:
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
    r = _Restriction(cost, goal)
    if not all(r.own(c) for c in own) or not all(r.derived(c, g) for c, g in derived):
        return None
    drop, only, cut = r.drop, r.only, r.cut
    if m._levels is None:  # the compiled builder's arrays: restrict them in the kernel
        raw = jit.mdd_restrict(m._raw, cost, goal, drop, only, cut)
        return None if raw is None else MDD(None, cost, goal, raw)
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


class _Restriction:
    """:func:`restrict`'s constraints as vertices dropped per level (``drop``), the
    vertex a level is reduced to (``only``; -1: none left) and cut moves ``(time of u,
    u, v)`` (``cut``). The old MDD is shared (cached): nothing of it is changed; one
    backward pass then builds the new levels, one forward pass prunes them."""

    __slots__ = ("cost", "goal", "drop", "only", "cut")

    def __init__(self, cost: int, goal: int) -> None:
        self.cost = cost
        self.goal = goal
        self.drop: list[set[int] | None] = [None] * (cost + 1)
        self.only: list[int | None] = [None] * (cost + 1)
        self.cut: set[tuple[int, int, int]] = set()

    def neg_v(self, v: int, t: int) -> bool:
        if t > self.cost:
            return v != self.goal
        if t > 0:  # like the low level, time 0 (the start) is never constrained
            d = self.drop[t]
            if d is None:
                self.drop[t] = {v}
            else:
                d.add(v)
        return True

    def neg_e(self, u: int, v: int, t: int) -> None:
        if 1 <= t <= self.cost:
            self.cut.add((t - 1, u, v))

    def pos_v(self, v: int, t: int) -> bool:
        if t > self.cost:
            return v == self.goal
        o = self.only[t]
        self.only[t] = v if o is None or o == v else -1
        return True

    def own(self, c: Constraint) -> bool:
        """Add one of the agent's own constraints; False if the cost is ruled out."""
        kind, _, a, b, t = c
        cost = self.cost
        if kind == NEG_V:
            return self.neg_v(a, t)
        if kind == NEG_E:
            self.neg_e(a, b, t)
            return True
        if kind == NEG_RANGE:
            return all([self.neg_v(a, tt) for tt in range(b, t + 1)])
        if kind == POS_V:
            return self.pos_v(a, t)
        if kind == POS_E:
            return t <= cost and self.pos_v(a, t - 1) and self.pos_v(b, t)
        if kind == LEN_GT:
            return cost > t
        if kind == LEN_LE:
            return cost <= t
        return False  # pragma: no cover

    def derived(self, c: Constraint, other_goal: int) -> bool:
        """Add a constraint derived from another agent's; False if the cost is ruled out."""
        kind, _, a, b, t = c
        if kind == POS_V:
            return self.neg_v(a, t)
        if kind == POS_E:
            ok = self.neg_v(b, t) and self.neg_v(a, t - 1)
            self.neg_e(b, a, t)
            return ok
        if kind == LEN_LE:
            if other_goal == self.goal:
                return False
            for tt in range(t, self.cost + 1):
                self.neg_v(other_goal, tt)
        return True
