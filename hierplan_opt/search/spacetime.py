"""The space-time core the low levels share: states, the successor rule, conventions.

A state is a vertex at a timestep, ``(v, t)``, keyed ``t * N + v`` (``N`` the number of
vertex ids) wherever a table holds states; a move or a wait takes one timestep. What
every space-time search of :mod:`hierplan_opt.search` shares is here:

* :func:`successors`: the order in which a state's moves are tried (the neighbours,
  then the wait), also the compiled kernel's CSR lists; ties are broken in that order;
* :class:`Moves`: *the* successor rule: which move is allowed at which time under an
  agent's constraints, with an admissible ``h`` (landmarks, finish bounds and
  forbidden-from included);
* :func:`unwind` and :class:`SearchTimeout`: terminal nodes (the agent parked at its
  goal, keyed ``-(key + 1)``) and the deadline.

The searches are strategies over this core, each with its own hot loop (written out
for speed, see the note above :func:`hierplan_opt.search.astar.space_time_astar`):
A* with conflict counts as tie-breaker (:mod:`~hierplan_opt.search.astar`, and its
compiled twin :mod:`~hierplan_opt.search._astar_kernel`), MDD construction
(:mod:`~hierplan_opt.search.mdd`, all paths of one cost), focal search with a focal
order by conflicts (:mod:`~hierplan_opt.search.focal`), and the highway-inflated focal
search with edge costs (:func:`hierplan_opt.search.highways.inflated_focal_path`); the
two focal searches share their move rule and conflict counts
(:func:`hierplan_opt.search.focal.scored_moves`, ``park_conflicts``). The
loops that write the rule out are tied to :class:`Moves` by
``tests/test_search_core.py`` and ``tests/test_jit_astar.py``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TypeVar

from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.search.constraints import AgentConstraints


class SearchTimeout(Exception):
    """Raised by the low level when the deadline expires mid-search."""


def unwind(parent: dict[int, int], key: int, goal: int, n: int) -> list[int]:
    """The path to terminal ``key`` (parked at ``goal``) from the ``parent`` links.

    Example
    -------
    >>> unwind({-9: 4, 4: 0, 0: -1}, -9, 2, 3)  # keys t * n + v; terminal -(key + 1)
    [0, 1, 2]
    """
    path = [goal]
    k = parent[key]
    while k >= 0:
        path.append(k % n)
        k = parent[k]
    path.reverse()
    return path


_T = TypeVar("_T")

_SUCC: dict[int, tuple[Sequence[Sequence[int]], list[tuple[int, ...]]]] = {}


def _per_adj(
    cache: dict[int, tuple[Sequence[Sequence[int]], _T]],
    adj: Sequence[Sequence[int]],
    make: Callable[[], _T],
) -> _T:
    """``make()``'s value for ``adj``, kept in ``cache`` by the identity of ``adj`` (the
    adjacency object kept beside it, so a new object at a reused id is a miss); the cache
    is emptied once it holds more than 16 graphs."""
    hit = cache.get(id(adj))
    if hit is not None and hit[0] is adj:
        return hit[1]
    value = make()
    if len(cache) > 16:
        cache.clear()
    cache[id(adj)] = (adj, value)
    return value


def successors(adj: Sequence[Sequence[int]]) -> list[tuple[int, ...]]:
    """Neighbours of every vertex followed by the vertex itself (a wait), cached per ``adj``.

    Example
    -------
    >>> successors([[1], [0]])
    [(1, 0), (0, 1)]
    """
    return _per_adj(_SUCC, adj, lambda: [(*nb, v) for v, nb in enumerate(adj)])


#: :func:`successors` made on demand (:func:`lazy_successors`): ``None`` until made.
Successors = list[tuple[int, ...] | None]

_LAZY: dict[int, tuple[Sequence[Sequence[int]], Successors]] = {}


def lazy_successors(adj: Sequence[Sequence[int]]) -> Successors:
    """:func:`successors` made on demand, one list per ``adj`` (cached by identity like
    :func:`successors`, so every search on a graph shares the entries made): entry ``v``
    is None until a search makes it ``(*adj[v], v)`` (:func:`successor`). A short search
    touches a few hundred of a map's thousands of vertices; a list (not a dict with
    ``__missing__``) keeps the lookup in the hot loops as fast as the full list's.

    Example
    -------
    >>> adj = [[1], [0]]
    >>> succ = lazy_successors(adj)
    >>> succ
    [None, None]
    >>> successor(succ, adj, 1), succ, lazy_successors(adj) is succ
    ((0, 1), [None, (0, 1)], True)
    """

    def fresh() -> Successors:
        return [None] * len(adj)

    return _per_adj(_LAZY, adj, fresh)


def successor(succ: Successors, adj: Sequence[Sequence[int]], v: int) -> tuple[int, ...]:
    """Entry ``v`` of a :func:`lazy_successors` list, made if not yet (the hot loops
    write this out)."""
    s = succ[v]
    if s is None:
        s = succ[v] = (*adj[v], v)
    return s


class Moves:
    """The moves one agent may make under its constraints, each with an admissible h.

    ``at(v, t)`` lists ``(u, h_u)`` for every move ``v -> u`` (or wait) arriving at ``t``
    that the constraints allow and after which the goal and every later landmark are
    still reachable in time; ``h_u = max(dist(u, goal), min_finish - t, t_L - t +
    dist(v_L, goal))`` with ``(t_L, v_L)`` the next landmark is a lower bound on the time
    still needed. After ``cons.tmax`` nothing depends on time, so those lists are cached
    per vertex. The space-time A* and the MDDs share this rule.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.search.constraints import NEG_V
    >>> g = Graph.grid(3, 1)
    >>> c = AgentConstraints.root(g.n, 2).add((NEG_V, 0, 1, -1, 1), n=g.n, goal=2)
    >>> Moves(g.adj, 2, g.dist_list(2), c).at(0, 1)
    [(0, 2)]
    """

    __slots__ = (
        "adj",
        "succ",
        "goal",
        "dist",
        "cons",
        "n",
        "nxt",
        "free",
        "tfree",
        "vc",
        "ec",
        "ff",
        "lms",
        "minf",
    )

    def __init__(
        self,
        adj: Sequence[Sequence[int]],
        goal: int,
        dist: Sequence[int],
        cons: AgentConstraints,
        dist_of: Callable[[int], Sequence[int]] | None = None,
    ) -> None:
        self.adj = adj
        self.succ = lazy_successors(adj)
        self.goal = goal
        self.dist = dist
        self.cons = cons
        self.n = len(adj)
        self.vc, self.ec, self.ff = cons.vertex, cons.edge, cons.forbid_from
        self.lms, self.minf = cons.landmarks, cons.min_finish
        # Next landmark after each time: (t_L, v_L, dist-to-v_L list, h_L = dist(v_L, goal)).
        nxt: list[tuple[int, int, Sequence[int], int]] = []
        lms = cons.landmarks
        if lms:
            if dist_of is None:
                raise ValueError("dist_of is needed for positive constraints")
            order = sorted(lms.items())
            k = 0
            for t in range(order[-1][0] + 1):
                while order[k][0] < t:
                    k += 1
                tl, vl = order[k]
                # A landmark at the goal may be met by parking early: no h term for it.
                hb = tl + dist[vl] if vl != goal else -1
                nxt.append((tl, vl, dist_of(vl), hb))
        self.nxt = nxt
        #: From this time on the moves depend on the vertex only (see ``at``).
        self.tfree = cons.tmax + 1
        self.free: dict[int, list[tuple[int, int]]] = {}

    def horizon(self) -> int:
        """The time from which the search merges states by vertex (nothing depends on
        time any more: after every constraint, ``min_finish`` and landmark)."""
        return max(self.cons.tmax, self.minf, len(self.nxt)) + 1

    def h0(self, start: int) -> int:
        """``h`` of the start state: ``max(dist(start, goal), min_finish)``."""
        return max(self.dist[start], self.minf)

    def at(self, v: int, t: int) -> list[tuple[int, int]]:
        """The allowed moves out of ``v`` arriving at ``t``: ``[(u, h_u), ...]``."""
        return self.layer((v,), t)[0]

    def layer(self, vs: Sequence[int], t: int) -> list[list[tuple[int, int]]]:
        """:meth:`at` for every vertex of ``vs`` (one call per layer of an MDD)."""
        if t >= self.tfree:
            free = self.free
            out = [free.get(v) for v in vs]
            if all(m is not None for m in out):
                return out  # type: ignore[return-value]
            todo = [v for v, m in zip(vs, out, strict=True) if m is None]
            for v, m in zip(todo, self._moves(todo, t), strict=True):
                free[v] = m
            return [free[v] for v in vs]
        return self._moves(vs, t)

    def _moves(self, vs: Sequence[int], t: int) -> list[list[tuple[int, int]]]:
        vc, ec, ff, lms, minf = self.vc, self.ec, self.ff, self.lms, self.minf
        dist = self.dist
        n = self.n
        succ, adj = self.succ, self.adj
        need = lms.get(t) if lms else None
        nl = self.nxt[t] if t < len(self.nxt) else None
        base = t * n
        layer: list[list[tuple[int, int]]] = []
        for v in vs:
            out: list[tuple[int, int]] = []
            cands = succ[v]
            if cands is None:
                cands = succ[v] = (*adj[v], v)
            for u in cands:
                if need is not None and u != need:
                    continue
                if base + u in vc:
                    continue
                if ec and u != v and ((base + v) * n + u) in ec:
                    continue
                if ff and u in ff and t >= ff[u]:
                    continue
                hu = dist[u]
                if hu >= UNREACHABLE:
                    continue
                if nl is not None:
                    tl, _, dl, hb = nl
                    if dl[u] > tl - t:
                        continue
                    if hb - t > hu:
                        hu = hb - t
                if minf - t > hu:
                    hu = minf - t
                out.append((u, hu))
            layer.append(out)
        return layer
