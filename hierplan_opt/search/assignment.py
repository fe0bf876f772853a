"""Target assignment by distance: the Hungarian method and the bottleneck value.

What the ``hungarian`` solver (:mod:`hierplan_opt.search.hungarian`) assigns with, and
the team makespan bound that CBM and max-flow start from:

* :func:`assign` with ``objective="soc"``: the assignment of minimum total distance
  (Hungarian method, :func:`scipy.optimize.linear_sum_assignment`); its value is a
  lower bound on the TAPF sum of costs;
* with ``objective="makespan"``: first the *bottleneck* value (:func:`bottleneck_value`,
  the smallest d such that every robot can get a target within d steps, found by
  bisection over bipartite matchings), then the minimum total distance among
  assignments within d. The largest bottleneck value over the teams is a lower bound on
  the TAPF makespan (:func:`team_makespan_bound`).

A library module: it registers no solver.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from hierplan_opt.core.graph import UNREACHABLE, Graph

log = logging.getLogger(__name__)


def distance_matrix(graph: Graph, starts: Sequence[int], targets: Sequence[int]) -> np.ndarray:
    """``D[i, j]`` = timestep distance from ``starts[i]`` to ``targets[j]``.

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> distance_matrix(g, [0, 1], [2]).tolist()
    [[2], [1]]
    """
    rows = graph.precompute_distances(list(targets))
    s = np.asarray(list(starts), dtype=np.int64)
    return np.stack([np.asarray(r)[s] for r in rows], axis=1).astype(np.int64)


def bottleneck_value(dist: np.ndarray) -> int:
    """The smallest d such that a perfect matching uses only entries ``<= d``.

    Returns :data:`~hierplan_opt.core.graph.UNREACHABLE` when no perfect matching
    avoids unreachable pairs.

    Example
    -------
    >>> bottleneck_value(np.array([[1, 5], [2, 9]]))
    5
    """
    values = np.unique(dist[dist < UNREACHABLE])
    k = dist.shape[0]

    def perfect(d: int) -> bool:
        m = maximum_bipartite_matching(csr_matrix(dist <= d), perm_type="column")
        return bool((m >= 0).all()) and len(m) == k

    if len(values) == 0 or not perfect(int(values[-1])):
        return UNREACHABLE
    lo, hi = 0, len(values) - 1  # values[hi] is feasible
    while lo < hi:
        mid = (lo + hi) // 2
        if perfect(int(values[mid])):
            hi = mid
        else:
            lo = mid + 1
    return int(values[hi])


def assign(dist: np.ndarray, objective: str = "makespan") -> np.ndarray:
    """Column (target) index for every row (robot).

    ``"soc"`` minimises the total distance; ``"makespan"`` minimises the largest
    distance, then the total among those assignments.

    Example
    -------
    >>> assign(np.array([[0, 5], [5, 9]]), "soc").tolist()
    [0, 1]
    >>> assign(np.array([[0, 5], [5, 9]]), "makespan").tolist()
    [1, 0]
    """
    cost = dist.astype(float)
    big = float(dist.shape[0] * (int(dist[dist < UNREACHABLE].max(initial=0)) + 1) + 1)
    cost[dist >= UNREACHABLE] = big * 1e3
    if objective == "makespan":
        b = bottleneck_value(dist)
        if b < UNREACHABLE:
            cost[dist > b] = big * 1e3
    rows, cols = linear_sum_assignment(cost)
    out = np.empty(dist.shape[0], dtype=np.int64)
    out[rows] = cols
    return out


def team_makespan_bound(graph: Graph, starts: Sequence[int], targets: Sequence[int]) -> int:
    """The bottleneck lower bound on one team's makespan (see :func:`bottleneck_value`).

    Example
    -------
    >>> g = Graph.grid(5, 1)
    >>> team_makespan_bound(g, [0, 1], [3, 4])
    3
    """
    return bottleneck_value(distance_matrix(graph, starts, targets))
