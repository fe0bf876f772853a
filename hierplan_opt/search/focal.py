"""Focal space-time A*: the low level of ECBS and EECBS.

A state is a pair (vertex, timestep), packed into one integer ``key = t * N + v``
(``N`` = number of vertex ids), so every table is a flat dict or set of ints.

*OPEN* holds every generated, not yet expanded state ordered by ``f = g + h``, where
``g = t`` and ``h(v, t) = max(dist(v, goal), hold - t)`` (``hold`` = earliest time the
agent may stay at its goal forever, one step after the last vertex constraint on the
goal). ``h`` is consistent, so ``f_min`` (the smallest ``f`` in OPEN) is a lower bound
on the cost of the best path that meets the constraints. *FOCAL* = {``f <= w *
f_min``} is ordered by the number of conflicts with the other agents' paths, then by
``g + 2h`` (towards the goal), then deeper first. The path returned costs at most
``w * f_min``. After ``budget`` expansions the search stops trading cost for
conflicts and finishes as plain A* (still within the bound): this caps the rare calls
that would otherwise sweep the whole focal region when a conflict is unavoidable.

Conflicts are counted incrementally from a :class:`Reservations` table of the other
agents' paths: vertex occupancy by (vertex, time), moves by (from, to, time), and the
goals where agents already finished (they stay there forever).

The goal test: reaching the goal at ``t >= hold`` creates a *terminal* node whose
conflict count includes every later visit of another agent to the goal (the agent
will be parked there). Terminal nodes compete in FOCAL like any other node.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence
from heapq import heapify, heappop, heappush

from hierplan_opt.core.timer import Deadline

#: "Never parks here": larger than any timestep.
NEVER = 1 << 60


#: Secondary FOCAL key: ``(f + h) * _TIE - t``, i.e. by ``g + 2h`` (leaning towards the
#: goal like weighted A*), deeper first. Any order keeps the bound; this one reaches a
#: low-conflict path with far fewer expansions than ordering by ``f`` (measured on
#: warehouse-10-20-10-2-1: 4x fewer for 200 agents, sum of costs about 3 % higher).
_TIE = 1 << 20

#: Expansions after which FOCAL gives up trading cost for conflicts (see ``budget``).
DEFAULT_BUDGET = 10_000


class SearchTimeout(Exception):
    """Raised by the low level when the deadline expires mid-search."""


class Reservations:
    """The other agents' paths, indexed for conflict counting.

    ``vt[t * N + v]`` lists the agents at ``v`` at time ``t`` (up to and including
    the last timestep of their path); ``et[(t * N + u) * N + v]`` lists the agents
    moving ``u -> v`` between ``t`` and ``t + 1``; ``parked[v] = (T, agent)`` says
    that ``agent`` ends its path at ``v`` at time ``T`` and stays there, and
    ``park_t[v]`` is that ``T`` (a huge number where nobody parks) for fast lookups.

    Example
    -------
    >>> r = Reservations(10)
    >>> r.add(0, (1, 2, 3))
    >>> r.vt[1 * 10 + 2], r.parked[3]
    ([0], (2, 0))
    >>> r.remove(0, (1, 2, 3))
    >>> r.vt, r.et, r.parked
    ({}, {}, {})
    """

    __slots__ = ("n", "vt", "et", "parked", "park_t")

    def __init__(self, n: int) -> None:
        self.n = n
        self.vt: dict[int, list[int]] = {}
        self.et: dict[int, list[int]] = {}
        self.parked: dict[int, tuple[int, int]] = {}
        self.park_t: list[int] = [NEVER] * n

    def add(self, agent: int, path: Sequence[int]) -> None:
        """Reserve ``path`` for ``agent``."""
        n = self.n
        vt = self.vt
        et = self.et
        prev = -1
        for t, v in enumerate(path):
            k = t * n + v
            lst = vt.get(k)
            if lst is None:
                vt[k] = [agent]
            else:
                lst.append(agent)
            if t and prev != v:
                ek = ((t - 1) * n + prev) * n + v
                lst = et.get(ek)
                if lst is None:
                    et[ek] = [agent]
                else:
                    lst.append(agent)
            prev = v
        self.parked[path[-1]] = (len(path) - 1, agent)
        self.park_t[path[-1]] = len(path) - 1

    def remove(self, agent: int, path: Sequence[int]) -> None:
        """Undo :meth:`add` of the same ``agent`` and ``path``."""
        n = self.n
        vt = self.vt
        et = self.et
        prev = -1
        for t, v in enumerate(path):
            k = t * n + v
            lst = vt[k]
            if len(lst) == 1:
                del vt[k]
            else:
                lst.remove(agent)
            if t and prev != v:
                ek = ((t - 1) * n + prev) * n + v
                lst = et[ek]
                if len(lst) == 1:
                    del et[ek]
                else:
                    lst.remove(agent)
            prev = v
        p = self.parked.get(path[-1])
        if p is not None and p[1] == agent:
            del self.parked[path[-1]]
            self.park_t[path[-1]] = NEVER


def goal_visits(goal: int, agent: int, paths: Sequence[Sequence[int] | None]) -> list[int]:
    """Sorted timesteps at which agents other than ``agent`` are at ``goal``.

    Example
    -------
    >>> goal_visits(5, 0, [(5,), (4, 5, 6, 5), None])
    [1, 3]
    """
    out: list[int] = []
    for j, p in enumerate(paths):
        if j == agent or p is None or goal not in p:
            continue
        out.extend(t for t, v in enumerate(p) if v == goal)
    out.sort()
    return out


def focal_path(
    adj_self: Sequence[Sequence[int]],
    h: Sequence[int],
    start: int,
    goal: int,
    w: float,
    vcons: set[int] | frozenset[int],
    econs: set[int] | frozenset[int],
    res: Reservations,
    goal_times: Sequence[int],
    *,
    deadline: Deadline | None = None,
    max_t: int | None = None,
    stats: dict[str, int] | None = None,
    budget: int = DEFAULT_BUDGET,
    avoid: bool = False,
    limit: int = -1,
) -> tuple[tuple[int, ...], int] | None:
    """A path for one agent of cost ``<= w * lb`` with few conflicts, and ``lb``.

    Parameters
    ----------
    adj_self
        ``adj_self[v]`` = neighbours of ``v`` followed by ``v`` itself (the wait).
    h
        Timestep distances to ``goal`` (``graph.dist_list(goal)``).
    vcons, econs
        Forbidden states ``t * N + v`` and forbidden moves ``(t * N + u) * N + v``
        (``u -> v`` between ``t`` and ``t + 1``); ``N = len(adj_self)``.
    res
        The other agents' paths (this agent's own path must not be in it).
    goal_times
        Sorted times at which other agents visit ``goal`` (see :func:`goal_visits`).
    budget
        After this many expansions (if positive) FOCAL shrinks to ``{f = f_min}``:
        the search stops trading cost for fewer conflicts and ends like A* (ties
        broken by conflicts). Caps the rare calls that would otherwise explore the
        whole focal region when a conflict cannot be avoided.
    limit
        Give up (return None) after this many expansions, if positive.
    avoid
        Treat every conflict with ``res`` as forbidden (only conflict-free paths;
        with ``w = 1`` this is plain space-time A* around the other agents).
    max_t
        No state later than this is generated (defaults to the last constraint time
        plus the number of vertices, after which waiting is never forced).

    Returns
    -------
    ``(path, lb)`` with ``path`` ending at ``goal`` (no trailing waits) and ``lb`` a
    lower bound on the cost of any path meeting the constraints; None if no path
    exists within ``max_t``. Raises :class:`SearchTimeout` when the deadline expires.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 1)
    >>> adj = [list(a) + [v] for v, a in enumerate(g.adj)]
    >>> focal_path(adj, g.dist_list(2), 0, 2, 1.0, {1 * 3 + 1}, set(), Reservations(3), [])
    ((0, 0, 1, 2), 3)
    """
    n = len(adj_self)
    hold = 0
    last_c = 0
    for k in vcons:
        t = k // n
        if t > last_c:
            last_c = t
        if k - t * n == goal and t + 1 > hold:
            hold = t + 1
    for k in econs:
        t = k // (n * n) + 1
        if t > last_c:
            last_c = t
    if max_t is None:
        max_t = last_c + n + 1
    vt = res.vt
    et = res.et
    park_t = res.park_t
    n_goal_times = len(goal_times)
    has_v = bool(vcons)
    has_e = bool(econs)

    best: dict[int, int] = {}  # key -> fewest conflicts found so far
    parent: dict[int, int] = {}
    closed: set[int] = set()
    live: dict[int, int] = {}  # f -> number of generated, never expanded states
    n_live = 0
    buckets: dict[int, list[tuple[int, int, int, int]]] = {}
    focal: list[tuple[int, int, int, int]] = []

    f0 = max(h[start], hold)
    fmin = f0
    bound = int(w * fmin + 1e-9)
    best[start] = 0
    parent[start] = -1
    live[f0] = 1
    n_live = 1
    heappush(focal, (0, (f0 + h[start]) * _TIE, f0, start))
    c = n_goal_times - bisect_right(goal_times, 0)
    if start == goal and hold == 0 and not (avoid and c):
        tk = -(start + 1)
        best[tk] = c
        parent[tk] = start
        live[0] = live.get(0, 0) + 1
        n_live += 1
        heappush(focal, (c, 0, 0, tk))
    expanded = 0
    fallback = False
    while True:
        if not focal:
            # Every node within the bound is gone: raise f_min to the next live f.
            if n_live == 0:
                if stats is not None:
                    stats["low_level_expanded"] = stats.get("low_level_expanded", 0) + expanded
                return None
            while not live.get(fmin):
                fmin += 1
            new_bound = int(w * fmin + 1e-9)
            for f in range(bound + 1, new_bound + 1):
                b = buckets.pop(f, None)
                if b:
                    for e in b:
                        heappush(focal, e)
            bound = max(bound, new_bound)
            continue
        x0, x1, f, key = heappop(focal)
        c = x1 if fallback else x0
        if best[key] != c:
            continue  # stale entry
        if key < 0:
            # Terminal node: the agent parks at its goal from time f on.
            path = [goal]
            k = parent[key]
            while k >= 0:
                path.append(k % n)
                k = parent[k]
            path.reverse()
            while len(path) > 1 and path[-2] == goal:
                path.pop()  # cannot happen (hold logic), kept for safety
            if stats is not None:
                stats["low_level_expanded"] = stats.get("low_level_expanded", 0) + expanded
            return tuple(path), fmin
        first = key not in closed
        if first:
            closed.add(key)
            live[f] -= 1
            n_live -= 1
        expanded += 1
        if expanded == limit:
            if stats is not None:
                stats["low_level_expanded"] = stats.get("low_level_expanded", 0) + expanded
            return None
        if expanded == budget:
            # Too much effort spent avoiding conflicts (typically a late constraint on
            # the goal makes a wide plateau of equal f): finish as plain A* (by f,
            # deeper first, then conflicts). The path still costs <= w * f_min.
            fallback = True
            entries = focal
            for b in buckets.values():
                entries.extend(b)
            buckets.clear()
            focal = [(e[1], e[0], e[2], e[3]) for e in entries]
            heapify(focal)
            bound = 1 << 62
        if deadline is not None and not expanded & 1023 and deadline.expired():
            raise SearchTimeout
        t = key // n
        v = key - t * n
        nt = t + 1
        if nt <= max_t:
            base = nt * n
            tv = t * n + v
            for u in adj_self[v]:
                nk = base + u
                if has_v and nk in vcons:
                    continue
                if has_e and u != v and tv * n + u in econs:
                    continue
                nc = c
                occ = vt.get(nk)
                if occ:
                    nc += len(occ)
                if nt > park_t[u]:
                    nc += 1
                if u != v:
                    occ = et.get((t * n + u) * n + v)
                    if occ:
                        nc += len(occ)
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
                    tk = -(nk + 1)
                    tc = nc + n_goal_times - bisect_right(goal_times, nt)
                    if avoid and tc:
                        continue
                    old = best.get(tk)
                    if old is None or tc < old:
                        if old is None:
                            live[nt] = live.get(nt, 0) + 1
                            n_live += 1
                        best[tk] = tc
                        parent[tk] = key
                        entry = (
                            (nt * _TIE - nt, tc, nt, tk)
                            if fallback
                            else (tc, nt * _TIE - nt, nt, tk)
                        )
                        if nt <= bound:
                            heappush(focal, entry)
                        else:
                            b = buckets.get(nt)
                            if b is None:
                                buckets[nt] = [entry]
                            else:
                                b.append(entry)
        if first and f == fmin and not live[f]:
            if n_live == 0:
                continue  # handled at the top of the loop
            while not live.get(fmin):
                fmin += 1
            new_bound = int(w * fmin + 1e-9)
            for ff in range(bound + 1, new_bound + 1):
                b = buckets.pop(ff, None)
                if b:
                    for e in b:
                        heappush(focal, e)
            bound = max(bound, new_bound)
