"""Schedules of an STN by graph algorithms.

* Lower bounds only (the usual MAPF-POST network): the TPG is a DAG, and the earliest
  time of every node is its longest path from X0, computed in topological order in
  O(V + E). The passes run "wave by wave" (all nodes whose predecessors are done at
  once) with numpy, so the Python overhead is per wave, not per node.
* Upper bounds or deadlines: Bellman-Ford on the distance graph (``u -> v`` weight
  ``ub``, ``v -> u`` weight ``-lb``; X0 arcs from the node bounds). A negative cycle
  means the STN is inconsistent; :class:`InconsistentSTNError` names its nodes.

Latest times come from a backward pass against the makespan (every robot must have
arrived by then; deadlines cap them further); slack = latest - earliest; the
critical path is a chain of tight arcs from a start node to the robot that
finishes last.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.schedule.stn import STN

log = logging.getLogger(__name__)

#: Tolerance for "tight" arcs and bound checks (seconds).
TOL = 1e-7


class InconsistentSTNError(InputError):
    """The STN has no solution (a negative cycle in its distance graph)."""

    def __init__(self, message: str, cycle: list[str]) -> None:
        super().__init__(message)
        self.cycle = cycle


@dataclass(frozen=True, eq=False)
class GraphSolution:
    """Earliest and latest node times, slack, makespan and a critical path."""

    earliest: np.ndarray
    latest: np.ndarray
    makespan: float
    critical_path: tuple[int, ...]

    @property
    def slack(self) -> np.ndarray:
        return self.latest - self.earliest


def _csr(n: int, key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arc ids grouped by ``key`` (CSR): ``order[ptr[v]:ptr[v+1]]`` are v's arcs."""
    order = np.argsort(key, kind="stable")
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(key, minlength=n), out=ptr[1:])
    return order, ptr


def _gather(order: np.ndarray, ptr: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Concatenated arc ids of ``nodes`` from a CSR grouping."""
    starts = ptr[nodes]
    lens = ptr[nodes + 1] - starts
    total = int(lens.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    offs = np.repeat(starts - np.concatenate(([0], np.cumsum(lens)[:-1])), lens)
    return order[offs + np.arange(total)]


@dataclass(frozen=True, eq=False)
class TopoOrder:
    """Kahn's waves of a DAG and its arcs grouped by the wave of their source.

    ``arcs[arc_ptr[k]:arc_ptr[k + 1]]`` are the arcs leaving wave ``k``; the forward
    and backward passes read them as contiguous slices.
    """

    waves: list[np.ndarray]
    arcs: np.ndarray
    arc_ptr: np.ndarray


def topo_order(n: int, src: np.ndarray, dst: np.ndarray) -> TopoOrder:
    """Kahn's algorithm in waves: wave k holds the nodes whose longest chain of
    predecessors has k arcs. Raises :class:`InputError` on a cycle."""
    indeg = np.bincount(dst, minlength=n).astype(np.int64)
    order, ptr = _csr(n, src)
    frontier = np.flatnonzero(indeg == 0)
    waves = []
    wave_arcs = []
    done = 0
    while frontier.size:
        waves.append(frontier)
        done += frontier.size
        arcs = _gather(order, ptr, frontier)
        wave_arcs.append(arcs)
        if not arcs.size:
            break
        d = dst[arcs]
        np.subtract.at(indeg, d, 1)
        zero = d[indeg[d] == 0]
        frontier = np.unique(zero) if zero.size > 1 else zero
    if done != n:
        raise InputError(
            f"the temporal plan graph has a cycle ({n - done} nodes on or behind it); "
            "the plan is not a valid MAPF plan"
        )
    sizes = np.array([len(a) for a in wave_arcs], dtype=np.int64)
    arc_ptr = np.zeros(len(wave_arcs) + 1, dtype=np.int64)
    np.cumsum(sizes, out=arc_ptr[1:])
    arcs_all = np.concatenate(wave_arcs) if wave_arcs else np.zeros(0, dtype=np.int64)
    return TopoOrder(waves, arcs_all, arc_ptr)


def topological_waves(n: int, src: np.ndarray, dst: np.ndarray) -> list[np.ndarray]:
    """The waves of :func:`topo_order`.

    Example
    -------
    >>> [w.tolist() for w in topological_waves(4, np.array([0, 1, 0]), np.array([1, 2, 2]))]
    [[0, 3], [1], [2]]
    """
    return topo_order(n, src, dst).waves


def earliest_times(stn: STN, topo: TopoOrder | None = None) -> np.ndarray:
    """Earliest time of every node (longest paths from X0), lower bounds only.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule.tpg import build_tpg
    >>> from hierplan_opt.schedule.stn import build_stn
    >>> g = Graph.grid(3, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(2, 0)])
    >>> earliest_times(build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2]])))).tolist()
    [0.0, 1.0, 2.0]
    """
    if topo is None:
        topo = topo_order(stn.num_nodes, stn.arc_src, stn.arc_dst)
    src = stn.arc_src[topo.arcs]
    dst = stn.arc_dst[topo.arcs]
    lb = stn.lb[topo.arcs]
    ptr = topo.arc_ptr.tolist()
    t = stn.release.astype(float).copy()
    for k in range(len(ptr) - 1):
        a, b = ptr[k], ptr[k + 1]
        if b > a:
            np.maximum.at(t, dst[a:b], t[src[a:b]] + lb[a:b])
    return t


def latest_times(stn: STN, horizon: float, topo: TopoOrder | None = None) -> np.ndarray:
    """Latest time of every node such that every robot arrives by ``horizon``
    (and by its deadline), lower bounds only."""
    if topo is None:
        topo = topo_order(stn.num_nodes, stn.arc_src, stn.arc_dst)
    src = stn.arc_src[topo.arcs]
    dst = stn.arc_dst[topo.arcs]
    lb = stn.lb[topo.arcs]
    ptr = topo.arc_ptr.tolist()
    t = stn.deadline.astype(float).copy()
    finals = stn.tpg.final_nodes()
    t[finals] = np.minimum(t[finals], horizon)
    for k in range(len(ptr) - 2, -1, -1):
        a, b = ptr[k], ptr[k + 1]
        if b > a:
            np.minimum.at(t, src[a:b], t[dst[a:b]] - lb[a:b])
    return t


def critical_path(stn: STN, earliest: np.ndarray) -> tuple[int, ...]:
    """A chain of tight arcs ending at the node that finishes last, from its start.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule.tpg import build_tpg
    >>> from hierplan_opt.schedule.stn import build_stn
    >>> g = Graph.grid(3, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(2, 0)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2]])))
    >>> critical_path(stn, earliest_times(stn))
    (0, 1, 2)
    """
    finals = stn.tpg.final_nodes()
    v = int(finals[int(np.argmax(earliest[finals]))])
    order, ptr = _csr(stn.num_nodes, stn.arc_dst)
    path = [v]
    while True:
        arcs = order[ptr[v] : ptr[v + 1]]
        if not arcs.size:
            break
        u_all = stn.arc_src[arcs]
        slack = earliest[v] - (earliest[u_all] + stn.lb[arcs])
        k = int(np.argmin(np.abs(slack)))
        if abs(slack[k]) > TOL * max(1.0, abs(earliest[v])):
            break  # v is held by its release time only
        v = int(u_all[k])
        path.append(v)
    return tuple(reversed(path))


def solve_graph(stn: STN) -> GraphSolution:
    """Earliest schedule, latest times, makespan and critical path of ``stn``.

    Networks with upper bounds or deadlines go through Bellman-Ford.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule.tpg import build_tpg
    >>> from hierplan_opt.schedule.stn import build_stn
    >>> g = Graph.grid(3, 2)
    >>> inst = Instance.mapf(g, [(0, 0), (2, 1)], [(2, 0), (1, 1)])
    >>> plan = Plan.from_paths([[0, 1, 2], [5, 4]])
    >>> sol = solve_graph(build_stn(inst, build_tpg(inst, plan)))
    >>> sol.makespan, sol.slack.tolist(), sol.critical_path
    (2.0, [0.0, 0.0, 0.0, 0.0, 1.0], (0, 1, 2))
    """
    if stn.has_upper_bounds:
        earliest, latest_fn = bellman_ford(stn)
        finals = stn.tpg.final_nodes()
        makespan = float(earliest[finals].max())
        latest = latest_fn(makespan)
    else:
        topo = topo_order(stn.num_nodes, stn.arc_src, stn.arc_dst)
        earliest = earliest_times(stn, topo)
        finals = stn.tpg.final_nodes()
        makespan = float(earliest[finals].max())
        latest = latest_times(stn, makespan, topo)
    return GraphSolution(earliest, latest, makespan, critical_path(stn, earliest))


# ---------------------------------------------------------------------- Bellman-Ford
X0 = -1  # the start event in the networkx graphs below


def _distance_graph(stn: STN, reverse: bool, horizon: float | None = None):  # noqa: ANN202
    """The STN's distance graph (``reverse``: all arcs flipped) as a networkx DiGraph.

    Parallel arcs keep the tightest weight.
    """
    import networkx as nx

    G = nx.DiGraph()
    G.add_node(X0)
    G.add_nodes_from(range(stn.num_nodes))

    def add(a: int, b: int, w: float) -> None:
        if reverse:
            a, b = b, a
        if G.has_edge(a, b):
            if w < G[a][b]["weight"]:
                G[a][b]["weight"] = w
        else:
            G.add_edge(a, b, weight=w)

    for u, v, lo, hi in zip(
        stn.arc_src.tolist(), stn.arc_dst.tolist(), stn.lb.tolist(), stn.ub.tolist(), strict=True
    ):
        add(v, u, -lo)
        if np.isfinite(hi):
            add(u, v, hi)
    deadline = stn.deadline.copy()
    if horizon is not None:
        finals = stn.tpg.final_nodes()
        deadline[finals] = np.minimum(deadline[finals], horizon)
    for v, (r, d) in enumerate(zip(stn.release.tolist(), deadline.tolist(), strict=True)):
        add(v, X0, -r)
        if np.isfinite(d):
            add(X0, v, d)
    return G


def _name(stn: STN, v: int) -> str:
    return "X0 (time 0)" if v == X0 else stn.tpg.label(v)


def bellman_ford(stn: STN):  # noqa: ANN201
    """Earliest times of a general STN, and a function ``horizon -> latest times``.

    Raises :class:`InconsistentSTNError` naming a negative cycle when no schedule
    meets every bound.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule.tpg import build_tpg
    >>> from hierplan_opt.schedule.stn import build_stn
    >>> g = Graph.grid(3, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(2, 0)])
    >>> tpg = build_tpg(inst, Plan.from_paths([[0, 1, 2]]))
    >>> earliest, _ = bellman_ford(build_stn(inst, tpg, deadlines={"agent0": 5}))
    >>> earliest.tolist()
    [0.0, 1.0, 2.0]
    >>> bellman_ford(build_stn(inst, tpg, deadlines={"agent0": 1.5}))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hierplan_opt.schedule.solve_graph.InconsistentSTNError: the STN is inconsistent ...
    """
    import networkx as nx

    H = _distance_graph(stn, reverse=True)
    try:
        dist = nx.single_source_bellman_ford_path_length(H, X0)
    except nx.NetworkXUnbounded:
        cycle = nx.find_negative_cycle(H, X0)
        # Arcs of H point forward in time (u -> v for t_v >= t_u + lb): start at X0.
        if X0 in cycle[:-1]:
            k = cycle.index(X0)
            cycle = cycle[k:-1] + cycle[:k] + [X0]
        names = [_name(stn, v) for v in cycle]
        total = sum(H[a][b]["weight"] for a, b in zip(cycle[:-1], cycle[1:], strict=True))
        raise InconsistentSTNError(
            "the STN is inconsistent (the bounds cannot all hold; a deadline or upper "
            f"bound is too tight by {-total:.6g} s): negative cycle " + " -> ".join(names),
            names,
        ) from None
    n = stn.num_nodes
    earliest = np.array([0.0 - dist[v] for v in range(n)], dtype=float) + 0.0

    def latest(horizon: float) -> np.ndarray:
        D = _distance_graph(stn, reverse=False, horizon=horizon)
        d = nx.single_source_bellman_ford_path_length(D, X0)
        return np.array([d.get(v, np.inf) for v in range(n)], dtype=float)

    return earliest, latest
