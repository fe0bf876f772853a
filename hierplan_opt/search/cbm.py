"""Conflict-Based Min-Cost Flow (CBM; Ma & Koenig, AAMAS 2016): optimal TAPF makespan.

CBS at the level of teams. Each high-level node holds, for every team, a set of
constraints (vertex ``(v, t)`` and move ``(u, v, t)``, forbidden to *every* robot of
the team) and the team's paths. A team's low level works on its time-expanded network
(:mod:`hierplan_opt.search.flow_network`) with the constrained nodes and arcs deleted:

1. the team's smallest feasible horizon ``T_i`` (max flow = team size), searched up
   from the team's previous value (constraints only ever add) and from the bottleneck
   bound; a vertex constraint on one of the team's own targets at ``t`` forces
   ``T_i > t`` because the robot that ends there must arrive after ``t``;
2. paths at the node's horizon ``H = max_j T_j`` (waiting for the others costs no
   makespan), chosen to collide as little as possible with the other teams' current
   paths: a min-cost flow whose arc costs count collisions (weighted above the number
   of moves, which breaks the remaining ties) on small networks, or on large networks
   a max flow with the other teams' cells removed, then with only the cells of their
   robots in transit removed, then the plain max flow (``tie_break`` option; OR-Tools'
   min-cost flow is far slower than its max flow on these networks).

The node's cost is ``max_i T_i``, a lower bound on the makespan of every plan that
respects the node's constraints; nodes are expanded best-first by (cost, number of
colliding robot pairs). The first conflict (earliest in time) between robots of two
teams is split into two children, one constraint per team. The first node without
conflicts is an optimal TAPF plan. A MAPF instance is solved as one team per agent.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import time
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.plan import Plan, path_cost
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.registry import solver
from hierplan_opt.search.assignment import team_makespan_bound
from hierplan_opt.search.conflicts import EDGE, VERTEX, Conflict
from hierplan_opt.search.flow_network import TeamDistances, TeamFlowNetwork, smallest_horizon

log = logging.getLogger(__name__)

TIE_BREAKS = ("auto", "cost", "avoid", "none")
VertexC = tuple[int, int]  # (v, t)
EdgeC = tuple[int, int, int]  # (u, v, t): moving u -> v between t and t + 1


@dataclass(frozen=True)
class _Constraints:
    vertex: frozenset[VertexC] = frozenset()
    edge: frozenset[EdgeC] = frozenset()


@dataclass
class _Node:
    cost: int
    horizons: list[int]  # T_i per team (lower bounds)
    paths: list[list[list[int]]]  # per team, per robot (in team order)
    constraints: list[_Constraints]
    conflicts: int = 0
    depth: int = 0
    first: Conflict | None = field(default=None, repr=False)


class _Team:
    """One team's data and its low level."""

    def __init__(
        self, graph: Graph, starts: list[int], targets: list[int], solver: _LowLevel
    ) -> None:
        self.graph = graph
        self.starts = starts
        self.targets = targets
        self.target_set = set(targets)
        self.k = len(starts)
        self.distances = TeamDistances(graph, starts, targets)
        self.bound = team_makespan_bound(graph, starts, targets)
        self.solver = solver


class _LowLevel:
    """Builds (and caches a few) networks and counts the flow solves."""

    def __init__(self, deadline: Deadline, tie_break: str, cost_arcs: int, cache: int = 6):
        self.deadline = deadline
        self.tie_break = tie_break
        self.cost_arcs = cost_arcs
        self.cache: OrderedDict[tuple[int, int], TeamFlowNetwork] = OrderedDict()
        self.cache_size = cache
        self.max_flow_solves = 0
        self.min_cost_solves = 0
        self.max_arcs = 0
        self.flow_time = 0.0

    def network(self, ti: int, team: _Team, horizon: int) -> TeamFlowNetwork:
        key = (ti, horizon)
        net = self.cache.get(key)
        if net is not None:
            self.cache.move_to_end(key)
            return net
        net = TeamFlowNetwork(
            team.graph, team.starts, team.targets, horizon, distances=team.distances
        )
        self.max_arcs = max(self.max_arcs, net.num_arcs)
        self.cache[key] = net
        # Keep a few networks per team, within a memory budget of arcs.
        total = sum(x.num_arcs for x in self.cache.values())
        while len(self.cache) > 1 and (len(self.cache) > self.cache_size or total > 20_000_000):
            _, old = self.cache.popitem(last=False)
            total -= old.num_arcs
        return net

    def min_horizon(self, ti: int, team: _Team, cons: _Constraints, lower: int) -> int | None:
        """Smallest feasible horizon under ``cons``; None on time-out or if there is none.

        Past the last constrained timestep the team is unconstrained; on an undirected
        graph unlabeled robots can then always be reconfigured by at most K moves of
        one robot along a free path (Calinescu, Dumitrescu & Pach 2008), i.e. within
        ``|V| * K`` further steps, so a larger horizon never helps. (On directed
        roadmaps this is only a safety cut-off.)
        """
        last = -1
        for v, t in cons.vertex:
            last = max(last, t)
            if v in team.target_set:
                lower = max(lower, t + 1)
        for _, _, t in cons.edge:
            last = max(last, t + 1)
        upper = max(lower, last + 1) + team.graph.num_vertices * team.k

        def feasible(h: int) -> bool:
            net = self.network(ti, team, h)
            caps = net.blocked_capacities(cons.vertex, cons.edge)
            t0 = time.perf_counter()
            value = net.max_flow(caps)
            self.flow_time += time.perf_counter() - t0
            self.max_flow_solves += 1
            return value == team.k

        horizon, _ = smallest_horizon(feasible, lower, deadline=self.deadline, upper=upper)
        return horizon

    def paths(
        self,
        ti: int,
        team: _Team,
        cons: _Constraints,
        horizon: int,
        others: Sequence[Sequence[int]],
    ) -> list[list[int]]:
        """The team's paths at ``horizon``, colliding little with ``others``."""
        net = self.network(ti, team, horizon)
        caps = net.blocked_capacities(cons.vertex, cons.edge)
        mode = self.tie_break
        if mode == "auto":
            mode = "cost" if net.num_arcs <= self.cost_arcs else "avoid"
        t0 = time.perf_counter()
        flows = None
        if mode == "cost":
            if others:
                occ, moves, sink, _ = _occupancy(others, horizon)
                weight = team.k * (horizon + 1) + 1  # one collision outweighs all moves
                costs = net.cost_array(
                    vertex_hits=occ, move_hits=moves, sink_hits=sink, weight=weight
                )
            else:
                costs = net.move_cost
            res = net.min_cost_flow(team.k, costs, caps)
            self.min_cost_solves += 1
            flows = None if res is None else res[1]
        elif mode == "avoid" and others:
            # Remove every cell and move the other teams use, if the team still fits;
            # else only those of robots in transit (robots parked in a passageway
            # can make full avoidance impossible), else nothing.
            occ, moves, _, parked = _occupancy(others, horizon)
            for keep in (None, ~parked):
                avoid = caps.copy()
                if keep is None:
                    avoid[net.vertex_arcs(*occ)] = 0
                else:
                    avoid[net.vertex_arcs(occ[0][keep], occ[1][keep])] = 0
                avoid[net.move_arcs(*moves)] = 0
                value, f = net.solve_max_flow(avoid)
                self.max_flow_solves += 1
                if value == team.k:
                    flows = f
                    break
        if flows is None:
            value, flows = net.solve_max_flow(caps)
            self.max_flow_solves += 1
            if value != team.k:
                raise RuntimeError("the team's horizon lost feasibility")  # cannot happen
        self.flow_time += time.perf_counter() - t0
        return net.extract_paths(flows)


def _padded(paths: Sequence[Sequence[int]], horizon: int) -> np.ndarray:
    """``P[r, t]`` = vertex of path ``r`` at ``t`` for ``t = 0..horizon`` (parked after)."""
    out = np.empty((len(paths), horizon + 1), dtype=np.int64)
    for r, p in enumerate(paths):
        m = min(len(p), horizon + 1)
        out[r, :m] = p[:m]
        out[r, m:] = p[-1]
    return out


def _occupancy(
    others: Sequence[Sequence[int]], horizon: int
) -> tuple[
    tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray, np.ndarray
]:
    """What a team would collide with in ``others``' paths, up to ``horizon``.

    Returns ``(v, t)`` for every robot position (parked robots included), ``(u, v, t)``
    for every move ``u -> v`` that would swap with another robot's ``v -> u``, the
    vertices other robots visit after ``horizon`` (a robot parking there is hit
    later), and a mask over the positions marking robots already parked for good.
    """
    P = _padded(others, horizon)
    ts = np.broadcast_to(np.arange(horizon + 1), P.shape)
    occ = (P.reshape(-1), ts.reshape(-1))
    a, b = P[:, :-1], P[:, 1:]
    moving = a != b
    moves = (b[moving], a[moving], ts[:, :-1][moving])
    late = [v for p in others if len(p) > horizon + 1 for v in p[horizon + 1 :]]
    arrival = np.array([path_cost(p) if len(p) <= horizon + 1 else 1 << 30 for p in others])
    parked = (ts >= arrival[:, None]).reshape(-1)
    return occ, moves, np.array(late, dtype=np.int64), parked


def _find_conflicts(
    paths: Sequence[Sequence[int]], team_of: Sequence[int]
) -> tuple[int, Conflict | None, set[int]]:
    """Colliding robot pairs of different teams: count, earliest conflict, teams involved.

    The earliest conflict is a vertex or edge :class:`Conflict` between robots ``a`` and
    ``b`` (a vertex conflict first when both happen at one step).
    """
    horizon = max(len(p) for p in paths) - 1
    P = _padded(paths, horizon)
    R = len(paths)
    team = np.asarray(team_of, dtype=np.int64)
    n = int(P.max()) + 1
    robots = np.broadcast_to(np.arange(R)[:, None], P.shape)
    ts = np.broadcast_to(np.arange(horizon + 1), P.shape)
    found: list[tuple[int, int, Conflict]] = []  # (t, kind order, conflict)
    count = 0
    involved: set[int] = set()
    # Vertex conflicts: equal (t, v) keys next to each other after sorting.
    key = (ts * n + P).reshape(-1)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    rs = robots.reshape(-1)[order]
    dup = np.flatnonzero(ks[1:] == ks[:-1])
    dup = dup[team[rs[dup]] != team[rs[dup + 1]]]
    if len(dup):
        count += len(dup)
        involved.update(team[rs[dup]].tolist())
        involved.update(team[rs[dup + 1]].tolist())
        i = int(dup[0])  # sorted by t first, so the earliest
        t, v = divmod(int(ks[i]), n)
        found.append((t, 0, Conflict(t, VERTEX, int(rs[i]), int(rs[i + 1]), -1, v)))
    # Swap conflicts: a move u -> v whose reverse v -> u happens at the same t.
    if horizon > 0:
        a, b = P[:, :-1], P[:, 1:]
        mv = a != b
        mu, mvv, mt, mr = a[mv], b[mv], ts[:, :-1][mv], robots[:, :-1][mv]
        fwd = (mt * n + mu) * n + mvv
        rev = (mt * n + mvv) * n + mu
        o = np.argsort(fwd, kind="stable")
        fs = fwd[o]
        pos = np.minimum(np.searchsorted(fs, rev), max(len(fs) - 1, 0))
        hit = np.flatnonzero((fs[pos] == rev) if len(fs) else np.zeros(0, dtype=bool))
        if len(hit):
            other = mr[o[pos[hit]]]
            mine = mr[hit]
            diff = team[mine] != team[other]
            hit, other, mine = hit[diff], other[diff], mine[diff]
            if len(hit):
                count += len(hit) // 2
                involved.update(team[mine].tolist())
                j = int(np.argmin(mt[hit]))
                h = int(hit[j])
                t = int(mt[h])  # the move leaves at t, arrives at t + 1
                c = Conflict(t + 1, EDGE, int(mine[j]), int(other[j]), int(mu[h]), int(mvv[h]))
                found.append((t, 1, c))
    first = min(found, key=lambda f: (f[0], f[1]))[2] if found else None
    return count, first, involved


@solver(
    "cbm",
    Option("tie_break", "choice", "how a team avoids the others' paths", choices=TIE_BREAKS),
    Option("cost_arcs", "int", "largest network for tie_break=auto to use cost", low=0),
    Option("repair_rounds", "int", "rounds of local re-planning per node (0: off)", low=0),
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "makespan",
    tie_break: str = "auto",
    cost_arcs: int = 60_000,
    repair_rounds: int = 0,
) -> Result:
    """Optimal makespan for TAPF (teams) or MAPF (one team per agent) by CBM.

    Parameters
    ----------
    instance
        TAPF or MAPF instance.
    time_limit
        Wall-clock seconds; on expiry TIME_LIMIT with the best proven lower bound.
    seed
        Unused (deterministic); accepted for the common signature.
    objective
        Only ``"makespan"``.
    tie_break
        How a team's paths avoid the other teams' paths: ``"cost"`` min-cost flow with
        collision costs (the published CBM), ``"avoid"`` max flow with the others'
        cells removed (falls back to a plain max flow), ``"none"`` plain max flow,
        ``"auto"`` = ``"cost"`` on networks with at most ``cost_arcs`` arcs, else
        ``"avoid"`` (OR-Tools' min-cost flow is slow on large time-expanded networks).
    cost_arcs
        Network size limit of ``"auto"``.
    repair_rounds
        Rounds of re-planning the conflicting teams of every new node under its own
        constraints (0 = off): a cheap local repair that keeps optimality.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 3, obstacles=[(1, 1)])
    >>> inst = Instance.tapf(g, [([(0, 0)], [(2, 2)]), ([(2, 2)], [(0, 0)])])
    >>> r = solve(inst)
    >>> r.status.value, r.cost
    ('OPTIMAL', 4)
    """
    del seed, objective  # deterministic; makespan only
    return _CBM(instance, Deadline(time_limit), tie_break, cost_arcs, repair_rounds).search()


class _CBM:
    """One CBM search: CBS over teams, each team's low level a flow problem."""

    def __init__(
        self,
        instance: Instance,
        deadline: Deadline,
        tie_break: str,
        cost_arcs: int,
        repair_rounds: int,
    ) -> None:
        self.instance = instance
        self.deadline = deadline
        self.started = time.perf_counter()
        g = instance.graph
        n_teams = len(instance.teams) if instance.is_tapf else instance.num_agents
        self.low = _LowLevel(deadline, tie_break, cost_arcs, cache=2 * n_teams + 4)
        if instance.is_tapf:
            self.members = [list(team.agents) for team in instance.teams]
            team_targets = [list(team.targets) for team in instance.teams]
        else:
            self.members = [[i] for i in range(instance.num_agents)]
            team_targets = [[g] for g in instance.goals]
        self.teams = [
            _Team(g, [instance.agents[i].start for i in m], tg, self.low)
            for m, tg in zip(self.members, team_targets, strict=True)
        ]
        self.team_of = [0] * instance.num_agents
        for ti, m in enumerate(self.members):
            for i in m:
                self.team_of[i] = ti
        self.stats: dict[str, Any] = {
            "teams": len(self.teams),
            "high_level_expanded": 0,
            "high_level_generated": 0,
            "low_level_calls": 0,
            "repair_replans": 0,
        }
        self.repair_rounds = repair_rounds if tie_break != "none" else 0
        self.lower_bound = max(t.bound for t in self.teams)
        self.open: list[tuple[int, int, int, _Node]] = []
        self.counter = itertools.count()

    # ------------------------------------------------------------------ paths
    def flat(self, node: _Node) -> list[list[int]]:
        """The node's paths in agent order."""
        out: list[list[int]] = [[] for _ in range(self.instance.num_agents)]
        for ti, m in enumerate(self.members):
            for i, p in zip(m, node.paths[ti], strict=True):
                out[i] = p
        return out

    def others(self, node: _Node, ti: int) -> list[list[int]]:
        """The paths of every team but ``ti``."""
        return [p for tj, ps in enumerate(node.paths) if tj != ti for p in ps]

    def evaluate(self, node: _Node) -> None:
        """Count conflicts, then re-plan conflicting teams within the node's constraints.

        Re-planning a team at the node's horizon under the same constraints keeps the
        node's lower bound valid; a new set of paths is kept only if it lowers the
        number of collisions. This shrinks the constraint tree a lot on crowded maps.
        """
        count, first, involved = _find_conflicts(self.flat(node), self.team_of)
        rounds = 0
        while count and rounds < self.repair_rounds and not self.deadline.expired():
            rounds += 1
            improved = False
            for ti in sorted(involved):
                if self.deadline.expired():
                    break
                old = node.paths[ti]
                node.paths[ti] = self.low.paths(
                    ti, self.teams[ti], node.constraints[ti], node.cost, self.others(node, ti)
                )
                self.stats["repair_replans"] += 1
                c2, f2, inv2 = _find_conflicts(self.flat(node), self.team_of)
                if c2 < count:
                    count, first, involved = c2, f2, inv2
                    improved = True
                    if not count:
                        break
                else:
                    node.paths[ti] = old
            if not improved:
                break
        node.conflicts, node.first = count, first

    # ------------------------------------------------------------------ tree
    def push(self, node: _Node) -> None:
        heapq.heappush(self.open, (node.cost, node.conflicts, next(self.counter), node))

    def root(self) -> _Node | Result:
        """Every team at its smallest horizon, paths at the largest (or a final result)."""
        empty = _Constraints()
        horizons: list[int] = []
        for ti, team in enumerate(self.teams):
            h = self.low.min_horizon(ti, team, empty, team.bound)
            self.stats["low_level_calls"] += 1
            if h is None:
                if self.deadline.expired():
                    return self.finish(Status.TIME_LIMIT, None, max([self.lower_bound, *horizons]))
                return self.finish(Status.INFEASIBLE, None, self.lower_bound)
            horizons.append(h)
        root_cost = max(horizons)
        root_paths: list[list[list[int]]] = []
        for ti, team in enumerate(self.teams):
            if self.deadline.expired():
                return self.finish(Status.TIME_LIMIT, None, root_cost)
            others = [p for ps in root_paths for p in ps]
            root_paths.append(self.low.paths(ti, team, empty, root_cost, others))
        root = _Node(root_cost, horizons, root_paths, [empty] * len(self.teams))
        self.evaluate(root)
        self.stats["high_level_generated"] = 1
        return root

    def split(self, c: Conflict) -> list[tuple[int, VertexC | None, EdgeC | None]]:
        """Per child: the team and the vertex or move it may no longer use."""
        team_of = self.team_of
        if c.kind == VERTEX:
            return [(team_of[c.a], (c.v, c.t), None), (team_of[c.b], (c.v, c.t), None)]
        t = c.t - 1  # moves are keyed by departure time here
        return [(team_of[c.a], None, (c.u, c.v, t)), (team_of[c.b], None, (c.v, c.u, t))]

    def child(self, node: _Node, ti: int, vc: VertexC | None, ec: EdgeC | None) -> _Node | None:
        """``node`` with one more constraint on team ``ti`` (None: no plan under it)."""
        old = node.constraints[ti]
        cons = _Constraints(
            old.vertex | {vc} if vc is not None else old.vertex,
            old.edge | {ec} if ec is not None else old.edge,
        )
        h = self.low.min_horizon(ti, self.teams[ti], cons, node.horizons[ti])
        self.stats["low_level_calls"] += 1
        if h is None:
            return None
        horizons = list(node.horizons)
        horizons[ti] = h
        cost = max(horizons)
        paths = list(node.paths)
        paths[ti] = self.low.paths(ti, self.teams[ti], cons, cost, self.others(node, ti))
        constraints = list(node.constraints)
        constraints[ti] = cons
        child = _Node(cost, horizons, paths, constraints, depth=node.depth + 1)
        self.evaluate(child)
        self.stats["high_level_generated"] += 1
        return child

    def search(self) -> Result:
        """Best-first search over the team constraint tree."""
        if any(t.bound >= UNREACHABLE for t in self.teams):  # the front door's checks
            return self.finish(Status.INFEASIBLE, None, self.lower_bound)
        root = self.root()
        if isinstance(root, Result):
            return root
        self.push(root)
        stats = self.stats
        last_log = time.perf_counter()
        while self.open:
            best = self.open[0][0]
            if self.deadline.expired():
                return self.finish(Status.TIME_LIMIT, None, best)
            node = heapq.heappop(self.open)[3]
            stats["high_level_expanded"] += 1
            if node.first is None:
                stats["conflicts_root"] = root.conflicts
                return self.finish(Status.OPTIMAL, Plan.from_paths(self.flat(node)), node.cost)
            if time.perf_counter() - last_log > 5:
                last_log = time.perf_counter()
                log.info(
                    "cbm: expanded %d, bound %d, open %d, conflicts %d",
                    stats["high_level_expanded"],
                    best,
                    len(self.open),
                    node.conflicts,
                )
            for ti, vc, ec in self.split(node.first):
                child = self.child(node, ti, vc, ec)
                if child is not None:
                    self.push(child)
                elif self.deadline.expired():
                    return self.finish(Status.TIME_LIMIT, None, best)
                # else: the team has no plan under these constraints: prune
        # CBS over teams only runs out of nodes if every branch lost feasibility.
        return self.finish(Status.INFEASIBLE, None, self.lower_bound)

    def finish(self, status: Status, plan: Plan | None, bound: int) -> Result:
        low, stats = self.low, self.stats
        stats["max_flow_solves"] = low.max_flow_solves
        stats["min_cost_solves"] = low.min_cost_solves
        stats["max_network_arcs"] = low.max_arcs
        stats["flow_time"] = round(low.flow_time, 3)
        stats["runtime_internal"] = round(time.perf_counter() - self.started, 3)
        if status is Status.TIME_LIMIT:  # only the deadline stops this search early
            stats["stopped_by"] = "time_limit"
        cost = plan.makespan if plan is not None else None
        return Result(status, plan, cost=cost, lower_bound=bound, objective="makespan", stats=stats)
