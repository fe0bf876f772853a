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

from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.search.constraints import NEG_RANGE, Constraint


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


def path_order_infeasibility(instance: Instance) -> str | None:
    """A reason why agents on a path-shaped component can never reach their goals.

    On a connected component that is a simple path (no vertex of degree > 2, no
    cycle) agents can never pass each other, so their order along the path is fixed:
    if the goals' order differs from the starts' order, there is no plan.

    Example
    -------
    >>> g = Graph.grid(4, 1)
    >>> inst = Instance.mapf(g, [(0, 0), (3, 0)], [(3, 0), (0, 0)])
    >>> path_order_infeasibility(inst) is not None
    True
    """
    g = instance.graph
    if g.directed or instance.is_tapf:
        return None
    adj = g.adj
    comp_of: dict[int, int] = {}
    order_of: dict[int, int] = {}
    for a in instance.agents:
        s = a.start
        if s in comp_of:
            continue
        # BFS the component; check it is a path and number its vertices from one end.
        comp = [s]
        seen = {s}
        i = 0
        edges = 0
        ok = True
        while i < len(comp):
            u = comp[i]
            i += 1
            if len(adj[u]) > 2:
                ok = False
            edges += len(adj[u])
            for w in adj[u]:
                if w not in seen:
                    seen.add(w)
                    comp.append(w)
        if not ok or edges // 2 != len(comp) - 1:
            for u in comp:
                comp_of[u] = -1
            continue
        end = next((u for u in comp if len(adj[u]) <= 1), comp[0])
        prev, cur, pos = -1, end, 0
        cid = len(order_of) + 1
        while True:
            comp_of[cur] = cid
            order_of[cur] = pos
            pos += 1
            nxt = [w for w in adj[cur] if w != prev]
            if not nxt:
                break
            prev, cur = cur, nxt[0]
    groups: dict[int, list[tuple[int, int, str]]] = {}
    for a in instance.agents:
        c = comp_of.get(a.start, -1)
        if c > 0 and a.goal is not None and comp_of.get(a.goal) == c:
            groups.setdefault(c, []).append((order_of[a.start], order_of[a.goal], a.name))
    for members in groups.values():
        by_start = [name for _, _, name in sorted(members)]
        by_goal = [name for _, _, name in sorted(members, key=lambda m: m[1])]
        if by_start != by_goal:
            return (
                "agents on a path-shaped part of the graph cannot pass each other, "
                f"but their goals are in a different order ({', '.join(map(repr, by_start))})"
            )
    return None
