"""Topological order of a temporal plan graph in numpy "waves", and cycle finding.

Kahn's algorithm, one wave at a time: wave ``k`` holds the nodes whose longest chain of
predecessors has ``k`` arcs. The forward and backward passes of the STN solvers read
the arcs grouped by the wave of their source as contiguous slices, so the Python
overhead is per wave, not per node.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def csr(n: int, key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arc ids grouped by ``key`` (CSR): ``order[ptr[v]:ptr[v+1]]`` are v's arcs.

    Example
    -------
    >>> order, ptr = csr(3, np.array([2, 0, 2]))
    >>> order[ptr[2]:ptr[3]].tolist()
    [0, 2]
    """
    order = np.argsort(key, kind="stable")
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(key, minlength=n), out=ptr[1:])
    return order, ptr


def gather(order: np.ndarray, ptr: np.ndarray, nodes: np.ndarray) -> np.ndarray:
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

    ``arcs[arc_ptr[k]:arc_ptr[k + 1]]`` are the arcs leaving wave ``k``; ``rank[v]`` is
    the wave of node ``v``; ``cyclic`` lists the nodes on or behind a cycle (empty for
    a DAG, whose waves then cover every node).
    """

    waves: list[np.ndarray]
    arcs: np.ndarray
    arc_ptr: np.ndarray
    rank: np.ndarray
    cyclic: np.ndarray

    @property
    def is_dag(self) -> bool:
        return not len(self.cyclic)


def topo_order(n: int, src: np.ndarray, dst: np.ndarray) -> TopoOrder:
    """Kahn's algorithm in waves (``cyclic`` lists the nodes it could not order).

    Example
    -------
    >>> t = topo_order(4, np.array([0, 1, 0]), np.array([1, 2, 2]))
    >>> [w.tolist() for w in t.waves], t.rank.tolist(), t.is_dag
    ([[0, 3], [1], [2]], [0, 1, 2, 0], True)
    """
    indeg = np.bincount(dst, minlength=n).astype(np.int64)
    order, ptr = csr(n, src)
    frontier = np.flatnonzero(indeg == 0)
    rank = np.full(n, -1, dtype=np.int64)
    waves = []
    wave_arcs = []
    while frontier.size:
        rank[frontier] = len(waves)
        waves.append(frontier)
        arcs = gather(order, ptr, frontier)
        wave_arcs.append(arcs)
        if not arcs.size:
            break
        d = dst[arcs]
        np.subtract.at(indeg, d, 1)
        zero = d[indeg[d] == 0]
        frontier = np.unique(zero) if zero.size > 1 else zero
    sizes = np.array([len(a) for a in wave_arcs], dtype=np.int64)
    arc_ptr = np.zeros(len(wave_arcs) + 1, dtype=np.int64)
    np.cumsum(sizes, out=arc_ptr[1:])
    arcs_all = np.concatenate(wave_arcs) if wave_arcs else np.zeros(0, dtype=np.int64)
    return TopoOrder(waves, arcs_all, arc_ptr, rank, np.flatnonzero(rank < 0))


def find_cycle(n: int, src: np.ndarray, dst: np.ndarray, candidates: np.ndarray) -> list[int]:
    """One directed cycle among ``candidates`` (the nodes Kahn's algorithm left), as a
    node list whose last arc returns to the first node.

    Example
    -------
    >>> find_cycle(4, np.array([0, 1, 2, 3]), np.array([1, 2, 1, 0]), np.array([1, 2]))
    [1, 2]
    """
    alive = np.zeros(n, dtype=bool)
    alive[candidates] = True
    # Peel nodes without successors among the alive ones: the rest lie on cycles or
    # lead into them, and every one of them has an alive successor.
    while True:
        keep = alive[src] & alive[dst]
        outdeg = np.bincount(src[keep], minlength=n)
        dead = alive & (outdeg == 0)
        if not dead.any():
            break
        alive &= ~dead
    keep = alive[src] & alive[dst]
    succ = np.full(n, -1, dtype=np.int64)
    succ[src[keep]] = dst[keep]
    v = int(np.flatnonzero(alive)[0])
    seen: dict[int, int] = {}
    path: list[int] = []
    while v not in seen:
        seen[v] = len(path)
        path.append(v)
        v = int(succ[v])
    return path[seen[v] :]
