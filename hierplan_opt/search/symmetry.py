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

Generalised (Li et al., AIJ 2021): every bound may come from the agents' constraints at
the CT node instead of the bare graph, since a node's descendants only add constraints.
``E_x`` becomes the earliest time ``x`` can reach ``e_R`` under its constraints and
``B_x`` the same with the last edge ``c_k - e_R`` blocked (:func:`travel_time`; any
lower bound is sound). The lemma only needs "a first arrival at the exit before
``B_x`` comes through the corridor", so it also holds for a single edge ``(p, q)``
(``k = 0``): a *pseudo-corridor*, used for a head-on meeting of two agents whose
every optimal path makes the meeting moves (:func:`pseudo_corridor_split`).

Starts inside the chain. Number the line ``e_L = 0, c_1 = 1, .., c_k = k, e_R = k + 1``
and let ``p_x`` be ``x``'s start position if it lies in the chain, else 0 (``p_y``: else
``k + 1``). If ``p_x < p_y`` the lemma still holds: before its first visit to ``e_R`` at
``tau_x < B_x``, ``x`` stays in the chain since its start or its last visit to ``e_L``,
so it moves from a position ``<= p_x`` to ``k + 1``, while ``y`` moves from ``>= p_y``
to 0; if the two time intervals overlap, the order of the agents on the line flips
inside the overlap (a vertex or swap conflict), so one agent ends its interval before
the other starts it, and that one starts at an end (``y`` at ``e_R`` at a time
``> tau_x``), which gives ``tau_y >= tau_x + k + 2`` as before (:func:`corridor_split`).

Corridor-target reasoning (after Li et al., AIJ 2021; proved here in this form). Let
agent ``m``'s goal ``g`` be a chain vertex at position ``j``, ``X`` one end of the
chain, ``Y`` the other, ``D = |pos(X) - j|``, ``n_X`` and ``n_Y`` the neighbours of
``g`` towards ``X`` and ``Y``, and let agent ``o`` not start strictly between ``g`` and
``X``. Take a conflict-free pair of paths (under the node's constraints) in which ``o``
is at ``X`` at a time in ``[1, B_o(X) - 1]``, ``B_o(X)`` the earliest arrival at ``X``
with the chain edge into ``X`` blocked, and ``m`` is parked at ``g`` from time ``f``.
Then ``o``'s first arrival at ``X``, at ``tau' < B_o(X)``, comes through the chain, so
``o`` was last at ``g`` at some ``tau_g < tau'`` and stayed strictly between ``g`` and
``X`` in between; ``o``'s first visit to ``g``, at ``tau_1 <= tau_g``, used no vertex
between ``g`` and ``X`` (they are reached only through ``g`` or ``X``). As ``m`` is
parked, ``f > tau_g``; let ``f_0 <= f`` be ``m``'s first time at ``g`` after ``tau_g``.
At ``f_0 - 1`` ``m`` is at ``n_Y`` or at ``n_X``.

* From ``n_Y``: ``f_0 >= T_m(n_Y) + 1`` and ``f_0 >= tau_1 + 1 >= B_o(g) + 1``, with
  ``B_o(g)`` the earliest arrival at ``g`` with the edge ``g - n_X`` blocked.
* From ``n_X``: let ``s`` be ``m``'s last time before ``f_0`` outside the open segment
  ``(g, X)``. If ``s < tau_g`` (or there is none), ``m`` is inside the segment at
  ``tau_g`` (ahead of ``o``) and behind ``o`` at ``min(f_0, tau')``: the order flips, a
  conflict. So ``s >= tau_g`` and ``m`` is at ``X`` at ``s`` (it is not at ``g`` during
  ``(tau_g, f_0)``). If ``s <= tau'``, ``m`` is ahead of ``o`` at ``s`` and behind it at
  ``min(f_0, tau')``: a conflict again. So ``s >= tau' + 1`` with ``tau' >= T_o(X)`` and
  ``tau' >= tau_1 + D``, ``s >= T_m(X)``, and ``f_0 >= s + D``.

(``T`` are earliest arrivals under the node's constraints, :func:`travel_time`.) So
``f >= l1 + 1`` with ``l1 + 1 = min(max(max(T_o(X), B_o(g) + D) + 1, T_m(X)) + D,
max(B_o(g), T_m(n_Y)) + 1)``, and every conflict-free solution of the node (and of its
descendants, whose constraints only add) has ``m`` finishing after ``l1``, or ``m``
finishing by ``l1`` and ``o`` away from ``X`` at all times in ``[1, l2]`` for any
``l2 < B_o(X)``: the two children of :func:`corridor_target_split` (the second also
keeps every other agent off ``g`` from ``l1`` on, as in target reasoning) exclude no
conflict-free solution.

Generalised rectangles (after Li et al., AIJ 2021; proved here in this form). The
rectangle rule (:func:`rectangle_split`) needs *entries* -- vertex-times every path of
the CT subtree passes (the start, landmarks of positive constraints) -- on one
anti-diagonal. :func:`generalized_rectangle_split` draws the rectangle instead where
both current paths run as staircases through the conflict (e.g. from a room's doors)
and takes the lemma's barriers ``B_1``, ``B_2`` of that rectangle as candidates. They
are used only if :func:`barriers_force_conflict` proves, from the agents' real entries
``(v_i, t_i)``, that no two paths -- each obeying its agent's constraints at the node
(waits allowed; landmarks and finish bounds dropped, which only adds paths) -- reach
``B_1`` and ``B_2`` without a vertex or swap conflict: a joint search over both agents'
positions from ``max(t_1, t_2)`` on, in which a state with an agent on its barrier is
an escape. Claim: then every conflict-free pair of paths of any descendant node avoids
``B_1`` with agent 1 or ``B_2`` with agent 2. Proof: a descendant's paths pass the
same entries and obey a superset of the constraints, so they are among the searched
paths. If both broke their barriers, take the first time either is on its barrier
vertex-time (no earlier than ``max(t_1, t_2)``, else the search reports an escape); the
pair's positions up to then are a run of the joint search without a conflict that ends
in an escape state -- but the search found none. So the two barrier children exclude
no conflict-free solution and CBS stays optimal. Pruning positions that cannot reach a
barrier vertex-time in time (graph distance) removes only states from which no escape
follows; a search over its budget answers "not proved" (no split), which is always safe.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from heapq import heappop, heappush
from types import ModuleType

from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.search import jit
from hierplan_opt.search.constraints import (
    LEN_GT,
    LEN_LE,
    NEG_RANGE,
    NEG_V,
    AgentConstraints,
    Constraint,
)


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
        #: ``travel_time`` values shared by a search and its WDG sub-searches:
        #: (constraints version, start, target, blocked edge) -> (value, upper bound used).
        self.travel_cache: dict[tuple[int, int, int, tuple[int, int] | None], tuple[int, int]] = {}

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


def _visits_by(path: tuple[int, ...], v: int, last: int) -> bool:
    """Whether ``path`` (parked at its end afterwards) is at ``v`` at a time in ``[1, last]``."""
    end = len(path) - 1
    for t in range(1, min(last, end) + 1):
        if path[t] == v:
            return True
    return last > end and path[-1] == v


def travel_time(
    adj: Sequence[Sequence[int]],
    start: int,
    target: int,
    h: Sequence[int],
    cons: AgentConstraints,
    blocked: tuple[int, int] | None = None,
    upper: int = UNREACHABLE,
    kernel: ModuleType | None = None,
) -> int:
    """A lower bound on the earliest time an agent under ``cons`` can be at ``target``.

    Space-time A* (heuristic ``h``: distances to ``target``) obeying the vertex, edge
    and forbidden-from constraints of ``cons`` (landmarks and finish bounds are
    ignored, so the value is a lower bound); ``blocked`` is an edge the agent may not
    use in either direction. Returns ``upper`` when the target cannot be reached
    before ``upper``. ``kernel``: the loaded compiled low level
    (:func:`.jit.kernel`), which runs the same search (:func:`.jit.travel`).

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> c = AgentConstraints.root(g.n, 2).add((NEG_V, 0, 1, -1, 1), n=g.n, goal=2)
    >>> h = g.dist_list(2)
    >>> travel_time(g.adj, 0, 2, h, AgentConstraints()), travel_time(g.adj, 0, 2, h, c)
    (2, 3)
    >>> travel_time(g.adj, 0, 2, h, c, blocked=(1, 2))
    1073741824
    """
    if start == target:
        return 0
    if h[start] >= upper:
        return upper
    n = len(adj)
    vc, ec, ff = cons.vertex, cons.edge, cons.forbid_from
    if blocked is None and not vc and not ec and not ff:
        return h[start]
    if kernel is not None:
        return jit.travel(kernel, adj, start, target, h, cons, blocked, upper)
    tcap = cons.tmax + 1
    bx, by = blocked if blocked is not None else (-1, -1)
    # Entries (f, -t, v): among equal f the deepest first reaches the target soonest.
    heap: list[tuple[int, int, int]] = [(h[start], 0, start)]
    closed: set[int] = set()
    while heap:
        _, negt, v = heappop(heap)
        t = -negt
        if v == target:
            return t
        key = (t if t < tcap else tcap) * n + v
        if key in closed:
            continue
        closed.add(key)
        t1 = t + 1
        base = t1 * n
        for u in (*adj[v], v):
            if (v == bx and u == by) or (v == by and u == bx):
                continue
            # The vertex/edge/goal-blocking part of spacetime.Moves, written out as in
            # the low level's loop (astar.space_time_astar); landmarks are left out.
            if base + u in vc:
                continue
            if ec and u != v and ((base + v) * n + u) in ec:
                continue
            if ff and u in ff and t1 >= ff[u]:
                continue
            hu = h[u]
            if t1 + hu >= upper:
                continue
            if (t1 if t1 < tcap else tcap) * n + u in closed:
                continue
            heappush(heap, (t1 + hu, -t1, u))
    return upper


#: ``travel(agent, target, blocked_edge, upper)``: see :func:`travel_time`.
Travel = Callable[[int, int, "tuple[int, int] | None", int], int]


def corridor_ranges(
    travel: Travel,
    x: tuple[int, int, int],
    y: tuple[int, int, int],
    length: int,
) -> tuple[int, int]:
    """Range ends ``(T_x, T_y)`` for two agents crossing a corridor in opposite directions.

    ``x = (agent, exit, inner)``: the agent leaves the corridor at ``exit`` by the edge
    from ``inner``; likewise ``y`` at the other end; ``length`` is the number of edges
    from one exit to the other. Every conflict-free pair of paths avoids ``exit_x`` at
    all times in ``[1, T_x]`` with ``x`` or ``exit_y`` in ``[1, T_y]`` with ``y``
    (see the module docstring; -1 when there is no such range).
    """
    ax, ex, ix = x
    ay, ey, iy = y
    tx = travel(ax, ex, None, UNREACHABLE)
    ty = travel(ay, ey, None, UNREACHABLE)
    if tx >= UNREACHABLE or ty >= UNREACHABLE:
        return -1, -1
    bx = travel(ax, ex, (ix, ex), ty + length + 1)
    by = travel(ay, ey, (iy, ey), tx + length + 1)
    return min(bx - 1, ty + length), min(by - 1, tx + length)


def corridor_split(
    corridors: Corridors,
    travel: Travel,
    starts: list[int],
    paths: list[tuple[int, ...]],
    a: int,
    b: int,
    vertices: tuple[int, ...],
) -> list[tuple[int, list[Constraint]]] | None:
    """Range-constraint children for a conflict of ``a`` and ``b`` in a corridor, or None.

    ``vertices`` are the conflict's vertices (one for a vertex conflict, two for a swap).
    Used only when both current paths break their range (both children replan).
    A start inside the chain is allowed when the agent heading for ``e_R`` starts
    nearer ``e_L`` than the other (see the module docstring).
    """
    for v in vertices:
        cor = corridors.corridor(v)
        if cor is None:
            continue
        chain, el, er = cor
        pos = _positions(chain)
        length = len(chain) + 1
        for x, y in ((a, b), (b, a)):
            # x crosses towards e_R, y towards e_L; x must start on e_L's side of y.
            if pos.get(starts[x], 0) >= pos.get(starts[y], length):
                continue
            if _first_visit(paths[x], er) is None or _first_visit(paths[y], el) is None:
                continue
            tx, ty = corridor_ranges(travel, (x, er, chain[-1]), (y, el, chain[0]), length)
            if tx < 1 or ty < 1:
                continue
            if not _visits_by(paths[x], er, tx) or not _visits_by(paths[y], el, ty):
                continue
            return [(x, [(NEG_RANGE, x, er, 1, tx)]), (y, [(NEG_RANGE, y, el, 1, ty)])]
        return None
    return None


def _positions(chain: tuple[int, ...]) -> dict[int, int]:
    """Position of each chain vertex on the line ``e_L = 0, c_1 = 1, .., e_R = k + 1``."""
    return {c: i + 1 for i, c in enumerate(chain)}


def corridor_target_bounds(
    travel: Travel,
    line: tuple[int, ...],
    j: int,
    xi: int,
    m: int,
    o: int,
    above: int = -1,
    arrival: int = 0,
) -> tuple[int, int]:
    """``(l1, B)`` of corridor-target reasoning, or ``(-1, 0)`` if ``l1 <= above`` or
    ``B <= arrival`` (``o``'s current first arrival at ``X``: no range would cover it).

    ``line`` is ``(e_L, c_1, .., c_k, e_R)``; ``m``'s goal is ``line[j]`` (``1 <= j <=
    k``) and ``X = line[xi]`` (``xi`` is 0 or ``k + 1``). Every conflict-free pair of paths
    in which ``o`` is at ``X`` at a time in ``[1, B - 1]`` and ``m`` is parked at its
    goal from time ``f`` has ``f > l1`` (module docstring; ``o`` must not start strictly
    between ``line[j]`` and ``X``). ``B`` is ``B_o(X)`` or, if that is larger, at least
    ``l1 + D + k + 2`` (the ranges used end there).

    Example
    -------
    >>> g = Graph.grid(5, 3, obstacles=[(1, 0), (2, 0), (3, 0), (1, 2), (2, 2), (3, 2)])
    >>> line = (g.vertex((0, 1)), *(g.vertex((x, 1)) for x in (1, 2, 3)), g.vertex((4, 1)))
    >>> s = [g.vertex((4, 0)), g.vertex((0, 0))]  # m = 0 (goal (2, 1)), o = 1 heads right
    >>> def travel(a, target, blocked, upper):
    ...     return travel_time(g.adj, s[a], target, g.dist_list(target), AgentConstraints(),
    ...                        blocked, upper)
    >>> corridor_target_bounds(travel, line, 2, 4, 0, 1)  # no bypass: B capped at 4 + 2 + 5
    (4, 11)
    """
    g = line[j]
    step = 1 if xi > j else -1
    x, d = line[xi], abs(xi - j)
    blocked_x = (line[xi - step], x)
    if travel(o, x, blocked_x, arrival + 1) <= arrival:
        return -1, 0  # e.g. a room corner: the way round is as fast
    # Lower bounds: o's first arrival at g (X side of g unused before it), m's arrival at
    # g's neighbour on the far side, o's and m's at X. Cheapest decision first: each
    # search is bounded by the value above which it no longer changes the result.
    t_my = travel(m, line[j - step], None, above + 1)
    b_og = travel(o, g, (g, line[j + step]), UNREACHABLE if t_my > above else above + 1)
    if max(b_og, t_my) <= above:
        return -1, 0
    if t_my > above:
        t_my = travel(m, line[j - step], None, UNREACHABLE)
    via_y = max(b_og, t_my) + 1
    t_ox = travel(o, x, None, max(via_y - d - 1, 0))
    t_mx = travel(m, x, None, max(via_y - d, 0))
    via_x = max(max(t_ox, b_og + d) + 1, t_mx) + d
    l1 = min(via_x, via_y) - 1
    if l1 <= above or l1 >= UNREACHABLE:
        return -1, 0
    # Only ranges up to l1 + d + k + 1 are used (see corridor_target_split).
    return l1, travel(o, x, blocked_x, l1 + d + len(line))


def _early(path: tuple[int, ...], v: int, avoid: int, bar: int) -> bool:
    """Whether ``path`` first visits ``v`` by time ``bar``, not visiting ``avoid`` before:
    then the earliest such arrival (a bound of :func:`corridor_target_bounds`) is ``<= bar``."""
    for u in path[: bar + 1]:
        if u == v:
            return True
        if u == avoid:
            return False
    return False


def corridor_target_split(
    corridors: Corridors,
    travel: Travel,
    starts: list[int],
    goals: list[int],
    paths: list[tuple[int, ...]],
    m: int,
    o: int,
    vertices: tuple[int, ...],
    above: int = -1,
) -> list[tuple[int, list[Constraint]]] | None:
    """Corridor-target children when ``m``'s goal lies in the corridor ``o`` passes, or None.

    Child 1: ``m`` finally arrives after ``l1``; child 2: ``m`` finishes by ``l1``
    (with the usual consequence for the others: off its goal from ``l1`` on) and ``o``
    is not at the exit ``X`` at any time in ``[1, l2]`` (:func:`corridor_target_bounds`).
    Used only when both current paths break their child's constraints (both children
    replan), and only if ``l1 > above`` (a TARGET conflict at time ``t`` passes
    ``above=t``: with ``l1 <= t`` the target split is as good).
    """
    g = goals[m]
    for v in vertices:
        cor = corridors.corridor(v)
        if cor is None or g not in cor[0]:
            continue
        chain, el, er = cor
        k1 = len(chain) + 1
        line = (el, *chain, er)
        j = chain.index(g) + 1
        so = chain.index(starts[o]) + 1 if starts[o] in chain else -1
        path_m, path_o = paths[m], paths[o]
        f_cur = len(path_m) - 1
        for xi in (k1, 0):
            x, d = line[xi], abs(xi - j)
            if min(j, xi) < so < max(j, xi):
                continue  # o starts between g and X: it need not pass g
            if not _visits_by(path_o, x, len(path_o)):
                continue  # o never at X: child 2 would not change its path
            bar = max(above, f_cur - 1)
            step = 1 if xi > j else -1
            if _early(path_m, line[j - step], -1, bar) and _early(path_o, g, line[j + step], bar):
                continue  # the current paths show l1 <= bar, without a search
            arrival = path_o.index(x, 1) if x in path_o[1:] else len(path_o) - 1
            l1, b_ox = corridor_target_bounds(travel, line, j, xi, m, o, bar, arrival)
            if l1 < 0 or b_ox <= 1:
                continue
            # Any end of the range is sound; a finite one keeps the constraint small (o
            # is off g from l1 on, so it arrives through the corridor soon after).
            l2 = min(b_ox - 1, l1 + d + k1)
            if not _visits_by(path_o, x, l2):
                continue
            return [
                (m, [(LEN_GT, m, -1, -1, l1)]),
                (m, [(LEN_LE, m, -1, -1, l1), (NEG_RANGE, o, x, 1, l2)]),
            ]
    return None


def pseudo_corridor_split(
    travel: Travel,
    paths: list[tuple[int, ...]],
    a: int,
    b: int,
    u: int,
    v: int,
    t: int,
) -> list[tuple[int, list[Constraint]]] | None:
    """Range-constraint children for a head-on conflict over one edge, or None.

    A vertex conflict at ``(v, t)`` (``u == -1``) where ``a`` goes ``p -> v -> q`` and
    ``b`` goes ``q -> v -> p``, or a swap of ``a: u -> v`` with ``b: v -> u`` at ``t``,
    is a corridor of length 1: ``a`` leaves it at ``q`` (``v``), ``b`` at ``v``
    (``u``). The caller checks that every optimal path of both agents makes these
    moves (singleton MDD levels), else the split rarely pays.
    """
    pa, pb = paths[a], paths[b]
    if u < 0:
        if len(pa) <= t + 1 or len(pb) <= t + 1 or t < 1:
            return None
        q = pa[t + 1]
        if pa[t - 1] != pb[t + 1] or q != pb[t - 1] or q == v:
            return None
        x, y = (a, q, v), (b, v, q)
    else:
        x, y = (a, v, u), (b, u, v)
    tx, ty = corridor_ranges(travel, x, y, 1)
    if tx < 1 or ty < 1:
        return None
    if not _visits_by(pa, x[1], tx) or not _visits_by(pb, y[1], ty):
        return None
    return [(a, [(NEG_RANGE, a, x[1], 1, tx)]), (b, [(NEG_RANGE, b, y[1], 1, ty)])]


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
        xy = graph.grid_xy
        if xy is not None:
            self.width, self.xs, self.ys = xy
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


# ---------------------------------------------------------------- generalised rectangles
#: Joint states a generalised-rectangle check may visit before it gives up (no split).
GR_BUDGET = 4000


def _reach_sets(
    adj: Sequence[Sequence[int]],
    n: int,
    entry: tuple[int, int],
    cons: AgentConstraints,
    bar: Barrier,
    dist_of: Callable[[int], Sequence[int]],
    cap: int,
) -> list[set[int]] | None:
    """Where a path under ``cons`` through ``entry`` can be, per time, on its way to ``bar``.

    ``out[tau - t_e]`` holds every vertex some path (waits allowed, vertex, edge and
    forbidden-from constraints obeyed; landmarks and finish bounds ignored, so a
    superset) can occupy at time ``tau`` and still reach a barrier vertex-time
    ``(u, T_u)`` with ``tau + dist(., u) <= T_u``, up to the last barrier time. None when
    more than ``cap`` vertex-times are involved.
    """
    ve, te = entry
    last = max(tt for _, tt in bar)
    tables = [(dist_of(u), tt) for u, tt in bar]
    slack: dict[int, int] = {}

    def ok(c: int, tau: int) -> bool:
        s = slack.get(c)
        if s is None:
            s = slack[c] = max(tt - d[c] for d, tt in tables)
        return tau <= s

    if not ok(ve, te):
        return [set() for _ in range(te, last + 1)]  # no barrier vertex-time in reach
    vc, ec, ff = cons.vertex, cons.edge, cons.forbid_from
    out = [{ve}]
    size = 1
    for tau in range(te + 1, last + 1):
        cur: set[int] = set()
        base = tau * n
        for p in out[-1]:
            for c in (p, *adj[p]):
                if c in cur or base + c in vc or not ok(c, tau):
                    continue
                if c != p and ec and (base + p) * n + c in ec:
                    continue
                if ff and c in ff and tau >= ff[c]:
                    continue
                cur.add(c)
        size += len(cur)
        if size > cap:
            return None
        out.append(cur)
    return out


def barriers_force_conflict(
    graph: Graph,
    entry_a: tuple[int, int],
    cons_a: AgentConstraints,
    bar_a: Barrier,
    entry_b: tuple[int, int],
    cons_b: AgentConstraints,
    bar_b: Barrier,
    budget: int = GR_BUDGET,
) -> bool:
    """Whether agents through ``entry_a`` and ``entry_b`` can never both break their barriers.

    ``entry = (vertex, time)`` is a vertex-time every path of the agent in the CT subtree
    passes (its start, or a landmark); ``cons_*`` the agents' constraints at the node (a
    descendant only adds to them, so its paths are among the ones searched here). A
    barrier is a list of ``(vertex, time)``. True when every pair of such paths (waits
    allowed) has a vertex or swap conflict, from the later entry on, before either is
    on a barrier vertex-time: a joint search over both agents' positions, pruned to
    positions that can still reach a barrier vertex-time (:func:`_reach_sets`). Then
    every conflict-free pair of paths avoids ``bar_a`` with a or ``bar_b`` with b, so
    the two barrier children exclude no conflict-free solution. False when some pair
    escapes or the search would exceed ``budget`` states (always safe: no split).

    Example
    -------
    >>> g = Graph.grid(3, 3)
    >>> v, free = g.vertex, AgentConstraints()
    >>> ea, eb = (v((0, 1)), 0), (v((1, 0)), 0)  # a enters west, b south
    >>> ba = [(v((2, 1)), 2), (v((2, 2)), 3)]  # a's east border, b's north border
    >>> bb = [(v((1, 2)), 2), (v((2, 2)), 3)]
    >>> barriers_force_conflict(g, ea, free, ba, eb, free, bb)
    True
    >>> barriers_force_conflict(g, ea, free, [(v((0, 2)), 1)], eb, free, bb)
    False
    """
    (_, ta), (_, tb) = entry_a, entry_b
    if not bar_a or not bar_b:
        return False
    t0 = max(ta, tb)
    if min(t for _, t in bar_a) < t0 or min(t for _, t in bar_b) < t0:
        return False  # one agent may be on its barrier before the other's entry
    adj, n = graph.adj, graph.n
    reach_a = _reach_sets(adj, n, entry_a, cons_a, bar_a, graph.dist_list, budget)
    reach_b = _reach_sets(adj, n, entry_b, cons_b, bar_b, graph.dist_list, budget)
    if reach_a is None or reach_b is None:
        return False
    hit_a: dict[int, set[int]] = {}
    hit_b: dict[int, set[int]] = {}
    for u, tt in bar_a:
        hit_a.setdefault(tt, set()).add(u)
    for u, tt in bar_b:
        hit_b.setdefault(tt, set()).add(u)
    end = min(ta + len(reach_a), tb + len(reach_b))  # first time past one agent's sets
    pairs = {(x, y) for x in reach_a[t0 - ta] for y in reach_b[t0 - tb] if x != y}
    seen = len(pairs)
    tau = t0
    while pairs:
        ha, hb = hit_a.get(tau, ()), hit_b.get(tau, ())
        if any(x in ha or y in hb for x, y in pairs):
            return False  # this pair is on a barrier without a conflict so far
        tau += 1
        if tau >= end:
            return False  # pragma: no cover - the last barrier time is in the sets
        ra, rb = reach_a[tau - ta], reach_b[tau - tb]
        nxt: set[tuple[int, int]] = set()
        for x, y in pairs:
            xs = [c for c in (x, *adj[x]) if c in ra]
            for y2 in (y, *adj[y]):
                if y2 not in rb:
                    continue
                for x2 in xs:
                    if x2 != y2 and not (x2 == y and y2 == x):
                        nxt.add((x2, y2))
        seen += len(nxt)
        if seen > budget:
            return False
        pairs = nxt
    return True


def _run(
    path: tuple[int, ...], t: int, xs: list[int], ys: list[int], sx: int, sy: int
) -> tuple[int, int]:
    """``(first, last)`` times of the staircase of ``path`` around ``t`` in frame ``(sx, sy)``:
    every step in ``[first, last]`` moves one cell in +x or +y of the frame (no waits)."""

    def fwd(p: int, q: int) -> bool:
        return sx * (xs[q] - xs[p]) + sy * (ys[q] - ys[p]) == 1 and p != q

    first = t
    while first > 0 and fwd(path[first - 1], path[first]):
        first -= 1
    last = t
    while last + 1 < len(path) and fwd(path[last], path[last + 1]):
        last += 1
    return first, last


def _latest_entry(start: int, cons: AgentConstraints, t: int) -> tuple[int, int]:
    """The latest vertex-time at or before ``t`` every path under ``cons`` passes."""
    return _entries(start, cons, t)[0]


def gr_candidates(
    rect: Rectangles,
    paths: list[tuple[int, ...]],
    a: int,
    b: int,
    v: int,
    t: int,
) -> list[tuple[bool, Barrier, Barrier]]:
    """Rectangle barriers of the lemma drawn on the agents' current paths (unverified).

    In each mirrored frame, the *virtual entry* of an agent is where its current path
    starts the staircase through the conflict ``(v, t)`` and its *virtual exit* where
    the staircase ends; :func:`rectangle_barriers` of those. Such entries are not
    certain for other paths of the subtree: :func:`generalized_rectangle_split` keeps a
    candidate only after :func:`barriers_force_conflict` proved it from real entries.

    Example
    -------
    >>> g = Graph.grid(5, 5)
    >>> v = g.vertex
    >>> pa = tuple(v((x, 2)) for x in range(5))  # west -> east
    >>> pb = tuple(v((2, y)) for y in range(5))  # south -> north
    >>> [(f, b1, b2) for f, b1, b2 in gr_candidates(Rectangles(g), [pa, pb], 0, 1, v((2, 2)), 2)]
    [(True, [(12, 2)], [(12, 2)])]
    """
    out: list[tuple[bool, Barrier, Barrier]] = []
    xs, ys = rect.xs, rect.ys
    pa, pb = paths[a], paths[b]
    if t >= len(pa) or t >= len(pb):
        return out
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        fa, la = _run(pa, t, xs, ys, sx, sy)
        fb, lb = _run(pb, t, xs, ys, sx, sy)
        if fa == t or fb == t or la == t or lb == t:
            continue  # a staircase must pass through the conflict
        for i, j, a_first in ((fa, fb, True), (fb, fa, False)):
            # The first agent must enter west-north of the second (frame coordinates):
            # move the entries forward along the staircases until it does.
            p1, p2 = (pa, pb) if a_first else (pb, pa)
            while i < t and sy * ys[p1[i]] < sy * ys[p2[j]]:
                i += 1
            while j < t and sx * xs[p2[j]] < sx * xs[p1[i]]:
                j += 1
            ea, eb = ((p1[i], i), (p2[j], j)) if a_first else ((p2[j], j), (p1[i], i))
            # Exits: where the staircases end, or (a larger rectangle) the goals.
            for xa, xb in ((pa[la], pb[lb]), (pa[-1], pb[-1])):
                for cand in rectangle_barriers(rect, ea, eb, xa, xb, v):
                    if cand not in out:
                        out.append(cand)
    return out


def generalized_rectangle_split(
    rect: Rectangles,
    starts: list[int],
    cons: list[AgentConstraints],
    paths: list[tuple[int, ...]],
    a: int,
    b: int,
    v: int,
    t: int,
    key: Callable[[list[tuple[int, list[Constraint]]]], int] | None = None,
) -> list[tuple[int, list[Constraint]]] | None:
    """Barrier children for a vertex conflict in a rectangle the agents enter anywhere.

    The plain rule (:func:`rectangle_split`) needs entries every path of the subtree
    passes (starts, landmarks) on the rectangle's anti-diagonal. Here the rectangle is
    drawn where the current paths run as staircases through the conflict
    (:func:`gr_candidates`), e.g. from a room's doors; its barrier vertex-times that
    only a shortest path from the agent's real entry reaches are kept, and the pair is
    used only if :func:`barriers_force_conflict` proves that two such prefixes always
    collide -- so the two children exclude no conflict-free solution (optimality kept)
    -- and both current paths break their barrier (both children replan). Without
    ``key`` the first such split is returned; with it, the one of smallest ``key``
    (e.g. the split's class: 0 when both children must cost more), the first 0 at once.

    Example
    -------
    >>> g = Graph.grid(6, 6, obstacles=[(1, 4), (2, 4)])  # a wall north of row 3
    >>> v, free = g.vertex, AgentConstraints()
    >>> pa = tuple(v(c) for c in [(0, 4), (0, 3), (1, 3), (2, 3), (3, 3), (4, 3), (5, 3)])
    >>> pb = tuple(v(c) for c in [(2, 0), (3, 0), (3, 1), (3, 2), (3, 3), (3, 4), (3, 5)])
    >>> args = ([pa[0], pb[0]], [free, free], [pa, pb], 0, 1, v((3, 3)), 4)
    >>> rectangle_split(Rectangles(g), args[0], [pa[-1], pb[-1]], *args[1:]) is None  # starts
    True
    >>> res = generalized_rectangle_split(Rectangles(g), *args)
    >>> [(x, [(g.location(c[2]), c[4]) for c in cs]) for x, cs in res]
    [(0, [((3, 3), 4)]), (1, [((2, 3), 3), ((3, 3), 4)])]
    """
    if not rect.enabled or t < 1:
        return None
    pa, pb = paths[a], paths[b]
    best: tuple[int, list[tuple[int, list[Constraint]]]] | None = None
    for a_first, b1, b2 in gr_candidates(rect, paths, a, b, v, t):
        if any(tt <= 0 for _, tt in b1) or any(tt <= 0 for _, tt in b2):
            continue  # time 0 is never constrained by the low level
        i1, i2 = (a, b) if a_first else (b, a)
        p1, p2 = (pa, pb) if a_first else (pb, pa)
        if not any(_at(p1, tt) == u for u, tt in b1):
            continue
        if not any(_at(p2, tt) == u for u, tt in b2):
            continue
        e1 = _latest_entry(starts[i1], cons[i1], min(tt for _, tt in b1))
        e2 = _latest_entry(starts[i2], cons[i2], min(tt for _, tt in b2))
        if not barriers_force_conflict(rect.graph, e1, cons[i1], b1, e2, cons[i2], b2):
            continue
        res = [
            (i1, [(NEG_V, i1, u, -1, tt) for u, tt in b1]),
            (i2, [(NEG_V, i2, u, -1, tt) for u, tt in b2]),
        ]
        k = key(res) if key is not None else 0
        if best is None or k < best[0]:
            best = (k, res)
        if k == 0:
            break
    return best[1] if best is not None else None
