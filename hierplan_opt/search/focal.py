"""Focal space-time A*: the low level of ECBS and EECBS.

A state is a pair (vertex, timestep), packed into one integer ``key = t * N + v``
(``N`` = number of vertex ids), so every table is a flat dict or set of ints.

*OPEN* holds every generated, not yet expanded state ordered by ``f = g + h``, where
``g = t`` and ``h(v, t) = max(dist(v, goal), hold - t)`` (``hold`` = earliest time the
agent may stay at its goal forever, one step after the last vertex constraint on the
goal: ``AgentConstraints.min_finish``). ``h`` is consistent, so ``f_min`` (the smallest
``f`` in OPEN) is a lower bound on the cost of the best path that meets the
constraints. *FOCAL* = {``f <= w * f_min``} is ordered by the number of conflicts with
the other agents' paths, then by ``g + 2h`` (towards the goal), then deeper first. The
path returned costs at most ``w * f_min``. After ``budget`` expansions the search stops
trading cost for conflicts: FOCAL (still ``f <= w * f_min``) is then ordered by
``g + 2h`` first, heading for the goal; this caps the rare calls that would otherwise
sweep the whole focal region when a conflict is unavoidable.

Conflicts are counted incrementally from the
:class:`~hierplan_opt.search.reservations.Reservations` of the other agents' paths:
vertex occupancy by (vertex, time), moves by (from, to, time), and the goals where
agents already finished (they stay there forever). The constraints are the CBS ones
(:class:`~hierplan_opt.search.constraints.AgentConstraints`), vertex and edge kinds.

The goal test: reaching the goal at ``t >= hold`` creates a *terminal* node whose
conflict count includes every later visit of another agent to the goal (the agent
will be parked there). Terminal nodes compete in FOCAL like any other node.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Iterable, Sequence
from heapq import heapify, heappop, heappush
from time import perf_counter
from typing import Any, Protocol

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search import jit
from hierplan_opt.search.constraints import NO_BOUND, AgentConstraints
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.spacetime import SearchTimeout, successors, unwind

#: Secondary FOCAL key: ``(f + h) * _TIE - t``, i.e. by ``g + 2h`` (leaning towards the
#: goal like weighted A*), deeper first. Any order keeps the bound; this one reaches a
#: low-conflict path with far fewer expansions than ordering by ``f`` (measured on
#: warehouse-10-20-10-2-1: 4x fewer for 200 agents, sum of costs about 3 % higher).
_TIE = 1 << 20

#: Weight of a conflict with the ``partner`` agent in FOCAL's count.
PARTNER_WEIGHT = 1 << 10

#: Expansions after which FOCAL gives up trading cost for conflicts (see ``budget``).
DEFAULT_BUDGET = 10_000


def focal_path(
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    cons: AgentConstraints,
    res: Reservations,
    *,
    w: float = 1.0,
    deadline: Deadline | None = None,
    max_t: int | None = None,
    stats: dict[str, int] | None = None,
    budget: int = DEFAULT_BUDGET,
    avoid: bool = False,
    limit: int = -1,
    partner: int = -1,
) -> tuple[tuple[int, ...], int] | None:
    """A path for one agent of cost ``<= w * lb`` with few conflicts, and ``lb``.

    Parameters
    ----------
    adj
        Neighbour lists (``graph.adj``).
    dist
        Timestep distances to ``goal`` (``graph.dist_list(goal)``).
    cons
        The agent's vertex and edge constraints (other kinds are refused).
    res
        The other agents' paths (this agent's own path must not be in it).
    w
        Suboptimality factor of the focal list (``>= 1``).
    budget
        After this many expansions (if positive) FOCAL (still ``f <= w * f_min``) is
        ordered by ``g + 2h`` before conflicts: the search stops trading cost for
        fewer conflicts and heads for the goal. Caps the rare calls that would
        otherwise explore the whole focal region when a conflict cannot be avoided.
    limit
        Give up (return None) after this many expansions, if positive.
    avoid
        Treat every conflict with ``res`` as forbidden (only conflict-free paths;
        with ``w = 1`` this is plain space-time A* around the other agents, i.e.
        prioritized planning).
    max_t
        No state later than this is generated (defaults to the last constraint time
        plus the number of vertices, after which waiting is never forced).
    partner
        An agent of ``res`` whose conflicts count :data:`PARTNER_WEIGHT` times each (the
        other agent of a conflict ECBS split on repeatedly, so the new path avoids it
        rather than meeting it one step later); only the order of FOCAL changes.

    Returns
    -------
    ``(path, lb)`` with ``path`` ending at ``goal`` (no trailing waits) and ``lb`` a
    lower bound on the cost of any path meeting the constraints; None if no path
    exists within ``max_t``. Raises :class:`SearchTimeout` when the deadline expires.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.search.constraints import NEG_V
    >>> g = Graph.grid(3, 1)
    >>> c = AgentConstraints.root(g.n, 2).add((NEG_V, 0, 1, -1, 1), n=g.n, goal=2)
    >>> focal_path(g.adj, 0, 2, g.dist_list(2), c, Reservations(3))
    ((0, 0, 1, 2), 3)
    """
    if cons.landmarks or cons.forbid_from or cons.max_finish != NO_BOUND:
        raise ValueError("focal_path supports vertex and edge constraints only")
    n = len(adj)
    hold = cons.min_finish  # earliest time the agent may stay at its goal forever
    if max_t is None:
        max_t = cons.tmax + n + 1
    fk = jit.focal_kernel(n)
    found = None
    if fk is not None and res.moves:  # the compiled twin (see search.jit): same results
        found = jit.run_focal(
            fk, adj, start, goal, dist, cons, res, hold=hold, max_t=max_t, partner=partner,
            w=w, deadline=deadline, budget=budget, avoid=avoid, limit=limit,
        )  # fmt: skip
    if found is None:
        res.undense()  # a table the kernel took over back into the dicts this loop reads
        partner_path = res.paths[partner] if 0 <= partner < len(res.paths) else None
        partner_goal = partner_path[-1] if partner_path is not None else -1
        # the partner's visits to this agent's goal (it would meet the parked agent there)
        partner_times = (
            [t for t, x in enumerate(partner_path) if x == goal] if partner_path is not None else []
        )
        t0 = perf_counter()
        try:
            found = _focal_loop(
                successors(adj), n, start, goal, dist, cons.vertex, cons.edge, hold, max_t,
                res.visits(goal), res.vt, res.et, res.park_t, partner, partner_goal,
                partner_times, w, deadline, budget, avoid, limit,
            )  # fmt: skip
        finally:
            jit.note_python(perf_counter() - t0)
    out, expanded = found
    if stats is not None:
        stats["low_level_expanded"] = stats.get("low_level_expanded", 0) + expanded
    return out


def scored_moves(
    succ_v: tuple[int, ...],
    v: int,
    nt: int,
    n: int,
    c: int,
    vcons: set[int] | frozenset[int],
    econs: set[int] | frozenset[int],
    vt: dict[int, list[int]],
    et: dict[int, list[int]],
    park_t: list[int],
    partner: int = -1,
    partner_goal: int = -1,
) -> list[tuple[int, int]]:
    """The moves out of ``v`` (``succ_v``, its successors) arriving at ``nt`` that the
    vertex and edge constraints allow, each with its conflict count: ``[(u, c_u)]``
    with ``c_u`` = ``c`` (the state's count) plus the move's conflicts.

    The successor rule of the focal searches, written once (:func:`focal_path`'s loop
    and :func:`~hierplan_opt.search.highways.inflated_focal_path`): a constraint prunes
    the move; each other agent at ``u`` at ``nt`` (``vt``), parked at ``u`` before
    ``nt`` (``park_t``) or moving ``u -> v`` at the same step (``et``, a swap) is one
    conflict, :data:`PARTNER_WEIGHT` more when it is the ``partner``.

    Example
    -------
    >>> res = Reservations(3)
    >>> res.add(0, (2, 1))  # agent 0 moves 2 -> 1 at time 1
    >>> scored_moves((0, 2, 1), 1, 1, 3, 0, set(), set(), res.vt, res.et, res.park_t)
    [(0, 0), (2, 1), (1, 1)]
    >>> scored_moves((0, 2, 1), 1, 1, 3, 0, {3}, set(), res.vt, res.et, res.park_t)
    [(2, 1), (1, 1)]
    """
    base = nt * n
    out: list[tuple[int, int]] = []
    for u in succ_v:
        nk = base + u
        if nk in vcons or (u != v and (base + v) * n + u in econs):
            continue
        nc = c
        occ = vt.get(nk)
        if occ:
            nc += len(occ)
            if partner in occ:
                nc += PARTNER_WEIGHT
        if nt > park_t[u]:
            nc += 1
            if u == partner_goal:  # the partner is the one parked at u
                nc += PARTNER_WEIGHT
        if u != v:
            occ = et.get((base + u) * n + v)  # someone moves u -> v: a swap
            if occ:
                nc += len(occ)
                if partner in occ:
                    nc += PARTNER_WEIGHT
        out.append((u, nc))
    return out


def park_conflicts(
    c: int, nt: int, goal_times: Sequence[int], partner_times: Sequence[int] = ()
) -> int:
    """The conflict count of parking at the goal from ``nt`` on, reached with ``c``
    conflicts: plus each later visit of another agent to the goal (``goal_times``,
    sorted; :meth:`Reservations.visits`), :data:`PARTNER_WEIGHT` more each for the
    partner's (``partner_times``).

    Example
    -------
    >>> park_conflicts(1, 2, [1, 3, 5])
    3
    """
    c += len(goal_times) - bisect_right(goal_times, nt)
    if partner_times:
        c += PARTNER_WEIGHT * (len(partner_times) - bisect_right(partner_times, nt))
    return c


def _raise_bound(
    live: dict[int, int],
    buckets: dict[int, list[tuple[int, int, int, int]]],
    focal: list[tuple[int, int, int, int]],
    fmin: int,
    bound: int,
    w: float,
) -> tuple[int, int]:
    """Raise ``f_min`` to the next live f and admit the states the new bound allows:
    the new ``(f_min, bound)``."""
    if not live.get(fmin):
        # f_min := max(f_min, smallest live f). With a consistent heuristic that is the
        # next live f; with the highway heuristic f can drop along a path, and the
        # largest true f_min seen is still a valid input to the bound (each one is
        # <= w_hwy * C*).
        fmin = max(fmin, min(f for f, k in live.items() if k))
    new_bound = int(w * fmin + 1e-9)
    if new_bound - bound <= len(buckets):
        admit: Iterable[int] = range(bound + 1, new_bound + 1)
    else:  # a far jump (f_min at an "unreachable" distance): the buckets, not the range
        admit = sorted(f for f in buckets if bound < f <= new_bound)
    for f in admit:
        b = buckets.pop(f, None)
        if b:
            for e in b:
                heappush(focal, e)
    return fmin, max(bound, new_bound)


def _fallback_order(
    focal: list[tuple[int, int, int, int]], buckets: dict[int, list[tuple[int, int, int, int]]]
) -> list[tuple[int, int, int, int]]:
    """FOCAL and the waiting buckets re-keyed by ``g + 2h`` first (see ``budget``)."""
    focal = [(e[1], e[0], e[2], e[3]) for e in focal]
    heapify(focal)
    for fb, b in buckets.items():
        buckets[fb] = [(e[1], e[0], e[2], e[3]) for e in b]
    return focal


def _park(
    tk: int,
    tc: int,
    key: int,
    nt: int,
    fallback: bool,
    bound: int,
    best: dict[int, int],
    parent: dict[int, int],
    live: dict[int, int],
    focal: list[tuple[int, int, int, int]],
    buckets: dict[int, list[tuple[int, int, int, int]]],
) -> int:
    """Offer the terminal node ``tk`` (parked at the goal from ``nt`` on, ``tc``
    conflicts, reached from ``key``); 1 if it is a new live state, else 0."""
    old = best.get(tk)
    if old is not None and tc >= old:
        return 0
    best[tk] = tc
    parent[tk] = key
    entry = (nt * _TIE - nt, tc, nt, tk) if fallback else (tc, nt * _TIE - nt, nt, tk)
    if nt <= bound:
        heappush(focal, entry)
    else:
        b = buckets.get(nt)
        if b is None:
            buckets[nt] = [entry]
        else:
            b.append(entry)
    if old is not None:
        return 0
    live[nt] = live.get(nt, 0) + 1
    return 1


# See the note above astar.space_time_astar: one of the hot inner loops, its state
# expansion written out in one body on purpose (complexity 34). Its move rule and
# conflict counts are scored_moves and park_conflicts written out (those helpers are the
# rule's one definition, used by highways.inflated_focal_path, and tied to this loop by
# tests/test_search_core.py): calling scored_moves here, once per expansion, made
# `hierplan bench ecbs --quick` 5.6 % slower (CPU, farm-bench medians of 3).
def _focal_loop(
    succ: list[tuple[int, ...]],
    n: int,
    start: int,
    goal: int,
    h: Sequence[int],
    vcons: set[int] | frozenset[int],
    econs: set[int] | frozenset[int],
    hold: int,
    max_t: int,
    goal_times: list[int],
    vt: dict[int, list[int]],
    et: dict[int, list[int]],
    park_t: list[int],
    partner: int,
    partner_goal: int,
    partner_times: list[int],
    w: float,
    deadline: Deadline | None,
    budget: int,
    avoid: bool,
    limit: int,
) -> tuple[tuple[tuple[int, ...], int] | None, int]:
    """The search of :func:`focal_path`: ``(its result, expansions)``."""
    n_goal_times = len(goal_times)
    pw = PARTNER_WEIGHT
    has_v = bool(vcons)
    has_e = bool(econs)
    best: dict[int, int] = {start: 0}  # key -> fewest conflicts found so far
    parent: dict[int, int] = {start: -1}
    closed: set[int] = set()
    f0 = max(h[start], hold)
    live: dict[int, int] = {f0: 1}  # f -> number of generated, never expanded states
    n_live = 1
    buckets: dict[int, list[tuple[int, int, int, int]]] = {}  # by f, above the bound
    focal: list[tuple[int, int, int, int]] = [(0, (f0 + h[start]) * _TIE, f0, start)]
    fmin = f0
    bound = int(w * fmin + 1e-9)
    c = n_goal_times - bisect_right(goal_times, 0)
    if start == goal and hold == 0 and not (avoid and c):
        n_live += _park(-(start + 1), c, start, 0, False, bound, best, parent, live, focal, buckets)
    expanded = 0
    fallback = False
    raise_fmin = False  # the last state of f = f_min was expanded
    while True:
        if raise_fmin or not focal:
            raise_fmin = False
            if n_live == 0:
                if not focal:
                    break
            else:
                fmin, bound = _raise_bound(live, buckets, focal, fmin, bound, w)
                if not focal:
                    continue
        x0, x1, f, key = heappop(focal)
        c = x1 if fallback else x0
        if best[key] != c:
            continue  # stale entry
        if key < 0:  # terminal node: the agent parks at its goal from time f on
            path = unwind(parent, key, goal, n)
            while len(path) > 1 and path[-2] == goal:
                path.pop()  # cannot happen (hold logic), kept for safety
            return (tuple(path), fmin), expanded
        first = key not in closed
        if first:
            closed.add(key)
            live[f] -= 1
            n_live -= 1
        expanded += 1
        if expanded == limit:
            break
        if expanded == budget:
            # Too much effort spent avoiding conflicts (typically a late constraint on
            # the goal makes a wide plateau of equal f): FOCAL is now ordered by g + 2h
            # (deeper first, then conflicts), heading for the goal. It still admits
            # only f <= w * f_min, so the path still costs <= w * f_min (admitting
            # everything here once returned paths beyond that).
            fallback = True
            focal = _fallback_order(focal, buckets)
        if deadline is not None and not expanded & 1023 and deadline.expired():
            raise SearchTimeout
        t = key // n
        v = key - t * n
        nt = t + 1
        if nt <= max_t:
            base = nt * n
            for u in succ[v]:
                nk = base + u
                if has_v and nk in vcons:
                    continue
                if has_e and u != v and (base + v) * n + u in econs:
                    continue
                nc = c
                occ = vt.get(nk)
                if occ:
                    nc += len(occ)
                    if partner in occ:
                        nc += pw
                if nt > park_t[u]:
                    nc += 1
                    if u == partner_goal:  # the partner is the one parked at u
                        nc += pw
                if u != v:
                    occ = et.get((base + u) * n + v)  # someone moves u -> v: a swap
                    if occ:
                        nc += len(occ)
                        if partner in occ:
                            nc += pw
                if avoid and nc:
                    continue
                hu = h[u]
                nf = nt + hu if nt + hu > hold else hold
                old = best.get(nk)
                if old is None or nc < old:
                    if old is None:
                        live[nf] = live.get(nf, 0) + 1
                        n_live += 1
                    best[nk] = nc
                    parent[nk] = key
                    entry = (
                        ((nf + hu) * _TIE - nt, nc, nf, nk)
                        if fallback
                        else (nc, (nf + hu) * _TIE - nt, nf, nk)
                    )
                    if nf <= bound:
                        heappush(focal, entry)
                    else:
                        b = buckets.get(nf)
                        if b is None:
                            buckets[nf] = [entry]
                        else:
                            b.append(entry)
                if u == goal and nt >= hold:
                    tc = nc + n_goal_times - bisect_right(goal_times, nt)
                    if partner_times:
                        tc += pw * (len(partner_times) - bisect_right(partner_times, nt))
                    if not (avoid and tc):
                        n_live += _park(
                            -(nk + 1), tc, key, nt, fallback, bound, best, parent, live,
                            focal, buckets,
                        )  # fmt: skip
        if first and f == fmin and not live[f]:
            raise_fmin = True
    return None, expanded  # no path within max_t (or limit)


# ---------------------------------------------------------------- the low level as a strategy
class LowLevelHost(Protocol):
    """What a low level reads of (and may set on) the high-level search that calls it
    (:class:`~hierplan_opt.search.ecbs_engine._ECBS` and its subclasses)."""

    instance: Instance
    adj: list[list[int]]
    starts: list[int]
    goals: list[int]
    dists: list[list[int]]
    res: Reservations
    w: float
    w_high: float
    deadline: Deadline
    stats: dict[str, Any]


class FocalLowLevel:
    """ECBS's low level: :func:`focal_path` on the true distances, ``f_min`` as the
    agent's lower bound. The high levels take a low level as a strategy object (this
    one by default; :class:`~hierplan_opt.search.highways.HighwayLowLevel` for
    highways) instead of being subclassed for each.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.search.ecbs_engine import _ECBS
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> search = _ECBS(inst, Deadline(None), w=1.0, polish=False, bypass=False)
    >>> FocalLowLevel().plan(search, 0, AgentConstraints())
    ((0, 1, 2), 2)
    """

    def prepare(self, search: LowLevelHost) -> None:
        """Set up for ``search`` (called once, at the end of its construction)."""

    def plan(
        self, search: LowLevelHost, a: int, cons: AgentConstraints, partner: int = -1
    ) -> tuple[tuple[int, ...], int] | None:
        """Agent ``a``'s path around ``search.res`` and a lower bound on its cost."""
        search.stats["low_level_calls"] += 1
        return focal_path(
            search.adj,
            search.starts[a],
            search.goals[a],
            search.dists[a],
            cons,
            search.res,
            w=search.w,
            deadline=search.deadline,
            stats=search.stats,
            partner=partner,
        )

    def annotate(self, stats: dict[str, Any], plan: Plan) -> None:
        """Add this low level's figures of the returned ``plan`` to ``stats``."""
