"""The pruned time-expanded network shared by the MIP and CP-SAT formulations.

Mathematics: ``formulations/time_expanded.md``. A *commodity* is one MAPF agent or one
TAPF team; it has sources (its agents' starts), sinks (its goal or its team's targets)
and a *deadline* ``T_k`` by which all its units are at sinks and after which they stay
there. Node ``(v, t)`` of commodity ``k`` exists only when the commodity can be there:

    min_s dist(s, v) <= t   and   min_g dist(v, g) <= T_k - t

(reachability pruning), and never on a sink of another commodity ``j`` at ``t >= T_j``
(that robot is parked there). Arcs ``(u, t) -> (v, t + 1)`` join existing nodes along
an edge or a wait (``u == v``). Every arc is one 0/1 variable of the models.

This module holds no solver object: the network is plain numpy arrays and lists of arc
ids, so :meth:`TimeExpandedNetwork.plan` turns any arc values back into a
:class:`~hierplan_opt.core.plan.Plan`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan


@dataclass(frozen=True)
class Commodity:
    """One flow: a MAPF agent (one unit) or a TAPF team (one unit per robot)."""

    agents: tuple[int, ...]
    sources: tuple[int, ...]
    sinks: tuple[int, ...]
    deadline: int

    @property
    def units(self) -> int:
        return len(self.agents)


def commodities_of(instance: Instance) -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    """``(agents, sinks)`` of every commodity: one per MAPF agent, one per TAPF team."""
    if instance.is_tapf:
        return [(team.agents, team.targets) for team in instance.teams]
    return [((i,), (a.goal,)) for i, a in enumerate(instance.agents)]  # type: ignore[misc]


def commodity_min_deadline(instance: Instance) -> list[int]:
    """Per commodity: the largest distance bound of its agents (deadline at slack 0).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> commodity_min_deadline(Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)]))
    [2]
    """
    return [max(instance.min_distance(i) for i in agents) for agents, _ in commodities_of(instance)]


class TimeExpandedNetwork:
    """Arcs, grouped constraints and per-commodity data of the pruned network.

    Build one with :meth:`build`. Arc ``i`` goes from ``(arc_u[i], arc_t[i])`` to
    ``(arc_v[i], arc_t[i] + 1)`` for commodity ``arc_k[i]``.

    Attributes (lists of arc-id arrays, one entry per constraint):

    * ``conservation``: ``(in_arcs, out_arcs)`` with sum(in) == sum(out) (inner nodes);
    * ``source_out``: sum == 1 (each source leaves at t = 0);
    * ``sink_in``: sum == 1 (each sink is reached at the commodity's deadline);
    * ``vertex_groups``: sum <= 1 (arcs entering one vertex at one time);
    * ``swap_groups``: sum <= 1 (arcs crossing one edge in opposite directions);
    * ``layers[k][t]``: arcs of commodity k leaving layer t (sum == units of k);
    * ``wait[k]``: int array ``(len(sinks), deadline)``, arc id of the wait at each sink
      and time, ``-1`` where none exists (used by the sum-of-costs objective).

    ``infeasible`` is a reason string when the network has no flow by construction (a
    source or sink missing after pruning), else None.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> net = TimeExpandedNetwork.build(inst, 4)
    >>> net.horizon, net.num_arcs > 0, net.infeasible
    (4, True, None)
    """

    def __init__(
        self,
        instance: Instance,
        commodities: list[Commodity],
        arc_k: np.ndarray,
        arc_u: np.ndarray,
        arc_v: np.ndarray,
        arc_t: np.ndarray,
        pruned: bool,
        infeasible: str | None,
    ) -> None:
        self.instance = instance
        self.commodities = commodities
        self.arc_k = arc_k
        self.arc_u = arc_u
        self.arc_v = arc_v
        self.arc_t = arc_t
        self.pruned = pruned
        self.infeasible = infeasible
        self.horizon = max((c.deadline for c in commodities), default=0)
        self._group()

    # ------------------------------------------------------------------ building
    @classmethod
    def build(
        cls,
        instance: Instance,
        horizon: int,
        *,
        deadlines: Sequence[int] | None = None,
        detours: Sequence[int] | None = None,
        prune: bool = True,
    ) -> TimeExpandedNetwork:
        """The network for ``instance`` with every deadline ``horizon`` (or ``deadlines``).

        ``deadlines`` gives one deadline per commodity (:func:`commodities_of` order);
        the sum-of-costs models use ``d_k + slack``. ``detours`` (optional, one per
        commodity) keeps only vertices with ``min_s dist(s, v) + min_g dist(v, g) <=
        detours[k]``: a restriction (not a relaxation) used to find plans fast.
        ``prune=False`` keeps every passable vertex at every inner time (for model-size
        comparisons).
        """
        g = instance.graph
        n = g.n
        specs = commodities_of(instance)
        if deadlines is None:
            deadlines = [horizon] * len(specs)
        if len(deadlines) != len(specs):
            raise ValueError(f"expected {len(specs)} deadlines, got {len(deadlines)}")
        commodities = [
            Commodity(agents, tuple(instance.agents[i].start for i in agents), sinks, int(T))
            for (agents, sinks), T in zip(specs, deadlines, strict=True)
        ]
        g.precompute_distances({v for c in commodities for v in c.sinks})

        # Graph arcs including waits, as two aligned arrays.
        deg = np.diff(g.indptr)
        free = np.flatnonzero(g.passable)
        e_src = np.concatenate([free, np.repeat(np.arange(n), deg)])
        e_dst = np.concatenate([free, g.indices])

        # parked_at[v] = earliest time from which a commodity occupies sink v for good.
        owner = np.full(n, -1, dtype=np.int64)
        parked_at = np.full(n, np.iinfo(np.int64).max // 4, dtype=np.int64)
        for k, c in enumerate(commodities):
            for v in c.sinks:
                owner[v] = k
                parked_at[v] = c.deadline

        ks: list[np.ndarray] = []
        us: list[np.ndarray] = []
        vs: list[np.ndarray] = []
        ts: list[np.ndarray] = []
        infeasible: str | None = None
        for k, c in enumerate(commodities):
            T = c.deadline
            d_src = np.min(np.stack([g.dist_from(s) for s in c.sources]), axis=0)
            d_snk = np.min(np.stack([g.dist_to(v) for v in c.sinks]), axis=0)
            for s in c.sources:
                if d_snk[s] > T:
                    infeasible = infeasible or (
                        f"agent {instance.agents[c.agents[c.sources.index(s)]].name!r} cannot "
                        f"reach a goal by t={T}"
                    )
            for v in c.sinks:
                if d_src[v] > T:
                    infeasible = infeasible or f"sink {g.location(v)} cannot be reached by t={T}"
            if T == 0:
                if set(c.sources) != set(c.sinks):
                    infeasible = infeasible or "a commodity with deadline 0 is not at its goals"
                continue
            other = (owner >= 0) & (owner != k)
            if prune:
                ok_e = (d_src[e_src] + d_snk[e_dst] + 1 <= T) & (d_src[e_dst] <= T)
            else:
                ok_e = np.ones(len(e_src), dtype=bool)
            if detours is not None:
                near = d_src + d_snk <= detours[k]
                ok_e &= near[e_src] & near[e_dst]
            es, ed = e_src[ok_e], e_dst[ok_e]
            srcs = np.asarray(c.sources)
            snks = np.asarray(c.sinks)
            for t in range(T):
                # Node masks of layers t and t + 1, evaluated on the arcs' endpoints.
                if t == 0:
                    ok_u = np.isin(es, srcs)
                elif prune:
                    ok_u = (d_src[es] <= t) & (d_snk[es] <= T - t)
                else:
                    ok_u = np.ones(len(es), dtype=bool)
                if t + 1 == T:
                    ok_v = np.isin(ed, snks)
                elif prune:
                    ok_v = (d_src[ed] <= t + 1) & (d_snk[ed] <= T - t - 1)
                else:
                    ok_v = np.ones(len(ed), dtype=bool)
                ok = ok_u & ok_v
                ok &= ~(other[es] & (parked_at[es] <= t))
                ok &= ~(other[ed] & (parked_at[ed] <= t + 1))
                m = int(ok.sum())
                if m:
                    ks.append(np.full(m, k, dtype=np.int64))
                    us.append(es[ok])
                    vs.append(ed[ok])
                    ts.append(np.full(m, t, dtype=np.int64))

        def cat(parts: list[np.ndarray]) -> np.ndarray:
            return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)

        return cls(instance, commodities, cat(ks), cat(us), cat(vs), cat(ts), prune, infeasible)

    def _group(self) -> None:
        n = self.instance.graph.n
        H = self.horizon + 2
        k, u, v, t = self.arc_k, self.arc_u, self.arc_v, self.arc_t
        ids = np.arange(len(k))
        dl = np.array([c.deadline for c in self.commodities], dtype=np.int64)
        multi = np.array([c.units > 1 for c in self.commodities], dtype=bool)

        # Nodes: out-arcs keyed by (k, t, u), in-arcs by (k, t + 1, v).
        out_key = (k * H + t) * n + u
        in_key = (k * H + t + 1) * n + v
        out_groups = _groups(out_key, ids)
        in_groups = _groups(in_key, ids)
        self.conservation: list[tuple[np.ndarray, np.ndarray]] = []
        self.source_out: list[np.ndarray] = []
        self.sink_in: list[np.ndarray] = []
        empty = np.zeros(0, dtype=np.int64)
        for key in out_groups.keys() | in_groups.keys():
            kk, rest = divmod(key, H * n)
            tt = rest // n
            if tt == 0:
                self.source_out.append(out_groups[key])
            elif tt == dl[kk]:
                self.sink_in.append(in_groups[key])
            else:
                self.conservation.append((in_groups.get(key, empty), out_groups.get(key, empty)))
        for kk, c in enumerate(self.commodities):
            if c.deadline == 0:
                continue
            for s in c.sources:
                if (kk * H) * n + s not in out_groups:
                    self.infeasible = self.infeasible or "a start has no move in the network"
            for snk in c.sinks:
                if (kk * H + c.deadline) * n + snk not in in_groups:
                    self.infeasible = self.infeasible or "a goal has no arc in the network"

        # Vertex capacity: arcs entering (v, t + 1), unless only one single-unit commodity.
        self.vertex_groups = [
            a for a in _groups(v * H + t + 1, ids).values() if len(a) > 1 and _shared(a, k, multi)
        ]
        # Swaps: opposite moves over one edge at one time.
        mv = u != v
        lo, hi = np.minimum(u, v), np.maximum(u, v)
        self.swap_groups = [
            a
            for a in _groups((lo[mv] * n + hi[mv]) * H + t[mv], ids[mv]).values()
            if len(a) > 1 and len(np.unique(u[a])) > 1 and _shared(a, k, multi)
        ]
        self.forbidden = self._extra_conflicts(ids, multi)
        # Layers per commodity.
        self.layers: list[list[np.ndarray]] = [[] for _ in self.commodities]
        lay = _groups(k * H + t, ids)
        for kk, c in enumerate(self.commodities):
            self.layers[kk] = [lay.get(kk * H + tt, empty) for tt in range(c.deadline)]
        # Waits at sinks (sum of costs).
        self.wait: list[np.ndarray] = []
        waits = ids[(u == v) & np.isin(u, np.fromiter(self._sinkset, dtype=np.int64))]
        wkey = {
            (kk, uu, tt): a
            for kk, uu, tt, a in zip(
                k[waits].tolist(), u[waits].tolist(), t[waits].tolist(), waits.tolist(), strict=True
            )
        }
        for kk, c in enumerate(self.commodities):
            w = np.full((len(c.sinks), c.deadline), -1, dtype=np.int64)
            for j, snk in enumerate(c.sinks):
                for tt in range(c.deadline):
                    w[j, tt] = wkey.get((kk, snk, tt), -1)
            self.wait.append(w)

    def _extra_conflicts(self, ids: np.ndarray, multi: np.ndarray) -> np.ndarray:
        """Annotated roadmaps' extra conflicts (``instance.meta["edge_conflicts"]``: move
        pairs no two robots may make at one time, besides vertex and swap conflicts): one
        more ``swap_groups`` entry (sum <= 1) per pair and time, and the arcs that meet a
        robot parked at its sink after its deadline (its wait there is a move too), which
        the models fix to 0 (returned)."""
        extra = self.instance.meta.get("edge_conflicts") or []
        if not extra:
            return np.zeros(0, dtype=np.int64)
        n = self.instance.graph.n
        H = self.horizon + 2
        k, u, v, t = self.arc_k, self.arc_u, self.arc_v, self.arc_t
        by_move = _groups((u * n + v) * H + t, ids)
        moves = _groups(u * n + v, ids)
        parked: dict[int, list[tuple[int, int]]] = {}  # sink -> (commodity, deadline)
        for kk, c in enumerate(self.commodities):
            for snk in c.sinks:
                parked.setdefault(snk, []).append((kk, c.deadline))
        forbidden: list[np.ndarray] = []
        for (a1, b1), (a2, b2) in extra:
            for tt in range(H):
                g1, g2 = by_move.get((a1 * n + b1) * H + tt), by_move.get((a2 * n + b2) * H + tt)
                if g1 is not None and g2 is not None:
                    grp = np.concatenate([g1, g2])
                    if _shared(grp, k, multi):
                        self.swap_groups.append(grp)
            for (wa, wb), (oa, ob) in (((a1, b1), (a2, b2)), ((a2, b2), (a1, b1))):
                if wa != wb:
                    continue
                other = moves.get(oa * n + ob)
                if other is None:
                    continue
                for kk, deadline in parked.get(wa, []):
                    if self.commodities[kk].units != len(self.commodities[kk].sinks):
                        continue  # not every sink is filled after the deadline
                    forbidden.append(other[(t[other] >= deadline) & (k[other] != kk)])
        return np.unique(np.concatenate(forbidden)) if forbidden else np.zeros(0, dtype=np.int64)

    @cached_property
    def _sinkset(self) -> set[int]:
        return {v for c in self.commodities for v in c.sinks}

    # ------------------------------------------------------------------ queries
    @property
    def num_arcs(self) -> int:
        """Number of arc variables."""
        return len(self.arc_k)

    @property
    def num_wait_vars(self) -> int:
        """Number of goal-reached indicators y (existing sink waits)."""
        return int(sum((w >= 0).sum() for w in self.wait))

    def num_constraints(self, objective: str) -> int:
        """Number of linear constraints of the MIP (sum of costs adds the y links)."""
        base = (
            len(self.conservation)
            + len(self.source_out)
            + len(self.sink_in)
            + len(self.vertex_groups)
            + len(self.swap_groups)
        )
        return base + (2 * self.num_wait_vars if objective == "soc" else 0)

    def stats(self, objective: str) -> dict[str, int]:
        """Model size: variables, constraints, horizon (for ``Result.stats``)."""
        y = self.num_wait_vars if objective == "soc" else 0
        return {
            "variables": self.num_arcs + y,
            "constraints": self.num_constraints(objective),
            "horizon": self.horizon,
        }

    def soc_constant(self) -> int:
        """The constant of the sum-of-costs objective: sum over commodities of units * deadline."""
        return sum(c.units * c.deadline for c in self.commodities)

    @cached_property
    def arc_index(self) -> dict[tuple[int, int, int, int], int]:
        """``(k, u, v, t) -> arc id`` (built on first use, for hints)."""
        return {
            (int(a), int(b), int(c), int(d)): i
            for i, (a, b, c, d) in enumerate(
                zip(
                    self.arc_k.tolist(),
                    self.arc_u.tolist(),
                    self.arc_v.tolist(),
                    self.arc_t.tolist(),
                    strict=True,
                )
            )
        }

    def arcs_of_plan(self, plan: Plan) -> np.ndarray | None:
        """0/1 arc values that encode ``plan``, or None if the plan does not fit the network."""
        x = np.zeros(self.num_arcs, dtype=np.int8)
        index = self.arc_index
        agent_k = {}
        for kk, c in enumerate(self.commodities):
            for i in c.agents:
                agent_k[i] = kk
        for i in range(self.instance.num_agents):
            kk = agent_k[i]
            T = self.commodities[kk].deadline
            if plan.costs[i] > T:
                return None
            for t in range(T):
                a = index.get((kk, plan.position(i, t), plan.position(i, t + 1), t))
                if a is None:
                    return None
                x[a] = 1
        return x

    def plan(self, values: Sequence[float] | np.ndarray) -> Plan:
        """The plan encoded by arc ``values`` (> 0.5 means used): one path per agent.

        Example
        -------
        >>> from hierplan_opt.core.graph import Graph
        >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
        >>> net = TimeExpandedNetwork.build(inst, 2)
        >>> net.plan(net.arcs_of_plan(Plan.from_paths([[0, 1, 2]]))).paths
        ((0, 1, 2),)
        """
        val = np.asarray(values, dtype=float) > 0.5
        paths: list[list[int]] = [[] for _ in range(self.instance.num_agents)]
        for kk, c in enumerate(self.commodities):
            sel = np.flatnonzero(val & (self.arc_k == kk))
            succ = {
                (u, t): v
                for u, v, t in zip(
                    self.arc_u[sel].tolist(),
                    self.arc_v[sel].tolist(),
                    self.arc_t[sel].tolist(),
                    strict=True,
                )
            }
            for i in c.agents:
                v = self.instance.agents[i].start
                p = [v]
                for t in range(c.deadline):
                    v = succ[(v, t)]
                    p.append(v)
                paths[i] = p
        return Plan.from_paths(paths)


def _groups(keys: np.ndarray, ids: np.ndarray) -> dict[int, np.ndarray]:
    """``key -> ids`` with that key."""
    if len(keys) == 0:
        return {}
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    cuts = np.flatnonzero(np.diff(sk)) + 1
    uniq = sk[np.concatenate([[0], cuts])]
    return dict(zip(uniq.tolist(), np.split(ids[order], cuts), strict=True))


def _shared(arcs: np.ndarray, k: np.ndarray, multi: np.ndarray) -> bool:
    """Whether a capacity group can be violated: several commodities, or a team."""
    ks = k[arcs]
    return bool(ks.min() != ks.max() or multi[ks[0]])
