"""Learned highways from the agents' independent shortest paths, and every highway
generator by name (:func:`resolve`, the ``highways`` option of the solvers).

The learned generators (``formulations/highways.md``):

Both generators start from the *traffic* of an instance: for every agent, one unit of
flow goes from its start to its goal along its shortest paths, splitting evenly among
the next hops that stay on a shortest path (:func:`traffic`); ``t[u, v]`` sums the
expected number of agents that move ``u -> v``.

* :func:`flow` orients every edge with traffic along its net flow (``u -> v`` when
  ``t[u, v] > t[v, u]``); edges without a net flow get no highway.
* :func:`learned` is a MAP assignment of a pairwise Markov random field over edge
  directions (after Cohen et al., IJCAI 2016, who learn highways with a graphical
  model over the same traffic): one binary label per undirected grid edge, a unary
  cost for the traffic that would drive against the chosen direction, a smoothness
  cost ``beta`` for consecutive edges of one line that disagree (lanes), and a cost
  ``gamma`` for neighbouring parallel edges that agree (opposite lanes side by side,
  also across a shelf row). Relabelling every other line makes every pairwise term
  submodular, so the MAP assignment is an exact minimum s-t cut (:func:`min_cut_labels`). Edges with
  traffic keep the direction chosen; the others get no highway.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hierplan_opt.core.errors import InputError, OptionError
from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.core.highways import (
    GENERATORS,
    Highways,
    corridors,
    crisscross,
    is_2d_grid,
)
from hierplan_opt.core.instance import Instance

#: Capacities are scaled to integers for the max-flow routine.
_SCALE = 1000


def traffic(instance: Instance) -> dict[tuple[int, int], float]:
    """Expected moves ``u -> v`` of the agents on even-split random shortest paths.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(2, 2), [(0, 0)], [(1, 1)])
    >>> sorted(traffic(inst).items())
    [((0, 1), 0.5), ((0, 2), 0.5), ((1, 3), 0.5), ((2, 3), 0.5)]
    """
    g = instance.graph
    goals = instance.goals
    g.precompute_distances(goals)
    adj = g.adj
    out: dict[tuple[int, int], float] = {}
    for s, goal in zip(instance.starts, goals, strict=True):
        dg = g.dist_list(goal)
        if dg[s] >= UNREACHABLE:
            continue
        layer = {s: 1.0}
        for _ in range(dg[s]):
            nxt: dict[int, float] = {}
            for v, mass in layer.items():
                hops = [u for u in adj[v] if dg[u] == dg[v] - 1]
                share = mass / len(hops)
                for u in hops:
                    out[(v, u)] = out.get((v, u), 0.0) + share
                    nxt[u] = nxt.get(u, 0.0) + share
            layer = nxt
    return out


def flow(instance: Instance) -> Highways:
    """Every edge with traffic oriented along its net flow.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0), (1, 0)], [(2, 0), (0, 0)])
    >>> sorted(flow(inst))  # 0 -> 1 and 1 -> 0 cancel; 1 -> 2 remains
    [(1, 2)]
    """
    t = traffic(instance)
    return frozenset(e for e, x in t.items() if x > t.get((e[1], e[0]), 0.0) + 1e-9)


def min_cut_labels(
    unary: np.ndarray, pairs: Sequence[tuple[int, int, float]]
) -> tuple[np.ndarray, float]:
    """Exact MAP of a binary energy with Potts pairwise terms, by one minimum s-t cut.

    ``E(x) = sum_i unary[i, x_i] + sum_{(i, j, c)} c * [x_i != x_j]`` with ``c >= 0``
    (submodular). Label 0 is the source side of the cut, 1 the sink side. Returns the
    labels and their energy (costs are rounded to ``1/1000`` for the integer max flow).

    Example
    -------
    >>> lab, e = min_cut_labels(np.array([[0.0, 2.0], [3.0, 0.0], [1.0, 1.1]]),
    ...                         [(0, 2, 5.0), (1, 2, 0.5)])
    >>> lab.tolist(), round(e, 3)
    ([0, 1, 0], 1.5)
    """
    import scipy.sparse as sp  # heavy module (scipy): loaded only for learned highways
    from scipy.sparse.csgraph import breadth_first_order, maximum_flow

    m = len(unary)
    s, t = m, m + 1
    rows: list[int] = []
    cols: list[int] = []
    caps: list[int] = []

    def arc(a: int, b: int, c: float) -> None:
        ci = int(round(c * _SCALE))
        if ci > 0:
            rows.append(a)
            cols.append(b)
            caps.append(ci)

    base = np.minimum(unary[:, 0], unary[:, 1])
    for i in range(m):
        arc(s, i, unary[i, 1] - base[i])  # cut when i takes label 1
        arc(i, t, unary[i, 0] - base[i])  # cut when i takes label 0
    for i, j, c in pairs:
        if c < 0:
            raise InputError("pairwise costs must be >= 0 (submodular)")
        arc(i, j, c)
        arc(j, i, c)
    cap = sp.csr_array(
        (np.array(caps, dtype=np.int32), (np.array(rows), np.array(cols))), shape=(m + 2, m + 2)
    )
    res = maximum_flow(cap, s, t)
    # Residual graph (flows are antisymmetric, so reverse arcs get the flow back).
    residual = sp.csr_array(cap - res.flow)
    residual.data[residual.data < 0] = 0
    residual.eliminate_zeros()
    reach = breadth_first_order(residual, s, directed=True, return_predecessors=False)
    labels = np.ones(m, dtype=int)
    side = np.zeros(m + 2, dtype=bool)
    side[np.asarray(reach)] = True
    labels[side[:m]] = 0
    energy = float(unary[np.arange(m), labels].sum())
    energy += sum(c for i, j, c in pairs if labels[i] != labels[j])
    return labels, energy


def learned(
    instance: Instance,
    *,
    beta: float = 1.0,
    gamma: float = 1.0,
    unit: float | None = None,
    reach: int = 3,
) -> Highways:
    """Highway directions by MAP inference over edge directions (module docstring).

    Parameters
    ----------
    beta
        Cost of two consecutive edges of one row (column) pointing different ways.
    gamma
        Cost of two neighbouring parallel edges pointing the same way.
    unit
        Cost per expected agent driving against an edge's direction (default: one
        over the mean traffic of the edges with traffic, so that the unary costs are
        of order 1 like ``beta`` and ``gamma`` and the same weights suit any fleet).
    reach
        Parallel edges up to this many lines apart are neighbours when only blocked
        cells lie between them (lanes on both sides of a shelf row).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(4, 2)
    >>> inst = Instance.mapf(g, [(0, 0), (3, 1)], [(3, 0), (0, 1)])
    >>> sorted(g.location(u) + g.location(v) for u, v in learned(inst))
    [(0, 0, 1, 0), (1, 0, 2, 0), (1, 1, 0, 1), (2, 0, 3, 0), (2, 1, 1, 1), (3, 1, 2, 1)]
    """
    g = instance.graph
    if not is_2d_grid(g):
        raise InputError("learned highways need a 2D grid map")
    assert g.shape is not None
    width, height = g.shape
    t = traffic(instance)
    if unit is None:
        busy = {frozenset(e): 0.0 for e in t}
        for (u, v), x in t.items():
            busy[frozenset((u, v))] += x
        unit = len(busy) / sum(busy.values()) if busy else 1.0
    # One variable per undirected edge (a, b), a < b: label 1 = a -> b (east / south).
    edges = sorted((u, v) for u, v in g.edges() if u < v)
    index = {e: i for i, e in enumerate(edges)}
    unary = np.zeros((len(edges), 2))
    for i, (a, b) in enumerate(edges):
        unary[i, 0] = unit * t.get((a, b), 0.0)  # label 0 (b -> a): a -> b drives against
        unary[i, 1] = unit * t.get((b, a), 0.0)
    # Flip the labels of horizontal edges on odd rows and vertical edges on odd columns,
    # so "parallel neighbours agree" becomes a disagreement of flipped labels.
    flip = np.zeros(len(edges), dtype=bool)
    for i, (a, b) in enumerate(edges):
        x, y = a % width, a // width
        flip[i] = (y % 2 == 1) if b == a + 1 else (x % 2 == 1)
    unary[flip] = unary[flip][:, ::-1]
    pairs: list[tuple[int, int, float]] = []
    for i, (a, b) in enumerate(edges):
        horizontal = b == a + 1
        step = 1 if horizontal else width
        across = width if horizontal else 1
        nxt = (b, b + step)  # the next edge on the same line
        if nxt in index:
            pairs.append((i, index[nxt], beta))
        # The nearest parallel edge across, skipping blocked lines (the aisle on the
        # other side of a shelf row); coupled only an odd number of lines away, where
        # the relabelling above makes the term submodular.
        x, y = a % width, a // width
        room = (height - 1 - y) if horizontal else (width - 1 - x)
        for k in range(1, min(reach, room) + 1):
            par = (a + k * across, b + k * across)
            if par in index:
                if k % 2 == 1 and gamma > 0:
                    pairs.append((i, index[par], gamma))
                break
            if g.passable[par[0]] or g.passable[par[1]]:
                break  # a free cell in between: no lane on the other side of a shelf
    labels, _ = min_cut_labels(unary, pairs)
    labels = np.where(flip, 1 - labels, labels)
    out: set[tuple[int, int]] = set()
    for (a, b), lab in zip(edges, labels, strict=True):
        if t.get((a, b), 0.0) + t.get((b, a), 0.0) > 0:
            out.add((a, b) if lab == 1 else (b, a))
    return frozenset(out)


__all__ = ["flow", "learned", "min_cut_labels", "traffic"]


# ---------------------------------------------------------------- by name
def resolve(instance: Instance, spec: object, solver: str = "solver") -> Highways:
    """The highway set named by the ``highways`` option.

    ``"instance"`` is the instance's own set (:attr:`Instance.highways`, e.g. read from a
    file), ``"crisscross"`` and ``"corridors"`` the generators of
    :mod:`hierplan_opt.core.highways`, ``"learned"`` and ``"flow"`` those above.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> sorted(resolve(inst, "crisscross"))
    [(0, 1), (1, 2)]
    >>> resolve(inst, "instance", "ecbs")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OptionError: ecbs option highways='instance': the instance has no ...
    """
    check_spec(instance, spec, solver)
    if spec == "instance":
        assert instance.highways is not None  # checked
        return instance.highways
    if spec == "crisscross":
        return crisscross(instance.graph)
    if spec == "corridors":
        return corridors(instance.graph)
    return learned(instance) if spec == "learned" else flow(instance)


def check_spec(instance: Instance, spec: object, solver: str) -> None:
    """The errors of :func:`resolve` without computing the set (for a solver that
    hands the option on to another).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> check_spec(Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)]), "instance", "cbs")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OptionError: cbs option highways='instance': the instance has no ...
    """
    if spec == "instance" and instance.highways is None:
        raise OptionError(f"{solver} option highways='instance': the instance has no highways")
    if spec not in GENERATORS:
        raise OptionError(
            f"{solver} option highways must be one of {', '.join(GENERATORS)}, got {spec!r}"
        )
