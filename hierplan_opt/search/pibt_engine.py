"""PIBT's engine: the space of compact vertex ids and the one-step generator.

:class:`Space` (the graph in compact vertex ids with every agent's distance table) and
:class:`PIBT` (one configuration step with priority inheritance and backtracking, and
the swap technique) are what the ``pibt`` solver (:mod:`hierplan_opt.search.pibt`,
where the algorithm is described) runs step after step, and what LaCAM
(:mod:`hierplan_opt.search.lacam`), its refinement and its guidance build on. A library
module: it registers no solver.
"""

from __future__ import annotations

import logging
import random
from collections import Counter
from collections.abc import Sequence

import numpy as np

from hierplan_opt import registry
from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline

log = logging.getLogger(__name__)

#: "No agent" in occupancy arrays and "undecided" in a configuration being built.
NIL = -1
#: Random orderings of every vertex's candidate list; ties between candidates at equal
#: distance are broken by picking one of them per decision (a power of two).
TIE_PERMUTATIONS = 8

Config = Sequence[int]


class Expired(Exception):
    """The deadline passed while preparing or searching (caught inside the solvers)."""


class Space:
    """The graph in compact vertex ids and each agent's timestep distance to its goal.

    Compact ids number the passable vertices only (on grids the graph's ids include
    blocked cells), so every table is as short as it can be. ``dist[i][v]`` is a plain
    list (the fastest lookup in pure Python); agents that share a goal share a table.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 2, obstacles=[(1, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (2, 0)], [(2, 1), (0, 1)])
    >>> s = Space(inst)
    >>> s.nv, s.lower_bound(), s.dist[0][s.starts[0]]
    (5, 6, 3)
    """

    def __init__(self, instance: Instance, deadline: Deadline | None = None, seed: int = 0):
        g = instance.graph
        free = np.flatnonzero(g.passable)
        self.nv = len(free)
        self.vid: list[int] = free.tolist()
        cid = np.full(g.n, NIL, dtype=np.int64)
        cid[free] = np.arange(self.nv)
        counts = np.diff(g.indptr)
        src = cid[np.repeat(np.arange(g.n), counts)]
        dst = cid[g.indices]
        self.directed = bool(g.directed)
        order = np.lexsort((dst, src))
        self.adj: list[list[int]] = [[] for _ in range(self.nv)]
        for a, b in zip(src[order].tolist(), dst[order].tolist(), strict=True):
            self.adj[a].append(b)
        self.starts: list[int] = [int(cid[a.start]) for a in instance.agents]
        self.goals: list[int] = [int(cid[a.goal]) for a in instance.agents]  # type: ignore[index]
        self.n_agents = len(self.starts)
        # Candidate lists (neighbours, then the vertex itself) in a few random orders;
        # vertices with the same number of candidates share the index permutations.
        rng = random.Random(seed)
        shapes: dict[int, list[list[int]]] = {}
        self.perms: list[list[list[int]]] = []
        for v, nb in enumerate(self.adj):
            base = [*nb, v]
            k = len(base)
            idx = shapes.get(k)
            if idx is None:
                idx = []
                for _ in range(TIE_PERMUTATIONS):
                    p = list(range(k))
                    rng.shuffle(p)
                    idx.append(p)
                shapes[k] = idx
            self.perms.append([[base[j] for j in p] for p in idx])
        self.dist = self._distances(instance, free, deadline)

    def _distances(
        self, instance: Instance, free: np.ndarray, deadline: Deadline | None
    ) -> list[list[int]]:
        # The graph's cached tables (the front door's checks made them), in compact ids;
        # blocked cells have no edges, so the distances are those of the compact graph.
        g = instance.graph
        unique = list(dict.fromkeys(a.goal for a in instance.agents))
        if not g.fill_distances(unique, deadline):  # type: ignore[arg-type]
            raise Expired
        every = self.nv == g.n  # no blocked cells: the graph's own lists, shared
        table: dict[int, list[int]] = {}
        for gl in unique:
            assert gl is not None
            table[gl] = g.dist_list(gl) if every else g.dist_to(gl)[free].tolist()
        return [table[a.goal] for a in instance.agents]  # type: ignore[index]

    def lower_bound(self) -> int:
        """Sum over agents of the distance from start to goal."""
        return sum(d[s] for d, s in zip(self.dist, self.starts, strict=True))

    def infeasibility(self, instance: Instance) -> str | None:
        """Why the instance has no plan (a shared or unreachable goal), or None."""
        counts = Counter(self.goals)
        for i, gl in enumerate(self.goals):
            if counts[gl] > 1:
                who = [instance.agents[j].name for j in range(self.n_agents) if self.goals[j] == gl]
                return f"agents {', '.join(map(repr, who))} share a goal"
            if self.dist[i][self.starts[i]] >= UNREACHABLE:
                return f"agent {instance.agents[i].name!r} cannot reach its goal"
        return None

    def plan(self, configs: Sequence[Config]) -> Plan:
        """The plan of a configuration sequence, in the graph's vertex ids, trimmed."""
        vid = self.vid
        paths = []
        for i in range(self.n_agents):
            p = [vid[q[i]] for q in configs]
            paths.append(p)
        return Plan.from_paths(paths).trimmed()


def sum_of_costs(configs: Sequence[Config], goals: Sequence[int]) -> int:
    """Sum over agents of the last arrival time at the goal in a configuration sequence.

    Example
    -------
    >>> sum_of_costs([(0, 5), (1, 5), (2, 4), (2, 5)], [2, 5])
    5
    """
    total = 0
    n = len(goals)
    last = len(configs) - 1
    for i in range(n):
        gl = goals[i]
        t = last
        while t > 0 and configs[t - 1][i] == gl and configs[t][i] == gl:
            t -= 1
        if configs[t][i] != gl:  # not at the goal at the end (only for partial plans)
            t = last
        total += t
    return total


class PIBT:
    """One-step configuration generator (PIBT with the swap extension).

    ``step(q_from, q_to, order)`` fills the undecided entries (``NIL``) of ``q_to``;
    entries already set are constraints it must respect. It returns False when no
    conflict-free completion was found (then ``q_to`` is garbage).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(0, 0), (1, 0)], [(1, 0), (2, 0)])
    >>> space = Space(inst)
    >>> q_to = [NIL, NIL]
    >>> PIBT(space, seed=0).step(space.starts, q_to, [1, 0]), q_to
    (True, [1, 2])
    """

    def __init__(
        self,
        space: Space,
        seed: int = 0,
        *,
        swap: bool = True,
        guide: list[dict[int, int]] | None = None,
    ) -> None:
        self.space = space
        self.adj = space.adj
        self.dist = space.dist
        self.goals = space.goals
        self.perms = space.perms
        self.occ_now = [NIL] * space.nv
        self.occ_next = [NIL] * space.nv
        self.rng = random.Random(seed)
        # Swap reasons about corridors, which needs moves to be reversible.
        self.swap = swap and not space.directed
        # Vertices with at least three neighbours that are not dead ends: from there
        # two ways always lead on, so no swap is ever needed towards them.
        adj = self.adj
        self.wide = [sum(len(adj[u]) > 1 for u in nb) >= 3 for nb in adj]
        self.guide = guide

    # ------------------------------------------------------------------ one step
    def step(
        self, q_from: Config, q_to: list[int], order: Sequence[int], fixed: Sequence[int] = ()
    ) -> bool:
        """Complete ``q_to`` (agents in ``fixed`` are already set) in priority ``order``."""
        occ_now = self.occ_now
        occ_next = self.occ_next
        for i, v in enumerate(q_from):
            occ_now[v] = i
        ok = True
        for i in fixed:
            u = q_to[i]
            if occ_next[u] != NIL:
                ok = False
                break
            j = occ_now[u]
            if j != NIL and j != i and q_to[j] == q_from[i]:
                ok = False
                break
            occ_next[u] = i
        if ok:
            push = self._push
            for i in order:
                if q_to[i] == NIL and not push(i, q_from, q_to):
                    ok = False
                    break
        for v in q_from:
            occ_now[v] = NIL
        if ok:
            for u in q_to:
                occ_next[u] = NIL
        else:
            for u in q_to:
                if u != NIL:
                    occ_next[u] = NIL
        return ok

    def _frame(self, i: int, q_from: Config, q_to: list[int]) -> list:
        """Agent ``i``'s candidates, best first, and its swap partner (or NIL)."""
        v = q_from[i]
        d = self.dist[i]
        cands = sorted(self.perms[v][self.rng.getrandbits(3)], key=d.__getitem__)
        if self.guide is not None:
            pref = self.guide[i].get(v)
            if pref is not None and pref != cands[0]:
                cands.remove(pref)
                cands.insert(0, pref)
        mate = NIL
        if self.swap:
            mate = self._swap_mate(i, v, cands, q_from, q_to)
            if mate != NIL:
                cands.reverse()
        return [i, cands, 0, mate]

    def _push(self, i0: int, q_from: Config, q_to: list[int]) -> bool:
        """Plan agent ``i0`` and, by priority inheritance, every agent in its way.

        An explicit stack instead of recursion: inheritance chains can be as long as
        the number of agents. A frame is ``[agent, candidates, index, swap mate]``.
        """
        occ_now = self.occ_now
        occ_next = self.occ_next
        stack = [self._frame(i0, q_from, q_to)]
        ret = None  # result of the frame just popped
        while stack:
            fr = stack[-1]
            i = fr[0]
            cands = fr[1]
            k = fr[2]
            vi = q_from[i]
            if ret is not None:
                if ret:  # the agent in the way moved: keep cands[k]
                    stack.pop()
                    if k == 0 and fr[3] != NIL:
                        self._pull(fr[3], vi, q_to)
                    continue
                k += 1
                ret = None
            n = len(cands)
            child = False
            while k < n:
                u = cands[k]
                if occ_next[u] != NIL:
                    k += 1
                    continue
                j = occ_now[u]
                if j != NIL and q_to[j] == vi:  # would swap places with j
                    k += 1
                    continue
                occ_next[u] = i
                q_to[i] = u
                if j != NIL and u != vi and q_to[j] == NIL:
                    fr[2] = k
                    stack.append(self._frame(j, q_from, q_to))
                    child = True
                break
            if child:
                continue
            stack.pop()
            if k < n:
                if k == 0 and fr[3] != NIL:
                    self._pull(fr[3], vi, q_to)
                ret = True
            else:  # nothing works: stay (the caller sees the failure)
                q_to[i] = vi
                occ_next[vi] = i
                ret = False
        return bool(ret)

    # ------------------------------------------------------------------ swap
    def _pull(self, mate: int, v: int, q_to: list[int]) -> None:
        """The retreating agent left ``v``; its swap mate follows into it if it can."""
        if q_to[mate] == NIL and self.occ_next[v] == NIL:
            self.occ_next[v] = mate
            q_to[mate] = v

    def _swap_mate(self, i: int, v: int, cands: list[int], q_from: Config, q_to: list[int]) -> int:
        """The agent ``i`` should swap with (retreat and pull along), or NIL.

        Case 1: the agent ``j`` on ``i``'s best vertex cannot make way before its
        corridor ends and wants to come towards ``i``; a junction behind ``i`` lets
        them pass. Case 2 looks one step ahead: after ``i`` moves on, would a
        neighbour ``k`` then be stuck behind it in the same way?
        """
        best = cands[0]
        if self.wide[best]:  # a junction ahead: whoever is there can make way
            return NIL
        occ_now = self.occ_now
        j = occ_now[best]
        if (
            j != NIL
            and j != i
            and q_to[j] == NIL
            and self._swap_needed(i, j, v, q_from[j])
            and self._swap_room(q_from[j], v)
        ):
            return j
        if best != v:
            for u in self.adj[v]:
                k = occ_now[u]
                if (
                    k != NIL
                    and u != best
                    and self._swap_needed(k, i, v, best)
                    and self._swap_room(best, v)
                ):
                    return k
        return NIL

    def _exits(self, v: int, came_from: int) -> tuple[int, int]:
        """How many ways lead on from ``v`` (not back, not into a dead end where an
        agent rests on its goal), and one of them."""
        occ_now = self.occ_now
        adj = self.adj
        goals = self.goals
        n = 0
        nxt = NIL
        for u in adj[v]:
            if u == came_from:
                continue
            if len(adj[u]) == 1:
                a = occ_now[u]
                if a != NIL and goals[a] == u:
                    continue
            n += 1
            nxt = u
        return n, nxt

    def _swap_needed(self, pusher: int, puller: int, vp: int, vq: int) -> bool:
        """Whether ``pusher`` at ``vp`` heading into ``puller`` at ``vq`` is stuck.

        Walks ahead along the corridor while the pusher keeps getting closer to its
        goal; a vertex with two ways on lets the puller step aside (no swap needed).
        """
        dp = self.dist[pusher]
        while dp[vq] < dp[vp]:
            n, nxt = self._exits(vq, vp)
            if n >= 2:
                return False
            if n == 0:
                break
            vp, vq = vq, nxt
        dq = self.dist[puller]
        return dq[vp] < dq[vq] and (dp[vp] == 0 or dp[vq] < dp[vp])

    def _swap_room(self, vp: int, vq: int) -> bool:
        """Whether retreating from ``vq`` away from ``vp`` reaches a junction."""
        origin = vp
        while vq != origin:
            n, nxt = self._exits(vq, vp)
            if n >= 2:
                return True
            if n == 0:
                return False
            vp, vq = vq, nxt
        return False


# ---------------------------------------------------------------------- priorities
def initial_priorities(space: Space) -> list[float]:
    """Fractional tie-breakers in [0, 1): agents farther from their goal go first."""
    scale = 1.0 / (space.nv + 1)
    return [min(d[s], space.nv) * scale for d, s in zip(space.dist, space.starts, strict=True)]


def next_priorities(prio: Sequence[float], q: Config, goals: Sequence[int]) -> list[float]:
    """Elapsed-time priorities: +1 while away from the goal, reset to the fraction there.

    Example
    -------
    >>> next_priorities([0.5, 2.25], [3, 7], [3, 8])
    [0.5, 3.25]
    """
    return [p - int(p) if v == gl else p + 1.0 for p, v, gl in zip(prio, q, goals, strict=True)]


def priority_order(prio: Sequence[float]) -> list[int]:
    """Agents by decreasing priority (stable: equal priorities keep index order)."""
    return sorted(range(len(prio)), key=prio.__getitem__, reverse=True)


# ---------------------------------------------------------------------- solver
def prepare(instance: Instance, deadline: Deadline, seed: int) -> tuple[Space, int] | Result:
    """The space and the sum of distances, or the Result that ends the solve early
    (TIME_LIMIT while computing distances, INFEASIBLE by the cheap checks)."""
    try:
        space = Space(instance, deadline, seed)
    except Expired:
        lb = registry.quick_lower_bound(instance)  # from the distance tables made so far
        return Result(
            Status.TIME_LIMIT,
            None,
            lower_bound=lb,
            stats={"stopped_by": "time_limit", "reason": "time limit while preparing"},
        )
    lb = space.lower_bound()
    why = space.infeasibility(instance)
    if why is not None:
        return Result(Status.INFEASIBLE, None, lower_bound=lb, stats={"reason": why})
    return space, lb


SWAP_OPTION = Option("swap", "bool", "PIBT's swap technique (undirected graphs)")
