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
agents' paths (a :class:`~hierplan_opt.search.reservations.Reservations` table used as
conflict-avoidance table), which keeps the high level small. The moves and heuristic
values come from :class:`~hierplan_opt.search.spacetime.Moves`, shared with the MDDs.
The focal variant for bounded-suboptimal search is :mod:`hierplan_opt.search.focal`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from heapq import heappop, heappush
from time import perf_counter

from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.search import jit
from hierplan_opt.search.constraints import AgentConstraints
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.spacetime import Moves, Successors

#: Third heap key of a final-arrival entry (smaller than any ``-t``).
TERMINAL = -(1 << 50)
#: ``best`` value of an expanded state (below every conflict count).
CLOSED = -1


# This function and focal.focal_path are the two hot inner loops of the solvers: their
# state expansion is written out in one body (locals, no per-successor calls) because
# every function call there costs measurable time on the benchmarks.
def space_time_astar(
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    cons: AgentConstraints,
    *,
    res: Reservations | None = None,
    dist_of: Callable[[int], Sequence[int]] | None = None,
    node_limit: int | None = None,
    cut_cache: dict[tuple[object, ...], int] | None = None,
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
    res
        The other agents' paths, for tie-breaking (optional; must not hold this agent).
    dist_of
        ``graph.dist_list`` (needed only when ``cons`` has landmarks).
    node_limit
        Give up (return None) after this many expansions.
    cut_cache
        If given, a dict kept across calls on one graph (by the caller): when ``cons``
        forbids vertices from some time on, :func:`cut_off` is tried first (once per
        start, goal, forbidden set and finish bound) and proves most searches without a
        path at once, instead of exhausting space-time.

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
    if goal in cons.forbid_from:
        return None, 0
    minf = cons.min_finish
    maxf = cons.max_finish
    lms = cons.landmarks
    moves = Moves(adj, goal, dist, cons, dist_of)
    nxt = moves.nxt
    if lms and 0 in lms and lms[0] != start:
        return None, 0
    tcap = moves.horizon()
    succ = moves.succ

    # Final arrival at time 0: every landmark must then be at the goal.
    if start == goal and minf <= 0 and all(v == goal for v in lms.values()):
        return (start,), 0

    h0 = moves.h0(start)
    if h0 > maxf:
        return None, 0
    memo = None
    if cut_cache is not None and cons.forbid_from and start != goal:
        key = (start, goal, frozenset(cons.forbid_from.items()), maxf)
        pops = cut_cache.get(key)
        if pops is None:
            pops = cut_cache[key] = cut_off(adj, start, goal, dist, cons.forbid_from, maxf)
            if pops < 0:
                return None, -pops  # the check's own expansions, counted once
        elif pops < 0:
            return None, 0
        # The same constraints already proven to admit no path (another branch or WDG
        # sub-search reached them): no search.
        memo = (start, goal, cons.content())
        if memo in cut_cache:
            return None, 0
    k = jit.kernel(len(adj))
    if k is not None and (res is None or res.moves):  # the kernel counts moves too
        found = jit.run(
            k, adj, start, goal, dist, cons, res, dist_of, node_limit, nxt=nxt, tcap=tcap, h0=h0
        )
    else:
        if res is not None and res.dense is not None:
            res.undense()  # the kernel's copy back into the dicts this loop reads
        t0 = perf_counter()
        try:
            found = _search(adj, start, goal, dist, cons, res, node_limit, succ, nxt, tcap, h0)
        finally:
            jit.note_python(perf_counter() - t0)
    if memo is not None and cut_cache is not None and found[0] is None and node_limit is None:
        cut_cache[memo] = -1
    return found


# The hot loop of space_time_astar (see the note above it): complexity 26 because the
# successor rule of spacetime.Moves and the conflict counts are written out here;
# tests/test_search_core.py and tests/test_jit_astar.py tie it to Moves and the kernel.
def _search(
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    cons: AgentConstraints,
    res: Reservations | None,
    node_limit: int | None,
    succ: Successors,
    nxt: list[tuple[int, int, Sequence[int], int]],
    tcap: int,
    h0: int,
) -> tuple[tuple[int, ...] | None, int]:
    """The pure-Python search loop of :func:`space_time_astar` (after its early exits)."""
    n = len(adj)
    minf = cons.min_finish
    maxf = cons.max_finish
    lms = cons.landmarks
    vc = cons.vertex
    ec = cons.edge
    ff = cons.forbid_from
    n_lm = len(nxt)
    vt = res.vt if res is not None else None
    et = res.et if res is not None else {}
    park_t = res.park_t if res is not None else []

    # Heap entries: (f, conflicts, -t or TERMINAL, seq, v, t, parent entry). A final
    # arrival sorts before every other entry with the same f and conflicts.
    open_heap: list[tuple] = [(h0, 0, 0, 0, start, 0, None)]
    # Fewest conflicts seen per state key; CLOSED (below every count) once expanded, so
    # one lookup serves both tests.
    best: dict[int, int] = {start: 0}
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
        if best.get(key) == CLOSED:
            continue
        best[key] = CLOSED
        expanded += 1
        if expanded == limit:
            return None, expanded
        t1 = t + 1
        if t1 > maxf:
            continue
        base = t1 * n
        keyt1 = (t1 if t1 < tcap else tcap) * n
        negt1 = -t1
        cands = succ[v]
        if cands is None:  # made on first expansion (spacetime.lazy_successors)
            cands = succ[v] = (*adj[v], v)
        if lms:
            lm_need = lms.get(t1)
            if lm_need is not None:  # a landmark at t1: the only move is onto it
                cands = (lm_need,) if lm_need in cands else ()
        nl = nxt[t1] if t1 < n_lm else None
        bv = (base + v) * n  # + u: the key of the move v -> u arriving at t1
        mt = minf - t1
        for u in cands:
            # The rule of spacetime.Moves (which the MDDs use), written out: a call per
            # expansion made CBS about 25 % slower on `hierplan bench cbs`.
            if base + u in vc:
                continue
            if ec and u != v and bv + u in ec:
                continue
            if ff and u in ff and t1 >= ff[u]:
                continue
            hu = dist[u]
            if hu >= UNREACHABLE:
                continue
            if nl is not None:
                tl, _, dl, hb = nl
                if dl[u] > tl - t1:
                    continue
                if hb - t1 > hu:
                    hu = hb - t1
            if mt > hu:
                hu = mt
            fu = t1 + hu
            if fu > maxf:
                continue
            c = conf
            if vt is not None:
                occ = vt.get(base + u)
                if occ:
                    c += len(occ)
                if t1 > park_t[u]:
                    c += 1
                # Another agent moving u -> v at the same time: a head-on swap (an edge
                # conflict; the same move v -> u is already a vertex conflict at u).
                # Measured against counting that same move (the earlier rule) on the 28
                # reference instances either solver solves: root plans with fewer
                # conflicts on 20, never more (maze-32-32-2 k5 conflict-free); CT nodes
                # -18 % on room-32-32-4 k30 (to f = 782; now solved in 60 s), -23 % on
                # warehouse k100, mixed on the small ones; more low-level expansions on
                # some (warehouse k100 +31 %), less CPU there.
                if u != v and (base + u) * n + v in et:
                    c += 1
            # A move into the goal (not a wait there) may be the final arrival.
            if (
                u == goal
                and v != goal
                and t1 >= minf
                and (not check_goal_lm or not _goal_blocked_later(cons, goal, t1))
            ):
                cnt += 1
                heappush(open_heap, (t1, c, TERMINAL, cnt, u, t1, entry))
            ku = keyt1 + u
            old = best.get(ku)
            if old is not None and old <= c:
                continue
            best[ku] = c
            cnt += 1
            heappush(open_heap, (fu, c, negt1, cnt, u, t1, entry))
    return None, expanded


def cut_off(
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    forbid_from: dict[int, int],
    max_finish: int,
) -> int:
    """Whether ``goal`` is out of reach under the forbidden-from constraints alone.

    A relaxation of :func:`space_time_astar`'s problem: vertex ``w`` may be entered
    only before time ``forbid_from[w]``, every other constraint is dropped. Waiting
    never helps there (a vertex only closes, never opens), so the earliest arrival at
    each vertex is a breadth-first search (A* with ``dist``); if it cannot reach the
    goal by ``max_finish``, no path obeys all the constraints. Returns the number of
    vertices expanded, negated when the goal is cut off.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 1)
    >>> h = g.dist_list(2)
    >>> cut_off(g.adj, 0, 2, h, {1: 5}, 1 << 40) > 0, cut_off(g.adj, 0, 2, h, {1: 1}, 1 << 40) < 0
    (True, True)
    """
    reach: dict[int, int] = {start: 0}
    # Entries (f, -t, v): among equal f the latest first, so that a goal in reach is
    # found along one shortest path, not after every vertex of the f plateau (an open
    # grid's whole rectangle between start and goal). Which vertices an exhausted search
    # pops does not depend on that order (each first at its earliest time).
    heap = [(dist[start], 0, start)]
    pops = 0
    while heap:
        f, negt, v = heappop(heap)
        t = -negt
        if f > max_finish:
            break
        if reach[v] < t:
            continue
        pops += 1
        if v == goal:
            return pops
        t1 = t + 1
        for u in adj[v]:
            if t1 >= forbid_from.get(u, UNREACHABLE) or reach.get(u, UNREACHABLE) <= t1:
                continue
            if dist[u] >= UNREACHABLE:
                continue
            reach[u] = t1
            heappush(heap, (t1 + dist[u], -t1, u))
    return -max(pops, 1)


def _goal_blocked_later(cons: AgentConstraints, goal: int, t: int) -> bool:
    """Whether parking at ``goal`` from time ``t`` on breaks a landmark elsewhere.

    Vertex constraints on the goal are already folded into ``min_finish``; landmarks
    at other vertices after ``t`` are folded there too, so only the rare case of a
    landmark not at the goal *at or after* ``t`` remains (kept for safety).
    """
    return any(tl >= t and vl != goal for tl, vl in cons.landmarks.items())
