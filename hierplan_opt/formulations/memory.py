"""Model size before building, and the memory budget of the time-expanded formulations.

A time-expanded model grows with agents x horizon x vertices; on a 200-agent warehouse
plan one CP-SAT model needs tens of GB. :func:`estimate_network` counts the arcs and
nodes of :meth:`TimeExpandedNetwork.build <hierplan_opt.formulations.time_expanded.
TimeExpandedNetwork.build>` in O(commodities x edges) without building anything (the
exact count, less the arcs that parked robots remove), :func:`model_bytes` turns that
into bytes for a backend, and :func:`check_model` refuses a model over the budget with
:class:`ModelTooLarge`, one line: "the cpsat model at horizon 180 would need ~31 GB ...".

The budget (:func:`memory_budget`) defaults to half of the physical memory, or 80 % of
what is available now if that is less; ``HIERPLAN_MEMORY_LIMIT_GB`` or ``hierplan
verify/solve --memory-limit GB`` (:func:`set_memory_budget`) change it.

Example
-------
>>> from hierplan_opt.core.graph import Graph
>>> from hierplan_opt.core.instance import Instance
>>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
>>> estimate_network(inst, 2)
NetworkSize(arcs=2, nodes=3)
>>> with memory_limit(1000):  # bytes
...     check_model(inst, 50, "cpsat")
Traceback (most recent call last):
...
hierplan_opt.formulations.memory.ModelTooLarge: the cpsat model at horizon 50 would need ...
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.errors import HierplanError, InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import positive_amount
from hierplan_opt.core.resources import cgroup_limit, meminfo

GB = 1 << 30

#: Peak bytes per arc and per node of one model: network, Python model, the solver's
#: copy and the first seconds of search. Measured (peak resident memory of a fresh
#: process less its baseline, formulations/verify.md): CP-SAT 2.1-2.3 kB per arc on
#: networks of 1.2-4.7 million arcs (about 0.27 nodes per arc); the estimate is 15-30 %
#: above. Small models use more per arc (search memory, up to 1.5 GB), which CP-SAT's
#: own ``max_memory_in_mb`` (set to the budget) bounds. MIP: 3.5 kB per arc measured
#: at 76 thousand arcs only; set higher than CP-SAT (one Pyomo object per variable).
BYTES_PER_ARC = {"cpsat": 2500, "mip": 4000}
BYTES_PER_NODE = {"cpsat": 1000, "mip": 2000}


class ModelTooLarge(HierplanError):
    """A model would need more memory than the budget (one-line message)."""


@dataclass(frozen=True)
class NetworkSize:
    """Arcs (0/1 variables) and inner nodes (flow-conservation constraints)."""

    arcs: int
    nodes: int


def estimate_network(
    instance: Instance,
    horizon: int,
    *,
    deadlines: Sequence[int] | None = None,
    detours: Sequence[int] | None = None,
) -> NetworkSize:
    """Arcs and nodes of the pruned network at ``horizon`` (or per-commodity ``deadlines``).

    Counts, per commodity and graph arc (waits included), the times at which both ends
    survive reachability pruning, as ``TimeExpandedNetwork.build`` keeps them; arcs that
    a parked robot removes are counted too, so this is an upper bound (equal on
    instances whose goals nobody else crosses). O(commodities x edges), no network built.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.formulations.time_expanded import TimeExpandedNetwork
    >>> g = Graph.grid(8, 8)
    >>> inst = Instance.mapf(g, [(0, 0), (7, 7)], [(7, 7), (0, 0)])
    >>> est = estimate_network(inst, 16)
    >>> est.arcs >= TimeExpandedNetwork.build(inst, 16).num_arcs
    True
    """
    # not at the top: the memory guard runs on `hierplan solve`'s path, the model does not
    from hierplan_opt.formulations.time_expanded import commodities_of

    g = instance.graph
    specs = commodities_of(instance)
    if deadlines is None:
        deadlines = [horizon] * len(specs)
    deg = np.diff(g.indptr)
    free = np.flatnonzero(g.passable)
    e_src = np.concatenate([free, np.repeat(np.arange(g.n), deg)])
    e_dst = np.concatenate([free, g.indices])
    g.precompute_distances({v for _, sinks in specs for v in sinks})
    arcs = nodes = 0
    for k, ((agents, sinks), T) in enumerate(zip(specs, deadlines, strict=True)):
        if T <= 0:
            continue
        starts = [instance.agents[i].start for i in agents]
        d_src = np.min(np.stack([g.dist_from(s) for s in starts]), axis=0)
        d_snk = np.min(np.stack([g.dist_to(v) for v in sinks]), axis=0)
        d_src = d_src.astype(np.int64)
        d_snk = d_snk.astype(np.int64)
        # node (v, t) exists for d_src[v] <= t <= T - d_snk[v]
        span = T - d_snk - d_src + 1
        if detours is not None:
            span = np.where(d_src + d_snk <= detours[k], span, 0)
        nodes += int(np.clip(span[free], 0, None).sum())
        # arc (u, t) -> (v, t + 1): both nodes exist and 0 <= t < T
        lo = np.maximum(np.maximum(d_src[e_src], d_src[e_dst] - 1), 0)
        hi = np.minimum(np.minimum(T - d_snk[e_src], T - 1 - d_snk[e_dst]), T - 1)
        count = np.clip(hi - lo + 1, 0, None)
        if detours is not None:
            near = d_src + d_snk <= detours[k]
            count = np.where(near[e_src] & near[e_dst], count, 0)
        arcs += int(count.sum())
    return NetworkSize(arcs, nodes)


def model_bytes(size: NetworkSize, backend: str) -> int:
    """Peak bytes of one ``backend`` ("cpsat" or "mip") model of a network of ``size``.

    Example
    -------
    >>> model_bytes(NetworkSize(arcs=10**6, nodes=10**5), "cpsat") / GB  # doctest: +ELLIPSIS
    2.42...
    """
    per_arc = BYTES_PER_ARC.get(backend, max(BYTES_PER_ARC.values()))
    per_node = BYTES_PER_NODE.get(backend, max(BYTES_PER_NODE.values()))
    return size.arcs * per_arc + size.nodes * per_node


# ---------------------------------------------------------------------- the budget
def default_budget() -> int:
    """Half of the physical memory (or of the cgroup limit), at most 80 % of what is free.

    Example
    -------
    >>> default_budget() > 0
    True
    """
    info = meminfo()
    total = info.get("MemTotal")
    if total is None:
        try:
            total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            total = 8 * GB
    cg = cgroup_limit()
    if cg is not None:
        total = min(total, cg)
    budget = total // 2
    if "MemAvailable" in info:
        budget = min(budget, int(info["MemAvailable"] * 0.8))
    return max(budget, 256 << 20)


_budget: int | None = None


def memory_budget() -> int:
    """The budget in force, in bytes (``HIERPLAN_MEMORY_LIMIT_GB`` or :func:`default_budget`)."""
    global _budget
    if _budget is None:
        text = os.environ.get("HIERPLAN_MEMORY_LIMIT_GB", "").strip()
        name = "HIERPLAN_MEMORY_LIMIT_GB"
        _budget = positive_amount(text, name, GB, "GB") if text else default_budget()
    return _budget


def set_memory_budget(nbytes: int | None) -> None:
    """Put a budget in force (bytes); None goes back to the environment / default."""
    global _budget
    if nbytes is not None and (isinstance(nbytes, bool) or nbytes < 1):
        raise InputError(f"the memory budget must be a positive number of bytes, got {nbytes!r}")
    _budget = nbytes


@contextlib.contextmanager
def memory_limit(nbytes: int) -> Iterator[int]:
    """Temporarily use a budget of ``nbytes``: ``with memory_limit(4 * GB): ...``."""
    before = _budget
    set_memory_budget(nbytes)
    try:
        yield nbytes
    finally:
        set_memory_budget(before)


def gb_text(nbytes: float) -> str:
    """``'31 GB'``, ``'0.42 GB'``: a byte count in GB with two significant digits.

    Example
    -------
    >>> gb_text(3.3e10), gb_text(4.5e8)
    ('31 GB', '0.42 GB')
    """
    return f"{nbytes / GB:.2g} GB" if nbytes < 10 * GB else f"{nbytes / GB:.0f} GB"


def check_model(
    instance: Instance,
    horizon: int,
    backend: str,
    *,
    deadlines: Sequence[int] | None = None,
    detours: Sequence[int] | None = None,
) -> NetworkSize:
    """The estimated size of the model; :class:`ModelTooLarge` if over :func:`memory_budget`."""
    size = estimate_network(instance, horizon, deadlines=deadlines, detours=detours)
    need = model_bytes(size, backend)
    budget = memory_budget()
    if need > budget:
        top = max(deadlines) if deadlines is not None else horizon
        raise ModelTooLarge(
            f"the {backend} model at horizon {top} would need ~{gb_text(need)} "
            f"({size.arcs:,} arc variables, {instance.num_agents} agents x {top} steps x "
            f"{instance.graph.num_vertices} vertices), over the memory budget of "
            f"{gb_text(budget)}; use fewer agents (--agents K) or a smaller horizon, or "
            "raise --memory-limit"
        )
    return size
