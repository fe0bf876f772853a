"""Time-expanded flow networks for anonymous MAPF and the team level of CBM.

The network for one team and horizon ``T`` (Yu & LaValle 2013):

* every vertex ``v`` and timestep ``t = 0..T`` becomes two nodes ``in(v, t)`` and
  ``out(v, t)`` joined by a capacity-1 arc, so at most one robot occupies ``v`` at ``t``;
* a wait arc ``out(v, t) -> in(v, t + 1)``;
* every undirected edge ``{u, v}`` and step ``t`` gets a *swap gadget*: the arcs
  ``out(u, t) -> a`` and ``out(v, t) -> a``, one shared capacity-1 arc ``a -> b`` and
  ``b -> in(v, t + 1)``, ``b -> in(u, t + 1)``. At most one robot crosses the edge per
  step, so two robots never swap. (The gadget also allows ``u -> a -> b -> u``, which is
  just a wait.) An arc of a directed graph whose reverse is not an arc needs no gadget
  and becomes one arc ``out(u, t) -> in(v, t + 1)``;
* a super source feeds ``in(s, 0)`` of every start, and ``out(g, T)`` of every target
  drains into a super sink.

An integral flow of value K is a set of K collision-free paths that end on distinct
targets at time ``T``; a robot that reached its target earlier waits there, and
because its waiting occupies ``in/out(g, t)`` it blocks the target for everybody.

Nodes ``(v, t)`` that no robot can use are pruned: a robot can be at ``v`` at ``t``
only if some start is within ``t`` steps of ``v`` and some target within ``T - t``.

Everything is built with numpy and handed to OR-Tools' ``SimpleMaxFlow`` /
``SimpleMinCostFlow`` in one call; this module writes no flow algorithm of its own.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from ortools.graph.python import max_flow, min_cost_flow

from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.timer import Deadline

#: Arc kinds, stored per arc so that costs and constraints can be applied by mask.
VERTEX, WAIT, ENTER, SHARED, LEAVE, DIRECT, SOURCE, SINK = range(8)


def multi_source_bfs(graph: Graph, sources: Iterable[int], *, reverse: bool = False) -> np.ndarray:
    """Timestep distance from the nearest of ``sources`` to every vertex.

    With ``reverse=True`` the distance is measured *to* the nearest source (on a
    directed graph that follows arcs backwards). Unreachable vertices get
    :data:`~hierplan_opt.core.graph.UNREACHABLE`.

    Example
    -------
    >>> g = Graph.grid(4, 1)
    >>> multi_source_bfs(g, [0, 3]).tolist()
    [0, 1, 1, 0]
    """
    adj = graph.reverse_adj if reverse else graph.adj
    dist = [UNREACHABLE] * graph.n
    queue: deque[int] = deque()
    for s in sources:
        if dist[s] != 0:
            dist[s] = 0
            queue.append(s)
    while queue:
        u = queue.popleft()
        du = dist[u] + 1
        for w in adj[u]:
            if dist[w] > du:
                dist[w] = du
                queue.append(w)
    return np.array(dist, dtype=np.int64)


@dataclass
class _EdgeSets:
    """Edges of a graph split into swap-gadget pairs and one-way arcs."""

    pair_u: np.ndarray  # undirected pairs u < v (both directions are arcs)
    pair_v: np.ndarray
    one_u: np.ndarray  # arcs whose reverse is not an arc
    one_v: np.ndarray


_EDGE_CACHE: dict[int, tuple[Graph, _EdgeSets]] = {}


def _edge_sets(graph: Graph) -> _EdgeSets:
    hit = _EDGE_CACHE.get(id(graph))
    if hit is not None and hit[0] is graph:
        return hit[1]
    src = np.repeat(np.arange(graph.n, dtype=np.int64), np.diff(graph.indptr))
    dst = graph.indices.astype(np.int64)
    if graph.directed:
        codes = set((src * graph.n + dst).tolist())
        rev = np.array(
            [int(d) * graph.n + int(s) in codes for s, d in zip(src, dst, strict=True)], dtype=bool
        )
    else:
        rev = np.ones(len(src), dtype=bool)
    pair = rev & (src < dst)
    one = ~rev
    es = _EdgeSets(src[pair], dst[pair], src[one], dst[one])
    if len(_EDGE_CACHE) > 32:
        _EDGE_CACHE.clear()
    _EDGE_CACHE[id(graph)] = (graph, es)
    return es


class TeamDistances:
    """Distances of one team, computed once and reused for every horizon.

    ``from_start[i, v]`` is the distance from start ``i`` to ``v``, ``to_target[j, v]``
    the distance from ``v`` to target ``j``, ``pair[i, j]`` from start ``i`` to target
    ``j``.

    Example
    -------
    >>> td = TeamDistances(Graph.grid(3, 1), [0], [2])
    >>> td.pair.tolist(), td.active(2).astype(int).tolist()
    ([[2]], [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    """

    def __init__(self, graph: Graph, starts: Sequence[int], targets: Sequence[int]) -> None:
        self.starts = [int(s) for s in starts]
        self.targets = [int(g) for g in targets]
        self.to_target = np.stack(graph.precompute_distances(self.targets)).astype(np.int64)
        if not graph.directed:
            graph.precompute_distances(self.starts)  # one batch
        self.from_start = np.stack([graph.dist_from(s) for s in self.starts]).astype(np.int64)
        self.pair = self.to_target[:, self.starts].T.copy()

    def active(self, horizon: int) -> np.ndarray:
        """``active[t, v]``: some robot can be at ``v`` at ``t`` and still end on time.

        Robot ``i`` can be at ``v`` at ``t`` only if ``dist(s_i, v) <= t`` and
        ``dist(v, g_j) <= T - t`` for a target ``g_j`` it can reach within ``T``. This
        is exact per robot, so no feasible flow uses a pruned node, and it is much
        tighter than "near some start and near some target" when the team is spread.
        """
        T = int(horizon)
        n = self.to_target.shape[1]
        out = np.zeros((T + 1, n), dtype=bool)
        ts = np.arange(T + 1, dtype=np.int64)[:, None]
        for i in range(len(self.starts)):
            allowed = self.pair[i] <= T
            if not allowed.any():
                continue
            lo = self.from_start[i]
            hi = self.to_target[allowed].min(axis=0)
            cols = np.flatnonzero(lo + hi <= T)
            if len(cols) == 0:
                continue
            out[:, cols] |= (lo[cols][None, :] <= ts) & (hi[cols][None, :] <= T - ts)
        return out


class TeamFlowNetwork:
    """The time-expanded flow network of one team for one horizon.

    Parameters
    ----------
    graph
        The roadmap or grid.
    starts, targets
        The team's start vertices and its targets (equally many).
    horizon
        The last timestep ``T``; every robot is on a distinct target at ``T``.
    distances
        The team's :class:`TeamDistances` (for pruning); computed when omitted.

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> net = TeamFlowNetwork(g, [0], [2], horizon=2)
    >>> net.max_flow()
    1
    >>> TeamFlowNetwork(g, [0], [2], horizon=1).max_flow()
    0
    """

    def __init__(
        self,
        graph: Graph,
        starts: Sequence[int],
        targets: Sequence[int],
        horizon: int,
        *,
        distances: TeamDistances | None = None,
    ) -> None:
        self.graph = graph
        self.starts = [int(s) for s in starts]
        self.targets = [int(g) for g in targets]
        self.horizon = T = int(horizon)
        n = graph.n
        if distances is None:
            distances = TeamDistances(graph, self.starts, self.targets)
        # active[t, v]: a robot can be at v at t.
        active = distances.active(T)
        ids = np.full((T + 1, n), -1, dtype=np.int64)
        nz = np.flatnonzero(active.reshape(-1))
        ids.reshape(-1)[nz] = np.arange(len(nz), dtype=np.int64)
        self.num_vertex_nodes = nv = len(nz)
        self.node_t = (nz // n).astype(np.int64)
        self.node_v = (nz % n).astype(np.int64)
        self._ids = ids

        tails: list[np.ndarray] = []
        heads: list[np.ndarray] = []
        kinds: list[np.ndarray] = []
        # Extra per-arc data: the (v, t) an arc enters or the (u, v, t) move it makes.
        arc_u: list[np.ndarray] = []
        arc_v: list[np.ndarray] = []
        arc_t: list[np.ndarray] = []

        def add(tl, hd, kind, u, v, t) -> None:
            tails.append(tl)
            heads.append(hd)
            kinds.append(np.full(len(tl), kind, dtype=np.int8))
            arc_u.append(u)
            arc_v.append(v)
            arc_t.append(t)

        # Vertex arcs (arc index == vertex-node id, used by constraints and costs).
        vid = np.arange(nv, dtype=np.int64)
        add(2 * vid, 2 * vid + 1, VERTEX, self.node_v, self.node_v, self.node_t)
        # Wait arcs.
        w_t, w_v = np.nonzero(active[:-1] & active[1:])
        add(
            2 * ids[w_t, w_v] + 1,
            2 * ids[w_t + 1, w_v],
            WAIT,
            w_v,
            w_v,
            w_t,
        )
        next_node = 2 * nv + 2
        self.source = 2 * nv
        self.sink = 2 * nv + 1
        es = _edge_sets(graph)
        # Swap gadgets for undirected pairs.
        if len(es.pair_u) and T > 0:
            pu, pv = es.pair_u, es.pair_v
            d1 = active[:-1][:, pu] & active[1:][:, pv]  # u -> v at t
            d2 = active[:-1][:, pv] & active[1:][:, pu]  # v -> u at t
            g_t, g_e = np.nonzero(d1 | d2)
            ng = len(g_t)
            a = next_node + 2 * np.arange(ng, dtype=np.int64)
            b = a + 1
            next_node += 2 * ng
            gu, gv = pu[g_e], pv[g_e]
            f1 = d1[g_t, g_e]
            f2 = d2[g_t, g_e]
            add(a, b, SHARED, gu, gv, g_t)
            # u -> v direction
            add(2 * ids[g_t[f1], gu[f1]] + 1, a[f1], ENTER, gu[f1], gv[f1], g_t[f1])
            add(b[f1], 2 * ids[g_t[f1] + 1, gv[f1]], LEAVE, gu[f1], gv[f1], g_t[f1])
            # v -> u direction
            add(2 * ids[g_t[f2], gv[f2]] + 1, a[f2], ENTER, gv[f2], gu[f2], g_t[f2])
            add(b[f2], 2 * ids[g_t[f2] + 1, gu[f2]], LEAVE, gv[f2], gu[f2], g_t[f2])
        # One-way arcs of directed graphs.
        if len(es.one_u) and T > 0:
            ou, ov = es.one_u, es.one_v
            d = active[:-1][:, ou] & active[1:][:, ov]
            o_t, o_e = np.nonzero(d)
            add(
                2 * ids[o_t, ou[o_e]] + 1,
                2 * ids[o_t + 1, ov[o_e]],
                DIRECT,
                ou[o_e],
                ov[o_e],
                o_t,
            )
        # Source and sink arcs (only where the node survived pruning).
        s_arr = np.array([s for s in self.starts if ids[0, s] >= 0], dtype=np.int64)
        g_arr = np.array([g for g in self.targets if ids[T, g] >= 0], dtype=np.int64)
        add(
            np.full(len(s_arr), self.source, dtype=np.int64),
            2 * ids[0, s_arr],
            SOURCE,
            s_arr,
            s_arr,
            np.zeros(len(s_arr), dtype=np.int64),
        )
        add(
            2 * ids[T, g_arr] + 1,
            np.full(len(g_arr), self.sink, dtype=np.int64),
            SINK,
            g_arr,
            g_arr,
            np.full(len(g_arr), T, dtype=np.int64),
        )
        self.num_nodes = next_node
        self.tails = np.concatenate(tails)
        self.heads = np.concatenate(heads)
        self.kinds = np.concatenate(kinds)
        self.arc_u = np.concatenate(arc_u).astype(np.int64)
        self.arc_v = np.concatenate(arc_v).astype(np.int64)
        self.arc_t = np.concatenate(arc_t).astype(np.int64)
        self.capacities = np.ones(len(self.tails), dtype=np.int64)
        # Unit cost per move: entering a gadget or a one-way arc.
        self.move_cost = ((self.kinds == ENTER) | (self.kinds == DIRECT)).astype(np.int64)

    # ------------------------------------------------------------------ sizes
    @property
    def num_arcs(self) -> int:
        return len(self.tails)

    def node_id(self, v: int, t: int) -> int:
        """Vertex-node id of ``(v, t)``, or -1 when pruned or outside the horizon."""
        if not 0 <= t <= self.horizon:
            return -1
        return int(self._ids[t, v])

    # ------------------------------------------------------------------ lookups
    def vertex_arcs(self, v: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Arc indices of the vertex arcs of ``(v[i], t[i])`` (pruned pairs dropped)."""
        v = np.asarray(v, dtype=np.int64).reshape(-1)
        t = np.asarray(t, dtype=np.int64).reshape(-1)
        ok = (t >= 0) & (t <= self.horizon)
        ids = self._ids[t[ok], v[ok]]
        return ids[ids >= 0]

    def move_arcs(self, u: np.ndarray, v: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Arc indices of the moves ``u[i] -> v[i]`` at ``t[i]`` (missing ones dropped).

        That is the arc entering the move's swap gadget from ``u`` (or the one-way
        arc), so deleting it leaves the opposite direction usable.
        """
        keys, order = self._move_keys()
        q = self._key(
            np.asarray(u, dtype=np.int64).reshape(-1),
            np.asarray(v, dtype=np.int64).reshape(-1),
            np.asarray(t, dtype=np.int64).reshape(-1),
        )
        if len(keys) == 0 or len(q) == 0:
            return np.zeros(0, dtype=np.int64)
        pos = np.minimum(np.searchsorted(keys, q), len(keys) - 1)
        hit = keys[pos] == q
        return order[pos[hit]]

    def _key(self, u: np.ndarray, v: np.ndarray, t: np.ndarray) -> np.ndarray:
        n = self.graph.n
        return (t * n + u) * n + v

    def _move_keys(self) -> tuple[np.ndarray, np.ndarray]:
        if not hasattr(self, "_mk"):
            m = np.flatnonzero((self.kinds == ENTER) | (self.kinds == DIRECT))
            keys = self._key(self.arc_u[m], self.arc_v[m], self.arc_t[m])
            order = np.argsort(keys, kind="stable")
            self._mk = (keys[order], m[order])
        return self._mk

    # ------------------------------------------------------------------ constraints
    def blocked_capacities(
        self,
        vertex_blocks: Iterable[tuple[int, int]] = (),
        edge_blocks: Iterable[tuple[int, int, int]] = (),
    ) -> np.ndarray:
        """Arc capacities with the nodes ``(v, t)`` and moves ``(u, v, t)`` deleted.

        A deleted move ``u -> v`` at ``t`` removes the arc that enters its gadget from
        ``u`` (or the one-way arc), so the opposite direction stays usable.
        """
        caps = self.capacities.copy()
        vb = np.array(list(vertex_blocks), dtype=np.int64).reshape(-1, 2)
        if len(vb):
            caps[self.vertex_arcs(vb[:, 0], vb[:, 1])] = 0
        eb = np.array(list(edge_blocks), dtype=np.int64).reshape(-1, 3)
        if len(eb):
            caps[self.move_arcs(eb[:, 0], eb[:, 1], eb[:, 2])] = 0
        return caps

    def cost_array(
        self,
        *,
        vertex_hits: tuple[np.ndarray, np.ndarray] | None = None,
        move_hits: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        sink_hits: np.ndarray | None = None,
        weight: int = 1,
        move_unit: int = 1,
    ) -> np.ndarray:
        """Arc costs: ``move_unit`` per move plus ``weight`` per listed hit.

        ``vertex_hits = (v, t)`` charges occupying ``v[i]`` at ``t[i]`` (repeat a pair
        to charge it twice), ``move_hits = (u, v, t)`` charges moving ``u -> v`` at
        ``t``, ``sink_hits`` charges ending on the listed targets.
        """
        cost = self.move_cost * move_unit
        if vertex_hits is not None:
            np.add.at(cost, self.vertex_arcs(*vertex_hits), weight)
        if move_hits is not None:
            np.add.at(cost, self.move_arcs(*move_hits), weight)
        if sink_hits is not None and len(sink_hits):
            sinks = np.flatnonzero(self.kinds == SINK)
            counts = np.bincount(np.asarray(sink_hits, dtype=np.int64), minlength=self.graph.n)
            cost[sinks] += weight * counts[self.arc_u[sinks]]
        return cost

    # ------------------------------------------------------------------ solving
    def max_flow(self, capacities: np.ndarray | None = None) -> int:
        """Value of the maximum flow (how many robots can reach distinct targets)."""
        return self.solve_max_flow(capacities)[0]

    def solve_max_flow(self, capacities: np.ndarray | None = None) -> tuple[int, np.ndarray]:
        """A maximum flow: ``(value, flow per arc)``."""
        caps = self.capacities if capacities is None else capacities
        mf = max_flow.SimpleMaxFlow()
        mf.add_arcs_with_capacity(_arr(self.tails), _arr(self.heads), _arr(caps))
        status = mf.solve(self.source, self.sink)
        if status != mf.OPTIMAL:
            raise RuntimeError(f"OR-Tools max flow failed with status {status}")
        return int(mf.optimal_flow()), np.asarray(mf.flows(_arr(np.arange(self.num_arcs))))

    def min_cost_flow(
        self, amount: int, costs: np.ndarray, capacities: np.ndarray | None = None
    ) -> tuple[int, np.ndarray] | None:
        """A min-cost flow of value ``amount``: ``(cost, flows)`` or None if infeasible."""
        caps = self.capacities if capacities is None else capacities
        mcf = min_cost_flow.SimpleMinCostFlow()
        mcf.add_arcs_with_capacity_and_unit_cost(
            _arr(self.tails), _arr(self.heads), _arr(caps), _arr(costs)
        )
        supplies = np.zeros(self.num_nodes, dtype=np.int64)
        supplies[self.source] = amount
        supplies[self.sink] = -amount
        mcf.set_nodes_supplies(_arr(np.arange(self.num_nodes, dtype=np.int32)), _arr(supplies))
        status = mcf.solve()
        if status != mcf.OPTIMAL:
            return None
        return int(mcf.optimal_cost()), np.asarray(mcf.flows(_arr(np.arange(self.num_arcs))))

    def extract_paths(self, flows: np.ndarray) -> list[list[int]]:
        """Vertex paths (index = timestep, length ``T + 1``) in the order of ``starts``.

        Follows the unit flow from each start's source arc to the sink.
        """
        used = np.flatnonzero(flows > 0)
        nxt: dict[int, int] = dict(
            zip(self.tails[used].tolist(), self.heads[used].tolist(), strict=True)
        )
        nv2 = 2 * self.num_vertex_nodes
        node_v = self.node_v.tolist()
        paths: list[list[int]] = []
        for s in self.starts:
            i = self.node_id(s, 0)
            node = 2 * i
            path = [s]
            if node not in nxt:
                raise RuntimeError(f"no flow leaves start {s}")
            node = nxt[node]  # out(s, 0)
            while True:
                node = nxt[node]
                while node >= nv2:  # gadget nodes
                    if node == self.sink:
                        break
                    node = nxt[node]
                if node == self.sink:
                    break
                # node is in(v, t); record v and step to out(v, t).
                path.append(node_v[node // 2])
                node = nxt[node]
            paths.append(path)
        return paths


def _arr(a: np.ndarray) -> Any:
    """An integer array for OR-Tools' flow classes, whose stubs spell the dtype where
    numpy's stubs put the shape (``ndarray[int32, ...]``); the values pass as they are."""
    return a


def conflict_free_paths(
    graph: Graph,
    starts: Sequence[int],
    targets: Sequence[int],
    horizon: int,
) -> list[list[int]] | None:
    """Collision-free paths of one team with makespan at most ``horizon``, or None.

    Minimises the total number of moves among all plans within the horizon.

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> conflict_free_paths(g, [0, 1], [1, 2], 0) is None
    True
    >>> conflict_free_paths(g, [0, 1], [1, 2], 1)
    [[0, 1], [1, 2]]
    """
    net = TeamFlowNetwork(graph, starts, targets, horizon)
    res = net.min_cost_flow(len(starts), net.move_cost)
    if res is None:
        return None
    return net.extract_paths(res[1])


def smallest_horizon(
    feasible: Callable[[int], bool],
    lower: int,
    *,
    deadline: Deadline | None = None,
    strategy: str = "doubling",
    upper: int | None = None,
) -> tuple[int | None, int]:
    """The smallest ``T >= lower`` with ``feasible(T)``, assuming feasibility is monotone.

    ``strategy="linear"`` tries ``lower, lower + 1, ...``; ``"doubling"`` tries
    ``lower, lower + 1, lower + 3, lower + 7, ...`` and then bisects between the last
    failure and the first success. Returns ``(T, largest_infeasible + 1)``; ``T`` is
    None when the deadline expired or ``upper`` was passed without success, and the
    second entry is then the proven lower bound.

    Example
    -------
    >>> smallest_horizon(lambda t: t >= 13, 2)
    (13, 13)
    >>> smallest_horizon(lambda t: t >= 13, 2, strategy="linear")
    (13, 13)
    """
    if strategy not in ("doubling", "linear"):
        raise ValueError(f"unknown horizon search strategy {strategy!r}")
    fail = lower - 1  # largest horizon known infeasible
    step = 1
    t = lower
    while True:
        if upper is not None and t > upper:
            return None, fail + 1
        if deadline is not None and deadline.expired():
            return None, fail + 1
        if feasible(t):
            ok = t
            break
        fail = t
        t = fail + step
        if strategy == "doubling":
            step *= 2
    while ok - fail > 1:
        if deadline is not None and deadline.expired():
            return None, fail + 1
        mid = (ok + fail) // 2
        if feasible(mid):
            ok = mid
        else:
            fail = mid
    return ok, ok
