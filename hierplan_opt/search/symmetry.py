"""Symmetry reasoning for CBS: corridor conflicts, plus a cheap infeasibility check.

Corridor reasoning (after Li et al., ICAPS 2020 / AIJ 2021), in the form proved here.
A *corridor* is a maximal chain ``c_1 .. c_k`` of degree-2 vertices of an undirected
graph, with end neighbours ``e_L`` (next to ``c_1``) and ``e_R`` (next to ``c_k``).

Lemma. Let agent ``x`` start outside the chain and first visit ``e_R`` at ``tau_x``
earlier than ``B_x``, the distance from its start to ``e_R`` in the graph without the
chain; then ``x`` crossed the whole chain from ``e_L``. If also ``y`` first visits
``e_L`` at ``tau_y < B_y`` (so ``y`` crossed from ``e_R``), two agents cannot pass each
other in a chain, so a conflict-free pair has ``tau_x >= tau_y + k + 2`` or
``tau_y >= tau_x + k + 2``. (Positions along ``e_L, c_1..c_k, e_R`` change by at most 1
per step; their difference changes sign, so it hits 0 -- a vertex conflict -- or jumps
over it -- a swap.)

Split. With ``E_x = dist(start_x, e_R)`` and ``E_y = dist(start_y, e_L)`` (lower bounds
on ``tau``), every conflict-free solution satisfies one of

* ``x`` is not at ``e_R`` at any time in ``[0, min(E_y + k + 1, B_x - 1)]``;
* ``y`` is not at ``e_L`` at any time in ``[0, min(E_x + k + 1, B_y - 1)]``,

because breaking both makes both agents cross with ``tau_x <= E_y + k + 1 < tau_y + k + 2``
and ``tau_y <= E_x + k + 1 < tau_x + k + 2``. These two range constraints replace the
single vertex/edge split when the current paths break both (so both children change
the paths); otherwise the ordinary split is used.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.search.constraints import NEG_RANGE, NEG_V, AgentConstraints, Constraint


class Corridors:
    """Corridor lookup and bypass distances for one undirected graph (cached).

    Example
    -------
    >>> g = Graph.grid(5, 3, obstacles=[(1, 0), (2, 0), (3, 0), (1, 2), (2, 2), (3, 2)])
    >>> c = Corridors(g)
    >>> chain, el, er = c.corridor(g.vertex((2, 1)))
    >>> [g.location(v) for v in chain], g.location(el), g.location(er)
    ([(1, 1), (2, 1), (3, 1)], (0, 1), (4, 1))
    """

    def __init__(self, graph: Graph) -> None:
        self.graph = graph
        self.adj = graph.adj
        self.enabled = not graph.directed
        self._cache: dict[int, tuple[tuple[int, ...], int, int] | None] = {}
        self._bypass: dict[tuple[int, int], list[int]] = {}

    def corridor(self, v: int) -> tuple[tuple[int, ...], int, int] | None:
        """``(chain, e_L, e_R)`` for a degree-2 vertex ``v``, or None."""
        if v in self._cache:
            return self._cache[v]
        out = self._find(v) if self.enabled and len(self.adj[v]) == 2 else None
        if out is not None:
            for c in out[0]:
                self._cache[c] = out
        else:
            self._cache[v] = None
        return out

    def _find(self, v: int) -> tuple[tuple[int, ...], int, int] | None:
        adj = self.adj
        ends = []
        sides: list[list[int]] = []
        for first in adj[v]:
            prev, cur = v, first
            side: list[int] = []
            while len(adj[cur]) == 2:
                if cur == v:
                    return None  # the chain is a cycle
                side.append(cur)
                a, b = adj[cur]
                prev, cur = cur, (b if a == prev else a)
            ends.append(cur)
            sides.append(side)
        chain = tuple(reversed(sides[0])) + (v,) + tuple(sides[1])
        el, er = ends[0], ends[1]
        if el == er or el in chain or er in chain:
            return None
        return chain, el, er

    def bypass(self, chain: tuple[int, ...], end: int) -> list[int]:
        """Distances to ``end`` in the graph without the chain's vertices."""
        key = (chain[0], end)
        d = self._bypass.get(key)
        if d is None:
            blocked = set(chain)
            d = [UNREACHABLE] * self.graph.n
            d[end] = 0
            q = deque([end])
            adj = self.adj
            while q:
                u = q.popleft()
                for w in adj[u]:
                    if w not in blocked and d[w] == UNREACHABLE:
                        d[w] = d[u] + 1
                        q.append(w)
            self._bypass[key] = d
        return d


def _first_visit(path: tuple[int, ...], v: int) -> int | None:
    for t, u in enumerate(path):
        if u == v:
            return t
    return None


def corridor_split(
    corridors: Corridors,
    starts: list[int],
    paths: list[tuple[int, ...]],
    a: int,
    b: int,
    vertices: tuple[int, ...],
) -> list[tuple[int, list[Constraint]]] | None:
    """Range-constraint children for a conflict of ``a`` and ``b`` in a corridor, or None.

    ``vertices`` are the conflict's vertices (one for a vertex conflict, two for a swap).
    """
    for v in vertices:
        cor = corridors.corridor(v)
        if cor is None:
            continue
        chain, el, er = cor
        inside = set(chain)
        if starts[a] in inside or starts[b] in inside:
            return None
        k = len(chain)
        g = corridors.graph
        dist_l = g.dist_list(el)
        dist_r = g.dist_list(er)
        byp_l = corridors.bypass(chain, el)
        byp_r = corridors.bypass(chain, er)
        for x, y in ((a, b), (b, a)):
            # x crosses towards e_R, y towards e_L. Starts are outside the chain and,
            # when tx, ty >= 0, not at e_R / e_L either, so time 0 needs no constraint.
            ex, ey = dist_r[starts[x]], dist_l[starts[y]]
            tx = min(ey + k + 1, byp_r[starts[x]] - 1)
            ty = min(ex + k + 1, byp_l[starts[y]] - 1)
            if tx < 0 or ty < 0:
                continue
            fx = _first_visit(paths[x], er)
            fy = _first_visit(paths[y], el)
            if fx is None or fy is None or fx > tx or fy > ty:
                continue
            return [
                (x, [(NEG_RANGE, x, er, 1, tx)]),
                (y, [(NEG_RANGE, y, el, 1, ty)]),
            ]
        return None
    return None


class Rectangles:
    """Coordinates of a 4-connected 2D grid for rectangle reasoning (disabled elsewhere).

    ``enabled`` is True only when the graph is a grid with one layer whose every edge
    joins cells one unit apart in x or y, and vertex ids are ``x + W * y``.

    Example
    -------
    >>> Rectangles(Graph.grid(4, 3)).enabled, Rectangles(Graph.grid(2, 2, 2)).enabled
    (True, False)
    """

    def __init__(self, graph: Graph) -> None:
        self.graph = graph
        self.enabled = False
        self.width = 0
        self.xs: list[int] = []
        self.ys: list[int] = []
        shape = graph.shape
        if graph.kind != "grid" or shape is None or not 2 <= len(shape) <= 3:
            return
        if len(shape) == 3 and shape[2] != 1:
            return
        w = int(shape[0])
        cx = graph.coords[:, 0].astype(np.int64)
        cy = graph.coords[:, 1].astype(np.int64)
        if not np.array_equal(cx + w * cy, np.arange(graph.n)):
            return
        src = np.repeat(np.arange(graph.n), np.diff(graph.indptr))
        dst = graph.indices
        if np.any(np.abs(cx[dst] - cx[src]) + np.abs(cy[dst] - cy[src]) != 1):
            return
        self.width, self.xs, self.ys = w, cx.tolist(), cy.tolist()
        self.enabled = True


def _entries(start: int, cons: AgentConstraints, t: int) -> list[tuple[int, int]]:
    """Vertex-times at or before ``t`` that every path under ``cons`` passes, latest first."""
    out = [(v, tl) for tl, v in cons.landmarks.items() if 0 < tl <= t]
    out.sort(key=lambda e: -e[1])
    out.append((start, 0))
    return out


def _at(path: tuple[int, ...], t: int) -> int:
    return path[t] if t < len(path) else path[-1]


Barrier = list[tuple[int, int]]


def rectangle_barriers(
    rect: Rectangles,
    entry_a: tuple[int, int],
    entry_b: tuple[int, int],
    goal_a: int,
    goal_b: int,
    v: int | None = None,
) -> list[tuple[bool, Barrier, Barrier]]:
    """Every barrier pair of the lemma for entries ``(vertex, time)`` of agents a and b.

    Returns ``(a_is_first, B_1, B_2)`` per frame in which the lemma applies (and, if
    ``v`` is given, the rectangle contains ``v``); ``B_i`` lists ``(vertex, time)``.
    Every pair of conflict-free paths through the entries avoids ``B_1`` with the
    first agent or ``B_2`` with the second.

    Example
    -------
    >>> g = Graph.grid(6, 6)
    >>> r = Rectangles(g)
    >>> first, b1, b2 = rectangle_barriers(r, (g.vertex((0, 2)), 0), (g.vertex((2, 0)), 0),
    ...                                    g.vertex((5, 4)), g.vertex((4, 5)))[0]
    >>> first, [(g.location(u), t) for u, t in b1], [(g.location(u), t) for u, t in b2]
    (True, [((4, 2), 4), ((4, 3), 5), ((4, 4), 6)], [((2, 4), 4), ((3, 4), 5), ((4, 4), 6)])
    """
    out: list[tuple[bool, Barrier, Barrier]] = []
    if not rect.enabled:
        return out
    xs, ys, w = rect.xs, rect.ys, rect.width
    ea, ta = entry_a
    eb, tb = entry_b
    if ea == eb:
        return out
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        xa, ya, xb, yb = sx * xs[ea], sy * ys[ea], sx * xs[eb], sy * ys[eb]
        gxa, gya = sx * xs[goal_a], sy * ys[goal_a]
        gxb, gyb = sx * xs[goal_b], sy * ys[goal_b]
        if gxa < xa or gya < ya or gxb < xb or gyb < yb:
            continue  # a goal behind its entry: not this frame
        if ta - xa - ya != tb - xb - yb:
            continue  # different diagonal offsets: the agents may pass one another
        if xa <= xb and ya >= yb:
            a_first = True
            x1, y1, t1, x2, y2, t2 = xa, ya, ta, xb, yb, tb
        elif xb <= xa and yb >= ya:
            a_first = False
            x1, y1, t1, x2, y2, t2 = xb, yb, tb, xa, ya, ta
        else:
            continue
        big_x = min(gxa, gxb)
        big_y = min(gya, gyb)
        if big_x < x2 or big_y < y1:
            continue
        if v is not None:
            cx, cy = sx * xs[v], sy * ys[v]
            if not (x2 <= cx <= big_x and y1 <= cy <= big_y):
                continue  # the conflict is not inside the rectangle
        b1 = [(sx * big_x + w * sy * y, t1 + big_x - x1 + y - y1) for y in range(y1, big_y + 1)]
        b2 = [(sx * x + w * sy * big_y, t2 + x - x2 + big_y - y2) for x in range(x2, big_x + 1)]
        out.append((a_first, b1, b2))
    return out


def rectangle_split(
    rect: Rectangles,
    starts: list[int],
    goals: list[int],
    cons: list[AgentConstraints],
    paths: list[tuple[int, ...]],
    a: int,
    b: int,
    v: int,
    t: int,
) -> list[tuple[int, list[Constraint]]] | None:
    """Barrier-constraint children for a vertex conflict of ``a``, ``b`` at ``(v, t)``, or None.

    Used only when both current paths break their barrier (both children replan).
    """
    if not rect.enabled:
        return None
    for entry_a in _entries(starts[a], cons[a], t):
        for entry_b in _entries(starts[b], cons[b], t):
            for a_first, b1, b2 in rectangle_barriers(
                rect, entry_a, entry_b, goals[a], goals[b], v
            ):
                i1, i2 = (a, b) if a_first else (b, a)
                if any(tt <= 0 for _, tt in b1) or any(tt <= 0 for _, tt in b2):
                    continue  # time 0 is never constrained by the low level
                p1, p2 = paths[i1], paths[i2]
                if not any(_at(p1, tt) == u for u, tt in b1):
                    continue
                if not any(_at(p2, tt) == u for u, tt in b2):
                    continue
                return [
                    (i1, [(NEG_V, i1, u, -1, tt) for u, tt in b1]),
                    (i2, [(NEG_V, i2, u, -1, tt) for u, tt in b2]),
                ]
    return None
