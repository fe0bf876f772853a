"""Space-time A* for one agent under CBS constraints (the low level of CBS).

States are ``(v, t)``; a move or a wait takes one timestep. The agent's *final
arrival* at its goal (the time from which it stays there forever; trailing waits do
not count) must satisfy the :class:`~hierplan_opt.search.constraints.AgentConstraints`:
it is later than every vertex constraint on the goal, not before ``min_finish`` and not
after ``max_finish``; landmarks (positive constraints) are visited on time.

Heuristic: ``max(dist(v, goal), min_finish - t, t_L - t + dist(v_L, goal))`` with
``(t_L, v_L)`` the next landmark; states that cannot reach the next landmark in time
or finish by ``max_finish`` are pruned. After the last constrained timestep the
problem no longer depends on time, so states are merged by vertex there: the search
always terminates, also when no path exists.

Ties between equal-cost paths are broken by the number of conflicts with the other
agents' paths (a conflict-avoidance table), which keeps the high level small.
"""

from __future__ import annotations

from heapq import heappop, heappush

from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.search.constraints import AgentConstraints

#: Third heap key of a final-arrival entry (smaller than any ``-t``).
TERMINAL = -(1 << 50)


class ConflictTable:
    """Where the *other* agents are: vertex-time counts, moves and parked agents.

    Example
    -------
    >>> cat = ConflictTable.from_paths([(0, 1, 2), (5, 4)], n=6, exclude=1)
    >>> cat.count(1 * 6 + 1), cat.parked
    (1, {2: 2})
    """

    __slots__ = ("vtab", "etab", "parked", "n")

    def __init__(self, n: int) -> None:
        self.n = n
        self.vtab: dict[int, int] = {}
        self.etab: set[int] = set()
        self.parked: dict[int, int] = {}

    @classmethod
    def from_paths(
        cls, paths: list[tuple[int, ...]] | tuple, n: int, exclude: int | set[int] = -1
    ) -> ConflictTable:
        cat = cls(n)
        vtab = cat.vtab
        etab = cat.etab
        ex = exclude if isinstance(exclude, set) else {exclude}
        for a, p in enumerate(paths):
            if a in ex or p is None:
                continue
            prev = p[0]
            for t, v in enumerate(p):
                k = t * n + v
                vtab[k] = vtab.get(k, 0) + 1
                if v != prev:
                    etab.add(k * n + prev)  # someone moves v <- prev, key (t, v, prev)
                prev = v
            last = len(p) - 1
            g = p[-1]
            old = cat.parked.get(g)
            if old is None or last < old:
                cat.parked[g] = last
        return cat

    def count(self, key: int) -> int:
        return self.vtab.get(key, 0)

    def add_path(self, p: tuple[int, ...]) -> None:
        """Count ``p`` in the table (its end vertex becomes parked)."""
        n = self.n
        vtab = self.vtab
        prev = p[0]
        for t, v in enumerate(p):
            k = t * n + v
            vtab[k] = vtab.get(k, 0) + 1
            if v != prev:
                self.etab.add(k * n + prev)
            prev = v
        self.parked[p[-1]] = len(p) - 1

    def remove_path(self, p: tuple[int, ...]) -> None:
        """Undo :meth:`add_path` (goals are distinct, so the parked entry is ``p``'s)."""
        n = self.n
        vtab = self.vtab
        prev = p[0]
        for t, v in enumerate(p):
            k = t * n + v
            c = vtab[k] - 1
            if c:
                vtab[k] = c
            else:
                del vtab[k]
            if v != prev:
                self.etab.discard(k * n + prev)
            prev = v
        if self.parked.get(p[-1]) == len(p) - 1:
            del self.parked[p[-1]]


def space_time_astar(
    adj: list[list[int]],
    start: int,
    goal: int,
    dist: list[int],
    cons: AgentConstraints,
    *,
    cat: ConflictTable | None = None,
    dist_of: object = None,
    node_limit: int | None = None,
) -> tuple[tuple[int, ...] | None, int]:
    """Shortest path of one agent under ``cons``; ties broken by fewest conflicts.

    Parameters
    ----------
    adj
        Neighbour lists (``graph.adj``).
    dist
        ``graph.dist_list(goal)``: exact timestep distances to the goal.
    cons
        The agent's constraints.
    cat
        Other agents' paths, for tie-breaking (optional).
    dist_of
        ``graph.dist_list`` (needed only when ``cons`` has landmarks).
    node_limit
        Give up (return None) after this many expansions.

    Returns
    -------
    (path, expanded)
        ``path`` is a tuple of vertex ids ending with the final arrival at the goal, or
        None if no path satisfies the constraints.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.search.constraints import AgentConstraints, NEG_V
    >>> g = Graph.grid(3, 1)
    >>> c = AgentConstraints.root(g.n, 2).add((NEG_V, 0, 2, -1, 3), n=g.n, goal=2)
    >>> path, _ = space_time_astar(g.adj, 0, 2, g.dist_list(2), c)
    >>> len(path) - 1, path[3], path[-1]
    (4, 1, 2)
    """
    if cons.infeasible or dist[start] >= UNREACHABLE:
        return None, 0
    n = len(adj)
    vc = cons.vertex
    ec = cons.edge
    ff = cons.forbid_from
    if goal in ff:
        return None, 0
    minf = cons.min_finish
    maxf = cons.max_finish
    lms = cons.landmarks
    # Next landmark after each time: (t_L, v_L, dist-to-v_L list, h_L = dist(v_L, goal)).
    nxt: list[tuple[int, int, list[int], int] | None] = []
    if lms:
        if dist_of is None:
            raise ValueError("dist_of is needed for positive constraints")
        order = sorted(lms.items())
        last_lm = order[-1][0]
        k = 0
        for t in range(last_lm + 1):
            while order[k][0] < t:
                k += 1
            tl, vl = order[k]
            # A landmark at the goal may be met by parking early: no h term for it.
            hb = tl + dist[vl] if vl != goal else -1
            nxt.append((tl, vl, dist_of(vl), hb))  # type: ignore[operator]
        if 0 in lms and lms[0] != start:
            return None, 0
    n_lm = len(nxt)
    tcap = max(cons.tmax, minf, n_lm) + 1

    # Final arrival at time 0: every landmark must then be at the goal.
    if start == goal and minf <= 0 and all(v == goal for v in lms.values()):
        return (start,), 0

    vtab = cat.vtab if cat is not None else None
    etab = cat.etab if cat is not None else None
    parked = cat.parked if cat is not None else None

    h0 = dist[start]
    if minf > h0:
        h0 = minf
    if h0 > maxf:
        return None, 0
    succ = _successors(adj)
    # Heap entries: (f, conflicts, -t or TERMINAL, seq, v, t, parent entry). A final
    # arrival sorts before every other entry with the same f and conflicts.
    open_heap: list[tuple] = [(h0, 0, 0, 0, start, 0, None)]
    best: dict[int, int] = {start: 0}  # fewest conflicts seen per state key
    closed: set[int] = set()
    expanded = 0
    limit = node_limit if node_limit is not None else -1
    cnt = 0
    check_goal_lm = bool(lms)
    while open_heap:
        entry = heappop(open_heap)
        _, conf, negt, _, v, t, _ = entry
        if negt == TERMINAL:
            path = []
            e = entry
            while e is not None:
                path.append(e[4])
                e = e[6]
            path.reverse()
            return tuple(path), expanded
        key = (t if t < tcap else tcap) * n + v
        if key in closed:
            continue
        closed.add(key)
        expanded += 1
        if expanded == limit:
            return None, expanded
        t1 = t + 1
        if t1 > maxf:
            continue
        lm_need = lms.get(t1) if lms else None
        nl = nxt[t1] if t1 < n_lm else None
        base = t1 * n
        keyt1 = (t1 if t1 < tcap else tcap) * n
        negt1 = -t1
        for u in succ[v]:
            if lm_need is not None and u != lm_need:
                continue
            if base + u in vc:
                continue
            if ec and u != v and ((base + v) * n + u) in ec:
                continue
            if ff and u in ff and t1 >= ff[u]:
                continue
            hu = dist[u]
            if hu >= UNREACHABLE:
                continue
            if nl is not None:
                tl, vl, dl, hb = nl
                if dl[u] > tl - t1:
                    continue
                if hb - t1 > hu:
                    hu = hb - t1
            if minf - t1 > hu:
                hu = minf - t1
            fu = t1 + hu
            if fu > maxf:
                continue
            c = conf
            if vtab is not None:
                c += vtab.get(base + u, 0)
                if u in parked and t1 > parked[u]:  # type: ignore[operator]
                    c += 1
                if u != v and ((base + u) * n + v) in etab:  # type: ignore[operator]
                    c += 1
            # A move into the goal (not a wait there) may be the final arrival.
            if (
                u == goal
                and v != goal
                and t1 >= minf
                and (not check_goal_lm or not _goal_blocked_later(cons, goal, t1, n))
            ):
                cnt += 1
                heappush(open_heap, (t1, c, TERMINAL, cnt, u, t1, entry))
            ku = keyt1 + u
            if ku in closed:
                continue
            old = best.get(ku)
            if old is not None and old <= c:
                continue
            best[ku] = c
            cnt += 1
            heappush(open_heap, (fu, c, negt1, cnt, u, t1, entry))
    return None, expanded


_SUCC: dict[int, tuple[list[list[int]], list[tuple[int, ...]]]] = {}


def _successors(adj: list[list[int]]) -> list[tuple[int, ...]]:
    """Neighbours plus the vertex itself (a wait), cached per adjacency list."""
    hit = _SUCC.get(id(adj))
    if hit is not None and hit[0] is adj:
        return hit[1]
    succ = [(*nb, v) for v, nb in enumerate(adj)]
    if len(_SUCC) > 16:
        _SUCC.clear()
    _SUCC[id(adj)] = (adj, succ)
    return succ


def _goal_blocked_later(cons: AgentConstraints, goal: int, t: int, n: int) -> bool:
    """Whether parking at ``goal`` from time ``t`` on breaks a landmark elsewhere.

    Vertex constraints on the goal are already folded into ``min_finish``; landmarks
    at other vertices after ``t`` are folded there too, so only the rare case of a
    landmark not at the goal *at or after* ``t`` remains (kept for safety).
    """
    return any(tl >= t and vl != goal for tl, vl in cons.landmarks.items())
