"""Schedules of an STN by graph algorithms, with a tolerance, and incremental re-solves.

* **Earliest times** (the least solution): longest paths from X0. The lower-bound arcs
  form a DAG, so one pass in topological order, run "wave by wave" with numpy, gives
  them in ``O(V + E)``. An arc upper bound ``t_v - t_u <= ub`` may push ``t_u`` up to
  ``t_v - ub``; the pass then repeats (a label-correcting Bellman-Ford whose rounds are
  whole topological passes). A consistent STN settles after at most (number of finite
  arc upper bounds + 1) passes; if it does not, or a node ends after its deadline, the
  STN is inconsistent and :class:`InconsistentSTNError` names the negative cycle of its
  distance graph.
* **Latest times** (the greatest solution with every robot arrived by a horizon):
  the same passes backwards.
* **Tolerance**: a bound counts as broken only by more than :data:`TOL` (relative to the
  times involved). Sums of inexact speeds (0.7, 1/3, ...) leave round-off of a few ulp;
  it never turns a consistent STN into an "inconsistent" one, and nodes within the
  tolerance of a bound are put on it.
* **Incremental**: :func:`fix_and_propagate` fixes some nodes at given times (executed
  events) and pushes the others forward in topological order, visiting only the nodes
  reachable from the changed ones.

Slack of a schedule: ``latest - times`` per node, latest against the schedule's own
makespan (:func:`windows`); the critical path is a chain of tight arcs from a start
node to the robot that finishes last.
"""

from __future__ import annotations

import heapq
import logging
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.schedule.dag import TopoOrder, topo_order
from hierplan_opt.schedule.stn import STN

log = logging.getLogger(__name__)

#: Tolerance for bound checks, "tight" arcs and consistency (seconds, relative to the
#: magnitude of the times compared, with 1 s as the smallest scale).
TOL = 1e-9
#: The start event in cycles and messages.
X0 = -1


class InconsistentSTNError(InputError):
    """The STN has no solution (a negative cycle in its distance graph).

    ``cycle`` names the events of the cycle (``X0 (time 0)`` for the start event);
    ``nodes`` holds their STN node ids (``-1`` for X0); ``excess`` is by how many
    seconds the bounds are too tight.
    """

    def __init__(
        self, message: str, cycle: list[str], nodes: list[int] | None = None, excess: float = 0.0
    ) -> None:
        super().__init__(message)
        self.cycle = cycle
        self.nodes = nodes or []
        self.excess = excess


@dataclass(frozen=True, eq=False)
class GraphSolution:
    """Earliest and latest node times, slack, makespan and a critical path."""

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    earliest: np.ndarray
    latest: np.ndarray
    makespan: float
    critical_path: tuple[int, ...]

    @property
    def slack(self) -> np.ndarray:
        return self.latest - self.earliest


def _tol(x: np.ndarray | float) -> np.ndarray | float:
    return TOL * np.maximum(1.0, np.abs(x))


def topological_waves(n: int, src: np.ndarray, dst: np.ndarray) -> list[np.ndarray]:
    """The waves of Kahn's algorithm (wave k: longest chain of predecessors has k arcs).

    Example
    -------
    >>> [w.tolist() for w in topological_waves(4, np.array([0, 1, 0]), np.array([1, 2, 2]))]
    [[0, 3], [1], [2]]
    """
    return topo_order(n, src, dst).waves


def _dag(stn: STN) -> TopoOrder:
    topo = stn.topo
    if not topo.is_dag:
        raise InputError(
            f"the temporal plan graph has a cycle ({len(topo.cyclic)} nodes on or behind it); "
            "the plan is not a valid MAPF plan"
        )
    return topo


# ---------------------------------------------------------------------- passes
def _forward(stn: STN, topo: TopoOrder, t: np.ndarray) -> None:
    """``t_v = max(t_v, t_u + lb)`` over every arc, in topological order (in place)."""
    src = stn.arc_src[topo.arcs]
    dst = stn.arc_dst[topo.arcs]
    lb = stn.lb[topo.arcs]
    ptr = topo.arc_ptr.tolist()
    for k in range(len(ptr) - 1):
        a, b = ptr[k], ptr[k + 1]
        if b > a:
            np.maximum.at(t, dst[a:b], t[src[a:b]] + lb[a:b])


def _backward(stn: STN, topo: TopoOrder, t: np.ndarray) -> None:
    """``t_u = min(t_u, t_v - lb)`` over every arc, in reverse topological order."""
    src = stn.arc_src[topo.arcs]
    dst = stn.arc_dst[topo.arcs]
    lb = stn.lb[topo.arcs]
    ptr = topo.arc_ptr.tolist()
    for k in range(len(ptr) - 2, -1, -1):
        a, b = ptr[k], ptr[k + 1]
        if b > a:
            np.minimum.at(t, src[a:b], t[dst[a:b]] - lb[a:b])


def _settle(stn: STN, topo: TopoOrder, t: np.ndarray, *, forward: bool) -> bool:
    """Passes (forward: raise to lower bounds; backward: lower to upper bounds) until
    every arc upper bound holds too; False when they do not settle (a cycle)."""
    fin = np.flatnonzero(np.isfinite(stn.ub))
    a, b, ub = stn.arc_src[fin], stn.arc_dst[fin], stn.ub[fin]
    for _ in range(len(fin) + 2):
        if forward:
            _forward(stn, topo, t)
            need = t[b] - ub  # t_a >= t_b - ub
            bad = need > t[a] + _tol(t[a])
            np.maximum.at(t, a[bad], need[bad])
        else:
            _backward(stn, topo, t)
            need = t[a] + ub  # t_b <= t_a + ub
            bad = need < t[b] - _tol(t[b])
            np.minimum.at(t, b[bad], need[bad])
        if not bad.any():
            return True
    return False


def earliest_times(stn: STN, topo: TopoOrder | None = None) -> np.ndarray:
    """Earliest time of every node (the least solution of the STN).

    Raises :class:`InconsistentSTNError` when no schedule meets every bound.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import build_stn, build_tpg
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> tpg = build_tpg(inst, Plan.from_paths([[0, 1, 2]]))
    >>> earliest_times(build_stn(inst, tpg)).tolist()
    [0.0, 1.0, 2.0]
    >>> earliest_times(build_stn(inst, tpg, deadlines={"agent0": 1.5}))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hierplan_opt.schedule.solve_graph.InconsistentSTNError: the STN is inconsistent ...
    """
    topo = topo if topo is not None else _dag(stn)
    t = stn.release.astype(float).copy()
    if not _settle(stn, topo, t, forward=True):
        _raise_cycle(stn, t, forward=True)
    late = t > stn.deadline + _tol(stn.deadline)
    if late.any():
        _raise_deadline(stn, t, int(np.flatnonzero(late)[0]))
    return np.minimum(t, stn.deadline)


def latest_times(stn: STN, horizon: float, topo: TopoOrder | None = None) -> np.ndarray:
    """Latest time of every node such that every robot arrives by ``horizon`` (and by
    its deadline): the greatest solution of the STN with that extra bound.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import build_stn, build_tpg
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> latest_times(build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2]]))), 5).tolist()
    [0.0, 4.0, 5.0]
    """
    topo = topo if topo is not None else _dag(stn)
    t = stn.deadline.astype(float).copy()
    finals = stn.tpg.final_nodes()
    t[finals] = np.minimum(t[finals], horizon)
    if not _settle(stn, topo, t, forward=False):
        _raise_cycle(stn, -t, forward=False)
    early = t < stn.release - _tol(stn.release)
    if early.any():
        raise InconsistentSTNError(
            f"the STN is inconsistent: {stn.tpg.label(int(np.flatnonzero(early)[0]))} would "
            f"have to happen before its release time to finish by {horizon:g} s",
            [],
        )
    return np.maximum(t, stn.release)


def windows(
    stn: STN, times: np.ndarray, *, earliest: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Earliest and latest time of every node for the schedule ``times``.

    Latest times are taken against the schedule's own makespan, so every scheduled
    time lies in its window and ``latest - times`` is the delay the event absorbs
    without delaying the schedule's last arrival.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import build_stn, build_tpg
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (2, 1)], [(2, 0), (1, 1)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2], [5, 4]])))
    >>> [x.tolist() for x in windows(stn, np.array([0.0, 1.5, 3.0, 0.0, 1.0]))]
    [[0.0, 1.0, 2.0, 0.0, 1.0], [0.0, 2.0, 3.0, 0.0, 3.0]]
    """
    topo = _dag(stn)
    if earliest is None:
        earliest = earliest_times(stn, topo)
    horizon = float(np.max(times[stn.tpg.final_nodes()]))
    latest = latest_times(stn, horizon, topo)
    # Round-off: a feasible schedule lies in its windows.
    earliest = np.minimum(earliest, times)
    latest = np.maximum(latest, times)
    return earliest, latest


def critical_path(stn: STN, times: np.ndarray) -> tuple[int, ...]:
    """A chain of tight arcs ending at the node that finishes last, from its start.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import build_stn, build_tpg
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2]])))
    >>> critical_path(stn, earliest_times(stn))
    (0, 1, 2)
    """
    finals = stn.tpg.final_nodes()
    v = int(finals[int(np.argmax(times[finals]))])
    path = [v]
    seen = {v}
    while True:
        arcs = stn.in_arcs(v)
        if not arcs.size:
            break
        u_all = stn.arc_src[arcs]
        gap = times[v] - (times[u_all] + stn.lb[arcs])
        k = int(np.argmin(np.abs(gap)))
        if abs(gap[k]) > 1e3 * _tol(times[v]) or int(u_all[k]) in seen:
            break  # v is held by its release time (or a bound the path cannot show)
        v = int(u_all[k])
        seen.add(v)
        path.append(v)
    return tuple(reversed(path))


def solve_graph(stn: STN) -> GraphSolution:
    """Earliest schedule, latest times, makespan and critical path of ``stn``.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import build_stn, build_tpg
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (2, 1)], [(2, 0), (1, 1)])
    >>> plan = Plan.from_paths([[0, 1, 2], [5, 4]])
    >>> sol = solve_graph(build_stn(inst, build_tpg(inst, plan)))
    >>> sol.makespan, sol.slack.tolist(), sol.critical_path
    (2.0, [0.0, 0.0, 0.0, 0.0, 1.0], (0, 1, 2))
    """
    topo = _dag(stn)
    earliest = earliest_times(stn, topo)
    makespan = float(earliest[stn.tpg.final_nodes()].max())
    latest = np.maximum(latest_times(stn, makespan, topo), earliest)
    return GraphSolution(earliest, latest, makespan, critical_path(stn, earliest))


def bellman_ford(stn: STN):
    """Earliest times of a general STN and a function ``horizon -> latest times``.

    Kept for callers of the earlier networkx version; :func:`earliest_times` and
    :func:`latest_times` do the work.
    """
    topo = _dag(stn)
    earliest = earliest_times(stn, topo)
    return earliest, lambda horizon: latest_times(stn, horizon, topo)


# ---------------------------------------------------------------------- incremental
def fix_and_propagate(
    stn: STN,
    times: np.ndarray,
    fixed: Mapping[int, float],
    *,
    changed: tuple[int, ...] | list[int] = (),
) -> np.ndarray:
    """New node times after fixing some events, pushing their successors forward.

    ``fixed`` maps STN nodes to the times they happened (executed events); ``changed``
    lists further nodes whose incoming bounds changed (e.g. after
    :meth:`STN.with_bounds` raised a late robot's remaining lower bounds). Every other
    node keeps its time unless a predecessor now pushes it later: the nodes reachable
    from the fixed and changed ones are visited once each, in topological order (a heap
    keyed by the wave of :attr:`STN.topo`), ``O(affected log affected)``.

    Raises :class:`InconsistentSTNError` when a pushed node misses its deadline or an
    arc upper bound, or a fixed time breaks a bound from a fixed predecessor.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import build_stn, build_tpg
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (2, 1)], [(2, 0), (1, 1)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2], [5, 4]])))
    >>> t = earliest_times(stn)
    >>> fix_and_propagate(stn, t, {1: 1.75}).tolist()  # agent0 reached (1, 0) late
    [0.0, 1.75, 2.75, 0.0, 1.0]
    """
    topo = _dag(stn)
    t = np.array(times, dtype=float)
    fixed_set = {int(v) for v in fixed}
    changed_set = {int(v) for v in changed}
    for v, when in fixed.items():
        t[int(v)] = float(when)
    heap = [(int(topo.rank[v]), v) for v in fixed_set | changed_set]
    heapq.heapify(heap)
    queued = fixed_set | changed_set
    while heap:
        _, v = heapq.heappop(heap)
        arcs = stn.in_arcs(v)
        pushes = t[stn.arc_src[arcs]] + stn.lb[arcs]
        need = max(float(pushes.max(initial=-np.inf)), float(stn.release[v]))
        if v in fixed_set:
            if need > t[v] + _tol(t[v]):
                k = int(arcs[int(np.argmax(pushes))])
                u = int(stn.arc_src[k])
                raise InconsistentSTNError(
                    f"the fixed time {t[v]:.6g} s of {stn.tpg.label(v)} comes before "
                    f"{stn.tpg.label(u)} + {stn.lb[k]:.6g} s",
                    [stn.tpg.label(u), stn.tpg.label(v)],
                    [u, v],
                    float(need - t[v]),
                )
        elif need > t[v]:
            t[v] = need
        elif v not in changed_set:
            continue  # not pushed: its successors keep their times
        if t[v] > stn.deadline[v] + _tol(stn.deadline[v]):
            _raise_deadline(stn, t, v)
        capped = arcs[np.isfinite(stn.ub[arcs])]
        for k in capped.tolist():
            u = int(stn.arc_src[k])
            if t[v] - t[u] > stn.ub[k] + _tol(t[v]):
                raise InconsistentSTNError(
                    f"the upper bound {stn.ub[k]:.6g} s from {stn.tpg.label(u)} to "
                    f"{stn.tpg.label(v)} no longer holds ({t[v] - t[u]:.6g} s)",
                    [stn.tpg.label(u), stn.tpg.label(v)],
                    [u, v],
                    float(t[v] - t[u] - stn.ub[k]),
                )
        for w in stn.arc_dst[stn.out_arcs(v)].tolist():
            if w not in queued:
                queued.add(w)
                heapq.heappush(heap, (int(topo.rank[w]), w))
    return t


# ---------------------------------------------------------------------- explanations
def _name(stn: STN, v: int) -> str:
    return "X0 (time 0)" if v == X0 else stn.tpg.label(v)


def _holder(stn: STN, t: np.ndarray, v: int) -> tuple[int, float] | None:
    """The node (and arc weight in the distance graph) that holds ``t[v]`` up: a tight
    lower-bound arc ``u -> v``, a tight upper bound ``v -> w`` (``t_v >= t_w - ub``),
    or ``None`` when only its release time does."""
    best: tuple[float, int, float] | None = None
    for k in stn.in_arcs(v).tolist():
        u = int(stn.arc_src[k])
        gap = abs(t[v] - (t[u] + stn.lb[k]))
        if best is None or gap < best[0]:
            best = (gap, u, -float(stn.lb[k]))
    for k in stn.out_arcs(v).tolist():
        if np.isfinite(stn.ub[k]):
            w = int(stn.arc_dst[k])
            gap = abs(t[v] - (t[w] - stn.ub[k]))
            if best is None or gap < best[0]:
                best = (gap, w, float(stn.ub[k]))
    release_gap = abs(t[v] - stn.release[v])
    if best is None or (release_gap <= best[0] and release_gap <= 1e3 * _tol(t[v])):
        return None
    return best[1], best[2]


def _raise_deadline(stn: STN, t: np.ndarray, v: int) -> None:
    """A node that cannot meet its deadline: the cycle X0 -> ... -> v -> X0."""
    chain = [v]
    seen = {v}
    while True:
        h = _holder(stn, t, chain[-1])
        if h is None or h[0] in seen:
            break
        chain.append(h[0])
        seen.add(h[0])
    nodes = [X0, *reversed(chain), X0]
    excess = float(t[v] - stn.deadline[v])
    names = [_name(stn, x) for x in nodes]
    raise InconsistentSTNError(
        "the STN is inconsistent (the bounds cannot all hold; a deadline or upper "
        f"bound is too tight by {excess:.6g} s): negative cycle " + " -> ".join(names),
        names,
        nodes,
        excess,
    )


def _raise_cycle(stn: STN, t: np.ndarray, *, forward: bool) -> None:
    """The passes did not settle: follow the holders to a cycle of bounds."""
    times = t if forward else -t
    v = int(np.argmax(times - stn.release)) if forward else int(np.argmax(t))
    walk: list[int] = [v]
    pos = {v: 0}
    while True:
        h = _holder(stn, times, walk[-1])
        if h is None:
            break
        if h[0] in pos:
            walk = walk[pos[h[0]] :]
            break
        pos[h[0]] = len(walk)
        walk.append(h[0])
    nodes = [*reversed(walk), walk[-1]] if walk else []
    names = [_name(stn, x) for x in nodes]
    raise InconsistentSTNError(
        "the STN is inconsistent (the bounds cannot all hold; an upper bound is too "
        "tight): negative cycle " + " -> ".join(names),
        names,
        nodes,
    )
